"""``ncopt`` command line: a thin typer layer over :mod:`ncopt.api`.

Startup stays light: ``ncopt --help``, ``ncopt COMMAND -h`` and ``ncopt version`` import
neither numpy nor lark nor the api, nor pydantic (which typer loads to convert any option
value that is not a flag); each command imports what it needs in its body.  Every command
runs inside :func:`ncopt.runtime.stdio.command_faults`, so an ncopt error, an interrupt (Ctrl-C or
SIGTERM) or a failed write to stdout ends it with one line on stderr and an exit code of
:class:`Exit`, never a traceback.  A command added with ``@app.command()`` gets the same.
"""

# No `from __future__ import annotations` here: typer evaluates every string annotation when
# it builds the commands, a third of the time `ncopt --help` took.
import functools
import math
import os
import re
import signal
import sys
from enum import IntEnum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Optional

import typer
from typer.core import TyperGroup

from ncopt import __version__
from ncopt.runtime.errors import (FileError, MeshError, NcoptError, NcParseError, NothingToPlan,
                     PlanningError, UsageError, ValueRangeError, VerificationError,
                     from_program)
from ncopt.runtime.stdio import (command_faults, count, err, interrupt, read_programs, require_stdout,
                    say, set_color, stages, stderr_console, styled, write_stdout)

if TYPE_CHECKING:
    from rich.console import Console

    from ncopt.api import Summary
    from ncopt.model import Job


class Exit(IntEnum):
    """Exit codes scripts can rely on."""

    OK = 0
    INTERNAL = 1
    USAGE = 2
    PROGRAM = 3  # the NC program is malformed or cannot be interpreted
    MESH = 4
    PLANNING = 5
    VERIFICATION = 6  # the rewrite failed its own checks; nothing written
    IO = 7
    SOME_FAILED = 8  # batch: some files failed, the others were written
    NOTHING_DONE = 9  # batch: no program found, or every file failed
    INTERRUPTED = 130


DIFFERENT = 1  # ncopt diff: the files differ (as diff(1) says it)
WOULD_CHANGE = 1  # ncopt rewrite --check: the rewrite would change the program (as black)


class _Group(TyperGroup):
    """typer's group, with shell completion served although ncopt declares the completion
    options itself (see InstallCompletion): typer registers its shells only where it adds
    them."""

    def _main_shell_completion(self, ctx_args, prog_name, complete_var=None):
        var = complete_var or f"_{prog_name}_COMPLETE".replace("-", "_").upper()
        if os.environ.get(var):
            from typer.completion import completion_init

            completion_init()
        return super()._main_shell_completion(ctx_args, prog_name, complete_var)


class _App(typer.Typer):
    """typer.Typer whose commands all run inside :func:`ncopt.runtime.stdio.command_faults`."""

    def command(self, *args, **kwargs):
        register = super().command(*args, **kwargs)

        def decorator(fn):
            register(_guarded(fn))
            return fn
        return decorator


app = _App(cls=_Group, add_completion=False, pretty_exceptions_show_locals=False,
           no_args_is_help=True, rich_markup_mode=None,
           context_settings={"help_option_names": ["-h", "--help"]},
           help="Rewrite S and F words of finishing programs for constant vc and fz.")


# options shared by rewrite, batch and simulate
Mesh = Annotated[Optional[Path], typer.Option(
    "--mesh", help="Part mesh (STL, binary or ASCII), mm. Without it, normals come from "
    "the toolpath.")]
Diameter = Annotated[Optional[str], typer.Option(
    "--diameter", help="Cutter diameter D: mm, or with a unit (6.35mm, 0.25in) (default: "
    "from the program's tool comments).")]
CornerRadius = Annotated[Optional[str], typer.Option(
    "--corner-radius", help="Bull-nose corner radius r: mm, or with a unit (default: a ball).")]
# Ranges: typer's own min= where the bound is closed (shown by -h as [x>=1], and a value
# outside, NaN included, is refused before the command runs); an open bound (above 0) is
# written in the help and checked, as every finite bound is, by make_job against
# ncopt.model.LIMITS, which the model's objects and the profiles share.
Teeth = Annotated[int, typer.Option("--teeth", min=1,
                                    help="Number of teeth z (matters with --fz).")]
Vc = Annotated[Optional[float], typer.Option(
    "--vc", help="Cutting speed target, m/min, above 0 (default: the program's S at the "
    "nominal D).")]
Fz = Annotated[Optional[float], typer.Option(
    "--fz", help="Feed per tooth target, mm, above 0 (default: the program's F / (z S)).")]
Accel = Annotated[Optional[float], typer.Option(
    "--accel", help="Spindle acceleration, rad/s^2, finite and above 0 (default: from "
    "--machine).")]
MaxRpm = Annotated[Optional[float], typer.Option(
    "--max-rpm", min=1, help="Highest spindle speed, RPM, finite (default: from --machine).")]
MinRpm = Annotated[Optional[float], typer.Option(
    "--min-rpm", min=0, help="Lowest spindle speed, RPM, below --max-rpm.")]
MaxFeed = Annotated[Optional[float], typer.Option(
    "--max-feed", help="Highest feed, mm/min, above 0 (inf: no limit).")]
MachineName = Annotated[Optional[str], typer.Option(
    "--machine", help="A machine profile (see ncopt profiles).")]
ToolsFile = Annotated[Optional[Path], typer.Option(
    "--tools", help="A TOML file of machines, tools and cutting data.")]
CutterName = Annotated[Optional[str], typer.Option(
    "--cutter", help="A named tool of the profiles instead of --diameter.")]
Material = Annotated[Optional[str], typer.Option(
    "--material", help="Cutting data (vc, fz) of the profiles by name.")]
Planner = Annotated[str, typer.Option("--planner", help="lookahead or forward.")]
ToolPoint = Annotated[str, typer.Option("--tool-point", help="Programmed point: tip or center.")]
MinStep = Annotated[float, typer.Option(
    "--min-rpm-step", help="Emit S only when it changes by at least this, RPM, above 0.")]
Tool = Annotated[Optional[int], typer.Option("--tool", min=0, help="Plan only this T number.")]
Rapid = Annotated[Optional[float], typer.Option(
    "--rapid", help="Rapid traverse rate, mm/min, finite and above 0.")]
FzPolicy = Annotated[str, typer.Option(
    "--fz-policy", help="centred: F keeps fz within the band both ways (default); below: fz "
    "never above its target (slower).")]
FzBand = Annotated[float, typer.Option("--fz-band", help="Allowed fz deviation while the "
                                       "spindle ramps, percent, above 0 and below 50.")]
Control = Annotated[Optional[str], typer.Option(
    "--dialect", "--control", help="The control the program is for: sinumerik, fanuc, "
    "linuxcnc, grbl, heidenhain-iso or generic (default: detected from the program's marks).")]
DecimalPoint = Annotated[Optional[str], typer.Option(
    "--decimal-point", help="How the Fanuc control reads a value without a decimal point: "
    "calculator (X25 = 25 mm), is-b (X25000 = 25 mm) or is-c (X250000 = 25 mm). Needed for a "
    "Fanuc program that writes such values.")]
MethodName = Annotated[str, typer.Option(
    "--method", help="contact: R_eff at the contact point (default); material: where the "
    "edge meets the remaining material (the paper's second method).")]
Ap = Annotated[str, typer.Option("--ap", help="Height of the remaining material: mm, or "
                                  "with a unit (0.008in).")]
AllowanceAlong = Annotated[str, typer.Option(
    "--allowance-along", help="normal (default) or axis: the remaining material is offset "
    "along the surface normal or the tool axis (finishing layers made by shifting Z).")]
SInterval = Annotated[float, typer.Option(
    "--min-s-interval-ms", min=0, help="Least time between S words, ms (Sinumerik PLC).")]
Operations = Annotated[Optional[str], typer.Option(
    "--operations", help="Plan these operations (names as the program's comments give "
    "them, comma-separated), or all; default: the finishing operations ncopt recognises.")]
Stock = Annotated[str, typer.Option(
    "--stock", help="Stock the program leaves on the part (as in the CAM): mm, or with a "
    "unit; the mesh is the finished part.")]
Shape = Annotated[Optional[str], typer.Option(
    "--shape", help="ball or bull-nose: the cutter's shape, where the program's tool "
    "comment says otherwise (default: --diameter alone never overrides a flat end mill).")]
ReportLite = Annotated[bool, typer.Option(
    "--report-lite", "--lite", help="Static images instead of the interactive plots: no "
    "plotly.js, a page well under 1 MB to mail.")]
ReportFile = Annotated[Optional[Path], typer.Option(
    "--report", help="Also write an HTML report: times, S/F/fz/D_eff curves, a 3D toolpath "
    "and the changed blocks, in one file that opens offline.")]
SChanges = Annotated[Optional[str], typer.Option(
    "--s-changes", help="anywhere: S follows the cut block by block; between-passes: one S "
    "per pass, changed only on the moves between passes (for controls that stop at every S "
    "word). Default: between-passes for grbl, else anywhere.")]
Quiet = Annotated[bool, typer.Option("--quiet", "-q", help="No summary on stderr (errors "
                                     "still are).")]
# per command, not on the root: typer converts every option value that is not a flag through
# pydantic (90 ms to import), and a root option is converted before any command's -h
Color = Annotated[str, typer.Option(
    "--color", metavar="WHEN", help="Colour: auto (on a terminal, unless NO_COLOR is set), "
    "always or never.")]
KinematicsName = Annotated[Optional[str], typer.Option(
    "--kinematics", help="The machine's 5-axis kinematics, for programs that tilt the tool "
    "with rotary axes A/B/C: xyzac-trt, xyzac-head-table, xyzac-trt-linuxcnc, xyzbc-trt, "
    "xyzbc-head-table, xyzbc-head-head, xyzbc-trt-linuxcnc, xyzbc-5axis-linuxcnc, or vector "
    "(tool vectors in the program, also detected). Default: from --machine.")]


def _exit_code(exc: NcoptError) -> Exit:
    for kind, code in ((FileError, Exit.IO), (UsageError, Exit.USAGE), (MeshError, Exit.MESH),
                       (PlanningError, Exit.PLANNING), (VerificationError, Exit.VERIFICATION),
                       (NcParseError, Exit.PROGRAM)):
        if isinstance(exc, kind):
            return code
    return Exit.PROGRAM


def _fail(exc: NcoptError) -> None:
    say(str(exc), error=True)
    raise typer.Exit(int(_exit_code(exc)))


def _guarded(fn):
    @functools.wraps(fn)
    def run(*args, **kwargs):
        with command_faults(_exit_code, Exit.INTERRUPTED):
            set_color(kwargs.get("color", "auto"))  # every run: in-process runs share it
            return fn(*args, **kwargs)
    return run


def _print_version(value: bool) -> None:
    if value:
        raise typer.Exit(_say_version())


def _say_version() -> int:
    """Print the version; the exit code (a closed stdout is exit 7 here too)."""
    try:
        write_stdout(f"{__version__}\n".encode())
    except FileError as exc:
        say(str(exc))
        return int(Exit.IO)
    return int(Exit.OK)


def _show_help(ctx: typer.Context, value: bool) -> None:
    if value and not ctx.resilient_parsing:
        typer.echo(ctx.get_help(), color=ctx.color)
        raise typer.Exit()


# The help flag of a group, declared rather than left to click: click's own reaches typer's
# value conversion as None, not a bool, and so imports pydantic before every `COMMAND -h`.
HelpFlag = Annotated[bool, typer.Option(
    "-h", "--help", is_eager=True, expose_value=False, callback=_show_help,
    help="Show this message and exit.")]


def _completion(action: str):
    """typer's --install-completion / --show-completion callback, for a flag of our own."""
    def run(ctx: typer.Context, param: typer.CallbackParam, value: bool) -> None:
        if value and not ctx.resilient_parsing:
            from typer import completion

            completion.completion_init()
            done = completion.install_callback if action == "install" else completion.show_callback
            done(ctx, param, value)
    return run


# typer's own completion options (add_completion) default to None, not False: like click's
# help flag above, they would load pydantic before every command ran or showed its help
InstallCompletion = Annotated[bool, typer.Option(
    "--install-completion", expose_value=False, callback=_completion("install"),
    help="Install completion for the current shell.")]
ShowCompletion = Annotated[bool, typer.Option(
    "--show-completion", expose_value=False, callback=_completion("show"),
    help="Show completion for the current shell, to copy it or customize the installation.")]


@app.callback()
def _root(version: Annotated[bool, typer.Option(
        "--version", is_eager=True, callback=_print_version,
        help="Print the version and exit.")] = False, show_help: HelpFlag = False,
        install_completion: InstallCompletion = False,
        show_completion: ShowCompletion = False) -> None:
    """Rewrite S and F words of finishing programs for constant vc and fz."""


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


def make_job(diameter=None, corner_radius=None, teeth=2, vc=None, fz=None, accel=None,
             max_rpm=None, min_rpm=None, max_feed=None, planner="lookahead",
             tool_point="tip", min_rpm_step=10.0, tool=None, rapid=None,
             fz_policy="centred", fz_band=2.0, control=None, min_s_interval_ms=None,
             machine=None, tools_file=None, cutter=None, material=None,
             method="contact", ap=0.2, allowance_along="normal", decimal_point=None,
             operations=None, shape=None, stock=0.0, s_changes=None,
             kinematics=None, spindle_needed=True) -> "Job":
    """A Job from command-line values and the profiles, checked; raises UsageError.

    Command-line values win; then the machine profile (--machine, else NCOPT_MACHINE,
    else the profiles' default_machine); then ncopt's defaults.  ``spindle_needed``
    False (inspect, which plans nothing): without a spindle given, its figures are NaN.
    """
    from ncopt.model import Job
    from ncopt.model import Method
    from ncopt.reading.controls import CONTROLS, S_CHANGES
    from ncopt.reading.dialect import DECIMAL_POINT_CONVENTIONS
    from ncopt.model import Cutter, CuttingData, Machine, PlanOptions
    from ncopt.planning.profiles import load

    bare = diameter is not None and not isinstance(diameter, (int, float)) and \
        _LENGTH.match(str(diameter)) is not None and _LENGTH.match(str(diameter)).group(2) is None
    diameter, corner_radius = length_mm(diameter, "--diameter"), length_mm(corner_radius,
                                                                          "--corner-radius")
    ap, stock = length_mm(ap, "--ap"), length_mm(stock, "--stock")
    profiles = load(tools_file=tools_file)
    m = profiles.chosen_machine(machine)
    name = m.name if m is not None else None
    pick = lambda given, attr, default: given if given is not None else (  # noqa: E731
        getattr(m, attr) if m is not None else default)
    accel, max_rpm = pick(accel, "accel_rad_s2", None), pick(max_rpm, "max_rpm", None)
    min_rpm, max_feed = pick(min_rpm, "min_rpm", 0.0), pick(max_feed, "max_feed_mm_min", float("inf"))
    control_from = "given" if control is not None else f"machine profile {name}"
    rapid, control = pick(rapid, "rapid_mm_min", 10000.0), pick(control, "control", None)
    min_s_interval_ms = pick(min_s_interval_ms, "min_s_interval_ms", 0.0)
    decimal_point = pick(decimal_point, "decimal_point", None)
    s_changes = pick(s_changes, "s_changes", None)
    from ncopt.motion.kinematics import check_name

    kinematics = check_name(pick(kinematics, "kinematics", None))
    if cutter is not None:
        if diameter is not None:
            raise UsageError("give --cutter or --diameter, not both")
        named = profiles.tool(cutter)
        if named is None:
            raise UsageError(f"no tool {cutter!r} in the profiles; see ncopt profiles")
        diameter, corner_radius, teeth = named.diameter_mm, named.corner_radius_mm, named.teeth
    if material is not None:
        if vc is not None or fz is not None:
            raise UsageError("give --material or --vc/--fz, not both")
        data = profiles.material(material)
        vc, fz = data.vc_m_min, data.fz_mm
    if (accel is None or max_rpm is None) and spindle_needed:
        raise UsageError("give the spindle: --accel RAD_S2 and --max-rpm RPM, or a --machine "
                         "profile (ncopt profiles lists them)")
    if accel is None or max_rpm is None:
        accel = max_rpm = float("nan")
    if planner not in ("lookahead", "forward"):
        raise UsageError(f"--planner must be lookahead or forward, not {planner!r}")
    if tool_point not in ("tip", "center"):
        raise UsageError(f"--tool-point must be tip or center, not {tool_point!r}")
    if (diameter is not None and diameter <= 0) or teeth <= 0 or accel <= 0 or max_rpm <= 0:
        raise UsageError("--diameter, --teeth, --accel and --max-rpm must be positive")
    check_numbers([("--diameter", "diameter_mm", diameter),
                   ("--corner-radius", "corner_radius_mm", corner_radius),
                   ("--teeth", "teeth", teeth), ("--vc", "vc_m_min", vc), ("--fz", "fz_mm", fz),
                   ("--min-rpm", "min_rpm", min_rpm), ("--max-feed", "max_feed_mm_min", max_feed),
                   ("--rapid", "rapid_mm_min", rapid),
                   ("--min-rpm-step", "min_rpm_step", min_rpm_step),
                   ("--min-s-interval-ms", "min_s_interval_ms", min_s_interval_ms)]
                  + ([("--accel", "accel_rad_s2", accel), ("--max-rpm", "max_rpm", max_rpm)]
                     if accel == accel or max_rpm == max_rpm else []))
    if corner_radius is not None and (diameter is None or not 0 < corner_radius <= diameter / 2 + 1e-12):
        raise UsageError("--corner-radius needs --diameter and must be above 0 and at most "
                         "half the diameter")
    if (vc is None) != (fz is None):
        raise UsageError("give both --vc and --fz, or neither (then the program's S and F set them)")
    if vc is not None and (vc <= 0 or fz <= 0):
        raise UsageError("--vc and --fz must be positive")
    if min_rpm >= max_rpm:  # (a NaN max_rpm, no spindle for inspect, passes)
        raise UsageError(f"--min-rpm is {'above' if min_rpm > max_rpm else 'equal to'} "
                         f"--max-rpm ({min_rpm:g} and {max_rpm:g} RPM): the lowest spindle "
                         "speed must be below the highest")
    if fz_policy not in ("centred", "below"):
        raise UsageError(f"--fz-policy must be centred or below, not {fz_policy!r}")
    if not 0 < fz_band < 50:
        raise UsageError("--fz-band is a percentage above 0 and below 50")
    if control is not None and control not in CONTROLS:
        raise UsageError(f"--dialect must be one of {', '.join(CONTROLS)}, not {control!r}")
    if s_changes is not None and s_changes not in S_CHANGES:
        raise UsageError(f"--s-changes must be anywhere or between-passes, not {s_changes!r}")
    if decimal_point is not None and decimal_point not in DECIMAL_POINT_CONVENTIONS:
        raise UsageError(f"--decimal-point must be one of {', '.join(DECIMAL_POINT_CONVENTIONS)}, "
                         f"not {decimal_point!r}")
    if method not in ("contact", "material"):
        raise UsageError(f"--method must be contact or material, not {method!r}")
    if allowance_along not in ("normal", "axis"):
        raise UsageError(f"--allowance-along must be normal or axis, not {allowance_along!r}")
    if not ap > 0:
        raise UsageError("--ap must be positive")
    if not stock >= 0:
        raise UsageError("--stock cannot be negative")
    if not math.isfinite(ap) or not math.isfinite(stock):
        raise UsageError(f"--{'ap' if not math.isfinite(ap) else 'stock'} must be a finite "
                         "length")
    names = None if operations is None else tuple(
        o.strip() for o in operations.split(",") if o.strip())
    if names == ():
        raise UsageError(f"--operations takes operation names separated by commas, or all; "
                         f"not {operations!r}")
    if shape is not None and shape not in ("ball", "bull-nose"):
        raise UsageError(f"--shape must be ball or bull-nose, not {shape!r}")
    if shape == "bull-nose" and corner_radius is None:
        raise UsageError("--shape bull-nose needs --corner-radius")
    if shape is not None and diameter is None:
        raise UsageError("--shape needs --diameter")
    if shape == "ball":
        corner_radius = None
    chosen = Cutter(diameter, teeth, corner_radius, tool_point) if diameter is not None else None
    return Job(cutter=chosen, machine=Machine(accel, max_rpm, min_rpm, max_feed, rapid),
               cutting=CuttingData(vc, fz) if vc is not None else None,
               options=PlanOptions(planner=planner, min_rpm_step=min_rpm_step,
                                   fz_tolerance=fz_band / 100.0, fz_policy=fz_policy,
                                   min_s_interval_ms=min_s_interval_ms, s_changes=s_changes),
               tool=tool, teeth=teeth, control=control, control_from=control_from,
               method=Method(method, ap, allowance_along), decimal_point=decimal_point,
               tool_library={k: c for k, (c, _) in profiles.tools.items() if isinstance(k, int)},
               operations=names,
               shape_named=shape is not None or corner_radius is not None or cutter is not None,
               stock_mm=stock, diameter_bare=bare, kinematics=kinematics, tcp=pick(None, "tcp", None),
               machine_name=name if m is not None and accel == m.accel_rad_s2
               and max_rpm == m.max_rpm else None)


def check_numbers(values) -> None:
    """Refuse (UsageError, exit 2) an option's number outside its range, naming the option
    and the range: ``values`` holds (option, key of ncopt.model.LIMITS, value or None)."""
    from ncopt.model import LIMITS

    for option, key, value in values:
        bounds = LIMITS[key]
        if value is not None and not bounds.holds(value):
            shown = f"{value:g}" if isinstance(value, float) else repr(value)
            raise UsageError(f"{option} must be {bounds.describe()}, not {shown}")


def _job_options(values: dict) -> dict:
    """The command's options that make_job takes (commands share their names)."""
    names = make_job.__code__.co_varnames[:make_job.__code__.co_argcount]
    return {k: v for k, v in values.items() if k in names}


@app.command()
def rewrite(
    input: Annotated[str, typer.Argument(help="NC program to rewrite, or - for stdin.")],
    output: Annotated[Optional[str], typer.Option(
        "-o", "--output", help="Where to write: a file, a folder (ending in /: the input's "
        "name inside it); - or omitted: stdout.")] = None,
    mesh: Mesh = None, diameter: Diameter = None, corner_radius: CornerRadius = None,
    teeth: Teeth = 2, vc: Vc = None, fz: Fz = None, accel: Accel = None,
    max_rpm: MaxRpm = None, min_rpm: MinRpm = None, max_feed: MaxFeed = None,
    planner: Planner = "lookahead", tool_point: ToolPoint = "tip", min_rpm_step: MinStep = 10.0,
    tool: Tool = None, rapid: Rapid = None, fz_policy: FzPolicy = "centred",
    fz_band: FzBand = 2.0, control: Control = None, decimal_point: DecimalPoint = None,
    min_s_interval_ms: SInterval = None, s_changes: SChanges = None,
    machine: MachineName = None, tools_file: ToolsFile = None, cutter: CutterName = None,
    material: Material = None, method: MethodName = "contact", ap: Ap = "0.2",
    allowance_along: AllowanceAlong = "normal", operations: Operations = None,
    shape: Shape = None, stock: Stock = "0", report: ReportFile = None, quiet: Quiet = False,
    kinematics: KinematicsName = None, report_lite: ReportLite = False,
    as_json: Annotated[bool, typer.Option(
        "--json", help="The summary as one JSON object on stderr instead of text (stdout "
        "stays the program).")] = False,
    check: Annotated[bool, typer.Option(
        "--check", help="Write nothing: exit 0 when the rewrite would change nothing, 1 "
        "when it would, and say what would change (unless -q).")] = False,
    color: Color = "auto",
) -> None:
    """Rewrite a program's S and F words; every other byte stays as it is."""
    from ncopt.api import rewrite_file
    from ncopt.runtime.fileio import output_file, write_output

    job = make_job(**_job_options(locals()))
    if check and (output is not None or report is not None):
        raise UsageError("--check writes nothing: leave out -o and --report")
    _check_report(report)
    target = None if check else output_file(output, input)
    guard_outputs(_read_by(("program", input), mesh=mesh, tools_file=tools_file),
                  [("-o", target), ("--report", report)])
    [data] = read_programs([input])
    try:
        with stages(quiet or as_json) as show:
            result = rewrite_file(input, job, mesh_path=mesh, data=data, progress=show)
    except ValueRangeError as exc:  # the options were checked: the program gave the value
        raise from_program(exc, input) from None
    except NothingToPlan as exc:
        if check:  # the rewrite would leave the program as it is
            if not quiet:
                say(f"ncopt: {input}: nothing would change: {exc.message}")
            return
        if target is None:  # a filter never eats its input
            write_stdout(data)
        raise
    text = result.text.encode("latin-1")
    if check:
        _check_verdict(input, data, text, result.summary, quiet, as_json)
        return
    if target is None:
        write_stdout(text)
    else:
        write_output(target, text)
    if report is not None:
        from ncopt.report.html import from_rewrite
        _write_report(report, lambda index: from_rewrite(
            result, data.decode("latin-1"), input, output or "-", job, index), mesh, quiet,
            report_lite)
    if as_json:
        import json
        say(json.dumps(result.summary.to_dict(), indent=2))
    elif not quiet:
        print_summary(result.summary, err)


def guard_outputs(inputs, outputs, in_place=()) -> None:
    """:func:`ncopt.runtime.fileio.guard_outputs`, imported when a command runs (not for -h)."""
    from ncopt.runtime import fileio

    fileio.guard_outputs(inputs, outputs, in_place)


def _read_by(*programs, mesh=None, tools_file=None) -> list:
    """(what, path) of every file a command reads: its programs, the mesh, the profile
    files (--tools, and the ncopt.toml files found: the project's, the user's)."""
    from ncopt.planning.profiles import search_paths

    return [*programs, ("mesh", mesh)] + [("profile file", p)
                                          for p in search_paths(tools_file=tools_file)]


def guard_batch(files, targets, report, pages, in_place, mesh, tools_file) -> None:
    """A batch's outputs (the rewrites, the report and its pages) checked against its
    inputs, one another and, in place, the programs' backups (ncopt.runtime.fileio.guard_outputs)."""
    outputs = [] if in_place else [("-o", t) for t in targets]
    outputs += [("--report", report)] + [("--report (a program's page)", p) for p in pages]
    guard_outputs([("program", f) for f in files] + _read_by(mesh=mesh, tools_file=tools_file),
                  outputs, in_place=files if in_place else ())


def _check_verdict(name: str, data: bytes, text: bytes, summary: "Summary", quiet: bool,
                   as_json: bool) -> None:
    """rewrite --check: what the rewrite would change; exit 1 when it would change
    anything (black's convention), else return (exit 0)."""
    if as_json:
        import json
        say(json.dumps(summary.to_dict(), indent=2))
    elif not quiet:
        print_summary(summary, err)
    if text == data:
        if not quiet and not as_json:
            say(f"ncopt: {name}: nothing would change")
        return
    if not quiet and not as_json:
        from ncopt.report.diffview import totals

        t = totals(data.decode("latin-1").splitlines(), text.decode("latin-1").splitlines())
        say(f"ncopt: {name} would change: {t.changed} of {count(t.lines, 'line')} (S in "
            f"{t.s_changed}, F in {t.f_changed}); nothing written (--check)")
    raise typer.Exit(WOULD_CHANGE)


def _check_report(report: Optional[Path], json_ok: bool = False,
                  made_folder: Optional[Path] = None) -> None:
    """Refuse a report that cannot be written before the (long) work, not after it
    (``made_folder``: the output folder the command creates, a report may go there)."""
    if report is None:
        return
    if not (json_ok and report.suffix.lower() == ".json"):
        from ncopt.report.html import require_libraries
        require_libraries()
    parent = report.resolve().parent
    if made_folder is not None and parent == made_folder.resolve():
        return
    if not parent.is_dir():
        raise FileError("the folder to write into does not exist; create it first", str(report))


def _write_report(path: Path, gather, mesh: Optional[Path], quiet: bool = False,
                  lite: bool = False) -> None:
    """Simulate what the report shows (with the mesh, if any) and write the page (``lite``:
    static images, no plotly.js)."""
    from ncopt.runtime.fileio import write_output
    from ncopt.contacts.geometry import MeshIndex, load_stl
    from ncopt.report.html import render

    page = render(gather(MeshIndex(load_stl(mesh)) if mesh else None), lite=lite)
    write_output(path, page.encode("utf-8"))
    if not quiet:
        say(f"ncopt: report written to {path}")


def s_changes_line(s: "Summary") -> str:
    """Where S changes, why, and what the other choice would cut in."""
    why = s.s_changes_source
    other = (f"{s.cut_time_other_min:.1f} min" if s.cut_time_other_min == s.cut_time_other_min
             else "not possible with these cutting data")
    n = f"{s.passes} pass" + ("" if s.passes == 1 else "es")
    if s.s_changes == "between-passes":
        return (f"S changes between passes only ({why}): one S for each of {n}; with S "
                f"changing anywhere along the cut: {other}")
    return (f"S changes anywhere along the cut ({why}); between passes only (one S for each "
            f"of {n}): {other}")


def print_summary(s: "Summary", console: "Console") -> None:
    """The few lines a machinist reads after a rewrite."""
    say = lambda text: console.print(styled(text))  # noqa: E731
    say(f"ncopt: {count(s.blocks, 'block')}, {count(s.cutting_blocks, 'cutting block')} "
        f"planned, {s.s_words} S and {count(s.f_words, 'F word')} written")
    planned = sum(1 for o in s.operations if o.planned)
    say(f"ncopt: {planned} of {count(len(s.operations), 'operation')} planned; program in "
        f"{s.units}")
    for o in s.operations:
        say("ncopt:   " + _op_line(o))
    for tool, what, source in s.tools:
        name = f"T{tool}" if tool >= 0 else "tool"
        say(f"ncopt: {name}: {what} (from {'the options' if source == 'options' else source})")
    for tool, why in s.skipped_tools:
        say(f"ncopt: T{tool} left untouched: {why}")
    say(f"ncopt: vc {s.vc_m_min:.1f} m/min, fz {s.fz_mm:.4f} mm, highest S {s.max_s_rpm:.0f} RPM")
    say(f"ncopt: estimated cutting time {s.cut_time_before_min:.1f} -> "
        f"{s.cut_time_after_min:.1f} min ({s.time_change_pct:+.1f} %), the whole program "
        f"(planned operations {s.planned_time_before_min:.1f} -> {s.planned_time_after_min:.1f} min)")
    if s.untimed_moves:
        say(f"ncopt: {count(s.untimed_moves, 'feed block')} "
            f"{'is' if s.untimed_moves == 1 else 'are'} not timed (position or feed not known)")
    say(f"ncopt: {s_changes_line(s)}")
    if s.mesh_edge_mm is not None:
        say(f"ncopt: mesh median edge {s.mesh_edge_mm:.2f} mm")
    for tool, fit in s.mesh_fit:
        say(f"ncopt: T{tool}: the mesh fits {fit.touching_pct:.1f} % of the planned cut "
            f"({fit.air_pct:.1f} % in the air, {fit.gouge_pct:.1f} % inside the part, deepest "
            f"{fit.deepest_gouge_mm:.3f} mm)")
    if s.normals_from == "toolpath":
        say(f"ncopt: no mesh: normals from the toolpath (stepover {s.stepover_mm:.2f} mm); "
            f"{count(s.one_sided_points, 'point')} at the edge of the machined area planned "
            "conservatively")
        if s.unknown_contact_pct > 0:
            say(f"ncopt: {s.unknown_contact_pct:.1f} % of the planned cut has no contact the "
                "toolpath can show (walls, plunges, passes with no neighbour): planned at the "
                "cutter's full diameter (see the warnings for the lines)")
    say(f"ncopt: dialect {s.control} ({s.control_source})")
    for note in s.control_notes:
        say(f"ncopt: {s.control} control: {note}")
    if s.close_s_words:
        say(f"ncopt: {count(s.close_s_words, 'S word')} had to come sooner than "
            "--min-s-interval-ms after the previous one (a fall in speed that vc needs)")
    for w in s.warnings[:10]:
        say(f"warning: {w}")
    if len(s.warnings) > 10:
        say(f"warning: {count(len(s.warnings) - 10, 'more warning')}")


def _op_line(o) -> str:
    """One operation of the summary: name, tool, lines, planned or why not, times."""
    tool = f"T{o.tool}" if o.tool >= 0 else "T?"
    head = f"{o.name} ({tool}, lines {o.lines}): "
    if o.planned:
        return (head + f"planned, {o.kind.lower()}, {o.time_before_min:.1f} -> "
                f"{o.time_after_min:.1f} min, S {o.s_min_rpm:.0f}-{o.s_max_rpm:.0f} RPM")
    return head + f"left as programmed ({o.time_before_min:.1f} min): {o.reason}"


@app.command()
def batch(
    inputs: Annotated[str, typer.Argument(help="A folder (searched recursively) or a glob.")],
    output: Annotated[Optional[Path], typer.Option("-o", "--output", help="Output folder; "
                                                   "subfolders are mirrored.")] = None,
    jobs: Annotated[int, typer.Option("--jobs", "-j", min=0, help="Parallel processes (0: "
                                      "one per CPU).")] = 0,
    in_place: Annotated[bool, typer.Option("--in-place", help="Replace the originals, each "
                                           "kept as NAME.bak (NAME.1.bak, ... after it).")] = False,
    report: Annotated[Optional[Path], typer.Option("--report", help="Write a report: JSON "
                      "(.json), or an HTML index (.html) with one page per file beside it.")] = None,
    mesh: Mesh = None, diameter: Diameter = None, corner_radius: CornerRadius = None,
    teeth: Teeth = 2, vc: Vc = None, fz: Fz = None, accel: Accel = None,
    max_rpm: MaxRpm = None, min_rpm: MinRpm = None, max_feed: MaxFeed = None,
    planner: Planner = "lookahead", tool_point: ToolPoint = "tip", min_rpm_step: MinStep = 10.0,
    tool: Tool = None, rapid: Rapid = None, fz_policy: FzPolicy = "centred",
    fz_band: FzBand = 2.0, control: Control = None, decimal_point: DecimalPoint = None,
    min_s_interval_ms: SInterval = None, s_changes: SChanges = None,
    machine: MachineName = None, tools_file: ToolsFile = None, cutter: CutterName = None,
    material: Material = None, method: MethodName = "contact", ap: Ap = "0.2",
    allowance_along: AllowanceAlong = "normal", operations: Operations = None,
    shape: Shape = None, stock: Stock = "0", quiet: Quiet = False,
    kinematics: KinematicsName = None, color: Color = "auto", report_lite: ReportLite = False,
) -> None:
    """Rewrite every program of a folder in parallel; one bad file never stops the others."""
    from ncopt.cli.batch import Task, find_programs, plan_targets, prepare_output_folder, run_batch
    from ncopt.cli.batchview import BatchView
    from ncopt.runtime.fileio import write_output

    job = make_job(**_job_options(locals()))
    _check_report(report, json_ok=True, made_folder=output)
    base, files = find_programs(inputs)
    targets = plan_targets(files, base, output, in_place, folder_given=Path(inputs).is_dir())
    html = report is not None and report.suffix.lower() != ".json"
    if not files:
        say(f"ncopt: no NC programs found in {inputs}")
        raise typer.Exit(int(Exit.NOTHING_DONE))
    if html:
        from ncopt.report.html import page_path
    pages = [page_path(report, base, f) if html else None for f in files]
    guard_batch(files, targets, report, pages, in_place, mesh, tools_file)
    if output is not None:
        prepare_output_folder(output)
    tasks = [Task(str(f), str(t), job, None if mesh is None else str(mesh), in_place,
                  None if page is None else str(page), report_lite)
             for f, t, page in zip(files, targets, pages)]
    view = BatchView(stderr_console(), files, quiet=quiet)
    try:
        with view:
            reports = run_batch(tasks, jobs or os.cpu_count() or 1, view.done)
    except KeyboardInterrupt:
        say("ncopt: interrupted; finished files are complete, no partial file was left")
        raise typer.Exit(int(Exit.INTERRUPTED)) from None
    view.table(reports, base)
    if report is not None and not html:
        import json
        write_output(report, json.dumps([r.to_dict() for r in reports], indent=2).encode())
    elif html:
        from ncopt.report.html import render_index
        write_output(report, render_index(reports, base, report).encode("utf-8"))
        say(f"ncopt: report written to {report}")
    failed = sum(r.status == "failed" for r in reports)
    raise typer.Exit(int(Exit.OK if failed == 0 else
                         Exit.NOTHING_DONE if failed == len(reports) else Exit.SOME_FAILED))


@app.command()
def report(
    program: Annotated[str, typer.Argument(help="NC program to report on (any program, by "
                                           "ncopt or not), or - for stdin.")],
    output: Annotated[Path, typer.Option("-o", "--output", help="The HTML file to write.")],
    against: Annotated[Optional[str], typer.Option(
        "--against", help="The original program, to compare with.")] = None,
    sample: Annotated[float, typer.Option("--sample", help="Sample spacing along the path, mm.")] = 0.1,
    mesh: Mesh = None, diameter: Diameter = None, corner_radius: CornerRadius = None,
    teeth: Teeth = 2, vc: Vc = None, fz: Fz = None, accel: Accel = None,
    max_rpm: MaxRpm = None, min_rpm: MinRpm = None, max_feed: MaxFeed = None,
    tool_point: ToolPoint = "tip", tool: Tool = None, rapid: Rapid = None,
    machine: MachineName = None, tools_file: ToolsFile = None, cutter: CutterName = None,
    material: Material = None, control: Control = None, decimal_point: DecimalPoint = None,
    quiet: Quiet = False, kinematics: KinematicsName = None, color: Color = "auto",
    lite: ReportLite = False,
) -> None:
    """Write one HTML page about a program (and its original): times, curves, 3D toolpath;
    a section per tool ncopt would plan (--tool N: that one), the others listed as left."""
    from ncopt.report.html import from_programs

    job = make_job(**_job_options(locals()))
    _check_report(output)
    guard_outputs(_read_by(("program", program), ("original", against), mesh=mesh,
                           tools_file=tools_file), [("-o", output)])
    names = [program] + ([against] if against else [])
    data = read_programs(names)
    text = data[0].decode("latin-1")
    original = data[1].decode("latin-1") if against else None
    _write_report(output, lambda index: from_programs(text, program, original, against, job,
                                                      index, sample), mesh, quiet, lite)


@app.command()
def simulate(
    program: Annotated[str, typer.Argument(help="NC program to replay (any program), or - "
                                           "for stdin.")],
    against: Annotated[Optional[str], typer.Option(
        "--against", help="Also replay this program (e.g. the original) and compare.")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="One JSON summary on stdout.")] = False,
    csv: Annotated[Optional[Path], typer.Option("--csv", help="Write the per-sample series.")] = None,
    plot: Annotated[Optional[Path], typer.Option(
        "--plot", help="Plot S, F, fz and effective diameter along the cut (PNG or SVG).")] = None,
    plot_path: Annotated[Optional[Path], typer.Option(
        "--plot-toolpath", help="Plot the toolpath coloured by --color-by (PNG or SVG).")] = None,
    color_by: Annotated[str, typer.Option("--color-by", help="s_rpm, f_mm_min, d_eff_mm or "
                                          "vc_m_min.")] = "s_rpm",
    sample: Annotated[float, typer.Option("--sample", help="Sample spacing along the path, mm.")] = 0.1,
    mesh: Mesh = None, diameter: Diameter = None, corner_radius: CornerRadius = None,
    teeth: Teeth = 2, vc: Vc = None, fz: Fz = None, accel: Accel = None,
    max_rpm: MaxRpm = None, min_rpm: MinRpm = None, max_feed: MaxFeed = None,
    tool_point: ToolPoint = "tip", tool: Tool = None, rapid: Rapid = None,
    machine: MachineName = None, tools_file: ToolsFile = None, cutter: CutterName = None,
    material: Material = None, control: Control = None, decimal_point: DecimalPoint = None,
    judged_band: Annotated[Optional[float], typer.Option(
        "--fz-band", help="fz band judged, percent (default: the band an ncopt stamp "
        "records, else 2).")] = None,
    quiet: Quiet = False, kinematics: KinematicsName = None, color: Color = "auto",
) -> None:
    """Replay a program on a spindle that ramps at its real acceleration: time, fz, vc.

    A program that cuts with several tools is replayed once per tool ncopt would plan
    (--tool N: that one only); the others are listed with why they are left."""
    from ncopt.contacts.geometry import MeshIndex, load_stl
    from ncopt.simulate.replay import tools_to_simulate

    _check_outputs(color_by, csv, plot, plot_path)
    if as_json:
        require_stdout("give --csv FILE, or leave out --json for the summary on stderr")
    job = make_job(**_job_options(locals()))
    guard_outputs(_read_by(("program", program), ("program compared", against), mesh=mesh,
                           tools_file=tools_file),
                  [("--csv", csv), ("--plot", plot), ("--plot-toolpath", plot_path)])
    names = ([against] if against else []) + [program]
    programs = read_programs(names)
    with stages(quiet or as_json) as show:
        if mesh:
            show(f"reading the mesh {mesh}")
        index = MeshIndex(load_stl(mesh)) if mesh else None
        show(f"reading {program}")
        chosen = tools_to_simulate(programs[-1].decode("latin-1"), job, program)
        sections = [(tool, _simulate_tool(names, programs, job, tool, index, sample,
                                          judged_band, show, chosen.read))
                    for tool in chosen.tools]
    _simulation_outputs(sections, chosen.left, as_json, csv, plot, plot_path, color_by, quiet)


def _simulate_tool(names, programs, job, tool, index, sample, judged_band, show,
                   read=None) -> list:
    """Every program replayed with one tool (None: the only one): [(name, series, report)];
    one target for all, the first program's.  ``read``: the last program, read already."""
    from dataclasses import replace

    from ncopt.model import CuttingData

    job = replace(job, tool=tool)
    runs = []
    for k, (name, data) in enumerate(zip(names, programs)):
        show(f"simulating {name}" + (f", T{tool}" if tool is not None else ""))
        runs.append(_simulate_one(name, data, job, index, sample, judged_band,
                                  read if k == len(names) - 1 else None))
        if len(runs) == 1 and job.cutting is None:  # one target for all: the first's
            first = runs[0][2]
            job = replace(job, cutting=CuttingData(first.vc_target_m_min, first.fz_target_mm))
    return runs


def _simulate_one(name, data, job, index, sample, judged_band, read=None):
    """One program replayed: (name, series, report)."""
    from ncopt.simulate.replay import simulate_program

    try:
        report, series = simulate_program(
            data.decode("latin-1"), job, index, path=name, sample_mm=sample, read=read,
            band=None if judged_band is None else judged_band / 100.0)
    except ValueRangeError as exc:  # the options were checked: the program gave the value
        raise from_program(exc, name) from None
    return name, series, report


COLOR_BY = ("s_rpm", "f_mm_min", "d_eff_mm", "vc_m_min")
PLOT_SUFFIXES = (".png", ".svg", ".pdf")


def _check_outputs(color_by, csv, plot, plot_path) -> None:
    """Refuse bad output options before the (long) simulation, not after it."""
    if color_by not in COLOR_BY:
        raise UsageError(f"--color-by must be one of {', '.join(COLOR_BY)}, not {color_by!r}")
    for path, option in ((plot, "--plot"), (plot_path, "--plot-toolpath")):
        if path is not None and Path(path).suffix.lower() not in PLOT_SUFFIXES:
            raise UsageError(f"{option} writes PNG, SVG or PDF: name the file .png, .svg or .pdf")
    for path in (csv, plot, plot_path):
        if path is not None and not Path(path).resolve().parent.is_dir():
            raise FileError("the folder to write into does not exist; create it first", str(path))
    if (plot is not None or plot_path is not None) and not _has_matplotlib():
        raise UsageError("plots need matplotlib: python -m pip install matplotlib (or, in "
                         "ncopt's source folder, python -m pip install \".[plot]\")")


def _has_matplotlib() -> bool:
    from importlib.util import find_spec
    return find_spec("matplotlib") is not None


def _simulation_outputs(sections, left, as_json, csv, plot, plot_path, color_by,
                        quiet=False) -> None:
    """Files, then the summary: ``sections`` [(tool, runs)], one per tool simulated (tool
    None: the program's only one), ``left`` (T, why) the tools not simulated.  With several
    tools each file is written once per tool, ``NAME.T3.csv``."""
    several = len(sections) > 1 or sections[0][0] is not None and bool(left)
    try:
        for tool, runs in sections:
            _simulation_files(runs, csv, plot, plot_path, color_by,
                              f".T{tool}" if several else "")
    except OSError as exc:
        raise FileError(f"cannot write the output: {exc.strerror or exc}; check the path",
                        str(exc.filename)) from None
    if as_json:
        import json
        print(json.dumps(_simulation_json(sections, left, several), indent=2))
        return
    if quiet:
        return
    for tool, runs in sections:
        if several:
            rep = runs[-1][2]
            say(f"T{tool}: {rep.cutter} (from {rep.cutter_from})")
        for _, _, rep in runs:
            print_simulation(rep, err)
    for tool, why in left:
        say(f"T{tool}: not simulated, left as programmed: {why}")


def _simulation_files(runs, csv, plot, plot_path, color_by, tag: str) -> None:
    """The series, the curves and the toolpath of one tool (``tag`` goes into the names)."""
    tagged = lambda path: path.with_name(path.stem + tag + path.suffix)  # noqa: E731
    series = runs[-1][1]
    if csv is not None:
        series.write_csv(tagged(csv))
    if plot is not None or plot_path is not None:
        from ncopt.report.plots import plot_along_path, plot_toolpath
        if plot is not None:
            plot_along_path(runs, tagged(plot))
        if plot_path is not None:
            plot_toolpath(series, tagged(plot_path), color_by)


def _simulation_json(sections, left, several: bool) -> dict:
    """One program: its report; with --against, one per program; with several tools,
    ``{"tools": {"T3": that}, "left": {"T1": why}}``."""
    def one(runs):
        return {r[0]: r[2].to_dict() for r in runs} if len(runs) > 1 else runs[-1][2].to_dict()

    if not several:
        return one(sections[0][1])
    return {"tools": {f"T{tool}": one(runs) for tool, runs in sections},
            "left": {f"T{tool}": why for tool, why in left}}


def print_simulation(r, console: "Console") -> None:
    """The simulation summary a technologist reads before sending a program."""
    say = lambda text: console.print(styled(text))  # noqa: E731
    say(f"{r.path}: feed moves {r.feed_moves_time_min:.2f} min ({r.cutting_time_min:.2f} min "
        f"cutting), rapids {r.rapid_time_min:.2f} min, total {r.total_time_min:.2f} min; "
        f"highest S {r.max_rpm:.0f} RPM (line {r.max_rpm_line})")
    say(f"  fz within +-{r.band_pct:g} % of {r.fz_target_mm:.4f} mm on {r.fz_in_band_pct:.2f} % "
        f"of the cut; most above {r.fz_max_over_pct:+.2f} % (line {r.fz_max_over_line}), "
        f"most below {-r.fz_min_under_pct:+.2f} % (line {r.fz_min_under_line})")
    say(f"  vc at most {r.vc_max_over_pct:+.2f} % of its target {r.vc_target_m_min:.1f} m/min "
        f"(line {r.vc_max_over_line}); mean {r.vc_mean_m_min:.1f} m/min; "
        f"{count(r.s_words, 'S word')}")
    if r.lag:
        say(f"  the spindle cannot follow the S words in {count(len(r.lag), 'place')} (first "
            f"at line {r.lag[0].first_line}): fz leaves its band while it catches up")
    for w in r.warnings[:5]:
        say(f"  warning: {w}")


@app.command()
def inspect(
    program: Annotated[str, typer.Argument(help="NC program, or - for stdin.")],
    as_json: Annotated[bool, typer.Option("--json", help="One JSON object on stdout.")] = False,
    diameter: Diameter = None, corner_radius: CornerRadius = None, teeth: Teeth = 2,
    shape: Shape = None, cutter: CutterName = None, vc: Vc = None, fz: Fz = None,
    material: Material = None, tool: Tool = None, operations: Operations = None,
    control: Control = None, decimal_point: DecimalPoint = None,
    machine: MachineName = None, tools_file: ToolsFile = None, max_feed: MaxFeed = None,
    kinematics: KinematicsName = None, color: Color = "auto",
) -> None:
    """Show what ncopt understands of a program before it changes anything, and its
    operations as rewrite would split and judge them (the same cutter, cutting-data and
    machine options; nothing is planned, so no spindle is needed)."""
    from ncopt.planning.inspection import inspect_text, render_inspection
    from ncopt.runtime.stdio import listing, stdout_console

    job = make_job(**_job_options(locals()), spindle_needed=False)
    [data] = read_programs([program])
    try:
        info = inspect_text(data.decode("latin-1"), program, dialect=job.control,
                            decimal_point=job.decimal_point, kinematics=job.kinematics,
                            max_feed_mm_min=job.machine.max_feed_mm_min, job=job)
    except ValueRangeError as exc:  # the options were checked: the program gave the value
        raise from_program(exc, program) from None
    with listing():  # `| head` ends it quietly
        if as_json:
            import json
            print(json.dumps(info.to_dict(), indent=2))
        else:
            render_inspection(info, stdout_console(highlight=False, soft_wrap=True))


@app.command()
def diff(
    original: Annotated[str, typer.Argument(help="The original program, or - for stdin.")],
    rewritten: Annotated[str, typer.Argument(help="The rewritten program, or - for stdin.")],
    plain: Annotated[bool, typer.Option("--plain", help="Unified diff even on a terminal.")] = False,
    no_pager: Annotated[bool, typer.Option("--no-pager", help="Print on the terminal, not "
                                           "through $PAGER (less -R).")] = False,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="Print nothing; the exit code "
                                        "says whether the files differ.")] = False,
    color: Color = "auto",
) -> None:
    """Show which blocks changed: side by side on a terminal (paged), a unified diff otherwise.

    Exit code 0 when the files are the same, 1 when they differ (as diff does).
    """
    from ncopt.report.diffview import show_diff

    a, b = read_programs([original, rewritten])
    if a == b:
        return
    if not quiet:
        require_stdout("use -q to learn from the exit code alone whether they differ")
        show_diff(original, rewritten, a.decode("latin-1").splitlines(),
                  b.decode("latin-1").splitlines(), plain=plain, pager=not no_pager)
    raise typer.Exit(DIFFERENT)


profiles_app = _App(no_args_is_help=False, rich_markup_mode=None,
                    context_settings={"help_option_names": ["-h", "--help"]})
app.add_typer(profiles_app, name="profiles")


@profiles_app.callback(invoke_without_command=True)
@_guarded
def profiles(ctx: typer.Context, tools_file: ToolsFile = None, color: Color = "auto") -> None:
    """List the machine, tool and cutting-data profiles found, and where from
    (profiles init: write a commented profile for a machine)."""
    if ctx.invoked_subcommand is not None:
        return
    from ncopt.planning.profiles import load, render_profiles
    from ncopt.runtime.stdio import listing, stdout_console

    found = load(tools_file=tools_file)
    with listing():  # `| head` ends it quietly
        render_profiles(found, stdout_console(highlight=False))


@profiles_app.command("init")
def profiles_init(
    name: Annotated[str, typer.Argument(help="The machine's name; a profile of that name "
                                        "(ncopt profiles) gives its values.")] = "my-machine",
    output: Annotated[Optional[str], typer.Option(
        "-o", "--output", help="The file to write (never one that exists, e.g. ncopt.toml "
        "in the project's folder); - or omitted: stdout.")] = None,
    tools_file: ToolsFile = None,
) -> None:
    """Write a commented TOML profile for a machine: every key, what it means, its unit."""
    from ncopt.planning.profiles import load, machine_template

    if not name.strip() or any(ord(c) < 32 for c in name):
        raise UsageError(f"a machine's name is a word such as my-mill, not {name!r}")
    base = load(tools_file=tools_file).machines.get(name)
    text = machine_template(name, base).encode("utf-8")
    if output in (None, "-"):
        write_stdout(text)
        return
    try:
        with open(output, "xb") as handle:
            handle.write(text)
    except FileExistsError:
        raise FileError("exists; profiles init never replaces a file: name another, or add "
                        "the machine to it by hand", output) from None
    except OSError as exc:
        raise FileError(f"cannot write the profile: {exc.strerror}; check the path",
                        output) from None
    todo = "" if base is not None else "; give accel_rad_s2 and max_rpm in it"
    say(f"ncopt: machine profile {name} written to {output}{todo}")


@app.command()
def version() -> None:
    """Print the ncopt version."""
    print(__version__)


def main() -> None:
    """Console entry point: ncopt errors become one located line and an exit code."""
    signal.signal(signal.SIGTERM, interrupt)  # from the start: SIGTERM is an interrupt
    if sys.argv[1:] in (["version"], ["--version"]):  # before typer builds its commands
        sys.exit(_say_version())
    try:
        app()
    except NcoptError as exc:  # raised outside a command body
        say(str(exc), error=True)
        sys.exit(int(_exit_code(exc)))
    except KeyboardInterrupt:  # before a command started
        say("ncopt: interrupted")
        sys.exit(int(Exit.INTERRUPTED))
