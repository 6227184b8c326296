"""``ncopt simulate`` and ``ncopt report``: a program (any program, by ncopt or not)
replayed on a spindle that ramps at its real acceleration; the figures on stderr, a JSON
summary, series and plots, or one HTML page."""

# No `from __future__ import annotations`: typer reads these annotations as objects.
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Literal, Optional

import typer

from ncopt.cli.files import check_report, guard_outputs, read_by, write_report
from ncopt.cli.options import (COLOR, FOR_REPLAY, OUTPUT, QUIET, REPORT_LITE, TARGETS, Given,
                               choice, option, takes)
from ncopt.planning.job import check_choice
from ncopt.runtime.errors import FileError, UsageError, ValueRangeError, from_program
from ncopt.runtime.stdio import count, err, read_programs, require_stdout, say, stages, styled

if TYPE_CHECKING:
    from rich.console import Console

REPLAY = "Replay"
PLOT_SUFFIXES = (".png", ".svg", ".pdf")
# The keys of ncopt.report.plots.COLOR_BY, for -h and the shell's completion (plots loads
# numpy, which -h must not; tests/test_cli_conventions.py holds the two equal).  The value
# given is checked against plots.COLOR_BY itself.
ColorBy = Literal["s_rpm", "f_mm_min", "d_eff_mm", "vc_m_min"]

# the plots of simulate
PLOTS = (
    option("plot", Optional[Path], None, "--plot", panel=OUTPUT, help=(
        "Plot S, F, fz and effective diameter along the cut (PNG or SVG).")),
    option("plot_path", Optional[Path], None, "--plot-toolpath", panel=OUTPUT,
           help="Plot the toolpath coloured by --color-by (PNG or SVG)."),
    choice("color_by", ColorBy, "s_rpm", "--color-by", panel=OUTPUT,
           help="What colours the toolpath plot."),
)
Sample = Annotated[float, typer.Option("--sample", rich_help_panel=REPLAY,
                                       help="Sample spacing along the path, mm.")]


@takes(*FOR_REPLAY, *PLOTS, QUIET, COLOR)
def simulate(
    program: Annotated[str, typer.Argument(help="NC program to replay (any program), or - "
                                           "for stdin.")],
    against: Annotated[Optional[str], typer.Option(
        "--against", rich_help_panel=REPLAY,
        help="Also replay this program (e.g. the original) and compare.")] = None,
    sample: Sample = 0.1,
    judged_band: Annotated[Optional[float], typer.Option(
        "--fz-band", rich_help_panel=TARGETS, help="fz band judged, percent (default: the "
        "band an ncopt stamp records, else 2).")] = None,
    as_json: Annotated[bool, typer.Option("--json", rich_help_panel=OUTPUT,
                                          help="One JSON summary on stdout.")] = False,
    csv: Annotated[Optional[Path], typer.Option("--csv", rich_help_panel=OUTPUT,
                                                help="Write the per-sample series.")] = None,
    given: Given = None,
) -> None:
    """Replay a program on a spindle that ramps at its real acceleration: time, fz, vc.

    A program that cuts with several tools is replayed once per tool ncopt would plan
    (--tool N: that one only); the others are listed with why they are left."""
    from ncopt.contacts.geometry import MeshIndex, load_stl
    from ncopt.simulate.replay import tools_to_simulate

    plots = (given.plot, given.plot_path)
    _check_outputs(given.color_by, csv, *plots)
    if as_json:
        require_stdout("give --csv FILE, or leave out --json for the summary on stderr")
    job, mesh = given.job(), given.mesh
    guard_outputs(read_by(("program", program), ("program compared", against), mesh=mesh,
                          tools_file=given.tools_file),
                  [("--csv", csv), ("--plot", plots[0]), ("--plot-toolpath", plots[1])])
    names = ([against] if against else []) + [program]
    programs = read_programs(names)
    with stages(given.quiet or as_json) as show:
        if mesh:
            show(f"reading the mesh {mesh}")
        index = MeshIndex(load_stl(mesh)) if mesh else None
        show(f"reading {program}")
        chosen = tools_to_simulate(programs[-1].decode("latin-1"), job, program)
        sections = [(tool, _simulate_tool(names, programs, job, tool, index, sample,
                                          judged_band, show, chosen.read))
                    for tool in chosen.tools]
    _simulation_outputs(sections, chosen.left, as_json, csv, *plots, given.color_by,
                        given.quiet)


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


def _check_outputs(color_by, csv, plot, plot_path) -> None:
    """Refuse bad output options before the (long) simulation, not after it."""
    from ncopt.report.plots import COLOR_BY  # loads what the simulation loads anyway

    check_choice(color_by, tuple(key for key, _ in COLOR_BY), "--color-by")
    for path, option_name in ((plot, "--plot"), (plot_path, "--plot-toolpath")):
        if path is not None and Path(path).suffix.lower() not in PLOT_SUFFIXES:
            raise UsageError(f"{option_name} writes PNG, SVG or PDF: name the file .png, .svg "
                             "or .pdf")
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


@takes(*FOR_REPLAY, REPORT_LITE, QUIET, COLOR)
def report(
    program: Annotated[str, typer.Argument(help="NC program to report on (any program, by "
                                           "ncopt or not), or - for stdin.")],
    output: Annotated[Path, typer.Option("-o", "--output", rich_help_panel=OUTPUT,
                                         help="The HTML file to write.")],
    against: Annotated[Optional[str], typer.Option(
        "--against", rich_help_panel=REPLAY, help="The original program, to compare with.")] = None,
    sample: Sample = 0.1,
    given: Given = None,
) -> None:
    """Write one HTML page about a program (and its original): times, curves, 3D toolpath;
    a section per tool ncopt would plan (--tool N: that one), the others listed as left."""
    from ncopt.report.gather import from_programs

    job, mesh = given.job(), given.mesh
    check_report(output)
    guard_outputs(read_by(("program", program), ("original", against), mesh=mesh,
                          tools_file=given.tools_file), [("-o", output)])
    names = [program] + ([against] if against else [])
    data = read_programs(names)
    text = data[0].decode("latin-1")
    original = data[1].decode("latin-1") if against else None
    write_report(output, lambda index: from_programs(text, program, original, against, job,
                                                     index, sample), mesh, given.quiet,
                 given.report_lite)
