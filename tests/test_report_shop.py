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

from ncopt.cli import Exit, app

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
