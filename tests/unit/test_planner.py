"""ncopt.planning.schedule: closed-form profiles, the forward planner's overshoot, _two_way_min.

The spindle limit of docs/method.md in the planner's per-block form: during cutting block b the
spindle goes from S_(b-1) to S_b with |S_b^2 - S_(b-1)^2| <= K L_b,
K = 2 * 60 * a / (fz z) with a in RPM/s.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ncopt.planning import schedule
from ncopt.model import CuttingData, Machine, PlanOptions

A_RPM_S = 1000.0
MACHINE = Machine(accel_rad_s2=A_RPM_S * 2 * math.pi / 60, max_rpm=12000.0)
CUT = CuttingData(vc_m_min=100.0, fz_mm=0.1)
TEETH = 2
K = 2 * 60 * A_RPM_S / (CUT.fz_mm * TEETH)  # 600 000 RPM^2 per mm
# the look-ahead keeps a documented share of the spindle's rate in reserve, so that the
# integer S words can follow its profile: its closed forms use the rest
KEEP = 1.0 - schedule.PLAN_MARGIN
K_LOOK = K * KEEP
LOOSE = PlanOptions(fz_tolerance=0.5)  # a per-block speed ratio of 3: never the binding limit


def blocks(req, length=1.0, cutting=True, planned=True, time_s=1.0, fixed=0.0):
    req = np.asarray(req, dtype=float)
    n = req.shape[0]
    full = lambda v, dtype=float: np.broadcast_to(np.asarray(v, dtype), (n,)).copy()  # noqa
    return schedule.Blocks(length_mm=full(length), req_rpm=req, cutting=full(cutting, bool),
                          planned=full(planned, bool), time_s=full(time_s),
                          fixed_rpm=full(fixed))


def plan(b, opts=LOOSE, machine=MACHINE, how=schedule.lookahead):
    return how(b, machine, CUT, TEETH, opts).s_rpm


def test_k_is_the_closed_form():
    assert schedule.k_rpm2_per_mm(MACHINE, CUT, TEETH) == pytest.approx(K, rel=1e-12)
    assert MACHINE.accel_rpm_s == pytest.approx(A_RPM_S, rel=1e-12)


@pytest.mark.parametrize("how", [schedule.lookahead, schedule.forward])
def test_constant_requirement_gives_a_constant_profile(how):
    s = plan(blocks([5000.0] * 30), how=how)
    assert np.allclose(s, 5000.0, rtol=1e-12)


def test_requirement_above_the_machine_is_capped():
    # 100 mm blocks: K L = 6e7 RPM^2, room to reach the top speed in two blocks
    s = plan(blocks([5000.0] * 5 + [np.inf] * 5 + [20000.0] * 5, length=100.0))
    assert np.all(s <= MACHINE.max_rpm + 1e-9)
    assert s[5] == pytest.approx(math.sqrt(5000.0 ** 2 + K_LOOK * 100.0))
    assert np.allclose(s[7:], MACHINE.max_rpm)


def test_max_feed_caps_the_speed():
    machine = Machine(MACHINE.accel_rad_s2, max_rpm=12000.0, max_feed_mm_min=1000.0)
    s = plan(blocks([9000.0] * 10), machine=machine)
    assert np.allclose(s, 1000.0 / (CUT.fz_mm * TEETH))  # F = fz z S <= F_max


def test_single_step_up_ramps_at_k_per_mm(rng):
    n_lo, n_hi = 10, 150
    length = rng.uniform(0.5, 1.5, n_lo + n_hi)
    s = plan(blocks([2000.0] * n_lo + [8000.0] * n_hi, length=length))
    assert np.allclose(s[:n_lo], 2000.0)
    # the rise during block b uses block b's own length: S_b^2 = S_(b-1)^2 + K L_b
    s2 = 2000.0 ** 2 + K_LOOK * np.cumsum(length[n_lo:])
    expected = np.sqrt(np.minimum(s2, 8000.0 ** 2))
    assert np.allclose(s[n_lo:], expected, rtol=1e-9)
    ramp = s[n_lo:] < 8000.0 - 1e-6
    assert ramp.sum() >= 90  # (8000^2 - 2000^2) / K = 100 mm of ramp
    # and the profile reaches the requirement after it
    assert np.allclose(s[-10:], 8000.0)


def test_single_step_down_decelerates_before_the_step(rng):
    n_hi, n_lo = 150, 10
    length = rng.uniform(0.5, 1.5, n_hi + n_lo)
    req = np.array([8000.0] * n_hi + [2000.0] * n_lo)
    s = plan(blocks(req, length=length))
    assert np.all(s <= req + 1e-9)
    # the block before the step already runs at the lower speed: the spindle is still
    # at S_b while it slows down for block b + 1
    assert np.allclose(s[n_hi - 1:], 2000.0)
    # before it, the fall is as late as the limit allows: S_(b-1)^2 = S_b^2 + K L_b
    tail = np.cumsum(length[1:n_hi][::-1])[::-1]  # sum of L_(b+1) .. L_(n_hi-1)
    expected = np.sqrt(np.minimum(2000.0 ** 2 + K_LOOK * tail, 8000.0 ** 2))
    assert np.allclose(s[:n_hi - 1], expected, rtol=1e-9)


def test_rising_and_falling_ramps_within_the_limit_follow_the_requirement():
    n, c = 60, 0.5 * K_LOOK  # half the spindle's ability, per mm
    rise = np.sqrt(3000.0 ** 2 + c * np.arange(n))
    s = plan(blocks(rise))
    assert np.allclose(s, rise, rtol=1e-12)
    fall = rise[::-1]
    s = plan(blocks(fall))
    # each block keeps min(req_b, req_(b+1)) so the spindle is slow enough for both
    assert np.allclose(s[:-1], fall[1:], rtol=1e-12)
    assert s[-1] == pytest.approx(fall[-1])


def test_fz_band_limits_the_ratio_per_block():
    huge = Machine(accel_rad_s2=1e6, max_rpm=12000.0)  # the spindle limit never binds
    tol = 0.02
    # fz within +-tol while the spindle ramps inside a block: F from the harmonic mean
    # of the lowest and highest speed ("centred") allows S_hi / S_lo = (1 + tol) / (1 - tol),
    # F from the lowest speed ("below") allows 1 / (1 - tol)
    for policy, ratio in (("centred", (1 + tol) / (1 - tol)), ("below", 1 / (1 - tol))):
        opts = PlanOptions(fz_tolerance=tol, fz_policy=policy)
        s = plan(blocks([2000.0] * 5 + [8000.0] * 150), opts=opts, machine=huge)
        # the profile keeps 1 % of the budget and 2 RPM at the lowest cutting speed (2000)
        # in reserve, so integer S words can follow it
        per_block = ratio ** KEEP * np.exp(-2.0 / 2000.0)
        expected = np.minimum(2000.0 * per_block ** np.maximum(np.arange(155) - 4, 0),
                              8000.0)
        assert np.allclose(s, expected, rtol=1e-9), policy


def test_rapid_between_cuts_ramps_in_rpm_over_its_duration():
    # two cuts at 2000, a 0.5 s rapid, cuts at 8000: during the rapid S may change by
    # a * T = 500 RPM, then the cut ramps in S^2 again
    req = np.array([2000.0] * 3 + [np.inf] + [8000.0] * 120)
    cutting = np.isfinite(req)
    b = schedule.Blocks(length_mm=np.ones(req.size), req_rpm=req, cutting=cutting,
                       planned=np.ones(req.size, bool), time_s=np.full(req.size, 0.5),
                       fixed_rpm=np.zeros(req.size))
    s = plan(b)
    assert np.allclose(s[:3], 2000.0)
    assert s[3] == pytest.approx(2000.0 + A_RPM_S * 0.5 * KEEP)
    expected = np.sqrt(np.minimum(s[3] ** 2 + K_LOOK * np.arange(1, 121), 8000.0 ** 2))
    assert np.allclose(s[4:], expected, rtol=1e-9)


def test_fixed_blocks_keep_the_program_speed():
    req = np.array([3000.0] * 5 + [0.0] * 3 + [3000.0] * 5)
    planned = np.array([True] * 5 + [False] * 3 + [True] * 5)
    b = schedule.Blocks(length_mm=np.ones(13), req_rpm=req, cutting=planned,
                       planned=planned, time_s=np.ones(13), fixed_rpm=np.full(13, 1500.0))
    cap = schedule.caps(b, 0.0, 12000.0, lookahead=True)
    assert np.allclose(cap[5:8], 1500.0)
    s = plan(b)
    assert np.allclose(s[5:8], 1500.0)
    # the cut before them slows to what the spindle can shed during the first fixed
    # block (a T, linear in S: it does not cut), the cut after ramps from 1500 in S^2
    assert s[4] == pytest.approx(1500.0 + A_RPM_S * 1.0 * KEEP)
    assert s[8] == pytest.approx(math.sqrt(1500.0 ** 2 + K_LOOK * 1.0))


def test_forward_overshoots_where_lookahead_does_not():
    """Where the requirement drops faster than the spindle can slow, the paper's flow chart
    runs the cut above its speed: vc = vc_target * S / S_req > vc_target."""
    req = np.array([8000.0] * 20 + [2000.0] * 20)
    b = blocks(req)
    fwd = plan(b, how=schedule.forward)
    look = plan(b)
    vc_fwd = CUT.vc_m_min * fwd / req
    vc_look = CUT.vc_m_min * look / req
    assert vc_fwd[20] > 3 * CUT.vc_m_min  # sqrt(8000^2 - K) / 2000 = 3.98
    assert fwd[20] == pytest.approx(math.sqrt(8000.0 ** 2 - K))
    assert np.all(vc_look <= CUT.vc_m_min * (1 + 1e-12))
    # both respect the spindle's limit
    for s in (fwd, look):
        assert np.all(np.abs(np.diff(s ** 2)) <= K * 1.0 * (1 + 1e-9))


def test_forward_follows_a_rise_from_behind():
    req = np.array([2000.0] * 10 + [8000.0] * 150)
    fwd = plan(blocks(req), how=schedule.forward)
    expected = np.sqrt(np.minimum(2000.0 ** 2 + K * np.maximum(np.arange(160) - 9, 0),
                                  8000.0 ** 2))
    assert np.allclose(fwd, expected, rtol=1e-9)


# ------------------------------------------------------------------ emission ----
def emit(b, opts=LOOSE, s_lo=0.0, machine=MACHINE):
    """Profile and emitted S as schedule.plan() wires them: (profile, s_cmd, s_low, s_high)."""
    profile = schedule.lookahead(b, machine, CUT, TEETH, opts)
    incs = schedule.increments(b, machine, profile.k_rpm2_per_mm)
    cut_caps = profile.cap_rpm[b.cutting & b.planned]
    ratio = schedule.max_speed_ratio(opts, CUT, TEETH, cut_caps.min() if cut_caps.size else 1.0)
    return (profile, *schedule.emit_rpm(profile, b, incs, opts, s_lo, ratio))


@pytest.mark.parametrize("rpm", [5000.7, 5000.0, 1393.0, 12000.0])
def test_emission_of_a_constant_requirement_is_constant(rpm):
    """One S word for a constant requirement: no toggling by min_rpm_step (the profile
    may sit an ulp below the requirement after the log-space pass)."""
    profile, cmd, low, high = emit(blocks([rpm] * 20))
    assert np.all(cmd == cmd[0])
    assert math.floor(rpm) - 1 <= cmd[0] <= rpm
    assert np.all(low == cmd[0]) and np.all(high == cmd[0])


@pytest.mark.parametrize("rpm", [1393.0, 2000.0, 3001.0, 5000.0, 12000.0])
@pytest.mark.parametrize("tolerance", [0.02, 0.5])
def test_an_integer_requirement_is_emitted_as_itself(rpm, tolerance):
    """A requirement met exactly is no reason to run one RPM slower."""
    profile, cmd, low, high = emit(blocks([rpm] * 20), PlanOptions(fz_tolerance=tolerance))
    assert cmd.tolist() == [rpm] * 20


@pytest.mark.parametrize("policy", ["centred", "below"])
def test_emission_of_a_step_up_rises_in_steps(policy):
    b = blocks([2000.0] * 10 + [8000.0] * 150, length=1.0)
    opts = PlanOptions(fz_tolerance=0.5, min_rpm_step=50.0, fz_policy=policy)
    profile, cmd, low, high = emit(b, opts)
    assert np.all(cmd == np.floor(cmd))
    steps = np.diff(cmd)
    assert np.all((steps == 0) | (np.abs(steps) >= 50.0))
    assert np.all(steps >= 0)  # a rising requirement never makes S fall
    assert np.all(cmd <= profile.s_rpm + 1.0)
    assert cmd[0] >= 2000.0 - 1 and cmd[-1] >= 8000.0 - 50.0
    assert np.all(low <= high)
    # F from the real speeds keeps fz inside its band at both ends of every block
    f = schedule.feeds(low, high, b, CUT, TEETH, np.inf, policy)
    fz_at_low = f / (TEETH * low)
    fz_at_high = f / (TEETH * high)
    top = CUT.fz_mm if policy == "below" else CUT.fz_mm * (1 + 0.5)
    assert np.all(fz_at_low <= top * (1 + 1e-12))
    assert np.all(fz_at_high >= CUT.fz_mm * (1 - 0.5) * (1 - 1e-12))


# ------------------------------------------------------ _two_way_min reference ----
def two_way_min_reference(x, inc):
    """The definition: y_b = min over j of x_j + (sum of inc between j and b), where an
    infinite inc cuts the chain (O(n^2), written for clarity)."""
    n = len(x)
    y = list(x)
    for b in range(n):
        for j in range(n):
            lo, hi = min(j, b), max(j, b)
            dist = sum(inc[k] for k in range(lo + 1, hi + 1))
            if math.isfinite(dist):
                y[b] = min(y[b], x[j] + dist)
    return np.array(y)


INC = st.one_of(st.floats(0.0, 5e6), st.just(math.inf), st.just(0.0))


@given(st.integers(1, 40).flatmap(lambda n: st.tuples(
    st.lists(st.floats(0.0, 2.5e8), min_size=n, max_size=n),
    st.lists(INC, min_size=n, max_size=n))))
def test_two_way_min_matches_the_definition(data):
    x, inc = (np.array(v, dtype=float) for v in data)
    got = schedule._two_way_min(x, inc)
    want = two_way_min_reference(x.tolist(), inc.tolist())
    # round-off relative to the largest value (the segment offsets add up in one accumulate)
    tol = 1e-12 * (1.0 + np.max(np.abs(x)) + np.sum(inc[np.isfinite(inc)])) * len(x)
    assert np.allclose(got, want, rtol=0, atol=tol)
    # it is the largest y under x that keeps every finite constraint, both ways
    assert np.all(got <= x + tol)
    fin = np.isfinite(inc[1:])
    assert np.all(np.abs(np.diff(got)[fin]) <= inc[1:][fin] + tol)


LOG_INC = st.one_of(st.floats(0.0, 0.1), st.just(math.inf), st.just(math.log(1 / 0.98)))


@given(st.integers(1, 30).flatmap(lambda n: st.tuples(
    st.lists(st.floats(-20.0, 20.0), min_size=n, max_size=n),
    st.lists(LOG_INC, min_size=n, max_size=n))))
def test_two_way_min_in_log_space(data):
    """The same passes run on log S (the fz band): small and negative values."""
    x, inc = (np.array(v, dtype=float) for v in data)
    got = schedule._two_way_min(x, inc)
    want = two_way_min_reference(x.tolist(), inc.tolist())
    tol = 1e-12 * (1.0 + np.max(np.abs(x)) + np.sum(inc[np.isfinite(inc)])) * len(x)
    assert np.allclose(got, want, rtol=0, atol=tol)


# --------------------------------------------- minimal cases found by the properties ----
def test_emitted_speed_never_below_the_machine_minimum():
    machine = Machine(accel_rad_s2=100.0, max_rpm=12000.0, min_rpm=299.5)
    opts = PlanOptions(min_rpm_step=5.0)
    profile, cmd, low, high = emit(blocks([300.0] * 12), opts, s_lo=299.5, machine=machine)
    assert np.all(profile.s_rpm >= 299.5)
    assert np.all(cmd >= 300.0), cmd  # ceil(min_rpm): the spindle cannot run slower


def test_a_cut_after_an_unplanned_block_is_not_planned_faster_than_reachable():
    """The S of an unplanned block is the program's: the look-ahead must not pretend it
    can lower it.  Here the program runs 3000 RPM before a cut that needs 1000; a spindle
    of 95 RPM/s cannot get there, so the emitted S stays near 3000 while the profile
    claims 1000 (vc three times its target, silently)."""
    b = schedule.Blocks(length_mm=np.ones(4), req_rpm=np.array([np.inf, 1000.0, 1000.0, 1000.0]),
                       cutting=np.array([False, True, True, True]),
                       planned=np.array([False, True, True, True]), time_s=np.ones(4),
                       fixed_rpm=np.full(4, 3000.0))
    slow = Machine(accel_rad_s2=10.0, max_rpm=12000.0)
    profile, cmd, low, high = emit(b, PlanOptions(), machine=slow)
    assert profile.s_rpm[0] == pytest.approx(3000.0)  # what the block really runs at
    assert np.all(cmd[1:] <= profile.s_rpm[1:] + 1.0)


def test_no_s_word_above_the_feed_limited_top_after_a_faster_unplanned_block():
    """The program keeps 12000 RPM in a block ncopt leaves alone; the cuts after it need
    9000 RPM, but F is limited to 1000 mm/min, so fz 0.1 x 2 teeth caps S at 5000.  The
    profile follows the spindle falling from 12000; the S words must still ask for no
    more than 5000 (the spindle then falls as fast as it can, as the profile assumes)."""
    n = 8
    b = schedule.Blocks(length_mm=np.full(n, 0.5), req_rpm=np.array([np.inf] + [9000.0] * (n - 1)),
                       cutting=np.array([False] + [True] * (n - 1)),
                       planned=np.array([False] + [True] * (n - 1)), time_s=np.full(n, 0.1),
                       fixed_rpm=np.full(n, 12000.0))
    machine = Machine(accel_rad_s2=A_RPM_S * 2 * math.pi / 60, max_rpm=12000.0,
                      max_feed_mm_min=1000.0)
    s_lo, s_hi = schedule.speed_limits(machine, CUT, TEETH)
    assert s_hi == pytest.approx(5000.0)
    profile = schedule.lookahead(b, machine, CUT, TEETH, LOOSE)
    assert profile.s_rpm[1] > 5500.0  # still falling from the program's 12000
    incs = schedule.increments(b, machine, profile.k_rpm2_per_mm)
    uncapped = schedule.emit_rpm(profile, b, incs, LOOSE, s_lo, 3.0)
    assert uncapped.s_cmd_rpm[1] > s_hi  # what the emission did without the limit
    em = schedule.emit_rpm(profile, b, incs, LOOSE, s_lo, 3.0, s_hi=s_hi)
    assert np.all(em.s_cmd_rpm[1:] <= 5000.0)
    assert np.all(em.s_high_rpm[1:] <= profile.s_rpm[:-1] + 1.0)  # the real speed falls


def test_the_lowest_speed_wins_over_a_feed_limited_top_below_it():
    """--min-rpm 3000 with a feed limit of 200 mm/min (fz 0.1 x 2: top 1000 RPM): the
    S words stay at the spindle's lowest speed, never under it (F is capped anyway)."""
    n = 6
    b = schedule.Blocks(length_mm=np.ones(n), req_rpm=np.full(n, 500.0),
                       cutting=np.ones(n, bool), planned=np.ones(n, bool),
                       time_s=np.ones(n), fixed_rpm=np.zeros(n))
    machine = Machine(accel_rad_s2=A_RPM_S * 2 * math.pi / 60, max_rpm=12000.0,
                      min_rpm=3000.0, max_feed_mm_min=200.0)
    em, f, _ = schedule.plan(b, machine, CUT, TEETH, LOOSE)
    assert np.all(em.s_cmd_rpm == 3000.0)
    assert np.all(f <= 200.0 + 1e-9)


def test_a_command_under_a_spindle_still_falling_keeps_the_fz_band():
    """The program keeps 529 then 346 RPM in two short blocks ncopt leaves alone; the real
    spindle is still at ~522 RPM when the next cut begins, planned at ~457.8.  Flooring
    the command to 457 would let the real speed fall by more than the fz band's ratio
    within that block (fz over its band at the block's slowest speed): the command is
    held at the band's floor, ceil(522.16 / ratio) = 458, one RPM within the profile."""
    b = schedule.Blocks(length_mm=np.array([0.417, 0.01, 1.476]),
                       req_rpm=np.array([np.inf, np.inf, 20633.6]),
                       cutting=np.array([False, False, True]),
                       planned=np.array([False, False, True]),
                       time_s=np.array([0.417, 0.001, 1.476]),
                       fixed_rpm=np.array([529.0, 346.0, 560.0]))
    machine = Machine(accel_rad_s2=716.4137, max_rpm=8657.4, min_rpm=345.36,
                      max_feed_mm_min=5000.0)
    cut = CuttingData(vc_m_min=100.0, fz_mm=0.15074388)
    opts = PlanOptions(min_rpm_step=10.0, fz_tolerance=0.0665056)
    profile = schedule.lookahead(b, machine, cut, 4, opts)
    incs = schedule.increments(b, machine, profile.k_rpm2_per_mm)
    s_lo, s_hi = schedule.speed_limits(machine, cut, 4)
    ratio = schedule.max_speed_ratio(opts, cut, 4, float(profile.cap_rpm[2]))
    em = schedule.emit_rpm(profile, b, incs, opts, s_lo, ratio, s_hi=s_hi)
    assert em.s_high_rpm[2] == pytest.approx(522.1587531)  # the spindle entering the cut
    assert em.s_high_rpm[2] / em.s_low_rpm[2] <= ratio
    assert em.s_cmd_rpm[2] == 458.0 <= profile.s_rpm[2] + 1.0


def test_a_fall_toward_a_block_the_program_keeps_lower_stays_within_the_profile():
    """A chain of falls held by a narrow fz band (1.5 %) toward a block ncopt leaves at the
    program's S491, far below the lowest requirement (7506 RPM): each fall's integer S word
    is rounded up by < 1 RPM, and with a reserve for that kept at the lowest requirement the
    chain ran 1.09 RPM over the profile at 552.9 RPM (S554).  The reserve is kept at the
    lowest speed a cut is planned at: every cut's S word within 1 RPM of the profile."""
    b = schedule.Blocks(
        length_mm=np.array([
            3.08824797, 4.82062823, 2.28603168, 3.11478104, 0.93575436, 4.33850422,
            0.46900177, 2.23610492, 3.48590527, 1.34890919, 1.51649621, 0.01, 2.91991108,
            4.78744289, 2.76280662, 3.82795001, 3.72884456, 0.27826807]),
        req_rpm=np.array([
            6598.39840027, np.inf, np.inf, np.inf, 39215.02664829, np.inf, 10000., 39999.,
            np.inf, 32068.25640523, np.inf, np.inf, np.inf, 7506.26270076, 7917.92699782,
            np.inf, np.inf, 30538.46480529]),
        cutting=np.array([
            False, False, True, False, True, True, True, True, True, True, True, False,
            True, True, False, False, False, True]),
        planned=np.array([
            True, True, True, True, True, True, True, True, True, True, True, False, True,
            True, False, False, True, True]),
        time_s=np.array([
            1.00000000e-03, 1.00000000e-03, 1.00000000e-03, 1.00000000e-03, 9.35754356e-01,
            1.00000000e-03, 4.69001771e-01, 1.00000000e-03, 1.00000000e-03, 1.34890919e+00,
            1.51649621e+00, 1.00000000e-02, 1.00000000e-03, 1.00000000e-03, 1.00000000e-03,
            1.00000000e-03, 1.00000000e-03, 2.78268072e-01]),
        fixed_rpm=np.full(18, 491.0))
    machine = Machine(accel_rad_s2=654.9200274369349, max_rpm=11186.031144651603,
                      min_rpm=490.0, max_feed_mm_min=20000.0)
    cut = CuttingData(vc_m_min=100.0, fz_mm=0.0947859319428369)
    opts = PlanOptions(min_rpm_step=2.0, fz_tolerance=0.01496852135245836)
    profile = schedule.lookahead(b, machine, cut, 4, opts)
    incs = schedule.increments(b, machine, profile.k_rpm2_per_mm)
    s_lo, s_hi = schedule.speed_limits(machine, cut, 4)
    cuts = b.cutting & b.planned
    ratio = schedule.max_speed_ratio(opts, cut, 4, float(profile.cap_rpm[cuts].min()))
    em = schedule.emit_rpm(profile, b, incs, opts, s_lo, ratio, s_hi=s_hi)
    assert np.all(em.s_cmd_rpm[cuts] <= profile.s_rpm[cuts] + 1.0)
    assert em.s_cmd_rpm[10] < 554.0  # the word of the old excess


def test_a_full_step_down_never_crosses_the_blocks_own_band_floor():
    """A forced fall smaller than --min-rpm-step (16) became a full step to S299, one RPM
    below the fz band's floor for the spindle still at 330.4 RPM in that block (F from the
    lowest speed): fz 0.003 % under its band (a case of test_properties' random runs).
    The full step is taken only where it stays within the block's band."""
    F, T = False, True
    b = schedule.Blocks(
        length_mm=np.array([
            0.89842116, 2.77049919, 1.59300144, 4.76466962, 3.84122682, 2.80256018,
            3.66405339, 0.16928337, 1.78513202, 4.87197308, 4.23569033, 3.64697279,
            2.90711781, 2.50545672, 3.75467333, 0.83784583, 0.04366095, 3.30693493,
            2.39075785, 4.84890672, 2.42645832, 4.58571395, 2.00001, 1.51435795, 0.80104327,
            0.7966265, 1.61561788, 0.844296, 1.35725106]),
        req_rpm=np.array([
            np.inf, np.inf, 35946.31392411, np.inf, 11972.66398855, np.inf, np.inf,
            13759.76286985, np.inf, np.inf, 300., 360., 300., 13841.17192776, np.inf,
            np.inf, 8852.64809843, np.inf, np.inf, 22202.94411498, np.inf, np.inf, np.inf,
            np.inf, np.inf, 29582.70449545, np.inf, np.inf, np.inf]),
        cutting=np.array([
            F, F, T, F, F, F, F, T, T, F, F, F, F, T, F, F, F, T, T, F, F, F, F, F, F, F, F,
            F, T]),
        planned=np.array([
            T, T, T, F, F, T, F, T, T, T, F, T, T, T, T, F, F, T, T, T, F, F, T, F, T, F, T,
            F, T]),
        time_s=np.array([
            8.98421160e-01, 1.00000000e-03, 1.59300144e+00, 1.00000000e-03, 1.00000000e-03,
            1.00000000e-03, 1.00000000e-03, 1.69283368e-01, 1.78513202e+00, 1.00000000e-03,
            1.00000000e-03, 1.00000000e-03, 1.00000000e-03, 1.00000000e-03, 1.00000000e-03,
            8.37845830e-01, 4.36609455e-02, 1.00000000e-03, 1.00000000e-03, 1.00000000e-03,
            1.00000000e-03, 1.00000000e-03, 1.00000000e-03, 1.51435795e+00, 8.01043273e-01,
            7.96626501e-01, 1.61561788e+00, 8.44296003e-01, 1.35725106e+00]),
        fixed_rpm=np.full(29, 301.0))
    machine = Machine(accel_rad_s2=66.5469267672768, max_rpm=22187.64373438376,
                      min_rpm=28.372686712254687, max_feed_mm_min=5000.0)
    cut = CuttingData(vc_m_min=100.0, fz_mm=0.14951868212349337)
    opts = PlanOptions(min_rpm_step=16.0, fz_tolerance=0.09490863374665456, fz_policy="below")
    profile = schedule.lookahead(b, machine, cut, 3, opts)
    incs = schedule.increments(b, machine, profile.k_rpm2_per_mm)
    s_lo, s_hi = schedule.speed_limits(machine, cut, 3)
    cuts = b.cutting & b.planned
    ratio = schedule.max_speed_ratio(opts, cut, 3, float(profile.cap_rpm[cuts].min()))
    cmd, low, high = schedule.emit_rpm(profile, b, incs, opts, s_lo, ratio, s_hi=s_hi)
    f = schedule.feeds(low, high, b, cut, 3, machine.max_feed_mm_min, "below")
    fz_lowest = f[cuts] / (3 * high[cuts])
    assert np.all(fz_lowest >= cut.fz_mm * (1 - opts.fz_tolerance) * (1 - 1e-9))
