"""Rotary axes A B C: where each stands after every line (degrees, or not known), and
the tool axis the machine's kinematics gives from them, with the reason of every move
that cannot be planned (an axis not stated or lost, no kinematics, no tool-centre-point
control)."""

from __future__ import annotations

import numpy as np

from ncopt.motion.kinematics import KINEMATICS, VECTOR, fitting
from ncopt.motion.modal import G_NON_MODAL_MOVE, HARMLESS_OPAQUE, ffill
from ncopt.motion.planes import G_ALIGN, KW_FRAME_OFF, KW_ROTATIONS, cycle800_args
from ncopt.motion.tcp import SWITCHES
from ncopt.motion.toolaxis import (G_CALLS, G_HOME, G_NOT_POSITION, KW_TCP, M_CALLS,
                                   ORIENTATION_ADDRESS, ROTARY, Z)

_NOT_STATED = ("the program {where}: where {c} stands{until} is not known (ncopt takes no "
               "rotary axis at 0); state {c} before the first move")


def positions_of(lines, c: str) -> np.ndarray:
    """(n,) bool: the lines whose ``c`` word is a rotary position: not the radius of
    G07.1 C10 (cylindrical interpolation) nor a G65/G66 macro argument."""
    return lines.present(c) & ~lines.has_g(G_NOT_POSITION)


def _losing_lines(prog, lines, executed, r):
    """(n,) bool: the lines after which no rotary position is known (G28/G30 without
    axes, a call, G53.1, a construct ncopt does not interpret), and (n,) int16 the
    reason code of each."""

    n = lines.n
    calls = lines.has_g(G_CALLS) | lines.has_m(M_CALLS)
    calls |= lines.present("L") & ~lines.has_g({100, 760})  # Sinumerik L100: a call
    home_all = lines.has_g(G_HOME) & ~lines.present_any("XYZ" + ROTARY)
    other = np.zeros(n, dtype=bool)
    why_line = np.zeros(n, dtype=np.int16)
    for i, head in prog.opaque_reason.items():
        up = head.upper()
        if not executed[i] or up in HARMLESS_OPAQUE or ORIENTATION_ADDRESS.match(head):
            continue
        if up in KW_TCP or up in KW_FRAME_OFF or up in KW_ROTATIONS or up == "TRANS":
            continue  # frames and TCP switches do not turn the axes
        if up == "CYCLE800" and cycle800_args(prog.line_text(i)) in ((), "zero"):
            continue  # CYCLE800() only deselects; zero angles swivel to the vertical
        other[i] = True
        why_line[i] = r.code(f"the rotary axis position is not known after '{head}' "
                             f"(line {i + 1}); state A/B/C again")
    align = lines.has_g({G_ALIGN})
    for mask, text in ((home_all, "G28/G30"), (calls, "a subprogram or macro call"),
                       (align, "G53.1")):
        for i in np.flatnonzero(mask & executed).tolist():
            why_line[i] = r.code(f"the rotary axis position is not known after {text} "
                                 f"(line {i + 1}); state A/B/C again")
    return (home_all | calls | other | align) & executed, why_line


def rotary_positions(prog, lines, modal, executed, r):
    """Rotary positions after each line, moves of them, and why each is not known.

    Returns angle (n, 3) degrees after each line (NaN: not known: before the program
    first states the axis absolutely, after a line that loses it until it is stated
    again, or never stated: ncopt takes no axis at 0), rotary_move (n,) bool and
    unknown (n, 3) int16: per axis, the reason code of a NaN.
    """

    n = lines.n
    g53 = lines.has_g({530})  # a machine position: taken as the rotary position (no offsets)
    special = lines.has_g(G_NON_MODAL_MOVE) & ~g53
    lost_all, why_line = _losing_lines(prog, lines, executed, r)
    angle = np.full((n, 3), np.nan)
    unknown = np.zeros((n, 3), dtype=np.int16)
    move = np.zeros(n, dtype=bool)
    idx = np.arange(n)
    for k, c in enumerate(ROTARY):
        present = positions_of(lines, c)
        if not present.any():
            unknown[:, k] = r.code(_NOT_STATED.format(c=c, where=f"never states {c}", until=""))
            continue
        value = lines.value(c)
        present &= executed
        gone_here = present & (special | np.isnan(value))
        for i in np.flatnonzero(gone_here & ~lost_all).tolist():
            why_line[i] = r.code(f"the rotary axis position is not known after the {c} word "
                                 f"of line {i + 1} (G28/G30/G10/G92 or a value ncopt cannot "
                                 "compute); state it again")
        ok = present & ~special & ~np.isnan(value)
        move |= ok & ~g53
        absolute = ok & (modal.absolute | g53)
        cum = np.cumsum(np.where(ok & ~absolute, value, 0.0))
        pos = ffill(np.where(absolute, value - cum, np.nan), np.nan) + cum
        last_abs = np.maximum.accumulate(np.where(absolute, idx, -1))
        last_lost = np.maximum.accumulate(np.where(lost_all | gone_here, idx, -1))
        gone = last_lost > last_abs
        pos[gone] = np.nan
        angle[:, k] = pos
        first = np.flatnonzero(absolute)
        before = r.code(_NOT_STATED.format(c=c, **(
            {"where": f"states {c} first on line {first[0] + 1}", "until": " until then"}
            if first.size else {"where": f"never states {c} absolutely", "until": ""})))
        unknown[:, k] = np.where(gone, why_line[np.maximum(last_lost, 0)],
                                 np.where(last_abs < 0, before, 0))
    return angle, move, unknown


def axes_from_angles(angle, unknown, rotary, kinematics, tcp, why, r):
    """Axis (n, 3), angles (n, 3) (the spin NaN where not known: the tool vertical) and
    (n,) the reason code of a spin axis that is not known where the tool stands vertical
    (no matter there, but the tool cannot tilt from there); fills ``why`` in place.
    ``tcp``: (on (n,) bool, whether the program switches it)."""
    n = angle.shape[0]
    axis = np.tile(Z, (n, 1))
    angles = np.full((n, 3), np.nan)
    spin_why = np.zeros(n, dtype=np.int16)
    turned = np.zeros(n, dtype=bool)  # a named axis away from 0 or not known
    for k in (ROTARY.index(c) for c in rotary):
        turned |= ~(np.abs(angle[:, k]) <= 1e-9)
    kin = KINEMATICS.get(kinematics)
    tcp_on = tcp[0]
    if not rotary:  # tool vectors or tilted planes only
        return axis, angles, spin_why
    if kin is None:
        why[turned & tcp_on] = r.code(_no_kinematics(rotary, kinematics))
        why[turned & ~tcp_on] = r.code(_tcp_off(rotary, None, tcp))
        for k in (ROTARY.index(c) for c in rotary):
            lost = (unknown[:, k] > 0) & tcp_on
            why[lost] = unknown[lost, k]
        return axis, angles, spin_why
    tilt_k, spin_k = ROTARY.index(kin.axes[0]), ROTARY.index(kin.axes[1])
    vertical = np.mod(angle[:, tilt_k], 360.0) == 0.0  # the spin does not matter
    known = ~np.isnan(angle[:, [tilt_k, spin_k]]).any(axis=1)
    axis[known] = kin.tool_axis(np.nan_to_num(angle[known]))
    axis[vertical] = Z
    stand = vertical & ~known
    angles[known | stand] = np.where(np.isnan(angle[known | stand]), 0.0, angle[known | stand])
    angles[stand, spin_k] = np.nan
    spin_why[stand] = unknown[stand, spin_k]
    off = turned & ~tcp_on
    why[off] = r.code(_tcp_off(rotary, kin.name, tcp))
    foreign = [c for c in rotary if c not in kin.axes]
    bad = np.zeros(n, dtype=bool)
    for c in foreign:
        bad |= ~(np.abs(angle[:, ROTARY.index(c)]) <= 1e-9)
    if len(foreign) == len(rotary):  # none of the machine's axes: the wrong machine
        bad[:] = True
    why[bad & (why == 0)] = r.code(f"the program turns {', '.join(foreign)}, which {kin.name} "
                                   "does not have; pass the machine's kinematics")
    for k in (spin_k, tilt_k):  # the tilt's reason wins
        lost = (unknown[:, k] > 0) & ~(vertical & (k == spin_k)) & ~bad & ~off
        why[lost] = unknown[lost, k]
    return axis, angles, spin_why


def _tcp_off(rotary, kinematics: str | None, tcp) -> str:
    """Why a move with the rotary axes turned is not planned without TCP in force."""
    names = ", ".join(rotary) or "rotary axes"
    if tcp[1]:  # the program switches it, and it is off here
        return (f"the rotary axes ({names}) are turned with tool-centre-point control off "
                f"(none of {SWITCHES} in force): X Y Z are machine positions, "
                "ncopt cannot place the tool tip; switch it on for these moves")
    fits = fitting(rotary) if kinematics is None else ""
    todo = f", with --kinematics {fits} as the machine is built" if fits else ""
    return (f"the rotary axes ({names}) are turned and the program never switches "
            f"tool-centre-point control on ({SWITCHES}): X Y Z are then machine "
            "positions, not the tool tip on the part (grbl and Mach have no such control); "
            "check on the machine whether its control runs tool-tip kinematics for this "
            'program, and if it always does, set tcp = "always" in its machine profile'
            + todo)


def _no_kinematics(rotary, kinematics: str | None) -> str:
    names = ", ".join(rotary) or "rotary axes"
    fits = fitting(rotary)
    todo = f"pass --kinematics {fits} as the machine is built" if fits else \
        f"ncopt knows no kinematics that turns {' and '.join(rotary)}"
    if kinematics == VECTOR:
        return (f"--kinematics vector reads tool vectors, and these blocks turn the rotary "
                f"axes ({names}); {todo}")
    return f"the rotary axes ({names}) tilt the tool and no kinematics is given; {todo}"
