"""Contact points and normals from a triangle mesh of the part.

Callers give cutter centres: ball centres, or the centres of a bull-nose's
torus core circle (programmed point + ``cutters.center_offset_mm`` along the
tool axis), and in 5 axes the tool axis per centre.  A ball's contact does not
depend on the axis (the closest point to its centre); its R_eff does.  The
bull-nose search below assumes the axis +Z.  The CC point is the mesh point
closest to the centre (fcpw's BVH finds the face, float64 numpy the point on
it), for a bull-nose to its core disc (radius R - r).

Normals (``normals=``): ``"facet"``; ``"center"`` (CC->centre: the facet
normal too wherever the CC point is inside a facet, so both jump from facet to
facet and R_eff with them); ``"phong"``: corner normals (angle-weighted vertex
normals, split where facets meet at more than ``feature_angle_deg``)
interpolated at the CC point; ``"smooth"`` (default): Newton steps on that
field to the point p whose normal passes through the centre (exact on a sphere
with exact vertex normals), at most 2x the phong/CC->centre angle away from
phong; CC->centre on sharp edges and where the two disagree by more than the
feature angle (e.g. inconsistent winding).

Measured (``bench/bench_geometry.py normals``): analytic surfaces meshed on
jittered grids, ball centres at distance R along the analytic normal.  Cells:
95th-percentile normal error, deg / worst vc overshoot R_true/R_est - 1, %
(where R_eff >= 0.2 R), at grid pitch 0.5 and 2 mm:

    surface, tool               grid | facet       center      phong       smooth
    convex sphere rho 20, D16   0.5  | 1.24 11.5   0.73  5.3   0.32  2.2   0.10  0.7
                                2.0  | 4.96 52.6   2.96 26.7   1.36 10.1   0.53  3.4
    concave bowl rho 50, D16    0.5  | 0.43  3.4   0.43  3.4   0.10  0.7   0.06  0.6
                                2.0  | 1.74 16.6   1.73 16.6   0.41  3.4   0.27  2.2
    concave fillet rho 5, D8    0.5  | 4.22 74.1   4.22 74.1   3.43 54.0   2.24 25.5
                                2.0  | 16.3  145   16.3  145   13.8 77.8   13.9 30.9
    convex fillet rho 5, D16    0.5  | 4.27 60.1   1.15  9.6   1.65 16.3   0.47  1.5
                                2.0  | 16.3  150   4.70 35.1   6.97 49.5   4.34  4.8
    gauss bump 8/12 mm, D8      0.5  | 1.15 15.5   0.89 11.6   0.27  5.0   0.15  1.4
                                2.0  | 4.61 85.6   3.61 57.9   1.57 22.6   1.33  9.9
    sharp 50 deg edge, D8       any  | 46.5  0.0   0.00  0.0   46.5  0.0   0.00  0.0

Area-weighted normals doubled the smooth errors; without the sharp-edge rule
the edge case erred 4-15 deg (p95); a 50/50 blend of CC->centre and phong was
worse than phong; unclamped Newton erred up to 12-21 deg on the concave fillet
at 0.5-1 mm (clamped: 4-8).  No method copes with a 5 mm fillet meshed at 2 mm:
report ``mesh_resolution_mm``.  Bull-nose (``... bullnose``, D8 r1): clearance
within 0.007 mm of a brute-force minimum over the disc, R_eff within 0.01 mm;
but with several bumps under a wide flat (D16 r2, egg-crate of 12.6 mm
period) the lowest can be missed (clearance up to 0.11 mm high; 15 % of the
near-contact points taken for air).  The closest-point query (fcpw) uses every
core itself (1M path-ordered points, 1M triangles: 2.6 s wall, 5.1 s CPU on 2
cores; libigl's AABB tree took 5.0 s wall, 9.8 s CPU): a thread pool spreads
only the numpy work (forked processes were slower than one: 1.27 s against
1.01 s serial and 0.67 s in two threads for 1M normals), and the queries run
in calls of up to 1M points (:meth:`MeshIndex._faces`).

The pieces: closest points (``ncopt.contacts.closest``) on the indexed mesh
(``ncopt.contacts.meshindex``), normals (``ncopt.contacts.normals``), the bull-nose
search (``ncopt.contacts.bullnose``); here the contacts and clearances from them.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ncopt.contacts import cutters
from ncopt.contacts.bullnose import torus_closest
from ncopt.contacts.closest import Closest
from ncopt.contacts.mesh import EdgeLengths, Mesh, load_stl, mesh_from_triangles, mesh_resolution_mm
from ncopt.contacts.meshindex import MeshIndex
from ncopt.contacts.normals import NORMAL_METHODS, contact_normal
from ncopt.model import Contacts, Cutter


__all__ = ["NORMAL_METHODS", "Closest", "EdgeLengths", "Mesh", "MeshContacts", "MeshIndex",
           "contacts_from_mesh", "load_stl", "mesh_contacts", "mesh_from_triangles",
           "mesh_resolution_mm"]


@dataclass(frozen=True)
class MeshContacts:
    """Contacts plus what the mesh says about the tool's clearance.

    Attributes
    ----------
    contacts : Contacts
        CC points (closest mesh points), normals toward the tool, ``R_eff``
        (:func:`ncopt.contacts.cutters.r_eff_mm`), ``cutting = gap_mm <= tol_mm``.
    gap_mm : (m,) float64
        Clearance of the cutter from the mesh less ``stock_mm``, mm; negative
        inside the part.  For bull-nose air points an upper bound.
    gouging : (m,) bool
        ``gap_mm < -tol_mm``: suggests a wrong tool, mesh, tool point or stock.
    face : (m,) int64
        Mesh face holding each CC point.
    """

    contacts: Contacts
    gap_mm: np.ndarray
    gouging: np.ndarray
    face: np.ndarray

    @property
    def n_gouging(self) -> int:
        return int(np.count_nonzero(self.gouging))


def _torus_chunk(centers: np.ndarray, index: MeshIndex, cutter: Cutter, band_mm: float) -> tuple:
    core, cl = torus_closest(index, centers, cutter, band_mm)
    return (core, *cl)


def _normal_chunk(core, dist, face, point, *axis, index: MeshIndex, method: str) -> tuple:
    return (contact_normal(index, Closest(dist, face, point), core, method,
                           axis[0] if axis else None),)


def mesh_contacts(centers_mm: np.ndarray, mesh_index: MeshIndex, cutter: Cutter,
                  tol_mm: float = 0.05, *, stock_mm: float = 0.0,
                  normals: str = "smooth", axis: np.ndarray | None = None) -> MeshContacts:
    """Contacts of a ball or bull-nose cutter with a mesh, with clearances.

    Parameters
    ----------
    centers_mm : (m, 3) float64
        Ball centres (ball) or torus core-circle centres (bull-nose), mm, in
        path order: programmed points raised by ``cutters.center_offset_mm``.
    mesh_index : MeshIndex
    cutter : Cutter
    tol_mm : float
        Contact where the clearance is within this of ``stock_mm`` (mesh
        chord error + CAM tolerance), mm.
    stock_mm : float
        Allowance the program leaves on the part, mm.
    normals : {"smooth", "phong", "center", "facet"}
        Contact normal estimate (module docstring).
    axis : (m, 3) float64 or None
        Unit tool axis at each centre (5 axes); None: +Z.  A bull-nose takes
        +Z only.

    Returns
    -------
    MeshContacts
        Air points (clearance above ``tol_mm``) are not cutting; points inside
        the part are cutting and flagged as gouging.
    """
    if normals not in NORMAL_METHODS:
        raise ValueError(f"normals must be one of {NORMAL_METHODS}, got {normals!r}")
    c = np.ascontiguousarray(centers_mm, dtype=np.float64)
    if c.ndim != 2 or c.shape[1] != 3:
        raise ValueError(f"centers_mm must be (m, 3), got {c.shape}")
    if not np.all(np.isfinite(c)):
        raise ValueError("centers_mm holds non-finite coordinates")
    if axis is not None and not cutter.is_ball and np.any(axis[:, :2]):
        raise ValueError("the bull-nose contact search takes a +Z tool axis only")
    if cutter.is_ball:
        core, cl = c, mesh_index.closest(c)
    else:  # the disc search is mostly queries: serial chunks, the library uses the cores
        work = functools.partial(_torus_chunk, index=mesh_index, cutter=cutter,
                                 band_mm=stock_mm + tol_mm)
        core, *found = mesh_index.map_chunks(work, c, pool=False)
        cl = Closest(*found)
    normal_work = functools.partial(_normal_chunk, index=mesh_index, method=normals)
    (normal,) = mesh_index.map_chunks(normal_work, core, *cl, *(() if axis is None else (axis,)))
    cc, dist, face = cl.point_mm, cl.dist_mm, cl.face
    gap = dist - cutter.corner_radius_mm - stock_mm
    contacts = Contacts(cc_mm=cc, normal=normal, r_eff_mm=cutters.r_eff_mm(cutter, normal, axis),
                        cutting=gap <= tol_mm)
    return MeshContacts(contacts=contacts, gap_mm=gap, gouging=gap < -tol_mm, face=face)


def contacts_from_mesh(centers_mm: np.ndarray, mesh_index: MeshIndex, cutter: Cutter,
                       tol_mm: float = 0.05, *, stock_mm: float = 0.0,
                       normals: str = "smooth", axis: np.ndarray | None = None) -> Contacts:
    """:func:`mesh_contacts` without the clearances (same parameters); returns Contacts."""
    return mesh_contacts(centers_mm, mesh_index, cutter, tol_mm, stock_mm=stock_mm,
                         normals=normals, axis=axis).contacts
