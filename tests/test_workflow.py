"""The commands around a rewrite, end to end through typer's CliRunner.

``simulate``, ``inspect``, ``diff``, ``profiles`` and ``version`` on the sample bowl and on real
programs of the shared corpus, with exact messages and the exit codes of ``ncopt.cli.app.Exit``.
The user's real config folder never takes part: ``ncopt.planning.profiles.user_file`` points into a
temporary folder and every test runs in an empty working folder.
"""

from __future__ import annotations

import importlib.metadata
import io
import json
import re
import tomllib
import traceback
from pathlib import Path

import numpy as np
import pytest
from rich.cells import cell_len
from rich.console import Console
from typer.testing import CliRunner

import ncopt
from ncopt.cli.app import DIFFERENT, Exit, app
from ncopt.report.diffview import render_side_by_side
from ncopt.reading.parse import parse_text
from ncopt.planning.profiles import EXAMPLES

ROOT = Path(__file__).resolve().parents[1]
CORPUS = Path(__file__).resolve().parents[1].parent / "shared" / "corpus"
BOWL_MPF = ROOT / "samples" / "bowl.mpf"
BOWL_STL = ROOT / "samples" / "bowl.stl"
CHESS = CORPUS / "fusion" / "chess_engraved_box.nc"
FLOWER = CORPUS / "camotics" / "flower_mold.nc"
BAD_DIR = CORPUS / "linuxcnc" / "interp-tests" / "bad"
BAD_PROGRAMS = sorted(BAD_DIR.glob("*.ngc")) if BAD_DIR.is_dir() else []
SPINDLE = ["--accel", "227", "--max-rpm", "15000"]
FAST = ["--sample", "1.0"]
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
SIM_KEYS = {"cutting_time_min", "rapid_time_min", "fz_in_band_pct", "fz_max_over_pct",
            "vc_max_over_pct", "max_rpm", "s_words"}
STAMP = re.compile(r"^\s*[(;]\s*ncopt ")  # a line of the stamp
STAMPED = 6  # stamp lines of a one-operation rewrite: four of header, two of its data


# ------------------------------------------------------------------ helpers ----
def invoke(args, stdin: bytes | None = None, columns: int = 100):
    """Run the app in-process, uncoloured; a crash (not a clean exit) fails the test."""
    runner = CliRunner(env={"NO_COLOR": "1", "TERM": "dumb", "COLUMNS": str(columns)})
    result = runner.invoke(app, [str(a) for a in args], input=stdin)
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        raise AssertionError(
            f"ncopt crashed with exit code {result.exit_code} instead of a clean error:\n"
            + "".join(traceback.format_exception(*result.exc_info, limit=-3)) + result.stderr)
    for stream in (result.stdout, result.stderr):
        assert "\x1b[" not in stream  # nothing rendered with colour
        assert "Traceback" not in stream
    return result


def error_line(result) -> str:
    """The single line a failing command prints on stderr."""
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    return lines[0]


def usage_message(result) -> str:
    """The usage error's text. Such errors concern no file, yet ncopt prefixes them with
    '<input>', its placeholder for an unnamed program (see
    test_usage_errors_do_not_name_a_phantom_input, which fails on that)."""
    line = error_line(result)
    return line.removeprefix("<input>: ")


def flat_raster(passes: int = 4, length: float = 40.0) -> str:
    """A few ball passes on a nearly flat floor (a 2.3 deg slope, so that it is a surface
    finish and not a facing pass): the requirement is the highest spindle speed."""
    lines = ["(flat raster, D16 ball)", "G21 G90", "T4 M6", "S1393 M3", "G0 X0 Y0 Z5",
             "G1 Z0 F279"]
    xs = np.arange(0.0, length + 0.5, 1.0)
    for i in range(passes):
        for x in (xs if i % 2 == 0 else xs[::-1]):
            lines.append(f"X{x:.3f} Y{i * 1.6:.3f} Z{0.04 * x:.3f}")
    return "\n".join(lines + ["G0 Z5", "M5", "M30"]) + "\n"


def highest_s(result) -> int:
    found = [re.search(r"highest S (\d+) RPM", line) for line in result.stderr.splitlines()]
    found = [m for m in found if m]
    assert len(found) == 1, result.stderr
    return int(found[0][1])


def strip_sf(line: str) -> str:
    """A bowl line without its S and F words (the sample's words are plain numbers)."""
    return re.sub(r"\s*[SF]-?\d+\.?\d*", "", line)


def apply_unified(a_lines: list[str], diff_lines: list[str]) -> list[str]:
    """Apply a unified diff to a's lines (an independent check of what diff printed)."""
    out, i, k = [], 0, 2
    while k < len(diff_lines):
        m = re.fullmatch(r"@@ -(\d+)(?:,(\d+))? \+(\d+)(?:,(\d+))? @@", diff_lines[k])
        assert m, diff_lines[k]
        start, count = int(m[1]), int(m[2]) if m[2] is not None else 1
        src = start - 1 if count else start
        assert src >= i
        out += a_lines[i:src]
        i, k = src, k + 1
        while k < len(diff_lines) and not diff_lines[k].startswith("@@ "):
            tag, text = diff_lines[k][:1], diff_lines[k][1:]
            assert tag in (" ", "-", "+"), diff_lines[k]
            if tag != "+":
                assert a_lines[i] == text, (i, text)
                i += 1
            if tag != "-":
                out.append(text)
            k += 1
    return out + a_lines[i:]


def table_row(text: str, first_cell: str) -> list[str]:
    """The cells of the rich table row whose first cell is ``first_cell``."""
    for line in text.splitlines():
        cells = [c.strip() for c in line.split("│")[1:-1]]
        if cells and cells[0] == first_cell:
            return cells
    raise AssertionError(f"no row {first_cell!r} in:\n{text}")


# ------------------------------------------------------------------ fixtures ----
@pytest.fixture(scope="module", autouse=True)
def isolated(tmp_path_factory):
    """No user config and no ./ncopt.toml take part in this module's module fixtures."""
    home = tmp_path_factory.mktemp("workflow-home")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr("ncopt.planning.profiles.user_file", lambda: home / "config" / "ncopt.toml")
        mp.chdir(home)
        yield home


@pytest.fixture(autouse=True)
def user_toml(monkeypatch, tmp_path) -> Path:
    """The user's profile file of this test (absent unless a test writes it)."""
    path = tmp_path / "user-config" / "ncopt" / "ncopt.toml"
    monkeypatch.setattr("ncopt.planning.profiles.user_file", lambda: path)
    return path


@pytest.fixture(scope="module")
def bowl_opt(isolated, tmp_path_factory):
    """The sample bowl rewritten with the shipped profiles (machine, cutter, material)."""
    out = tmp_path_factory.mktemp("workflow-rewrite") / "bowl_opt.mpf"
    result = invoke(["rewrite", BOWL_MPF, "--machine", "paper-direct-15000", "--cutter",
                     "paper-d16", "--material", "1.4462", "-o", out])
    return result, out


@pytest.fixture
def flat(tmp_path) -> Path:
    path = tmp_path / "flat.nc"
    path.write_text(flat_raster())
    return path


def bowl_lines() -> list[str]:
    return BOWL_MPF.read_bytes().decode("latin-1").splitlines()


# ------------------------------------------------------------------ simulate ----
def test_simulate_prints_a_summary_that_agrees_with_its_json():
    text = invoke(["simulate", BOWL_MPF, *FAST, *SPINDLE])
    assert text.exit_code == Exit.OK, text.stderr
    assert text.stdout == ""  # the summary goes to stderr
    data = json.loads(invoke(["simulate", BOWL_MPF, *FAST, *SPINDLE, "--json"]).stdout)
    first, second, third = text.stderr.splitlines()
    assert first == (f"{BOWL_MPF}: feed moves {data['feed_moves_time_min']:.2f} min "
                     f"({data['cutting_time_min']:.2f} min cutting), rapids "
                     f"{data['rapid_time_min']:.2f} min, total {data['total_time_min']:.2f} "
                     "min; highest S 1393 RPM (line 10)")
    assert second.startswith(f"  fz within +-2 % of {data['fz_target_mm']:.4f} mm on "
                             f"{data['fz_in_band_pct']:.2f} % of the cut; most above "
                             f"{data['fz_max_over_pct']:+.2f} % (line ")
    assert third.startswith(f"  vc at most {data['vc_max_over_pct']:+.2f} % of its target "
                            "70.0 m/min (line ")
    assert third.endswith("; 1 S word")


@pytest.mark.parametrize("with_mesh", [False, True], ids=["toolpath", "mesh"])
def test_simulate_json_of_the_sample_bowl(with_mesh):
    mesh = ["--mesh", BOWL_STL] if with_mesh else []
    result = invoke(["simulate", BOWL_MPF, *FAST, *SPINDLE, *mesh, "--json"])
    assert result.exit_code == Exit.OK, result.stderr
    assert result.stderr == ""
    data = json.loads(result.stdout)
    assert SIM_KEYS <= set(data)
    assert data["path"] == str(BOWL_MPF)
    # the README's results table: original program, 59.30 min, fz 100 % in band, one S word
    assert data["cutting_time_min"] == pytest.approx(59.30, abs=0.1)
    assert 0 <= data["rapid_time_min"] < 0.1
    assert data["fz_in_band_pct"] == pytest.approx(100.0)
    assert abs(data["fz_max_over_pct"]) < 0.2
    assert data["max_rpm"] == 1393 and data["s_words"] == 1
    if with_mesh:  # "-17.5 % (far below on the flat bottom)"
        assert data["vc_max_over_pct"] == pytest.approx(-17.5, abs=0.1)
    else:
        assert -18.0 < data["vc_max_over_pct"] < -17.0


def test_simulate_csv_series(tmp_path):
    csv = tmp_path / "series.csv"
    result = invoke(["simulate", BOWL_MPF, *FAST, *SPINDLE, "--csv", csv, "--json"])
    assert result.exit_code == Exit.OK, result.stderr
    data = json.loads(result.stdout)
    rows = csv.read_text().splitlines()
    assert rows[0] == ("dist_mm,time_s,line,x_mm,y_mm,z_mm,s_rpm,s_cmd_rpm,f_mm_min,fz_mm,"
                       "d_eff_mm,vc_m_min,cutting")
    assert len(rows) - 1 == data["samples"] > 16000  # one row per sample, >= 1 per mm of cut
    table = np.genfromtxt(csv, delimiter=",", skip_header=1)
    assert table.shape == (data["samples"], 13)
    assert set(np.unique(table[:, 12])) <= {0.0, 1.0}
    assert table[:, 2].min() >= 1 and table[:, 2].max() <= len(bowl_lines())
    assert np.all(np.diff(table[:, 0]) >= 0) and np.all(np.diff(table[:, 1]) >= 0)
    assert np.nanmax(table[:, 6]) == pytest.approx(1393)


@pytest.mark.slow
@pytest.mark.parametrize("along, toolpath", [("png", "svg"), ("svg", "png")])
def test_simulate_plots(tmp_path, along, toolpath):
    plot, path_plot = tmp_path / f"along.{along}", tmp_path / f"toolpath.{toolpath}"
    result = invoke(["simulate", BOWL_MPF, *FAST, *SPINDLE, "--plot", plot, "--plot-toolpath",
                     path_plot, "--color-by", "f_mm_min" if toolpath == "svg" else "d_eff_mm"])
    assert result.exit_code == Exit.OK, result.stderr
    for path in (plot, path_plot):
        data = path.read_bytes()
        if path.suffix == ".png":
            assert data.startswith(PNG_MAGIC)
        else:
            assert b"<svg" in data[:5000]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([plot.name, path_plot.name])


def test_simulate_against_the_original(bowl_opt):
    _, opt = bowl_opt
    result = invoke(["simulate", opt, "--against", BOWL_MPF, *FAST, *SPINDLE, "--json"])
    assert result.exit_code == Exit.OK, result.stderr
    data = json.loads(result.stdout)
    assert list(data) == [str(BOWL_MPF), str(opt)]
    before, after = data[str(BOWL_MPF)], data[str(opt)]
    assert SIM_KEYS <= set(before) and SIM_KEYS <= set(after)
    # one target for both: the first program's (S1393 F279 with D16 z2)
    assert after["vc_target_m_min"] == before["vc_target_m_min"]
    assert after["fz_target_mm"] == before["fz_target_mm"]
    assert before["s_words"] == 1 and after["s_words"] > 10000
    assert after["max_rpm"] == 15000
    # README: 59.3 -> 28.6 min (-51.7 %)
    assert after["cutting_time_min"] == pytest.approx(28.7, abs=0.5)
    # the text form names both programs, the original first
    text = invoke(["simulate", opt, "--against", BOWL_MPF, *FAST, *SPINDLE])
    heads = [line for line in text.stderr.splitlines() if not line.startswith("  ")]
    assert [h.split(": feed moves ")[0] for h in heads] == [str(BOWL_MPF), str(opt)]


def test_simulate_missing_program(tmp_path):
    missing = tmp_path / "nope.mpf"
    for args in (["simulate", missing], ["simulate", BOWL_MPF, "--against", missing]):
        result = invoke([*args, *FAST, *SPINDLE])
        assert result.exit_code == Exit.IO
        assert result.stderr == (f"{missing}: cannot read the file: No such file or "
                                 "directory; check the path\n")
        assert result.stdout == ""


def test_simulate_missing_mesh(tmp_path):
    mesh = tmp_path / "none.stl"
    result = invoke(["simulate", BOWL_MPF, *FAST, *SPINDLE, "--mesh", mesh])
    assert result.exit_code == Exit.MESH
    assert result.stderr == f"{mesh}: no such file; check the mesh path\n"


def test_simulate_bad_option_values():
    result = invoke(["simulate", BOWL_MPF, *SPINDLE, "--sample", "abc"])
    assert result.exit_code == Exit.USAGE
    assert "Invalid value for '--sample'" in result.stderr
    result = invoke(["simulate", BOWL_MPF, *SPINDLE, "--sample", "0"])
    assert result.exit_code == Exit.USAGE
    assert error_line(result) == f"{BOWL_MPF}: sample spacing must be positive, got 0.0"
    result = invoke(["simulate", BOWL_MPF, *FAST, "--accel", "0", "--max-rpm", "15000"])
    assert result.exit_code == Exit.USAGE
    assert usage_message(result) == "--diameter, --teeth, --accel and --max-rpm must be positive"


def test_simulate_unknown_color_by_is_a_usage_error(tmp_path):
    """--color-by takes s_rpm, f_mm_min, d_eff_mm or vc_m_min; anything else is wrong usage
    (today: AttributeError traceback, exit 1, after the whole simulation)."""
    plot = tmp_path / "t.png"
    result = invoke(["simulate", BOWL_MPF, *FAST, *SPINDLE, "--plot-toolpath", plot,
                     "--color-by", "nope"])
    assert result.exit_code == Exit.USAGE
    line = usage_message(result)
    assert "--color-by" in line and "'nope'" in line
    assert not plot.exists()


@pytest.mark.parametrize("option, name", [("--csv", "s.csv"), ("--plot", "p.png"),
                                          ("--plot-toolpath", "t.png")])
def test_simulate_output_in_a_missing_folder_is_an_io_error(tmp_path, option, name):
    """README: exit 7 when a file cannot be written (today: a traceback and exit 1)."""
    target = tmp_path / "no" / "such" / "folder" / name
    result = invoke(["simulate", BOWL_MPF, *FAST, *SPINDLE, option, target])
    assert result.exit_code == Exit.IO
    assert error_line(result).startswith(f"{target}: ")


# ------------------------------------------------------------------- inspect ----
def test_inspect_the_sample_bowl():
    result = invoke(["inspect", BOWL_MPF])
    assert result.exit_code == Exit.OK, result.stderr
    lines = result.stdout.splitlines()
    info = json.loads(invoke(["inspect", BOWL_MPF, "--json"]).stdout)
    assert lines == [
        f"{BOWL_MPF}: sinumerik dialect (1 mark), mm, 21902 lines",
        f"  blocks {info['blocks']}, moves {info['moves']} (feed {info['feed_moves']}, rapid "
        f"{info['rapids']}, arcs 0), not plannable {info['unknown_moves']} (line 10)",
        "  tool T4: ball D16 r8 mm, 2 teeth (line 4, free text)",
        "  tools cutting: T4",
        "  S 1393..1393 RPM, F 279..279 mm/min",
        f"  cutting {info['cut_length_mm']:.0f} mm in 59.3 min at the programmed feed",
        "  operations: 1 of 1 operation would be planned (times at the programmed feed):",
        "    T4 (T4, lines 1-21902): planned, 3d surface finishing, 59.3 min",
        f"  warning: {BOWL_MPF}: no G20/G21 in the program: ncopt reads it in mm, as a control "
        "does that starts in metric; add G21 (or G20) to say which",
    ]


def test_inspect_json():
    result = invoke(["inspect", BOWL_MPF, "--json"])
    assert result.exit_code == Exit.OK and result.stderr == ""
    info = json.loads(result.stdout)
    assert set(info) == {"path", "dialect", "dialect_marks", "units", "lines", "blocks",
                         "moves", "feed_moves", "rapids", "arcs", "unknown_moves", "tools",
                         "tools_used", "opaque", "warnings", "s_range_rpm", "f_range_mm_min",
                         "cut_length_mm", "cut_time_min", "kinematics", "tilt_range_deg",
                         "unknown_lines", "operations", "operations_not_judged"}
    assert info["kinematics"] is None and info["tilt_range_deg"] == [0.0, 0.0]  # 3 axes
    assert info["path"] == str(BOWL_MPF)
    assert (info["dialect"], info["units"], info["lines"]) == ("sinumerik", "mm", 21902)
    assert info["dialect_marks"]  # why the dialect was chosen
    # T, kind, D, r, line, teeth and their line ("z 2" in the comment), unit (None: the
    # program's), which format read it
    assert info["tools"] == [[4, "ball", 16.0, 8.0, 4, 2, 4, None, "free text"]]
    assert info["tools_used"] == [4]
    assert info["s_range_rpm"] == [1393.0, 1393.0]
    assert info["f_range_mm_min"] == [279.0, 279.0]
    assert info["arcs"] == 0 and info["rapids"] == 2
    assert info["feed_moves"] <= info["moves"] <= info["blocks"] <= info["lines"]
    assert info["cut_time_min"] == pytest.approx(info["cut_length_mm"] / 279.0)
    assert info["cut_time_min"] == pytest.approx(59.3, abs=0.1)


def test_inspect_a_fusion_program():
    result = invoke(["inspect", CHESS])
    assert result.exit_code == Exit.OK, result.stderr
    lines = result.stdout.splitlines()
    assert lines[0] == f"{CHESS}: fanuc dialect (3 marks), mm, 35211 lines"
    for tool in ("T1: other D100 r0 mm, teeth not given (line 3,",
                 "T2: flat D5 r0 mm, teeth not given (line 4,",
                 "T3: ball D1.5 r0.75 mm, teeth not given (line 5,",
                 "T4: flat D10 r0 mm, teeth not given (line 6,",
                 "T9: flat D3 r0 mm, teeth not given (line 7,",
                 "T11: other D8 r0 mm, teeth not given (line 8,"):
        assert f"  tool {tool} Fusion 360)" in lines
    assert "  tools cutting: T1, T2, T3, T4, T9" in lines
    info = json.loads(invoke(["inspect", CHESS, "--json"]).stdout)
    assert info["arcs"] > 1000 and info["units"] == "mm" and info["dialect"] == "fanuc"
    assert info["tools_used"] == [1, 2, 3, 4, 9]


def test_inspect_an_inch_program():
    result = invoke(["inspect", FLOWER])
    assert result.exit_code == Exit.OK, result.stderr
    assert result.stdout.splitlines()[0] == f"{FLOWER}: generic dialect (0 marks), inch, 16562 lines"
    info = json.loads(invoke(["inspect", FLOWER, "--json"]).stdout)
    assert info["units"] == "inch"
    assert info["f_range_mm_min"][1] == pytest.approx(20 * 25.4)  # F20 in/min, shown in mm


def test_inspect_does_not_call_an_unnumbered_tool_t_minus_1():
    """A program without T words: the rewrite summary says 'tool' and the error messages
    'the tool (the program names none)'; inspect prints an internal placeholder 'T-1'."""
    result = invoke(["inspect", FLOWER])
    assert result.exit_code == Exit.OK
    assert "T-1" not in result.stdout, result.stdout


def test_inspect_a_malformed_program(tmp_path):
    bad = tmp_path / "open.ngc"
    bad.write_bytes(b"G21 G90\nS1000 M3\nG1 X1 Y1 Z0 F100 (this comment never ends\nM30\n")
    result = invoke(["inspect", bad])
    assert result.exit_code == Exit.PROGRAM
    assert result.stdout == ""
    first, *context = result.stderr.splitlines()
    assert first == (f"{bad}:3:18: unbalanced comment parentheses; close every '(' with ')' "
                     "on the same line")
    assert context == ["    G1 X1 Y1 Z0 F100 (this comment never ends",
                       "    " + " " * 17 + "^"]
    assert invoke(["inspect", bad, "--json"]).exit_code == Exit.PROGRAM


@pytest.mark.parametrize("path", BAD_PROGRAMS, ids=lambda p: p.name)
def test_inspect_linuxcnc_bad_programs_fail_located(path):
    result = invoke(["inspect", path])
    assert result.exit_code == Exit.PROGRAM
    assert result.stdout == ""
    first = result.stderr.splitlines()[0]
    m = re.fullmatch(re.escape(str(path)) + r":(\d+):(\d+): (\S.*)", first)
    assert m, first
    n_lines = len(path.read_bytes().splitlines())
    # line 1 of these files is a comment with rs274's expected error
    assert 2 <= int(m[1]) <= n_lines
    assert int(m[2]) >= 1


def test_inspect_a_linuxcnc_bad_program_exact_message():
    path = BAD_DIR / "no-ijr.ngc"
    result = invoke(["inspect", path])
    assert result.exit_code == Exit.PROGRAM
    assert result.stderr == (f"{path}:2:1: arc with none of I, J, K or R; give the centre or "
                             "the radius\n")


def test_inspect_missing_file(tmp_path):
    result = invoke(["inspect", tmp_path / "nope.nc"])
    assert result.exit_code == Exit.IO
    assert result.stderr == (f"{tmp_path / 'nope.nc'}: cannot read the file: No such file or "
                             "directory; check the path\n")


# ---------------------------------------------------------------------- diff ----
def test_diff_identical_files(tmp_path):
    copy = tmp_path / "copy.mpf"
    copy.write_bytes(BOWL_MPF.read_bytes())
    for extra in ([], ["--plain"]):
        result = invoke(["diff", BOWL_MPF, copy, *extra])
        assert result.exit_code == Exit.OK
        assert result.stdout == "" and result.stderr == ""


def test_diff_of_a_rewrite_is_a_unified_diff_of_s_and_f_words(bowl_opt):
    _, opt = bowl_opt
    result = invoke(["diff", BOWL_MPF, opt])
    assert result.exit_code == DIFFERENT and result.stderr == ""  # as diff(1): they differ
    out = result.stdout.splitlines()
    assert out[:2] == [f"--- {BOWL_MPF}", f"+++ {opt}"]
    a = bowl_lines()
    b = opt.read_bytes().decode("latin-1").splitlines()
    assert apply_unified(a, out) == b  # the diff is complete and correct
    # every hunk pairs removed and added lines one for one, differing in S and F only;
    # the lines added on their own are the stamp's
    hunks, added_alone = [], []
    for line in out[2:]:
        if line.startswith("@@ "):
            hunks.append(([], []))
        elif line[:1] in "-+":
            hunks[-1][line[:1] == "+"].append(line[1:])
    changed = 0
    for minus, plus in hunks:
        stamps = [p for p in plus if STAMP.match(p)]
        added_alone += stamps
        plus = [p for p in plus if not STAMP.match(p)]
        assert len(minus) == len(plus)
        for x, y in zip(minus, plus):
            assert x != y and strip_sf(x) == strip_sf(y), (x, y)
        changed += len(minus)
    assert added_alone == b[:STAMPED]
    assert changed > 15000


def test_diff_plain_is_the_default_when_not_a_terminal(bowl_opt):
    _, opt = bowl_opt
    default = invoke(["diff", BOWL_MPF, opt])
    plain = invoke(["diff", BOWL_MPF, opt, "--plain"])
    assert plain.exit_code == default.exit_code == DIFFERENT
    assert plain.stdout == default.stdout and plain.stdout.startswith("--- ")


def test_diff_missing_file(tmp_path):
    result = invoke(["diff", BOWL_MPF, tmp_path / "none.mpf"])
    assert result.exit_code == Exit.IO
    assert result.stderr == (f"{tmp_path / 'none.mpf'}: cannot read the file: No such file or "
                             "directory; check the path\n")


def side_by_side(a, b, a_name="bowl.mpf", b_name="bowl_opt.mpf"):
    buffer = io.StringIO()
    console = Console(file=buffer, width=100, color_system=None, force_terminal=True)
    totals = render_side_by_side(a_name, b_name, a, b, console)
    text = buffer.getvalue()
    assert "\x1b[" not in text
    return totals, text.splitlines()


FOLD = re.compile(r"^  ··· (\d+) unchanged lines? ···$")


def parse_rows(lines):
    """(folded counts, rows (left number or None, left text, separator, right text))."""
    folds, rows = [], []
    for line in lines:
        if m := FOLD.match(line):
            folds.append(int(m[1]))
            continue
        m = re.fullmatch(r"([ \d]{6}) (.*?) ([│┃]) (.*)", line)
        assert m, line
        rows.append((int(m[1]) if m[1].strip() else None, m[2].rstrip(), m[3], m[4].rstrip()))
    return folds, rows


def test_side_by_side_folds_unchanged_runs_with_line_numbers(bowl_opt):
    """Two programs with the same lines (the rewrite without its stamp)."""
    _, opt = bowl_opt
    a = bowl_lines()[:400]
    b = opt.read_bytes().decode("latin-1").splitlines()[STAMPED:STAMPED + 400]
    totals, lines = side_by_side(a, b)
    assert max(cell_len(line) for line in lines) <= 100
    changed = [i + 1 for i in range(400) if a[i] != b[i]]
    s = sum(re.findall(r"S\d+", x) != re.findall(r"S\d+", y) for x, y in zip(a, b))
    f = sum(re.findall(r"F[\d.]+", x) != re.findall(r"F[\d.]+", y) for x, y in zip(a, b))
    assert lines[0] == (f"bowl.mpf -> bowl_opt.mpf: {len(changed)} of 400 lines changed "
                        f"(S in {s}, F in {f})")
    assert (totals.changed, totals.s_changed, totals.f_changed) == (len(changed), s, f)
    folds, rows = parse_rows(lines[1:])
    assert folds and all(n > 0 for n in folds)
    numbers = [r[0] for r in rows]
    assert numbers == sorted(set(numbers)) and None not in numbers
    assert sum(folds) + len(rows) == 400  # every line is shown or counted in a fold
    assert set(changed) <= set(numbers)
    for n, left, sep, right in rows:
        assert left == a[n - 1] and right == b[n - 1]
        assert sep == ("┃" if a[n - 1] != b[n - 1] else "│")


def test_side_by_side_of_a_rewrite_with_its_stamp(bowl_opt):
    _, opt = bowl_opt
    a = bowl_lines()[:400]
    b = opt.read_bytes().decode("latin-1").splitlines()[:STAMPED + 400]
    _, lines = side_by_side(a, b)
    assert max(cell_len(line) for line in lines) <= 100
    folds, rows = parse_rows(lines[1:])
    # the stamp first, added lines: no number on the left, cut to the column on the right
    for k, (n, left, sep, right) in enumerate(rows[:STAMPED]):
        assert (n, left, sep) == (None, "", "┃")
        assert right == b[k] or (right.endswith("…") and b[k].startswith(right[:-1]))
    numbers = [r[0] for r in rows[STAMPED:]]
    assert None not in numbers and numbers == sorted(set(numbers))
    assert sum(folds) + len(numbers) == 400
    for n, left, sep, right in rows[STAMPED:]:  # the original's own line numbers
        assert left == a[n - 1] and right == b[n - 1 + STAMPED]
    assert any(FOLD.match(line) for line in lines)


def test_side_by_side_header_counts_the_changed_lines_of_a_rewrite(bowl_opt):
    """The header counts the changed lines on the pairing it shows: the stamp's lines and
    the rewritten ones (most others are folded as unchanged)."""
    _, opt = bowl_opt
    a = bowl_lines()[:400]
    b = opt.read_bytes().decode("latin-1").splitlines()[:STAMPED + 400]
    totals, lines = side_by_side(a, b)
    changed = STAMPED + sum(x != y for x, y in zip(a, b[STAMPED:]))
    assert changed < len(b)  # some lines are folded as unchanged
    assert totals.changed == changed, lines[0]
    assert lines[0].startswith(f"bowl.mpf -> bowl_opt.mpf: {changed} of ")


def test_side_by_side_keeps_long_lines_and_names_within_the_width():
    a = ["G21 G90", "G1 X1 (" + "very long comment " * 20 + ")", "G1 X2 F100", "M30"]
    b = ["G21 G90", "G1 X1 (" + "very long comment " * 20 + ") S2000", "G1 X2 F200", "M30"]
    name = "/a/very/long/folder/name/" * 6 + "part.nc"
    _, lines = side_by_side(a, b, name, name + ".opt")
    assert max(cell_len(line) for line in lines) <= 100
    assert "".join(lines[:3]).startswith(name[:60])
    body = [ln for ln in lines if FOLD.match(ln) or re.match(r"[ \d]{6} .* [│┃] ", ln)]
    folds, rows = parse_rows(body)
    assert [r[0] for r in rows if r[2] == "┃"] == [2, 3]


# ------------------------------------------------------------------ profiles ----
def test_profiles_lists_the_shipped_machines(user_toml):
    result = invoke(["profiles"], columns=300)
    assert result.exit_code == Exit.OK, result.stderr
    lines = result.stdout.splitlines()
    assert lines[0] == (f"profile files, later ones win (user file: {user_toml}; project file: "
                        "the nearest ncopt.toml from here up):")
    assert lines[1] == f"  {EXAMPLES}" and not lines[2].startswith("  /")
    assert table_row(result.stdout, "paper-direct-15000") == [
        "paper-direct-15000", "227", "15000", "sinumerik", str(EXAMPLES)]
    assert table_row(result.stdout, "paper-geared-4000")[1:3] == ["131", "4000"]
    assert table_row(result.stdout, "paper-direct-40000")[1:3] == ["751", "40000"]
    assert table_row(result.stdout, "paper-d16")[1] == "D16 ball, 2 teeth"
    assert table_row(result.stdout, "1.4462")[1:3] == ["70", "0.1"]
    assert "default machine" not in result.stdout


SHOP = """\
default_machine = "shop"
[machines.shop]
accel_rad_s2 = 227
max_rpm = {shop}
[machines.paper-direct-15000]
accel_rad_s2 = 227
max_rpm = {paper}
control = "{control}"
"""


def write_profiles(path: Path, shop: int, paper: int, control: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(SHOP.format(shop=shop, paper=paper, control=control))
    return path


def test_user_project_and_tools_files_apply_in_order(tmp_path, monkeypatch, user_toml):
    project = tmp_path / "project"
    project.mkdir()
    monkeypatch.chdir(project)
    write_profiles(user_toml, 3000, 3500, "fanuc")
    listing = invoke(["profiles"], columns=300)
    assert listing.exit_code == Exit.OK, listing.stderr
    assert table_row(listing.stdout, "paper-direct-15000") == [
        "paper-direct-15000", "227", "3500", "fanuc", str(user_toml)]
    assert f"default machine: shop ({user_toml})" in listing.stdout.splitlines()

    local = write_profiles(Path.cwd() / "ncopt.toml", 2000, 2500, "linuxcnc")
    listing = invoke(["profiles"], columns=300)
    assert [ln for ln in listing.stdout.splitlines() if ln.startswith("  /")] == [
        f"  {EXAMPLES}", f"  {user_toml}", f"  {local}"]
    assert table_row(listing.stdout, "paper-direct-15000") == [
        "paper-direct-15000", "227", "2500", "linuxcnc", str(local)]
    assert table_row(listing.stdout, "shop")[2:] == ["2000", "detected", str(local)]
    assert f"default machine: shop ({local})" in listing.stdout.splitlines()

    tools = write_profiles(tmp_path / "elsewhere" / "mine.toml", 2200, 2300, "grbl")
    listing = invoke(["profiles", "--tools", tools], columns=300)
    assert listing.exit_code == Exit.OK, listing.stderr
    assert [ln for ln in listing.stdout.splitlines() if ln.startswith("  /")][-1] == f"  {tools}"
    assert table_row(listing.stdout, "paper-direct-15000")[2:] == ["2300", "grbl", str(tools)]
    # profile entries only they define stay (paper-d16 from the examples)
    assert table_row(listing.stdout, "paper-d16")[2] == str(EXAMPLES)


def test_the_winning_profile_drives_the_rewrite(tmp_path, monkeypatch, user_toml, flat):
    project = tmp_path / "project"
    project.mkdir()
    monkeypatch.chdir(project)
    write_profiles(user_toml, 3000, 3500, "fanuc")
    write_profiles(project / "ncopt.toml", 2000, 2500, "linuxcnc")
    tools = write_profiles(tmp_path / "mine.toml", 2200, 2300, "grbl")
    # S anywhere along the cut whatever the control: the raster's opening plunge ends below
    # the top of its cut, so its contact is unknown and planned at the full diameter
    # (S1393); between passes only, grbl's default, that S would hold the one pass
    base = ["rewrite", flat, "--cutter", "paper-d16", "-o", tmp_path / "out.nc",
            "--s-changes", "anywhere"]
    cases = [([], 2000),  # default_machine "shop" of the project file
             (["--machine", "paper-direct-15000"], 2500),  # the project file beats user, shipped
             (["--machine", "paper-direct-15000", "--tools", tools], 2300),  # --tools wins
             (["--machine", "paper-direct-15000", "--tools", tools, "--max-rpm", "1800"], 1800)]
    for extra, expected in cases:
        result = invoke([*base, *extra])
        assert result.exit_code == Exit.OK, (extra, result.stderr)
        # the profile's top speed, or a fall from it by less than one --min-rpm-step
        assert expected - 10 < highest_s(result) <= expected, (extra, result.stderr)


def test_rewrite_with_the_shipped_profiles(bowl_opt):
    result, out = bowl_opt
    assert result.exit_code == Exit.OK, result.stderr
    lines = result.stderr.splitlines()
    assert "ncopt: T4: D16 ball, 2 teeth (from the options)" in lines
    assert "ncopt: vc 70.0 m/min, fz 0.1000 mm, highest S 15000 RPM" in lines
    assert any(line.startswith("ncopt: sinumerik control: ") for line in lines)
    text = out.read_bytes().decode("latin-1")
    assert re.match(r"; ncopt \S+ \d{4}-\d\d-\d\d: S and F for constant vc and fz\n"
                    r"; ncopt from bowl.mpf\n"
                    r"; ncopt machine paper-direct-15000: 227 rad/s2, 15000 RPM\n"
                    r"; ncopt cutting time 59\.3 -> \d+\.\d min, estimated\n"
                    r"; ncopt T4 lines=1-21902 vc=70\.0+ fz=0\.10+ band=2\n"
                    r"; ncopt T4 D=16mm r=8mm z=2 S0=1393 F0=279mm/min\n", text)
    prog = parse_text(text)
    s = prog.word_value[prog.word_letter == ord("S")]
    assert s.max() == 15000 and s.size > 10000


@pytest.mark.parametrize("option, message", [
    (["--machine", "nope"], "no machine profile 'nope' (known: paper-direct-15000, "
                            "paper-direct-40000, paper-geared-4000); see ncopt profiles"),
    (["--cutter", "nope", *SPINDLE], "no tool 'nope' in the profiles; see ncopt profiles"),
    (["--material", "nope", "--diameter", "16", *SPINDLE],
     "no cutting data for 'nope' (known: 1.4462); see ncopt profiles"),
], ids=["machine", "cutter", "material"])
def test_unknown_profile_names(tmp_path, flat, option, message):
    out = tmp_path / "out.nc"
    result = invoke(["rewrite", flat, *option, "-o", out])
    assert result.exit_code == Exit.USAGE
    assert usage_message(result) == message
    assert not out.exists()


@pytest.mark.parametrize("where", ["--tools", "project"])
def test_broken_toml_names_the_file(tmp_path, monkeypatch, flat, where):
    monkeypatch.chdir(tmp_path)
    broken = "[machines.shop]\naccel_rad_s2 = 227\nmax_rpm = [\n"
    with pytest.raises(tomllib.TOMLDecodeError) as exc:
        tomllib.loads(broken)
    path = (tmp_path / "mine.toml") if where == "--tools" else Path.cwd() / "ncopt.toml"
    path.write_text(broken)
    extra = ["--tools", path] if where == "--tools" else []
    for args in (["profiles", *extra], ["rewrite", flat, *SPINDLE, "--diameter", "16", *extra]):
        result = invoke(args)
        assert result.exit_code == Exit.USAGE
        assert result.stderr == f"{path}: cannot read the profile: {exc.value}; fix the TOML\n"


def test_missing_tools_file(tmp_path):
    result = invoke(["profiles", "--tools", tmp_path / "none.toml"])
    assert result.exit_code == Exit.USAGE
    assert result.stderr == f"{tmp_path / 'none.toml'}: the tools file does not exist; " \
                            "check --tools\n"


def test_a_profile_value_of_the_wrong_type_names_the_file(tmp_path):
    """max_rpm = "fast": today a ValueError traceback and exit 1."""
    path = tmp_path / "mine.toml"
    path.write_text('[machines.shop]\naccel_rad_s2 = 227\nmax_rpm = "fast"\n')
    result = invoke(["profiles", "--tools", path])
    assert result.exit_code == Exit.USAGE
    line = error_line(result)
    assert line.startswith(f"{path}: ") and "max_rpm" in line


@pytest.mark.parametrize("args", [
    ["rewrite", BOWL_MPF, "--machine", "nope"],
    ["rewrite", BOWL_MPF, "--vc", "70", *SPINDLE],
], ids=["unknown-machine", "vc-without-fz"])
def test_usage_errors_do_not_name_a_phantom_input(args):
    """'<input>' is ncopt's placeholder for a program without a name: an option error of
    'ncopt rewrite samples/bowl.mpf ...' should not be located in a file '<input>'."""
    result = invoke(args)
    assert result.exit_code == Exit.USAGE
    assert not error_line(result).startswith("<input>"), result.stderr


# ------------------------------------------------------------------- version ----
def test_version_is_the_package_version_and_the_stamps(flat, tmp_path):
    result = invoke(["version"])
    assert result.exit_code == Exit.OK
    assert result.stdout == f"{importlib.metadata.version(ncopt.DISTRIBUTION)}\n" \
        == f"{ncopt.__version__}\n"
    assert result.stderr == ""
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert pyproject["project"]["version"] == ncopt.__version__
    out = tmp_path / "out.nc"
    assert invoke(["rewrite", flat, "--diameter", "16", *SPINDLE, "-o", out, "-q"]).exit_code == 0
    assert re.match(rf"\(ncopt {re.escape(ncopt.__version__)} \d{{4}}-\d\d-\d\d: .*\)\n",
                    out.read_text())


# ---------------------------------------------------------------- exit codes ----
def test_readme_exit_code_table_is_the_enum():
    readme = (ROOT / "README.md").read_text()
    section = readme.split("## Exit codes", 1)[1].split("\n## ", 1)[0]
    codes = {int(m[1]) for m in re.finditer(r"^\| (\d+) \|", section, re.M)}
    assert codes == {int(e) for e in Exit} - {Exit.INTERNAL}
    assert Exit.INTERRUPTED == 130


def test_exit_planning_when_nothing_can_be_planned(tmp_path):
    empty = tmp_path / "empty.nc"
    empty.write_bytes(b"")
    no_speed = tmp_path / "no_speed.nc"
    no_speed.write_text("G21 G90\nG0 X0 Y0 Z5\nM3\nG1 Z0 F100\nX10\nY10\nX0\nM30\n")
    for path, message in ((empty, "nothing to plan (no feed moves with a running spindle and a "
                                  "known position)"),
                          (no_speed, "nothing to plan: the program (lines 1-8): the program "
                                     "states no S (the spindle runs at a speed set at the "
                                     "machine): give --vc and --fz to plan it")):
        out = tmp_path / "out.nc"
        result = invoke(["rewrite", path, "--diameter", "6", *SPINDLE, "-o", out])
        assert result.exit_code == Exit.PLANNING
        assert result.stderr == f"{path}: {message}\n"
        assert not out.exists()


def test_exit_verification_writes_nothing(tmp_path, flat, monkeypatch):
    """A rewrite that changes a geometry word is caught by the checks: exit 6, no file."""
    import ncopt.api

    real = ncopt.api.apply_edits

    def corrupting(text, edits):
        out = real(text, edits)
        assert "X10.000 Y1.600" in out
        return out.replace("X10.000 Y1.600", "X10.001 Y1.600", 1)

    monkeypatch.setattr(ncopt.api, "apply_edits", corrupting)
    out = tmp_path / "out.nc"
    result = invoke(["rewrite", flat, "--diameter", "16", *SPINDLE, "-o", out])
    assert result.exit_code == Exit.VERIFICATION
    assert result.stderr == f"{flat}: the rewrite changed more than S and F words; nothing " \
                            "written\n"
    assert [p.name for p in tmp_path.iterdir()] == ["flat.nc"]  # no output, no temporary


@pytest.mark.parametrize("geometry, feed, message", [
    (True, True, ": the rewrite changed more than S and F words; nothing written"),
    (True, False, ": the rewrite changed more than S and F words; nothing written"),
    (False, True, ":{line}: rewriting the result again would change it; nothing written"),
])
def test_verification_reports_the_masked_comparison_first(tmp_path, flat, monkeypatch,
                                                          geometry, feed, message):
    """A rewrite that fails several of the checks is reported by the masked comparison
    first; one that only the rerun of the rewrite catches, at the line of its F word."""
    import ncopt.api

    real = ncopt.api.apply_edits
    where = {}

    def corrupting(text, edits):
        out = real(text, edits)
        lines = out.split("\n")
        planned = [i for i, ln in enumerate(lines) if " F" in ln and ln.startswith("X")]
        if feed:  # a planned F written one unit too low: the checks would rewrite it
            k = planned[0]
            word = lines[k].rsplit(" F", 1)[1].split()[0]
            lines[k] = lines[k].replace(f" F{word}", f" F{float(word) - 1.0:.0f}", 1)
            where["line"] = k + 1  # of the output, as the message gives it
        out = "\n".join(lines)
        if geometry:
            out = out.replace("X10.000 Y1.600", "X10.001 Y1.600", 1)
        return out

    monkeypatch.setattr(ncopt.api, "apply_edits", corrupting)
    out = tmp_path / "out.nc"
    result = invoke(["rewrite", flat, "--diameter", "16", *SPINDLE, "-o", out])
    assert result.exit_code == Exit.VERIFICATION
    assert result.stderr == f"{flat}{message.format(**where)}\n"
    assert not out.exists()
