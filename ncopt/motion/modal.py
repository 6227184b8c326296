"""The modal tables of RS-274 (G codes x10, so that 38.2 -> 382 is an integer key), the
keywords ncopt knows, and the array helpers every motion stage uses (forward fill, row norms).

Constant data and pure functions: the interpreter, the orientation and the plane readers
share them without importing each other.
"""

from __future__ import annotations

import re

import numpy as np

# modal groups of G codes (values x10 so that 38.2 -> 382 is an integer key)
G_MOTION = {0, 10, 20, 30, 330, 382, 383, 384, 385, 730, 760, 800, 810, 820, 830, 840,
            850, 860, 870, 880, 890}
G_PLANE = {170, 180, 190, 171, 181, 191}
G_DISTANCE = {900, 910}
G_ARC_DISTANCE = {901, 911}
G_UNITS = {200, 210}
G_FEED_MODE = {930, 940, 950}
G_COMP = {400, 410, 420, 411, 421}
G_NON_MODAL_MOVE = {280, 300, 530, 920, 921, 922, 923, 520, 100, 281, 301}
# lines whose axis words are not a move's target: those above, and the origins of
# coordinate rotations and tilted planes (G68, G68.2-G68.4, Haas G268)
# splines and NURBS (LinuxCNC G5, G5.1, G5.2/G5.3; Fanuc G06.2) and Fanuc's AI contour
# control G05.1 Q1 R5 / Q0, nano smoothing G05.1 Q2 X0 Y0 Z0: with axis words either a
# curve ncopt does not follow or an axis designation that is no move; without them a mode
G_SPLINE = {50, 51, 52, 53, 62}
# Fanuc scaling G51 (P or I J K the factors) and programmable mirror image G51.1, cancelled
# by G50 / G50.1: their axis words are a centre or the axes mirrored, not a target
G_SCALE_ON = {510, 511, 720}  # and Heidenhain ISO's G72 scaling factor (a lathe cycle elsewhere)
G_SCALE_OFF = {500, 501}
# moves whose end ncopt cannot know or that are no plain move: Fanuc G27 (reference
# position check) and G29 (return from it), G31 (skip: stops at a signal), LinuxCNC G33.1
# (rigid tapping, back out); and G110-G112: Sinumerik poles (the axis words are the pole),
# Haas work offsets (a move on the line is in the new offset): the position is lost
G_OTHER_MOVES = {270, 290, 310, 331}
G_POLE = {1100, 1110, 1120}
G_NOT_A_TARGET = G_NON_MODAL_MOVE | {680, 682, 683, 684, 2680} | G_SPLINE | G_SCALE_ON \
    | G_SCALE_OFF | G_OTHER_MOVES | G_POLE
# Sinumerik's programmable frame: SCALE/ASCALE and MIRROR/AMIRROR scale or mirror the
# geometry; TRANS, ROT, SCALE or MIRROR without arguments reset the whole frame
KW_SCALE = {"SCALE", "ASCALE", "MIRROR", "AMIRROR"}
KW_FRAME_RESET = {"SCALE", "MIRROR", "TRANS", "ROT"}
SCALED_WHY = ("scaling or a mirror image in force (G51, G51.1, G72, SCALE, MIRROR): ncopt plans "
              "programs as written, unscaled")
# modes under which the words do not mean what ncopt reads: (on codes, off codes, why);
# their moves are left as programmed (G07.1 is switched off by G07.1 C0)
G_MODES_NOT_READ = (
    ({160}, {150}, "polar coordinates (G16): X is a radius and Y an angle"),
    ({121}, {131}, "polar coordinate interpolation (G12.1)"),
    ({71}, set(), "cylindrical interpolation (G07.1)"),
    ({960}, {970}, "constant surface speed (G96): S is a cutting speed, not RPM"),
    ({700, 7000}, {200, 210, 710, 7100}, "inch lengths selected by G70 (Sinumerik: F stays "
     "in the machine's basic unit, which the program does not say; G700 sets both and is "
     "read) or by a Heidenhain ISO G70"),
)
# a Heidenhain ISO program in inch: "%NAME G70 *" on its first line (a tape mark, no words)
INCH_HEADER = re.compile(r"^\s*%\S+\s+G0*70\s*\*", re.I)
CANNED = {730, 760, 810, 820, 830, 840, 850, 860, 870, 880, 890}

# every G code ncopt reads or knows to leave positions, feeds and speeds as written (x10);
# a line with any other (Haas G12/G13 circle pockets, G45-G48 offsets, Heidenhain ISO's
# polar G10-G16...) is no move ncopt reads, and the position is lost after it
# work offsets: G54-G59.x, G54.1 Pn, Sinumerik G500 and G505-G599
G_WORK_OFFSETS = set(range(540, 600)) | {541, 5000} | set(range(5050, 6000, 10))
G_READ = (G_MOTION | G_PLANE | G_DISTANCE | G_ARC_DISTANCE | G_UNITS | G_FEED_MODE | G_COMP
          | G_NOT_A_TARGET | CANNED | {740, 711, 712, 720, 721, 722}
          | set().union(*(on | off for on, off, _ in G_MODES_NOT_READ))
          | {690, 2540, 2550, 2690, 531, 430, 431, 440, 434, 435, 490, 2340}  # frames, lengths
          | {40, 90, 80, 600, 610, 611, 620, 630, 640, 641, 642, 643, 644, 645, 1870,
             4500, 4510, 6010, 6020, 6030, 6410, 6420, 6430, 6440, 6450, 250, 260}  # modes
          | G_WORK_OFFSETS | {1530}  # G153: machine coordinates for the block
          | {650, 660, 670, 980, 990})
HARMLESS_OPAQUE = {"MSG", "CYCLE832", "DEF", "STOPRE", "WORKPIECE", "SOFT", "BRISK",
                   "FFWON", "FFWOF", "COMPCAD", "COMPON", "COMPOF", "COMPSURF", "G642",
                   "G641", "G64", "TRAFOOF", "UPATH", "SPATH", "FGROUP", "FNORM", "FLIN",
                   # TCP and orientation modes: ncopt.motion.orientation reads them
                   "TRAORI", "ORIWKS", "ORIMKS", "ORIVECT", "ORIAXES"}
FLOW_CONTROL = {"IF", "GOTO", "WHILE", "DO", "END", "REPEAT", "CALL", "PCALL", "LOOP",
                "ENDLOOP", "FOR", "ENDFOR", "ENDIF", "ELSE", "ENDWHILE", "RET", "M17"}


def sorted_unique(a: np.ndarray) -> np.ndarray:
    """The distinct values of a sorted array, in order (``np.unique`` without its sort or
    hash: at 200k values numpy's hashed unique took 0.44 s where this takes a millisecond)."""
    return a[np.concatenate(([True], np.diff(a) != 0))] if a.size else a


def ffill(values: np.ndarray, initial: float = np.nan) -> np.ndarray:
    """Forward-fill NaNs with the last value before them (``initial`` at the start)."""
    n = values.shape[0]
    pos = np.flatnonzero(~np.isnan(values))  # each value repeated up to the next one
    vals = np.asarray(values, dtype=np.float64)
    if pos.size == n:
        return vals.copy()
    src = np.empty(pos.size + 1)
    src[0] = initial
    src[1:] = vals[pos]
    counts = np.diff(pos, prepend=0, append=n)  # counts[0]: before the first value
    return np.repeat(src, counts)


def row_norms(d: np.ndarray) -> np.ndarray:
    """(m,) Euclidean length of each row of the (m, 3) ``d``: ``np.linalg.norm(d, axis=1)``,
    the same sums in the same order (x^2 + y^2, then + z^2), without its reduction over a
    3-long axis (2-3x slower at 1M rows)."""
    sq = d * d
    out = sq[:, 0] + sq[:, 1]
    out += sq[:, 2]
    return np.sqrt(out, out=out)
