"""Tilted working planes (3+2): which are in force on each line, and the one ncopt reads.

Fanuc ``G68.2 X Y Z I J K`` (Euler angles, P0) followed by ``G53.1`` is read: the
positions are in the tilted frame, ``p_part = origin + R p`` with ``R =
Rz(I) Rx(J) Rz(K)`` (``ncopt.motion.kinematics.euler_zxz``), and the tool points along
its Z.  The others are recognised and not read, so the moves under them are
not planned until they are reset: G68.2 with P or R, ``G68.3``/``G68.4``, a ``G68``
about X or Y, Haas ``G254``/``G268``, Sinumerik ``CYCLE800`` (reset by
``CYCLE800()`` or zero angles), ``ROT``/``AROT``/``ROTS``/``AROTS``/``CROTS`` about X or
Y (reset by ``ROT`` or ``TRANS`` alone), ``TOFRAME``, ``TOROT``, ``TCARR``, ``PAROT``,
Heidenhain ``PLANE`` (reset by ``PLANE RESET``); M2/M30 reset all.  After any
change of plane the position is known again once X, Y and Z are given
absolutely.
"""

from __future__ import annotations

import re

import numpy as np

from ncopt.motion.kinematics import euler_zxz
from ncopt.motion.modal import G_NON_MODAL_MOVE, ffill

G_FRAME = 682  # G68.2, the tilted plane ncopt reads (with G53.1)
G_FRAME_ON = {682, 683, 684, 2540, 2680}  # G68.2-G68.4, Haas DWO G254 and G268
G_FRAME_OFF = {690, 2550, 2690}  # G69, G255, G269
G_ROTATION = 680  # G68: a tilt when it turns about X or Y (I/J/K given, or G18/G19)
G_ALIGN = 531  # G53.1: the tool turns to the tilted plane's Z

# Sinumerik and Heidenhain keywords (the opaque lines' heads, upper case)
KW_SWIVEL = {"CYCLE800", "PLANE", "TCARR", "TOFRAME", "TOFRAMEX", "TOFRAMEY", "TOFRAMEZ",
             "TOROT", "TOROTX", "TOROTY", "TOROTZ", "PAROT"}
KW_ROTATIONS = {"ROT", "AROT", "ROTS", "AROTS", "CROTS"}
KW_FRAME_OFF = {"TOROTOF", "PAROTOF"}

_ARGS = re.compile(r"\(([^()]*)\)")
_TILT_WORDS = re.compile(r"\b[XY]\s*=|\bRPL\s*=", re.IGNORECASE)
_NUMBER = re.compile(r"\s*[+-]?(?:\d+\.?\d*|\.\d+)\s*$")


def frames(prog, lines, modal, executed, keywords, rotary, r):
    """The tilted working plane in force per line.

    Returns frame (n,) int32 (index into the planes ncopt reads, -1 none), the
    planes ``[(origin_mm, R)]``, and (n,) int16 reason codes where a plane ncopt
    does not read (or a G68.2 before its G53.1) is in force.
    """
    n = lines.n
    state = np.full(n, np.nan)  # per setting line: reason code (> 0), 0 reset, -(k+1) plane k
    on = lines.has_g(G_FRAME_ON) & executed
    rot = lines.has_g({G_ROTATION}) & executed
    tilting_68 = rot & (lines.present_any("IJK")
                        | (modal.plane != 170))
    frames = []
    for i in np.flatnonzero(on | tilting_68).tolist():
        plane = _g68_2(lines, modal, i)
        if plane is not None:
            frames.append(plane)
            state[i] = -len(frames)
        else:
            state[i] = r.code(f"a tilted working plane (G68.x/G254/G268, line {i + 1}) is "
                              "active; ncopt reads G68.2 X Y Z I J K only")
    for i, head in keywords.items():
        text = prog.line_text(i)
        if head in KW_SWIVEL:
            reset = (head == "CYCLE800" and cycle800_args(text) in ((), "zero")) \
                or (head == "PLANE" and re.search(r"\bRESET\b", text, re.IGNORECASE)) \
                or (head == "TCARR" and re.search(r"=\s*0+\b", text))
            state[i] = 0.0 if reset else r.code(
                f"a tilted working plane ('{head}', line {i + 1}) is active; ncopt does not "
                "read its frame")
        elif head in KW_ROTATIONS and _TILT_WORDS.search(text):
            state[i] = r.code(f"a frame rotation about X or Y ('{head}', line {i + 1}) tilts "
                              "the plane; ncopt does not read its frame")
        elif head in KW_FRAME_OFF or (head in ("ROT", "TRANS") and not after_keyword(text, head)):
            state[i] = 0.0
    state[lines.has_g(G_FRAME_OFF) & executed & np.isnan(state)] = 0.0
    state[lines.has_m({2, 30}) & executed] = 0.0
    state = ffill(state, 0.0)
    frame = np.where(state < 0, -state - 1, -1).astype(np.int32)
    why = np.where(state > 0, state, 0).astype(np.int16)
    why[(frame >= 0) & ~_aligned(lines, executed, state, rotary)] = r.code(
        "G68.2 without G53.1 after it (or with rotary words since): ncopt cannot tell "
        "where the tool points")
    why[~_restated(lines, modal, executed, state)] = r.code(
        "the position in the new working plane is not known until X, Y and Z are given "
        "absolutely")
    return frame, frames, why


def _g68_2(lines, modal, i):
    """(origin_mm, R) of a G68.2 X Y Z I J K line (P0, Euler angles), else None."""
    if not lines.has_g({G_FRAME})[i] or lines.present("R")[i] or \
            (lines.present("P")[i] and lines.value("P")[i] != 0):
        return None
    if lines.has_g(G_FRAME_ON - {G_FRAME} | {G_ROTATION})[i]:
        return None
    scale = 25.4 if modal.inch[i] else 1.0
    origin = np.array([np.nan_to_num(lines.value(c)[i]) for c in "XYZ"]) * scale
    ijk = [np.nan_to_num(lines.value(c)[i]) for c in "IJK"]
    if not (np.all(np.isfinite(origin)) and np.all(np.isfinite(ijk))):
        return None
    return origin, euler_zxz(*ijk)


def _aligned(lines, executed, state, rotary) -> np.ndarray:
    """(n,) bool: a G53.1 came after the plane was set and no rotary word since."""
    idx = np.arange(lines.n)
    setting = ~np.isnan(state) & executed & (np.concatenate(([True], state[1:] != state[:-1])))
    align = lines.has_g({G_ALIGN}) & executed
    turned = np.zeros(lines.n, dtype=bool)
    for c in rotary:
        turned |= lines.present(c) & executed
    last_set = np.maximum.accumulate(np.where(setting, idx, -1))
    last_align = np.maximum.accumulate(np.where(align, idx, -1))
    last_turn = np.maximum.accumulate(np.where(turned & ~align, idx, -1))
    return (last_align >= last_set) & (last_align > last_turn)


def _restated(lines, modal, executed, state) -> np.ndarray:
    """(n,) bool: X, Y and Z were each given absolutely since the plane changed."""

    idx = np.arange(lines.n)
    change = np.concatenate(([False], state[1:] != state[:-1]))
    last_change = np.maximum.accumulate(np.where(change, idx, -1))
    ok = np.ones(lines.n, dtype=bool)
    plain = executed & modal.absolute & ~lines.has_g(G_NON_MODAL_MOVE)
    for c in "XYZ":
        last = np.maximum.accumulate(np.where(lines.present(c) & plain, idx, -1))
        ok &= last > last_change
    return ok | (last_change < 0)


def after_keyword(text: str, head: str) -> str:
    """What follows the keyword ``head`` on its line (comments dropped)."""
    at = text.upper().find(head)
    rest = text[at + len(head):] if at >= 0 else ""
    return re.sub(r"\([^()]*\)|;.*$", "", rest).strip()


def cycle800_args(text: str):
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
