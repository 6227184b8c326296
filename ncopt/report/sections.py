"""The parts of a report page, each an HTML fragment of a :class:`ReportData`: the big
numbers, the tables (job, tools, operations, control, warnings), each tool's plots along
the cut and its 3D toolpath, the changed blocks side by side and the rewrite's figures
by name.

The plots are plotly JSON (:mod:`ncopt.report.plots`), thinned to their min/max per
bucket (peaks survive), the 3D path to evenly spaced samples; each has a static PNG
beside it for print (or, on a lite page, instead of it).
"""

from __future__ import annotations

import base64
import html
from dataclasses import fields
from itertools import islice
from pathlib import Path

from ncopt import __version__
from ncopt.report.diffview import _rows, changed_words, totals
from ncopt.report.gather import ReportData, ToolSection
from ncopt.report.plots import along_path_figure, curves_json, path_json, png_bytes, toolpath_figure

__all__ = ["diff_section", "esc", "figures_by_name", "operations_table", "overview", "subtitle",
           "table", "tool_section", "tools_table", "warnings_section"]

CURVE_POINTS = 4000  # per curve and program (min/max buckets)
PATH_POINTS = 24000  # 3D toolpath samples, all tools together
PRINT_PATH_POINTS = 20000  # samples in the printed toolpath image
DIFF_ROWS = 60  # changed blocks shown side by side


def subtitle(d: ReportData) -> str:
    """``original → program · ncopt version · created``, under the page's title."""
    what = f"{d.against} → {d.program}" if d.against else d.program
    return f"{what} · ncopt {__version__} · {d.created}"


def esc(text) -> str:
    """``text`` (any value, as ``str``) escaped for HTML text and quoted attributes."""
    return html.escape(str(text), quote=True)


def overview(d: ReportData) -> str:
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
    items = "".join(f"<div class=card><div class=k>{esc(k)}</div><div class=v>{esc(v)}</div>"
                    f"<div class=n>{esc(n)}</div></div>" for k, v, n in cards)
    return f"<section class=cards>{items}</section>"


def _tool_name(tool: int) -> str:
    return f"T{tool}" if tool >= 0 else "the program's tool (no T word)"


def table(title: str, head: tuple[str, ...], rows, classes: tuple[str, ...] = ()) -> str:
    """A titled table; no header row when ``head`` is empty or all blank; ``classes``: a
    class per column (or "")."""
    if not rows:
        return ""
    th = "<tr>" + "".join(f"<th>{esc(h)}</th>" for h in head) + "</tr>" if any(head) else ""
    tr = "".join("<tr>" + "".join(_td(c, classes[j] if j < len(classes) else "")
                                  for j, c in enumerate(row)) + "</tr>" for row in rows)
    return f"<section><h2>{esc(title)}</h2><table>{th}{tr}</table></section>"


def _td(cell, cls: str) -> str:
    if cls == "status":
        cls = "planned" if cell == "planned" else "left"
    return f"<td class={cls}>{esc(cell)}</td>" if cls else f"<td>{esc(cell)}</td>"


def tools_table(d: ReportData) -> str:
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
    return table("Tools", ("tool", "", "cutter, or why it is left", "targets",
                           "cutting time", "fz in band", "fz extremes", "vc at most",
                           "cut length"), rows, ("nowrap", "status"))


def operations_table(d: ReportData) -> str:
    """Each operation: its tool and lines, planned or left, what it is or why it is left."""
    return table("Operations", ("operation", "tool", "lines", "", "what it is, or why it "
                                "is left", "time"), d.operations,
                 ("", "nowrap", "nowrap", "status", "", "nowrap"))


def figures_by_name(summary) -> str:
    """The rewrite's figures by the names ``rewrite --json`` gives them, folded away (for
    scripts and support; everything a shop reads is in the tables above)."""
    rows = []
    for f in fields(summary):
        value = getattr(summary, f.name)
        if not isinstance(value, (tuple, list)):
            rows.append((f.name.replace("_", " "), _fmt(value)))
    cells = "".join(f"<tr><td>{esc(k)}</td><td>{esc(v)}</td></tr>" for k, v in rows)
    return (f"<details class='figures screen-only'><summary><h2>Rewrite summary: the figures "
            f"by name, as rewrite --json gives them</h2></summary><table>{cells}</table>"
            "</details>")


def _fmt(value) -> str:
    """A figure as the summary table shows it: 4 significant digits, blank for NaN/None."""
    if isinstance(value, float):
        return "" if value != value else f"{value:.4g}" if abs(value) < 1e4 else f"{value:.0f}"
    return "" if value is None else str(value)


def warnings_section(warnings) -> str:
    """The warnings, the first 200 listed ("none" when there are none)."""
    if not warnings:
        return "<section><h2>Warnings</h2><p>none</p></section>"
    items = "".join(f"<li>{esc(w)}</li>" for w in warnings[:200])
    more = f"<p>{len(warnings) - 200} more</p>" if len(warnings) > 200 else ""
    return f"<section><h2>Warnings</h2><ul class=warn>{items}</ul>{more}</section>"


def tool_section(section: ToolSection, k: int, n: int,
                 lite: bool) -> tuple[str, list[tuple[str, str]]]:
    """A tool's curves and 3D path: interactive divs and their print images, or (lite)
    the images alone; and the (div id, plotly JSON) figures to draw in the divs.

    ``k``: the section's place on the page, ``n``: how many there are (they share the
    3D path's samples)."""
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
    part = (f"<section class='plots along'><h2>Along the cut: {esc(name)}, {esc(section.cutter)}"
            f"</h2><p>{note}</p>{curves}</section><section class=plots><h2>Toolpath: "
            f"{esc(name)}</h2>{path}</section>")
    if lite:
        return part, []
    return part, [(curves_id, curves_json(runs, CURVE_POINTS)),
                  (path_id, path_json(last, PATH_POINTS // n))]


def _img(png: bytes, shown: bool) -> str:
    cls = "figure" if shown else "print-only"
    return (f"<img class={cls} alt='' src='data:image/png;base64,"
            f"{base64.b64encode(png).decode('ascii')}'>")


def diff_section(d: ReportData) -> str:
    """The first changed blocks, original left and rewrite right, changed words marked."""
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
            left = "".join(f"<del>{esc(w)}</del>" if x else esc(w) for w, x in fa)
            right = "".join(f"<ins>{esc(w)}</ins>" if x else esc(w) for w, x in fb)
        else:
            left, right = esc(ta), esc(tb)
        rows.append(f"<tr class={kind}><td class=n>{na or ''}</td><td>{left}</td>"
                    f"<td class=n>{nb or ''}</td><td>{right}</td></tr>")
        if sum(r.startswith("<tr class=change") for r in rows) >= DIFF_ROWS:
            break
    head = (f"{t.changed} of {t.lines} lines changed (S in {t.s_changed}, F in "
            f"{t.f_changed}); the first {min(DIFF_ROWS, t.changed)}:")
    return (f"<section class=diff><h2>Changed blocks</h2><p>{esc(head)}</p><table class=code>"
            f"<tr><th class=n></th><th>{esc(Path(d.against).name)}</th><th class=n></th>"
            f"<th>{esc(Path(d.program).name)}</th></tr>{''.join(rows)}</table></section>")
