"""What a report page shows (:class:`ReportData`), gathered from the simulator.

:func:`from_rewrite` (an ``ncopt.api.Result``: original and rewrite) and
:func:`from_programs` (given programs, as ``ncopt simulate`` sees them) are the only
functions of the report that know ``ncopt.api`` and ``ncopt.simulate``; everything
else renders a :class:`ReportData`.
"""

from __future__ import annotations

import datetime
from dataclasses import dataclass, replace
from pathlib import Path

from ncopt.model import CuttingData
from ncopt.reading.dialect import detect
from ncopt.simulate.replay import simulate_program, tools_to_simulate
from ncopt.simulate.results import SimReport, SimSeries
from ncopt.simulate.toolchoice import describe_cutter

__all__ = ["CONTROL_NAMES", "ReportData", "Run", "ToolSection", "from_programs",
           "from_rewrite", "now_text"]

CONTROL_NAMES = {"sinumerik": "Siemens Sinumerik", "fanuc": "Fanuc", "linuxcnc": "LinuxCNC",
                 "grbl": "grbl", "heidenhain-iso": "Heidenhain (ISO programs)",
                 "generic": "generic G-code"}


@dataclass(frozen=True)
class Run:
    """One program replayed by the simulator."""

    label: str
    series: SimSeries
    report: SimReport


@dataclass(frozen=True)
class ToolSection:
    """The runs of one tool: the original first (when there is one).

    tool : T number (-1: the program names none);  cutter : ``D16 ball, 2 teeth``;
    cutter_from : where the cutter came from
    """

    tool: int
    cutter: str
    runs: tuple[Run, ...]
    cutter_from: str = ""


@dataclass(frozen=True)
class ReportData:
    """Everything the page shows; built by :func:`from_rewrite` or :func:`from_programs`.

    settings : (name, value) rows;  summary : the rewrite's summary (any frozen
    dataclass), None for a report of given programs;  lines : (original, program)
    text lines for the side-by-side blocks, None without an original;
    operations : (operation, tool, lines, planned, what or why, time) text rows;
    left : (T, why) the tools that cut but are not planned;  notes : what the
    control does with the program
    """

    program: str
    against: str | None
    settings: tuple[tuple[str, str], ...]
    sections: tuple[ToolSection, ...]
    summary: object | None = None
    warnings: tuple[str, ...] = ()
    lines: tuple[list[str], list[str]] | None = None
    created: str = ""
    operations: tuple[tuple[str, str, str, str, str, str], ...] = ()
    left: tuple[tuple[int, str], ...] = ()
    notes: tuple[str, ...] = ()


# ------------------------------------------------------------ gathering (the coupling)


def from_rewrite(result, original_text: str, original_path: str, output_path: str, job,
                 mesh_index=None, sample_mm: float = 0.1) -> ReportData:
    """The report of an ``ncopt.api.Result``: original and rewrite simulated per planned tool."""
    s = result.summary
    sources = {t: src for t, _, src in s.tools}
    sections, done = [], set()
    for plan in result.plans:
        if plan.tool in done:  # one section per tool, however many operations it planned
            continue
        done.add(plan.tool)
        tool_job = replace(job, cutter=plan.cutter, cutting=plan.cutting, tool=plan.tool)
        runs = []
        for path, text, role in ((original_path, original_text, "original"),
                                 (output_path, result.text, "rewrite")):
            rep, series = simulate_program(text, tool_job, mesh_index, path=path,
                                           sample_mm=sample_mm)
            runs.append(Run(f"{Path(path).name} ({role})", series, rep))
        source = sources.get(plan.tool, "")
        sections.append(ToolSection(plan.tool, describe_cutter(plan.cutter), tuple(runs),
                                    "the options" if source == "options" else source))
    operations = tuple(_op_row(o.name, o.tool, o.lines, o.planned, o.kind, o.reason,
                               f"{o.time_before_min:.1f} → {o.time_after_min:.1f} min",
                               f"S {o.s_min_rpm:.0f}-{o.s_max_rpm:.0f} RPM")
                       for o in s.operations)
    control = _control(s.control, s.control_source)
    rows = _settings(job, control, s.s_changes, True) + _mesh_rows(s)
    return ReportData(output_path, original_path, rows, tuple(sections), s, tuple(s.warnings),
                      (original_text.splitlines(), result.text.splitlines()), now_text(),
                      operations, tuple(s.skipped_tools), tuple(s.control_notes))


def from_programs(program_text: str, program_path: str, against_text: str | None,
                  against_path: str | None, job, mesh_index=None,
                  sample_mm: float = 0.1) -> ReportData:
    """The report of given programs (any, by ncopt or not), as ``ncopt simulate`` sees them:
    a section per tool ncopt would plan (or ``job.tool``), the others listed as left.

    The original's targets (its own S and F at the nominal diameter) judge both.
    """
    chosen = tools_to_simulate(program_text, job, program_path, judge=True)
    sections = []
    for tool in chosen.tools:
        tool_job, runs = replace(job, tool=tool), []
        for path, text, role in ((against_path, against_text, " (original)"),
                                 (program_path, program_text, "")):
            if text is None:
                continue
            rep, series = simulate_program(text, tool_job, mesh_index, path=path,
                                           sample_mm=sample_mm,
                                           read=chosen.read if text is program_text else None)
            if tool_job.cutting is None:  # one target for all: the first program's
                tool_job = replace(tool_job, cutting=CuttingData(rep.vc_target_m_min,
                                                                 rep.fz_target_mm))
            runs.append(Run(Path(path).name + role, series, rep))
        last = runs[-1].report
        sections.append(ToolSection(last.tool, last.cutter, tuple(runs), last.cutter_from))
    operations = tuple(_op_row(o.name, o.tool, o.lines, o.planned, o.kind, o.reason,
                               f"{o.time_min:.1f} min at the programmed feed", "")
                       for o in chosen.operations)
    found = detect(program_text)
    control = _control(job.control or found.name, job.control_from if job.control else (
        f"detected from {len(found.marks)} mark{'s' if len(found.marks) > 1 else ''}"
        if found.marks else "no marks: generic"))
    warnings = tuple(dict.fromkeys(w for s in sections for r in s.runs
                                   for w in r.report.warnings))
    lines = (against_text.splitlines(), program_text.splitlines()) if against_text else None
    rows = _settings(job, control, None, False) + (
        ("mesh", "given" if mesh_index is not None else
         "none: contacts from the toolpath's own shape"),)
    return ReportData(program_path, against_path, rows, tuple(sections), None, warnings, lines,
                      now_text(), operations, chosen.left)


def _op_row(name: str, tool: int, lines: str, planned: bool, kind: str, reason: str, time: str,
            extra: str) -> tuple[str, str, str, str, str, str]:
    """An operation as the page shows it."""
    what = (kind.lower() + (f", {extra}" if extra else "")) if planned else reason
    return (name, f"T{tool}" if tool >= 0 else "-", lines,
            "planned" if planned else "left as programmed", what, time)


def _control(name: str, source: str) -> str:
    """``Siemens Sinumerik (sinumerik): detected from 1 mark``."""
    if not name:
        return "not known"
    if name == "generic" and source.startswith("no marks"):
        return "generic G-code: the program has no mark of a particular control"
    return f"{CONTROL_NAMES.get(name, name)} ({name})" + (f": {source}" if source else "")


def _mesh_rows(s) -> tuple[tuple[str, str], ...]:
    """How the contacts were found: the mesh and how well it fits, or the toolpath."""
    if s.normals_from == "toolpath":
        return (("mesh", f"none: normals from the toolpath (stepover {s.stepover_mm:.2f} mm); "
                         f"{s.unknown_contact_pct:.1f} % of the planned cut with no contact "
                         "the toolpath can show, planned at the full diameter"),)
    fits = "; ".join(f"T{t} fits {f.touching_pct:.1f} % of the planned cut ({f.air_pct:.1f} "
                     f"% in the air, {f.gouge_pct:.1f} % inside the part, deepest "
                     f"{f.deepest_gouge_mm:.3f} mm)" for t, f in s.mesh_fit)
    edge = f"median edge {s.mesh_edge_mm:.2f} mm" if s.mesh_edge_mm is not None else "given"
    return (("mesh", edge + (f"; {fits}" if fits else "")),)


def _settings(job, control: str, s_changes, planned: bool) -> tuple[tuple[str, str], ...]:
    """Machine, control, cutter and targets; with ``planned``, how ncopt planned too."""
    m, o = job.machine, job.options
    top = f"at most {m.max_feed_mm_min:g} mm/min" if m.max_feed_mm_min < float("inf") else \
        "no limit"
    rows = [("spindle", f"{m.accel_rad_s2:g} rad/s² ({m.accel_rpm_s:.0f} RPM/s), "
                        f"{m.min_rpm:g}-{m.max_rpm:g} RPM"),
            ("feed", f"{top}; rapids {m.rapid_mm_min:g} mm/min"), ("control", control)]
    if job.cutter is not None:
        rows.append(("cutter", describe_cutter(job.cutter)
                     + f", programmed at the {job.cutter.tool_point}"))
    if job.cutting is not None:
        rows.append(("targets", f"vc {job.cutting.vc_m_min:.1f} m/min, "
                                f"fz {job.cutting.fz_mm:.4f} mm"))
    if planned:
        rows.append(("planner", f"{o.planner}, fz {o.fz_policy} within "
                                f"+-{100 * o.fz_tolerance:g} %, S steps of at least "
                                f"{o.min_rpm_step:g} RPM, S changes {s_changes}"))
    return tuple(rows)


def now_text() -> str:
    """The local time now, to the minute, as the pages print it (``2024-05-01 14:03 CEST``)."""
    return datetime.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z")
