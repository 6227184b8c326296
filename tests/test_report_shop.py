"""simulate and report on programs of several tools, and the report a shop reads: the tool
and the control named, the operations left alone listed, fz and vc scaled to their band,
no raw dumps, batch pages that share one plotly.js, a lite page of static images."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from ncopt.cli.app import Exit, app

ROOT = Path(__file__).resolve().parents[1]
CORPUS = ROOT.parent / "shared" / "corpus"
CHESS = CORPUS / "fusion" / "chess_engraved_box.nc"
NOZZLE = CORPUS / "more" / "fusion-generic_Nozzle_OP_A.nc"
BOWL_MPF = ROOT / "samples" / "bowl.mpf"
SPINDLE = ["--accel", "227", "--max-rpm", "15000"]
needs_corpus = pytest.mark.skipif(not CHESS.is_file(), reason="needs ../shared/corpus")


def invoke(args):
    runner = CliRunner(env={"NO_COLOR": "1", "TERM": "dumb", "COLUMNS": "100"})
    result = runner.invoke(app, [str(a) for a in args], catch_exceptions=False)
    assert "Traceback" not in result.stdout + result.stderr
    return result


def two_ball_tools() -> str:
    """Two ball mills, each finishing the same dish z = -8 + 0.01 (x^2 + y^2) mm in parallel
    passes, each named by a Fusion 360 tool comment such as the corpus's
    ``(T3 D=1.5 CR=0.75 - ZMIN=-29.522 - BALL END MILL)``:
    T1 D10 at S4000 F800 (fz 800 / (2 * 4000) = 0.1 mm, vc pi 10 4000 / 1000 = 125.7 m/min),
    T2 D6 at S6000 F900 (fz 0.075 mm, vc pi 6 6000 / 1000 = 113.1 m/min)."""
    lines = ["(T1 D=10 CR=5 - ZMIN=-8 - ball end mill)", "(T2 D=6 CR=3 - ZMIN=-8 - ball end mill)",
             "G90 G94 G17", "G21"]
    for tool, s, f, step in ((1, 4000, 800, 2.0), (2, 6000, 900, 1.2)):
        lines += ["", f"(Parallel{tool})", f"T{tool} M6", f"S{s} M3", "G0 X-20 Y-20 Z10"]
        for k, y in enumerate(np.arange(-20.0, 20.0 + 1e-9, step)):
            xs = np.arange(-20.0, 20.0 + 1e-9, 0.5)[::-1 if k % 2 else 1]
            zs = -8.0 + 0.01 * (xs ** 2 + y ** 2)
            if k == 0:
                lines += [f"G1 Z{zs[0] + 1:.3f} F{f // 2}", f"G1 Z{zs[0]:.3f} F{f}"]
            else:
                lines.append(f"G1 Y{y:.3f} Z{zs[0]:.3f}")
            lines += [f"G1 X{x:.3f} Z{z:.3f}" for x, z in zip(xs, zs)]
        lines.append("G0 Z10")
    return "\n".join(lines + ["M5", "M30"]) + "\n"


@pytest.fixture(scope="module")
def two_tools(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("two") / "two.nc"
    path.write_text(two_ball_tools())
    return path


# ------------------------------------------------------------ simulate: several tools


def test_simulate_replays_each_planned_tool_of_a_program(two_tools):
    result = invoke(["simulate", two_tools, *SPINDLE, "--sample", "0.5"])
    assert result.exit_code == Exit.OK, result.stderr
    heads = [line for line in result.stderr.splitlines() if line.startswith("T")]
    assert heads == [
        "T1: D10 ball, 2 teeth (from line 1: (T1 D=10 CR=5 - ZMIN=-8 - ball end mill); "
        "2 teeth assumed)",
        "T2: D6 ball, 2 teeth (from line 2: (T2 D=6 CR=3 - ZMIN=-8 - ball end mill); "
        "2 teeth assumed)"]
    data = json.loads(invoke(["simulate", two_tools, *SPINDLE, "--sample", "0.5",
                              "--json"]).stdout)
    assert set(data) == {"tools", "left"} and data["left"] == {}
    t1, t2 = data["tools"]["T1"], data["tools"]["T2"]
    # each tool judged against its own S and F at its own diameter (the docstring's figures)
    assert (t1["tool"], t1["fz_target_mm"]) == (1, pytest.approx(0.1))
    assert t1["vc_target_m_min"] == pytest.approx(np.pi * 10 * 4000 / 1000)
    assert (t2["tool"], t2["fz_target_mm"]) == (2, pytest.approx(0.075))
    assert t2["vc_target_m_min"] == pytest.approx(np.pi * 6 * 6000 / 1000)
    # --tool N still picks one, as before: the same figures, the single-program form
    alone = json.loads(invoke(["simulate", two_tools, *SPINDLE, "--sample", "0.5", "--json",
                               "--tool", "2"]).stdout)
    assert alone == t2


def test_simulate_writes_one_file_per_tool(two_tools, tmp_path):
    csv = tmp_path / "s.csv"
    result = invoke(["simulate", two_tools, *SPINDLE, "--sample", "1", "--csv", csv, "-q"])
    assert result.exit_code == Exit.OK, result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.T1.csv", "s.T2.csv"]


@needs_corpus
def test_simulate_a_real_multi_tool_program_lists_the_tools_it_leaves():
    """chess_engraved_box.nc: T1 face mill, T2/T4/T9 flat end mills (their Fusion comments,
    lines 3-7 of the file) and T3 the D1.5 ball of line 5 ``(T3 D=1.5 CR=0.75 - ZMIN=-29.522
    - BALL END MILL)``: today's exit 2 "use --tool N" becomes a T3 section and four lefts."""
    result = invoke(["simulate", CHESS, *SPINDLE, "--sample", "1"])
    assert result.exit_code == Exit.OK, result.stderr
    lines = result.stderr.splitlines()
    assert lines[0] == ("T3: D1.5 ball, 2 teeth (from line 5: (T3 D=1.5 CR=0.75 - "
                        "ZMIN=-29.522 - BALL END MILL); 2 teeth assumed)")
    left = [line for line in lines if "not simulated" in line]
    assert [line.split(":")[0] for line in left] == ["T1", "T2", "T4", "T9"]
    assert left[0] == ("T1: not simulated, left as programmed: not a ball or bull-nose (T1 "
                       "D=100. CR=0. - ZMIN=-0.5 - FACE MILL, line 3); ncopt plans ball and "
                       "bull-nose cutters only")
    assert "FLAT END MILL, line 4" in left[1]


# ------------------------------------------------------------ the report a shop reads

pytest.importorskip("plotly")
pytest.importorskip("matplotlib")

from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from ncopt.report import plots  # noqa: E402

CHROMIUM = Path("/usr/bin/chromium")
needs_chromium = pytest.mark.skipif(not CHROMIUM.exists(), reason="needs chromium")


def figure(html: str, div: str) -> dict:
    """The plotly figure the page draws into ``div``."""
    head = f"ncoptPlot({json.dumps(div)}, "
    start = html.index(head) + len(head)
    return json.JSONDecoder().raw_decode(html[start:])[0]


def visible(html: str) -> str:
    """The page's text outside scripts, styles and the folded figures by name."""
    html = re.sub(r"<script.*?</script>|<style.*?</style>|<details.*?</details>", "", html,
                  flags=re.S)
    return re.sub(r"<[^>]+>", " ", html)


@pytest.fixture(scope="module")
def bowl_page(tmp_path_factory) -> tuple[Path, str]:
    """The README's sample: rewrite samples/bowl.mpf with its mesh, and its report."""
    out = tmp_path_factory.mktemp("bowl")
    page = out / "b.html"
    result = invoke(["rewrite", BOWL_MPF, "--mesh", ROOT / "samples" / "bowl.stl",
                     "--diameter", "16", "--teeth", "2", *SPINDLE, "-o", out / "b.mpf",
                     "--report", page, "-q"])
    assert result.exit_code == Exit.OK, result.stderr
    return page, page.read_text(encoding="utf-8")


def test_the_report_names_the_tool_and_the_control_and_dumps_nothing(bowl_page):
    _, html = bowl_page
    text = visible(html)
    # bowl.mpf: "N100 T04 D01", and a Sinumerik program by its marks (the rewrite says so)
    assert "Along the cut: T4, D16 ball, 2 teeth" in html and "Toolpath: T4" in html
    assert "Siemens Sinumerik (sinumerik): detected from 1 mark" in text
    assert "detected from the program" not in html
    # the mesh's fit in words, never a Python repr or an every-field dump
    assert "T4 fits 100.0 % of the planned cut" in text
    assert "MeshFit(" not in html and "every field" not in html
    assert not re.search(r"\b[A-Z][A-Za-z]+\(\w+=", text), "a Python repr on the page"
    assert "<td>True</td>" not in html and "<td>False</td>" not in html
    # the operations table: the one operation, planned, with its kind and times
    ops = re.search(r"<h2>Operations</h2><table>(.*?)</table>", html).group(1)
    assert "<td class=planned>planned</td>" in ops and "3d surface finishing" in ops


def test_a_single_report_carries_its_own_plotly(bowl_page):
    _, html = bowl_page
    assert "<script src" not in html and "plotly.js v" in html


@pytest.mark.browser
@needs_chromium
def test_the_stamp_line_wraps_instead_of_widening_the_page(bowl_page, tmp_path):
    """The stamp (137 characters in the changed blocks) ran off a 1280 px page."""
    page, html = bowl_page
    assert re.search(r"<td><ins>[;(] ?ncopt", html)  # the stamp is among the changed blocks
    probe = tmp_path / "probe.html"
    probe.write_text(html.replace("</body>", "<script>document.body.setAttribute('data-width',"
                                  " document.documentElement.scrollWidth);</script></body>"),
                     encoding="utf-8")
    dom = chromium_dom(probe, tmp_path)
    width = int(re.search(r'data-width="(\d+)"', dom).group(1))
    assert width <= 1280


def chromium_dom(page: Path, tmp_path: Path) -> str:
    import subprocess

    profile = tmp_path / "profile"
    return subprocess.run(
        [str(CHROMIUM), "--headless", "--no-sandbox", "--disable-gpu",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--no-first-run", f"--user-data-dir={profile}", "--window-size=1280,2000",
         "--virtual-time-budget=20000", "--dump-dom", page.as_uri()],
        capture_output=True, text=True, timeout=180).stdout


def test_the_fz_panel_is_scaled_to_the_band_and_the_plunge_marked(bowl_page):
    """bowl.mpf plunges at the cutting feed, ``N112 Z0.000`` under ``N110 G1 Z3.000 F279``
    (line 19 of the rewrite, after its six stamp lines): a plunge's F is never raised, and the spindle
    already turns at 15000 RPM, so fz = 279 / (2 * 15000) = 0.0093 mm, -91 % of 0.1 mm.
    That one sample must not set the panel's scale: the band does."""
    _, html = bowl_page
    fig = figure(html, "curves-0")
    axes = {fig["layout"][f"yaxis{k if k > 1 else ''}"]["title"]["text"]: k for k in range(1, 6)}
    assert list(axes) == ["S [RPM]", "F [mm/min]", "fz [mm]", "vc [m/min]", "D_eff [mm]"]
    target = fig["layout"]["shapes"][1]["y0"]  # the fz target line (band below, above)
    lo, hi = fig["layout"]["yaxis3"]["range"]
    assert (lo, hi) == (pytest.approx(target * 0.94), pytest.approx(target * 1.06))
    marks = [t for t in fig["data"] if t["mode"] == "markers" and t["yaxis"] == "y3"]
    assert len(marks) == 1 and marks[0]["y"] == [pytest.approx(lo)]
    (hover,) = marks[0]["hovertext"]
    assert hover.startswith("line 19: fz 0.0093 mm (-90.")
    assert 279 / (2 * 15000) == pytest.approx(0.0093, abs=5e-5)
    assert any("vc [m/min]" == t for t in axes) and fig["layout"]["yaxis4"]["range"][1] > 0


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(0.0, 10.0), min_size=1, max_size=400),
       st.floats(0.01, 5.0), st.floats(0.005, 0.1))
def test_a_panel_range_holds_the_band_and_the_bulk(values, target, band):
    v = np.asarray(values)
    lo, hi = plots.panel_range([v], target, band)
    assert lo >= 0.0
    assert lo <= target * (1 - 3 * band) + 1e-12 or lo == 0.0
    assert hi >= target * (1 + 3 * band) - 1e-12
    inside = np.mean((v >= lo - 1e-12) & (v <= hi + 1e-12))
    assert inside >= 1 - 2 * plots.BULK_SHARE - 1.0 / v.size  # all but the ends' shares


def test_one_plunge_does_not_scale_the_printed_fz_panel():
    """The matplotlib figure (print images, lite pages, simulate --plot) scales the same."""
    n = 5000
    fz = np.full(n, 0.1)
    fz[10] = 0.0093  # the plunge
    s = np.full(n, 15000.0)
    series = plots.SimSeries(
        dist_mm=np.arange(n) * 0.1, time_s=np.arange(n) * 0.01, line=np.arange(n) + 1,
        xyz_mm=np.zeros((n, 3)), s_rpm=s, s_cmd_rpm=s, f_mm_min=fz * 2 * s, fz_mm=fz,
        d_eff_mm=np.full(n, 8.0), vc_m_min=np.full(n, 70.0), cutting=np.ones(n, bool))
    report = plots.SimReport("p.nc", 70.0, 0.1, 2.0, 0.1, n, 1.0, 0.0, 0.0, 1.0, 500.0, 99.98,
                             0.0, 1, 90.7, 11, 0.0, 1, 70.0, 15000.0, 1, 1)
    fig = plots.along_path_figure([("p.nc", series, report)])
    fz_ax = fig.axes[plots.ALONG.index("fz_mm")]
    assert fz_ax.get_ylim() == (pytest.approx(0.094), pytest.approx(0.106))
    assert "1 sample beyond the scale: lowest -90.7 % (line 11)" in fz_ax.get_title("right")
    assert fig.axes[plots.ALONG.index("vc_m_min")].get_ylabel() == plots.LABELS["vc_m_min"]
    plots._pyplot().close(fig)


@needs_corpus
def test_the_report_of_a_multi_tool_program(tmp_path):
    """chess_engraved_box.nc (see above): a section for T3, the four other tools and their
    operations listed as left, with the reason; the Fanuc-style post (``%``, ``O1001``,
    ``N10 G90 G94 G17 G49 G40 G80``) named as such."""
    page = tmp_path / "chess.html"
    result = invoke(["report", CHESS, *SPINDLE, "--sample", "0.5", "-o", page])
    assert result.exit_code == Exit.OK, result.stderr
    html = page.read_text(encoding="utf-8")
    text = visible(html)
    assert re.findall(r"<h2>Along the cut: (T\d+)", html) == ["T3"]
    tools = re.search(r"<h2>Tools</h2><table>(.*?)</table>", html).group(1)
    assert re.findall(r"<td class=nowrap>(T\d+)</td><td class=(\w+)>", tools) == [
        ("T3", "planned"), ("T1", "left"), ("T2", "left"), ("T4", "left"), ("T9", "left")]
    assert "a flat end mill (T2 D=5. CR=0. - ZMIN=-10.5 - FLAT END MILL, line 4)" in tools
    ops = re.search(r"<h2>Operations</h2><table>(.*?)</table>", html).group(1)
    assert "<td>FACE2</td><td class=nowrap>T1</td><td class=nowrap>1-35</td>" in ops
    assert "PENCIL2" in ops and "one Z level" in ops  # T3's operation left alone, and why
    assert "Fanuc (fanuc): detected from" in text


@needs_corpus
def test_a_lite_report_is_small_and_has_only_images(tmp_path):
    page = tmp_path / "lite.html"
    result = invoke(["report", NOZZLE, *SPINDLE, "--sample", "0.5", "--report-lite", "-o",
                     page, "-q"])
    assert result.exit_code == Exit.OK, result.stderr
    html = page.read_text(encoding="utf-8")
    assert page.stat().st_size < 1_000_000
    assert "<script" not in html  # no plotly, no drawing code
    images = re.findall(r"<img class=figure alt='' src='data:image/png;base64,", html)
    assert len(images) == 2  # T3's curves and toolpath (T1 is a flat end mill: left)
    assert "Along the cut: T3" in html


@pytest.mark.browser
@needs_corpus
def test_batch_pages_share_one_plotly_file(tmp_path):
    """Three real programs: each page used to embed its own 4.8 MB plotly.js."""
    src = tmp_path / "in"
    (src / "sub").mkdir(parents=True)
    (src / BOWL_MPF.name).symlink_to(BOWL_MPF)
    (src / "sub" / CHESS.name).symlink_to(CHESS)
    (src / "sub" / NOZZLE.name).symlink_to(NOZZLE)
    index = tmp_path / "index.html"
    result = invoke(["batch", src, "-o", tmp_path / "out", *SPINDLE, "--report", index,
                     "--jobs", "2", "-q"])
    assert result.exit_code == Exit.OK, result.stderr
    pages = sorted((tmp_path / "index").rglob("*.html"))
    assert [p.relative_to(tmp_path / "index").as_posix() for p in pages] == [
        "bowl.mpf.html", "sub/chess_engraved_box.nc.html",
        "sub/fusion-generic_Nozzle_OP_A.nc.html"]
    shared = tmp_path / "index" / "plotly.min.js"
    assert shared.read_text(encoding="utf-8").lstrip().startswith("/**\n* plotly.js v")
    for page in pages:
        html = page.read_text(encoding="utf-8")
        (src_attr,) = re.findall(r"<script src='([^']+)'>", html)
        assert (page.parent / src_attr).resolve() == shared.resolve()
        assert "plotly.js v" not in html  # not embedded as well
    total = sum(p.stat().st_size for p in [*pages, shared, index])
    assert total < 10_000_000, f"{total / 1e6:.1f} MB"
    if CHROMIUM.exists():  # the shared file is found and every plot draws
        dom = chromium_dom(pages[1], tmp_path)
        assert len(re.findall(r"data-drawn=\"1\"", dom)) == 2
        assert re.search(r"<pre id=\"ncopt-errors\"[^>]*></pre>", dom)


@pytest.mark.slow
def test_rewrite_and_batch_take_report_lite(tmp_path):
    """--report-lite on rewrite and batch too: pages of static images, no plotly.js."""
    src = tmp_path / "in"
    src.mkdir()
    (src / "bowl.mpf").write_bytes(BOWL_MPF.read_bytes())
    page = tmp_path / "bowl.html"
    result = invoke(["rewrite", src / "bowl.mpf", "--diameter", "16", *SPINDLE,
                     "-o", tmp_path / "bowl_opt.mpf", "--report", page, "--report-lite", "-q"])
    assert result.exit_code == Exit.OK, result.stderr
    html = page.read_text()
    assert "<img" in html and "Plotly" not in html and page.stat().st_size < 1_000_000
    index = tmp_path / "report" / "index.html"
    index.parent.mkdir()
    result = invoke(["batch", src, "-o", tmp_path / "out", "--diameter", "16", *SPINDLE,
                     "--report", index, "--report-lite", "-q"])
    assert result.exit_code == Exit.OK, result.stderr
    pages = [p for p in index.parent.rglob("*.html") if p != index]
    assert pages and all("Plotly" not in p.read_text() for p in pages)
    assert not list(index.parent.rglob("plotly*.js"))  # nothing to share
    assert sum(p.stat().st_size for p in pages) < 1_000_000
