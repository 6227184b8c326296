"""A :class:`~ncopt.model.Job` from plain values, checked: what the command line's options
ask for, and what a library caller asks for the same way.

The values come in six small records, one per kind (the panels of ``ncopt rewrite -h``):
:class:`CutterOptions`, :class:`TargetOptions`, :class:`MachineOptions`,
:class:`ControlOptions`, :class:`PartOptions` and :class:`PlanningOptions`.
:func:`build_job` resolves them against the profiles (:mod:`ncopt.planning.profiles`:
a value given wins, then the machine profile, then ncopt's default) and checks every one
once, here: a number against :data:`ncopt.model.LIMITS`, a choice against the model's own
tuples.  A value refused raises :class:`~ncopt.runtime.errors.UsageError` (a
:class:`~ncopt.runtime.errors.ValueRangeError` for a number out of its range) whose
message names the command-line option, as ``ncopt`` prints it (exit 2).
:func:`job_from_values` takes the same values as flat keywords.

This module imports only typing at its top: the command line reads its choices
(:data:`Planner`, ...) to show them in ``-h``, which must not load numpy.
"""

from __future__ import annotations

import math
import numbers
import re
from dataclasses import dataclass, fields
from pathlib import Path
from typing import TYPE_CHECKING, Literal, get_args

from ncopt.runtime.errors import UsageError, ValueRangeError

if TYPE_CHECKING:
    from ncopt.model import Job

# The choices.  Each is spelt as its source spells it (tests/test_job.py holds them equal):
# those sources import numpy, and ``ncopt COMMAND -h`` shows these without loading it.
ToolPoint = Literal["tip", "center"]  #: ncopt.model.TOOL_POINTS
Planner = Literal["lookahead", "forward"]  #: ncopt.model.PLANNERS
FzPolicy = Literal["centred", "below"]  #: ncopt.model.FZ_POLICIES
SChanges = Literal["anywhere", "between-passes"]  #: ncopt.model.S_CHANGES
#: ncopt.reading.controls.CONTROLS
Control = Literal["grbl", "fanuc", "linuxcnc", "sinumerik", "heidenhain-iso", "generic"]
DecimalPoint = Literal["calculator", "is-b", "is-c"]  #: ncopt.reading.dialect conventions
#: ncopt.motion.kinematics.NAMES
Kinematics = Literal["xyzac-trt", "xyzac-head-table", "xyzac-trt-linuxcnc", "xyzbc-trt",
                     "xyzbc-head-table", "xyzbc-head-head", "xyzbc-trt-linuxcnc",
                     "xyzbc-5axis-linuxcnc", "vector"]
MethodName = Literal["contact", "material"]  #: ncopt.model.Method.name
AllowanceAlong = Literal["normal", "axis"]  #: ncopt.model.Method.along
Shape = Literal["ball", "bull-nose"]

Length = float | str  # mm, or text with its unit: "6.35mm", "0.25in"


@dataclass(frozen=True)
class CutterOptions:
    """The cutter: a named tool of the profiles (``cutter``), or a diameter, mm (a ball;
    with ``corner_radius``, mm, a bull-nose); None for both: each tool as the program's
    tool comments say.  ``shape`` overrides the shape those comments give; ``teeth`` z;
    ``tool_point``: the point the program moves (tip or centre).  Lengths are mm, or text
    with a unit (``"0.25in"``)."""

    cutter: str | None = None
    diameter: Length | None = None
    corner_radius: Length | None = None
    shape: Shape | None = None
    teeth: int = 2
    tool_point: ToolPoint = "tip"


@dataclass(frozen=True)
class TargetOptions:
    """The cutting data: ``vc`` m/min and ``fz`` mm (both or neither: none takes them
    from the program's S and F), or a ``material`` of the profiles; the fz band, percent,
    kept while the spindle ramps, and whether fz may go both ways of its target."""

    material: str | None = None
    vc: float | None = None
    fz: float | None = None
    fz_band: float = 2.0
    fz_policy: FzPolicy = "centred"


@dataclass(frozen=True)
class MachineOptions:
    """The machine: a profile's name (None: NCOPT_MACHINE, else the profiles' default), and
    values that override it: spindle acceleration ``accel`` rad/s^2, ``max_rpm`` and
    ``min_rpm`` RPM, ``max_feed`` and ``rapid`` mm/min, the 5-axis ``kinematics``."""

    machine: str | None = None
    accel: float | None = None
    max_rpm: float | None = None
    min_rpm: float | None = None
    max_feed: float | None = None
    rapid: float | None = None
    kinematics: Kinematics | None = None


@dataclass(frozen=True)
class ControlOptions:
    """The control the program is for (None: the machine profile's, else detected), how a
    Fanuc reads a number without a decimal point, where S may change, and the least time
    between two S words, ms (None: the machine profile's)."""

    control: Control | None = None
    decimal_point: DecimalPoint | None = None
    s_changes: SChanges | None = None
    min_s_interval_ms: float | None = None


@dataclass(frozen=True)
class PartOptions:
    """What the cutter meets: the ``stock`` the program leaves on the mesh, and where R_eff
    is taken (``method``: at the contact point, or where the edge meets the remaining
    material of height ``ap``, offset along the surface normal or the tool axis).  Lengths
    are mm, or text with a unit."""

    stock: Length = 0.0
    method: MethodName = "contact"
    ap: Length = 0.2
    allowance_along: AllowanceAlong = "normal"


@dataclass(frozen=True)
class PlanningOptions:
    """What is planned and how: only T ``tool``; the ``operations`` named (comma-separated
    text or names; "all"; None: the finishing operations ncopt recognises); the planner;
    the least change of S written, RPM."""

    tool: int | None = None
    operations: str | tuple | None = None
    planner: Planner = "lookahead"
    min_rpm_step: float = 10.0


RECORDS = {"cutter": CutterOptions, "targets": TargetOptions, "machine": MachineOptions,
           "control": ControlOptions, "part": PartOptions, "planning": PlanningOptions}
#: every value :func:`job_from_values` takes, by name
VALUE_NAMES = frozenset(f.name for record in RECORDS.values() for f in fields(record)) | {
    "tools_file"}


def job_from_values(*, spindle_needed: bool = True, tools_file: Path | None = None,
                    **values) -> "Job":
    """:func:`build_job` with the records' fields as flat keywords (``diameter=6``,
    ``accel=227``, ...); a name no record has is a TypeError."""
    unknown = set(values) - VALUE_NAMES
    if unknown:
        raise TypeError(f"job_from_values() got unknown values {sorted(unknown)}")
    records = {key: record(**{f.name: values[f.name] for f in fields(record)
                              if f.name in values})
               for key, record in RECORDS.items()}
    return build_job(**records, tools_file=tools_file, spindle_needed=spindle_needed)


_LENGTH = re.compile(r"^\s*([+-]?(?:\d+\.?\d*|\.\d+))\s*(mm|in|inch|inches|\")?\s*$", re.I)


def length_mm(value, option: str) -> float | None:
    """A length option in mm: a bare number is mm; ``0.25in``, ``6.35mm`` say their unit."""
    if value is None or isinstance(value, (int, float)):
        return value
    m = _LENGTH.match(str(value))
    if not m:
        raise UsageError(f"{option} takes a length such as 6.35, 6.35mm or 0.25in, not {value!r}")
    unit = (m.group(2) or "mm").lower()
    return float(m.group(1)) * (1.0 if unit == "mm" else 25.4)


def check_numbers(values) -> None:
    """Refuse (ValueRangeError, exit 2) an option's number outside its range, naming the
    option and the range: ``values`` holds (option, key of ncopt.model.LIMITS, or "tool",
    value or None)."""
    from ncopt.model import LIMITS, Bounds

    for option, key, value in values:
        bounds = Bounds(0, integer=True) if key == "tool" else LIMITS[key]  # a T number
        if value is not None and not bounds.holds(value):
            shown = f"{value:g}" if isinstance(value, float) else repr(value)
            raise ValueRangeError(f"{option} must be {bounds.describe()}, not {shown}")


def check_choice(value, choices: tuple, option: str) -> None:
    """Refuse (UsageError) a value not among ``choices``: ``--planner must be lookahead or
    forward, not 'x'`` (two), ``--dialect must be one of a, b, c, not 'x'`` (more).  None
    passes: the option was not given."""
    if value is None or value in choices:
        return
    said = " or ".join(choices) if len(choices) == 2 else "one of " + ", ".join(choices)
    raise UsageError(f"{option} must be {said}, not {value!r}")


def build_job(cutter: CutterOptions = CutterOptions(), targets: TargetOptions = TargetOptions(),
              machine: MachineOptions = MachineOptions(),
              control: ControlOptions = ControlOptions(), part: PartOptions = PartOptions(),
              planning: PlanningOptions = PlanningOptions(), *,
              tools_file: Path | None = None, spindle_needed: bool = True) -> "Job":
    """A Job from the values asked for and the profiles, checked; raises UsageError.

    Values given win; then the machine profile (``machine.machine``, else NCOPT_MACHINE,
    else the profiles' default_machine; ``tools_file`` adds a profile file); then ncopt's
    defaults.  ``spindle_needed`` False (inspect, which plans nothing): without a spindle
    given, its figures are NaN.
    """
    from ncopt.planning.profiles import load

    v = _Values.of(cutter, targets, machine, control, part, planning)
    profiles = load(tools_file=tools_file)
    v.from_profile(profiles.chosen_machine(machine.machine))
    v.from_named(profiles, spindle_needed)
    v.check()
    return v.job(profiles)


@dataclass
class _Values:
    """The values while they are resolved and checked, in the order the checks run (the
    first value refused is the one reported, as it always was)."""

    diameter: float | None
    corner_radius: float | None
    teeth: int
    cutter: str | None
    shape: str | None
    tool_point: str
    material: str | None
    vc: float | None
    fz: float | None
    fz_band: float
    fz_policy: str
    accel: float | None
    max_rpm: float | None
    min_rpm: float | None
    max_feed: float | None
    rapid: float | None
    kinematics: str | None
    control: str | None
    decimal_point: str | None
    s_changes: str | None
    min_s_interval_ms: float | None
    stock: float
    method: str
    ap: float
    allowance_along: str
    tool: int | None
    operations: str | tuple | None
    planner: str
    min_rpm_step: float
    bare: bool = False  # the diameter was a bare number in text (read as mm)
    profile: object = None  # the machine profile chosen (MachineProfile or None)
    control_from: str = "given"

    @staticmethod
    def of(cutter, targets, machine, control, part, planning) -> "_Values":
        """The records' values, lengths in mm."""
        d = cutter.diameter
        text = d is not None and not isinstance(d, (int, float))
        match = _LENGTH.match(str(d)) if text else None
        values = {f.name: getattr(record, f.name)
                  for record in (cutter, targets, machine, control, part, planning)
                  for f in fields(record) if f.name != "machine"}
        values.update(diameter=length_mm(d, "--diameter"),
                      corner_radius=length_mm(cutter.corner_radius, "--corner-radius"),
                      ap=length_mm(part.ap, "--ap"), stock=length_mm(part.stock, "--stock"))
        return _Values(**values, bare=match is not None and match.group(2) is None)

    def from_profile(self, m) -> None:
        """Values not given from the machine profile ``m`` (None: ncopt's defaults)."""
        self.profile = m
        pick = lambda given, attr, default: given if given is not None else (  # noqa: E731
            getattr(m, attr) if m is not None else default)
        self.accel, self.max_rpm = pick(self.accel, "accel_rad_s2", None), pick(
            self.max_rpm, "max_rpm", None)
        self.min_rpm = pick(self.min_rpm, "min_rpm", 0.0)
        self.max_feed = pick(self.max_feed, "max_feed_mm_min", float("inf"))
        self.control_from = ("given" if self.control is not None else
                             f"machine profile {m.name if m is not None else None}")
        self.rapid = pick(self.rapid, "rapid_mm_min", 10000.0)
        self.control = pick(self.control, "control", None)
        self.min_s_interval_ms = pick(self.min_s_interval_ms, "min_s_interval_ms", 0.0)
        self.decimal_point = pick(self.decimal_point, "decimal_point", None)
        self.s_changes = pick(self.s_changes, "s_changes", None)
        from ncopt.motion.kinematics import check_name

        self.kinematics = check_name(pick(self.kinematics, "kinematics", None))

    def from_named(self, profiles, spindle_needed: bool) -> None:
        """The named tool and cutting data of the profiles; the spindle, or NaN for none."""
        if self.cutter is not None:
            if self.diameter is not None:
                raise UsageError("give --cutter or --diameter, not both")
            named = profiles.tool(self.cutter)
            if named is None:
                raise UsageError(f"no tool {self.cutter!r} in the profiles; see ncopt profiles")
            self.diameter, self.corner_radius = named.diameter_mm, named.corner_radius_mm
            self.teeth = named.teeth
        if self.material is not None:
            if self.vc is not None or self.fz is not None:
                raise UsageError("give --material or --vc/--fz, not both")
            data = profiles.material(self.material)
            self.vc, self.fz = data.vc_m_min, data.fz_mm
        if (self.accel is None or self.max_rpm is None) and spindle_needed:
            raise UsageError("give the spindle: --accel RAD_S2 and --max-rpm RPM, or a "
                             "--machine profile (ncopt profiles lists them)")
        if self.accel is None or self.max_rpm is None:
            self.accel = self.max_rpm = float("nan")

    def check(self) -> None:
        """Every value against its range and choices, and against one another."""
        from ncopt.model import FZ_POLICIES, PLANNERS, TOOL_POINTS

        check_choice(self.planner, PLANNERS, "--planner")
        check_choice(self.tool_point, TOOL_POINTS, "--tool-point")
        if any(_at_most_zero(x) for x in (self.diameter, self.teeth, self.accel, self.max_rpm)):
            raise ValueRangeError("--diameter, --teeth, --accel and --max-rpm must be "
                                  "positive")
        self.check_numbers()
        r, d = self.corner_radius, self.diameter
        if r is not None and (d is None or not 0 < r <= d / 2 + 1e-12):
            wrong = UsageError if d is None else ValueRangeError
            raise wrong("--corner-radius needs --diameter and must be above 0 and at most "
                        "half the diameter")
        if (self.vc is None) != (self.fz is None):
            raise UsageError("give both --vc and --fz, or neither (then the program's S and F "
                             "set them)")
        if self.vc is not None and (self.vc <= 0 or self.fz <= 0):
            raise ValueRangeError("--vc and --fz must be positive")
        low, high = self.min_rpm, self.max_rpm
        if low >= high:  # (a NaN max_rpm, no spindle for inspect, passes)
            raise ValueRangeError(f"--min-rpm is {'above' if low > high else 'equal to'} "
                                  f"--max-rpm ({low:g} and {high:g} RPM): the lowest spindle "
                                  "speed must be below the highest")
        check_choice(self.fz_policy, FZ_POLICIES, "--fz-policy")
        if not 0 < self.fz_band < 50:
            raise ValueRangeError("--fz-band is a percentage above 0 and below 50")
        self.check_control()
        self.check_part()
        self.check_shape()

    def check_numbers(self) -> None:
        """The numbers against :data:`ncopt.model.LIMITS` (the spindle's where it is known)."""
        spindle = ([("--accel", "accel_rad_s2", self.accel),
                    ("--max-rpm", "max_rpm", self.max_rpm)]
                   if self.accel == self.accel or self.max_rpm == self.max_rpm else [])
        check_numbers([("--diameter", "diameter_mm", self.diameter),
                       ("--corner-radius", "corner_radius_mm", self.corner_radius),
                       ("--teeth", "teeth", self.teeth), ("--vc", "vc_m_min", self.vc),
                       ("--fz", "fz_mm", self.fz), ("--min-rpm", "min_rpm", self.min_rpm),
                       ("--max-feed", "max_feed_mm_min", self.max_feed),
                       ("--rapid", "rapid_mm_min", self.rapid),
                       ("--min-rpm-step", "min_rpm_step", self.min_rpm_step),
                       ("--min-s-interval-ms", "min_s_interval_ms", self.min_s_interval_ms),
                       ("--tool", "tool", self.tool)]
                      + spindle)

    def check_control(self) -> None:
        """The control, where S may change and the decimal-point convention."""
        from ncopt.model import S_CHANGES
        from ncopt.reading.controls import CONTROLS
        from ncopt.reading.dialect import DECIMAL_POINT_CONVENTIONS

        check_choice(self.control, CONTROLS, "--dialect")
        check_choice(self.s_changes, S_CHANGES, "--s-changes")
        check_choice(self.decimal_point, DECIMAL_POINT_CONVENTIONS, "--decimal-point")

    def check_part(self) -> None:
        """The method, the remaining material and the stock; the operations named."""
        check_choice(self.method, get_args(MethodName), "--method")
        check_choice(self.allowance_along, get_args(AllowanceAlong), "--allowance-along")
        if not self.ap > 0:
            raise ValueRangeError("--ap must be positive")
        if not self.stock >= 0:
            raise ValueRangeError("--stock cannot be negative")
        if not math.isfinite(self.ap) or not math.isfinite(self.stock):
            raise ValueRangeError(f"--{'ap' if not math.isfinite(self.ap) else 'stock'} must "
                                  "be a finite length")
        given = self.operations
        if given is not None:
            parts = given.split(",") if isinstance(given, str) else list(given)
            self.operations = tuple(o.strip() for o in parts if o.strip())
            if self.operations == ():
                raise UsageError(f"--operations takes operation names separated by commas, "
                                 f"or all; not {given!r}")

    def check_shape(self) -> None:
        """The shape named: a bull-nose needs its corner radius, any shape a diameter."""
        check_choice(self.shape, get_args(Shape), "--shape")
        if self.shape == "bull-nose" and self.corner_radius is None:
            raise UsageError("--shape bull-nose needs --corner-radius")
        if self.shape is not None and self.diameter is None:
            raise UsageError("--shape needs --diameter")

    def job(self, profiles) -> "Job":
        """The Job of the values checked."""
        from ncopt.model import Cutter, CuttingData, Job, Machine, Method, PlanOptions

        named_shape = (self.shape is not None or self.corner_radius is not None
                       or self.cutter is not None)
        if self.shape == "ball":
            self.corner_radius = None
        m = self.profile
        cutter = (Cutter(self.diameter, self.teeth, self.corner_radius, self.tool_point)
                  if self.diameter is not None else None)
        same_spindle = m is not None and self.accel == m.accel_rad_s2 and self.max_rpm == m.max_rpm
        return Job(
            cutter=cutter,
            machine=Machine(self.accel, self.max_rpm, self.min_rpm, self.max_feed, self.rapid),
            cutting=CuttingData(self.vc, self.fz) if self.vc is not None else None,
            options=PlanOptions(planner=self.planner, min_rpm_step=self.min_rpm_step,
                                fz_tolerance=self.fz_band / 100.0, fz_policy=self.fz_policy,
                                min_s_interval_ms=self.min_s_interval_ms,
                                s_changes=self.s_changes),
            tool=self.tool, teeth=self.teeth, control=self.control,
            control_from=self.control_from,
            method=Method(self.method, self.ap, self.allowance_along),
            decimal_point=self.decimal_point,
            tool_library={k: c for k, (c, _) in profiles.tools.items() if isinstance(k, int)},
            operations=self.operations, shape_named=named_shape, stock_mm=self.stock,
            diameter_bare=self.bare, kinematics=self.kinematics,
            tcp=m.tcp if m is not None else None,
            machine_name=m.name if same_spindle else None)


def _at_most_zero(value) -> bool:
    """``value <= 0`` for a number; other values are left to their range's check."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool) and value <= 0
