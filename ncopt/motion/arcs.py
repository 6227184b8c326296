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
