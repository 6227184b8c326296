"""Where the tool points in every block: rotary axes, tool vectors, tilted planes.

ncopt plans a move only when it knows the tool axis ``e`` (unit, from the tip
toward the spindle, in the part frame) at both its ends.  A 3-axis program
never mentions anything below, its tool axis is +Z and the reader returns
``None`` (no cost).  Everything that can turn the tool away from +Z is read
here, per source line; a move whose axis ncopt cannot know is left as
programmed with a located reason.

* Rotary axis words ``A B C`` (degrees; G90/G91 as the linear axes).  Before
  the first one a rotary axis stands at 0, as a 3-axis program assumes.  Where
  one is not 0 the machine's kinematics gives ``e`` (``ncopt.kinematics``,
  ``--kinematics``).  Their position is lost after a move that can turn them
  without saying where to (G28/G30, offsets set with rotary words, a call, a
  swivel, G53.1, a construct ncopt does not interpret) until stated again.
* Tool-centre-point control (TCP): with it the programmed X Y Z are the tool
  tip in the part frame.  Switched on by Sinumerik ``TRAORI``, Fanuc
  ``G43.4``/``G43.5``, Haas ``G234``, Heidenhain ``M128``/``FUNCTION TCPM``, the
  LinuxCNC 5-axis configurations' ``M428``; off by ``TRAFOOF``, ``G49`` (or
  ``G43``/``G44``), ``M129``, ``FUNCTION RESET TCPM``, ``M429``, M2/M30.  A program
  that never switches it is taken as running under the kinematics given (as
  LinuxCNC's trt kinematics always do).  A tilted tool with TCP switched off:
  X Y Z are machine positions, not planned.  The block that switches TCP on
  does not move under it (Fanuc): not planned when the tool is tilted.
* Tool vectors, which need no machine data: Fanuc ``G43.5`` ``I J K`` (a
  component left out of a block is 0; none given, the last vector holds) and
  Sinumerik ``A3= B3= C3=`` under ``TRAORI`` (same rule; orientation in the
  workpiece frame, ORIWKS, the default; ``ORIMKS`` is not read).  Other
  Sinumerik orientation addresses (``A2=``, ``A4=``, ``LEAD=``...) are not read.
* Tilted working planes (3+2): ``ncopt.planes``.
* Arcs keep the tool axis: an arc that turns it is not planned, nor any arc
  under G43.5 (its I J K would be both centre and vector).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from .errors import NcoptError
from .kinematics import KINEMATICS, VECTOR, unit
from .model import VECTOR_WORD_CODES
from .planes import (G_ALIGN, G_FRAME_OFF, G_FRAME_ON, G_ROTATION, KW_FRAME_OFF,
                     KW_ROTATIONS, KW_SWIVEL, cycle800_args, frames)

ROTARY = "ABC"
Z = np.array([0.0, 0.0, 1.0])

# G codes x10, as the interpreter keeps them
G_VECTOR_TCP = 435  # G43.5: tool vectors in I J K
G_TCP_ON = {434, 435, 2340}  # G43.4 G43.5, Haas G234
G_LENGTH_GROUP = {430, 440, 434, 435, 490, 2340}  # G43 G44 G43.4 G43.5 G49 G234
G_HOME = {280, 281, 300, 301}  # G28 G30: may turn every rotary axis
G_CALLS = {650, 660}  # G65 G66 macro calls
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
    from .interp import ffill

    return ffill(values, initial)


def _before(a: np.ndarray, first) -> np.ndarray:
    """``a`` shifted one line down: the state in force when each line starts."""
    return np.concatenate(([first] if np.ndim(a) == 1 else [first], a[:-1]))


def read_orientation(prog, lines, modal, executed: np.ndarray,
                     kinematics: str | None = None) -> Orientation | None:
    """The tool axis per line, or None when nothing in the program tilts the tool.

    ``lines`` and ``modal`` are the interpreter's line table and modal state
    (``ncopt.interp``); ``executed`` (n,) the lines the control runs;
    ``kinematics`` a name of :data:`ncopt.kinematics.NAMES` or None.
    """
    keywords = _keywords(prog, executed)
    rotary = [c for c in ROTARY if c in lines.letters]
    # the codes alone, not per-line arrays: a 3-axis program pays a few milliseconds here
    flagged = np.isin(lines.g_code, list(G_FRAME_ON | G_FRAME_OFF | G_TCP_ON
                                          | {G_ROTATION, G_ALIGN})).any() \
        or np.isin(lines.m_code, list(M_TCP_ON)).any() \
        or any(chr(c) in lines.letters for c in VECTOR_WORD_CODES.values())
    if not rotary and not keywords and not flagged:
        return None
    r = _Reasons()
    angle, move, lost = _rotary_positions(prog, lines, modal, executed, r)
    tcp_on, tcp_explicit, switch = _tcp(prog, lines, executed, keywords)
    why = np.zeros(lines.n, dtype=np.int16)
    axis, angles = _from_angles(angle, lost, rotary, kinematics, tcp_on, tcp_explicit, why, r)
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
    blocked = _moves(lines, modal, executed, axis, angles, why, switch, frame, r, tcp_on)
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


def _moves(lines, modal, executed, axis, angles, why, switch, frame, r, tcp_on) -> np.ndarray:
    """(n,) reason a move on each line is not planned: its start or end axis is not
    known, it is an arc that turns the tool (or any arc under G43.5), it switches
    TCP on with the tool tilted, or it starts in another frame."""
    blocked = np.where(why > 0, why, _before(why, 0)).astype(np.int16)
    start = _before(axis, Z)
    tilted = np.abs(axis[:, :2]).sum(1) > 1e-12
    turns = (np.abs(axis - start).sum(1) > 1e-12) | ~np.all(
        (angles == _before(angles, np.full(3, np.nan))) | np.isnan(angles), axis=1)
    arc = np.isin(modal.motion, [20, 30])
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


def _from_angles(angle, lost, rotary, kinematics, tcp_on, tcp_explicit, why, r):
    """Axis (n, 3) and angles (n, 3) from the rotary positions; fills ``why`` in place."""
    n = angle.shape[0]
    axis = np.tile(Z, (n, 1))
    angles = np.full((n, 3), np.nan)
    tilted = np.any(np.abs(np.nan_to_num(angle)) > 1e-9, axis=1)
    kin = KINEMATICS.get(kinematics)
    names = ", ".join(rotary) or "rotary axes"
    if kin is None:
        fits = [k.name for k in KINEMATICS.values() if set(rotary) <= set(k.axes)]
        choice = (", ".join(fits[:-1]) + " or " + fits[-1]) if len(fits) > 1 else \
            (fits[0] if fits else "")
        todo = f"pass --kinematics {choice} as the machine is built" if fits else \
            f"ncopt knows no kinematics that turns {' and '.join(rotary)}"
        what = ("--kinematics vector reads tool vectors, and these blocks turn the rotary "
                f"axes ({names}); {todo}" if kinematics == VECTOR else
                f"the rotary axes ({names}) tilt the tool and no kinematics is given; {todo}")
        why[tilted] = r.code(what)
    else:
        foreign = [c for c in rotary if c not in kin.axes]
        bad = np.zeros(n, dtype=bool)
        for c in foreign:
            bad |= np.abs(np.nan_to_num(angle[:, ROTARY.index(c)])) > 1e-9
        why[bad] = r.code(f"the program turns {', '.join(foreign)}, which {kin.name} does not "
                          "have; pass the machine's kinematics")
        known = ~np.isnan(angle).any(axis=1)
        axis[known & tilted] = kin.tool_axis(angle[known & tilted])
        angles[known] = angle[known]
        off = tilted & tcp_explicit & ~tcp_on
        why[off & (why == 0)] = r.code(
            "the tool is tilted with tool-centre-point control off (no TRAORI, G43.4, M128 or "
            "M428 in force): X Y Z are machine positions, ncopt cannot place the tool tip")
    why[lost > 0] = lost[lost > 0]
    return axis, angles


def _tcp(prog, lines, executed, keywords):
    """TCP on after each line, whether the program ever switches it, and the lines
    that switch it on.  Each switch ends only with its own off code: G43.4/G43.5
    (and Haas G234) with the rest of their modal group (G43, G44, G49), M128 with
    M129, M428 with M429, TRAORI with TRAFOOF, FUNCTION TCPM with its RESET."""
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
    if not on.any():  # never switched: the kinematics given run the program (LinuxCNC's do)
        return np.ones(lines.n, dtype=bool), False, on
    end = lines.has_m({2, 30}) & executed
    state = np.zeros(lines.n, dtype=bool)
    for sw_on, sw_off in ((g_on, g_off), (m_on, m_off)):
        st = np.full(lines.n, np.nan)
        st[sw_off | end] = 0.0
        st[sw_on] = 1.0
        state |= _ffill(st, 0.0) > 0
    return state, True, on


def _rotary_positions(prog, lines, modal, executed, r):
    """Rotary positions after each line, moves of them, and where they are lost.

    Returns angle (n, 3) degrees after each line (NaN: unknown), rotary_move
    (n,) bool and lost (n,) int16: a reason code from the line where the
    position was lost, on every line until it is stated again.
    """
    from .interp import G_NON_MODAL_MOVE, HARMLESS_OPAQUE

    n = lines.n
    g53 = lines.has_g({530})  # a machine position: taken as the rotary position (no offsets)
    special = lines.has_g(G_NON_MODAL_MOVE) & ~g53
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
    angle = np.zeros((n, 3))
    lost = np.zeros(n, dtype=np.int16)
    move = np.zeros(n, dtype=bool)
    lost_all = (home_all | calls | other | align) & executed
    idx = np.arange(n)
    for k, c in enumerate(ROTARY):
        if not lines.present(c).any():  # an axis the program never names stays at 0
            continue
        value = lines.value(c)
        present = lines.present(c) & executed
        gone_here = present & (special | np.isnan(value))
        for i in np.flatnonzero(gone_here & ~lost_all).tolist():
            why_line[i] = r.code(f"the rotary axis position is not known after the {c} word "
                                 f"of line {i + 1} (G28/G30/G10/G92 or a value ncopt cannot "
                                 "compute); state it again")
        ok = present & ~special & ~np.isnan(value)
        move |= ok & ~g53
        absolute = ok & (modal.absolute | g53)
        cum = np.cumsum(np.where(ok & ~absolute, value, 0.0))
        pos = _ffill(np.where(absolute, value - cum, np.nan), 0.0) + cum
        last_abs = np.maximum.accumulate(np.where(absolute, idx, -1))
        last_lost = np.maximum.accumulate(np.where(lost_all | gone_here, idx, -1))
        gone = last_lost > last_abs
        pos[gone] = np.nan
        angle[:, k] = pos
        first = np.where(gone, why_line[np.maximum(last_lost, 0)], 0)
        lost = np.where((lost == 0) & gone, first, lost).astype(np.int16)
    return angle, move, lost


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


def with_tool_axis(tp, o: Orientation):
    """``tp`` (a :class:`~ncopt.model.Toolpath` in programmed coordinates) in the part
    frame with its tool axis per point (and the rotary angles where a kinematics gave
    it: between two such points the angles turn linearly); points in a tilted working
    plane are carried into the part frame.  ``tool_axis`` stays None where every axis
    is +Z."""
    from dataclasses import replace

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
