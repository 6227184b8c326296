"""Toolpath -> contacts: where the cutter touches the part, per sample point.

With a mesh, every move is sampled at most ``sample_mm`` apart and the
contacts come from closest-point queries (:mod:`ncopt.geometry`).  Without a
mesh, the CL points themselves are the samples and the normals come from the
toolpath's own shape (:mod:`ncopt.pathnormals`); between two points the
normal is their interpolation, so no interior samples are needed.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .geometry import MeshIndex, mesh_contacts
from .model import Contacts, Cutter, Toolpath
from .pathnormals import PathNormals, contacts_from_path
from .remaining import r_eff_material_mm
from .tools import center_offset_mm


@dataclass(frozen=True)
class Sampled:
    """Contacts and, per sample, the index of the toolpath point whose move it is on."""

    contacts: Contacts
    point: np.ndarray  # (m,) int
    estimate: PathNormals | None = None  # mesh-free only
    gap_mm: np.ndarray | None = None  # (m,) with a mesh: clearance of the cutter, mm (< 0 inside)


def sample_fractions(tp: Toolpath, sample_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """Per sample: the toolpath point whose move it lies on, and how far along (0..1].

    Samples are at most ``sample_mm`` apart and end on each CL point; the first
    sample is point 0 itself (fraction 1).
    """
    seg = np.linalg.norm(np.diff(tp.xyz_mm, axis=0), axis=1)
    n_per = np.maximum(np.ceil(seg / sample_mm).astype(np.int64), 1)
    point = np.concatenate(([0], np.repeat(np.arange(1, tp.n), n_per)))
    offsets = np.concatenate(([0], np.cumsum(n_per)))
    k = np.arange(1, offsets[-1] + 1) - np.repeat(offsets[:-1], n_per)
    frac = np.concatenate(([1.0], k / np.repeat(n_per, n_per)))
    return point, frac


def sample_points(tp: Toolpath, sample_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """Points along every move, at most ``sample_mm`` apart, ending on each CL point.

    Returns xyz (m, 3) in mm and, per sample, the index of the toolpath point
    whose move it lies on (point 0 for the start point).
    """
    point, frac = sample_fractions(tp, sample_mm)
    a = tp.xyz_mm[np.maximum(point - 1, 0)]
    b = tp.xyz_mm[point]
    return a + (b - a) * frac[:, None], point


def path_contacts_at_samples(tp: Toolpath, cutter: Cutter, selected: np.ndarray,
                             sample_mm: float) -> Contacts:
    """Mesh-free contacts on the samples of :func:`sample_points`: the per-point
    estimate, R_eff interpolated along each move (as the planner assumes)."""
    at_points = contacts_for(tp, cutter, selected, None, sample_mm, 0.0).contacts
    point, frac = sample_fractions(tp, sample_mm)
    prev = np.maximum(point - 1, 0)
    r = at_points.r_eff_mm[prev] * (1.0 - frac) + at_points.r_eff_mm[point] * frac
    normal = at_points.normal[prev] * (1.0 - frac)[:, None] + at_points.normal[point] * frac[:, None]
    normal /= np.maximum(np.linalg.norm(normal, axis=1), 1e-12)[:, None]
    xyz, _ = sample_points(tp, sample_mm)
    cc = xyz + np.array([0.0, 0.0, center_offset_mm(cutter)]) - cutter.corner_radius_mm * normal
    return Contacts(cc_mm=cc, normal=normal, r_eff_mm=r, cutting=at_points.cutting[point])


def air_moves(tp: Toolpath) -> np.ndarray:
    """(n,) bool: feed moves that cannot be cutting when no mesh says otherwise:
    plunges and retracts (within 11 deg of vertical).

    Other air moves are planned like cuts: with no neighbouring pass their
    normal is that of the move itself, which can only make them run faster.
    """
    d = np.diff(tp.xyz_mm, axis=0)
    length = np.linalg.norm(d, axis=1)
    return np.concatenate(([False], np.abs(d[:, 2]) > 0.98 * np.maximum(length, 1e-12)))


@dataclass(frozen=True)
class Method:
    """How R_eff is found: at the contact point (``contact``, the default) or where the
    edge meets the remaining material of height ``ap_mm`` (``material``), offset along
    the surface normal or the tool axis (``along``)."""

    name: str = "contact"
    ap_mm: float = 0.2
    along: str = "normal"


def contacts_for(tp: Toolpath, cutter: Cutter, selected: np.ndarray, mesh_index: MeshIndex | None,
                 sample_mm: float, tol_mm: float, method: Method = Method(),
                 stock_mm: float = 0.0) -> Sampled:
    """Contacts of ``cutter`` along the toolpath, from the mesh if there is one
    (``stock_mm``: the allowance the program leaves on the mesh)."""
    offset = np.array([0.0, 0.0, center_offset_mm(cutter)])
    if mesh_index is not None:
        xyz, point = sample_points(tp, sample_mm)
        found = mesh_contacts(xyz + offset, mesh_index, cutter, tol_mm, stock_mm=stock_mm)
        sampled = Sampled(found.contacts, point, gap_mm=found.gap_mm)
    else:
        path = np.cumsum(tp.seg_len_mm)
        cutting = selected & ~air_moves(tp)
        contacts, estimate = contacts_from_path(tp.xyz_mm + offset, path, cutting, cutter)
        sampled = Sampled(contacts, np.arange(tp.n), estimate)
    if method.name == "material":
        sampled = replace(sampled, contacts=_with_material(tp, cutter, sampled, method))
    return sampled


def _with_material(tp: Toolpath, cutter: Cutter, sampled: Sampled, method: Method) -> Contacts:
    """R_eff from the remaining material, with each sample's direction of motion."""
    d = tp.xyz_mm[sampled.point] - tp.xyz_mm[np.maximum(sampled.point - 1, 0)]
    r = r_eff_material_mm(cutter, sampled.contacts.normal, d, method.ap_mm, method.along)
    return replace(sampled.contacts, r_eff_mm=r)
