"""Tool-centre-point control (TCP): where it is in force, the lines that switch it, and
the Sinumerik TCP lines ncopt reads (:func:`tcp_switches`)."""

from __future__ import annotations

import numpy as np

from ncopt.motion.modal import ffill
from ncopt.motion.toolaxis import (G_LENGTH_GROUP, G_TCP_ON, KW_TCP, M_TCP_OFF, M_TCP_ON, ROTARY,
                                   VECTOR_LETTERS)

SWITCHES = "G43.4/G43.5, TRAORI, M128 or FUNCTION TCPM, LinuxCNC's M428"


def tcp_state(prog, lines, executed, keywords, always: bool = False):
    """TCP on after each line, whether the program ever switches it, and the lines
    that switch it on.  Each switch ends only with its own off code: G43.4/G43.5
    (and Haas G234) with the rest of their modal group (G43, G44, G49), M128 with
    M129, M428 with M429, TRAORI with TRAFOOF, FUNCTION TCPM with its RESET.  A
    program that never switches it runs without it, unless ``always`` (the machine
    profile's ``tcp = "always"``: the control runs tool-tip kinematics for every
    program, whatever it switches)."""
    if always:
        return np.ones(lines.n, dtype=bool), False, np.zeros(lines.n, dtype=bool)
    length = lines.g_group(G_LENGTH_GROUP)
    g_on = np.isin(length, list(G_TCP_ON)) & executed
    g_off = np.isfinite(length) & ~g_on & executed
    m_on = (lines.has_m(M_TCP_ON)) & executed
    m_off = lines.has_m(M_TCP_OFF) & executed
    for i, head in keywords.items():
        text = prog.line_text(i).upper()
        if head == "TRAORI" or (head == "FUNCTION" and "TCPM" in text and "RESET" not in text):
            m_on[i] = True
        elif head == "TRAFOOF" or (head == "FUNCTION" and "TCPM" in text):
            m_off[i] = True
    on = g_on | m_on
    if not on.any():  # never switched on: X Y Z are machine positions
        return np.zeros(lines.n, dtype=bool), False, on
    end = lines.has_m({2, 30}) & executed
    state = np.zeros(lines.n, dtype=bool)
    for sw_on, sw_off in ((g_on, g_off), (m_on, m_off)):
        st = np.full(lines.n, np.nan)
        st[sw_off | end] = 0.0
        st[sw_on] = 1.0
        state |= ffill(st, 0.0) > 0
    return state, True, on


def tcp_changed(lines, executed, tcp_on) -> np.ndarray:
    """(n,) bool: TCP was switched on or off since the last line with axis words."""
    moved = lines.present_any("XYZ" + ROTARY + VECTOR_LETTERS) & executed
    change = np.concatenate(([False], tcp_on[1:] != tcp_on[:-1]))
    count = np.cumsum(change)
    idx = np.arange(lines.n)
    last_move = np.maximum.accumulate(np.where(moved, idx, -1))
    before = np.concatenate(([-1], last_move[:-1]))  # the last move line before each line
    return moved & (count - np.where(before >= 0, count[np.maximum(before, 0)], 0) > 0)


def tcp_switches(prog) -> np.ndarray:
    """(n_lines,) bool: the Sinumerik TCP and orientation-mode lines (TRAORI, TRAFOOF,
    ORIWKS...), which ncopt reads here: they use no S or F, so they need not run with
    the program's own (they stay opaque, never edited)."""
    out = np.zeros(prog.n_lines, dtype=bool)
    for i, head in prog.opaque_reason.items():
        if head.upper() in KW_TCP - {"FUNCTION"}:
            out[i] = True
    return out
