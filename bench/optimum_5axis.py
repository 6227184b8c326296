"""The spindle-limited optimum of a 5-axis case of ``bench/make_5axis.py``, computed
without ncopt.

Nothing here imports ncopt: the tool axis between block ends, the contact, R_eff and the
look-ahead are written out from their definitions, so that a fault in ncopt's blending,
sampling or planning cannot hide in its own yardstick.

* The toolpath is the generator's moves (exact, not the printed words).  Inside a block
  the tip runs straight; the tool axis turns as the control turns it: a tool vector
  (Sinumerik ``ORIVECT``, Fanuc ``G43.5``) along the great circle at a constant angular
  rate (slerp), rotary angles (xyzac-trt, ISO 841: ``e = (sinA sinC, -sinA cosC, cosA)``)
  linearly.
* Every block is sampled ``step_mm`` apart (default 0.02 mm); the ball touches where its
  centre is within ``TOL_MM`` of the offset sphere (the simulator's contact tolerance),
  and there R_eff = R sqrt(1 - (n.e)^2) with n the sphere's normal through the centre.
* The required speed is ``min(S_max, 1000 vc / (2 pi R_eff))`` where the ball touches,
  ``S_max`` on feed moves in the air.  The optimum is the largest S(s) under it with the
  spindle's acceleration a (RPM/s) everywhere: on feed moves F = fz z S exactly, so
  |d(S^2)/ds| <= 2 * 60 * a / (fz z); on rapids |dS| <= a T, T their length at the rapid
  rate (``rapid_free=True``: unlimited, a lower bound).  A forward and a backward pass
  give the greatest such profile (the constraints are symmetric and monotone).
* Its cutting time is the time of the feed moves that touch the part anywhere (what
  ``ncopt simulate`` counts): the integral of ds / (fz z S) over them (trapezoid rule).

Per block (``Optimum.block_min``) the same time is kept, so a run of ncopt can be
compared block by block.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

VC_M_MIN, FZ_MM, TEETH, ACCEL_RAD_S2, S_MAX_RPM = 150.0, 0.08, 2, 227.0, 18000.0
RAPID_MM_MIN = 10000.0  # ncopt's default machine: what the simulator times rapids with
TOL_MM = 0.05
STEP_MM = 0.02


@dataclass(frozen=True)
class Optimum:
    """cutting_min : the optimum cutting time, minutes
    block_min : (q,) per move of ``make_5axis.moves`` (move i ends at point i; 0 for
        rapids and moves that never touch), minutes
    block_req_rpm : (q,) the lowest required speed along each move (inf: never touches)
    block_touch : (q,) bool, the move touches the part
    s : (m,) path length of the samples (feed and rapid moves, mm);  s_rpm : (m,) the
        optimum speed there;  req_rpm : (m,) the requirement;  move : (m,) the move index
    """

    cutting_min: float
    block_min: np.ndarray
    block_req_rpm: np.ndarray
    block_touch: np.ndarray
    s: np.ndarray
    s_rpm: np.ndarray
    req_rpm: np.ndarray
    move: np.ndarray


def slerp(e0: np.ndarray, e1: np.ndarray, f: np.ndarray) -> np.ndarray:
    """(k, 3) unit vectors ``f`` (k,) of the way from e0 to e1 along their great circle
    at a constant angular rate."""
    c = float(np.clip(np.dot(e0, e1), -1.0, 1.0))
    omega = math.acos(c)
    if omega < 1e-12:
        return np.tile(e0, (f.size, 1))
    s = math.sin(omega)
    return (np.sin((1.0 - f) * omega)[:, None] * e0 + np.sin(f * omega)[:, None] * e1) / s


def axis_ac_iso(angles_deg: np.ndarray) -> np.ndarray:
    """(k, 3) the tool axis of xyzac-trt (table A about X carrying table C, ISO 841)."""
    a, c = np.radians(angles_deg[:, 0]), np.radians(angles_deg[:, 2])
    return np.column_stack((np.sin(a) * np.sin(c), -np.sin(a) * np.cos(c), np.cos(a)))


def sphere_contact(kind: str, centre: np.ndarray, sphere_mm: float, ball_mm: float):
    """Gap (mm; < 0 inside) of ball centres to the offset sphere, and the unit normal of
    the part (toward the tool) at the closest point."""
    if kind == "dome":
        d = centre - np.array([0.0, 0.0, -sphere_mm])
        r = np.linalg.norm(d, axis=1)
        return r - sphere_mm - ball_mm, d / r[:, None]
    d = np.array([0.0, 0.0, sphere_mm]) - centre
    r = np.linalg.norm(d, axis=1)
    return sphere_mm - ball_mm - r, d / r[:, None]


def _samples(gen, case, mv, angles: bool, step_mm: float):
    """Per move: (fractions, requirement (RPM), touches) of its samples, None for rapids."""
    out = []
    for i in range(1, mv.tip_mm.shape[0]):
        p0, p1 = mv.tip_mm[i - 1], mv.tip_mm[i]
        length = float(np.linalg.norm(p1 - p0))
        if mv.rapid[i]:
            out.append((length, None, None, None))
            continue
        n = max(int(math.ceil(length / step_mm)), 1)
        f = np.linspace(0.0, 1.0, n + 1)
        tip = p0 + (p1 - p0) * f[:, None]
        if angles:
            e = axis_ac_iso(mv.angles_deg[i - 1] + (mv.angles_deg[i] - mv.angles_deg[i - 1])
                            * f[:, None])
        else:
            e = slerp(mv.axis[i - 1], mv.axis[i], f)
        gap, normal = sphere_contact(case.kind, tip + gen.BALL_MM * e, gen.SPHERE_MM,
                                     gen.BALL_MM)
        touch = gap <= TOL_MM
        c = np.clip(np.einsum("ij,ij->i", normal, e), -1.0, 1.0)
        r_eff = gen.BALL_MM * np.sqrt(1.0 - c * c)
        with np.errstate(divide="ignore"):
            req = np.minimum(S_MAX_RPM, 1000.0 * VC_M_MIN / (2.0 * math.pi * r_eff))
        out.append((length, f, np.where(touch, req, S_MAX_RPM), touch))
    return out


def optimum(gen, case, angles: bool, *, step_mm: float = STEP_MM,
            rapid_free: bool = False) -> Optimum:
    """The spindle-limited optimum of ``case`` (module docstring); ``angles``: the axis
    between block ends from the xyzac-trt angles turned linearly, else the vectors."""
    mv = gen.moves(case)
    per = _samples(gen, case, mv, angles, step_mm)
    a_rpm_s = ACCEL_RAD_S2 * 60.0 / (2.0 * math.pi)
    k = 2.0 * 60.0 * a_rpm_s / (FZ_MM * TEETH)
    # the nodes: the start, then the samples of every move after its start; each node's
    # edge to the one before: (kind, amount) with kind 0 feed (ds), 1 rapid (dS allowed)
    cap, edge_kind, edge_amt, s_at, move_of = [S_MAX_RPM], [0], [0.0], [0.0], [0]
    for i, (length, f, req, _) in enumerate(per, start=1):
        if f is None:
            cap.append(S_MAX_RPM)
            edge_kind.append(1)
            edge_amt.append(math.inf if rapid_free else a_rpm_s * 60.0 * length / RAPID_MM_MIN)
            s_at.append(s_at[-1] + length)
            move_of.append(i)
            continue
        cap[-1] = min(cap[-1], req[0])
        ds = np.diff(f) * length
        cap.extend(req[1:].tolist())
        edge_kind.extend([0] * ds.size)
        edge_amt.extend(ds.tolist())
        s_at.extend((s_at[-1] + np.cumsum(ds)).tolist())
        move_of.extend([i] * ds.size)
    s2 = [c * c for c in cap]
    m = len(s2)
    for j in range(1, m):  # forward: rises limited
        s2[j] = min(s2[j], _reach(s2[j - 1], edge_kind[j], edge_amt[j], k))
    for j in range(m - 2, -1, -1):  # backward: falls limited
        s2[j] = min(s2[j], _reach(s2[j + 1], edge_kind[j + 1], edge_amt[j + 1], k))
    speed = np.sqrt(np.array(s2))
    s_at, move_of = np.array(s_at), np.array(move_of)
    q = mv.tip_mm.shape[0]
    block_min, block_req, block_touch = np.zeros(q), np.full(q, np.inf), np.zeros(q, bool)
    inv = 1.0 / (FZ_MM * TEETH * speed)
    dt = np.diff(s_at) * 0.5 * (inv[1:] + inv[:-1])
    feed = np.array(edge_kind[1:]) == 0
    np.add.at(block_min, move_of[1:][feed], dt[feed])
    for i, (_, f, req, touch) in enumerate(per, start=1):
        if f is not None and touch.any():
            block_touch[i] = True
            block_req[i] = float(req[touch].min())
    block_min[~block_touch] = 0.0
    return Optimum(float(block_min.sum()), block_min, block_req, block_touch, s_at, speed,
                   np.array(cap), move_of)


def _reach(s2_from: float, kind: int, amount: float, k: float) -> float:
    """The highest S^2 one edge away from ``s2_from``: K ds on a feed move, a T in S on a
    rapid."""
    if kind == 0:
        return s2_from + k * amount
    if math.isinf(amount):
        return math.inf
    s = math.sqrt(s2_from) + amount
    return s * s
