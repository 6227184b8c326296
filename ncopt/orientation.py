"""Where the tool points in every block: rotary axes, tool vectors, tilted planes.

ncopt plans a move only when it knows the tool axis ``e`` there.  A 3-axis
program never mentions anything below and its tool axis is +Z (the reader
returns ``None`` and costs nothing).  Everything that can turn the tool away
from +Z is read here, per source line, and a move whose axis ncopt cannot
know is left as programmed with a located reason:

* rotary axis words ``A B C`` (degrees; G90/G91 as the linear axes).  Before
  the first one a rotary axis stands at 0, as a 3-axis program assumes.  Where
  any of them is not 0 the tool may be tilted: the machine's kinematics
  decides (``--kinematics``).  Their position is unknown after a move that can
  turn them without saying where to (G28/G30, offsets set with rotary words,
  a subprogram call, a construct ncopt does not interpret, a swivel cycle);
* tool vectors: Fanuc ``G43.5`` with ``I J K``, Sinumerik ``A3= B3= C3=``;
* tilted working planes (3+2): Fanuc ``G68.2``/``G68.3``/``G68.4`` and a
  ``G68`` that turns about X or Y, Haas ``G254``/``G268``, Sinumerik
  ``CYCLE800`` and the frame rotations ``ROT``/``AROT`` about X or Y,
  ``TOFRAME``, ``TOROT``, ``TCARR``, Heidenhain ``PLANE``.

The tool-centre-point switches (Sinumerik ``TRAORI``, Fanuc ``G43.4``/``G43.5``,
Heidenhain ``M128``, the LinuxCNC 5-axis configurations' ``M428``) change
what X Y Z mean while the tool is tilted; with the tool vertical they change
nothing.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

ROTARY = "ABC"

# G codes x10, as the interpreter keeps them
G_FRAME_ON = {682, 683, 684, 2540, 2680}  # G68.2-G68.4, Haas DWO G254 and G268
G_FRAME_OFF = {690, 2550, 2690}  # G69, G255, G269
G_ROTATION = 680  # G68: a tilt when it turns about X or Y (I/J/K given, or G18/G19)
G_VECTOR_TCP = 435  # G43.5: tool vectors in I J K
G_LENGTH_GROUP = {430, 440, 434, 435, 490, 2340}  # G43 G44 G43.4 G43.5 G49 (Haas G234)
G_HOME = {280, 281, 300, 301}  # G28 G30: may turn every rotary axis
G_OFFSETS = {100, 520, 920, 921, 922, 923}  # G10 G52 G92...: offsets of the named axes
G_CALLS = {650, 660}  # G65 G66 macro calls
M_CALLS = {98, 99}

# Sinumerik and Heidenhain keywords (the opaque lines' heads, upper case)
KW_SWIVEL = {"CYCLE800", "PLANE", "TCARR", "TOFRAME", "TOFRAMEX", "TOFRAMEY", "TOFRAMEZ",
             "TOROT", "TOROTX", "TOROTY", "TOROTZ", "PAROT"}
KW_ROTATIONS = {"ROT", "AROT", "ROTS", "AROTS", "CROTS"}
KW_FRAME_OFF = {"TOROTOF", "PAROTOF"}
KW_TCP = {"TRAORI", "TRAFOOF", "ORIWKS", "ORIMKS", "ORIAXES", "ORIVECT", "FUNCTION"}

_ARGS = re.compile(r"\(([^()]*)\)")
_TILT_WORDS = re.compile(r"\b[XY]\s*=|\bRPL\s*=", re.IGNORECASE)
_NUMBER = re.compile(r"\s*[+-]?(?:\d+\.?\d*|\.\d+)\s*$")
# Sinumerik orientation addresses: Euler/RPY angles, vectors, normals, lead and tilt
_ORIENTATION_ADDRESS = re.compile(r"^(?:[ABC][2-7]|LEAD|TILT|THETA|PHI|PSI)$", re.IGNORECASE)


@dataclass(frozen=True)
class Orientation:
    """What ncopt knows of the tool axis, per source line.

    Attributes
    ----------
    blocked : (n_lines,) int16
        0 where the tool axis of a move on that line is known (+Z); else an
        index into ``reasons``: why a move there is left as programmed.
    reasons : tuple[str, ...]
        ``reasons[0] == ""``; the others say what tilts the tool and what to do.
    rotary_move : (n_lines,) bool
        The line moves a rotary axis: a move even without X Y Z words (its
        feed stays as programmed).
    """

    blocked: np.ndarray
    reasons: tuple
    rotary_move: np.ndarray


class _Reasons:
    """Interned reason texts (index 0: none)."""

    def __init__(self) -> None:
        self.texts = [""]

    def code(self, text: str) -> int:
        if text not in self.texts:
            self.texts.append(text)
        return self.texts.index(text)


def read_orientation(prog, lines, modal, executed: np.ndarray,
                     kinematics: str | None = None) -> Orientation | None:
    """The tool axis per line, or None when nothing in the program tilts the tool.

    ``lines`` and ``modal`` are the interpreter's line table and modal state
    (``ncopt.interp``); ``executed`` (n_lines,) the lines the control runs.
    """
    keywords = _keywords(prog, executed)
    rotary = [c for c in ROTARY if lines.present(c).any()]
    tcp_g = lines.has_g(G_FRAME_ON | G_FRAME_OFF | {G_ROTATION, G_VECTOR_TCP, 434, 2340, 531})
    if not rotary and not keywords and not tcp_g.any():
        return None
    reasons = _Reasons()
    blocked = np.zeros(lines.n, dtype=np.int16)
    angle, move, unknown = _rotary_positions(prog, lines, modal, executed, keywords, reasons)
    tilted = np.any(np.abs(np.nan_to_num(angle)) > 1e-9, axis=1)
    start_tilted = np.concatenate(([False], tilted[:-1]))
    names = ", ".join(rotary) or "rotary axes"
    need = reasons.code(f"the rotary axes ({names}) tilt the tool and no kinematics is given; "
                        "pass --kinematics NAME as the machine is built")
    blocked[(tilted | start_tilted) & executed] = need
    start_unknown = np.concatenate(([0], unknown[:-1]))
    lost = np.where(unknown > 0, unknown, start_unknown)
    blocked = np.where(lost > 0, lost, blocked).astype(np.int16)
    vector = _vector_lines(lines, executed) | _sinumerik_orientation(prog, lines, executed)
    blocked[vector] = reasons.code("tool vectors (G43.5 I J K, TRAORI A3= B3= C3=) tilt the "
                                   "tool; ncopt does not plan them")
    frame = _frames(prog, lines, modal, executed, keywords, reasons)
    blocked = np.where(frame > 0, frame, blocked).astype(np.int16)
    blocked[~executed] = 0
    return Orientation(blocked=blocked, reasons=tuple(reasons.texts), rotary_move=move)


def _keywords(prog, executed) -> dict:
    """{0-based line: keyword} of the executed opaque lines that concern the tool axis."""
    wanted = KW_SWIVEL | KW_ROTATIONS | KW_FRAME_OFF | KW_TCP | {"TRANS"}
    return {i: why.upper() for i, why in prog.opaque_reason.items()
            if (why.upper() in wanted or _ORIENTATION_ADDRESS.match(why)) and executed[i]}


def _rotary_positions(prog, lines, modal, executed, keywords, reasons):
    """Rotary positions after each line, moves of them, and where they are lost.

    Returns angle (n, 3) degrees after each line (NaN: unknown), rotary_move
    (n,) bool and unknown (n,) int16: a reason code from the line where the
    position was lost, on every line until it is stated again.
    """
    from .interp import G_NON_MODAL_MOVE, HARMLESS_OPAQUE, ffill

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
        if up == "CYCLE800" and _cycle800_args(prog.line_text(i)) in ((), "zero"):
            continue  # CYCLE800() only deselects; zero angles swivel to the vertical
        other[i] = True
        why_line[i] = reasons.code(f"the rotary axis position is not known after '{head}' "
                                   f"(line {i + 1}); state A/B/C again")
    align = lines.has_g({531})  # G53.1 turns the tool to the tilted plane's Z
    for mask, text in ((home_all, "G28/G30"), (calls, "a subprogram or macro call"),
                       (align, "G53.1")):
        for i in np.flatnonzero(mask & executed).tolist():
            why_line[i] = reasons.code(f"the rotary axis position is not known after {text} "
                                       f"(line {i + 1}); state A/B/C again")
    angle = np.zeros((n, 3))
    unknown = np.zeros(n, dtype=np.int16)
    move = np.zeros(n, dtype=bool)
    lost_all = (home_all | calls | other | align) & executed
    idx = np.arange(n)
    for k, c in enumerate(ROTARY):
        if not lines.present(c).any():  # an axis the program never names stays at 0
            continue
        value = lines.value(c)
        present = lines.present(c) & executed
        lost = lost_all | (present & (special | np.isnan(value)))
        for i in np.flatnonzero(present & (special | np.isnan(value)) & ~lost_all).tolist():
            why_line[i] = reasons.code(f"the rotary axis position is not known after the {c} "
                                       f"word of line {i + 1} (G28/G30/G10/G92 or a value "
                                       "ncopt cannot compute); state it again")
        ok = present & ~special & ~np.isnan(value)
        move |= ok & ~g53
        absolute = ok & (modal.absolute | g53)
        inc = np.where(ok & ~modal.absolute, value, 0.0)
        cum = np.cumsum(inc)
        base = np.where(absolute, value - cum, np.nan)
        pos = ffill(base, 0.0) + cum
        last_abs = np.maximum.accumulate(np.where(absolute, idx, -1))
        last_lost = np.maximum.accumulate(np.where(lost, idx, -1))
        gone = last_lost > last_abs
        pos[gone] = np.nan
        angle[:, k] = pos
        first = np.where(gone, why_line[np.maximum(last_lost, 0)], 0)
        unknown = np.where((unknown == 0) & gone, first, unknown).astype(np.int16)
    return angle, move, unknown


def _vector_lines(lines, executed) -> np.ndarray:
    """(n,) bool: moves under G43.5 whose tool vector (I J K) at either end is not +Z.

    Fanuc: I, J or K omitted in a block is 0; all omitted, the vector of the
    block before holds.  Until G43.5 gives one the rotary axes decide.
    """
    from .interp import ffill

    length = ffill(np.where(executed, lines.g_group(G_LENGTH_GROUP), np.nan), 490.0)
    active = (length == G_VECTOR_TCP) & executed
    if not active.any():
        return np.zeros(lines.n, dtype=bool)
    idx = np.arange(lines.n)
    has = (lines.present("I") | lines.present("J") | lines.present("K")) & active
    starts = active & ~np.concatenate(([False], active[:-1]))
    last_set = np.maximum.accumulate(np.where(has, idx, -1))
    last_start = np.maximum.accumulate(np.where(starts, idx, -1))
    given = active & (last_set >= last_start) & (last_set >= 0)
    vec = np.stack([np.nan_to_num(lines.value(c))[np.maximum(last_set, 0)] for c in "IJK"], 1)
    norm = np.linalg.norm(vec, axis=1)
    vertical = (np.abs(vec[:, 0]) + np.abs(vec[:, 1]) <= 1e-9 * norm) & (vec[:, 2] > 0)
    tilted = given & ~vertical
    return active & (tilted | np.concatenate(([False], tilted[:-1])))


def _sinumerik_orientation(prog, lines, executed) -> np.ndarray:
    """(n,) bool: lines from a Sinumerik orientation (A3=, LEAD=...) until TRAFOOF."""
    from .interp import ffill

    state = np.full(lines.n, np.nan)
    for i, head in prog.opaque_reason.items():
        if executed[i] and _ORIENTATION_ADDRESS.match(head):
            state[i] = 1.0
        elif executed[i] and head.upper() == "TRAFOOF":
            state[i] = 0.0
    if np.isnan(state).all():
        return np.zeros(lines.n, dtype=bool)
    state[lines.has_m({2, 30}) & executed] = 0.0
    return ffill(state, 0.0) > 0


def _frames(prog, lines, modal, executed, keywords, reasons) -> np.ndarray:
    """(n,) int16: the reason code of the tilted working plane in force on each line."""
    from .interp import ffill

    n = lines.n
    state = np.full(n, np.nan)  # reason code of the frame set on a line; 0 resets
    code_of = {}
    on = lines.has_g(G_FRAME_ON) & executed
    off = lines.has_g(G_FRAME_OFF) & executed
    rot = lines.has_g({G_ROTATION}) & executed
    tilting_68 = rot & (lines.present("I") | lines.present("J") | lines.present("K")
                        | (modal.plane != 170))
    for i in np.flatnonzero(on | tilting_68).tolist():
        code_of[i] = reasons.code(f"a tilted working plane (G68.x/G254/G268, line {i + 1}) "
                                  "is active; ncopt does not read its frame")
    for i, head in keywords.items():
        text = prog.line_text(i)
        if head in KW_SWIVEL:
            reset = (head == "CYCLE800" and _cycle800_args(text) in ((), "zero")) \
                or (head == "PLANE" and re.search(r"\bRESET\b", text, re.IGNORECASE)) \
                or (head == "TCARR" and re.search(r"=\s*0+\b", text))
            state[i] = 0.0 if reset else reasons.code(
                f"a tilted working plane ('{head}', line {i + 1}) is active; ncopt does not "
                "read its frame")
        elif head in KW_ROTATIONS and _TILT_WORDS.search(text):
            state[i] = reasons.code(f"a frame rotation about X or Y ('{head}', line {i + 1}) "
                                    "tilts the plane; ncopt does not read its frame")
        elif head in KW_FRAME_OFF or (head in ("ROT", "TRANS") and not _after(text, head)):
            state[i] = 0.0
    for i, code in code_of.items():
        state[i] = code
    state[off & np.isnan(state)] = 0.0
    state[lines.has_m({2, 30}) & executed] = 0.0
    return ffill(state, 0.0).astype(np.int16)


def _after(text: str, head: str) -> str:
    """What follows the keyword ``head`` on its line (comments dropped)."""
    at = text.upper().find(head)
    rest = text[at + len(head):] if at >= 0 else ""
    return re.sub(r"\([^()]*\)|;.*$", "", rest).strip()


def _cycle800_args(text: str):
    """CYCLE800's arguments: () for an empty call, ``"zero"`` when every angle
    (_A, _B, _C, the 8th-10th) is 0, else the argument strings."""
    m = _ARGS.search(text)
    if m is None or not m.group(1).strip():
        return ()
    args = [a.strip() for a in m.group(1).split(",")]
    angles = args[7:10]
    if angles and all(a == "" or (_NUMBER.match(a) and float(a) == 0.0) for a in angles):
        return "zero"
    return tuple(args)
