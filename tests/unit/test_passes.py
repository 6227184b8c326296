"""ncopt.planning.passes: one S per pass, changed only on the moves between passes.

Closed form: with c_q the lowest requirement of pass q and R(p, q) the speed the
spindle can gain or lose over the non-cutting blocks between passes p and q, the
highest feasible speed of pass p is min over q of (c_q + R(p, q)).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from ncopt.planning import passes
from ncopt.planning import schedule
from ncopt.api import rewrite_text
from ncopt.model import Job
from ncopt.model import Cutter, CuttingData, Machine, PlanOptions
from ncopt.reading.parse import parse_text
from ncopt.simulate.replay import simulate_program

A_RPM_S = 1000.0
MACHINE = Machine(accel_rad_s2=A_RPM_S * 2 * math.pi / 60, max_rpm=12000.0)
CUT = CuttingData(vc_m_min=100.0, fz_mm=0.1)
BETWEEN = PlanOptions(s_changes="between-passes")


def blocks(kinds, req, time_s, length=1.0, planned=None, start=None):
    """Blocks from a string: 'c' a cutting block, '.' a non-cutting one."""
    cutting = np.array([k == "c" for k in kinds])
    n = cutting.size
    return schedule.Blocks(
        length_mm=np.broadcast_to(np.asarray(length, float), (n,)).copy(),
        req_rpm=np.where(cutting, np.asarray(req, float), np.inf),
        cutting=cutting, planned=np.ones(n, bool) if planned is None else planned,
        time_s=np.asarray(time_s, float), fixed_rpm=np.zeros(n),
        spindle_start=np.zeros(n, bool) if start is None else start)


def reach(time_s):
    """What one non-cutting block lets the spindle change, with the planner's reserve."""
    return max(A_RPM_S * time_s * (1 - schedule.PLAN_MARGIN) - passes._ROUNDING_RPM, 0.0)


def test_passes_are_runs_of_cutting_blocks_that_move():
    b = blocks("cc..ccc.c..c", req=[1000] * 12, time_s=[1] * 12,
               length=[1, 1, 1, 1, 1, 1, 1, 1, 0, 1, 1, 1])
    # the lone zero-length cutting block (index 8) is no pass
    assert passes.pass_ids(b).tolist() == [0, 0, -1, -1, 1, 1, 1, -1, -1, -1, -1, 2]
    start = np.zeros(12, bool)
    start[5] = True  # the spindle (re)starts inside a run: a new pass
    b = blocks("cc..ccc.c..c", req=[1000] * 12, time_s=[1] * 12, start=start)
    assert passes.pass_ids(b).tolist() == [0, 0, -1, -1, 1, 2, 2, -1, 3, -1, -1, 4]


def test_without_a_mesh_only_gaps_that_surely_leave_the_part_separate_passes():
    # a steep move inside a raster (taken for an air move) must not end the pass; a
    # retract to the top of the cut does
    kinds = "cc.cc..cc"
    sep = np.array([0, 0, 0, 0, 0, 1, 0, 0, 0], bool)
    b = blocks(kinds, req=[1000] * 9, time_s=[1] * 9)
    assert passes.pass_ids(b, sep).tolist() == [0, 0, 0, 0, 0, -1, -1, 1, 1]
    assert passes.pass_ids(b).tolist() == [0, 0, -1, 1, 1, -1, -1, 2, 2]  # a mesh: every gap
    # the program's own S (a block ncopt does not plan) always separates
    planned = np.ones(9, bool)
    planned[2] = False
    b = blocks(kinds, req=[1000] * 9, time_s=[1] * 9, planned=planned)
    assert passes.pass_ids(b, sep).tolist() == [0, 0, -1, 1, 1, -1, -1, 2, 2]
    # the bridged block keeps the pass's S: no S word inside a pass
    b = blocks(kinds, req=[3000, 3000, 0, 2000, 2000, 0, 0, 9000, 9000], time_s=[1] * 9)
    em, _, _ = passes.plan(b, MACHINE, CUT, 2, BETWEEN, sep)
    assert em.s_cmd_rpm[:5].tolist() == [2000] * 5


@pytest.mark.parametrize("caps, gaps", [
    ([3000, 9000, 2000], [2.0, 1.0]),   # the middle pass limited from both sides
    ([8000, 1500, 8000, 8000], [0.5, 3.0, 0.2]),  # a slow pass pulls its neighbours down
    ([2000, 2500, 11000, 4000], [4.0, 4.0, 4.0]),  # rises and falls within reach
])
def test_each_pass_runs_at_the_highest_feasible_speed(caps, gaps):
    kinds, req, time_s = "", [], []
    for i, cap in enumerate(caps):
        kinds += "ccc"
        req += [cap + 500.0, cap, cap + 200.0]  # the pass's lowest requirement is cap
        time_s += [0.1] * 3
        if i < len(gaps):
            kinds += ".."  # a retract and a rapid share the gap's time
            req += [0.0, 0.0]
            time_s += [gaps[i] / 2] * 2
    b = blocks(kinds, req, time_s)
    em, f, _ = passes.plan(b, MACHINE, CUT, 2, BETWEEN)
    pid = passes.pass_ids(b)
    got = [em.s_cmd_rpm[pid == p][0] for p in range(len(caps))]
    gap_reach = [2 * reach(g / 2) for g in gaps]
    expected = []
    for p in range(len(caps)):
        def between(q):
            lo, hi = sorted((p, q))
            return sum(gap_reach[lo:hi])
        expected.append(math.floor(min(caps[q] + between(q) for q in range(len(caps)))))
    assert got == expected
    # feasible for the real spindle: every change completes within the gap, vc never above
    for p in range(1, len(caps)):
        assert abs(got[p] - got[p - 1]) <= A_RPM_S * gaps[p - 1]
    assert all(s <= c for s, c in zip(got, caps))
    # one constant S per pass and F = fz z S on every cutting block
    for p in range(len(caps)):
        assert np.ptp(em.s_cmd_rpm[pid == p]) == 0
        assert np.allclose(f[pid == p], CUT.fz_mm * 2 * got[p], rtol=1e-12)


def test_s_changes_only_on_the_blocks_between_passes():
    b = blocks("ccc..ccc..ccc", req=[3000] * 3 + [0, 0] + [9000] * 3 + [0, 0] + [2000] * 3,
               time_s=[0.1] * 3 + [1, 1] + [0.1] * 3 + [1, 1] + [0.1] * 3)
    em, _, _ = passes.plan(b, MACHINE, CUT, 2, BETWEEN)
    s = em.s_cmd_rpm
    changed = np.flatnonzero(s[1:] != s[:-1]) + 1
    assert changed.size == 2
    assert not b.cutting[changed].any()
    assert changed.tolist() == [3, 8]  # the first block after each pass: the longest ramp


def test_a_rise_smaller_than_the_step_keeps_the_speed():
    b = blocks("ccc..ccc", req=[3000] * 3 + [0, 0] + [3005] * 3, time_s=[0.1] * 3 + [1, 1] +
               [0.1] * 3)
    em, _, _ = passes.plan(b, MACHINE, CUT, 2, BETWEEN)
    assert np.all(em.s_cmd_rpm == 3000)


def test_a_spindle_start_between_passes_frees_the_next_pass():
    start = np.zeros(8, bool)
    start[3] = True  # the spindle stops and starts again between the passes (tool change)
    b = blocks("ccc..ccc", req=[1000] * 3 + [0, 0] + [11000] * 3, time_s=[0.1] * 8, start=start)
    em, _, _ = passes.plan(b, MACHINE, CUT, 2, BETWEEN)
    assert em.s_cmd_rpm[-1] == 11000  # no ramp from 1000 needed: the control brings it up


def _pass_program(make_bowl, ends_mm=(58.0, 70.0, 54.0, 76.0, 62.0), y_mm=(0, 3, 6, 9, 12)):
    """Radial passes over the sample bowl's floor and wall, retract and rapid between them:
    each pass's lowest requirement is at its outer end, where the wall is steepest."""
    lines = ["; passes", "G21 G90 G94", "T1 M6", "S1393 M3"]
    for y, end in zip(y_mm, ends_mm):
        xs = np.linspace(40.0, end, 13)
        zs = make_bowl.drop_ball_tip_z_mm(xs, np.full_like(xs, float(y)), 8.0)
        lines += [f"G0 X{xs[0]:.3f} Y{y:.3f} Z10", f"G1 Z{zs[0] + 2:.3f} F1000",
                  f"G1 Z{zs[0]:.3f} F279"]
        lines += [f"G1 X{x:.3f} Z{z:.3f}" for x, z in zip(xs[1:], zs[1:])]
        lines.append("G0 Z10")
    lines += ["M5", "M30"]
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def bowl_passes(make_bowl, bowl_index):
    text = _pass_program(make_bowl)
    job = Job(cutter=Cutter(16.0, 2), machine=Machine(227.0, 15000.0),
              cutting=CuttingData(70.0, 0.1), options=BETWEEN)
    return text, job, rewrite_text(text, job, "passes.nc", bowl_index)


def test_a_program_gets_one_s_word_per_pass_off_the_cut(bowl_passes):
    text, job, result = bowl_passes
    plan = result.plan
    assert plan.passes == 5 and result.summary.passes == 5
    out = parse_text(result.text)
    s_lines = out.word_line[out.word_letter == ord("S")]
    cutting_lines = set((plan.blocks.cutting.nonzero()[0]).tolist())
    block_of_line = {int(line) + 6: b for b, line in enumerate(result.block_index.line)}  # the stamp
    assert all(block_of_line.get(int(line)) not in cutting_lines for line in s_lines)
    assert len(s_lines) <= 5  # at most one per pass (the first on the M3 line)
    speeds = [plan.s_cmd_rpm[passes.pass_ids(plan.blocks) == p][0] for p in range(5)]
    assert len(set(speeds)) == 5  # the passes differ, and each gets its own speed


def test_the_real_spindle_keeps_vc_and_fz_on_every_pass(bowl_passes, bowl_index):
    text, job, result = bowl_passes
    report, _ = simulate_program(result.text, job, bowl_index, path="out.nc", sample_mm=0.25)
    assert report.vc_max_over_pct <= 0.05  # the mesh's facets: a few hundredths
    # the plunges into the floor keep their programmed F under a faster spindle: below
    # the band, never above it
    assert report.fz_in_band_pct >= 99.0
    assert report.fz_max_over_pct <= 0.0  # F rounded down, S constant: fz never above
    assert report.lag == ()


def test_the_summary_gives_the_time_of_both_modes(bowl_passes, bowl_index):
    text, job, result = bowl_passes
    s = result.summary
    anywhere = rewrite_text(text, Job(cutter=job.cutter, machine=job.machine,
                                      cutting=job.cutting), "passes.nc", bowl_index).summary
    assert s.s_changes == "between-passes" and s.s_changes_source == "given"
    assert anywhere.s_changes == "anywhere"
    assert s.cut_time_other_min == pytest.approx(anywhere.cut_time_after_min, rel=1e-9)
    assert anywhere.cut_time_other_min == pytest.approx(s.cut_time_after_min, rel=1e-9)
    assert anywhere.cut_time_after_min < s.cut_time_after_min < s.cut_time_before_min


def test_grbl_programs_change_s_between_passes_by_default(make_bowl, bowl_index):
    text = "$H\n" + _pass_program(make_bowl)
    job = Job(cutter=Cutter(16.0, 2), machine=Machine(227.0, 15000.0),
              cutting=CuttingData(70.0, 0.1))
    s = rewrite_text(text, job, "grbl.nc", bowl_index).summary
    assert s.control == "grbl"
    assert (s.s_changes, s.s_changes_source) == ("between-passes", "the default for grbl")
    assert "$32=0" in s.control_notes[0] and "between passes" in s.control_notes[0]
    given = Job(cutter=job.cutter, machine=job.machine, cutting=job.cutting,
                options=PlanOptions(s_changes="anywhere"))
    s = rewrite_text(text, given, "grbl.nc", bowl_index).summary
    assert (s.s_changes, s.s_changes_source) == ("anywhere", "given")
    assert "would stop" in s.control_notes[0]


def _dome_groups(groups=3, rows=4):
    """A zig-zag over a dome without a mesh: ``groups`` of ``rows`` rows, a retract to Z30
    between groups; the first row dips into a 3 mm deep notch on two near-vertical moves."""
    lines = ["G21 G90 G94", "T1 M6", "S4000 M3"]
    xs = np.arange(-20.0, 20.01, 1.0)
    for g in range(groups):
        for r in range(rows):
            y = -20.0 + 3.0 * (g * rows + r)
            row = xs[::-1] if r % 2 else xs
            z = 10.0 - (row ** 2 + y ** 2) / 80.0
            if r == 0:
                lines += [f"G0 X{row[0]:.3f} Y{y:.3f} Z30", f"G1 Z{z[0]:.3f} F800"]
            for k, (x, zk) in enumerate(zip(row, z)):
                lines.append(f"G1 X{x:.3f} Y{y:.3f} Z{zk:.3f}")
                if g == 0 and r == 0 and k == 20:  # the notch: down and up again
                    lines += [f"G1 X{x + 0.05:.3f} Z{zk - 3:.3f}", f"G1 X{x + 0.1:.3f} Z{zk:.3f}"]
        lines.append("G0 Z30")
    return "\n".join(lines + ["M5", "M30"]) + "\n"


def test_without_a_mesh_a_steep_move_inside_a_pass_is_no_place_for_s():
    job = Job(cutter=Cutter(6.0, 2), machine=Machine(227.0, 15000.0),
              cutting=CuttingData(60.0, 0.03), options=BETWEEN)
    result = rewrite_text(_dome_groups(), job, "dome.nc")
    assert result.summary.normals_from == "toolpath"
    assert result.summary.passes == 3  # one per retract, the notch inside the first
    out = parse_text(result.text)
    s_lines = sorted(int(v) for v in out.word_line[out.word_letter == ord("S")])
    texts = [out.line_text(v) for v in s_lines]
    assert all(not t.startswith("G1 X") for t in texts), texts  # none on a raster move
