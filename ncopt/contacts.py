"""Toolpath -> contacts: where the cutter touches the part, per sample point.

With a mesh, the planner's samples are every block end and, inside a move, only
where the geometry asks for them (:mod:`ncopt.sampling`), and the contacts come
from closest-point queries (:mod:`ncopt.geometry`).  Without a mesh, the CL
points themselves are the samples and the normals come from the toolpath's own
shape (:mod:`ncopt.pathnormals`); between two points the normal is their
interpolation, so no interior samples are needed.  ``sample_points`` spaces
samples evenly (the simulator's), at most ``MAX_SAMPLES_PER_MOVE`` per move.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .geometry import MeshIndex, mesh_contacts
from .memory import release_freed_memory
from .model import Contacts, Cutter, Toolpath
from .pathnormals import PathNormals, contacts_from_path
from .remaining import r_eff_material_mm
from .sampling import Probe, Refinement, adaptive_samples
from .tools import center_offset_mm

# Evenly spaced samples stop at this many per move: a longer move is sampled every
# length / MAX_SAMPLES_PER_MOVE (10 m at 0.1 mm; memory stays bounded by the moves).
MAX_SAMPLES_PER_MOVE = 100_000


@dataclass(frozen=True)
class Sampled:
    """Contacts and, per sample, the index of the toolpath point whose move it is on."""

    contacts: Contacts
    point: np.ndarray  # (m,) int
    estimate: PathNormals | None = None  # mesh-free only
    gap_mm: np.ndarray | None = None  # (m,) with a mesh: clearance of the cutter, mm (< 0 inside)


def samples_per_move(tp: Toolpath, sample_mm: float) -> np.ndarray:
    """(n-1,) evenly spaced samples of each move: at most ``sample_mm`` apart, at
    least one, at most ``MAX_SAMPLES_PER_MOVE``."""
    seg = np.linalg.norm(np.diff(tp.xyz_mm, axis=0), axis=1)
    return np.clip(np.ceil(seg / sample_mm), 1, MAX_SAMPLES_PER_MOVE).astype(np.int64)


def sample_fractions(tp: Toolpath, sample_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """Per sample: the toolpath point whose move it lies on, and how far along (0..1].

    Samples are at most ``sample_mm`` apart (``length / MAX_SAMPLES_PER_MOVE`` on a
    longer move) and end on each CL point; the first sample is point 0 itself
    (fraction 1).
    """
    n_per = samples_per_move(tp, sample_mm)
    point = np.concatenate(([0], np.repeat(np.arange(1, tp.n), n_per)))
    offsets = np.concatenate(([0], np.cumsum(n_per)))
    k = np.arange(1, offsets[-1] + 1) - np.repeat(offsets[:-1], n_per)
    frac = np.concatenate(([1.0], k / np.repeat(n_per, n_per)))
    return point, frac


def sample_points(tp: Toolpath, sample_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """Points along every move, at most ``sample_mm`` apart (see
    :func:`sample_fractions`), ending on each CL point.

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


def mesh_contacts_at_samples(tp: Toolpath, cutter: Cutter, mesh_index: MeshIndex,
                             sample_mm: float, tol_mm: float) -> Contacts:
    """Contacts from the mesh on every sample of :func:`sample_points` (the simulator's
    evenly spaced samples: an original and its rewrite can share them)."""
    xyz, _ = sample_points(tp, sample_mm)
    offset = np.array([0.0, 0.0, center_offset_mm(cutter)])
    return mesh_contacts(xyz + offset, mesh_index, cutter, tol_mm).contacts


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
                 stock_mm: float = 0.0, *, r_floor_mm: float = 0.0) -> Sampled:
    """Contacts of ``cutter`` along the toolpath, from the mesh if there is one
    (``stock_mm``: the allowance the program leaves on the mesh).

    With a mesh: every block end of the ``selected`` moves and, inside them, samples
    where the geometry asks for them (:mod:`ncopt.sampling`; ``sample_mm`` is the
    longest interval between samples where the tool cuts; below ``r_floor_mm`` the
    requirement is capped at S_max, so R_eff differences there need no samples).
    """
    release_freed_memory()  # the interpreter's and the mesh loading's leftovers
    offset = np.array([0.0, 0.0, center_offset_mm(cutter)])
    if mesh_index is not None:
        ref = Refinement(coarse_mm=sample_mm, r_floor_mm=r_floor_mm, contact_tol_mm=tol_mm)
        got = adaptive_samples(tp.xyz_mm + offset, selected,
                               _mesh_probe(mesh_index, cutter, tol_mm, stock_mm), ref)
        p = got.probe
        sampled = Sampled(Contacts(cc_mm=p.cc_mm, normal=p.normal, r_eff_mm=p.r_eff_mm,
                                   cutting=p.cutting), got.point, gap_mm=p.gap_mm)
    else:
        path = np.cumsum(tp.seg_len_mm)
        cutting = selected & ~air_moves(tp)
        contacts, estimate = contacts_from_path(tp.xyz_mm + offset, path, cutting, cutter)
        sampled = Sampled(contacts, np.arange(tp.n), estimate)
    if method.name == "material":
        sampled = replace(sampled, contacts=_with_material(tp, cutter, sampled, method))
    release_freed_memory()
    return sampled


def _mesh_probe(mesh_index: MeshIndex, cutter: Cutter, tol_mm: float, stock_mm: float = 0.0):
    """The query :func:`ncopt.sampling.adaptive_samples` makes of the mesh."""
    flat_mm = cutter.radius_mm - cutter.corner_radius_mm

    def query(centers_mm: np.ndarray) -> Probe:
        mc = mesh_contacts(centers_mm, mesh_index, cutter, tol_mm, stock_mm=stock_mm)
        c = mc.contacts
        # a bull-nose's clearance is searched over its disc near the part only; the
        # centre's distance less the disc radius bounds it from below everywhere
        return Probe(c.r_eff_mm, c.normal, c.cc_mm, mc.gap_mm - flat_mm, c.cutting,
                     mc.gap_mm)

    return query


def _with_material(tp: Toolpath, cutter: Cutter, sampled: Sampled, method: Method) -> Contacts:
    """R_eff from the remaining material, with each sample's direction of motion."""
    d = tp.xyz_mm[sampled.point] - tp.xyz_mm[np.maximum(sampled.point - 1, 0)]
    r = r_eff_material_mm(cutter, sampled.contacts.normal, d, method.ap_mm, method.along)
    return replace(sampled.contacts, r_eff_mm=r)
