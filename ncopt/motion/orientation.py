"""Where the tool points in every block: rotary axes, tool vectors, tilted planes.

ncopt plans a move only when it knows the tool axis ``e`` (unit, from the tip
toward the spindle, in the part frame) at both its ends.  A 3-axis program
never mentions anything below, its tool axis is +Z and the reader returns
``None`` (no cost).  Everything that can turn the tool away from +Z is read
here, per source line; a move whose axis ncopt cannot know is left as
programmed with a located reason.

* Rotary axis words ``A B C`` (degrees; G90/G91 as the linear axes).  An axis
  is not known until the program states it (ncopt takes none at 0), and is lost
  after a move that can turn it without saying where to (G28/G30, offsets set
  with rotary words, a call, a swivel, G53.1, a construct ncopt does not
  interpret) until stated again.  Where one is not 0 the machine's kinematics
  gives ``e`` (``ncopt.motion.kinematics``, ``--kinematics``); a spin axis (C) not known
  matters only where the tool tilts.  A feed block whose axis turns more than
  :data:`MAX_TURN_DEG` along the way (a full turn A360 -> A0 ends upright) is a
  reorientation, not planned.
* Tool-centre-point control (TCP): with it the programmed X Y Z are the tool
  tip in the part frame.  Switched on by Sinumerik ``TRAORI``, Fanuc
  ``G43.4``/``G43.5``, Haas ``G234``, Heidenhain ``M128``/``FUNCTION TCPM``, the
  LinuxCNC 5-axis configurations' ``M428``; off by ``TRAFOOF``, ``G49`` (or
  ``G43``/``G44``), ``M129``, ``FUNCTION RESET TCPM``, ``M429``, M2/M30.  Without
  it X Y Z are machine positions: a move with a rotary axis turned is not
  planned, unless the machine profile says its control always runs tool-tip
  kinematics (``tcp = "always"``).  The block that switches TCP on does not move
  under it (Fanuc): not planned when the tool is tilted.
* Tool vectors, which need no machine data: Fanuc ``G43.5`` ``I J K`` (a
  component left out of a block is 0; none given, the last vector holds) and
  Sinumerik ``A3= B3= C3=`` under ``TRAORI`` (same rule; orientation in the
  workpiece frame, ORIWKS, the default; ``ORIMKS`` is not read).  Other
  Sinumerik orientation addresses (``A2=``, ``A4=``, ``LEAD=``...) are not read.
* Tilted working planes (3+2): ``ncopt.motion.planes``.
* Fanuc ``G43.5 ... Q``: the tool leans Q degrees toward the direction of
  travel (:func:`lean_toward_travel`, once the positions are known).
* Arcs keep the tool axis: an arc that turns it is not planned, nor any arc
  under G43.5 (its I J K would be both centre and vector).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, replace

import numpy as np

from ncopt.runtime.errors import NcoptError
from ncopt.motion.kinematics import KINEMATICS, VECTOR, fitting, lean, turn_deg, unit
from ncopt.model import VECTOR_WORD_CODES
from ncopt.motion.planes import (G_ALIGN, G_FRAME_OFF, G_FRAME_ON, G_ROTATION, KW_FRAME_OFF,
                     KW_ROTATIONS, KW_SWIVEL, cycle800_args, frames)
from ncopt.motion.modal import CANNED, G_NON_MODAL_MOVE, HARMLESS_OPAQUE, ffill

ROTARY = "ABC"
Z = np.array([0.0, 0.0, 1.0])
TCP_ALWAYS = "always"  # the machine profile's tcp: its control runs tool-tip kinematics always
# A feed block whose tool axis turns more than this (deg, along its path) is a reorientation,
# not a cut ncopt plans: real finishing turns it a few degrees a block (LinuxCNC's 5-axis
# demos: at most 7.6 deg on their cuts; 48 deg on the impeller's links between blades).
MAX_TURN_DEG = 30.0
# Under Fanuc G43.5 Q a block whose start axis leans toward the last block's direction and
# toward its own this far apart (deg) is not planned: at 0.25 deg and a 15 deg lead R_eff is
# off by at most 1.6 % at its start, nothing at its end.
MAX_LEAN_GAP_DEG = 0.25
_SWITCHES = "G43.4/G43.5, TRAORI, M128 or FUNCTION TCPM, LinuxCNC's M428"
_NOT_STATED = ("the program {where}: where {c} stands{until} is not known (ncopt takes no "
               "rotary axis at 0); state {c} before the first move")

# G codes x10, as the interpreter keeps them
G_VECTOR_TCP = 435  # G43.5: tool vectors in I J K
G_TCP_ON = {434, 435, 2340}  # G43.4 G43.5, Haas G234
G_LENGTH_GROUP = {430, 440, 434, 435, 490, 2340}  # G43 G44 G43.4 G43.5 G49 G234
G_HOME = {280, 281, 300, 301}  # G28 G30: may turn every rotary axis
G_CALLS = {650, 660}  # G65 G66 macro calls
G_NOT_POSITION = G_CALLS | {71}  # their A B C are arguments; G07.1 C: a radius
M_CALLS = {98, 99}
M_TCP_ON, M_TCP_OFF = {128, 428}, {129, 429}

# Sinumerik and Heidenhain keywords (the opaque lines' heads, upper case)
KW_TCP = {"TRAORI", "TRAFOOF", "ORIWKS", "ORIMKS", "ORIAXES", "ORIVECT", "FUNCTION"}

# Sinumerik orientation addresses ncopt does not read (A3= B3= C3= with a number are words)
_ORIENTATION_ADDRESS = re.compile(r"^(?:[ABC][2-7]|LEAD|TILT|THETA|PHI|PSI)$", re.IGNORECASE)


@dataclass(frozen=True)
class Orientation:
    """What ncopt knows of the tool axis, per source line (``n = n_lines``).

    Attributes
    ----------
    blocked : (n,) int16
        0 where a move on that line has a known tool axis at both ends (and
        ncopt can follow it in between); else an index into ``reasons``.
    reasons : tuple[str, ...]
        ``reasons[0] == ""``; the others say what tilts the tool and what to do.
    rotary_move : (n,) bool
        The line moves a rotary axis: a move even without X Y Z words.
    axis : (n, 3) float64
        Unit tool axis after each line, part frame (+Z where not known).
    angles_deg : (n, 3) float64
        A B C after each line where the axis comes from a kinematics (NaN
        elsewhere): a block between two such lines turns the angles linearly.
    kinematics : str or None
        Name of the kinematics that gave axes, ``"vector"`` for a program of
        tool vectors, None when the tool never tilts.
    frame : (n,) int32
        Index into ``frames`` of the tilted working plane in force, -1 none.
    frames : tuple
        ``(origin_mm (3,), R (3, 3))`` per plane: ``p_part = origin + R p``.
    """

    blocked: np.ndarray
    reasons: tuple
    rotary_move: np.ndarray
    axis: np.ndarray
    angles_deg: np.ndarray
    kinematics: str | None = None
    frame: np.ndarray | None = None
    frames: tuple = ()


class _Reasons:
    """Interned reason texts (index 0: none)."""

    def __init__(self) -> None:
        self.texts = [""]

    def code(self, text: str) -> int:
        if text not in self.texts:
            self.texts.append(text)
        return self.texts.index(text)


def _ffill(values, initial=np.nan):

    return ffill(values, initial)


def _before(a: np.ndarray, first) -> np.ndarray:
    """``a`` shifted one line down: the state in force when each line starts."""
    return np.concatenate(([first] if np.ndim(a) == 1 else [first], a[:-1]))


def read_orientation(prog, lines, modal, executed: np.ndarray,
                     kinematics: str | None = None,
                     tcp: str | None = None) -> Orientation | None:
    """The tool axis per line, or None when nothing in the program tilts the tool.

    ``lines`` and ``modal`` are the interpreter's line table and modal state
    (``ncopt.motion.interp``); ``executed`` (n,) the lines the control runs;
    ``kinematics`` a name of :data:`ncopt.motion.kinematics.NAMES` or None; ``tcp``
    ``"always"`` where the machine's control runs tool-tip kinematics for every
    program (the machine profile says so), None: as the program switches it.
    """
    keywords = _keywords(prog, executed)
    rotary = [c for c in ROTARY if _positions_of(lines, c).any()]
    # the codes alone, not per-line arrays: a 3-axis program pays a few milliseconds here
    flagged = np.isin(lines.g_code, list(G_FRAME_ON | G_FRAME_OFF | G_TCP_ON
                                          | {G_ROTATION, G_ALIGN})).any() \
        or np.isin(lines.m_code, list(M_TCP_ON)).any() \
        or any(chr(c) in lines.letters for c in VECTOR_WORD_CODES.values())
    if not rotary and not keywords and not flagged:
        return None
    r = _Reasons()
    angle, move, unknown = _rotary_positions(prog, lines, modal, executed, r)
    tcp_on, tcp_explicit, switch = _tcp(prog, lines, executed, keywords, tcp == TCP_ALWAYS)
    why = np.zeros(lines.n, dtype=np.int16)
    axis, angles, spin_why = _from_angles(angle, unknown, rotary, kinematics,
                                          (tcp_on, tcp_explicit), why, r)
    vec, vec_why = _vectors(prog, lines, executed, keywords, tcp_on, r)
    has_vec = ~np.isnan(vec).any(axis=1)
    axis[has_vec], angles[has_vec] = unit(vec[has_vec]), np.nan
    why = np.where(vec_why > 0, vec_why, np.where(has_vec, 0, why))
    frame, planes, frame_why = frames(prog, lines, modal, executed, keywords, rotary, r)
    in_frame = frame >= 0
    for k, (_, rot) in enumerate(planes):
        axis[frame == k] = rot @ Z
    angles[in_frame] = np.nan
    why = np.where(in_frame, 0, why)
    why = np.where(frame_why > 0, frame_why, why).astype(np.int16)
    blocked = _moves(lines, modal, executed, axis, angles, why, switch, frame, r, tcp_on,
                     np.where(has_vec | in_frame, 0, spin_why), kinematics)
    blocked[~executed] = 0
    used = (kinematics if np.isfinite(angles).any() and kinematics != VECTOR else
            VECTOR if has_vec.any() else None)
    return Orientation(blocked=blocked, reasons=tuple(r.texts), rotary_move=move, axis=axis,
                       angles_deg=angles, kinematics=used, frame=frame, frames=tuple(planes))


def _tcp_changed(lines, executed, tcp_on) -> np.ndarray:
    """(n,) bool: TCP was switched on or off since the last line with axis words."""
    moved = np.zeros(lines.n, dtype=bool)
    for c in "XYZ" + ROTARY + "".join(chr(v) for v in VECTOR_WORD_CODES.values()):
        moved |= lines.present(c)
    moved &= executed
    change = np.concatenate(([False], tcp_on[1:] != tcp_on[:-1]))
    count = np.cumsum(change)
    idx = np.arange(lines.n)
    last_move = np.maximum.accumulate(np.where(moved, idx, -1))
    before = np.concatenate(([-1], last_move[:-1]))  # the last move line before each line
    return moved & (count - np.where(before >= 0, count[np.maximum(before, 0)], 0) > 0)


def _moves(lines, modal, executed, axis, angles, why, switch, frame, r, tcp_on, spin_why,
           kinematics) -> np.ndarray:
    """(n,) reason a move on each line is not planned: its start or end axis is not
    known, it tilts the tool from a vertical stand whose spin axis is not known, it is
    an arc that turns the tool (or any arc under G43.5), a block whose tool axis turns
    more than :data:`MAX_TURN_DEG`, it switches TCP on with the tool tilted, or it
    starts in another frame."""
    blocked = np.where(why > 0, why, _before(why, 0)).astype(np.int16)
    start = _before(axis, Z)
    start_angles = _before(angles, np.full(3, np.nan))
    tilted = np.abs(axis[:, :2]).sum(1) > 1e-12
    turns = (np.abs(axis - start).sum(1) > 1e-12) | np.any(
        (angles != start_angles) & np.isfinite(angles) & np.isfinite(start_angles), axis=1)
    spin = np.where(turns, np.maximum(_before(spin_why, 0), spin_why), 0)
    blocked = np.where((blocked == 0) & executed, spin, blocked).astype(np.int16)
    arc = np.isin(modal.motion, [20, 30])
    feed = np.isin(modal.motion, [10, 20, 30]) & turns & executed & (blocked == 0)
    turn = np.zeros(lines.n)
    turn[feed] = turn_deg(start[feed], axis[feed], start_angles[feed], angles[feed],
                          kinematics, MAX_TURN_DEG)
    for i in np.flatnonzero(turn > MAX_TURN_DEG).tolist():
        blocked[i] = r.code(f"the tool axis turns {turn[i]:.0f} deg within this block: a "
                            f"reorientation, not a cut ncopt plans (at most {MAX_TURN_DEG:g} "
                            "deg a block)")
    length = _ffill(np.where(executed, lines.g_group(G_LENGTH_GROUP), np.nan), 490.0)
    rules = (
        (arc & turns, "an arc that turns the tool: ncopt keeps the tool axis fixed on arcs"),
        (arc & (length == G_VECTOR_TCP), "an arc under G43.5, where I J K give the tool "
         "vector"),
        (switch & (tilted | _before(tilted, False)), "the block that switches tool-centre-"
         "point control on does not move under it"),
        (_tcp_changed(lines, executed, tcp_on) & _before(tilted, False),
         "the first move after tool-centre-point control was switched with the tool tilted "
         "starts from a machine position"),
        (frame != _before(frame, -1), "the first move in a new tilted working plane"),
    )
    for mask, text in rules:
        hit = mask & executed & (blocked == 0)
        if hit.any():
            blocked[hit] = r.code(text)
    return blocked


def tcp_switches(prog) -> np.ndarray:
    """(n_lines,) bool: the Sinumerik TCP and orientation-mode lines (TRAORI, TRAFOOF,
    ORIWKS...), which ncopt reads here: they use no S or F, so they need not run with
    the program's own (they stay opaque, never edited)."""
    out = np.zeros(prog.n_lines, dtype=bool)
    for i, head in prog.opaque_reason.items():
        if head.upper() in KW_TCP - {"FUNCTION"}:
            out[i] = True
    return out


def _keywords(prog, executed) -> dict:
    """{0-based line: keyword} of the executed opaque lines that concern the tool axis."""
    wanted = KW_SWIVEL | KW_ROTATIONS | KW_FRAME_OFF | KW_TCP | {"TRANS"}
    return {i: why.upper() for i, why in prog.opaque_reason.items()
            if (why.upper() in wanted or _ORIENTATION_ADDRESS.match(why)) and executed[i]}


def _from_angles(angle, unknown, rotary, kinematics, tcp, why, r):
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
                f"(none of {_SWITCHES} in force): X Y Z are machine positions, "
                "ncopt cannot place the tool tip; switch it on for these moves")
    fits = fitting(rotary) if kinematics is None else ""
    todo = f", with --kinematics {fits} as the machine is built" if fits else ""
    return (f"the rotary axes ({names}) are turned and the program never switches "
            f"tool-centre-point control on ({_SWITCHES}): X Y Z are then machine "
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


def _tcp(prog, lines, executed, keywords, always: bool = False):
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
        state |= _ffill(st, 0.0) > 0
    return state, True, on


def _positions_of(lines, c: str) -> np.ndarray:
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
    any_axis = np.zeros(n, dtype=bool)
    for c in "XYZ" + ROTARY:
        any_axis |= lines.present(c)
    home_all = lines.has_g(G_HOME) & ~any_axis
    other = np.zeros(n, dtype=bool)
    why_line = np.zeros(n, dtype=np.int16)
    for i, head in prog.opaque_reason.items():
        up = head.upper()
        if not executed[i] or up in HARMLESS_OPAQUE or _ORIENTATION_ADDRESS.match(head):
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


def _rotary_positions(prog, lines, modal, executed, r):
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
        present = _positions_of(lines, c)
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
        pos = _ffill(np.where(absolute, value - cum, np.nan), np.nan) + cum
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


def _vectors(prog, lines, executed, keywords, tcp_on, r):
    """Tool vector in force after each line (n, 3), NaN where none, and why a line's
    vector cannot be used (n,) int16.  Raises NcoptError for a vector of zero length."""
    n = lines.n
    vec = np.full((n, 3), np.nan)
    why = np.zeros(n, dtype=np.int16)
    length = _ffill(np.where(executed, lines.g_group(G_LENGTH_GROUP), np.nan), 490.0)
    fanuc = (length == G_VECTOR_TCP) & executed
    sinumerik = _sinumerik_section(prog, lines, executed, keywords)
    for active, letters, name in ((fanuc, "IJK", "G43.5 I J K"),
                                  (sinumerik & tcp_on, [chr(c) for c in VECTOR_WORD_CODES.values()],
                                   "A3= B3= C3=")):
        if not active.any():
            continue
        got = _vector_in_force(prog, lines, active, letters, name)
        vec = np.where(np.isnan(got), vec, got)
    codes = [chr(c) for c in VECTOR_WORD_CODES.values()]
    stray = np.full(n, np.nan)  # A3= where TRAORI is not in force: until TRAORI or TRAFOOF
    for c in codes:
        stray[lines.present(c) & executed & ~(sinumerik & tcp_on)] = 1.0
    for i, head in keywords.items():
        if head in ("TRAORI", "TRAFOOF"):
            stray[i] = 0.0
    why[_ffill(stray, 0.0) > 0] = r.code("A3= B3= C3= without TRAORI in force; ncopt does "
                                         "not read them")
    why[_orientation_opaque(prog, lines, executed, keywords)] = r.code(
        "Sinumerik orientation given in a form ncopt does not read (A2=, A4=, LEAD=, a "
        "computed A3=...); only A3= B3= C3= with numbers are read")
    mks = _keyword_state(lines.n, keywords, {"ORIMKS"}, {"ORIWKS", "TRAFOOF"}, lines, executed)
    has = ~np.isnan(vec).any(axis=1)
    why[has & mks] = r.code("ORIMKS: tool vectors in machine coordinates are not read; "
                            "program them with ORIWKS")
    return vec, why


def _vector_in_force(prog, lines, active, letters, name) -> np.ndarray:
    """(n, 3) the vector given in the section ``active`` (NaN before the first)."""
    idx = np.arange(lines.n)
    has = np.zeros(lines.n, dtype=bool)
    for c in letters:
        has |= lines.present(c)
    has &= active
    comp = np.stack([np.nan_to_num(lines.value(c)) for c in letters], axis=1)
    zero = has & (np.linalg.norm(comp, axis=1) == 0)
    if zero.any():
        i = int(np.flatnonzero(zero)[0])
        raise NcoptError(f"the tool vector ({name}) has no direction; give the tool axis",
                         prog.path, i + 1, 1)
    starts = active & ~_before(active, False)
    last_set = np.maximum.accumulate(np.where(has, idx, -1))
    last_start = np.maximum.accumulate(np.where(starts, idx, -1))
    given = active & (last_set >= 0) & (last_set >= last_start)
    return np.where(given[:, None], comp[np.maximum(last_set, 0)], np.nan)


def _keyword_state(n, keywords, on_words, off_words, lines, executed) -> np.ndarray:
    """(n,) bool: from a line with a keyword of ``on_words`` until one of ``off_words``."""
    state = np.full(n, np.nan)
    for i, head in keywords.items():
        if head in on_words:
            state[i] = 1.0
        elif head in off_words:
            state[i] = 0.0
    state[lines.has_m({2, 30}) & executed] = 0.0
    return _ffill(state, 0.0) > 0


def _sinumerik_section(prog, lines, executed, keywords) -> np.ndarray:
    """(n,) bool: from TRAORI until TRAFOOF (or the program end)."""
    return _keyword_state(lines.n, keywords, {"TRAORI"}, {"TRAFOOF"}, lines, executed)


def _orientation_opaque(prog, lines, executed, keywords) -> np.ndarray:
    """(n,) bool: from a Sinumerik orientation ncopt does not read until TRAFOOF."""
    heads = {i: "ORI" for i, h in keywords.items() if _ORIENTATION_ADDRESS.match(h)}
    heads.update({i: h for i, h in keywords.items() if h == "TRAFOOF"})
    return _keyword_state(lines.n, heads, {"ORI"}, {"TRAFOOF"}, lines, executed)


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
    r = _Reasons()
    r.texts = list(o.reasons)
    travel = pos_mm - _before(pos_mm, np.zeros(3))
    moving = np.abs(travel).sum(axis=1) > 0
    switch = lines.g_group(G_LENGTH_GROUP) == G_VECTOR_TCP  # moves without TCP: keeps the axis
    moves = active & np.isin(modal.motion, [0, 10]) & moving & ~switch
    vector = np.zeros(lines.n, dtype=bool)
    for c in "IJK":
        vector |= lines.present(c)
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
    why[lost] = _ffill(code, 0.0)[lost]
    own = ~active | moves | unknown  # the other lines keep the axis of the line before
    src = np.maximum.accumulate(np.where(own, np.arange(lines.n), 0))
    axis = np.where(moves[:, None], leaned, o.axis)[src]
    why = why[src]
    axis[why > 0] = Z  # not known: never used (its moves are not planned)
    blocked = np.where(why > 0, why, _before(why, 0)).astype(np.int16)
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
    section = _ffill(np.where(np.isfinite(length), tcp_g, np.nan), 0.0) > 0
    stray = lines.present("Q") & executed & section & ~g435
    stray &= ~np.isin(modal.motion, list(CANNED))
    state[stray] = np.inf
    q = _ffill(state, 0.0)
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


def with_tool_axis(tp, o: Orientation):
    """``tp`` (a :class:`~ncopt.model.Toolpath` in programmed coordinates) in the part
    frame with its tool axis per point (and the rotary angles where a kinematics gave
    it: between two such points the angles turn linearly); points in a tilted working
    plane are carried into the part frame.  ``tool_axis`` stays None where every axis
    is +Z."""
    if tp.n < 2:
        return tp
    line = np.maximum(tp.line, 0)
    start = tp.line < 0
    axis = np.where(start[:, None], Z, o.axis[line])
    angles = np.where(start[:, None], np.nan, o.angles_deg[line])
    xyz = tp.xyz_mm
    if o.frames:
        xyz = xyz.copy()
        frame_of = np.where(start, -1, o.frame[line])
        for k, (org, rot) in enumerate(o.frames):
            sel = frame_of == k
            xyz[sel] = org + xyz[sel] @ rot.T
    if np.all(axis == Z):
        return replace(tp, xyz_mm=xyz, kinematics=o.kinematics)
    turned = np.isfinite(angles).all(axis=1)
    return replace(tp, xyz_mm=xyz, tool_axis=axis, kinematics=o.kinematics,
                   tool_angles_deg=angles if turned.any() else None)
