"""The options several commands share, each declared once, and :func:`takes`, which gives
a command the ones it names.

Each option is a :class:`Shared`: its parameter name (the name
:func:`ncopt.planning.job.job_from_values` takes it by), its typer declaration and its
default; its ``rich_help_panel`` is where ``-h`` lists it (:data:`ncopt.cli.core.PANELS`).
A command declares only its own parameters and a ``given`` one: ``@takes(*FOR_PLANNING,
QUIET)`` adds the shared options to what typer sees and hands them to the command gathered
in one :class:`Given` (``given.mesh``, ``given.job()``).

A choice is typed by its ``Literal`` (``-h`` shows ``<lookahead|forward>``; the shell
completes it) but passed on as given: :mod:`ncopt.planning.job` checks it, with the message
ncopt has always given, in the order its checks run.
"""

# No `from __future__ import annotations`: typer reads these annotations as objects.
import functools
import inspect
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal, NamedTuple, Optional, get_args

import typer

from ncopt.planning.job import (AllowanceAlong, Control, DecimalPoint, FzPolicy, Kinematics,
                                MethodName, Planner, SChanges, Shape, ToolPoint)
from ncopt.runtime.stdio import COLOR_MODES

if TYPE_CHECKING:
    from ncopt.model import Job


class Shared(NamedTuple):
    """One option of several commands: parameter name, typer annotation, default."""

    name: str
    annotation: Any
    default: Any


def option(name: str, kind, default, *decls: str, panel: str, **settings) -> Shared:
    """A :class:`Shared` option: ``kind`` its type, ``decls`` its flags, listed by ``-h``
    in ``panel``."""
    return Shared(name, Annotated[kind, typer.Option(*decls, rich_help_panel=panel,
                                                     **settings)], default)


def as_given(value: str) -> str:
    """A choice passes as given: the library checks it (see the module's doc)."""
    return value


def choice(name: str, kind, default, *decls: str, panel: str, **settings) -> Shared:
    """A :class:`Shared` option whose values are the ``Literal`` ``kind``."""
    return option(name, kind if default is not None else Optional[kind], default, *decls,
                  panel=panel, parser=as_given, **settings)


# ------------------------------------------------------------------------- Cutter ----
CUTTER = "Cutter"
CUTTER_NAME = option("cutter", Optional[str], None, "--cutter", panel=CUTTER,
                     help="A named tool of the profiles instead of --diameter.")
DIAMETER = option("diameter", Optional[str], None, "--diameter", panel=CUTTER, help=(
    "Cutter diameter D: mm, or with a unit (6.35mm, 0.25in) (default: from the program's "
    "tool comments)."))
CORNER_RADIUS = option("corner_radius", Optional[str], None, "--corner-radius", panel=CUTTER,
                       help="Bull-nose corner radius r: mm, or with a unit (default: a ball).")
SHAPE = choice("shape", Shape, None, "--shape", panel=CUTTER, help=(
    "The cutter's shape, where the program's tool comment says otherwise (default: "
    "--diameter alone never overrides a flat end mill)."))
# Ranges: typer's own min= where the bound is closed (shown by -h as [x>=1], and a value
# outside, NaN included, is refused before the command runs); an open bound (above 0) is
# written in the help and checked, as every finite bound is, by ncopt.planning.job against
# ncopt.model.LIMITS, which the model's objects and the profiles share.
TEETH = option("teeth", int, 2, "--teeth", min=1, panel=CUTTER,
               help="Number of teeth z (matters with --fz).")
TOOL_POINT = choice("tool_point", ToolPoint, "tip", "--tool-point", panel=CUTTER,
                    help="The point the program moves: the tool's tip or its center.")

# ------------------------------------------------------------------------ Targets ----
TARGETS = "Targets"
MATERIAL = option("material", Optional[str], None, "--material", panel=TARGETS,
                  help="Cutting data (vc, fz) of the profiles by name.")
VC = option("vc", Optional[float], None, "--vc", panel=TARGETS, help=(
    "Cutting speed target, m/min, above 0 (default: the program's S at the nominal D)."))
FZ = option("fz", Optional[float], None, "--fz", panel=TARGETS, help=(
    "Feed per tooth target, mm, above 0 (default: the program's F / (z S))."))
FZ_BAND = option("fz_band", float, 2.0, "--fz-band", panel=TARGETS, help=(
    "Allowed fz deviation while the spindle ramps, percent, above 0 and below 50."))
FZ_POLICY = choice("fz_policy", FzPolicy, "centred", "--fz-policy", panel=TARGETS, help=(
    "centred: F keeps fz within the band both ways (default); below: fz never above its "
    "target (slower)."))

# ------------------------------------------------------------------------ Machine ----
MACHINE = "Machine"
MACHINE_NAME = option("machine", Optional[str], None, "--machine", panel=MACHINE,
                      help="A machine profile (see ncopt profiles).")
TOOLS_FILE = option("tools_file", Optional[Path], None, "--tools", panel=MACHINE,
                    help="A TOML file of machines, tools and cutting data.")
ACCEL = option("accel", Optional[float], None, "--accel", panel=MACHINE, help=(
    "Spindle acceleration, rad/s^2, finite and above 0 (default: from --machine)."))
MAX_RPM = option("max_rpm", Optional[float], None, "--max-rpm", min=1, panel=MACHINE,
                 help="Highest spindle speed, RPM, finite (default: from --machine).")
MIN_RPM = option("min_rpm", Optional[float], None, "--min-rpm", min=0, panel=MACHINE,
                 help="Lowest spindle speed, RPM, below --max-rpm.")
MAX_FEED = option("max_feed", Optional[float], None, "--max-feed", panel=MACHINE,
                  help="Highest feed, mm/min, above 0 (inf: no limit).")
RAPID = option("rapid", Optional[float], None, "--rapid", panel=MACHINE,
               help="Rapid traverse rate, mm/min, finite and above 0.")
KINEMATICS = choice("kinematics", Kinematics, None, "--kinematics", panel=MACHINE,
                    show_choices=False, help=(  # nine long names: listed in the help
    "The machine's 5-axis kinematics, for programs that tilt the tool with rotary axes "
    f"A/B/C: {', '.join(get_args(Kinematics)[:-1])}, or vector (tool vectors in the "
    "program, also detected). Default: from --machine."))

# ------------------------------------------------------------------------ Control ----
CONTROL = "Control"
DIALECT = choice("control", Control, None, "--dialect", "--control", panel=CONTROL, help=(
    "The control the program is for (default: detected from the program's marks)."))
DECIMAL_POINT = choice("decimal_point", DecimalPoint, None, "--decimal-point", panel=CONTROL,
                       help=(
    "How the Fanuc control reads a value without a decimal point: calculator (X25 = 25 mm), "
    "is-b (X25000 = 25 mm) or is-c (X250000 = 25 mm). Needed for a Fanuc program that "
    "writes such values."))
S_CHANGES = choice("s_changes", SChanges, None, "--s-changes", panel=CONTROL, help=(
    "anywhere: S follows the cut block by block; between-passes: one S per pass, changed "
    "only on the moves between passes (for controls that stop at every S word). Default: "
    "between-passes for grbl, else anywhere."))
S_INTERVAL = option("min_s_interval_ms", float, None, "--min-s-interval-ms", min=0,
                    panel=CONTROL, help="Least time between S words, ms (Sinumerik PLC).")

# --------------------------------------------------------------------------- Part ----
PART = "Part"
MESH = option("mesh", Optional[Path], None, "--mesh", panel=PART, help=(
    "Part mesh (STL, binary or ASCII), mm. Without it, normals come from the toolpath."))
STOCK = option("stock", str, "0", "--stock", panel=PART, help=(
    "Stock the program leaves on the part (as in the CAM): mm, or with a unit; the mesh is "
    "the finished part."))
METHOD = choice("method", MethodName, "contact", "--method", panel=PART, help=(
    "contact: R_eff at the contact point (default); material: where the edge meets the "
    "remaining material (the paper's second method)."))
AP = option("ap", str, "0.2", "--ap", panel=PART,
            help="Height of the remaining material: mm, or with a unit (0.008in).")
ALLOWANCE_ALONG = choice("allowance_along", AllowanceAlong, "normal", "--allowance-along",
                         panel=PART, help=(
    "normal (default) or axis: the remaining material is offset along the surface normal "
    "or the tool axis (finishing layers made by shifting Z)."))

# ----------------------------------------------------------------------- Planning ----
PLANNING = "Planning"
TOOL = option("tool", Optional[int], None, "--tool", min=0, panel=PLANNING,
              help="Plan only this T number.")
OPERATIONS = option("operations", Optional[str], None, "--operations", panel=PLANNING, help=(
    "Plan these operations (names as the program's comments give them, comma-separated), "
    "or all; default: the finishing operations ncopt recognises."))
PLANNER = choice("planner", Planner, "lookahead", "--planner", panel=PLANNING, help=(
    "lookahead (default), or forward: the paper's flow chart."))
MIN_STEP = option("min_rpm_step", float, 10.0, "--min-rpm-step", panel=PLANNING,
                  help="Emit S only when it changes by at least this, RPM, above 0.")

# ------------------------------------------------------------------------- Output ----
OUTPUT = "Output"
REPORT_LITE = option("report_lite", bool, False, "--report-lite", "--lite", panel=OUTPUT, help=(
    "Static images instead of the interactive plots: no plotly.js, a page well under 1 MB "
    "to mail."))
QUIET = option("quiet", bool, False, "--quiet", "-q", panel=OUTPUT,
               help="No summary on stderr (errors still are).")
# per command, not on the root: typer converts every option value that is not a flag through
# pydantic (90 ms to import), and a root option is converted before any command's -h.
# ncopt.runtime.stdio.set_color checks it, as every command starts.
COLOR = choice("color", Literal[COLOR_MODES], "auto", "--color", panel=OUTPUT, help=(
    "Colour: auto (on a terminal, unless NO_COLOR is set), always or never."))

# ------------------------------------------------------- what each command takes ----
#: rewrite and batch: everything that makes a plan
FOR_PLANNING = (CUTTER_NAME, DIAMETER, CORNER_RADIUS, SHAPE, TEETH, TOOL_POINT,
                MATERIAL, VC, FZ, FZ_BAND, FZ_POLICY,
                MACHINE_NAME, TOOLS_FILE, ACCEL, MAX_RPM, MIN_RPM, MAX_FEED, RAPID, KINEMATICS,
                DIALECT, DECIMAL_POINT, S_CHANGES, S_INTERVAL,
                MESH, STOCK, METHOD, AP, ALLOWANCE_ALONG,
                TOOL, OPERATIONS, PLANNER, MIN_STEP)
#: simulate and report: the program replayed as written, with the cutter, targets and machine
FOR_REPLAY = (CUTTER_NAME, DIAMETER, CORNER_RADIUS, SHAPE, TEETH, TOOL_POINT, MATERIAL, VC, FZ,
              MACHINE_NAME, TOOLS_FILE, ACCEL, MAX_RPM, MIN_RPM, MAX_FEED, RAPID, KINEMATICS,
              DIALECT, DECIMAL_POINT, MESH, TOOL)
#: inspect: what ncopt reads of a program, with no spindle
FOR_INSPECTION = (CUTTER_NAME, DIAMETER, CORNER_RADIUS, SHAPE, TEETH, MATERIAL, VC, FZ,
                  MACHINE_NAME, TOOLS_FILE, MAX_FEED, KINEMATICS, DIALECT, DECIMAL_POINT,
                  TOOL, OPERATIONS)


class Given:
    """The shared options a command was given, by parameter name (``given.mesh``)."""

    def __init__(self, values: dict) -> None:
        self.__dict__.update(values)

    def job(self, spindle_needed: bool = True) -> "Job":
        """The Job these options ask for, checked (:func:`ncopt.planning.job.build_job`)."""
        from ncopt.planning.job import VALUE_NAMES, job_from_values

        values = {k: v for k, v in vars(self).items() if k in VALUE_NAMES}
        return job_from_values(spindle_needed=spindle_needed, **values)


def takes(*shared: Shared):
    """A command that takes ``shared`` besides its own parameters: typer sees them all; the
    command gets the shared ones in its parameter ``given`` (a :class:`Given`)."""
    def decorate(command):
        signature = inspect.signature(command)
        own = [p.replace(kind=inspect.Parameter.KEYWORD_ONLY)
               for p in signature.parameters.values() if p.name != "given"]
        added = [inspect.Parameter(s.name, inspect.Parameter.KEYWORD_ONLY,
                                   annotation=s.annotation, default=s.default) for s in shared]
        names = [s.name for s in shared]

        @functools.wraps(command)
        def run(**values):
            given = Given({name: values.pop(name) for name in names})
            return command(**values, given=given)

        run.__signature__ = signature.replace(parameters=own + added)
        run.__annotations__ = {p.name: p.annotation for p in own + added}
        return run
    return decorate
