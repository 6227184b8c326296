"""What ncopt knows of the tool axis per line (:class:`Orientation`), the codes and
keywords that turn the tool, and the small pieces every orientation reader shares (the
reason texts, the state in force when a line starts).  :mod:`ncopt.motion.orientation`
says what is read and how."""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from ncopt.model import VECTOR_WORD_CODES

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
# G codes x10, as the interpreter keeps them
G_VECTOR_TCP = 435  # G43.5: tool vectors in I J K
G_TCP_ON = {434, 435, 2340}  # G43.4 G43.5, Haas G234
G_LENGTH_GROUP = {430, 440, 434, 435, 490, 2340}  # G43 G44 G43.4 G43.5 G49 G234
G_HOME = {280, 281, 300, 301}  # G28 G30: may turn every rotary axis
G_CALLS = {650, 660}  # G65 G66 macro calls
G_NOT_POSITION = G_CALLS | {71}  # their A B C are arguments; G07.1 C: a radius
M_CALLS = {98, 99}
M_TCP_ON, M_TCP_OFF = {128, 428}, {129, 429}
# the letter codes the line table keeps the tool vector words A3= B3= C3= under
VECTOR_LETTERS = "".join(chr(c) for c in VECTOR_WORD_CODES.values())

# Sinumerik and Heidenhain keywords (the opaque lines' heads, upper case)
KW_TCP = {"TRAORI", "TRAFOOF", "ORIWKS", "ORIMKS", "ORIAXES", "ORIVECT", "FUNCTION"}

# Sinumerik orientation addresses ncopt does not read (A3= B3= C3= with a number are words)
ORIENTATION_ADDRESS = re.compile(r"^(?:[ABC][2-7]|LEAD|TILT|THETA|PHI|PSI)$", re.IGNORECASE)


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
    frames : tuple[tuple[ndarray, ndarray], ...]
        ``(origin_mm (3,), R (3, 3))`` per plane: ``p_part = origin + R p``.
    """

    blocked: np.ndarray
    reasons: tuple[str, ...]
    rotary_move: np.ndarray
    axis: np.ndarray
    angles_deg: np.ndarray
    kinematics: str | None = None
    frame: np.ndarray | None = None
    frames: tuple[tuple[np.ndarray, np.ndarray], ...] = ()


class Reasons:
    """Interned reason texts (index 0: none)."""

    def __init__(self) -> None:
        self.texts = [""]

    def code(self, text: str) -> int:
        """The index of ``text``, added if new."""
        if text not in self.texts:
            self.texts.append(text)
        return self.texts.index(text)


def before(a: np.ndarray, first) -> np.ndarray:
    """``a`` shifted one line down: the state in force when each line starts."""
    return np.concatenate(([first] if np.ndim(a) == 1 else [first], a[:-1]))
