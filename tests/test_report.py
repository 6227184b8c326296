"""The HTML report: what it holds, that it opens offline and draws in a real browser,
and the CLI around it (report, rewrite --report, batch --report, --s-changes)."""

from __future__ import annotations

import re
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

pytest.importorskip("plotly")
pytest.importorskip("matplotlib")

from ncopt.report import html, plots  # noqa: E402
from ncopt.api import rewrite_text  # noqa: E402
from ncopt.model import Job
from ncopt.cli.app import Exit, app  # noqa: E402
from ncopt.model import Cutter, CuttingData, Machine  # noqa: E402

SPINDLE = ["--diameter", "16", "--accel", "227", "--max-rpm", "15000"]
CHROMIUM = next((shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome")
                 if shutil.which(n)), None)


def invoke(args):
    runner = CliRunner(env={"NO_COLOR": "1", "TERM": "dumb", "COLUMNS": "100"})
    result = runner.invoke(app, [str(a) for a in args], catch_exceptions=False)
    assert "Traceback" not in result.stdout + result.stderr
    return result


def passes_program(make_bowl) -> str:
    """Three radial passes over the sample bowl, a retract and a rapid between them."""
    lines = ["; report test", "G21 G90 G94", "T1 M6", "S1393 M3"]
    for y, end in ((0.0, 60.0), (4.0, 72.0), (8.0, 55.0)):
        xs = np.linspace(40.0, end, 12)
        zs = make_bowl.drop_ball_tip_z_mm(xs, np.full_like(xs, y), 8.0)
        lines += [f"G0 X{xs[0]:.3f} Y{y:.3f} Z10", f"G1 Z{zs[0] + 2:.3f} F1000",
                  f"G1 Z{zs[0]:.3f} F279"]
        lines += [f"G1 X{x:.3f} Z{z:.3f}" for x, z in zip(xs[1:], zs[1:])]
        lines.append("G0 Z10")
    return "\n".join(lines + ["M5", "M30"]) + "\n"


@pytest.fixture(scope="module")
def page(make_bowl, bowl_index, tmp_path_factory):
    text = passes_program(make_bowl)
    job = Job(cutter=Cutter(16.0, 2), machine=Machine(227.0, 15000.0),
              cutting=CuttingData(70.0, 0.1))
    result = rewrite_text(text, job, "in.nc", bowl_index)
    data = html.from_rewrite(result, text, "in.nc", "out.nc", job, bowl_index, sample_mm=0.25)
    path = tmp_path_factory.mktemp("report") / "r.html"
    html.write(path, html.render(data))
    return path, data, result


def test_the_page_holds_the_summary_figures(page):
    path, data, result = page
    html = path.read_text(encoding="utf-8")
    (section,) = data.sections
    before, after = (r.report for r in section.runs)
    assert f"{before.cutting_time_min:.1f} → {after.cutting_time_min:.1f} min" in html
    change = 100 * (after.cutting_time_min / before.cutting_time_min - 1)
    assert f"{change:+.1f} %" in html
    assert f"{after.fz_in_band_pct:.2f} %" in html
    s = result.summary
    assert f"between passes: {s.cut_time_other_min:.1f} min cutting" in html
    assert "227 rad/s² (2168 RPM/s), 0-15000 RPM" in html
    assert html.count("<img class=print-only alt='' src='data:image/png;base64,") == 2
    for field in ("s words", "cut time before min", "passes"):  # every summary field
        assert f"<td>{field}</td>" in html
    # the changed blocks: the spindle start's S word, old and new, side by side
    old_s = "<del>S1393</del>"
    assert old_s in html and re.search(r"<ins>S\d+</ins> M3", html)


def test_the_page_needs_nothing_from_the_network(page):
    html = page[0].read_text(encoding="utf-8")
    assert not re.search(r"<(script|link|img)[^>]+(src|href)=['\"]?https?:", html)
    assert "cdn.plot.ly" not in html.split("<script>")[0]


def test_a_program_line_cannot_inject_markup(make_bowl, bowl_index, tmp_path):
    # shown as context of the first change (the spindle start's S word)
    text = passes_program(make_bowl).replace("S1393 M3", "; <script>alert(1)</script>\nS1393 M3")
    job = Job(cutter=Cutter(16.0, 2), machine=Machine(227.0, 15000.0),
              cutting=CuttingData(70.0, 0.1))
    result = rewrite_text(text, job, "x.nc", bowl_index)
    page = html.render(html.from_rewrite(result, text, "x.nc", "<b>y</b>.nc", job,
                                         bowl_index, sample_mm=0.5))
    assert "<script>alert(1)</script>" not in page and "<b>y</b>" not in page
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in page and "&lt;b&gt;y&lt;/b&gt;" in page


@pytest.mark.browser
@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed (.ci/run installs it)")
def test_headless_chromium_draws_every_plot_without_errors(page):
    path = page[0]
    with tempfile.TemporaryDirectory() as profile:
        dom = subprocess.run(
            [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             "--no-first-run", f"--user-data-dir={profile}", "--virtual-time-budget=20000",
             "--dump-dom", path.as_uri()],
            capture_output=True, text=True, timeout=180).stdout
    plots = re.findall(r"<div id=\"(curves|path)-0\"[^>]*>", dom)
    assert sorted(plots) == ["curves", "path"]
    drawn = re.findall(r"<div id=\"(?:curves|path)-0\"[^>]*data-drawn=\"1\"", dom)
    assert len(drawn) == 2, "a plot did not draw"
    assert re.search(r"data-drawn-ms=\"\d+\"", dom)
    assert re.search(r"<pre id=\"ncopt-errors\"[^>]*></pre>", dom), "the page met an error"
    assert dom.count("class=\"main-svg\"") >= 2  # plotly's own SVG layers were built
    assert "gl-container" in dom  # the 3D view got its WebGL canvas


# ------------------------------------------------------------------- the command line


def test_report_command_on_a_program_and_its_original(make_bowl, bowl_stl, tmp_path):
    src, out, page_path = tmp_path / "in.nc", tmp_path / "out.nc", tmp_path / "r.html"
    src.write_text(passes_program(make_bowl))
    assert invoke(["rewrite", src, "--mesh", bowl_stl, *SPINDLE, "-o", out,
                   "-q"]).exit_code == Exit.OK
    result = invoke(["report", out, "--against", src, "--mesh", bowl_stl, *SPINDLE,
                     "--sample", "0.5", "-o", page_path])
    assert result.exit_code == Exit.OK, result.stderr
    assert result.stderr == f"ncopt: report written to {page_path}\n"
    html = page_path.read_text(encoding="utf-8")
    assert "in.nc (original)" in html and "Changed blocks" in html
    assert "Rewrite summary" not in html  # no rewrite here: the programs as they are


def test_rewrite_writes_its_report_and_quiet_says_nothing(make_bowl, bowl_stl, tmp_path):
    src, out, page_path = tmp_path / "in.nc", tmp_path / "out.nc", tmp_path / "r.html"
    src.write_text(passes_program(make_bowl))
    result = invoke(["rewrite", src, "--mesh", bowl_stl, *SPINDLE, "-o", out, "--report",
                     page_path, "-q"])
    assert result.exit_code == Exit.OK and result.stderr == ""
    assert out.exists() and "Rewrite summary" in page_path.read_text(encoding="utf-8")


def test_a_report_into_a_missing_folder_is_refused_before_any_work(make_bowl, tmp_path):
    src, out = tmp_path / "in.nc", tmp_path / "out.nc"
    src.write_text(passes_program(make_bowl))
    target = tmp_path / "nope" / "r.html"
    result = invoke(["rewrite", src, *SPINDLE, "-o", out, "--report", target])
    assert result.exit_code == Exit.IO
    assert result.stderr == f"{target}: the folder to write into does not exist; create it first\n"
    assert not out.exists()


def test_without_plotly_the_report_says_what_to_install(make_bowl, tmp_path, monkeypatch):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "plotly" else real(name, *a))
    src = tmp_path / "in.nc"
    src.write_text(passes_program(make_bowl))
    result = invoke(["report", src, *SPINDLE, "-o", tmp_path / "r.html"])
    assert result.exit_code == Exit.USAGE
    # 'ncopt' on the package index is another project: the hint never names it
    assert result.stderr == ("the HTML report needs plotly: python -m pip install plotly (or, "
                             "in ncopt's source folder, python -m pip install \".[plot]\")\n")


@pytest.mark.slow
def test_batch_writes_an_index_linking_each_files_page(make_bowl, bowl_stl, tmp_path):
    src = tmp_path / "in"
    (src / "sub").mkdir(parents=True)
    (src / "a.nc").write_text(passes_program(make_bowl))
    (src / "sub" / "b.nc").write_text(passes_program(make_bowl))
    (src / "flat.nc").write_text("G21 G90\nT1 M6\nS1000 M3\nG0 X0 Y0 Z5\nG0 Z10\nM30\n")
    index = tmp_path / "index.html"
    result = invoke(["batch", src, "-o", tmp_path / "out", "--mesh", bowl_stl, *SPINDLE,
                     "--report", index, "--jobs", "1"])
    assert result.exit_code == Exit.OK, result.stderr
    html = index.read_text(encoding="utf-8")
    links = re.findall(r"<a href='([^']+)'>([^<]+)</a>", html)
    assert sorted(links) == [("index/a.nc.html", "a.nc"), ("index/sub/b.nc.html", "sub/b.nc")]
    for href, _ in links:
        assert "Changed blocks" in (tmp_path / href).read_text(encoding="utf-8")
    assert "<td>flat.nc</td><td>unchanged</td>" in html  # nothing planned: no page, a row


def test_a_batch_report_may_go_into_the_output_folder_the_batch_creates(make_bowl, tmp_path):
    src, out = tmp_path / "in", tmp_path / "out"
    src.mkdir()
    (src / "a.nc").write_text(passes_program(make_bowl))
    result = invoke(["batch", src, "-o", out, *SPINDLE, "--report", out / "index.html",
                     "--jobs", "1", "-q"])
    assert result.exit_code == Exit.OK, result.stderr
    assert (out / "a.nc").exists() and "a.nc" in (out / "index.html").read_text(encoding="utf-8")
    # any other missing folder is still refused before the work
    result = invoke(["batch", src, "-o", tmp_path / "o2", *SPINDLE,
                     "--report", tmp_path / "nope" / "index.html"])
    assert result.exit_code == Exit.IO and not (tmp_path / "o2").exists()


def test_a_json_batch_report_stays_json(make_bowl, tmp_path):
    src = tmp_path / "in"
    src.mkdir()
    (src / "flat.nc").write_text("G21 G90\nT1 M6\nS1000 M3\nG0 X0 Y0 Z5\nM30\n")
    out = tmp_path / "r.json"
    result = invoke(["batch", src, "-o", tmp_path / "out", *SPINDLE, "--report", out])
    assert result.exit_code == Exit.OK
    assert out.read_text().lstrip().startswith("[")


@pytest.mark.parametrize("value", ["between", "passes"])
def test_a_bad_s_changes_value_is_refused(make_bowl, tmp_path, value):
    src = tmp_path / "in.nc"
    src.write_text(passes_program(make_bowl))
    result = invoke(["rewrite", src, *SPINDLE, "--s-changes", value, "-o", tmp_path / "o.nc"])
    assert result.exit_code == Exit.USAGE
    assert result.stderr == (f"--s-changes must be anywhere or between-passes, not "
                             f"{value!r}\n")


def test_a_machine_profile_sets_where_s_changes(make_bowl, bowl_stl, tmp_path):
    src = tmp_path / "in.nc"
    src.write_text(passes_program(make_bowl))
    profiles = tmp_path / "p.toml"
    profiles.write_text('[machines.m]\naccel_rad_s2 = 227\nmax_rpm = 15000\n'
                        's_changes = "between-passes"\n')
    result = invoke(["rewrite", src, "--mesh", bowl_stl, "--diameter", "16", "--machine", "m",
                     "--tools", profiles, "-o", tmp_path / "o.nc"])
    assert result.exit_code == Exit.OK, result.stderr
    line = next(x for x in result.stderr.splitlines() if "S changes" in x)
    assert line.startswith("ncopt: S changes between passes only (given): one S for each of "
                           "3 passes; with S changing anywhere along the cut: ")


def test_a_constant_colour_gets_a_plain_scale():
    """One S for a whole pass: the colour bar spans 2 % around it, not +-0.4 RPM."""
    lo, hi = plots.colour_range(np.array([1688.0, np.nan, 1688.0]))
    assert hi - lo == pytest.approx(0.02 * 1688.0) and lo < 1688.0 < hi
    assert plots.colour_range(np.array([1000.0, 15000.0])) == (1000.0, 15000.0)
    assert plots.colour_range(np.array([np.nan])) == (0.0, 1.0)
