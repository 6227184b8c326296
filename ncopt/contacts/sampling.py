"""Where the planner queries the mesh: at every block end, and inside a block only where
the geometry asks for it.

A block's requirement is the lowest required speed anywhere along it (docs/method.md,
"Contacts with a mesh"): the largest effective radius ``R_eff`` along it, not only at its ends.
Sampling every move every millimetre makes the cost grow with the path length, misses
what happens between samples of long blocks (on a wavy part with 6 mm blocks, 1 mm
samples put the requirement 1.9 % above the one every 0.1 mm gives) and lets a single
1e9 mm move ask for 1e9 samples.  Instead, along each run of planned moves (consecutive
selected moves: a continuous path):

1. every CL point of the run is queried (the ends of its blocks);
2. the interval between two neighbouring samples is halved, level by level, while

   * both ends cut, and it is longer than ``coarse_mm`` or the interpolation error of
     ``R_eff``, estimated as ``|R_eff''| h^2 / 8`` from the smaller of the second
     differences at its two ends (both see a curve inside it; a kink at one end bends
     one side only), exceeds ``rel_tol`` of ``R_eff`` (+ ``abs_tol_mm``).
     Below ``r_floor_mm`` the requirement is capped at the machine's S_max, so
     ``R_eff`` counts as ``r_floor_mm`` there and the flat bottom of a part costs
     nothing;
   * one end cuts and the other does not (where the contact starts or ends);
   * neither end cuts but the tool could touch in between.  The distance to the mesh
     changes by at most the distance moved (it is 1-Lipschitz), so with clearances
     ``g_a, g_b`` at the ends the clearance inside is at least ``(g_a + g_b - h) / 2``:
     where that exceeds the contact tolerance the interval is air throughout, however
     long (a 1e9 mm move past the part costs a few dozen queries);

   and never into pieces shorter than ``fine_mm``.

So the samples are bounded by the blocks and by the length of path that lies along the
part, not by the length of a move.  Accuracy, measured against querying every 0.1 mm
(``tests/unit/test_sampling.py``), every block's required S capped to the machine's
range: sample bowl (0.75 mm blocks, 0.8 mm mesh) within 0.34 %, a wavy part with 3 and
6 mm blocks within 0.2 %.  A feature narrower than the spacing of the samples that none
of them sees can be missed, as by any sampling; the surface a ball's centre follows over
a convex part has no radius below the ball's.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ncopt.motion.modal import sorted_unique

# at most this many levels of halving: a 1e9 mm move halves down to 0.1 mm in 34
MAX_LEVELS = 64


@dataclass(frozen=True)
class Refinement:
    """How densely the mesh is queried (module docstring).

    coarse_mm : longest interval between samples where the tool cuts, mm
    fine_mm : no interval is halved into pieces shorter than this, mm
    rel_tol : allowed interpolation error of R_eff between samples, relative
    abs_tol_mm : and absolute, mm
    r_floor_mm : R_eff below this counts as this (the requirement is capped at S_max)
    contact_tol_mm : clearance up to which the tool touches, mm
    """

    coarse_mm: float = 1.0
    fine_mm: float = 0.1
    rel_tol: float = 0.003
    abs_tol_mm: float = 1e-4
    r_floor_mm: float = 0.0
    contact_tol_mm: float = 0.05


@dataclass(frozen=True)
class Probe:
    """What a query of the mesh gives per point: (k,) or (k, 3) arrays.

    r_eff_mm, normal, cc_mm, cutting : as in :class:`ncopt.model.Contacts`
    gap_low_mm : a lower bound of the tool's clearance from the part, mm
    gap_mm : the clearance as the query found it, mm (< 0 inside the part)
    """

    r_eff_mm: np.ndarray
    normal: np.ndarray
    cc_mm: np.ndarray
    gap_low_mm: np.ndarray
    cutting: np.ndarray
    gap_mm: np.ndarray

    def columns(self) -> tuple:
        return (self.r_eff_mm, self.normal, self.cc_mm, self.gap_low_mm, self.cutting,
                self.gap_mm)

    def take(self, rows: np.ndarray) -> "Probe":
        return Probe(*(a[rows] for a in self.columns()))


@dataclass(frozen=True)
class Samples:
    """Every CL point and every point queried inside a move, in path order, (m,) arrays.

    point : index of the toolpath point whose move the sample lies on (the CL point
        itself at fraction 1)
    frac : how far along that move, (0, 1]
    probe : the values at each sample; CL points of moves not planned (and not the
        start of one) are not queried: not cutting, R_eff 0
    queried : the mesh was queried there
    """

    point: np.ndarray
    frac: np.ndarray
    probe: Probe
    queried: np.ndarray


@dataclass
class _Anchors:
    """Queried samples in path order: move ``p``, fraction ``f``, path length ``s``."""

    p: np.ndarray
    f: np.ndarray
    s: np.ndarray
    run: np.ndarray
    probe: Probe | None


def adaptive_samples(xyz_mm: np.ndarray, selected: np.ndarray,
                     query: Callable[[np.ndarray], Probe], ref: Refinement) -> Samples:
    """Samples of the moves ``selected`` and their start points (module docstring).

    Parameters
    ----------
    xyz_mm : (n, 3) the points to query along the toolpath (ball or torus centres), mm
    selected : (n,) bool, the move ending at each point is planned
    query : points (k, 3) -> Probe
    ref : Refinement
    """
    chord = np.concatenate(([0.0], np.linalg.norm(np.diff(xyz_mm, axis=0), axis=1)))
    path = np.cumsum(chord)
    sel = np.asarray(selected, dtype=bool).copy()
    sel[:1] = False
    anchors = _cl_points(path, sel)
    anchors.probe = query(np.take(xyz_mm, anchors.p, axis=0))  # take: rows 4x faster
    near = None
    for _ in range(MAX_LEVELS):
        k, move, frac = _splits(anchors, ref, near)
        if k.size == 0:
            break
        start = np.take(xyz_mm, move - 1, axis=0)
        _insert(anchors, k, move, frac, path[move - 1] + frac * chord[move],
                query(start + (np.take(xyz_mm, move, axis=0) - start) * frac[:, None]))
        near = _around(k + 1 + np.arange(k.size), anchors.p.size - 1)
    return _with_other_points(anchors, xyz_mm, sel)


def _around(new: np.ndarray, n_intervals: int) -> np.ndarray:
    """The intervals whose verdict the new samples (indices ``new``) can change.

    Interval ``i`` is judged from samples ``i - 1 .. i + 2`` only (:func:`_splits`), and
    every interval judged to need it was halved: all others stay as they were, so each
    level after the first looks at the intervals ``j - 2 .. j + 1`` of its new samples
    ``j`` only (the dense bench case: 1M samples, then 17, 1, 1, 1 new ones).
    """
    i = (new[:, None] + np.arange(-2, 2)).ravel()
    # (numpy 2.4's hashed unique took 10 times as long on such nearly sorted indices)
    return sorted_unique(np.sort(i[(i >= 0) & (i < n_intervals)]))


def _cl_points(path: np.ndarray, sel: np.ndarray) -> _Anchors:
    """The CL points of the runs of selected moves, with their run numbers."""
    run_of = np.cumsum(sel & ~np.concatenate(([False], sel[:-1])))
    starts = np.concatenate((sel[1:], [False]))  # the point a selected move starts from
    pts = np.flatnonzero(sel | starts)
    run = np.where(sel[pts], run_of[pts], run_of[np.minimum(pts + 1, sel.size - 1)])
    return _Anchors(pts.astype(np.int64), np.ones(pts.size), path[pts], run, None)


def _effective(anchors: _Anchors, ref: Refinement) -> np.ndarray:
    return np.maximum(anchors.probe.r_eff_mm, ref.r_floor_mm)


def _curvature(anchors: _Anchors, ref: Refinement) -> np.ndarray:
    """|R_eff''| at each sample from its two neighbours (NaN where unknown)."""
    r, s, cut, run = _effective(anchors, ref), anchors.s, anchors.probe.cutting, anchors.run
    h = np.diff(s)
    with np.errstate(divide="ignore", invalid="ignore"):
        d2 = 2.0 * np.diff(np.diff(r) / h) / (h[:-1] + h[1:])
    ok = (run[:-2] == run[1:-1]) & (run[1:-1] == run[2:]) & cut[:-2] & cut[1:-1] & cut[2:]
    ok &= (h[:-1] > 0) & (h[1:] > 0)
    return np.concatenate(([np.nan], np.where(ok, np.abs(d2), np.nan), [np.nan]))


def _splits(anchors: _Anchors, ref: Refinement, near: np.ndarray | None = None) -> tuple:
    """Intervals to halve: index of their first sample, the move their second lies on,
    and the fraction of that move at their middle.  ``near``: of these intervals only
    (sorted), judged on the samples around them; None: all."""
    if near is not None:
        rows = (near[:, None] + np.arange(-1, 3)).ravel()
        rows = sorted_unique(np.sort(rows[(rows >= 0) & (rows < anchors.p.size)]))
        k, move, frac = _splits(_Anchors(anchors.p[rows], anchors.f[rows], anchors.s[rows],
                                         anchors.run[rows], anchors.probe.take(rows)), ref)
        k_full = rows[k]  # a pair of rows that are neighbours in the whole is an interval
        at = np.minimum(np.searchsorted(near, k_full), near.size - 1)
        keep = (rows[k + 1] == k_full + 1) & (near[at] == k_full)  # np.isin, by bisection
        return k_full[keep], move[keep], frac[keep]
    pr, h = anchors.probe, np.diff(anchors.s)
    a_cut, b_cut = pr.cutting[:-1], pr.cutting[1:]
    # curved inside only where both ends see it: a kink at an end bends one side only
    worst = _curvature(anchors, ref)
    worst = np.fmin(worst[:-1], worst[1:])
    r = _effective(anchors, ref)
    allowed = ref.rel_tol * np.minimum(r[:-1], r[1:]) + ref.abs_tol_mm
    with np.errstate(invalid="ignore"):
        rough = np.isnan(worst) | (worst * h * h / 8.0 > allowed)
    touch = pr.gap_low_mm[:-1] + pr.gap_low_mm[1:] - h <= 2.0 * ref.contact_tol_mm
    need = (a_cut & b_cut & (rough | (h > ref.coarse_mm))) | (a_cut != b_cut)
    need |= ~a_cut & ~b_cut & touch
    k = np.flatnonzero(need & (h >= 2.0 * ref.fine_mm) & (anchors.run[:-1] == anchors.run[1:]))
    move = anchors.p[k + 1]
    before = np.where(anchors.p[k] == move, anchors.f[k], 0.0)
    return k, move, 0.5 * (before + anchors.f[k + 1])


def _insert(anchors: _Anchors, k, move, frac, s, probe: Probe) -> None:
    """Insert the middles of intervals ``k`` (distinct) after their first samples."""
    at = k + 1
    into = _Gaps(at, anchors.p.size)
    anchors.p = into.fill(anchors.p, move)
    anchors.f = into.fill(anchors.f, frac)
    anchors.s = into.fill(anchors.s, s)
    anchors.run = into.fill(anchors.run, anchors.run[k])
    anchors.probe = Probe(*(into.fill(a, b)
                            for a, b in zip(anchors.probe.columns(), probe.columns())))


class _Gaps:
    """Where ``np.insert(a, at, rows, axis=0)`` puts the rows of ``a`` (length ``n``) and
    the new ones, for sorted ``at``: worked out once for all the columns of the samples
    (np.insert masks every row of every column: 9 ms a column at 1M rows), a few rows
    by slices."""

    def __init__(self, at: np.ndarray, n: int) -> None:
        self.at, self.n = at, n
        self.new = at + np.arange(at.size)  # np.insert's places for sorted indices
        self.old = None
        if at.size > 64:
            old = np.ones(n + at.size, dtype=bool)
            old[self.new] = False
            self.old = np.flatnonzero(old)  # by index: a mask took 3x as long for (m, 3) rows

    def fill(self, a: np.ndarray, rows) -> np.ndarray:
        """``np.insert(a, at, rows, axis=0)``: the same values (``rows`` cast to a's type)."""
        out = np.empty((self.n + self.at.size, *a.shape[1:]), dtype=a.dtype)
        if self.old is None:
            rows = np.broadcast_to(np.asarray(rows, dtype=a.dtype),
                                   (self.at.size, *a.shape[1:]))
            lo = 0
            for i, j in enumerate(self.at.tolist()):
                out[lo + i:j + i] = a[lo:j]
                out[j + i] = rows[i]
                lo = j
            out[lo + self.at.size:] = a[lo:]
            return out
        out[self.new] = rows
        out[self.old] = a
        return out


def _with_other_points(anchors: _Anchors, xyz_mm: np.ndarray, sel: np.ndarray) -> Samples:
    """The queried samples and, not cutting, the CL points no planned move touches."""
    n = xyz_mm.shape[0]
    other = np.ones(n, dtype=bool)
    other[anchors.p[anchors.f >= 1.0]] = False
    rest = np.flatnonzero(other)
    nothing = Probe(np.zeros(rest.size), np.tile([0.0, 0.0, 1.0], (rest.size, 1)),
                    xyz_mm[rest], np.full(rest.size, np.inf), np.zeros(rest.size, dtype=bool),
                    np.full(rest.size, np.inf))
    at = np.searchsorted(anchors.p, rest, side="right")  # after the samples on its move
    into = _Gaps(at, anchors.p.size)
    probe = Probe(*(into.fill(a, b) for a, b in zip(anchors.probe.columns(),
                                                     nothing.columns())))
    return Samples(into.fill(anchors.p, rest), into.fill(anchors.f, 1.0), probe,
                   into.fill(np.ones(anchors.p.size, bool), False))
