"""One HTML report a shop can open offline, print and mail, and a batch's pages.

What it holds: the job (machine, control, targets), time before -> after for the
whole program and per tool, every tool and operation (planned, or left as
programmed and why), the control's notes and the warnings, S, F, fz, vc and
effective diameter along the cut of each planned tool (original and rewrite), a
3D toolpath coloured by S, F, D_eff or vc that turns and zooms, and the first
changed blocks side by side.

* This module puts the page together (:func:`render`) and writes it (:func:`write`);
  the parts are :mod:`ncopt.report.sections`, what they show is gathered by
  :mod:`ncopt.report.gather`.
* Interactive plots are plotly.js (no network at view time): embedded whole in a
  single page; a batch's pages share one ``plotly.min.js`` in their folder
  (:func:`write_file_page`, :mod:`ncopt.report.plotlyjs`).
* Printed (A4), the interactive plots give way to static PNGs (matplotlib,
  embedded as data URIs, shown only in print).  A lite page (``lite``) has only
  those images, on screen too, and no plotly: well under a megabyte.
"""

from __future__ import annotations

import importlib.util
import json
import os
from pathlib import Path

from ncopt import __version__
from ncopt.contacts.geometry import MeshIndex, load_stl
from ncopt.report.gather import ReportData, from_rewrite, now_text
from ncopt.report.plotlyjs import PLOTLY_FILE, plotly_js, shared_plotly
from ncopt.report.sections import (diff_section, esc, figures_by_name, operations_table, overview,
                                   subtitle, table, tool_section, tools_table, warnings_section)
from ncopt.runtime.errors import NcoptError, UsageError
from ncopt.runtime.fileio import write_output

_TEMPLATE = Path(__file__).resolve().parent.parent / "data" / "report.css"


# ------------------------------------------------------------ the page


def render(data: ReportData, *, lite: bool = False, plotly_src: str | None = None) -> str:
    """The whole page as one string.

    Default: plotly.js inside the page (it opens anywhere, offline);  ``plotly_src``: a
    ``<script src>`` to a shared copy instead (a batch's pages);  ``lite``: no plotly,
    static images only.
    """
    title = f"ncopt report: {Path(data.program).name}"
    body = [f"<header><h1>{esc(title)}</h1><p class=meta>{esc(subtitle(data))}</p></header>",
            overview(data), table("Job", ("", ""), data.settings), tools_table(data),
            operations_table(data),
            table("Control", ("what the control does with this program",),
                  [(n,) for n in data.notes]),
            warnings_section(data.warnings)]
    figures = []
    for k, section in enumerate(data.sections):
        html_part, figs = tool_section(section, k, len(data.sections), lite)
        body.append(html_part)
        figures += figs
    if data.lines is not None:
        body.append(diff_section(data))
    if data.summary is not None:
        body.append(figures_by_name(data.summary))
    if lite:
        script = ""
    elif plotly_src is not None:
        script = f"<script src='{esc(plotly_src)}'></script>"
    else:
        script = f"<script>{plotly_js()}</script>"
    return _page(title, "\n".join(body), figures, script)


def write(path: str | Path, page: str, make_parents: bool = False) -> Path:
    """Write a page as ``-o`` writes a program (atomically, with the usual file mode)."""
    target = Path(path)
    write_output(target, page.encode("utf-8"), make_parents=make_parents)
    return target


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


def _page(title: str, body: str, figures: list[tuple[str, str]], script: str) -> str:
    """The page around ``body``: the styles, ``script`` (plotly.js or nothing) and the
    calls that draw each (div id, plotly JSON) figure."""
    css = _TEMPLATE.read_text(encoding="utf-8") + _CSS
    draw = ""
    if figures:
        calls = "\n".join(f"ncoptPlot({json.dumps(div)}, {fig});" for div, fig in figures)
        draw = f"<script>{_DRAW_JS}\n{calls}\n</script>\n"
    return (f"<!DOCTYPE html>\n<html lang=en><head><meta charset=utf-8>"
            f"<meta name=viewport content='width=device-width, initial-scale=1'>"
            f"<title>{esc(title)}</title><style>{css}</style>{script}</head>\n<body>\n{body}\n"
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


# ------------------------------------------------------------ batch: pages and the index


def require_libraries() -> None:
    """Raise UsageError unless plotly and matplotlib (the ``plot`` extra) are installed."""
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


def render_index(reports, base: Path, index_path: str | Path) -> str:
    """The batch's index page: a row per file, linking to each file's page."""
    folder = Path(index_path).resolve().parent
    rows, before, after = [], 0.0, 0.0
    for r in reports:
        name = esc(_relative(r.source, base))
        link = (f"<a href='{esc(Path(os.path.relpath(r.report, folder)).as_posix())}'>{name}</a>"
                if r.report else name)
        time = ""
        if r.status == "ok":
            before, after = before + r.time_before_min, after + r.time_after_min
            time = f"{r.time_before_min:.1f} → {r.time_after_min:.1f}"
        note = r.error or (f"no report: {r.report_error}" if r.report_error else "")
        rows.append(f"<tr><td>{link}</td><td>{esc(r.status)}</td><td>{r.blocks}</td>"
                    f"<td>{r.s_words}</td><td>{time}</td><td>{r.warnings}</td>"
                    f"<td>{esc(_planned(r))}</td><td>{esc(note)}</td></tr>")
    counts = {k: sum(r.status == k for r in reports) for k in ("ok", "unchanged", "failed")}
    total = (f"{counts['ok']} rewritten, {counts['unchanged']} unchanged, {counts['failed']} "
             f"failed, of {len(reports)} files; estimated cutting time of the rewritten ones "
             f"{before:.1f} → {after:.1f} min")
    body = (f"<header><h1>ncopt batch report</h1><p class=meta>{esc(base)} · ncopt "
            f"{__version__} · {now_text()}</p></header><section><p>{esc(total)}</p><table>"
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
