"""One HTML report a shop can open offline, print and mail.

What it holds: the job (machine, control, targets), time before -> after for the
whole program and per tool, every tool and operation (planned, or left as
programmed and why), the control's notes and the warnings, S, F, fz, vc and
effective diameter along the cut of each planned tool (original and rewrite), a
3D toolpath coloured by S, F, D_eff or vc that turns and zooms, and the first
changed blocks side by side.

* Interactive plots are plotly.js (no network at view time): embedded whole in a
  single page; a batch's pages share one ``plotly.min.js`` in their folder
  (:func:`write_file_page`).  The figures are plotly JSON with float32 typed
  arrays (:mod:`ncopt.report.plots`), thinned to their min/max per bucket (peaks survive),
  the 3D path to evenly spaced samples.
* Printed (A4), the interactive plots give way to static PNGs (matplotlib,
  embedded as data URIs, shown only in print).  A lite page (``lite``) has only
  those images, on screen too, and no plotly: well under a megabyte.
* :func:`from_rewrite` and :func:`from_programs` are the only functions that
  know ``ncopt.api`` and ``ncopt.simulate.replay``; everything else renders a
  :class:`ReportData`.
"""

from __future__ import annotations

import base64
import datetime
import html
import json
import os
from dataclasses import dataclass, fields, replace
from itertools import islice
from pathlib import Path

from ncopt import __version__
from ncopt.report.plots import colour_range as _colour_range  # noqa: F401 - the report's colour scales
from ncopt.simulate.results import SimReport, SimSeries

CURVE_POINTS = 4000  # per curve and program (min/max buckets)
PATH_POINTS = 24000  # 3D toolpath samples, all tools together
PRINT_PATH_POINTS = 20000  # samples in the printed toolpath image
DIFF_ROWS = 60  # changed blocks shown side by side
PLOTLY_FILE = "plotly.min.js"  # a batch's pages share this file, in the pages' folder
_TEMPLATE = Path(__file__).resolve().parent.parent / "data" / "report.css"
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
    settings: tuple
    sections: tuple[ToolSection, ...]
    summary: object | None = None
    warnings: tuple = ()
    lines: tuple | None = None
    created: str = ""
    operations: tuple = ()
    left: tuple = ()
    notes: tuple = ()


# ------------------------------------------------------------ gathering (the coupling)


def from_rewrite(result, original_text: str, original_path: str, output_path: str, job,
                 mesh_index=None, sample_mm: float = 0.1) -> ReportData:
    """The report of an ``ncopt.api.Result``: original and rewrite simulated per planned tool."""
    from ncopt.simulate.replay import simulate_program
    from ncopt.simulate.toolchoice import describe_cutter

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
                      (original_text.splitlines(), result.text.splitlines()), _now(),
                      operations, tuple(s.skipped_tools), tuple(s.control_notes))


def from_programs(program_text: str, program_path: str, against_text: str | None,
                  against_path: str | None, job, mesh_index=None,
                  sample_mm: float = 0.1) -> ReportData:
    """The report of given programs (any, by ncopt or not), as ``ncopt simulate`` sees them:
    a section per tool ncopt would plan (or ``job.tool``), the others listed as left.

    The original's targets (its own S and F at the nominal diameter) judge both.
    """
    from ncopt.reading.dialect import detect
    from ncopt.model import CuttingData
    from ncopt.simulate.replay import simulate_program, tools_to_simulate

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
                      _now(), operations, chosen.left)


def _op_row(name, tool, lines, planned, kind, reason, time, extra) -> tuple:
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


def _mesh_rows(s) -> tuple:
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


def _settings(job, control: str, s_changes, planned: bool) -> tuple:
    """Machine, control, cutter and targets; with ``planned``, how ncopt planned too."""
    from ncopt.simulate.toolchoice import describe_cutter

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


def _now() -> str:
    return datetime.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z")


# ------------------------------------------------------------ the page


def render(data: ReportData, *, lite: bool = False, plotly_src: str | None = None) -> str:
    """The whole page as one string.

    Default: plotly.js inside the page (it opens anywhere, offline);  ``plotly_src``: a
    ``<script src>`` to a shared copy instead (a batch's pages);  ``lite``: no plotly,
    static images only.
    """
    title = f"ncopt report: {Path(data.program).name}"
    body = [f"<header><h1>{_e(title)}</h1><p class=meta>{_e(_subtitle(data))}</p></header>",
            _overview(data), _table("Job", ("", ""), data.settings), _tools_table(data),
            _operations_table(data),
            _table("Control", ("what the control does with this program",),
                   [(n,) for n in data.notes]),
            _warnings(data.warnings)]
    figures = []
    for k, section in enumerate(data.sections):
        html_part, figs = _section(section, k, len(data.sections), lite)
        body.append(html_part)
        figures += figs
    if data.lines is not None:
        body.append(_diff_section(data))
    if data.summary is not None:
        body.append(_figures_by_name(data.summary))
    if lite:
        script = ""
    elif plotly_src is not None:
        script = f"<script src='{_e(plotly_src)}'></script>"
    else:
        from plotly.offline import get_plotlyjs

        script = f"<script>{get_plotlyjs()}</script>"
    return _page(title, "\n".join(body), figures, script)


def write(path: str | Path, page: str, make_parents: bool = False) -> Path:
    """Write a page as ``-o`` writes a program (atomically, with the usual file mode)."""
    from ncopt.runtime.fileio import write_output

    target = Path(path)
    write_output(target, page.encode("utf-8"), make_parents=make_parents)
    return target


def _subtitle(d: ReportData) -> str:
    what = f"{d.against} → {d.program}" if d.against else d.program
    return f"{what} · ncopt {__version__} · {d.created}"


def _e(text) -> str:
    return html.escape(str(text), quote=True)


# what report.css (the screen and print layout) leaves to the report's later parts
_CSS = """
table.code { table-layout: fixed; }
table.code th.n { width: 4.5em; }
table.code td { white-space: pre-wrap; overflow-wrap: anywhere; }
img.figure { display: block; max-width: 100%; height: auto; margin: 8px 0; }
td.planned { color: #060; font-weight: 600; white-space: nowrap; }
td.left { color: var(--mute); white-space: nowrap; }
td.nowrap { white-space: nowrap; }
details.figures > summary { cursor: pointer; }
details.figures > summary h2 { display: inline-block; border: none; }
"""


def _page(title: str, body: str, figures: list, script: str) -> str:
    css = _TEMPLATE.read_text(encoding="utf-8") + _CSS
    draw = ""
    if figures:
        calls = "\n".join(f"ncoptPlot({json.dumps(div)}, {fig});" for div, fig in figures)
        draw = f"<script>{_DRAW_JS}\n{calls}\n</script>\n"
    return (f"<!DOCTYPE html>\n<html lang=en><head><meta charset=utf-8>"
            f"<meta name=viewport content='width=device-width, initial-scale=1'>"
            f"<title>{_e(title)}</title><style>{css}</style>{script}</head>\n<body>\n{body}\n"
            f"<pre id=ncopt-errors class=screen-only></pre>\n{draw}</body></html>\n")


# The page notes every plot it drew (data-drawn) and every script error it met, so a
# headless browser (and a user) can tell that all went well.
_DRAW_JS = """
window.addEventListener('error', function (e) {
  document.getElementById('ncopt-errors').textContent += 'error: ' + e.message + '\\n';
});
var ncoptPending = 0;
function ncoptPlot(id, fig) {
  var div = document.getElementById(id);
  if (typeof Plotly === 'undefined') {
    document.getElementById('ncopt-errors').textContent +=
      'plotly.js did not load: keep ' + %s + ' beside this page\\n';
    return;
  }
  ncoptPending += 1;
  Plotly.newPlot(div, fig.data, fig.layout, fig.config).then(function () {
    div.setAttribute('data-drawn', '1');
    ncoptPending -= 1;
    if (ncoptPending === 0) {  // ms from the start of loading to the last plot drawn
      document.body.setAttribute('data-drawn-ms', Math.round(performance.now()));
    }
  }, function (err) {
    document.getElementById('ncopt-errors').textContent += 'plot ' + id + ': ' + err + '\\n';
  });
}
""" % json.dumps(PLOTLY_FILE)


def _overview(d: ReportData) -> str:
    """The big numbers: cutting time before -> after and the checks of the simulation."""
    cards = []
    runs = [s.runs for s in d.sections]
    before = sum(r[0].report.cutting_time_min for r in runs)
    after = sum(r[-1].report.cutting_time_min for r in runs)
    tools = ", ".join(_tool_name(s.tool) for s in d.sections)
    if d.against:
        change = 100.0 * (after / before - 1.0) if before > 0 else 0.0
        cards.append((f"cutting time ({tools})", f"{before:.1f} → {after:.1f} min",
                      f"{change:+.1f} %"))
        total = (runs[0][0].report.total_time_min, runs[0][-1].report.total_time_min)
        cards.append(("whole program", f"{total[0]:.1f} → {total[1]:.1f} min",
                      "feeds and rapids"))
    else:
        cards.append((f"cutting time ({tools})", f"{after:.1f} min",
                      f"whole program {runs[0][-1].report.total_time_min:.1f} min"))
    last = [r[-1].report for r in runs]
    band = min(r.fz_in_band_pct for r in last)
    cards.append(("fz within +-%g %%" % last[0].band_pct, f"{band:.2f} %", "of the cut"))
    vc = max(r.vc_max_over_pct for r in last)
    cards.append(("vc at most", f"{vc:+.2f} %", "of its target"))
    cards.append(("S words", f"{last[0].s_words}",
                  f"highest S {max(r.max_rpm for r in last):.0f} RPM"))
    if d.summary is not None and hasattr(d.summary, "s_changes"):
        s = d.summary
        other = getattr(s, "cut_time_other_min", float("nan"))
        alt = "anywhere" if s.s_changes == "between-passes" else "between passes"
        cards.append(("S changes", s.s_changes.replace("-", " "),
                      f"{alt}: {other:.1f} min cutting" if other == other else ""))
    items = "".join(f"<div class=card><div class=k>{_e(k)}</div><div class=v>{_e(v)}</div>"
                    f"<div class=n>{_e(n)}</div></div>" for k, v, n in cards)
    return f"<section class=cards>{items}</section>"


def _tool_name(tool: int) -> str:
    return f"T{tool}" if tool >= 0 else "the program's tool (no T word)"


def _table(title: str, head: tuple, rows, classes: tuple = ()) -> str:
    """A titled table; no header row when ``head`` is empty or all blank; ``classes``: a
    class per column (or "")."""
    if not rows:
        return ""
    th = "<tr>" + "".join(f"<th>{_e(h)}</th>" for h in head) + "</tr>" if any(head) else ""
    tr = "".join("<tr>" + "".join(_td(c, classes[j] if j < len(classes) else "")
                                  for j, c in enumerate(row)) + "</tr>" for row in rows)
    return f"<section><h2>{_e(title)}</h2><table>{th}{tr}</table></section>"


def _td(cell, cls: str) -> str:
    if cls == "status":
        cls = "planned" if cell == "planned" else "left"
    return f"<td class={cls}>{_e(cell)}</td>" if cls else f"<td>{_e(cell)}</td>"


def _tools_table(d: ReportData) -> str:
    """Each tool simulated: its cutter, targets, times and checks; each tool left, why."""
    rows = []
    for s in d.sections:
        first, last = s.runs[0].report, s.runs[-1].report
        if len(s.runs) > 1:
            change = (100.0 * (last.cutting_time_min / first.cutting_time_min - 1.0)
                      if first.cutting_time_min > 0 else 0.0)
            time = (f"{first.cutting_time_min:.2f} → {last.cutting_time_min:.2f} min "
                    f"({change:+.1f} %)")
        else:
            time = f"{last.cutting_time_min:.2f} min"
        cutter = s.cutter + (f" (from {s.cutter_from})" if s.cutter_from else "")
        rows.append((_tool_name(s.tool), "planned", cutter,
                     f"vc {first.vc_target_m_min:.1f} m/min, fz {first.fz_target_mm:.4f} mm",
                     time, f"{last.fz_in_band_pct:.2f} %",
                     f"{last.fz_max_over_pct:+.2f} / {-last.fz_min_under_pct:+.2f} %",
                     f"{last.vc_max_over_pct:+.2f} % (line {last.vc_max_over_line})",
                     f"{last.cut_length_mm / 1000:.2f} m"))
    for tool, why in d.left:
        rows.append((_tool_name(tool), "left as programmed", why, "", "", "", "", "", ""))
    return _table("Tools", ("tool", "", "cutter, or why it is left", "targets",
                            "cutting time", "fz in band", "fz extremes", "vc at most",
                            "cut length"), rows, ("nowrap", "status"))


def _operations_table(d: ReportData) -> str:
    return _table("Operations", ("operation", "tool", "lines", "", "what it is, or why it "
                                 "is left", "time"), d.operations,
                  ("", "nowrap", "nowrap", "status", "", "nowrap"))


def _figures_by_name(summary) -> str:
    """The rewrite's figures by the names ``rewrite --json`` gives them, folded away (for
    scripts and support; everything a shop reads is in the tables above)."""
    rows = []
    for f in fields(summary):
        value = getattr(summary, f.name)
        if not isinstance(value, (tuple, list)):
            rows.append((f.name.replace("_", " "), _fmt(value)))
    table = "".join(f"<tr><td>{_e(k)}</td><td>{_e(v)}</td></tr>" for k, v in rows)
    return (f"<details class='figures screen-only'><summary><h2>Rewrite summary: the figures "
            f"by name, as rewrite --json gives them</h2></summary><table>{table}</table>"
            "</details>")


def _fmt(value) -> str:
    if isinstance(value, float):
        return "" if value != value else f"{value:.4g}" if abs(value) < 1e4 else f"{value:.0f}"
    return "" if value is None else str(value)


def _warnings(warnings) -> str:
    if not warnings:
        return "<section><h2>Warnings</h2><p>none</p></section>"
    items = "".join(f"<li>{_e(w)}</li>" for w in warnings[:200])
    more = f"<p>{len(warnings) - 200} more</p>" if len(warnings) > 200 else ""
    return f"<section><h2>Warnings</h2><ul class=warn>{items}</ul>{more}</section>"


def _section(section: ToolSection, k: int, n: int, lite: bool) -> tuple[str, list]:
    """A tool's curves and 3D path: interactive divs and their print images, or (lite)
    the images alone."""
    from ncopt.report.plots import along_path_figure, curves_json, path_json, png_bytes, toolpath_figure

    name = _tool_name(section.tool)
    runs = [(r.label, r.series, r.report) for r in section.runs]
    curves_id, path_id = f"curves-{k}", f"path-{k}"
    last = section.runs[-1].series
    curves_png = png_bytes(along_path_figure(runs, max_points=CURVE_POINTS,
                                             size=(11, 11.5)), dpi=100 if lite else 72)
    path_png = png_bytes(toolpath_figure(last, "s_rpm", max_points=PRINT_PATH_POINTS),
                         dpi=100 if lite else 72)
    shown = "" if lite else "class='plot {} screen-only'"
    curves = _img(curves_png, lite) if lite else (
        f"<div id={curves_id} {shown.format('curves')}></div>{_img(curves_png, lite)}")
    path = _img(path_png, lite) if lite else (
        f"<p class=screen-only>Drag to turn, scroll to zoom; the menu colours the path by "
        f"S, F, effective diameter or vc.</p>"
        f"<div id={path_id} {shown.format('path')}></div>{_img(path_png, lite)}")
    note = ("fz and vc are scaled to their target's band; samples beyond the scale (a plunge, "
            "a spindle catching up) are marked at the panel's edge, the extremes named above "
            "it.")
    part = (f"<section class='plots along'><h2>Along the cut: {_e(name)}, {_e(section.cutter)}"
            f"</h2><p>{note}</p>{curves}</section><section class=plots><h2>Toolpath: "
            f"{_e(name)}</h2>{path}</section>")
    if lite:
        return part, []
    return part, [(curves_id, curves_json(runs, CURVE_POINTS)),
                  (path_id, path_json(last, PATH_POINTS // n))]


def _img(png: bytes, shown: bool) -> str:
    cls = "figure" if shown else "print-only"
    return (f"<img class={cls} alt='' src='data:image/png;base64,"
            f"{base64.b64encode(png).decode('ascii')}'>")


def _diff_section(d: ReportData) -> str:
    """The first changed blocks, original left and rewrite right, changed words marked."""
    from ncopt.report.diffview import _rows, changed_words, totals

    a, b = d.lines
    t = totals(a, b)
    rows = []
    for row in islice((r for r in _rows(a, b)), DIFF_ROWS * 3):
        if row[0] == "fold":
            rows.append(f"<tr class=fold><td colspan=4>{row[1]} unchanged lines</td></tr>")
            continue
        kind, na, ta, nb, tb = row
        if kind == "change":
            fa, fb = changed_words(ta, tb)
            left = "".join(f"<del>{_e(w)}</del>" if x else _e(w) for w, x in fa)
            right = "".join(f"<ins>{_e(w)}</ins>" if x else _e(w) for w, x in fb)
        else:
            left, right = _e(ta), _e(tb)
        rows.append(f"<tr class={kind}><td class=n>{na or ''}</td><td>{left}</td>"
                    f"<td class=n>{nb or ''}</td><td>{right}</td></tr>")
        if sum(r.startswith("<tr class=change") for r in rows) >= DIFF_ROWS:
            break
    head = (f"{t.changed} of {t.lines} lines changed (S in {t.s_changed}, F in "
            f"{t.f_changed}); the first {min(DIFF_ROWS, t.changed)}:")
    return (f"<section class=diff><h2>Changed blocks</h2><p>{_e(head)}</p><table class=code>"
            f"<tr><th class=n></th><th>{_e(Path(d.against).name)}</th><th class=n></th>"
            f"<th>{_e(Path(d.program).name)}</th></tr>{''.join(rows)}</table></section>")


# ------------------------------------------------------------ batch: pages and the index


def require_libraries() -> None:
    """Raise UsageError unless plotly and matplotlib (the ``plot`` extra) are installed."""
    import importlib.util

    from ncopt.runtime.errors import UsageError

    missing = [m for m in ("plotly", "matplotlib") if importlib.util.find_spec(m) is None]
    if missing:
        raise UsageError(f"the HTML report needs {' and '.join(missing)}: python -m pip install "
                         f"{' '.join(missing)} (or, in ncopt's source folder, python -m pip "
                         "install \".[plot]\")")


_ROOT_MARK = os.sep + "." + os.sep  # ends the pages' folder in a page's path (rsync -R's mark)


def page_path(index: Path, base: Path, program: Path) -> str:
    """Where a batch file's page goes: mirrored in a folder named after the index page.

    The path marks where that folder ends with a ``/./`` component (as rsync's
    ``--relative`` does: the same file to the system), so :func:`write_file_page`, in a
    worker, knows where the pages' shared plotly.js lies."""
    root = str(Path(index).with_suffix(""))
    return root + _ROOT_MARK + os.path.relpath(program, base) + ".html"


def write_file_page(path: str, result, data: bytes, src: str, target: str, job,
                    mesh, lite: bool = False) -> tuple[str, str]:
    """One batch file's page: (path written, "") or ("", why not); never raises for the file.

    Its plotly.js is the pages' shared ``plotly.min.js`` (written once, by the first page
    that needs it), where :func:`page_path` marks the pages' folder; embedded otherwise."""
    from ncopt.runtime.errors import NcoptError
    from ncopt.contacts.geometry import MeshIndex, load_stl

    root, marked, _ = path.partition(_ROOT_MARK)
    page_file = Path(os.path.normpath(path))
    try:
        index = MeshIndex(load_stl(mesh)) if mesh else None
        report = from_rewrite(result, data.decode("latin-1"), src, target, job, index)
        shared = None
        if marked and not lite:
            js = shared_plotly(Path(root))
            shared = Path(os.path.relpath(js, page_file.parent)).as_posix()
        page_file.parent.mkdir(parents=True, exist_ok=True)
        return str(write(page_file, render(report, lite=lite, plotly_src=shared))), ""
    except NcoptError as exc:
        return "", exc.message
    except OSError as exc:
        return "", f"cannot write the report: {exc.strerror or exc}"


def shared_plotly(folder: Path) -> Path:
    """``folder/plotly.min.js``, written (atomically) unless it already holds this plotly.js."""
    from plotly.offline import get_plotlyjs

    from ncopt.runtime.fileio import write_output

    js = get_plotlyjs().encode("utf-8")
    target = folder / PLOTLY_FILE
    try:
        same = target.stat().st_size == len(js) and target.read_bytes() == js
    except OSError:
        same = False
    if not same:
        write_output(target, js, make_parents=True)
    return target


def render_index(reports, base: Path, index_path: str | Path) -> str:
    """The batch's index page: a row per file, linking to each file's page."""
    folder = Path(index_path).resolve().parent
    rows, before, after = [], 0.0, 0.0
    for r in reports:
        name = _e(_relative(r.source, base))
        link = (f"<a href='{_e(Path(os.path.relpath(r.report, folder)).as_posix())}'>{name}</a>"
                if r.report else name)
        time = ""
        if r.status == "ok":
            before, after = before + r.time_before_min, after + r.time_after_min
            time = f"{r.time_before_min:.1f} → {r.time_after_min:.1f}"
        note = r.error or (f"no report: {r.report_error}" if r.report_error else "")
        rows.append(f"<tr><td>{link}</td><td>{_e(r.status)}</td><td>{r.blocks}</td>"
                    f"<td>{r.s_words}</td><td>{time}</td><td>{r.warnings}</td>"
                    f"<td>{_e(_planned(r))}</td><td>{_e(note)}</td></tr>")
    counts = {k: sum(r.status == k for r in reports) for k in ("ok", "unchanged", "failed")}
    total = (f"{counts['ok']} rewritten, {counts['unchanged']} unchanged, {counts['failed']} "
             f"failed, of {len(reports)} files; estimated cutting time of the rewritten ones "
             f"{before:.1f} → {after:.1f} min")
    body = (f"<header><h1>ncopt batch report</h1><p class=meta>{_e(base)} · ncopt "
            f"{__version__} · {_now()}</p></header><section><p>{_e(total)}</p><table>"
            "<tr><th>file</th><th>status</th><th>blocks</th><th>S words</th>"
            "<th>cutting time (min)</th><th>warnings</th><th>operations planned</th>"
            f"<th>note</th></tr>{''.join(rows)}</table></section>")
    css = _TEMPLATE.read_text(encoding="utf-8") + _CSS
    return (f"<!DOCTYPE html>\n<html lang=en><head><meta charset=utf-8><title>ncopt batch "
            f"report</title><style>{css}</style></head>\n<body>\n{body}\n</body></html>\n")


def _planned(r) -> str:
    """``SCALLOP1 (1 of 13)``: the operations a file's rewrite planned."""
    ops = getattr(r, "operations", ()) or ()
    names = [name for name, planned, _ in ops if planned]
    if not ops:
        return ""
    shown = ", ".join(names[:3]) + (f" and {len(names) - 3} more" if len(names) > 3 else "")
    return f"{shown or 'none'} ({len(names)} of {len(ops)})"


def _relative(path: str, base: Path) -> str:
    """The path as found under the batch's folder (a symlink keeps its place in it)."""
    rel = os.path.relpath(os.path.abspath(path), os.path.abspath(base))
    return path if rel.startswith("..") else rel
