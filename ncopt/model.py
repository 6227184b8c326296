"""Small typed objects passed between the pipeline stages.

The data flows one way::

    text -> Program (parse) -> Toolpath (interp) -> Contacts (geometry)
         -> Plan (planner) -> edits (rewrite) -> text

Arrays are numpy; every array documents its shape and unit.  Lengths are in
millimetres inside ncopt whatever the program's own units are.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field
from enum import IntEnum
from typing import NamedTuple

import numpy as np

from ncopt.runtime.errors import ValueRangeError


#: ``Program.word_letter`` codes of the Sinumerik tool vector words ``A3=``, ``B3=``,
#: ``C3=`` (not ASCII letters, so they never mix with the A, B, C rotary axis words)
MM_PER_INCH = 25.4  # exact, by the 1959 international yard

VECTOR_WORD_CODES = {"A": 0x81, "B": 0x82, "C": 0x83}


class LineKind(IntEnum):
    """What a source line is, as far as ncopt is concerned."""

    BLANK = 0  #: empty or whitespace / comment only
    WORDS = 1  #: word-address block ncopt understands (maybe with expressions)
    OPAQUE = 2  #: recognised but not understood (cycles, macros, o-words); never touched
    PERCENT = 3  #: a ``%`` tape mark line
    TRAILER = 4  #: after the closing ``%``: not part of the program, kept as is


class Motion(IntEnum):
    """Motion mode of a toolpath point (the move that ends at it)."""

    NONE = -1  #: not a move (start point)
    RAPID = 0
    LINEAR = 1
    ARC_CW = 2
    ARC_CCW = 3


@dataclass(frozen=True)
class Program:
    """A parsed NC program: the text and a table of its words.

    The text is the file decoded as latin-1, so character offsets are byte
    offsets and any byte round-trips.

    Attributes
    ----------
    path : str
        Name used in messages (``-`` for stdin).
    text : str
        Whole program, latin-1 decoded, unchanged.
    line_start : (n_lines + 1,) int64
        Character offset of each line start; the last entry is ``len(text)``.
        Line ``i`` (0-based) spans ``text[line_start[i]:line_start[i+1]]``
        including its newline.
    line_kind : (n_lines,) int8
        :class:`LineKind` of each line.
    line_has_expr : (n_lines,) bool
        The line holds a word whose value is an expression or parameter, or a
        parameter assignment: its numbers are not known without evaluation.
    word_line : (n_words,) int32
        0-based line of each word, non-decreasing.
    word_letter : (n_words,) uint8
        Upper-case ASCII code of the word's letter (``ord('X')``); the Sinumerik
        tool vector words ``A3=`` ``B3=`` ``C3=`` have the codes of
        :data:`VECTOR_WORD_CODES`.
    word_value : (n_words,) float64
        Numeric value; NaN where the value is an expression.
    word_start, word_end : (n_words,) int32 (int64 for a text of 2 GiB or more)
        Character span of the whole word (letter to last character of value).
    word_num_start : (n_words,) int32 (int64 likewise)
        Character offset where the value text starts (after letter and blanks).
    opaque_reason : dict[int, str]
        For OPAQUE lines: why ncopt leaves the line alone (0-based line -> text).
    line_exprs : dict[int, tuple]
        For lines with expressions or assignments: the parsed items in order,
        ``("word", word_start, tree)`` or ``("assign", param_tree, expr_tree)``,
        evaluated by the interpreter.
    """

    path: str
    text: str
    line_start: np.ndarray
    line_kind: np.ndarray
    line_has_expr: np.ndarray
    word_line: np.ndarray
    word_letter: np.ndarray
    word_value: np.ndarray
    word_start: np.ndarray
    word_end: np.ndarray
    word_num_start: np.ndarray
    opaque_reason: dict = field(default_factory=dict)
    line_exprs: dict = field(default_factory=dict)

    @property
    def n_words(self) -> int:
        return int(self.word_line.shape[0])

    @property
    def n_lines(self) -> int:
        return int(self.line_kind.shape[0])

    @property
    def newline(self) -> str:
        """The program's dominant line ending (``\\r\\n`` or ``\\n``)."""
        first = self.text.find("\n")
        return "\r\n" if first > 0 and self.text[first - 1] == "\r" else "\n"

    def line_text(self, i: int) -> str:
        """Text of 0-based line ``i`` without its line ending."""
        return self.text[self.line_start[i] : self.line_start[i + 1]].rstrip("\r\n")


@dataclass(frozen=True)
class LineState:
    """The program's state per source line, (n_lines,) arrays: what the control has in
    force when it runs each line (the line's own words included).

    executed : bool, the control runs the line in reading order: not a subprogram body,
        not after M2/M30 or the closing ``%``
    tool : int32, active tool number (-1 before any)
    s_rpm : float64, programmed S in force (0 before any S)
    f_prog : float64, programmed F in force, in the program's units per minute (NaN
        before any F)
    s_known, f_known : bool, the S (F) in force is the program's own word: False after a
        subprogram call, a macro, a block-delete line with an S (F) word or a line ncopt
        does not interpret, and where the word is an expression ncopt cannot evaluate,
        until the program states S (F) again
    block_delete : bool, the line starts with ``/`` (it runs or not at the operator's switch)
    canned : bool, a canned cycle (G73, G76, G81-G89) is in force on the line
    call : bool, the line calls a subprogram or macro (M98, G65, L.., o-call, CALL)
    """

    executed: np.ndarray
    tool: np.ndarray
    s_rpm: np.ndarray
    f_prog: np.ndarray
    s_known: np.ndarray
    f_known: np.ndarray
    block_delete: np.ndarray
    canned: np.ndarray
    call: np.ndarray


@dataclass(frozen=True)
class Toolpath:
    """Cutter locations (CL points) of a program, one row per point.

    Point 0 is the start position; point ``i > 0`` is the end of the move
    ``i-1 -> i``.  Arcs are split into several points that all carry the same
    ``line``.

    Attributes
    ----------
    xyz_mm : (n, 3) float64
        Programmed tool point (tip or centre, see Cutter) in mm, work coordinates.
    line : (n,) int32
        0-based source line of the move ending at each point (-1 for point 0).
    motion : (n,) int8
        :class:`Motion` of the move ending at each point.
    feed_mm_min : (n,) float64
        Programmed feed in force for that move, mm/min (NaN for rapids/unknown).
    spindle_rpm : (n,) float64
        Programmed S word value in force (whether or not the spindle runs), RPM
        in the program's words (0 before any S).
    seg_len_mm : (n,) float64
        Exact length of the move ending at each point (arc length for arcs); 0 for point 0.
    known : (n,) bool
        False where the interpreter cannot know the position (after macros,
        subprogram calls, expressions it cannot evaluate...): such moves are not planned.
    tool : (n,) int32
        Active tool number (-1 if none).
    line_inch : (n_lines,) bool
        The program is in inches (G20) at each line; words are written back in inch.
    spindle_on : (n,) bool
        The spindle turns (M3/M4 in force) during the move.
    lines : LineState
        The modal state per source line.
    warnings : tuple[str, ...]
        Located messages about lines left alone.
    tool_axis : (n, 3) float64 or None
        Unit tool axis ``e`` at each point, from the tip toward the spindle, in
        the part frame (the frame of ``xyz_mm``: a tilted working plane's points
        are carried into it).  Between two points the axis is their normalised
        blend (``ncopt.motion.kinematics.blend``), or where both have ``tool_angles_deg``
        the axis of the angles turned linearly.  None: +Z everywhere (3-axis; the
        fast path).  Rows of moves ncopt does not plan may hold +Z.
    tool_angles_deg : (n, 3) float64 or None
        A B C at each point where the machine's kinematics gave the axis (NaN
        elsewhere); None when none did.
    kinematics : str or None
        What gave the tool axes: a name of ``ncopt.motion.kinematics.KINEMATICS``,
        ``"vector"`` (tool vectors in the program), or None (the tool never tilts).
    inverse_time : (n,) bool or None
        The move is in G93: its ``feed_mm_min`` is the tip feed its F word (1 /
        minutes) stands for, F x the block's length (``ncopt.motion.feedmode``).  None:
        no G93 move.
    """

    xyz_mm: np.ndarray
    line: np.ndarray
    motion: np.ndarray
    feed_mm_min: np.ndarray
    spindle_rpm: np.ndarray
    seg_len_mm: np.ndarray
    known: np.ndarray
    tool: np.ndarray
    line_inch: np.ndarray | None = None
    spindle_on: np.ndarray | None = None
    lines: LineState | None = None
    warnings: tuple[str, ...] = ()
    tool_axis: np.ndarray | None = None
    kinematics: str | None = None
    inverse_time: np.ndarray | None = None
    tool_angles_deg: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = self.xyz_mm.shape[0]
        if self.xyz_mm.shape != (n, 3):
            raise ValueError(f"xyz_mm must be (n, 3), got {self.xyz_mm.shape}")
        if self.tool_axis is not None and self.tool_axis.shape != (n, 3):
            raise ValueError(f"tool_axis must be ({n}, 3), got {self.tool_axis.shape}")
        for name in ("line", "motion", "feed_mm_min", "spindle_rpm", "seg_len_mm", "known", "tool"):
            arr = getattr(self, name)
            if arr.shape != (n,):
                raise ValueError(f"{name} must be ({n},), got {arr.shape}")

    @property
    def n(self) -> int:
        return int(self.xyz_mm.shape[0])


# ------------------------------------------------------------------ allowed values ----
@dataclass(frozen=True)
class Bounds:
    """The values a number may take: between ``low`` and ``high`` (either end open or
    closed, None: none), finite unless ``finite`` is False (then inf is allowed, as
    "no limit"; NaN never is), an integer where ``integer``; ``unit`` for messages.

    One table of these (:data:`LIMITS`) is what the model's objects, the profiles and the
    command line check, so all three refuse the same values with the same words."""

    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    finite: bool = True
    integer: bool = False
    unit: str = ""

    def describe(self) -> str:
        """The allowed values in words: ``a finite number above 0 rad/s^2``."""
        what = "an integer" if self.integer else "a finite number" if self.finite else "a number"
        unit = f" {self.unit}" if self.unit else ""
        lo = None if self.low is None else (
            f"above {self.low:g}" if self.low_open else f"of at least {self.low:g}")
        hi = None if self.high is None else (
            f"below {self.high:g}" if self.high_open else f"of at most {self.high:g}")
        range_ = " and ".join(x for x in (lo, hi) if x) or ""
        tail = "" if self.finite else " (inf: no limit)"
        return f"{what} {range_}{unit}{tail}".replace("  ", " ").strip()

    def holds(self, value) -> bool:
        """Whether ``value`` is one of the allowed values (a bool is no number)."""
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            return False
        if self.integer and not isinstance(value, numbers.Integral):
            return False
        v = float(value)
        if math.isnan(v) or (self.finite and math.isinf(v)):
            return False
        if self.low is not None and (v <= self.low if self.low_open else v < self.low):
            return False
        return self.high is None or (v < self.high if self.high_open else v <= self.high)

    def check(self, value, name: str) -> None:
        """Raise :class:`~ncopt.runtime.errors.ValueRangeError` naming ``name`` and the range
        unless ``value`` is allowed."""
        if not self.holds(value):
            raise ValueRangeError(f"{name} must be {self.describe()}, not {value!r}")


#: What each value of the model may be (the command line's options and the profiles'
#: keys of the same meaning are checked against the same bounds).
LIMITS = {
    "diameter_mm": Bounds(0, low_open=True, unit="mm"),
    "corner_radius_mm": Bounds(0, low_open=True, unit="mm"),
    "teeth": Bounds(1, integer=True),
    "accel_rad_s2": Bounds(0, low_open=True, unit="rad/s^2"),
    "max_rpm": Bounds(1, unit="RPM"),
    "min_rpm": Bounds(0, unit="RPM"),
    "max_feed_mm_min": Bounds(0, low_open=True, finite=False, unit="mm/min"),
    "rapid_mm_min": Bounds(0, low_open=True, unit="mm/min"),
    "vc_m_min": Bounds(0, low_open=True, unit="m/min"),
    "fz_mm": Bounds(0, low_open=True, unit="mm"),
    "min_rpm_step": Bounds(0, low_open=True, unit="RPM"),
    "fz_tolerance": Bounds(0, 1, low_open=True, high_open=True),  # --fz-band: below 50 %
    "sample_mm": Bounds(0, low_open=True, unit="mm"),
    "f_quantum_mm_min": Bounds(0, finite=False, unit="mm/min"),
    "min_s_interval_ms": Bounds(0, unit="ms"),
}
TOOL_POINTS = ("tip", "center")
PLANNERS = ("lookahead", "forward")
FZ_POLICIES = ("centred", "below")
S_CHANGES = ("anywhere", "between-passes")  # as ncopt.reading.controls.S_CHANGES


def check_fields(obj, names, what: str) -> None:
    """Check the fields ``names`` of a model object against :data:`LIMITS`."""
    for name in names:
        LIMITS[name].check(getattr(obj, name), f"{what}: {name}")


def check_choice(value, choices: tuple, name: str) -> None:
    """Raise ValueRangeError unless ``value`` is one of ``choices``."""
    if value not in choices:
        raise ValueRangeError(f"{name} must be one of {', '.join(choices)}, not {value!r}")


def min_below_max(min_rpm: float, max_rpm: float) -> str:
    """Why a lowest spindle speed does not fit under the highest ("" when it does)."""
    if min_rpm < max_rpm:
        return ""
    return (f"the lowest spindle speed ({min_rpm:g} RPM) must be below the highest "
            f"({max_rpm:g} RPM)")


@dataclass(frozen=True)
class Cutter:
    """A ball-end (corner_radius_mm == radius_mm) or bull-nose cutter.

    Attributes
    ----------
    diameter_mm : float
    corner_radius_mm : float
        Torus tube radius r; equal to D/2 for a ball.
    teeth : int
    tool_point : str
        ``"tip"`` (programmed point at the tool tip, the default of CAM posts) or ``"center"``.
    """

    diameter_mm: float
    teeth: int
    corner_radius_mm: float | None = None
    tool_point: str = "tip"

    def __post_init__(self) -> None:
        """Checks the values (:data:`LIMITS`); raises ValueRangeError naming the field."""
        check_fields(self, ("diameter_mm", "teeth"), "cutter")
        if self.corner_radius_mm is None:
            object.__setattr__(self, "corner_radius_mm", self.diameter_mm / 2.0)
        check_fields(self, ("corner_radius_mm",), "cutter")
        if self.corner_radius_mm > self.diameter_mm / 2.0 * (1.0 + 1e-9):
            raise ValueRangeError(f"cutter: corner_radius_mm must be at most half the "
                                  f"diameter ({self.diameter_mm / 2.0:g} mm), not "
                                  f"{self.corner_radius_mm!r}")
        check_choice(self.tool_point, TOOL_POINTS, "cutter: tool_point")

    @property
    def radius_mm(self) -> float:
        return self.diameter_mm / 2.0

    @property
    def is_ball(self) -> bool:
        return abs(self.corner_radius_mm - self.radius_mm) < 1e-9


@dataclass(frozen=True)
class Contacts:
    """Where the cutter touches the part, per sample point.

    Attributes
    ----------
    cc_mm : (m, 3) float64
        Cutter-contact (CC) points in mm.
    normal : (m, 3) float64
        Unit outward surface normal at the CC point, oriented toward the tool.
    r_eff_mm : (m,) float64
        Effective cutting radius: distance of the CC point from the tool axis.
    cutting : (m,) bool
        The cutter touches the part within tolerance at this sample.
    """

    cc_mm: np.ndarray
    normal: np.ndarray
    r_eff_mm: np.ndarray
    cutting: np.ndarray


@dataclass(frozen=True)
class Machine:
    """Spindle and axis limits of the machine.

    accel_rad_s2 is the spindle acceleration as users state it (rad/s^2);
    ``accel_rpm_s`` converts it (a = alpha * 60 / (2 pi)).  Each value is checked
    against :data:`LIMITS` (ValueRangeError), and min_rpm must be below max_rpm.  NaN
    for both accel_rad_s2 and max_rpm says no spindle is known (``ncopt inspect``,
    which plans nothing); planning needs them.
    """

    accel_rad_s2: float
    max_rpm: float
    min_rpm: float = 0.0
    max_feed_mm_min: float = float("inf")
    rapid_mm_min: float = 10000.0

    def __post_init__(self) -> None:
        if not self.spindle_unknown:
            check_fields(self, ("accel_rad_s2", "max_rpm"), "machine")
        check_fields(self, ("min_rpm", "max_feed_mm_min", "rapid_mm_min"), "machine")
        why = "" if self.spindle_unknown else min_below_max(self.min_rpm, self.max_rpm)
        if why:
            raise ValueRangeError(f"machine: {why}")

    @property
    def spindle_unknown(self) -> bool:
        """No spindle given: accel_rad_s2 and max_rpm both NaN."""
        return all(isinstance(v, numbers.Real) and not isinstance(v, bool) and math.isnan(v)
                   for v in (self.accel_rad_s2, self.max_rpm))

    @property
    def accel_rpm_s(self) -> float:
        return self.accel_rad_s2 * 60.0 / (2.0 * np.pi)


@dataclass(frozen=True)
class CuttingData:
    """Targets: cutting speed vc (m/min) and feed per tooth fz (mm), both finite and
    above 0 (ValueRangeError otherwise)."""

    vc_m_min: float
    fz_mm: float

    def __post_init__(self) -> None:
        check_fields(self, ("vc_m_min", "fz_mm"), "cutting data")


@dataclass(frozen=True)
class PlanOptions:
    """How the planner and rewriter behave.

    planner : ``"lookahead"`` (default) or ``"forward"`` (the paper's flow chart)
    min_rpm_step : emit S only when it changes by at least this many RPM
    fz_tolerance : allowed relative fz drift inside a block while the spindle ramps
    sample_mm : longest distance between mesh samples where the tool cuts, mm (every block
        end is sampled, and more where R_eff curves: :mod:`ncopt.contacts.sampling`)
    f_quantum_mm_min : resolution of the F words written (1 for ``F279``), mm/min: F is
        rounded down to it, which the fz band must absorb
    fz_policy : ``"centred"`` (default): F from the harmonic mean of the block's lowest and
        highest real spindle speed, so fz stays within +-fz_tolerance both ways;
        ``"below"``: F from the lowest speed, so fz never exceeds its target (docs/method.md's
        choice; it halves the speed change allowed per block)
    min_s_interval_ms : least time between two S words (Sinumerik acknowledges each S
        through the PLC): a rise waits; a fall, which vc needs, never waits and is counted
    s_changes : ``"anywhere"``: S follows the cut block by block; ``"between-passes"``: one S
        per pass, changed only on the non-cutting blocks between passes (controls that stop
        or wait at every S word, e.g. grbl); None: the control's default
        (:func:`ncopt.reading.controls.default_s_changes`)
    """

    planner: str = "lookahead"
    min_rpm_step: float = 10.0
    fz_tolerance: float = 0.02
    sample_mm: float = 1.0
    f_quantum_mm_min: float = 0.0
    fz_policy: str = "centred"
    min_s_interval_ms: float = 0.0
    s_changes: str | None = None

    def __post_init__(self) -> None:
        """Checks the values (:data:`LIMITS`, the named choices): ValueRangeError."""
        check_choice(self.planner, PLANNERS, "plan options: planner")
        check_fields(self, ("min_rpm_step", "fz_tolerance", "sample_mm", "f_quantum_mm_min",
                            "min_s_interval_ms"), "plan options")
        check_choice(self.fz_policy, FZ_POLICIES, "plan options: fz_policy")
        if self.s_changes is not None:
            check_choice(self.s_changes, S_CHANGES, "plan options: s_changes")


@dataclass(frozen=True)
class Plan:
    """Commanded spindle speed and feed per toolpath point (the move ending there).

    Attributes
    ----------
    s_req_rpm : (n,) float64
        Required spindle speed of each move (lowest along it); NaN if not cutting.
    s_rpm : (n,) float64
        Planned spindle speed in force during each move.
    f_mm_min : (n,) float64
        Planned feed of each move (NaN where the program's own feed stays).
    planned : (n,) bool
        The move's S/F are set by ncopt.
    """

    s_req_rpm: np.ndarray
    s_rpm: np.ndarray
    f_mm_min: np.ndarray
    planned: np.ndarray


class Edit(NamedTuple):
    """Replace ``text[start:end]`` by ``text``: one edit (see :class:`Edits` for many)."""

    start: int
    end: int
    text: str


@dataclass(frozen=True)
class Method:
    """How R_eff is found: at the contact point (``contact``, the default) or where the
    edge meets the remaining material of height ``ap_mm`` (``material``), offset along
    the surface normal or the tool axis (``along``)."""

    name: str = "contact"
    ap_mm: float = 0.2
    along: str = "normal"


@dataclass(frozen=True)
class Job:
    """Everything a rewrite needs besides the program and the mesh.

    cutter : None reads each tool from the program's tool comments
    cutting : None takes vc and fz from the program's own S and F
    tool : plan only this T number's moves
    teeth : used when the cutter comes from the program (only matters with cutting data given)
    """

    machine: Machine
    cutter: Cutter | None = None
    cutting: CuttingData | None = None
    options: PlanOptions = PlanOptions()
    tool: int | None = None
    control: str | None = None  # None: detected from the program's dialect
    control_from: str = "given"  # where a set control came from (the options, a profile)
    tool_library: dict = field(default_factory=dict)  # T number -> Cutter (profiles)
    teeth: int = 2
    method: Method = Method()  # contact point (default) or remaining material
    decimal_point: str | None = None  # Fanuc input convention: calculator, is-b, is-c
    contact_tol_mm: float = 0.05
    verify: bool = True
    stamp: bool = True
    operations: tuple[str, ...] | None = None  # --operations (or "all"); None: by kind
    stock_mm: float = 0.0  # --stock: allowance the program leaves on the mesh, mm
    diameter_bare: bool = False  # --diameter was a bare number (read as mm)
    shape_named: bool = False  # the user named the cutter's shape (not --diameter alone)
    kinematics: str | None = None  # 5-axis: how rotary angles tilt the tool (ncopt.motion.kinematics)
    tcp: str | None = None  # "always": the control runs TCP for every program (else as switched)
    machine_name: str | None = None  # the machine profile the spindle comes from (the stamp)
