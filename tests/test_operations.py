"""Operations: ncopt plans the surface finishes it understands and leaves every other line
of a program exactly as it is (issue 12).

Each test builds a small program the way a CAM post writes it (a blank line and the
operation's name, the tool call, the spindle start, the approach, the cut, the retract)
and reproduces one defect a machinist would reject at first sight.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ncopt.api import rewrite_text
from ncopt.model import Job
from ncopt.runtime.errors import MeshError, NothingToPlan, PlanningError
from ncopt.contacts.geometry import MeshIndex, mesh_from_triangles
from ncopt.motion.interp import interpret
from ncopt.model import Cutter, CuttingData, Machine, Motion
from ncopt.planning.operations import CANNED, CLEARING, FINISH_3D, FINISH_ZLEVEL, ISOLATED, ROUGH_LEVELS, \
    TWO_D, find
from ncopt.reading.parse import parse_text

MACHINE = Machine(accel_rad_s2=227.0, max_rpm=15000.0)
JOB = Job(machine=MACHINE)


def dome_z(x: float, y: float) -> float:
    """Tool tip height of a D6 ball over a dome (a gentle sphere cap), mm."""
    return 10.0 - (x * x + y * y) / 120.0


# ------------------------------------------------------------ program pieces ----
def header(tools: list[str]) -> list[str]:
    return ["%", "O1000 (TEST)"] + tools + ["G90 G94 G17", "G21"]


def finish(name: str, tool: int, s: int = 6000, f: int = 1000, ramp_f: int = 333,
           passes: int = 12, step: float = 0.6, new_tool: bool = True) -> list[str]:
    """A parallel finish over the dome: ramp in at a reduced feed, zig-zag passes, lead
    out, retract."""
    out = ["", f"({name})"]
    if new_tool:
        out += [f"T{tool} M6", f"S{s} M3", "G54"]
    x0, y0 = -10.0, -step * passes / 2
    out += [f"G0 X{x0 - 3:.3f} Y{y0:.3f}", "Z15.", f"G1 Z{dome_z(x0, y0) + 1:.3f} F{ramp_f}",
            f"X{x0:.3f} Z{dome_z(x0, y0):.3f}"]  # plunge, then ramp onto the surface
    first = True
    for i in range(passes):
        y = y0 + i * step
        xs = np.linspace(-10.0, 10.0, 21)
        for x in (xs if i % 2 == 0 else xs[::-1]):
            words = f"X{x:.3f} Y{y:.3f} Z{dome_z(x, y):.3f}"
            out.append(words + (f" F{f}" if first else ""))
            first = False
    out += ["G0 Z15."]
    return out


def drill(tool: int, s: int = 4000) -> list[str]:
    return ["", "(DRILL1)", f"T{tool} M6", f"S{s} M3", "G0 X10. Y10.", "Z15.",
            "G81 X10. Y10. Z-4. R2. F333", "X20.", "X30.", "G80", "G0 Z15."]


def adaptive(name: str, tool: int, s: int = 5000, new_tool: bool = False) -> list[str]:
    """Area clearing at constant Z levels 3 mm apart: concentric loops at each level."""
    out = ["", f"({name})"] + ([f"T{tool} M6", f"S{s} M3"] if new_tool else [])
    out += ["G0 X0. Y0.", "Z15."]
    for z in (6.0, 3.0, 0.0):
        out.append(f"G1 Z{z:.3f} F300")
        for r in np.arange(1.0, 12.0, 1.2):
            for a in np.linspace(0.0, 2 * np.pi, 24):
                out.append(f"X{r * np.cos(a):.3f} Y{r * np.sin(a):.3f} F1200")
        out.append("G0 Z15.")
    return out


def contour2d(name: str, tool: int) -> list[str]:
    out = ["", f"({name})", "G0 X15. Y0.", "Z15.", "G1 Z-2. F200"]
    out += [f"X{15 * np.cos(a):.3f} Y{15 * np.sin(a):.3f} F800"
            for a in np.linspace(0.0, 2 * np.pi, 40)]
    return out + ["G0 Z15."]


def footer() -> list[str]:
    return ["M5", "M30", "%"]


def program(*pieces: list[str], tools: list[str]) -> str:
    lines = header(tools)
    for p in pieces:
        lines += p
    return "\n".join(lines + footer()) + "\n"


BALL1 = "(T1 D=6 CR=3 - ZMIN=0 - ball end mill)"
DRILL2 = "(T2 D=8 CR=0 TAPER=118DEG - ZMIN=-4 - drill)"
FLAT3 = "(T3 D=6 CR=0 - ZMIN=0 - flat end mill)"


def lines_of(text: str) -> list[str]:
    return text.splitlines(keepends=True)


def unchanged_outside(before: str, after: str, first: int, last: int) -> bool:
    """Every line outside [first, last] (0-based, in ``before``) is byte-identical; the
    output holds one stamp line more near the top."""
    a, b = lines_of(before), lines_of(after)
    stamp = [i for i, line in enumerate(b) if line.lstrip().startswith("(ncopt ")]
    b = [line for i, line in enumerate(b) if i not in stamp]
    assert len(a) == len(b)
    return all(a[i] == b[i] for i in range(len(a)) if not first <= i <= last)


def span(text: str, name: str) -> tuple[int, int]:
    prog = parse_text(text)
    op = next(o for o in find(prog, interpret(prog), {1: 6.0, 3: 6.0}) if o.name == name)
    return op.first_line, op.last_line


# --------------------------------------------------------- the defects of #12 ----
def test_a_drill_cycle_keeps_its_feed_and_its_tool_its_spindle_start():
    text = program(finish("PARALLEL1", 1), drill(2), tools=[BALL1, DRILL2])
    out = rewrite_text(text, JOB).text
    assert "G81 X10. Y10. Z-4. R2. F333\n" in out
    assert "S4000 M3\n" in out
    first, last = span(text, "PARALLEL1")
    assert unchanged_outside(text, out, first, last)
    assert out != text


def test_a_tool_with_nothing_planned_keeps_its_spindle_start():
    """T3 (a flat end mill, the same raster) is left: its S4000 M3 stays, and so does
    every one of its lines, while T1's finish is planned."""
    text = program(finish("PARALLEL1", 1), finish("PARALLEL2", 3, s=4000), tools=[BALL1, FLAT3])
    result = rewrite_text(text, JOB)
    first, last = span(text, "PARALLEL1")
    assert unchanged_outside(text, result.text, first, last)
    rows = {o.name: o for o in result.summary.operations}
    assert rows["PARALLEL1"].planned and not rows["PARALLEL2"].planned
    assert "flat end mill" in rows["PARALLEL2"].reason


def test_reduced_feeds_never_get_a_higher_feed_per_tooth():
    """The ramp at F333 (cutting F1000) is scaled with the spindle: its fz is the
    program's, at the lowest real speed of the block."""
    text = program(finish("PARALLEL1", 1, ramp_f=333), tools=[BALL1])
    result = rewrite_text(text, JOB)
    (p,) = result.plans
    tp, idx = result.toolpath, result.block_index
    lo, hi = p.window
    fp = idx.first_point[lo:hi]
    prog_fz = tp.feed_mm_min[fp] / tp.spindle_rpm[fp]
    reduced = p.reduced
    d = tp.xyz_mm[fp] - tp.xyz_mm[fp - 1]
    plunge = -d[:, 2] > 0.99 * np.linalg.norm(d, axis=1)
    slow = reduced & (tp.feed_mm_min[fp] == 333)
    assert (slow & plunge).any() and (slow & ~plunge).any()
    # fz at the block's lowest real speed, the highest it reaches: the program's
    assert np.all(p.f_mm_min[reduced] / p.s_low_rpm[reduced] <= prog_fz[reduced] * (1 + 1e-9))
    assert np.all(p.f_mm_min[slow & plunge] <= 333)  # a plunge's F is never raised
    ramp = slow & ~plunge & p.blocks.cutting
    assert ramp.any() and np.all(p.f_mm_min[ramp] > 333)  # the spindle runs faster: so does F


def test_the_sample_bowls_plunge_keeps_its_feed_per_tooth(bowl_index):
    from pathlib import Path
    text = (Path(__file__).resolve().parents[1] / "samples" / "bowl.mpf").read_bytes().decode(
        "latin-1")
    job = replace(JOB, cutter=Cutter(16, 2))
    result = rewrite_text(text, job, "bowl.mpf", bowl_index)
    (p,) = result.plans
    tp, idx = result.toolpath, result.block_index
    lo, hi = p.window
    fp = idx.first_point[lo:hi]
    d = tp.xyz_mm[fp] - tp.xyz_mm[fp - 1]
    plunge = -d[:, 2] > 0.99 * np.linalg.norm(d, axis=1)
    assert plunge.any() and np.all(p.reduced[plunge])
    # F279 at S1393: a plunge's F is never raised (S rises tenfold where the ball's tip
    # touches: F3004 before), and falls with the spindle where it runs slower
    assert np.all(p.f_mm_min[plunge] <= 279 * (1 + 1e-9))
    assert np.all(p.f_mm_min[plunge] <= 279 * p.s_low_rpm[plunge] / 1393 * (1 + 1e-9)
                  + (p.s_low_rpm[plunge] >= 1393) * 1e9)


@pytest.mark.parametrize("pieces, kinds", [
    (lambda: [adaptive("ADAPTIVE1", 1, new_tool=True)], {CLEARING, ROUGH_LEVELS}),
    (lambda: [["", "(POCKET1)", "T1 M6", "S5000 M3"] + adaptive("x", 1)[2:]],
     {CLEARING, ROUGH_LEVELS}),
    (lambda: [["", "(2D CONTOUR1)", "T1 M6", "S5000 M3"] + contour2d("x", 1)[2:]], {TWO_D}),
])
def test_roughing_and_2d_cutting_with_a_ball_are_left(pieces, kinds):
    text = program(*pieces(), tools=[BALL1])
    with pytest.raises(NothingToPlan) as exc:
        rewrite_text(text, JOB)
    prog = parse_text(text)
    ops = [o for o in find(prog, interpret(prog), {1: 6.0}) if o.kind != "no cut"]
    assert ops and all(o.kind in kinds and not o.planned for o in ops), ops
    assert "the cutter cuts with its side" in str(exc.value) or "one Z level" in str(exc.value)


def test_a_flat_end_mill_named_in_its_comment_is_never_planned_as_a_ball():
    text = program(finish("PARALLEL1", 3), tools=[FLAT3])
    job = replace(JOB, cutter=Cutter(6.0, 2))  # --diameter 6 alone
    with pytest.raises(NothingToPlan, match="flat end mill"):
        rewrite_text(text, job)
    planned = rewrite_text(text, replace(job, shape_named=True))  # --shape ball
    assert planned.summary.cutting_blocks > 100


def test_a_mesh_of_another_part_is_refused():
    """The dome program against a plane 5 mm below it: the cutter never touches it."""
    text = program(finish("PARALLEL1", 1), tools=[BALL1])
    plane = np.array([[[-50, -50, -5], [50, -50, -5], [50, 50, -5]],
                      [[-50, -50, -5], [50, 50, -5], [-50, 50, -5]]], dtype=float)
    index = MeshIndex(mesh_from_triangles(plane))
    with pytest.raises(MeshError) as exc:
        rewrite_text(text, JOB, "dome.nc", index)
    message = str(exc.value)
    assert "the mesh does not fit T1's cut" in message and "% is in the air" in message
    assert "first line that does not fit" in message and exc.value.line is not None


def test_an_inch_output_rewritten_again_is_the_same_and_simulates_right():
    from ncopt.simulate.replay import simulate_program
    mm = program(finish("PARALLEL1", 1), tools=[BALL1])
    inch = mm.replace("G21", "G20")
    inch = "\n".join(_to_inch(line) for line in inch.split("\n"))
    inch = inch.replace(BALL1, "(T1 D=0.25 CR=0.125 - ZMIN=0 - ball end mill)")
    once = rewrite_text(inch, JOB).text
    assert "D=6.35mm" in once  # the stamp's lengths say their unit
    assert rewrite_text(once, JOB).text == once
    report, _ = simulate_program(once, replace(JOB, cutter=None), path="once.nc")
    assert report.vc_max_over_pct < 1.0  # not +2500 %: the stamp's mm read as mm
    assert report.fz_in_band_pct > 95.0


def _to_inch(line: str) -> str:
    """Axis words of a mm program in inches (4 decimals); F in inch/min."""
    import re
    if line.startswith("("):
        return line
    line = re.sub(r"([XYZR])(-?\d+\.?\d*)", lambda m: f"{m[1]}{float(m[2]) / 25.4:.4f}", line)
    return re.sub(r"F(\d+)", lambda m: f"F{float(m[1]) / 25.4:.2f}", line)


def test_a_program_for_a_faster_spindle_says_so():
    text = program(finish("PARALLEL1", 1, s=24000, f=4000), tools=[BALL1])
    result = rewrite_text(text, JOB)
    warning = next(w for w in result.summary.warnings if "faster spindle" in w)
    assert "S24000" in warning and "15000 RPM" in warning and "vc reaches" in warning


def test_one_f1_block_does_not_refuse_the_rewrite():
    """F written in whole mm/min with a trailing point, and one block at F1.: it keeps its
    feed per tooth (scaled with the spindle), the rest is planned."""
    body = finish("PARALLEL1", 1, f=1000)
    body[12] += " F1."
    body[13] += " F1000."
    text = program(body, tools=[BALL1]).replace(" F1000\n", " F1000.\n")
    result = rewrite_text(text, JOB)
    (p,) = result.plans
    tp, idx = result.toolpath, result.block_index
    fp = idx.first_point[p.window[0]:p.window[1]]
    one = tp.feed_mm_min[fp] == 1.0
    assert one.sum() == 1 and p.reduced[one].all()
    assert np.all(p.f_mm_min[one] / p.s_low_rpm[one] <= 1.0 / 6000 * (1 + 1e-9))
    assert result.summary.cutting_blocks > 200


def test_feed_words_too_coarse_for_the_band_keep_their_blocks():
    """At F10. (whole mm/min) a change of 1 mm/min is several % of fz: the blocks whose
    feed stays that low keep their S and F, with a located warning."""
    slow = finish("PARALLEL1", 1, s=300, f=10)
    text = program(slow, tools=[BALL1]).replace(" F10\n", " F10.\n")
    result = rewrite_text(text, JOB)
    warning = next(w for w in result.summary.warnings if "too low for the resolution" in w)
    path, line = warning.split(":")[:2]
    assert path == "<input>" and int(line) > 10
    (p,) = result.plans
    assert p.coarse_lines.size > 0
    assert not p.blocks.planned[np.isin(result.block_index.line[p.window[0]:p.window[1]],
                                        p.coarse_lines)].any()


def test_the_summary_times_the_whole_program():
    text = program(finish("PARALLEL1", 1), adaptive("ADAPTIVE2", 1), tools=[BALL1])
    result = rewrite_text(text, JOB)
    s = result.summary
    tp = result.toolpath
    feed = np.isin(tp.motion, [Motion.LINEAR, Motion.ARC_CW, Motion.ARC_CCW]) & tp.known
    whole = float(np.sum(tp.seg_len_mm[feed] / tp.feed_mm_min[feed]))
    assert s.cut_time_before_min == pytest.approx(whole, rel=1e-9)
    rows = {o.name: o for o in s.operations}
    assert rows["PARALLEL1"].planned and not rows["ADAPTIVE2"].planned
    assert rows["ADAPTIVE2"].time_before_min == pytest.approx(rows["ADAPTIVE2"].time_after_min)
    assert s.cut_time_before_min == pytest.approx(sum(o.time_before_min for o in s.operations))
    assert s.cut_time_after_min - s.cut_time_before_min == pytest.approx(
        s.planned_time_after_min - s.planned_time_before_min, abs=1e-9)


# ------------------------------------------------ lines whose place is unknown ----
def test_a_subroutine_body_and_its_call_are_untouched():
    body = finish("PARALLEL1", 1)
    sub = ["o100 sub", "S3000", "G1 X5. F100", "o100 endsub"]
    text = "\n".join(sub + ["G21 G90", BALL1] + body[1:] + ["o100 call"] + footer()[:-1]) + "\n"
    result = rewrite_text(text, JOB, "sub.ngc")
    out = lines_of(result.text)
    for line in sub + ["o100 call"]:
        assert sum(x.rstrip("\n") == line for x in out) == 1, line
    assert result.summary.cutting_blocks > 100


def test_block_delete_lines_are_untouched_and_their_operation_left():
    body = finish("PARALLEL1", 1)
    body.insert(6, "/S9000")
    text = program(body, tools=[BALL1])
    with pytest.raises(NothingToPlan, match="block-delete line"):
        rewrite_text(text, JOB)


def test_after_a_subprogram_call_the_blocks_keep_s_and_f():
    """Fanuc M98: the subprogram may set S and F; the blocks after the call, up to the
    program's next S and F, are left alone; the S in force at the call is the program's."""
    body = finish("PARALLEL1", 1)
    cut_at = len(body) // 2
    body = body[:cut_at] + ["M98 P2000"] + body[cut_at:]
    text = program(body, tools=[BALL1])
    result = rewrite_text(text, JOB, "m98.nc")
    i = next(k for k, line in enumerate(lines_of(text)) if line.startswith("M98"))
    after = lines_of(result.text)
    stamp = 6  # four header lines and two for the operation
    assert after[i + stamp] == "M98 P2000\n"
    assert all(after[k + stamp] == lines_of(text)[k] for k in range(i, len(lines_of(text)) - 5))
    prog = parse_text(result.text)
    s_words = prog.word_value[(prog.word_letter == ord("S")) & (prog.word_line < i + stamp)]
    assert s_words[-1] == 6000  # the program's S back in force before the call


def test_a_mid_program_percent_ends_the_program():
    body = finish("PARALLEL1", 1)
    text = program(body, tools=[BALL1])
    text = text.replace("M5\nM30\n%\n", "%\n(after the tape end)\nS15000 M3\nG1 X1. F5000\n")
    result = rewrite_text(text, JOB)
    assert result.text.endswith("%\n(after the tape end)\nS15000 M3\nG1 X1. F5000\n")


def test_a_mesh_the_toolpath_never_touches_is_refused():
    text = program(finish("PARALLEL1", 1), tools=[BALL1])
    far = np.array([[[500, 500, 0], [510, 500, 0], [510, 510, 0]]], dtype=float)
    with pytest.raises(MeshError, match="100.0 % is in the air"):
        rewrite_text(text, JOB, "far.nc", MeshIndex(mesh_from_triangles(far)))


# ----------------------------------------------------------- the property ----
PIECES = ("drill", "flat", "rough", "contour")


@settings(max_examples=25)
@given(st.lists(st.sampled_from(PIECES), max_size=3), st.integers(0, 3),
       st.sampled_from([333, 500, 1000]))
def test_only_the_finish_changes_and_no_fz_rises(others, position, ramp_f):
    """Random programs mixing a finishing operation with drilling cycles, flat-tool and
    roughing operations: every line outside the finish is byte-identical, no cutting
    block's fz rises above the program's (the cut's within the band), and a move in the
    air keeps the program's F (its time is what the plan took)."""
    pieces = []
    for kind in others:
        pieces.append({"drill": lambda: drill(2), "flat": lambda: finish("FLAT1", 3, s=4000),
                       "rough": lambda: adaptive("ADAPTIVE1", 1, new_tool=True),
                       "contour": lambda: contour2d("2D CONTOUR1", 1)}[kind]())
    position = min(position, len(pieces))
    pieces.insert(position, finish("FINISH1", 1, ramp_f=ramp_f))
    text = program(*pieces, tools=[BALL1, DRILL2, FLAT3])
    result = rewrite_text(text, JOB)
    first, last = span(text, "FINISH1")
    assert unchanged_outside(text, result.text, first, last)
    (p,) = result.plans
    tp, idx = result.toolpath, result.block_index
    lo, hi = p.window
    fp = idx.first_point[lo:hi]
    prog_fz = tp.feed_mm_min[fp] / (2 * tp.spindle_rpm[fp])
    f = p.f_mm_min
    cuts = np.isfinite(f) & p.blocks.cutting
    band = 1 + JOB.options.fz_tolerance
    fz = f[cuts] / (2 * p.s_low_rpm[cuts])  # at the lowest real speed of the block: its highest
    assert np.all(fz <= prog_fz[cuts] * band * (1 + 1e-9) + 1e-12)
    red = p.reduced & p.blocks.cutting
    assert np.all(f[red] / (2 * p.s_low_rpm[red]) <= prog_fz[red] * (1 + 1e-9))
    air = np.isfinite(f) & ~p.blocks.cutting  # no tooth cuts: the program's F, as it was
    assert np.all(f[air] == np.minimum(tp.feed_mm_min[fp][air], JOB.machine.max_feed_mm_min))


# ------------------------------------------------------------ one truth (#13) ----
def test_the_same_program_has_the_same_time_in_every_command(tmp_path):
    """inspect, rewrite, simulate and batch count the same moves the same way: every feed
    move whose ends are known, at its F (ncopt.motion.times)."""
    import json

    from typer.testing import CliRunner

    from ncopt.cli.app import app
    text = program(finish("PARALLEL1", 1), adaptive("ADAPTIVE2", 1), drill(2),
                   tools=[BALL1, DRILL2])
    src = tmp_path / "in" / "p.nc"
    src.parent.mkdir()
    src.write_text(text)
    run = CliRunner().invoke
    spindle = ["--accel", "227", "--max-rpm", "15000"]
    inspected = json.loads(run(app, ["inspect", str(src), "--json"]).stdout)["cut_time_min"]
    result = rewrite_text(text, JOB, str(src))
    simulated = run(app, ["simulate", str(src), "--json", "--tool", "1", *spindle])
    assert simulated.exit_code == 0, simulated.output
    batch = tmp_path / "report.json"
    run(app, ["batch", str(src.parent), "-o", str(tmp_path / "out"), *spindle, "--report",
              str(batch)])
    batched = json.loads(batch.read_text())[0]["time_before_min"]
    assert result.summary.cut_time_before_min == pytest.approx(inspected, rel=1e-12)
    assert batched == pytest.approx(inspected, rel=1e-12)
    sim = json.loads(simulated.stdout)["feed_moves_time_min"]  # T1 judged, every move timed
    assert sim == pytest.approx(inspected, rel=1e-9)


def test_simulate_judges_a_rewrite_with_the_teeth_and_band_of_its_stamp():
    """A rewrite for a 3-tooth cutter with a 1 % band: simulate, given neither, reads both
    from the stamp (it used to judge it at 2 teeth: '0.00 % in band, +52.85 %')."""
    from ncopt.model import PlanOptions
    from ncopt.simulate.replay import simulate_program
    text = program(finish("PARALLEL1", 1), tools=[BALL1])
    job = replace(JOB, cutter=Cutter(6.0, 3), shape_named=True,
                  options=PlanOptions(fz_tolerance=0.01))
    out = rewrite_text(text, job).text
    assert " band=1)" in out and " z=3 " in out
    report, _ = simulate_program(out, Job(machine=MACHINE), path="out.nc")
    assert report.band_pct == 1.0
    assert report.fz_in_band_pct > 95.0 and report.fz_max_over_pct < 1.0


def test_json_summary_and_batch_report_list_every_operation(tmp_path):
    import json

    from typer.testing import CliRunner

    from ncopt.cli.app import app
    text = program(finish("PARALLEL1", 1), drill(2), tools=[BALL1, DRILL2])
    src = tmp_path / "in" / "p.nc"
    src.parent.mkdir()
    src.write_text(text)
    spindle = ["--accel", "227", "--max-rpm", "15000"]
    run = CliRunner().invoke(app, ["rewrite", str(src), "-o", str(tmp_path / "o.nc"), "--json",
                                   *spindle])
    assert run.exit_code == 0, run.output
    data = json.loads(run.stderr)
    assert [(o["name"], o["planned"]) for o in data["operations"]] == [
        ("PARALLEL1", True), ("DRILL1", False)]
    assert data["cut_time_before_min"] > data["cut_time_after_min"] > 0
    report = tmp_path / "r.json"
    CliRunner().invoke(app, ["batch", str(src.parent), "-o", str(tmp_path / "out"), *spindle,
                             "--report", str(report)])
    (entry,) = json.loads(report.read_text())
    assert [tuple(o[:2]) for o in entry["operations"]] == [("PARALLEL1", True), ("DRILL1", False)]
    assert entry["summary"]["cut_time_before_min"] == pytest.approx(data["cut_time_before_min"])


def levels(name: str, radius_mm, depths) -> list[str]:
    """A circle at each depth (mm), 0.5 mm apart; ``radius_mm(z)`` its radius there."""
    out = ["", f"({name})", "T1 M6", "S5000 M3", "G0 X15. Y0.", "Z15."]
    for z in depths:
        r = radius_mm(z)
        out.append(f"G1 X{r:.3f} Y0. Z{z:.3f} F200")
        out += [f"X{r * np.cos(a):.3f} Y{r * np.sin(a):.3f} F800"
                for a in np.linspace(0.0, 2 * np.pi, 120)[1:]]
    return out + ["G0 Z15."]


@pytest.mark.parametrize("radius, kind, why", [
    (lambda z: 15.0, TWO_D, "the same contour at several depths"),  # a wall: side cutting
    (lambda z: 15.0 + 2.0 * z, FINISH_ZLEVEL, "constant-Z passes"),  # a cone: Z-level finish
])
def test_constant_z_levels_close_together_are_a_wall_or_a_z_level_finish(radius, kind, why):
    text = program(levels("LEVELS", radius, np.arange(0.0, -4.0, -0.5)), tools=[BALL1])
    prog = parse_text(text)
    ops = [o for o in find(prog, interpret(prog), {1: 6.0}) if o.kind != "no cut"]
    assert [o.kind for o in ops] == [kind] and why in ops[0].reason, ops


def test_operation_comments_of_the_linuxcnc_5axis_demos_name_the_operation():
    """``( OPERATION=  ROUGH7  Z LEVEL  SRF_MILL1  )`` (the post of the LinuxCNC boat demos)
    names the operation; it used to be dropped for its '=' and shown as ``T1``."""
    from ncopt.planning.opnames import operation_comments
    text = ("%\n(BOAT)\n\n( OPERATION=  ROUGH7  Z LEVEL  SRF_MILL1  )\n"
            "( TOOL: T1 = 10.0 dia. ENDMILLM1000:REG )\nG00 G17 G40 G90 G94\nT1 M6\n"
            "S630 M03\nG01 Z-6.625 F300.0\nX-49.375 F600.0\n\n( FINISH1 FLOWLINE SRF_MILL1 )\n"
            "G01 X-34.78 Y-2.436\nM30\n%\n")
    names = operation_comments(parse_text(text))
    assert names == {3: "ROUGH7 Z LEVEL SRF_MILL1", 11: "FINISH1 FLOWLINE SRF_MILL1"}


def test_nothing_to_plan_names_operations_with_the_same_reason_once():
    """Nine Estlcam operations with one flat end mill: one row for the reason, three names
    and "and 6 more" (it listed the reason six times, then "and 3 more")."""
    from types import SimpleNamespace

    from ncopt.planning.judging import nothing_why as _nothing_why
    flat = "a flat end mill (2mm); ncopt plans ball and bull-nose cutters only"
    ops = [SimpleNamespace(kind=TWO_D, name=f"Hole {k}", lines=f"lines {k}-{k}", reason=flat)
           for k in range(1, 10)]
    ops.insert(1, SimpleNamespace(kind=CANNED, name="Drill", lines="lines 20-30",
                                  reason="a canned cycle"))
    assert _nothing_why(ops, None) == (
        "nothing to plan: Hole 1 (lines 1-1), Hole 2 (lines 2-2), Hole 3 (lines 3-3) "
        f"and 6 more: {flat}; Drill (lines 20-30): a canned cycle")


def test_a_fanuc_finish_with_ai_contour_control_is_planned():
    """A Fanuc finishing program switching AI contour control on and off (``G05.1 Q1 R5``
    ... ``G05.1 Q0``, as high-speed posts write it) is planned; both lines come out as they
    went in.  It was refused at ``Q1`` ("no decimal point"), then at its R word."""
    passes = []
    for k, y in enumerate(np.arange(-6.0, 6.01, 1.0)):
        xs = np.arange(-12.0, 12.01, 0.5)[::(-1 if k % 2 else 1)]
        passes += [f"X{x:.3f} Y{y:.3f} Z{-0.02 * x * x - 0.01 * y * y:.3f}" for x in xs]
    text = "\n".join(["%", "O1234 (FINISH)", "(T1 D=10. CR=5. - BALL END MILL)",
                      "G21 G90 G17 G40 G49 G80", "T1 M6", "G54", "G05.1 Q1 R5", "S5000 M3",
                      "G0 X-12. Y-6.", "G43 H1 Z10.", "G1 Z0. F1000.", *passes, "G05.1 Q0",
                      "G0 Z50.", "M5", "M30", "%"]) + "\n"
    res = rewrite_text(text, JOB, "aicc.nc")
    assert res.summary.cutting_blocks > 600
    out = res.text.splitlines()
    assert "G05.1 Q1 R5" in out and "G05.1 Q0" in out
