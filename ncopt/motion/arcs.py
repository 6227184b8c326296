"""Arcs (G2/G3) as points within a chord tolerance, with their exact lengths; the centre
from I J K or from R, checked as LinuxCNC checks it."""

from __future__ import annotations

import math

import numpy as np

from ncopt.model import MM_PER_INCH
from ncopt.motion.checks import fail
from ncopt.reading.refuse import MIN_ARC_RADIUS_MM

_PLANE_AXES = {170: (0, 1, 2), 180: (2, 0, 1), 190: (1, 2, 0)}


def arc_points(prog, lines, modal, i, p0, p1, tol_mm):
    """Points and exact lengths of the arc on line i from p0 to p1 (mm)."""
    a, b, c = _PLANE_AXES.get(int(modal.plane[i]), (0, 1, 2))
    scale = MM_PER_INCH if modal.inch[i] else 1.0
    off = np.nan_to_num(np.array([lines.value_at(k, i) * scale for k in "IJK"]))
    has_ijk = any(lines.present_at(k, i) for k in "IJK")
    cw = modal.motion[i] == 20
    if lines.present_at("R", i) and not has_ijk:
        center = _center_from_r(prog, i, modal, p0, p1, lines.value_at("R", i) * scale, cw, a, b)
    elif has_ijk:
        center = off.copy() if modal.arc_absolute[i] else p0 + off
    else:
        fail(prog, i, "arc with none of I, J, K or R; give the centre or the radius")
    u0, v0 = p0[a] - center[a], p0[b] - center[b]
    u1, v1 = p1[a] - center[a], p1[b] - center[b]
    r0, r1 = math.hypot(u0, v0), math.hypot(u1, v1)
    if min(r0, r1) < MIN_ARC_RADIUS_MM * (1.0 - 1e-9):
        where = "start" if r0 < r1 else "end"
        fail(prog, i, f"zero-radius arc: the centre is on the {where} point (radius "
             f"{min(r0, r1):.4f} mm); correct I, J, K (LinuxCNC refuses it: \"Zero-radius arc\")")
    # LinuxCNC's tolerance: 2*0.01 mm*sqrt2 (2*0.001 inch*sqrt2) and 0.1 % relative
    t_abs = 2 * math.sqrt(2) * (0.001 * MM_PER_INCH if modal.inch[i] else 0.01)
    err = abs(r0 - r1)
    if err > 100 * t_abs or (err > t_abs and err / max(r0, r1) > 0.001):
        fail(prog, i, f"radius to end of arc differs from radius to start "
             f"({r0:.4f} vs {r1:.4f} mm); correct the arc centre or end point")
    t0, t1 = math.atan2(v0, u0), math.atan2(v1, u1)
    sweep = (t0 - t1) if cw else (t1 - t0)
    sweep %= 2 * math.pi
    if sweep < 1e-12:
        sweep = 2 * math.pi
    turns = lines.value_at("P", i)
    if not np.isnan(turns) and turns > 1:
        sweep += 2 * math.pi * (int(turns) - 1)
    r = max(r0, 1e-9)
    step = 2 * math.acos(max(1 - tol_mm / r, -1.0)) if tol_mm < r else math.pi / 2
    n = max(int(math.ceil(sweep / max(step, 1e-6))), 1)
    n = min(n, 100000)
    t = t0 + (-1 if cw else 1) * sweep * np.arange(1, n + 1) / n
    pts = np.empty((n, 3))
    pts[:, a] = center[a] + r * np.cos(t)
    pts[:, b] = center[b] + r * np.sin(t)
    pts[:, c] = p0[c] + (p1[c] - p0[c]) * np.arange(1, n + 1) / n
    pts[-1] = p1
    length = math.hypot(r * sweep, p1[c] - p0[c]) / n
    return pts, np.full(n, length)


def _center_from_r(prog, i, modal, p0, p1, radius, cw, a, b):
    du, dv = p1[a] - p0[a], p1[b] - p0[b]
    chord = math.hypot(du, dv)
    if chord < 1e-12:
        fail(prog, i, "R-format arc with identical start and end point; use I/J/K")
    r = abs(radius)
    # a half circle whose printed end point is a hair too far: the LinuxCNC interpreter
    # allows the half chord to exceed R by 0.0001 inch (its TOLERANCE_EQUAL)
    if chord / 2 > r + 0.0001 * MM_PER_INCH:
        fail(prog, i, f"arc radius {r:.4f} mm is too small for the chord {chord:.4f} mm; "
             "correct R or the end point")
    r = max(r, chord / 2)
    h = math.sqrt(max(r * r - chord * chord / 4, 0.0))
    # the centre lies left of the chord for CCW short arcs; R < 0 asks for the long arc
    sign = (1 if not cw else -1) * (1 if radius > 0 else -1)
    center = np.array(p0, dtype=float)
    center[a] = p0[a] + du / 2 - sign * h * dv / chord
    center[b] = p0[b] + dv / 2 + sign * h * du / chord
    return center


def _column(lines, letter: str, at: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(values, present) of ``letter`` on the lines ``at`` (NaN, False where absent)."""
    column = lines.letters.get(letter)
    if column is None:
        return np.full(at.shape[0], np.nan), np.zeros(at.shape[0], dtype=bool)
    return column[0][at], column[1][at]


def _each(fn, *args) -> np.ndarray:
    """``fn`` (a math function) on each element: the same bits as :func:`arc_points`'s
    scalar calls (math.hypot is not libm's hypot)."""
    return np.array([fn(*xs) for xs in zip(*(a.tolist() for a in args))], dtype=np.float64)


# arcs worked out together at most (arcs_points): their temporaries bounded
ARC_CHUNK = 65536


def arcs_points(prog, lines, modal, at: np.ndarray, p0: np.ndarray, p1: np.ndarray,
                tol_mm: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`arc_points` for many arcs at once: the arcs on lines ``at`` (k,) from ``p0``
    to ``p1`` ((k, 3) mm).  Returns (points per arc (k,), points (sum, 3), lengths (sum,)),
    bit for bit what :func:`arc_points` gives arc by arc (tested); an arc it would refuse
    is refused by it, with its message, the first such arc in program order.

    Every arc is worked out on its own, so they go ``ARC_CHUNK`` at a time: the same
    values, and the temporaries of a million arcs (some thirty arrays of them) are not
    all held at once (1M arcs: 1.08 GB at the interpretation's peak, against 0.51 GB for the
    same path in straight moves)."""
    k = at.shape[0]
    if k <= ARC_CHUNK:
        return _arcs_points(prog, lines, modal, at, p0, p1, tol_mm)
    parts = [_arcs_points(prog, lines, modal, at[i:i + ARC_CHUNK], p0[i:i + ARC_CHUNK],
                          p1[i:i + ARC_CHUNK], tol_mm) for i in range(0, k, ARC_CHUNK)]
    return tuple(np.concatenate([part[j] for part in parts]) for j in range(3))


def _arcs_points(prog, lines, modal, at: np.ndarray, p0: np.ndarray, p1: np.ndarray,
                 tol_mm: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`arcs_points` for one chunk of arcs."""
    k = at.shape[0]
    if k == 0:
        return np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0)
    axes = np.array([_PLANE_AXES.get(int(p), (0, 1, 2)) if p == p else (0, 1, 2)
                     for p in modal.plane[at].tolist()], dtype=np.int64).reshape(k, 3)
    a, b, c = axes[:, 0], axes[:, 1], axes[:, 2]
    scale = np.where(modal.inch[at], MM_PER_INCH, 1.0)
    ijk = [_column(lines, x, at) for x in "IJK"]
    off = np.nan_to_num(np.column_stack([v * scale for v, _ in ijk]))
    has_ijk = ijk[0][1] | ijk[1][1] | ijk[2][1]
    r_value, has_r = _column(lines, "R", at)
    cw = modal.motion[at] == 20
    rows = np.arange(k)
    center = np.where(modal.arc_absolute[at][:, None], off, p0 + off)
    by_r = has_r & ~has_ijk
    bad = ~(has_ijk | has_r)
    if by_r.any():
        bad |= _centres_from_r(center, by_r, p0, p1, r_value * scale, cw, a, b, rows)
    u0, v0 = p0[rows, a] - center[rows, a], p0[rows, b] - center[rows, b]
    u1, v1 = p1[rows, a] - center[rows, a], p1[rows, b] - center[rows, b]
    r0, r1 = _each(math.hypot, u0, v0), _each(math.hypot, u1, v1)
    t_abs = 2 * math.sqrt(2) * np.where(modal.inch[at], 0.001 * MM_PER_INCH, 0.01)
    err = np.abs(r0 - r1)
    bad |= np.minimum(r0, r1) < MIN_ARC_RADIUS_MM * (1.0 - 1e-9)
    with np.errstate(divide="ignore", invalid="ignore"):  # 0/0: refused above already
        bad |= (err > 100 * t_abs) | ((err > t_abs) & (err / np.maximum(r0, r1) > 0.001))
    if bad.any():  # refused as arc_points refuses it (it raises)
        j = int(np.flatnonzero(bad)[0])
        arc_points(prog, lines, modal, int(at[j]), p0[j], p1[j], tol_mm)
    t0, t1 = _each(math.atan2, v0, u0), _each(math.atan2, v1, u1)
    sweep = np.where(cw, t0 - t1, t1 - t0) % (2 * math.pi)
    sweep[sweep < 1e-12] = 2 * math.pi
    turns, _ = _column(lines, "P", at)
    extra = ~np.isnan(turns) & (turns > 1)
    if extra.any():
        sweep[extra] += 2 * math.pi * (np.trunc(turns[extra]) - 1)
    r = np.maximum(r0, 1e-9)
    step = np.array([2 * math.acos(max(1 - tol_mm / x, -1.0)) if tol_mm < x else math.pi / 2
                     for x in r.tolist()])
    n = np.minimum(np.maximum(np.ceil(sweep / np.maximum(step, 1e-6)).astype(np.int64), 1),
                   100000)
    owner = np.repeat(rows, n)
    first = np.concatenate(([0], np.cumsum(n)[:-1]))
    kk = (np.arange(owner.shape[0]) - first[owner] + 1).astype(np.float64)
    direction = np.where(cw, -1.0, 1.0)
    t = t0[owner] + direction[owner] * sweep[owner] * kk / n[owner]
    pts = np.empty((owner.shape[0], 3))
    ca, cb, cc = a[owner], b[owner], c[owner]
    pr = np.arange(owner.shape[0])
    pts[pr, ca] = center[owner, ca] + r[owner] * np.cos(t)
    pts[pr, cb] = center[owner, cb] + r[owner] * np.sin(t)
    pts[pr, cc] = p0[owner, cc] + (p1[owner, cc] - p0[owner, cc]) * kk / n[owner]
    last = first + n - 1
    pts[last] = p1
    length = _each(math.hypot, r * sweep, p1[rows, c] - p0[rows, c]) / n
    return n, pts, np.repeat(length, n)


def _centres_from_r(center, by_r, p0, p1, radius, cw, a, b, rows) -> np.ndarray:
    """Fill ``center`` of the R-format arcs (``by_r``) as :func:`_center_from_r` does;
    returns the arcs it would refuse (no chord, R too small for the chord)."""
    j = np.flatnonzero(by_r)
    aj, bj = a[j], b[j]
    du, dv = p1[j, aj] - p0[j, aj], p1[j, bj] - p0[j, bj]
    chord = _each(math.hypot, du, dv)
    rr = np.abs(radius[j])
    refused = np.zeros(by_r.shape[0], dtype=bool)
    refused[j] = (chord < 1e-12) | (chord / 2 > rr + 0.0001 * MM_PER_INCH)
    ok = ~refused[j]
    rr = np.maximum(rr, chord / 2)
    h = np.sqrt(np.maximum(rr * rr - chord * chord / 4, 0.0))
    sign = np.where(~cw[j], 1, -1) * np.where(radius[j] > 0, 1, -1)
    with np.errstate(divide="ignore", invalid="ignore"):
        ca = p0[j, aj] + du / 2 - sign * h * dv / chord
        cb = p0[j, bj] + dv / 2 + sign * h * du / chord
    center[j] = p0[j]
    center[j[ok], aj[ok]] = ca[ok]
    center[j[ok], bj[ok]] = cb[ok]
    return refused
