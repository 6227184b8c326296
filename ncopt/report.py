"""One self-contained HTML report a shop can open offline, print and mail.

What it holds: the settings, time before -> after for the whole program and per
tool, the rewrite's summary and warnings, S, F, fz and effective diameter along
the cut (original and rewrite), a 3D toolpath coloured by S, F, D_eff or vc
that turns and zooms, and the first changed blocks side by side.

* Interactive plots are plotly.js, embedded whole (no network at view time);
  the figures are written here as plotly JSON with float32 typed arrays, so the
  data of a 150k-block program stays around a megabyte: curves are thinned to
  their min/max per bucket (peaks survive), the 3D path to evenly spaced samples.
* Printed (A4), the interactive plots give way to static PNGs (matplotlib,
  embedded as data URIs, shown only in print).
* :func:`from_rewrite` and :func:`from_programs` are the only functions that
  know ``ncopt.api`` and ``ncopt.simulate``; everything else renders a
  :class:`ReportData`.  The rewrite's :class:`ncopt.api.Summary` is rendered
  field by field, whatever fields it has.
"""

from __future__ import annotations

import base64
import dataclasses
import datetime
import html
import json
from dataclasses import dataclass, replace
from itertools import islice
from pathlib import Path

import numpy as np

from . import __version__
from .simulate import SimReport, SimSeries

CURVE_POINTS = 4000  # per curve and program (min/max buckets)
PATH_POINTS = 30000  # 3D toolpath samples, all tools together
PRINT_PATH_POINTS = 20000  # samples in the printed toolpath image
DIFF_ROWS = 60  # changed blocks shown side by side
COLOR_BY = (("s_rpm", "S [RPM]"), ("f_mm_min", "F [mm/min]"), ("d_eff_mm", "D_eff [mm]"),
            ("vc_m_min", "vc [m/min]"))
_TEMPLATE = Path(__file__).resolve().parent / "data" / "report.css"


@dataclass(frozen=True)
class Run:
    """One program replayed by the simulator."""

    label: str
    series: SimSeries
    report: SimReport


@dataclass(frozen=True)
class ToolSection:
    """The runs of one tool: the original first (when there is one)."""

    tool: int
    cutter: str
    runs: tuple[Run, ...]


@dataclass(frozen=True)
class ReportData:
    """Everything the page shows; built by :func:`from_rewrite` or :func:`from_programs`.

    settings : (name, value) rows;  summary : the rewrite's summary (any frozen
    dataclass), None for a report of given programs;  lines : (original, program)
    text lines for the side-by-side blocks, None without an original
    """

    program: str
    against: str | None
    settings: tuple
    sections: tuple[ToolSection, ...]
    summary: object | None = None
    warnings: tuple = ()
    lines: tuple | None = None
    created: str = ""


# ------------------------------------------------------------ gathering (the coupling)


def from_rewrite(result, original_text: str, original_path: str, output_path: str, job,
                 mesh_index=None, sample_mm: float = 0.1) -> ReportData:
    """The report of an ``ncopt.api.Result``: original and rewrite simulated per planned tool."""
    from .simulate import simulate_program

    sections = []
    for plan in result.plans:
        tool_job = replace(job, cutter=plan.cutter, cutting=plan.cutting, tool=plan.tool)
        runs = []
        for path, text, role in ((original_path, original_text, "original"),
                                 (output_path, result.text, "rewrite")):
            rep, series = simulate_program(text, tool_job, mesh_index, path=path,
                                           sample_mm=sample_mm)
            runs.append(Run(f"{Path(path).name} ({role})", series, rep))
        sections.append(ToolSection(plan.tool, _describe(plan.cutter), tuple(runs)))
    s = result.summary
    return ReportData(output_path, original_path, _settings(job, s.control, s.s_changes, True),
                      tuple(sections), s, tuple(s.warnings),
                      (original_text.splitlines(), result.text.splitlines()), _now())


def from_programs(program_text: str, program_path: str, against_text: str | None,
                  against_path: str | None, job, mesh_index=None,
                  sample_mm: float = 0.1) -> ReportData:
    """The report of given programs (any, by ncopt or not), as ``ncopt simulate`` sees them.

    The original's targets (its own S and F at the nominal diameter) judge both.
    """
    from .model import CuttingData
    from .simulate import simulate_program

    runs = []
    for path, text, role in ((against_path, against_text, " (original)"),
                             (program_path, program_text, "")):
        if text is None:
            continue
        rep, series = simulate_program(text, job, mesh_index, path=path, sample_mm=sample_mm)
        if job.cutting is None:  # one target for all: the first program's
            job = replace(job, cutting=CuttingData(rep.vc_target_m_min, rep.fz_target_mm))
        runs.append(Run(Path(path).name + role, series, rep))
    cutter = job.cutter
    section = ToolSection(job.tool if job.tool is not None else -1,
                          _describe(cutter) if cutter else "from the program's comments",
                          tuple(runs))
    warnings = tuple(w for r in runs for w in r.report.warnings)
    lines = (against_text.splitlines(), program_text.splitlines()) if against_text else None
    return ReportData(program_path, against_path, _settings(job, job.control, None, False),
                      (section,), None, warnings, lines, _now())


def _describe(cutter) -> str:
    kind = "ball" if cutter.is_ball else f"bull-nose r{cutter.corner_radius_mm:g}"
    return f"D{cutter.diameter_mm:g} {kind}, {cutter.teeth} teeth"


def _settings(job, control, s_changes, planned: bool) -> tuple:
    """Machine, cutter and targets; with ``planned``, how ncopt planned too."""
    m, o = job.machine, job.options
    top = f"at most {m.max_feed_mm_min:g} mm/min" if m.max_feed_mm_min < float("inf") else \
        "no limit"
    rows = [("spindle", f"{m.accel_rad_s2:g} rad/s² ({m.accel_rpm_s:.0f} RPM/s), "
                        f"{m.min_rpm:g}-{m.max_rpm:g} RPM"),
            ("feed", f"{top}; rapids {m.rapid_mm_min:g} mm/min")]
    if job.cutter is not None:
        rows.append(("cutter", _describe(job.cutter) + f", programmed at the {job.cutter.tool_point}"))
    if job.cutting is not None:
        rows.append(("targets", f"vc {job.cutting.vc_m_min:.1f} m/min, "
                                f"fz {job.cutting.fz_mm:.4f} mm"))
    if planned:
        rows.append(("planner", f"{o.planner}, fz {o.fz_policy} within "
                                f"+-{100 * o.fz_tolerance:g} %, S steps of at least "
                                f"{o.min_rpm_step:g} RPM, S changes {s_changes}"))
    rows.append(("control", control or "detected from the program"))
    return tuple(rows)


def _now() -> str:
    return datetime.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z")


# ------------------------------------------------------------ the page


def render(data: ReportData) -> str:
    """The whole page as one string (plotly.js and the print images inside)."""
    from plotly.offline import get_plotlyjs

    title = f"ncopt report: {Path(data.program).name}"
    body = [f"<header><h1>{_e(title)}</h1><p class=meta>{_e(_subtitle(data))}</p></header>",
            _overview(data), _table("Settings", ("setting", "value"), data.settings)]
    body.append(_tools_table(data))
    notes = getattr(data.summary, "control_notes", ())
    body.append(_table("Control", ("what the control does with this program",),
                       [(n,) for n in notes]))
    body.append(_warnings(data.warnings))
    figures = []
    for k, section in enumerate(data.sections):
        html_part, figs = _section(section, k, len(data.sections))
        body.append(html_part)
        figures += figs
    if data.lines is not None:
        body.append(_diff_section(data))
    if data.summary is not None:
        body.append(_summary_section(data.summary))
    return _page(title, "\n".join(body), figures, get_plotlyjs())


def write(path: str | Path, page: str, make_parents: bool = False) -> Path:
    """Write a page as ``-o`` writes a program (atomically, with the usual file mode)."""
    from .fileio import write_output

    target = Path(path)
    write_output(target, page.encode("utf-8"), make_parents=make_parents)
    return target


def _subtitle(d: ReportData) -> str:
    what = f"{d.against} → {d.program}" if d.against else d.program
    return f"{what} · ncopt {__version__} · {d.created}"


def _e(text) -> str:
    return html.escape(str(text), quote=True)


def _page(title: str, body: str, figures: list, plotly_js: str) -> str:
    css = _TEMPLATE.read_text(encoding="utf-8")
    calls = "\n".join(f"ncoptPlot({json.dumps(div)}, {fig});" for div, fig in figures)
    return (f"<!DOCTYPE html>\n<html lang=en><head><meta charset=utf-8>"
            f"<meta name=viewport content='width=device-width, initial-scale=1'>"
            f"<title>{_e(title)}</title><style>{css}</style>"
            f"<script>{plotly_js}</script></head>\n<body>\n{body}\n"
            f"<pre id=ncopt-errors class=screen-only></pre>\n<script>{_DRAW_JS}\n{calls}\n"
            "</script>\n</body></html>\n")


# The page notes every plot it drew (data-drawn) and every script error it met, so a
# headless browser (and a user) can tell that all went well.
_DRAW_JS = """
window.addEventListener('error', function (e) {
  document.getElementById('ncopt-errors').textContent += 'error: ' + e.message + '\\n';
});
var ncoptPending = 0;
function ncoptPlot(id, fig) {
  var div = document.getElementById(id);
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
"""


def _overview(d: ReportData) -> str:
    """The big numbers: cutting time before -> after and the checks of the simulation."""
    cards = []
    runs = [s.runs for s in d.sections]
    before = sum(r[0].report.cutting_time_min for r in runs)
    after = sum(r[-1].report.cutting_time_min for r in runs)
    if d.against:
        change = 100.0 * (after / before - 1.0) if before > 0 else 0.0
        cards.append(("cutting time", f"{before:.1f} → {after:.1f} min", f"{change:+.1f} %"))
        total = (runs[0][0].report.total_time_min, runs[0][-1].report.total_time_min)
        cards.append(("whole program", f"{total[0]:.1f} → {total[1]:.1f} min",
                      "feeds and rapids"))
    else:
        cards.append(("cutting time", f"{after:.1f} min",
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


def _table(title: str, head: tuple, rows) -> str:
    """A titled table; no header row when ``head`` is empty."""
    if not rows:
        return ""
    th = "<tr>" + "".join(f"<th>{_e(h)}</th>" for h in head) + "</tr>" if head else ""
    tr = "".join("<tr>" + "".join(f"<td>{_e(c)}</td>" for c in row) + "</tr>" for row in rows)
    return f"<section><h2>{_e(title)}</h2><table>{th}{tr}</table></section>"


def _tools_table(d: ReportData) -> str:
    rows = []
    for s in d.sections:
        first, last = s.runs[0].report, s.runs[-1].report
        name = f"T{s.tool}" if s.tool >= 0 else "tool"
        if len(s.runs) > 1:
            change = (100.0 * (last.cutting_time_min / first.cutting_time_min - 1.0)
                      if first.cutting_time_min > 0 else 0.0)
            time = (f"{first.cutting_time_min:.2f} → {last.cutting_time_min:.2f} min "
                    f"({change:+.1f} %)")
        else:
            time = f"{last.cutting_time_min:.2f} min"
        rows.append((name, s.cutter, f"vc {first.vc_target_m_min:.1f} m/min, fz "
                     f"{first.fz_target_mm:.4f} mm", time, f"{last.fz_in_band_pct:.2f} %",
                     f"{last.fz_max_over_pct:+.2f} / {-last.fz_min_under_pct:+.2f} %",
                     f"{last.vc_max_over_pct:+.2f} % (line {last.vc_max_over_line})",
                     f"{last.cut_length_mm / 1000:.2f} m"))
    return _table("Per tool (simulated)", ("tool", "cutter", "targets", "cutting time",
                                            "fz in band", "fz extremes", "vc at most",
                                            "cut length"), rows)


def _summary_section(summary) -> str:
    """The rewrite's summary, every field: scalars in one table, row lists below it."""
    scalars, lists = [], []
    for f in dataclasses.fields(summary):
        value = getattr(summary, f.name)
        if f.name == "warnings":
            continue
        if isinstance(value, (tuple, list)):
            if value:
                lists.append((f.name, value))
            continue
        scalars.append((f.name.replace("_", " "), _fmt(value)))
    parts = [_table("Rewrite summary: every field", ("field", "value"), scalars)]
    for name, rows in lists:
        rows = [_row(r) for r in rows]
        width = max(len(r) for r in rows)
        parts.append(_table(name.replace("_", " "), (), [r + ("",) * (width - len(r))
                                                         for r in rows]))
    return "\n".join(parts)


def _row(item) -> tuple:
    if dataclasses.is_dataclass(item):
        return tuple(_fmt(getattr(item, f.name)) for f in dataclasses.fields(item))
    if isinstance(item, (tuple, list)):
        return tuple(_fmt(v) for v in item)
    return (_fmt(item),)


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


def _section(section: ToolSection, k: int, n: int) -> tuple[str, list]:
    """A tool's curves and 3D path: interactive divs, and their print images."""
    from .plots import along_path_figure, png_bytes, toolpath_figure

    name = f"T{section.tool}" if section.tool >= 0 else "the tool"
    runs = [(r.label, r.series, r.report) for r in section.runs]
    curves_id, path_id = f"curves-{k}", f"path-{k}"
    last = section.runs[-1].series
    print_curves = png_bytes(along_path_figure(runs, max_points=CURVE_POINTS), dpi=90)
    print_path = png_bytes(toolpath_figure(last, "s_rpm", max_points=PRINT_PATH_POINTS), dpi=90)
    part = (f"<section class='plots along'><h2>Along the cut: {_e(name)}, {_e(section.cutter)}</h2>"
            f"<div id={curves_id} class='plot curves screen-only'></div>{_img(print_curves)}"
            f"</section><section class=plots><h2>Toolpath: {_e(name)}</h2>"
            f"<p class=screen-only>Drag to turn, scroll to zoom; the menu colours the path by "
            f"S, F, effective diameter or vc.</p>"
            f"<div id={path_id} class='plot path screen-only'></div>{_img(print_path)}</section>")
    figs = [(curves_id, _curves_json(section)), (path_id, _path_json(last, PATH_POINTS // n))]
    return part, figs


def _img(png: bytes) -> str:
    return (f"<img class=print-only alt='' src='data:image/png;base64,"
            f"{base64.b64encode(png).decode('ascii')}'>")


def _array(values) -> dict:
    """A plotly typed array: float32, base64 (a third of the JSON's digits)."""
    a = np.ascontiguousarray(np.asarray(values, dtype="<f4"))
    return {"dtype": "f4", "bdata": base64.b64encode(a.tobytes()).decode("ascii")}


def _curves_json(section: ToolSection) -> str:
    """S, F, fz and D_eff along the cut: four stacked panels sharing the cut length."""
    from .plots import ALONG, cut_length_m, decimate

    traces = []
    for i, run in reversed(list(enumerate(section.runs))):
        first = i == 0 and len(section.runs) > 1
        x = cut_length_m(run.series)
        for p, name in enumerate(ALONG):
            xd, yd = decimate(x, getattr(run.series, name)[run.series.cutting],
                              max_points=CURVE_POINTS)
            traces.append({"type": "scatter", "mode": "lines",
                           "x": _array(xd), "y": _array(yd), "xaxis": "x",
                           "yaxis": f"y{p + 1 if p else ''}", "name": Path(run.label).name,
                           "legendgroup": str(i), "showlegend": p == 0, "legendrank": i,
                           "line": {"width": 1.6 if first else 1.0,
                                    "dash": "dash" if first else "solid",
                                    "color": "#1a1a1a" if first else _COLOURS[(i - 1) % 5]}})
    target = section.runs[0].report
    band = target.band_pct / 100.0
    shapes = [{"type": "line", "xref": "paper", "x0": 0, "x1": 1, "yref": "y3",
               "y0": target.fz_target_mm * k, "y1": target.fz_target_mm * k, "layer": "below",
               "line": {"color": "#d62728", "width": 1.2 if k == 1 else 0.8,
                        "dash": "solid" if k == 1 else "dot"}}
              for k in (1 - band, 1.0, 1 + band)]
    layout = {"height": 760, "margin": {"l": 70, "r": 20, "t": 40, "b": 50},
              "legend": {"orientation": "h", "y": 1.06, "x": 0}, "shapes": shapes,
              "xaxis": {"title": {"text": "cut length [m]"}, "anchor": "y4"},
              "hovermode": "x unified"}
    labels = ("S [RPM]", "F [mm/min]", "fz [mm]", "D_eff [mm]")
    for p, label in enumerate(labels):
        top = 1.0 - p * 0.25
        layout[f"yaxis{p + 1 if p else ''}"] = {"domain": [top - 0.22, top],
                                                "title": {"text": label}}
    return json.dumps({"data": traces, "layout": layout, "config": _CONFIG})


_COLOURS = ("#ff7f0e", "#1f77b4", "#2ca02c", "#9467bd", "#8c564b")
_CONFIG = {"displaylogo": False, "responsive": True}


def _colour_range(values: np.ndarray) -> tuple[float, float]:
    """The colour scale's ends: the values' range, widened to at least 2 % of their size so
    a constant S (one S per pass) reads as one colour on a plain scale, not as
    1687.6-1688.4 RPM."""
    finite = values[np.isfinite(values)]
    if finite.size == 0:
        return 0.0, 1.0
    lo, hi = float(finite.min()), float(finite.max())
    least = 0.02 * max(abs(lo), abs(hi), 1e-9)
    if hi - lo < least:
        mid = 0.5 * (lo + hi)
        lo, hi = mid - 0.5 * least, mid + 0.5 * least
    return lo, hi


def _path_json(series: SimSeries, max_points: int) -> str:
    """The cutting samples in 3D, evenly thinned, broken where the cut is interrupted;
    a menu recolours them by S, F, D_eff or vc."""
    idx = np.flatnonzero(series.cutting)
    step = max(1, -(-idx.size // max(max_points, 1)))
    keep = idx[::step]
    brk = np.concatenate(([False], np.diff(keep) > step))  # not consecutive cut samples
    pos = np.arange(keep.size) + np.cumsum(brk)
    n = keep.size + int(brk.sum())

    def gapped(values):
        out = np.full(n, np.nan)
        out[pos] = values[keep]
        return out

    xyz = [gapped(series.xyz_mm[:, j]) for j in range(3)]
    colours = {key: gapped(getattr(series, key)) for key, _ in COLOR_BY}
    first, label = COLOR_BY[0]
    ranges = {key: _colour_range(colours[key]) for key, _ in COLOR_BY}
    lo, hi = ranges[first]
    trace = {"type": "scatter3d", "mode": "lines", "x": _array(xyz[0]), "y": _array(xyz[1]),
             "z": _array(xyz[2]), "connectgaps": False, "hoverinfo": "x+y+z",
             "line": {"width": 4, "color": _array(colours[first]), "colorscale": "Viridis",
                      "cmin": lo, "cmax": hi,
                      "showscale": True, "colorbar": {"title": {"text": label}}}}
    buttons = [{"label": lab, "method": "restyle",
                "args": [{"line.color": [_array(colours[key])],
                          "line.cmin": [ranges[key][0]], "line.cmax": [ranges[key][1]],
                          "line.colorbar.title.text": lab}]} for key, lab in COLOR_BY]
    span = np.nanmax(np.vstack(xyz), axis=1) - np.nanmin(np.vstack(xyz), axis=1)
    span = np.maximum(np.nan_to_num(span, nan=1.0), 1e-3)
    ratio = span / span.max()
    ratio[2] = max(ratio[2], 0.25)  # as the printed view: a flat part stretched to 1:4
    layout = {"height": 640, "margin": {"l": 0, "r": 0, "t": 30, "b": 0},
              "updatemenus": [{"buttons": buttons, "x": 0, "y": 1.08, "xanchor": "left",
                               "direction": "right", "type": "buttons"}],
              "scene": {"aspectmode": "manual",
                        "aspectratio": dict(zip("xyz", map(float, ratio))),
                        "xaxis": {"title": {"text": "X [mm]"}},
                        "yaxis": {"title": {"text": "Y [mm]"}},
                        "zaxis": {"title": {"text": "Z [mm]"}, "nticks": 4},
                        "camera": {"eye": {"x": 0.95, "y": -1.2, "z": 0.75}}}}
    return json.dumps({"data": [trace], "layout": layout, "config": _CONFIG})


def _diff_section(d: ReportData) -> str:
    """The first changed blocks, original left and rewrite right, changed words marked."""
    from .diffview import _rows, changed_words, totals

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
            f"<tr><th></th><th>{_e(Path(d.against).name)}</th><th></th>"
            f"<th>{_e(Path(d.program).name)}</th></tr>{''.join(rows)}</table></section>")


# ------------------------------------------------------------ batch: pages and the index


def require_libraries() -> None:
    """Raise UsageError unless plotly and matplotlib (the ``plot`` extra) are installed."""
    import importlib.util

    from .errors import UsageError

    missing = [m for m in ("plotly", "matplotlib") if importlib.util.find_spec(m) is None]
    if missing:
        raise UsageError(f"the HTML report needs {' and '.join(missing)}: python -m pip install "
                         f"{' '.join(missing)} (or, in ncopt's source folder, python -m pip "
                         "install \".[plot]\")")


def page_path(index: Path, base: Path, program: Path) -> str:
    """Where a batch file's page goes: mirrored in a folder named after the index page."""
    import os

    return str(Path(index).with_suffix("") / (os.path.relpath(program, base) + ".html"))


def write_file_page(path: str, result, data: bytes, src: str, target: str, job,
                    mesh) -> tuple[str, str]:
    """One batch file's page: (path written, "") or ("", why not); never raises for the file."""
    from .errors import NcoptError
    from .geometry import MeshIndex, load_stl

    try:
        index = MeshIndex(load_stl(mesh)) if mesh else None
        page = render(from_rewrite(result, data.decode("latin-1"), src, target, job, index))
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        return str(write(path, page)), ""
    except NcoptError as exc:
        return "", exc.message
    except OSError as exc:
        return "", f"cannot write the report: {exc.strerror or exc}"


def render_index(reports, base: Path, index_path: str | Path) -> str:
    """The batch's index page: a row per file, linking to each file's page."""
    import os

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
                    f"<td>{_e(note)}</td></tr>")
    counts = {k: sum(r.status == k for r in reports) for k in ("ok", "unchanged", "failed")}
    total = (f"{counts['ok']} rewritten, {counts['unchanged']} unchanged, {counts['failed']} "
             f"failed, of {len(reports)} files; estimated cutting time of the rewritten ones "
             f"{before:.1f} → {after:.1f} min")
    body = (f"<header><h1>ncopt batch report</h1><p class=meta>{_e(base)} · ncopt "
            f"{__version__} · {_now()}</p></header><section><p>{_e(total)}</p><table>"
            "<tr><th>file</th><th>status</th><th>blocks</th><th>S words</th>"
            "<th>cutting time (min)</th><th>warnings</th><th>note</th></tr>"
            f"{''.join(rows)}</table></section>")
    css = _TEMPLATE.read_text(encoding="utf-8")
    return (f"<!DOCTYPE html>\n<html lang=en><head><meta charset=utf-8><title>ncopt batch "
            f"report</title><style>{css}</style></head>\n<body>\n{body}\n</body></html>\n")


def _relative(path: str, base: Path) -> str:
    """The path as found under the batch's folder (a symlink keeps its place in it)."""
    import os

    rel = os.path.relpath(os.path.abspath(path), os.path.abspath(base))
    return path if rel.startswith("..") else rel
