"""Invariants under hypothesis: identity without edits, only S/F spans change, rewriting keeps
the toolpath and is idempotent, the planner keeps the spindle's limits."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import Phase, assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra.lark import from_lark

from ncopt.planning import schedule
from ncopt.api import rewrite_text
from ncopt.model import Job
from ncopt.runtime.errors import NcParseError
from ncopt.motion.interp import interpret
from ncopt.model import Cutter, CuttingData, Edit, LineKind, Machine, PlanOptions
from ncopt.reading.parse import parse_text, parser
from ncopt.writing.edits import (F_CODE, S_CODE, Targets, apply_edits, detect_style, masked,
                           plan_edits)

LATIN1_LINE = st.characters(codec="latin-1", exclude_characters="\r\n")
NEWLINE = st.sampled_from(["\n", "\r\n"])
NUMBER_TEXT = st.one_of(
    st.integers(0, 30000).map(str),
    st.from_regex(r"[+-]?(?:[0-9]{1,5}\.?[0-9]{0,4}|\.[0-9]{1,4})", fullmatch=True),
)


# ------------------------------------------------- (a) no edits: the input back ----
@given(st.lists(st.one_of(from_lark(parser(), start="line", alphabet=LATIN1_LINE),
                          st.text(LATIN1_LINE, max_size=40)), max_size=6),
       NEWLINE, st.booleans())
def test_zero_edits_give_the_input_back(lines, newline, final):
    text = newline.join(lines) + (newline if final else "")
    assert apply_edits(text, []) == text
    try:
        prog = parse_text(text)
    except NcParseError:
        return
    assert prog.text == text
    assert list(plan_edits(prog, Targets(np.zeros(0, int), np.zeros(0), np.zeros(0)),
                           detect_style(prog, S_CODE), detect_style(prog, F_CODE))) == []


@st.composite
def move_programs(draw):
    """Programs whose every line is a feed move, some with S and F words."""
    sep = draw(st.sampled_from([" ", ""]))
    lines = []
    for i in range(draw(st.integers(1, 12))):
        words = [f"G1{sep}X{i}.{draw(st.integers(0, 999)):03d}"]
        if draw(st.booleans()):
            words.append("S" + draw(NUMBER_TEXT.filter(lambda t: float(t) >= 0)))
        if draw(st.booleans()):
            words.append("F" + draw(NUMBER_TEXT.filter(lambda t: float(t) > 0)))
        if draw(st.booleans()):
            words = [words[0]] + words[1:][::-1]
        lines.append(sep.join(words))
    return "".join(line + draw(NEWLINE) for line in lines)


def in_force(prog, code):
    """(n_lines,) value of the last ``code`` word at or before each line (NaN before any)."""
    out = np.full(prog.n_lines, np.nan)
    for line, letter, value in zip(prog.word_line, prog.word_letter, prog.word_value):
        if letter == code:
            out[line] = value
    for i in range(1, out.size):
        if np.isnan(out[i]):
            out[i] = out[i - 1]
    return out


@given(move_programs())
def test_targets_equal_to_what_is_in_force_need_no_edit(text):
    prog = parse_text(text)
    lines = np.arange(prog.n_lines)
    targets = Targets(lines, in_force(prog, S_CODE), in_force(prog, F_CODE))
    edits = plan_edits(prog, targets, detect_style(prog, S_CODE),
                       detect_style(prog, F_CODE, default_decimals=1))
    assert list(edits) == []


# --------------------------------------- (b) edits on S/F value spans only ----
@st.composite
def sf_programs_and_edits(draw):
    text = draw(move_programs())
    prog = parse_text(text)
    sf = np.flatnonzero((prog.word_letter == S_CODE) | (prog.word_letter == F_CODE))
    assume(sf.size > 0)
    chosen = draw(st.lists(st.sampled_from(sf.tolist()), unique=True, min_size=1))
    edits = [Edit(int(prog.word_num_start[w]), int(prog.word_end[w]), draw(NUMBER_TEXT))
             for w in chosen]
    return text, prog, edits


@given(sf_programs_and_edits())
def test_edits_on_s_and_f_values_change_only_those_spans(case):
    text, prog, edits = case
    out = apply_edits(text, edits)
    # outside the edited spans, the text is the input
    pos, rebuilt = 0, []
    for e in sorted(edits, key=lambda e: e.start):
        rebuilt += [text[pos:e.start], e.text]
        pos = e.end
    assert out == "".join(rebuilt) + text[pos:]
    out_prog = parse_text(out)
    assert masked(out_prog) == masked(prog)
    # the other words keep their letters and values; the S/F words hold the new values
    other = (prog.word_letter != S_CODE) & (prog.word_letter != F_CODE)
    other_out = (out_prog.word_letter != S_CODE) & (out_prog.word_letter != F_CODE)
    assert np.array_equal(prog.word_letter[other], out_prog.word_letter[other_out])
    assert np.array_equal(prog.word_value[other], out_prog.word_value[other_out])
    # S/F words stay where they were, holding the new value where edited
    new = {e.start: float(e.text) for e in edits}
    expected = [new.get(int(n), float(v)) for n, v in
                zip(prog.word_num_start[~other], prog.word_value[~other])]
    assert out_prog.word_value[~other_out].tolist() == expected


def test_overlapping_edits_are_refused():
    from ncopt.runtime.errors import VerificationError
    with pytest.raises(VerificationError):
        apply_edits("G1 X1 F100\n", [Edit(7, 10, "200"), Edit(8, 9, "5")])


# ------------------------- (c) rewrite: only S/F change, same toolpath, idempotent ----
RADIUS = 8.0  # D16 ball: the tool samples/make_bowl.py computes its drop-cutter for


@st.composite
def bowl_programs(draw, mb):
    """Zig-zag passes over the sample bowl's wall, tool tip from the exact drop-cutter,
    written in one of several post styles."""
    n_pass = draw(st.integers(2, 4))
    y0 = draw(st.floats(20.0, 70.0))
    stepover = draw(st.floats(0.8, 2.5))
    x0 = draw(st.floats(-95.0, 50.0))
    span = draw(st.floats(6.0, 30.0))
    step = draw(st.floats(0.3, 1.5))
    sep = draw(st.sampled_from([" ", ""]))
    decimals = draw(st.sampled_from([3, 4]))
    f_text = draw(st.sampled_from(["279", "279.", "279.0", "279.00"]))
    s_line = draw(st.sampled_from(["S1393 M3", "M3 S1393", "M03S1393", "S1393. M3"]))
    modal = draw(st.booleans())
    numbered = draw(st.booleans())
    tape = draw(st.booleans())
    newline = draw(NEWLINE)

    def fmt(v):
        return f"{v:.{decimals}f}"

    pts = []
    for i in range(n_pass):
        y = y0 + i * stepover
        xs = np.linspace(x0, x0 + span, int(math.ceil(span / step)) + 1)
        if i % 2:
            xs = xs[::-1]
        zs = mb.drop_ball_tip_z_mm(xs, np.full_like(xs, y), RADIUS)
        pts += [(x, y, z) for x, z in zip(xs.tolist(), zs.tolist())]
    head = (["%", "O1000 (GENERATED)"] if tape else []) + [
        "(bowl wall finish, D16 ball)", f"G21{sep}G90{sep}G17", f"T1{sep}M6",
        s_line.replace(" ", sep),
        sep.join(["G0", f"X{fmt(pts[0][0])}", f"Y{fmt(pts[0][1])}", f"Z{fmt(pts[0][2] + 5)}"]),
        sep.join(["G1", f"Z{fmt(pts[0][2])}", f"F{f_text}"]),
    ]
    body, last = [], (None, None, None)
    for p in pts[1:]:
        words = [f"{a}{fmt(v)}" for a, v, old in zip("XYZ", p, last) if not modal or
                 fmt(v) != (fmt(old) if old is not None else None)]
        body.append(sep.join(words or [f"Z{fmt(p[2])}"]))
        last = p
    tail = [f"G0{sep}Z{fmt(pts[-1][2] + 20)}", "M5", "M30"] + (["%"] if tape else [])
    lines = head + body + tail
    if numbered:
        lines = [f"N{10 * (i + 1)}{sep}{line}" if line[0] in "GTMSXYZ" else line
                 for i, line in enumerate(lines)]
    return newline.join(lines) + newline, sep


@st.composite
def jobs(draw):
    machine = Machine(accel_rad_s2=draw(st.floats(20.0, 600.0)),
                      max_rpm=draw(st.sampled_from([6000.0, 12000.0, 18000.0])),
                      min_rpm=draw(st.sampled_from([0.0, 500.0])))
    cutting = CuttingData(vc_m_min=draw(st.floats(40.0, 150.0)),
                          fz_mm=draw(st.floats(0.03, 0.15)))
    opts = PlanOptions(planner=draw(st.sampled_from(["lookahead", "forward"])),
                       min_rpm_step=draw(st.sampled_from([1.0, 10.0, 50.0])))
    # some draws lie on the bowl's flat bottom, a 2D pass by itself: planned all the same
    return Job(cutter=Cutter(2 * RADIUS, 2), machine=machine, cutting=cutting, options=opts,
               operations=("all",))


@pytest.fixture(scope="module")
def bowl_case(make_bowl):
    return bowl_programs(make_bowl)


def _words(prog, code):
    sel = prog.word_letter == code
    return [prog.text[n:e] for n, e in zip(prog.word_num_start[sel], prog.word_end[sel])]


def test_rewrite_keeps_geometry_changes_only_sf_and_is_idempotent(bowl_case, bowl_index):
    @settings(max_examples=15)
    @given(bowl_case, jobs())
    def check(case, job):
        text, sep = case
        prog = parse_text(text, "gen.nc")
        bare = replace(job, stamp=False)  # S/F only: the stamp comment is checked below
        out = rewrite_text(text, bare, "gen.nc", bowl_index).text
        out_prog = parse_text(out, "gen.nc")
        assert masked(out_prog) == masked(prog)
        assert out.count("\n") == text.count("\n")
        assert out.count("\r\n") == text.count("\r\n")
        a, b = interpret(prog), interpret(out_prog)
        assert np.array_equal(a.xyz_mm, b.xyz_mm) and np.array_equal(a.line, b.line)
        # lines that are not word blocks are untouched
        for i in np.flatnonzero(prog.line_kind != LineKind.WORDS).tolist():
            assert out_prog.line_text(i) == prog.line_text(i)
        # a post without blanks gets words without blanks
        if sep == "":
            for i in np.flatnonzero(prog.line_kind == LineKind.WORDS).tolist():
                if " " not in prog.line_text(i):
                    assert " " not in out_prog.line_text(i), out_prog.line_text(i)
        # S within the machine's range; F words written as the program writes them
        s_values = out_prog.word_value[out_prog.word_letter == S_CODE]
        assert np.all(s_values <= job.machine.max_rpm)
        f_in = _words(prog, F_CODE)[0]
        for f in _words(out_prog, F_CODE):
            assert f.endswith(".") == f_in.endswith(".")
            assert len(f.partition(".")[2]) == len(f_in.partition(".")[2])
        # the stamp: a block of comment lines more, everything else as without it;
        # rewriting a stamped output changes nothing (without the stamp, the feed each
        # block stands for is no longer in the program: a second run re-plans from it)
        stamped = rewrite_text(text, job, "gen.nc", bowl_index).text
        extra = _inserted_lines(out, stamped)
        assert parse_text(extra, "stamp").line_kind.tolist() == [LineKind.BLANK] * 6
        assert rewrite_text(stamped, job, "gen.nc", bowl_index).text == stamped

    check()


def test_a_plunge_kept_at_the_cutting_feed_rewrites_the_same_twice(bowl_index):
    """Found by the property above: a plunge at the program's only feed keeps its F while
    S rises; the second rewrite read its feed per revolution at the new S (k-limit not
    scaled) and raised the spindle start, S5419 -> S5450."""
    passes = "".join(f"{xyz}\n" for xyz in (
        "X1.000 Y47.000 Z-24.792", "X2.000 Y47.000 Z-24.791", "X3.000 Y47.000 Z-24.788",
        "X4.000 Y47.000 Z-24.785", "X5.000 Y47.000 Z-24.780", "X6.000 Y47.000 Z-24.774",
        "X6.000 Y49.000 Z-24.655", "X5.000 Y49.000 Z-24.663", "X4.000 Y49.000 Z-24.669",
        "X3.000 Y49.000 Z-24.674", "X2.000 Y49.000 Z-24.678", "X1.000 Y49.000 Z-24.680",
        "X0.000 Y49.000 Z-24.681", "X0.000 Y51.000 Z-24.514", "X1.000 Y51.000 Z-24.513",
        "X2.000 Y51.000 Z-24.510", "X3.000 Y51.000 Z-24.505", "X4.000 Y51.000 Z-24.498",
        "X5.000 Y51.000 Z-24.489", "X6.000 Y51.000 Z-24.477", "X6.000 Y53.000 Z-24.214",
        "X5.000 Y53.000 Z-24.230", "X4.000 Y53.000 Z-24.243", "X3.000 Y53.000 Z-24.253",
        "X2.000 Y53.000 Z-24.261", "X1.000 Y53.000 Z-24.265", "X0.000 Y53.000 Z-24.266",
    ))
    text = ("(bowl wall finish, D16 ball)\nG21 G90 G17\nT1 M6\nS1393 M3\n"
            "G0 X0.000 Y47.000 Z-19.792\nG1 Z-24.792 F279\n" + passes + "G0 Z-4.266\nM5\nM30\n")
    job = Job(cutter=Cutter(2 * RADIUS, 2),
              machine=Machine(accel_rad_s2=20.0, max_rpm=6000.0, min_rpm=0.0),
              cutting=CuttingData(vc_m_min=40.0, fz_mm=0.0625),
              options=PlanOptions(planner="lookahead", min_rpm_step=1.0), operations=("all",))
    once = rewrite_text(text, job, "gen.nc", bowl_index).text
    assert once != text
    assert rewrite_text(once, job, "gen.nc", bowl_index).text == once


def _inserted_lines(base: str, longer: str) -> str:
    """The whole lines, one block, ``longer`` has in addition to ``base``."""
    a, b = base.splitlines(keepends=True), longer.splitlines(keepends=True)
    n = len(b) - len(a)
    assert n > 0
    i = next((k for k, (x, y) in enumerate(zip(a, b)) if x != y), len(a))
    assert b[:i] + b[i + n:] == a
    return "".join(b[i:i + n])


# ---------------------------------------------------- (d) the planner's limits ----
@st.composite
def planning_cases(draw):
    n = draw(st.integers(1, 30))
    machine = Machine(accel_rad_s2=draw(st.floats(10.0, 1000.0)),
                      max_rpm=draw(st.floats(3000.0, 30000.0)),
                      min_rpm=draw(st.floats(0.0, 2000.0)),
                      max_feed_mm_min=draw(st.sampled_from([math.inf, 5000.0, 20000.0])))
    cut = CuttingData(vc_m_min=100.0, fz_mm=draw(st.floats(0.02, 0.2)))
    teeth = draw(st.integers(1, 4))
    # min_rpm_step at most what the fz band lets S fall in one block at the lowest speed
    # (300 RPM): otherwise the two options contradict each other
    # the planner refuses, by design (PlanningError), an fz band too narrow for integer S
    # words at the lowest speed: with F from the lower speed ("below") that is under 0.68 %
    # at 300 RPM, so narrower bands are no valid case
    tolerance = draw(st.floats(0.007, 0.1))
    opts = PlanOptions(fz_tolerance=tolerance,
                       min_rpm_step=float(draw(st.integers(1, max(1, int(300 * tolerance))))))
    arr = lambda s: np.array(draw(st.lists(s, min_size=n, max_size=n)))  # noqa: E731
    planned = arr(st.floats(0.0, 1.0).map(lambda u: u < 0.75))
    cutting = planned & arr(st.booleans())
    req = arr(st.one_of(st.floats(300.0, 40000.0), st.just(math.inf)))
    blocks = schedule.Blocks(
        length_mm=arr(st.floats(0.01, 5.0)), req_rpm=req, cutting=cutting, planned=planned,
        time_s=arr(st.floats(0.001, 2.0)),
        fixed_rpm=arr(st.integers(int(max(300.0, machine.min_rpm)) + 1,
                                  int(machine.max_rpm)).map(float)))
    return blocks, machine, cut, teeth, opts


@settings(max_examples=200)
@given(planning_cases())
def test_lookahead_keeps_the_spindle_limits(case):
    blocks, machine, cut, teeth, opts = case
    prof = schedule.lookahead(blocks, machine, cut, teeth, opts)
    s = prof.s_rpm
    k = schedule.k_rpm2_per_mm(machine, cut, teeth)
    assert prof.k_rpm2_per_mm == pytest.approx(k)
    s_lo, s_hi = schedule.speed_limits(machine, cut, teeth)
    cap = schedule.caps(blocks, s_lo, s_hi, lookahead=True)
    eps = 1e-9
    assert np.all(np.isfinite(s))
    # round-off is compared in S^2, where the passes work, against the largest speed
    scale = float(np.max(cap ** 2, initial=0.0) + np.max(blocks.fixed_rpm ** 2)) + 1.0
    # above its cap only where an unplanned block (the program's own S) came before in the
    # same spindle run, and there only falling as fast as the spindle allows
    over = np.flatnonzero(s ** 2 > cap ** 2 + 1e-12 * scale)
    unplanned = ~blocks.planned & blocks.running
    for b in over.tolist():
        run_start = max(np.flatnonzero(blocks.spindle_start[: b + 1]).tolist() + [0])
        assert unplanned[run_start:b + 1].any(), b
        if blocks.planned[b]:  # the real speed, still falling from the program's own S
            assert s[b] <= s[b - 1] + 1e-9 * math.sqrt(scale), b
    cut_b = blocks.cutting & blocks.planned
    assert np.all(s[cut_b] >= s_lo * (1 - eps) - eps)
    within = np.ones(s.size, dtype=bool)
    within[over] = False  # checked above: the program's own S still falling
    assert np.all(s[cut_b & within] <= s_hi * (1 + eps) + eps)
    for b in range(1, s.size):
        if not blocks.planned[b]:
            continue  # the program's own S: its change is the program's, not ncopt's
        if blocks.cutting[b]:
            assert abs(s[b] ** 2 - s[b - 1] ** 2) <= k * blocks.length_mm[b] + 1e-9 * scale
        else:
            ramp = machine.accel_rpm_s * blocks.time_s[b]
            assert abs(s[b] - s[b - 1]) <= ramp + 1e-9 * math.sqrt(scale)
        if cut_b[b] and s[b - 1] > 0:
            # the default fz policy ("centred") keeps fz within +-tol while S ramps
            ratio = (1 + opts.fz_tolerance) / (1 - opts.fz_tolerance)
            assert s[b] / s[b - 1] <= ratio * (1 + eps)
            assert s[b] / s[b - 1] >= (1 / ratio) * (1 - eps)


def emitted(case, policy):
    blocks, machine, cut, teeth, opts = case
    opts = PlanOptions(fz_tolerance=opts.fz_tolerance, min_rpm_step=opts.min_rpm_step,
                       fz_policy=policy)
    prof = schedule.lookahead(blocks, machine, cut, teeth, opts)
    incs = schedule.increments(blocks, machine, prof.k_rpm2_per_mm)
    s_lo, s_hi = schedule.speed_limits(machine, cut, teeth)
    cut_b = blocks.cutting & blocks.planned
    lowest = float(prof.cap_rpm[cut_b].min()) if cut_b.any() else 1.0
    ratio = schedule.max_speed_ratio(opts, cut, teeth, lowest)
    cmd, low, high = schedule.emit_rpm(prof, blocks, incs, opts, s_lo, ratio, s_hi=s_hi)
    return blocks, machine, cut, teeth, opts, prof, cmd, low, high


# no shrinking: a failing case shrinks for minutes through the per-block Python loop;
# the minimal cases found so far are unit tests in tests/unit/test_planner.py
@settings(max_examples=100, phases=[Phase.explicit, Phase.reuse, Phase.generate])
@given(planning_cases(), st.sampled_from(["centred", "below"]))
def test_emitted_commands_never_exceed_the_profile(case, policy):
    blocks, machine, cut, teeth, opts, prof, cmd, low, high = emitted(case, policy)
    free = blocks.planned
    assert np.all(cmd[free] <= prof.s_rpm[free] + 1.0 + 1e-9)


# no shrinking: a failing case shrinks for minutes through the per-block Python loop;
# the minimal cases found so far are unit tests in tests/unit/test_planner.py
@settings(max_examples=100, phases=[Phase.explicit, Phase.reuse, Phase.generate])
@given(planning_cases(), st.sampled_from(["centred", "below"]))
def test_emitted_commands_step_and_keep_fz_in_band(case, policy):
    blocks, machine, cut, teeth, opts, prof, cmd, low, high = emitted(case, policy)
    free = blocks.planned
    cut_b = blocks.cutting & blocks.planned
    assert np.all(cmd[free] == np.floor(cmd[free]))
    assert np.all(cmd[cut_b] <= prof.s_rpm[cut_b] + 1.0 + 1e-9)  # vc never above target
    s_lo, s_hi = schedule.speed_limits(machine, cut, teeth)
    assert np.all(cmd[free] >= math.ceil(s_lo - 1e-9))  # the machine's lowest speed
    assert np.all(cmd[free] <= s_hi + 1e-9)
    assert np.all(low <= high)
    lowest = float(prof.cap_rpm[cut_b].min()) if cut_b.any() else 1.0
    ratio = schedule.max_speed_ratio(opts, cut, teeth, lowest)
    for b in range(1, cmd.size):
        if free[b] and free[b - 1] and cmd[b] != cmd[b - 1]:
            # a fall onto the spindle's lowest speed may be shorter than a step: holding
            # the speed above it would run vc over its target
            onto_floor = cmd[b] < cmd[b - 1] and cmd[b] <= math.ceil(s_lo)
            # and so may a fall in a cut where a full step would take the spindle below
            # the fz band's floor within the block (from the speed it enters with)
            band_first = (cmd[b] < cmd[b - 1] and cut_b[b]
                          and cmd[b - 1] - opts.min_rpm_step < math.ceil(high[b] / ratio))
            assert abs(cmd[b] - cmd[b - 1]) >= opts.min_rpm_step or onto_floor or band_first, \
                (b, cmd[b - 1], cmd[b])
    # fz stays in its band at the slowest and the fastest real speed of each cutting block
    f = schedule.feeds(low, high, blocks, cut, teeth, machine.max_feed_mm_min, policy)
    tol = opts.fz_tolerance
    top = cut.fz_mm * (1.0 if policy == "below" else 1.0 + tol)
    assert np.all(f[cut_b] / (teeth * low[cut_b]) <= top * (1 + 1e-9))
    uncapped = cut_b & (f < machine.max_feed_mm_min)
    assert np.all(f[uncapped] / (teeth * high[uncapped]) >= cut.fz_mm * (1 - tol) * (1 - 1e-9))
