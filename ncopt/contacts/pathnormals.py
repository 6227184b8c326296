"""Contact normals from the toolpath alone, for programs that come without a mesh.

The surface traced by the cutter centre is an offset of the part surface, so it
has the same normals.  At every cutter-centre point:

* the along-pass tangent ``t`` comes from its neighbours on the path;
* the cross-slope comes from nearby points on *other* passes: neighbours from a
  k-d tree (scipy's cKDTree) whose distance along the path is much larger than
  their straight distance;
* the normal is the unit vector perpendicular to ``t`` that best fits the
  offsets to those neighbours (a weighted 2x2 least-squares problem, solved in
  closed form for all points at once), oriented toward the tool (+Z, or in 5
  axes the tool axis at the point: ball centres trace the part's offset surface
  whatever the axis, so the estimate holds; "vertical" below means "along the
  tool axis").

Where neighbours lie on one side only (the first and last pass, the edge of
the machined area) the fit is one-sided and a curved surface tilts it: such
points get a lower confidence, and the planner makes them conservative.  Where
no other pass is near (a single 2D profile) the cross-slope cannot be known:
it is taken as zero and reported.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ncopt.motion.modal import row_norms
from ncopt.contacts.curvedfit import curved_normals
from ncopt.contacts.kdtree import cKDTree
# the confidences, the pass ratio and across are used from here by the other stages
from ncopt.contacts.pathfit import (CONFIDENT, NO_CROSS, ONE_SIDED, OTHER_PASS_RATIO, across,
                                    by_rank, fit_cross, frame, other_pass)
from ncopt.model import Contacts, Cutter
from ncopt.runtime.threads import available_cpus, map_in_threads
from ncopt.contacts.cutters import r_eff_mm

K_NEIGHBOURS = 12  # enough for 4-5 points per pass on each side at CAM-typical spacings
CHUNK = 16384  # points a chunk: its (k, chunk) temporaries stay in a core's cache
# A one-sided fit on a curved surface tilts the normal by about half the stepover
# times the curvature; planning takes the normal this much steeper (a larger
# R_eff, a lower required speed), so vc stays under its target there.
ONE_SIDED_TILT_DEG = 3.0


@dataclass(frozen=True)
class PathNormals:
    """Normals per point and how far to trust them.

    normal : (m, 3) unit normals toward the tool
    confidence : (m,) int8, CONFIDENT (passes on both sides), ONE_SIDED, NO_CROSS
    stepover_mm : median distance to the nearest other pass (nan if none)
    """

    normal: np.ndarray
    confidence: np.ndarray
    stepover_mm: float


def path_normals(centers_mm: np.ndarray, path_mm: np.ndarray, cutting: np.ndarray,
                 k: int = K_NEIGHBOURS, workers: int = -1,
                 axis: np.ndarray | None = None, end_order: int = 1,
                 curved: bool = False, balanced: bool = False) -> PathNormals:
    """Estimate surface normals at cutter-centre points.

    Parameters
    ----------
    centers_mm : (m, 3) cutter centres in path order, mm
    path_mm : (m,) cumulative path length at each point, mm
    cutting : (m,) bool, points on cutting moves (only these are neighbours)
    workers : threads for the neighbour search and the fit (-1: every CPU available)
    axis : (m, 3) unit tool axes (5 axes), or None for +Z
    end_order : 1, where the path breaks the tangent is the chord to the one neighbour
        (it leans by half the turn over that step: 0.44 deg on 1 mm steps round a 65 mm
        radius); 2, the derivative of the parabola through the next two points
        (:func:`second_order_ends`), where they follow on the path
    curved : refit the confident normals with the surface's curvature
        (:func:`ncopt.contacts.curvedfit.curved_normals`)
    balanced : fit to the ``k // 2`` nearest other-pass neighbours on each side of the
        pass, out of the ``2 k`` nearest points (the ``k`` nearest alone are all on the
        point's own pass where the points lie much closer than the passes: the boat
        hulls of LinuxCNC's 5-axis demos, 0.4-1 mm blocks 2.2 mm apart, left 6 % of their
        points with no cross-slope, planned at the cutter's full radius)
    """
    m = centers_mm.shape[0]
    if axis is None:
        normal = np.zeros((m, 3))
        normal[:, 2] = 1.0
    else:
        normal = axis.copy()
    confidence = np.zeros(m, dtype=np.int8)
    idx = np.flatnonzero(cutting)
    if idx.size < 2:
        return PathNormals(normal, confidence, float("nan"))
    whole = idx.size == m  # every point is fitted (most programs): slices, no copies
    pts = np.ascontiguousarray(centers_mm) if whole else np.take(centers_mm, idx, axis=0)
    s = path_mm if whole else np.take(path_mm, idx)
    threads = available_cpus() if workers == -1 else workers
    kk = min(2 * k + 1 if balanced else k + 1, idx.size)
    sp = _searchable(pts, s, axis if axis is None or whole else axis[idx], end_order,
                     balanced or curved, threads)

    def chunk(a: int) -> np.ndarray:  # bounded temporaries: (k, chunk) at a time
        at, n, conf, closest = _fit_chunk(sp, a, min(a + CHUNK, idx.size), kk,
                                          k // 2 if balanced else None, curved)
        rows = at if whole else idx[at]
        normal[rows] = n
        confidence[rows] = conf
        return closest

    # each thread queries and fits its own chunks: scipy's query and numpy's loops
    # release the GIL, so the fit of one chunk overlaps the query of the next
    near = np.concatenate(map_in_threads(chunk, range(0, idx.size, CHUNK), threads))
    finite = np.isfinite(near)
    stepover = float(np.median(near[finite])) if finite.any() else float("nan")
    return PathNormals(normal, confidence, stepover)


class _Searchable(NamedTuple):
    """The fitted points as the chunks read them, in the path's order: ``pts`` (M, 3),
    ``s`` (M,), ``xyz`` (3, M) (:func:`ncopt.contacts.pathfit.by_rank`), ``u``, ``v``
    (M, 3) (their :func:`ncopt.contacts.pathfit.frame`), ``tangent`` and ``up`` (M, 3)
    or None."""

    tree: object
    pts: np.ndarray
    s: np.ndarray
    xyz: np.ndarray
    u: np.ndarray
    v: np.ndarray
    tangent: np.ndarray | None
    up: np.ndarray | None


def _searchable(pts: np.ndarray, s: np.ndarray, up: np.ndarray | None, end_order: int,
                keep_tangent: bool, threads: int) -> _Searchable:
    """The k-d tree of the fitted points ``pts`` (path lengths ``s``, tool axes ``up``)
    and their frames across the pass (:class:`_Searchable`)."""
    def along() -> tuple:  # the frames across the pass and the tangents
        tangent = _tangents(pts, s)
        if end_order == 2:
            tangent = second_order_ends(pts, s, tangent)
        # the tangents are kept for the balanced and curved fits only (24 MB at 1M points)
        return (*frame(tangent, up), tangent if keep_tangent else None)

    # the tree's build releases the GIL (0.3 s at 1M points): the rest is found meanwhile
    tree, (u, v, tangent), xyz = map_in_threads(
        lambda job: job(), (lambda: cKDTree(pts), along, lambda: by_rank(pts)), threads)
    return _Searchable(tree, pts, s, xyz, u, v, tangent, up)


def _fit_chunk(sp: _Searchable, a: int, b: int, kk: int, per_side: int | None, curved: bool):
    """Points ``a:b``: their normals, confidences and distances to the nearest other pass
    (``per_side``: the balanced fit's neighbours on each side, None for the plain fit)."""
    dist, nb = sp.tree.query(sp.pts[a:b], k=kk, workers=1)
    dist, nb = by_rank(np.atleast_2d(dist)[:, 1:]), by_rank(np.atleast_2d(nb)[:, 1:])
    at = slice(a, b)

    def here(rows: np.ndarray | None) -> np.ndarray | None:
        return None if rows is None else rows[at]

    pts, up, tangent = sp.pts[a:b], here(sp.up), here(sp.tangent)
    other = other_pass(sp.s, a, nb, dist)
    if per_side is not None:
        other &= _balanced(pts, tangent, sp.pts, nb.T, other.T, up, per_side).T
    n, conf, closest = fit_cross(pts, here(sp.u), here(sp.v), sp.xyz, nb, dist, other, up)
    if curved:
        n = curved_normals(pts, tangent, sp.pts, nb.T, dist.T, other.T, n, conf == CONFIDENT)
    return at, n, conf, closest


def _tangents(pts: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Unit along-path tangents: central differences, one-sided at breaks."""
    unit = np.diff(pts, axis=0)
    seg = row_norms(unit)
    jump = np.diff(s)
    jump -= seg
    np.abs(jump, out=jump)
    bad = jump > 1e-6  # not consecutive on the path
    bad |= seg < 1e-9
    np.maximum(seg, 1e-12, out=seg)
    unit /= seg[:, None]
    unit[bad] = 0.0
    if not np.isfinite(seg).all():  # an overflow (inf / inf): as nan_to_num did
        np.nan_to_num(unit, copy=False)
    # the sum of the unit steps before and after each point, a missing one zero (the
    # ends add 0.0 too: the same bits, signed zeros included)
    t = np.empty((pts.shape[0], 3))
    t[0] = 0.0
    t[1:] = unit
    t[:-1] += unit
    t[-1] += 0.0
    norm = row_norms(t)
    t /= np.maximum(norm, 1e-12)[:, None]
    t[norm < 1e-9] = [1.0, 0.0, 0.0]
    return t


def second_order_ends(pts: np.ndarray, s: np.ndarray, tangent: np.ndarray) -> np.ndarray:
    """``tangent`` (m, 3) with the points that follow on the path on one side only (a
    break on the other, as :func:`_tangents` finds them) given the one-sided second-order
    tangent: the derivative at the point of the parabola through it and the next two
    points on that side (exact on a circle to second order in the step), where both
    follow on the path; the others keep theirs."""
    d = np.diff(pts, axis=0)
    seg = row_norms(d)
    link = (np.abs(np.diff(s) - seg) <= 1e-6) & (seg >= 1e-9)  # as _tangents' steps
    m = pts.shape[0]
    out = tangent.copy()
    if m < 3:
        return out
    prev_ok = np.concatenate(([False], link))
    next_ok = np.concatenate((link, [False]))
    two_after = np.zeros(m, bool)
    two_after[:-2] = link[:-1] & link[1:]
    two_before = np.zeros(m, bool)
    two_before[2:] = link[:-1] & link[1:]
    for rows, sign in ((np.flatnonzero(~prev_ok & next_ok & two_after), 1),
                       (np.flatnonzero(prev_ok & ~next_ok & two_before), -1)):
        if rows.size == 0:
            continue
        p0, p1, p2 = pts[rows], pts[rows + sign], pts[rows + 2 * sign]
        h1 = seg[rows if sign > 0 else rows - 1]
        h2 = seg[rows + 1 if sign > 0 else rows - 2]
        # d/dx at x = 0 of the parabola through (0, p0), (h1, p1), (h1 + h2, p2)
        w0 = -(2.0 * h1 + h2) / (h1 * (h1 + h2))
        w1 = (h1 + h2) / (h1 * h2)
        w2 = -h1 / (h2 * (h1 + h2))
        t = sign * (w0[:, None] * p0 + w1[:, None] * p1 + w2[:, None] * p2)
        norm = row_norms(t)
        good = norm > 1e-12
        out[rows[good]] = t[good] / norm[good, None]
    return out


def _balanced(pts, tangent, all_pts, nb, other, axis, per_side: int) -> np.ndarray:
    """(m, k) bool: of the other passes' neighbours, the ``per_side`` nearest on each side
    of the pass (across it, as :func:`ncopt.contacts.pathfit.fit_cross` measures across)."""
    up = np.array([0.0, 0.0, 1.0]) if axis is None else axis
    u = np.cross(tangent, up)
    vertical = row_norms(u) < 1e-6
    u[vertical] = [1.0, 0.0, 0.0] if axis is None else across(axis[vertical])
    off = np.take(all_pts, nb, axis=0)
    off -= pts[:, None, :]
    side = np.einsum("mkj,mj->mk", off, u) > 0.0
    keep = np.zeros(other.shape, dtype=bool)
    for this in (side, ~side):
        on = other & this
        keep |= on & (np.cumsum(on, axis=1) <= per_side)
    return keep


def contacts_from_path(centers_mm: np.ndarray, path_mm: np.ndarray, cutting: np.ndarray,
                       cutter: Cutter, axis: np.ndarray | None = None
                       ) -> tuple[Contacts, PathNormals]:
    """Contacts (CC point, normal, R_eff) from the toolpath alone; ``axis`` (m, 3) the
    tool axis per point (None: +Z)."""
    est = path_normals(centers_mm, path_mm, cutting, axis=axis)
    m = centers_mm.shape[0]
    cc, r_eff = np.empty((m, 3)), np.empty(m)

    def part(a: int) -> None:  # row by row: chunks in threads give the same bits
        b = min(a + CHUNK, m)
        normal = est.normal[a:b]
        cc[a:b] = centers_mm[a:b] - cutter.corner_radius_mm * normal
        tilt = np.where(est.confidence[a:b] == ONE_SIDED, np.radians(ONE_SIDED_TILT_DEG), 0.0)
        ax = None if axis is None else axis[a:b]
        r_eff[a:b] = r_eff_mm(cutter, tilt_from_axis(normal, tilt, ax), ax)

    map_in_threads(part, range(0, m, CHUNK), available_cpus())
    return Contacts(cc_mm=cc, normal=est.normal, r_eff_mm=r_eff, cutting=cutting.copy()), est


def tilt_from_axis(normal: np.ndarray, angle_rad: np.ndarray,
                   axis: np.ndarray | None = None) -> np.ndarray:
    """Normals turned away from the tool axis (+Z, or ``axis`` (m, 3)) by ``angle_rad``
    in the plane of both."""
    if axis is not None:
        c = np.clip(np.einsum("ij,ij->i", normal, axis), -1.0, 1.0)
        side = normal - c[:, None] * axis
        hn = row_norms(side)
        side = np.where(hn[:, None] > 1e-12, side / np.maximum(hn, 1e-12)[:, None],
                        across(axis))
        polar = np.arccos(c) + angle_rad
        return np.cos(polar)[:, None] * axis + np.sin(polar)[:, None] * side
    polar = np.arccos(np.clip(normal[:, 2], -1.0, 1.0)) + angle_rad
    horiz = normal[:, :2]
    hn = np.sqrt(horiz[:, 0] * horiz[:, 0] + horiz[:, 1] * horiz[:, 1])  # linalg.norm's bits
    direction = np.where(hn[:, None] > 1e-12, horiz / np.maximum(hn, 1e-12)[:, None], [1.0, 0.0])
    out = np.empty_like(normal)
    out[:, :2] = direction * np.sin(polar)[:, None]
    out[:, 2] = np.cos(polar)
    return out
