"""``ncopt rewrite`` and ``ncopt batch``: a program's S and F words rewritten (one, or
every program of a folder in parallel), and the summary a machinist reads after it."""

# No `from __future__ import annotations`: typer reads these annotations as objects.
import os
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Optional

import typer

from ncopt.cli.core import WOULD_CHANGE, Exit
from ncopt.cli.files import check_report, guard_batch, guard_outputs, read_by, write_report
from ncopt.cli.options import COLOR, FOR_PLANNING, OUTPUT, QUIET, REPORT_LITE, Given, takes
from ncopt.runtime.errors import NothingToPlan, UsageError, ValueRangeError, from_program
from ncopt.runtime.stdio import (count, err, read_programs, say, stages, stderr_console,
                                 styled, write_stdout)

if TYPE_CHECKING:
    from rich.console import Console

    from ncopt.api import Summary


@takes(*FOR_PLANNING, REPORT_LITE, QUIET, COLOR)
def rewrite(
    input: Annotated[str, typer.Argument(help="NC program to rewrite, or - for stdin.")],
    output: Annotated[Optional[str], typer.Option(
        "-o", "--output", rich_help_panel=OUTPUT, help="Where to write: a file, a folder "
        "(ending in /: the input's name inside it); - or omitted: stdout.")] = None,
    report: Annotated[Optional[Path], typer.Option(
        "--report", rich_help_panel=OUTPUT, help="Also write an HTML report: times, "
        "S/F/fz/D_eff curves, a 3D toolpath and the changed blocks, in one file that opens "
        "offline.")] = None,
    as_json: Annotated[bool, typer.Option(
        "--json", rich_help_panel=OUTPUT, help="The summary as one JSON object on stderr "
        "instead of text (stdout stays the program).")] = False,
    check: Annotated[bool, typer.Option(
        "--check", rich_help_panel=OUTPUT, help="Write nothing: exit 0 when the rewrite "
        "would change nothing, 1 when it would, and say what would change (unless -q).")] = False,
    given: Given = None,
) -> None:
    """Rewrite a program's S and F words; every other byte stays as it is."""
    from ncopt.api import rewrite_file
    from ncopt.runtime.fileio import output_file, write_output

    job, mesh, quiet = given.job(), given.mesh, given.quiet
    if check and (output is not None or report is not None):
        raise UsageError("--check writes nothing: leave out -o and --report")
    check_report(report)
    target = None if check else output_file(output, input)
    guard_outputs(read_by(("program", input), mesh=mesh, tools_file=given.tools_file),
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
        write_report(report, lambda index: from_rewrite(
            result, data.decode("latin-1"), input, output or "-", job, index), mesh, quiet,
            given.report_lite)
    _say_summary(result.summary, quiet, as_json)


def _say_summary(summary: "Summary", quiet: bool, as_json: bool) -> None:
    """The summary on stderr: JSON, text, or (quiet) nothing."""
    if as_json:
        import json
        say(json.dumps(summary.to_dict(), indent=2))
    elif not quiet:
        print_summary(summary, err)


def _check_verdict(name: str, data: bytes, text: bytes, summary: "Summary", quiet: bool,
                   as_json: bool) -> None:
    """rewrite --check: what the rewrite would change; exit 1 when it would change
    anything (black's convention), else return (exit 0)."""
    _say_summary(summary, quiet, as_json)
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


@takes(*FOR_PLANNING, REPORT_LITE, QUIET, COLOR)
def batch(
    inputs: Annotated[str, typer.Argument(help="A folder (searched recursively) or a glob.")],
    output: Annotated[Optional[Path], typer.Option(
        "-o", "--output", rich_help_panel=OUTPUT,
        help="Output folder; subfolders are mirrored.")] = None,
    jobs: Annotated[int, typer.Option("--jobs", "-j", min=0, help="Parallel processes (0: "
                                      "one per CPU).")] = 0,
    in_place: Annotated[bool, typer.Option(
        "--in-place", rich_help_panel=OUTPUT, help="Replace the originals, each kept as "
        "NAME.bak (NAME.1.bak, ... after it).")] = False,
    report: Annotated[Optional[Path], typer.Option(
        "--report", rich_help_panel=OUTPUT, help="Write a report: JSON (.json), or an HTML "
        "index (.html) with one page per file beside it.")] = None,
    given: Given = None,
) -> None:
    """Rewrite every program of a folder in parallel; one bad file never stops the others."""
    from ncopt.cli.batch import Task, find_programs, plan_targets, prepare_output_folder

    job = given.job()
    check_report(report, json_ok=True, made_folder=output)
    base, files = find_programs(inputs)
    targets = plan_targets(files, base, output, in_place, folder_given=Path(inputs).is_dir())
    html = report is not None and report.suffix.lower() != ".json"
    if not files:
        say(f"ncopt: no NC programs found in {inputs}")
        raise typer.Exit(int(Exit.NOTHING_DONE))
    if html:
        from ncopt.report.html import page_path
    pages = [page_path(report, base, f) if html else None for f in files]
    guard_batch(files, targets, report, pages, in_place, given.mesh, given.tools_file)
    if output is not None:
        prepare_output_folder(output)
    mesh = None if given.mesh is None else str(given.mesh)
    tasks = [Task(str(f), str(t), job, mesh, in_place, None if page is None else str(page),
                  given.report_lite)
             for f, t, page in zip(files, targets, pages)]
    reports = _run_batch(tasks, files, jobs, given.quiet, base)
    _batch_report(report, html, reports, base)
    failed = sum(r.status == "failed" for r in reports)
    raise typer.Exit(int(Exit.OK if failed == 0 else
                         Exit.NOTHING_DONE if failed == len(reports) else Exit.SOME_FAILED))


def _run_batch(tasks, files, jobs: int, quiet: bool, base) -> list:
    """The tasks run on ``jobs`` processes (0: one per CPU), shown as they finish; their
    reports."""
    from ncopt.cli.batch import run_batch
    from ncopt.cli.batchview import BatchView

    view = BatchView(stderr_console(), files, quiet=quiet)
    try:
        with view:
            reports = run_batch(tasks, jobs or os.cpu_count() or 1, view.done)
    except KeyboardInterrupt:
        say("ncopt: interrupted; finished files are complete, no partial file was left")
        raise typer.Exit(int(Exit.INTERRUPTED)) from None
    view.table(reports, base)
    return reports


def _batch_report(report: Optional[Path], html: bool, reports: list, base) -> None:
    """The batch's report: JSON, or the HTML index (its pages are written by the tasks)."""
    from ncopt.runtime.fileio import write_output

    if report is not None and not html:
        import json
        write_output(report, json.dumps([r.to_dict() for r in reports], indent=2).encode())
    elif html:
        from ncopt.report.html import render_index
        write_output(report, render_index(reports, base, report).encode("utf-8"))
        say(f"ncopt: report written to {report}")


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
    _print_contacts(s, say)
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


def _print_contacts(s: "Summary", say) -> None:
    """The summary's lines on where the contacts came from: the mesh, or the toolpath."""
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


def _op_line(o) -> str:
    """One operation of the summary: name, tool, lines, planned or why not, times."""
    tool = f"T{o.tool}" if o.tool >= 0 else "T?"
    head = f"{o.name} ({tool}, lines {o.lines}): "
    if o.planned:
        return (head + f"planned, {o.kind.lower()}, {o.time_before_min:.1f} -> "
                f"{o.time_after_min:.1f} min, S {o.s_min_rpm:.0f}-{o.s_max_rpm:.0f} RPM")
    return head + f"left as programmed ({o.time_before_min:.1f} min): {o.reason}"
