"""Where the tool is after every line (mm), and whether each axis is known there.

Nothing is guessed: where the position cannot be known (a subprogram call, a macro, a
return to home, a parameter the program does not set, an opaque line that may move the
machine) the axes become unknown until the program states them again absolutely.
"""

from __future__ import annotations

import numpy as np

from ncopt.model import MM_PER_INCH
from ncopt.motion.flow import l_calls, unread_opaque
from ncopt.motion.modal import (CANNED, G_NOT_A_TARGET, G_OTHER_MOVES, G_POLE, G_READ, G_SCALE_OFF,
                                G_SCALE_ON, G_SPLINE, G_WORK_OFFSETS, KW_SCALE, ffill)


def _unknown_events(prog, lines, modal, executed, poisoned, warnings) -> np.ndarray:
    """(n,) bool: lines after which no axis position can be trusted."""
    event = np.zeros(lines.n, dtype=bool)
    # G10: data setting (offsets); Heidenhain ISO's polar rapid: either way a lost position
    event |= lines.has_g({280, 300, 530, 920, 921, 922, 923, 520, 281, 301, 100}
                         | G_OTHER_MOVES | G_POLE)
    event |= lines.has_m({6, 98, 99}) | lines.has_g({650, 660} | G_SCALE_ON | G_SCALE_OFF
                                                    | {160, 150, 121, 131, 71})
    event |= np.isin(modal.motion, list(CANNED)) | np.isin(modal.motion, [330, 382, 383, 384, 385])
    event |= np.isin(modal.comp, [410, 420, 411, 421])
    event |= _offset_changes(lines, executed)
    unread = lines.unread_g() & executed
    for i in np.flatnonzero(unread)[:20].tolist():
        codes = lines.g_code[(lines.g_line == i) & ~np.isin(lines.g_code, list(G_READ))]
        warnings.append(f"{prog.path}:{i + 1}: G{codes[0] / 10:g} is a G code ncopt does not "
                        "read; the moves after it keep their S/F until the position is known "
                        "again")
    event |= unread
    spline = lines.has_g(G_SPLINE) & executed
    spline &= lines.present_any("XYZ")
    for i in np.flatnonzero(spline)[:20].tolist():
        warnings.append(f"{prog.path}:{i + 1}: a spline, NURBS or smoothing block (G5, G5.1, "
                        "G5.2, G6.2) with axis words is not followed by ncopt; the moves after "
                        "it keep their S/F until the position is known again")
    event |= spline
    for i, reason in prog.opaque_reason.items():
        if reason.upper() in KW_SCALE:
            event[i] = True  # the moves under it get their own reason (SCALED_WHY)
        elif reason.upper() in ("F", "S"):
            # G1 X15 F=R1: the line is no move ncopt reads, so the position is lost too;
            # the moves under it get their own reason, not this warning
            event[i] = True
        elif unread_opaque(reason):
            event[i] = True
            warnings.append(f"{prog.path}:{i + 1}: '{reason}' is not interpreted by ncopt; "
                            "the moves after it keep their S/F until the position is "
                            "known again")
        elif reason.upper().startswith(("$", ":")):
            event[i] = True
    event |= l_calls(lines, modal)  # Sinumerik L100: subprogram call
    event |= poisoned & lines.present_any("XYZ")
    return event & executed


def _offset_changes(lines, executed) -> np.ndarray:
    """(n,) bool: lines that select a work offset other than the one in force (G54 ->
    G55): the moves after them are in another frame.  Re-stating the same one (posts write
    G54 at every operation) changes nothing."""
    code = lines.g_group(G_WORK_OFFSETS)
    code[~executed] = np.nan
    extended = code == 541  # G54.1 P1..P300: the P word says which
    code[extended] += np.nan_to_num(lines.value("P")[extended], nan=-1.0) / 1000.0
    given = np.flatnonzero(~np.isnan(code))
    out = np.zeros(lines.n, dtype=bool)
    if given.size > 1:
        change = code[given[1:]] != code[given[:-1]]
        out[given[1:][change]] = True
    return out


def positions(prog, lines, modal, executed, poisoned, warnings):
    """Absolute positions in mm per line (n,3), whether each axis is known, and (n,) the
    last line at or before each after which no position can be trusted (-1: none)."""
    events = _unknown_events(prog, lines, modal, executed, poisoned, warnings)
    special = lines.has_g(G_NOT_A_TARGET) | lines.unread_g() | np.isin(modal.motion, list(CANNED))
    scale = np.where(modal.inch, MM_PER_INCH, 1.0)
    pos = np.zeros((lines.n, 3))
    known = np.zeros((lines.n, 3), dtype=bool)
    idx = np.arange(lines.n)
    last_evt = np.maximum.accumulate(np.where(events, idx, -1))
    for k, axis in enumerate("XYZ"):
        value = lines.value(axis) * scale
        present = lines.present(axis) & executed & ~special & ~np.isnan(value)
        absolute = present & modal.absolute
        increment = np.where(present & ~modal.absolute, value, 0.0)
        cum = np.cumsum(increment)
        base = np.where(absolute, value - cum, np.nan)
        pos[:, k] = ffill(base, 0.0) + cum
        last_abs = np.maximum.accumulate(np.where(absolute, idx, -1))
        known[:, k] = last_abs > last_evt
        # an event on the same line as an absolute word: the word is a target
        # of that special move (G28 X0...), the axis stays unknown
    return pos, known, last_evt
