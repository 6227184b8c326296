"""The emission's per-block kernel (``ncopt.planning.emission._walk``) against its reference.

The walk was made faster in place (a block's time with ``--min-s-interval-ms`` is an
expression in the loop, 60 x the length taken once per block by numpy); its outputs must not
change by one bit.  ``_reference_emit`` below is the walk as it was before, kept verbatim as
the reference, and a property test holds the two to the same bits (S commanded, lowest and
highest real speed per block, and the count of close S words) over generated block columns:
fixed blocks (with NaN, 0 and running speeds), spindle starts, cutting and non-cutting blocks,
banded (finite ratio) and unbanded, timed (an interval) and untimed, top infinite and finite.
A compiled walk was measured and not taken (why: :mod:`ncopt.planning.emission`); the same
test would hold one to these bits.
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ncopt.model import PlanOptions
from ncopt.planning.emission import _fall, _items, _rise, _Rules, emit_rpm, snapped
from ncopt.planning.spindle import Blocks, Profile


def _reference_emit(profile, blocks, incs, opts, s_lo, ratio, feed_per_rev_mm, s_hi):
    """``emit_rpm`` before the walk was sped up: its columns and its walk, as they were."""
    lo_int = math.ceil(s_lo)
    top = max(math.floor(s_hi), lo_int) if math.isfinite(s_hi) else math.inf
    rules = _Rules(opts.min_rpm_step, lo_int, top, ratio, opts.min_s_interval_ms / 1000.0,
                   feed_per_rev_mm)
    timed = rules.interval_s > 0
    timing = ((_items(blocks.length_mm, np.float64), _items(blocks.time_s, np.float64))
              if timed else (None, None))
    columns = (_items(snapped(profile.s_rpm), np.float64), _items(~blocks.planned, bool),
               _items(blocks.spindle_start, bool), _items(blocks.cutting & blocks.planned, bool),
               *(_items(a, np.float64) for a in incs), *timing)
    n = len(columns[0])
    out = np.zeros(n), np.zeros(n), np.zeros(n)
    close = _reference_walk(columns, blocks.fixed_rpm, rules, out)
    return (*out, close)


def _reference_walk(columns, fixed_rpm, rules, out):
    """``emission._walk`` as it was (a call per block for its time), verbatim."""
    s_plan, fixed, starts, cutting, inc_s2, inc_s, length, time_free = columns
    cmd_out, low_out, high_out = (memoryview(a) for a in out)
    step, lo_int, top, interval_s = rules.step, rules.lo_int, rules.top, rules.interval_s
    ratio, feed_per_rev_mm = rules.ratio, rules.feed_per_rev_mm
    band = not math.isinf(ratio)
    timed = interval_s > 0
    floor, sqrt, inf = math.floor, math.sqrt, math.inf
    cur = real = None
    since_s, close = inf, 0
    for b, target, fixed_b, start_b, cut_b, inc2_b, inc_b in zip(
            range(len(s_plan)), s_plan, fixed, starts, cutting, inc_s2, inc_s):
        before = cur
        if fixed_b:
            cur = float(fixed_rpm[b])
            if not cur > 0:
                real = None
        elif cur is None or start_b or not cur > 0:
            cur = real = float(min(max(floor(target), lo_int), top))
        elif real == cur and cur <= target < cur + step:
            cmd_out[b] = low_out[b] = high_out[b] = cur
            if timed:
                since_s += _reference_block_s(cut_b, length[b], time_free[b], feed_per_rev_mm,
                                              cur)
            continue
        else:
            r = ratio if cut_b else inf
            banded = cut_b and band
            if target >= cur + step:
                new = _rise(target, cur, real, r, banded, step)
            elif target < cur:
                new = _fall(target, cur, real, r, banded, step, inc2_b, inc_b, ratio)
            else:
                new = cur
            if banded:
                ceiling = floor(real * r)
                if new > real and new > ceiling:
                    new = float(ceiling)
                    if abs(new - cur) < step:
                        if cur <= ceiling:
                            new = cur
                        elif (cur - step) * r >= real:
                            new = cur - step
            cur = lo_int if lo_int > new else new
            if cur > top:
                cur = before if before <= top and top - before < step else float(top)
            if timed and since_s < interval_s:
                if cur > before:
                    cur = before
                elif cur < before:
                    close += 1
        start = cur if real is None else real
        if start == cur:
            real = cur
        elif cur > start:
            sq = sqrt(start * start + inc2_b)
            real = sq if sq < cur else cur
            lin = start + inc_b
            if lin < real:
                real = lin
        else:
            sq = start * start - inc2_b
            sq = sqrt(0.0 if 0.0 > sq else sq)
            real = sq if sq > cur else cur
            lin = start - inc_b
            if lin > real:
                real = lin
        if start < real:
            cmd_out[b], low_out[b], high_out[b] = cur, start, real
        else:
            cmd_out[b], low_out[b], high_out[b] = cur, real, start
        if timed:
            since_s = (since_s if cur == before else 0.0) + _reference_block_s(
                cut_b, length[b], time_free[b], feed_per_rev_mm, start if start < real else real)
    return close


def _reference_block_s(cut_b, length_mm, time_s, feed_per_rev_mm, speed_rpm):
    """``emission._block_s`` as it was: a block's time (s)."""
    return (60.0 * length_mm / (feed_per_rev_mm * max(speed_rpm, 1.0))
            if cut_b and feed_per_rev_mm > 0 else time_s)


@st.composite
def _cases(draw):
    """Block columns and the emission's rules: (profile, blocks, incs, opts, s_lo, ratio,
    feed per rev mm, s_hi).  Hypothesis draws the shape (how smooth the profile, how many
    fixed, starting and cutting blocks, how fast the spindle may change, the rules) and a
    seed; numpy draws the blocks from them."""
    n = draw(st.integers(1, 120))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    share = st.sampled_from([0.0, 0.05, 0.3, 0.7, 1.0])  # of blocks that are so
    s_rpm = rng.uniform(200.0, 16000.0, n)
    scale = draw(st.sampled_from([0.0, 0.05, 0.3, 1.0, 5.0, 30.0]))
    if scale:  # a smooth profile (RPM per block): holds, single steps and slow ramps
        s_rpm = np.clip(s_rpm[0] + np.cumsum(rng.uniform(-scale, scale, n)), 200.0, 16000.0)
    on_integer = rng.uniform(size=n) < draw(share)  # some on integers, some ulps under one
    s_rpm = np.where(on_integer, np.round(s_rpm) * (1.0 - 1e-15 * rng.integers(0, 2, n)),
                     s_rpm)
    # the program's own S: off (NaN), 0, near the profile or far below it (a fall to make)
    fixed_rpm = np.round(s_rpm * rng.choice([0.3, 0.9, 1.0, 1.1, 1.5], n))
    fixed_rpm[rng.uniform(size=n) < draw(share)] = np.nan
    fixed_rpm[rng.uniform(size=n) < draw(share) / 4] = 0.0
    # the planned blocks: one by one, all, none (a replay), or after a fixed stretch
    planned = draw(st.sampled_from(["drawn", "all", "none", "after"]))
    planned = {"drawn": rng.uniform(size=n) >= draw(share), "all": np.ones(n, bool),
               "none": np.zeros(n, bool), "after": np.arange(n) >= n // 3}[planned]
    # the spindle's change per block: S^2 (cuts) and S (other blocks), sometimes unbounded
    inc2 = rng.uniform(0.0, draw(st.sampled_from([1e5, 3e6, 3e7])), n)
    inc2[rng.uniform(size=n) < draw(share)] = np.inf
    inc = rng.uniform(0.0, draw(st.sampled_from([20.0, 300.0, 3000.0])), n)
    inc[rng.uniform(size=n) < draw(share)] = np.inf
    blocks = Blocks(length_mm=rng.uniform(0.0, 2.0, n), req_rpm=s_rpm,
                    cutting=rng.uniform(size=n) >= draw(share), planned=planned,
                    time_s=rng.uniform(0.0, 0.2, n), fixed_rpm=fixed_rpm,
                    spindle_start=rng.uniform(size=n) < draw(share) / 5)
    opts = PlanOptions(min_rpm_step=draw(st.sampled_from([1.0, 10.0, 7.5, 100.0])),
                       min_s_interval_ms=draw(st.sampled_from([0.0, 0.0, 1.0, 100.0, 2000.0])))
    s_lo = draw(st.sampled_from([0.0, 500.0, 1234.5]))
    s_hi = draw(st.one_of(st.sampled_from([math.inf, 15000.0, 8000.7, 300.0]),
                          st.floats(-60.0, 60.0).map(lambda d: float(np.median(s_rpm)) + d)))
    ratio = draw(st.sampled_from([math.inf, 1.0347569470545248, 1.2, 2.0]))
    feed_per_rev_mm = draw(st.sampled_from([0.0, 0.200288, 0.05]))
    return (Profile(s_rpm, s_rpm, 1.0), blocks, (inc2, inc), opts, s_lo, ratio,
            feed_per_rev_mm, s_hi)


def _bits(a: np.ndarray) -> np.ndarray:
    """The float64 items as their bit patterns (NaN equals NaN, 0.0 differs from -0.0)."""
    return np.ascontiguousarray(a, dtype=np.float64).view(np.int64)


@settings(max_examples=1000, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_cases())
def test_walk_gives_the_reference_bits(case):
    """Every generated program: the same S words, real speeds and close count, bit for bit."""
    profile, blocks, incs, opts, s_lo, ratio, feed_per_rev_mm, s_hi = case
    got = emit_rpm(profile, blocks, incs, opts, s_lo, ratio, feed_per_rev_mm, s_hi)
    want = _reference_emit(profile, blocks, incs, opts, s_lo, ratio, feed_per_rev_mm, s_hi)
    for name, g, w in zip(("s_cmd", "s_low", "s_high"), got, want):
        assert np.array_equal(_bits(g), _bits(w)), name
    assert got.close_s_words == want[3]


def test_timed_walk_counts_close_words_as_the_reference():
    """A long timed run whose falls come within the interval: the clock (the inlined block
    time) decides the count, which must be the reference's and not zero."""
    rng = np.random.default_rng(7)
    n = 5000
    s_rpm = 6000.0 + 3000.0 * np.sin(np.arange(n) / 15.0) + rng.uniform(-50, 50, n)
    blocks = Blocks(length_mm=rng.uniform(0.05, 0.5, n), req_rpm=s_rpm,
                    cutting=rng.uniform(size=n) > 0.02, planned=np.ones(n, bool),
                    time_s=rng.uniform(0.0, 0.05, n), fixed_rpm=np.full(n, np.nan))
    incs = (np.full(n, 2e6), np.full(n, np.inf))
    opts = PlanOptions(min_rpm_step=10.0, min_s_interval_ms=100.0)
    args = (Profile(s_rpm, s_rpm, 1.0), blocks, incs, opts, 0.0, 1.0347569470545248, 0.2, 15000.0)
    got, want = emit_rpm(*args), _reference_emit(*args)
    assert want[3] > 0
    assert got.close_s_words == want[3]
    for g, w in zip(got, want):
        assert np.array_equal(_bits(g), _bits(w))

