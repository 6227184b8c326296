"""Arcs (G2/G3) as points within a chord tolerance, with their exact lengths; the centre
from I J K or from R, checked as LinuxCNC checks it."""

from __future__ import annotations

import cmath
import math

import numpy as np

from ncopt.model import MM_PER_INCH
from ncopt.motion.checks import fail
from ncopt.motion.mathhypot import hypot
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


def _atan2(y: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``math.atan2`` of each pair: the C library's atan2, as :func:`arc_points` takes it
    (numpy's arctan2 may be its own SIMD version, another last bit).

    Through ``cmath.phase`` of ``x + iy``: the same special cases and the same atan2
    call as ``math.atan2`` (CPython's c_atan2 and m_atan2), at 1.4x the speed of a map
    of ``math.atan2`` (one argument, one list: 64 against 90 ms per million); it raises
    where atan2 underflows, which ``math.atan2`` lets pass: then ``math.atan2`` itself."""
    z = np.empty(y.shape[0], dtype=np.complex128)
    z.real = x
    z.imag = y
    try:
        return np.fromiter(map(cmath.phase, z.tolist()), np.float64, y.shape[0])
    except (OverflowError, ValueError):
        return np.fromiter(map(math.atan2, y.tolist(), x.tolist()), np.float64, y.shape[0])


def _plane_axes(plane: np.ndarray) -> tuple:
    """The (first, second, normal) axes of each arc's plane (G17 where the plane is none
    of G17, G18, G19), as :func:`arc_points` picks them, and the rows to take them on:
    three ints and ``slice(None)`` where every arc is in one plane (the usual program),
    else three (k,) int64 arrays and ``arange(k)``."""
    code = np.trunc(plane)
    if plane.shape[0] and (code == code[0]).all():
        return (*_PLANE_AXES.get(float(code[0]), (0, 1, 2)), slice(None))
    axes = np.tile(np.array([0, 1, 2], dtype=np.int64), (plane.shape[0], 1))
    for g, row in _PLANE_AXES.items():
        axes[code == g] = row
    return axes[:, 0], axes[:, 1], axes[:, 2], np.arange(plane.shape[0])


def _on(axis, at):
    """An axis per arc (:func:`_plane_axes`) on the arcs ``at``: the int where all share it."""
    return axis[at] if isinstance(axis, np.ndarray) else axis


def _piece_counts(sweep: np.ndarray, r: np.ndarray, tol_mm: float) -> np.ndarray:
    """Pieces of each arc (int64): the sweep over the angle whose chord strays
    ``tol_mm`` from the arc, rounded up, 1 to 100,000, as :func:`arc_points` counts them.

    That angle is numpy's arccos (within an ulp or so of ``math.acos``, which the
    reference calls); the count is its ceiling, the same for both wherever the quotient
    is not within a millionth of a whole number: there (rarely) it is ``math.acos``'s."""
    with np.errstate(divide="ignore", invalid="ignore"):
        step = np.where(tol_mm < r, 2 * np.arccos(np.maximum(1 - tol_mm / r, -1.0)),
                        math.pi / 2)
        q = sweep / np.maximum(step, 1e-6)
        near = ~(np.abs(q - np.rint(q)) > 1e-6 * np.maximum(np.abs(q), 1.0))
    for j in np.flatnonzero(near).tolist():
        x = float(r[j])
        exact = 2 * math.acos(max(1 - tol_mm / x, -1.0)) if tol_mm < x else math.pi / 2
        q[j] = float(sweep[j]) / max(exact, 1e-6)
    with np.errstate(invalid="ignore"):
        return np.minimum(np.maximum(np.ceil(q).astype(np.int64), 1), 100000)


def _radii_refused(r0: np.ndarray, u1: np.ndarray, v1: np.ndarray,
                   inch: np.ndarray) -> np.ndarray:
    """The arcs :func:`arc_points` refuses for their radii (k,) bool: zero radius, or the
    end's radius ``hypot(u1, v1)`` off the start's ``r0`` beyond LinuxCNC's tolerance.

    The end's radius decides nothing else, so it is numpy's hypot (an ulp from
    ``math.hypot`` at most), but ``math.hypot``'s bits wherever a test is within a
    millionth of a millionth of its threshold."""
    t_abs = 2 * math.sqrt(2) * np.where(inch, 0.001 * MM_PER_INCH, 0.01)
    least = MIN_ARC_RADIUS_MM * (1.0 - 1e-9)
    with np.errstate(all="ignore"):  # 0/0, NaN: refused by the radius
        r1 = np.hypot(u1, v1)
        err = np.abs(r0 - r1)
        big = np.maximum(r0, r1)
        margin = 1e-12 * big
        doubt = ~((np.abs(r1 - least) > margin) & (np.abs(err - t_abs) > margin)
                  & (np.abs(err - 100 * t_abs) > margin)
                  & (np.abs(err / big - 0.001) > 1e-12))
        if doubt.any():
            r1[doubt] = hypot(u1[doubt], v1[doubt])
            err, big = np.abs(r0 - r1), np.maximum(r0, r1)
        bad = np.minimum(r0, r1) < least
        return bad | (err > 100 * t_abs) | ((err > t_abs) & (err / big > 0.001))


# arcs worked out together at most (arcs_points): their temporaries bounded
ARC_CHUNK = 65536


def arcs_points(prog, lines, modal, at: np.ndarray, p0: np.ndarray, p1: np.ndarray,
                tol_mm: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`arc_points` for many arcs at once: the arcs on lines ``at`` (k,) from ``p0``
    to ``p1`` ((k, 3) mm).  Returns (points per arc (k,), points (sum, 3), lengths (sum,)),
    bit for bit what :func:`arc_points` gives arc by arc (tested); an arc it would refuse
    is refused by it, with its message, the first such arc in program order.

    Every arc is worked out on its own, so they go ``ARC_CHUNK`` at a time: the same
    values, and the temporaries of a million arcs are not all held at once."""
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
    a, b, c, rows = _plane_axes(modal.plane[at])
    inch = modal.inch[at]
    scale = np.where(inch, MM_PER_INCH, 1.0)
    ijk = [_column(lines, x, at) for x in "IJK"]
    off = np.nan_to_num(np.column_stack([v * scale for v, _ in ijk]))
    has_ijk = ijk[0][1] | ijk[1][1] | ijk[2][1]
    r_value, has_r = _column(lines, "R", at)
    cw = modal.motion[at] == 20
    center = np.where(modal.arc_absolute[at][:, None], off, p0 + off)
    by_r = has_r & ~has_ijk
    bad = ~(has_ijk | has_r)
    if by_r.any():
        bad |= _centres_from_r(center, by_r, p0, p1, r_value * scale, cw, a, b)
    ca, cb = center[rows, a], center[rows, b]
    u0, v0 = p0[rows, a] - ca, p0[rows, b] - cb
    u1, v1 = p1[rows, a] - ca, p1[rows, b] - cb
    r0 = hypot(u0, v0)
    bad |= _radii_refused(r0, u1, v1, inch)
    if bad.any():  # refused as arc_points refuses it (it raises)
        j = int(np.flatnonzero(bad)[0])
        arc_points(prog, lines, modal, int(at[j]), p0[j], p1[j], tol_mm)
    t0 = _atan2(v0, u0)
    t1 = _atan2(v1, u1)
    sweep = np.where(cw, t0 - t1, t1 - t0) % (2 * math.pi)
    sweep[sweep < 1e-12] = 2 * math.pi
    turns, _ = _column(lines, "P", at)
    extra = ~np.isnan(turns) & (turns > 1)
    if extra.any():
        sweep[extra] += 2 * math.pi * (np.trunc(turns[extra]) - 1)
    r = np.maximum(r0, 1e-9)
    n = _piece_counts(sweep, r, tol_mm)
    length = hypot(r * sweep, p1[rows, c] - p0[rows, c]) / n
    if (n == 1).all():  # one piece each (most arcs of a fine program): their ends
        return n, p1.copy(), length
    pts = _inner_points(n, t0, sweep, cw, r, center, (a, b, c), p0, p1)
    return n, pts, np.repeat(length, n)


def _centres_from_r(center, by_r, p0, p1, radius, cw, a, b) -> np.ndarray:
    """Fill ``center`` of the R-format arcs (``by_r``) as :func:`_center_from_r` does;
    returns the arcs it would refuse (no chord, R too small for the chord)."""
    j = np.flatnonzero(by_r)
    aj, bj = _on(a, j), _on(b, j)
    du, dv = p1[j, aj] - p0[j, aj], p1[j, bj] - p0[j, bj]
    chord = hypot(du, dv)
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
    center[j[ok], _on(aj, ok)] = ca[ok]
    center[j[ok], _on(bj, ok)] = cb[ok]
    return refused


def _inner_points(n, t0, sweep, cw, r, center, axes, p0, p1) -> np.ndarray:
    """The points of the arcs ((sum n, 3) mm): each arc's end ``p1``, and before it the
    ``n - 1`` points within it, as :func:`arc_points` places them (only those are
    worked out).  ``axes``: (a, b, c) as :func:`_plane_axes` gives them."""
    last = np.cumsum(n) - 1
    pts = np.empty((int(last[-1]) + 1, 3))
    pts[last] = p1
    inner = n - 1
    owner = np.repeat(np.arange(n.shape[0]), inner)
    kk = (np.arange(owner.shape[0]) - np.repeat(np.cumsum(inner) - inner, inner) + 1
          ).astype(np.float64)
    at = last[owner] - n[owner] + kk.astype(np.int64)  # the rows of the inner points
    n_f = n[owner]
    direction = np.where(cw, -1.0, 1.0)
    t = t0[owner] + direction[owner] * sweep[owner] * kk / n_f
    ca, cb, cc = (_on(x, owner) for x in axes)
    pts[at, ca] = center[owner, ca] + r[owner] * np.cos(t)
    pts[at, cb] = center[owner, cb] + r[owner] * np.sin(t)
    pts[at, cc] = p0[owner, cc] + (p1[owner, cc] - p0[owner, cc]) * kk / n_f
    return pts
