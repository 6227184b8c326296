"""Mesh-free normals where a run of 5-axis cuts begins and ends.

Each toolpath point stands for the move that ends there; a run of cuts is a stretch of
consecutive cutting moves.  A 5-axis finishing pass is entered and left along short moves
(lead-in and lead-out ramps) that touch the part only near the pass: a ramp leaves the
surface at a few degrees and stays within the contact tolerance for a few tenths of a mm.
From the ball centres alone (:mod:`ncopt.contacts.pathnormals`) such a move corrupted the
normals: the lead-out's far end, in the air, was fitted as if on the surface, bent the
tangent of the pass's last point by half the ramp's angle (4 deg on the 8.5 deg ramps of
bench/make_5axis.py) and served as a neighbour of the other passes' ends (0.3 mm above
them, it tilts their cross-slope).  With the tool axis turning a few degrees a block the
error in R_eff reached -6 % at a pass end (vc +2.2 % on the flowline bowl in 2 mm blocks).

Here, in every run of at least :data:`MIN_RUN_POINTS` points:

* the last point (the lead-out's far end) is left out of the fit, and the points beside
  a break take the one-sided second-order tangent (``path_normals(end_order=2)``);
* the lead-out's far end takes the normal where the move stops touching: its pass end's
  normal turned on as from the point before, over the length that can touch (the whole
  move where it runs along the surface, ``2 LEAVE_TOL_MM / sin(angle)`` where it leaves at
  an angle, at most one step of the pass);
* the run's first point (the lead-in's end, on the part) is planned alone for its move:
  it is turned away from the tool axis by what the lead-in's contact adds, found the same
  way backward along the lead-in.

Both ends of every run keep a margin of :data:`RUN_END_MARGIN_DEG`.  The normals are fitted
with as many neighbours on each side of a pass and the curvature
(:mod:`ncopt.contacts.curvedfit`).
"""

from __future__ import annotations

import numpy as np

from ncopt.contacts.pathnormals import PathNormals, path_normals

# A run of cuts this long has its end moves treated here (shorter ones: their last point
# takes the normal before it)
MIN_RUN_POINTS = 4
# How far a move that leaves the surface can touch it: the contact tolerance (mm) the
# planner and simulate use by default (Job.contact_tol_mm)
LEAVE_TOL_MM = 0.05
# An end move that rises from the pass's tangent plane by less than this (deg) runs along
# the surface: it may touch all the way
LEAVE_MIN_DEG = 0.5
# The first and last point of every run of cuts are planned with their normal turned
# this much (deg) farther from the tool axis, for what the estimate there cannot see
RUN_END_MARGIN_DEG = 0.1


def end_normals(centres: np.ndarray, cutting: np.ndarray,
                axis: np.ndarray) -> tuple[PathNormals, np.ndarray]:
    """Path normals of the ball centres (m, 3) on the ``cutting`` points (each the end
    of a cutting move), with the ends of runs of cuts as the module says, and (m,) the
    angle (rad) each point's normal is to be turned away from the tool axis ``axis`` (m,
    3) for planning: :data:`RUN_END_MARGIN_DEG` at the first and last point of every run,
    and what the contact along an end move adds to the angle between normal and axis."""
    step = np.linalg.norm(np.diff(centres, axis=0), axis=1)
    path = np.concatenate(([0.0], np.cumsum(step)))
    before = np.concatenate(([False], cutting[:-1]))
    after = np.concatenate((cutting[1:], [False]))
    first, last = cutting & ~before, cutting & ~after
    run = np.cumsum(first) - 1
    size = np.bincount(run[cutting], minlength=max(int(first.sum()), 1))
    long_run = cutting & (size[np.maximum(run, 0)] >= MIN_RUN_POINTS)
    ends = np.flatnonzero(last & long_run)
    short_last = last & before & ~long_run
    fitted = cutting & ~short_last
    fitted[ends] = False
    est = path_normals(centres, path, fitted, axis=axis, end_order=2,
                       balanced=True, curved=True)
    inner = np.flatnonzero(short_last)
    est.normal[inner] = est.normal[inner - 1]
    est.confidence[inner] = est.confidence[inner - 1]  # and as far as that one is trusted
    tilt = np.where(first | last, np.radians(RUN_END_MARGIN_DEG), 0.0)
    # a lead-out: its far end, off the part, takes the normal where it stops touching
    zone, e_zone = _zone(est.normal, centres, axis, ends, ends - 1, ends - 2)
    est.normal[ends] = zone
    est.confidence[ends] = est.confidence[ends - 1]
    tilt[ends] += np.maximum(_angle(zone, e_zone) - _angle(zone, axis[ends]), 0.0)
    # a lead-in is planned at its end alone: that point covers the turn along it
    starts = np.flatnonzero(first & long_run)
    starts = starts[(starts > 0) & np.isfinite(centres[starts - 1]).all(axis=1)]
    zone, e_zone = _zone(est.normal, centres, axis, starts - 1, starts, starts + 1)
    grow = _angle(zone, e_zone) - _angle(est.normal[starts], axis[starts])
    tilt[starts] += np.maximum(grow, 0.0)
    return est, tilt


def _zone(normal: np.ndarray, centres: np.ndarray, axis: np.ndarray, far: np.ndarray,
          joint: np.ndarray, inner: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where an end move from ``joint`` (on the pass) to ``far`` stops touching the part:
    the normal there, ``joint``'s turned on as from ``inner`` (the next point inside) to
    ``joint``, and the tool axis there (both (k, 3), unit; module docstring)."""
    d = centres[far] - centres[joint]
    length = np.linalg.norm(d, axis=1)
    n_joint = normal[joint]
    rise = np.einsum("ij,ij->i", d, n_joint) / np.maximum(length, 1e-12)
    leaves = rise > np.sin(np.radians(LEAVE_MIN_DEG))
    reach = np.where(leaves, np.minimum(length, 2.0 * LEAVE_TOL_MM / np.where(leaves, rise, 1.0)),
                     length)
    h = np.linalg.norm(centres[joint] - centres[inner], axis=1)
    reach = np.minimum(reach, h)  # a longer move: its far side is beyond what the pass shows
    turned = n_joint + (n_joint - normal[inner]) * (reach / np.maximum(h, 1e-12))[:, None]
    share = (reach / np.maximum(length, 1e-12))[:, None]
    e = axis[joint] + (axis[far] - axis[joint]) * share
    return _unit(turned), _unit(e)


def _angle(n: np.ndarray, e: np.ndarray) -> np.ndarray:
    """(k,) angle (rad) between unit rows."""
    return np.arccos(np.clip(np.einsum("ij,ij->i", n, e), -1.0, 1.0))


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=1), 1e-12)[:, None]
