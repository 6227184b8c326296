"""``ncopt`` command line: a thin typer layer over :mod:`ncopt.api`."""

from __future__ import annotations

import json
import os
import sys
import tempfile
from enum import IntEnum
from pathlib import Path
from typing import Optional

import typer
from rich.console import Console

from . import __version__
from .api import Job, Summary, rewrite_file
from .errors import MeshError, NcoptError, NcParseError, PlanningError, UsageError, VerificationError
from .model import Cutter, CuttingData, Machine, PlanOptions


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


app = typer.Typer(add_completion=False, pretty_exceptions_show_locals=False,
                  help="Rewrite S and F words of finishing programs for constant vc and fz.")
err = Console(stderr=True, highlight=False, soft_wrap=True)


def _exit_code(exc: NcoptError) -> Exit:
    for kind, code in ((UsageError, Exit.USAGE), (MeshError, Exit.MESH),
                       (PlanningError, Exit.PLANNING), (VerificationError, Exit.VERIFICATION),
                       (NcParseError, Exit.PROGRAM)):
        if isinstance(exc, kind):
            return code
    return Exit.PROGRAM


def _fail(exc: NcoptError) -> None:
    err.print(str(exc), markup=False)
    raise typer.Exit(int(_exit_code(exc)))


@app.command()
def rewrite(
    input: str = typer.Argument(..., help="NC program to rewrite, or - for stdin."),
    output: Optional[str] = typer.Option(None, "-o", "--output",
                                         help="Where to write; - or omitted: stdout."),
    mesh: Optional[Path] = typer.Option(None, "--mesh", help="Part mesh (STL, binary or "
                                        "ASCII), mm. Without it, normals come from the toolpath."),
    diameter: Optional[float] = typer.Option(None, "--diameter", help="Cutter diameter D, mm "
                                             "(default: from the program's tool comments)."),
    corner_radius: Optional[float] = typer.Option(None, "--corner-radius",
                                                  help="Bull-nose corner radius r, mm (default: ball)."),
    teeth: int = typer.Option(2, "--teeth", help="Number of teeth z (matters only with --fz)."),
    vc: Optional[float] = typer.Option(None, "--vc", help="Cutting speed target, m/min "
                                       "(default: the program's S at the nominal diameter)."),
    fz: Optional[float] = typer.Option(None, "--fz", help="Feed per tooth target, mm "
                                       "(default: the program's F / (z S))."),
    accel: float = typer.Option(..., "--accel", help="Spindle acceleration, rad/s^2."),
    max_rpm: float = typer.Option(..., "--max-rpm", help="Highest spindle speed, RPM."),
    min_rpm: float = typer.Option(0.0, "--min-rpm", help="Lowest spindle speed, RPM."),
    max_feed: float = typer.Option(float("inf"), "--max-feed", help="Highest feed, mm/min."),
    planner: str = typer.Option("lookahead", "--planner", help="lookahead or forward."),
    tool_point: str = typer.Option("tip", "--tool-point", help="Programmed point: tip or center."),
    min_rpm_step: float = typer.Option(10.0, "--min-rpm-step", help="Emit S only when it "
                                       "changes by at least this, RPM."),
    tool: Optional[int] = typer.Option(None, "--tool", help="Plan only this T number."),
    rapid: float = typer.Option(10000.0, "--rapid", help="Rapid traverse rate, mm/min."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No summary on stderr."),
) -> None:
    """Rewrite a program's S and F words; every other byte stays as it is."""
    try:
        job = _job(diameter, corner_radius, teeth, vc, fz, accel, max_rpm, min_rpm, max_feed,
                   planner, tool_point, min_rpm_step, tool, rapid)
        data = sys.stdin.buffer.read() if input == "-" else _read(input)
        result = rewrite_file("-" if input == "-" else input, job, mesh_path=mesh, data=data)
        _write(output, result.text.encode("latin-1"), input)
    except NcoptError as exc:
        _fail(exc)
    if not quiet:
        _print_summary(result.summary)


def _job(diameter, corner_radius, teeth, vc, fz, accel, max_rpm, min_rpm, max_feed, planner,
         tool_point, min_rpm_step, tool, rapid) -> Job:
    if planner not in ("lookahead", "forward"):
        raise UsageError(f"--planner must be lookahead or forward, not {planner!r}")
    if tool_point not in ("tip", "center"):
        raise UsageError(f"--tool-point must be tip or center, not {tool_point!r}")
    if (diameter is not None and diameter <= 0) or teeth <= 0 or accel <= 0 or max_rpm <= 0:
        raise UsageError("--diameter, --teeth, --accel and --max-rpm must be positive")
    if corner_radius is not None and (diameter is None or not 0 < corner_radius <= diameter / 2):
        raise UsageError("--corner-radius needs --diameter and must be above 0 and at most "
                         "half the diameter")
    if (vc is None) != (fz is None):
        raise UsageError("give both --vc and --fz, or neither (then the program's S and F set them)")
    if min_rpm > max_rpm:
        raise UsageError("--min-rpm is above --max-rpm")
    cutting = CuttingData(vc, fz) if vc is not None else None
    if cutting is not None and (vc <= 0 or fz <= 0):
        raise UsageError("--vc and --fz must be positive")
    cutter = Cutter(diameter, teeth, corner_radius, tool_point) if diameter is not None else None
    return Job(cutter=cutter, machine=Machine(accel, max_rpm, min_rpm, max_feed, rapid),
               cutting=cutting, options=PlanOptions(planner=planner, min_rpm_step=min_rpm_step),
               tool=tool, teeth=teeth)


def _read(path: str) -> bytes:
    try:
        return Path(path).read_bytes()
    except OSError as exc:
        raise _IoError(f"cannot read the program: {exc.strerror}; check the path", path) from None


class _IoError(UsageError):
    pass


def _write(output: Optional[str], data: bytes, input: str) -> None:
    """stdout, or a new file written atomically (temporary file + rename)."""
    if output is None or output == "-":
        sys.stdout.buffer.write(data)
        sys.stdout.buffer.flush()
        return
    target = Path(output)
    if input != "-" and target.exists() and target.resolve() == Path(input).resolve():
        raise UsageError("the output would overwrite the input; write to another file", output)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp",
                                   dir=target.parent if str(target.parent) else ".")
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
        os.replace(tmp, target)
    except OSError as exc:
        raise UsageError(f"cannot write the output: {exc.strerror}", output) from None


def _print_summary(s: Summary) -> None:
    err.print(f"ncopt: {s.blocks} blocks, {s.cutting_blocks} cutting blocks planned, "
              f"{s.s_words} S and {s.f_words} F words written")
    for tool, what, source in s.tools:
        err.print(f"ncopt: T{tool}: {what} ({'from ' + source if source != 'options' else 'from the options'})",
                  markup=False)
    for tool, why in s.skipped_tools:
        err.print(f"ncopt: T{tool} left untouched: {why}", markup=False)
    err.print(f"ncopt: vc {s.vc_m_min:.1f} m/min, fz {s.fz_mm:.4f} mm, highest S {s.max_s_rpm:.0f} RPM")
    err.print(f"ncopt: estimated cutting time {s.cut_time_before_min:.1f} -> "
              f"{s.cut_time_after_min:.1f} min ({s.time_change_pct:+.1f} %)")
    if s.mesh_edge_mm is not None:
        err.print(f"ncopt: mesh median edge {s.mesh_edge_mm:.2f} mm")
    if s.normals_from == "toolpath":
        err.print(f"ncopt: no mesh: normals from the toolpath (stepover {s.stepover_mm:.2f} mm); "
                  f"{s.one_sided_points} points at the edge of the machined area planned "
                  "conservatively")
        if s.no_cross_points:
            err.print(f"ncopt: {s.no_cross_points} cutting points have no neighbouring pass: "
                      "their cross-slope is unknown and taken as zero")
    for w in s.warnings[:10]:
        err.print(f"warning: {w}", markup=False)
    if len(s.warnings) > 10:
        err.print(f"warning: {len(s.warnings) - 10} more warnings")


@app.command()
def inspect(
    program: str = typer.Argument(..., help="NC program, or - for stdin."),
    as_json: bool = typer.Option(False, "--json", help="One JSON object on stdout."),
) -> None:
    """Show what ncopt understands of a program before it changes anything."""
    from .inspect import inspect_text

    try:
        data = sys.stdin.buffer.read() if program == "-" else _read(program)
        info = inspect_text(data.decode("latin-1"), program)
    except NcoptError as exc:
        _fail(exc)
    if as_json:
        print(json.dumps(info.to_dict(), indent=2))
        return
    out = Console(highlight=False, soft_wrap=True)
    out.print(f"{info.path}: {info.dialect} dialect, {info.units}, {info.lines} lines", markup=False)
    out.print(f"  blocks {info.blocks}, moves {info.moves} (feed {info.feed_moves}, rapid "
              f"{info.rapids}, arcs {info.arcs}), not plannable {info.unknown_moves}")
    for t in info.tools:
        out.print(f"  tool T{t[0]}: {t[1]} D{t[2]:g} r{t[3]:g} (line {t[4]})", markup=False)
    out.print(f"  tools cutting: {', '.join(f'T{t}' for t in info.tools_used) or 'none'}")
    out.print(f"  S {info.s_range_rpm[0]:g}..{info.s_range_rpm[1]:g} RPM, "
              f"F {info.f_range_mm_min[0]:g}..{info.f_range_mm_min[1]:g} mm/min")
    out.print(f"  cutting {info.cut_length_mm:.0f} mm in {info.cut_time_min:.1f} min at the "
              "programmed feed")
    for line, why in info.opaque[:20]:
        out.print(f"  line {line}: '{why}' left alone", markup=False)
    if len(info.opaque) > 20:
        out.print(f"  ... {len(info.opaque) - 20} more lines left alone")
    for w in info.warnings[:20]:
        out.print(f"  warning: {w}", markup=False)


@app.command()
def diff(
    original: str = typer.Argument(..., help="The original program."),
    rewritten: str = typer.Argument(..., help="The rewritten program."),
    plain: bool = typer.Option(False, "--plain", help="Unified diff even on a terminal."),
) -> None:
    """Show which blocks changed: side by side on a terminal, a unified diff otherwise."""
    from .diffview import render_side_by_side, write_unified

    try:
        a = _read(original).decode("latin-1").splitlines()
        b = _read(rewritten).decode("latin-1").splitlines()
    except NcoptError as exc:
        _fail(exc)
    out = Console(highlight=False)
    if plain or not out.is_terminal:
        write_unified(original, rewritten, a, b, sys.stdout)
    else:
        render_side_by_side(original, rewritten, a, b, out)


@app.command()
def version() -> None:
    """Print the ncopt version."""
    print(__version__)


def main() -> None:
    """Console entry point: ncopt errors become one located line and an exit code."""
    try:
        app()
    except NcoptError as exc:  # raised outside a command body
        err.print(str(exc), markup=False)
        sys.exit(int(_exit_code(exc)))
