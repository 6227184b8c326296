"""Fanuc ``G43.5 ... Q``: the tool leans Q degrees toward the direction of travel
(:func:`lean_toward_travel`), read once the positions are known."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ncopt.motion.kinematics import lean
from ncopt.motion.modal import CANNED, ffill
from ncopt.motion.toolaxis import (G_LENGTH_GROUP, G_VECTOR_TCP, MAX_LEAN_GAP_DEG, Z, Orientation,
                                   Reasons, before)


def lean_toward_travel(o: Orientation | None, prog, lines, modal, executed,
                       pos_mm: np.ndarray) -> Orientation | None:
    """``o`` with Fanuc's ``G43.5 ... Q`` read: in tool-centre-point control type 2 Q is
    the inclination of the tool (degrees) toward the direction of travel, in the plane
    of the vector I J K and that direction (Fanuc Series 30i, tool centre point control
    for 5-axis machining: "G43.5 I_ J_ K_ H_ Q2.0" inclines the tool two degrees toward
    the proceeding direction).  It holds from its G43.5 block to G49 (or another code of
    its group, M2/M30).  Each block's tool axis is then its I J K leaned Q toward its own
    travel ``pos_mm[i] - pos_mm[i - 1]`` (mm), reached at its end as any G43.5 vector;
    not planned: a block whose lean ncopt cannot know (the first move under Q, a block
    that turns the vector without moving the tip, runs along the tool axis or is an arc,
    a Q written on another block) or where the direction of travel turns so much that
    leaning toward the last block's direction or this one's differs by more than
    :data:`MAX_LEAN_GAP_DEG` at its start (how the control turns the tool at a corner
    is not in the definition)."""
    if o is None:
        return o
    q, stray = _lean_in_force(lines, modal, executed)
    active = (q != 0.0) & executed  # NaN: a stray Q, the lean is not known
    if not active.any():
        return o
    r = Reasons()
    r.texts = list(o.reasons)
    travel = pos_mm - before(pos_mm, np.zeros(3))
    moving = np.abs(travel).sum(axis=1) > 0
    switch = lines.g_group(G_LENGTH_GROUP) == G_VECTOR_TCP  # moves without TCP: keeps the axis
    moves = active & np.isin(modal.motion, [0, 10]) & moving & ~switch
    vector = lines.present_any("IJK")
    leaned = np.full((lines.n, 3), np.nan)
    leaned[moves] = lean(o.axis[moves], travel[moves], q[moves])
    unknown = active & ((moves & np.isnan(leaned).any(axis=1)) | (vector & ~moves)
                        | (moving & ~moves & ~switch) | np.isnan(q))
    why = np.zeros(lines.n, dtype=np.int16)
    why[unknown] = r.code("under G43.5 Q the tool leans toward the direction of travel, "
                          "and this block gives none ncopt can use (it turns the tool vector "
                          "without moving the tip, runs along the tool axis or is an arc): "
                          "the tool axis after it is not known")
    code = np.full(lines.n, np.nan)
    for i in np.flatnonzero(stray).tolist():
        code[i] = r.code(f"a Q word under G43.4/G43.5 outside a G43.5 block (line {i + 1}): "
                         "ncopt reads the lean of the tool only there")
    lost = np.isnan(q) & executed
    why[lost] = ffill(code, 0.0)[lost]
    own = ~active | moves | unknown  # the other lines keep the axis of the line before
    src = np.maximum.accumulate(np.where(own, np.arange(lines.n), 0))
    axis = np.where(moves[:, None], leaned, o.axis)[src]
    why = why[src]
    axis[why > 0] = Z  # not known: never used (its moves are not planned)
    blocked = np.where(why > 0, why, before(why, 0)).astype(np.int16)
    gap = _lean_gap(o.axis, travel, q, moves, src)
    corner = moves & ~(gap <= MAX_LEAN_GAP_DEG) & (blocked == 0)
    blocked[corner] = r.code(f"under G43.5 Q the tool leans toward the direction of travel, "
                             "which starts or turns at this block: the axis at its start "
                             "leans toward the last block's direction or this one's, "
                             f"{MAX_LEAN_GAP_DEG:g} deg or more apart (how the control turns "
                             "the tool there is not in Fanuc's definition)")
    blocked = np.where(o.blocked > 0, o.blocked, np.where(executed, blocked, 0))
    return replace(o, blocked=blocked.astype(np.int16), reasons=tuple(r.texts), axis=axis)


def _lean_in_force(lines, modal, executed) -> tuple[np.ndarray, np.ndarray]:
    """(n,) the G43.5 Q in force after each line (degrees; 0: none; NaN: a Q written on
    another block under G43.4/G43.5 makes it unknown until the group changes), and (n,)
    bool those other blocks (a canned cycle's Q is its own)."""

    length = np.where(executed, lines.g_group(G_LENGTH_GROUP), np.nan)
    g435 = length == G_VECTOR_TCP
    state = np.full(lines.n, np.nan)
    state[np.isfinite(length)] = 0.0
    state[g435] = np.nan_to_num(lines.value("Q")[g435], nan=0.0)
    state[lines.has_m({2, 30}) & executed] = 0.0
    tcp_g = np.isin(length, [434, G_VECTOR_TCP]).astype(float)  # G43.4 has no Q either
    section = ffill(np.where(np.isfinite(length), tcp_g, np.nan), 0.0) > 0
    stray = lines.present("Q") & executed & section & ~g435
    stray &= ~np.isin(modal.motion, list(CANNED))
    state[stray] = np.inf
    q = ffill(state, 0.0)
    q[np.isinf(q)] = np.nan
    return q, stray


def _lean_gap(e_prog, travel, q, moves, src) -> np.ndarray:
    """(n,) deg, per move under Q: at its start, the angle between the last block's I J K
    leaned toward the last block's travel and toward this one's (NaN: no last block)."""
    gap = np.full(moves.shape[0], np.nan)
    rows = np.flatnonzero(moves)
    prev = src[np.maximum(rows - 1, 0)]
    ok = (rows > 0) & moves[prev] & (q[prev] == q[rows])
    rows, prev = rows[ok], prev[ok]
    a = lean(e_prog[prev], travel[prev], q[prev])
    b = lean(e_prog[prev], travel[rows], q[rows])
    gap[rows] = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", a, b), -1.0, 1.0)))
    return gap
