"""Spindle profile -> integer S words, one block at a time.

The planned profile (:mod:`ncopt.planning.schedule`) is real-valued; a control takes
integer S words, and the real spindle only ramps toward each at its acceleration.  The
emission walks the blocks in order, keeps the S commanded and the real speed it gives,
and chooses each block's word: hold, rise or fall by at least ``--min-rpm-step``, never
above the profile (vc stays under its target), never out of the fz band.

The walk is a sequential hysteresis that runs once per block (1M blocks in a big
program): it reads and writes memoryviews of the arrays (their items are Python floats
and bools, as with tolist(), without building lists of 1M objects first), a steady block
costs no call, a block's time (with ``--min-s-interval-ms``) is an expression in the loop
rather than a call, and ``b if b > a else a`` stands for max(a, b) (exactly: the first of
equals, NaN alike, the same type; ``b if b < a else a`` for min), at a third of the cost
of the builtin call.  A compiled walk (numba) was measured and not taken: this walk
costs about 0.6 us of CPU a block (0.6 s over 1M blocks); importing numba and loading the
compiled walk from its cache costs 0.3-0.5 s, compiling it (a cold cache, or every run
where no cache folder is writable) 1.2-2 s, and numba with llvmlite installs 200 MB.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ncopt.model import PlanOptions
from ncopt.planning.spindle import Blocks, Profile


@dataclass(frozen=True)
class Emitted:
    """Integer S commands and the real spindle speeds they give, per block.

    s_cmd_rpm : commanded S;  s_low_rpm, s_high_rpm : lowest and highest real speed
    in the block;  close_s_words : falls that came sooner than ``min_s_interval_ms``
    after the previous S word (vc needs them; the control may pause there)
    """

    s_cmd_rpm: np.ndarray
    s_low_rpm: np.ndarray
    s_high_rpm: np.ndarray
    close_s_words: int = 0

    def __iter__(self):
        """Unpacks as ``s_cmd, s_low, s_high``."""
        return iter((self.s_cmd_rpm, self.s_low_rpm, self.s_high_rpm))


@dataclass(frozen=True)
class _Rules:
    """What bounds every S word of one emission.

    step : the smallest change of S (RPM);  lo_int, top : the lowest and highest S word
    (RPM, integers; top may be inf);  ratio : the fz band's largest ratio of the real
    speeds within a cutting block (inf: no band);  interval_s : the shortest time
    between S words (0: no such rule);  feed_per_rev_mm : fz z, for the blocks' times
    """

    step: float
    lo_int: int
    top: float
    ratio: float
    interval_s: float
    feed_per_rev_mm: float


def emit_rpm(profile: Profile, blocks: Blocks, incs: tuple, opts: PlanOptions,
             s_lo: float, ratio: float, feed_per_rev_mm: float = 0.0,
             s_hi: float = math.inf) -> Emitted:
    """Integer S commands per block, and the lowest real spindle speed in each block.

    S changes only by at least ``opts.min_rpm_step`` (but for a last fall onto the
    spindle's lowest speed) and never rises above the planned profile, so vc stays
    under its target.  The real spindle is
    tracked: a rise may take several short blocks to complete (F then follows
    the real, lower speed, so fz never exceeds its target), a fall always
    completes inside its block (the plan's look-ahead made room for it), and
    within one block the speed changes by at most the fz-band ratio.
    This is a sequential hysteresis, one step per block.

    With ``opts.min_s_interval_ms`` a rise waits until that long after the
    previous S word (block times estimated at F = fz z S, ``feed_per_rev_mm``
    = fz z); a fall never waits.

    ``s_lo``, ``s_hi`` (RPM): the speed limits of :func:`ncopt.planning.spindle.speed_limits`.
    No S word asks for more than ``s_hi``, even where the profile follows a spindle still
    falling from a higher S the program keeps (the fall is then as fast as the
    spindle allows, and F is capped by the feed limit anyway).
    """
    lo_int = math.ceil(s_lo)
    # the spindle's lowest speed wins over the feed-limited top (F is capped there anyway)
    top = max(math.floor(s_hi), lo_int) if math.isfinite(s_hi) else math.inf
    rules = _Rules(opts.min_rpm_step, lo_int, top, ratio, opts.min_s_interval_ms / 1000.0,
                   feed_per_rev_mm)
    columns = _columns(profile, blocks, incs, rules.interval_s > 0)
    n = len(columns[0])
    out = np.zeros(n), np.zeros(n), np.zeros(n)  # S commanded, lowest and highest real speed
    close = _walk(columns, blocks.fixed_rpm, rules, out)
    return Emitted(*out, close)


def _columns(profile: Profile, blocks: Blocks, incs: tuple, timed: bool) -> tuple:
    """The per-block inputs of the walk, as memoryviews of Python floats and bools: the
    profile (snapped), fixed, spindle start, cutting, the two increments of
    :func:`ncopt.planning.spindle.increments`, and (only when ``timed``) 60 times the
    length (mm s/min: over a feed in mm/min, the block's time in s) and the time of a block
    at its own feed."""
    inc_s2, inc_s = (_items(a, np.float64) for a in incs)
    # 60.0 * L first, as the walk's 60.0 * L / F did: the same product, the same bits
    timing = ((_items(60.0 * np.asarray(blocks.length_mm, dtype=np.float64), np.float64),
               _items(blocks.time_s, np.float64)) if timed else (None, None))
    return (_items(snapped(profile.s_rpm), np.float64), _items(~blocks.planned, bool),
            _items(blocks.spindle_start, bool), _items(blocks.cutting & blocks.planned, bool),
            inc_s2, inc_s, *timing)


def _walk(columns: tuple, fixed_rpm: np.ndarray, rules: _Rules, out: tuple) -> int:
    """Fill ``out`` (S commanded, lowest and highest real speed per block) block by block;
    returns the count of falls that came sooner than ``rules.interval_s`` after the
    previous S word.  ``fixed_rpm`` is read only in fixed blocks (no list of 1M floats)."""
    s_plan, fixed, starts, cutting, inc_s2, inc_s, length60, time_free = columns
    cmd_out, low_out, high_out = (memoryview(a) for a in out)
    step, lo_int, top, interval_s = rules.step, rules.lo_int, rules.top, rules.interval_s
    ratio, per_rev_mm = rules.ratio, rules.feed_per_rev_mm  # fz z: a cut's F = fz z S
    per_rev = per_rev_mm > 0
    band, timed = not math.isinf(ratio), interval_s > 0  # untimed: the clock never matters
    floor, sqrt, inf = math.floor, math.sqrt, math.inf
    cur = real = None
    since_s, close = inf, 0
    for b, target, fixed_b, start_b, cut_b, inc2_b, inc_b in zip(
            range(len(s_plan)), s_plan, fixed, starts, cutting, inc_s2, inc_s):
        before = cur
        if fixed_b:
            cur = float(fixed_rpm[b])
            if not cur > 0:  # the program runs this block with no S in force
                real = None
        elif cur is None or start_b or not cur > 0:  # a (re)start: the control brings it up
            cur = real = float(min(max(floor(target), lo_int), top))
        elif real == cur and cur <= target < cur + step:  # holding steady: nothing to do
            cmd_out[b] = low_out[b] = high_out[b] = cur
            if timed:  # a cut at F = fz z S (max(cur, 1.0) spelled out), else at its own F
                since_s += (length60[b] / (per_rev_mm * (1.0 if 1.0 > cur else cur))
                            if cut_b and per_rev else time_free[b])
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
            if banded and new > real and new > real * r:
                new = _within_band(new, cur, real, r, step)
            cur = lo_int if lo_int > new else new
            if cur > top:  # a step from the previous command, or else the limit itself
                cur = before if before <= top and top - before < step else float(top)
            if timed and since_s < interval_s:  # the control is still taking the last S word
                if cur > before:
                    cur = before  # a rise waits
                elif cur < before:
                    close += 1
        # the real speed at the block's end: toward cur, S^2 moves by <= inc2_b, S by <= inc_b
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
        if timed:  # the clock restarts at a new S word; a cut at its lowest real speed
            low = start if start < real else real
            since_s = (since_s if cur == before else 0.0) + (
                length60[b] / (per_rev_mm * (1.0 if 1.0 > low else low))
                if cut_b and per_rev else time_free[b])
    return close


def _within_band(new: float, cur: float, real: float, r: float, step: float) -> float:
    """A command above the real speed (the spindle still rising, e.g. after the program's
    own S) may let it rise by no more than the fz band (ratio ``r``) in the block; and the
    change keeps to at least one step, but for a step down that the spindle, still rising,
    would fall by more than the band over this block and the next: the band comes first,
    a smaller change."""
    ceiling = math.floor(real * r)
    if not new > ceiling:
        return new
    new = float(ceiling)
    if abs(new - cur) < step:
        if cur <= ceiling:
            new = cur
        elif (cur - step) * r >= real:
            new = cur - step
    return new


def _rise(target: float, cur: float, real: float, r: float, banded: bool,
          step: float) -> float:
    """A rise toward ``target``, by at least ``step``: the fz band (ratio ``r``) bounds
    it by the real speed."""
    up = real * r
    up = math.floor(up if up < target else target)
    new = float(up) if up >= cur + step else cur
    if banded and new < real:
        # above the command, the real speed still falls (from a faster S the program
        # keeps): the fz band bounds that fall as any other
        up = float(math.ceil(real / r))
        if up > new:
            new = up
        if 0 < new - cur < step:  # target >= cur + step: vc stays under it
            new = cur + step
    return new


def _fall(target: float, cur: float, real: float, r: float, banded: bool, step: float,
          inc2_b: float, inc_b: float, band: float) -> float:
    """A fall to ``target`` now, with margin against chatter.  The spindle limit
    (``inc2_b`` RPM^2, ``inc_b`` RPM over the block) may leave the real speed up to 1 RPM
    above an integer command (the ramp tracking keeps the real value); the fz band
    (ratio ``r``) may not be crossed at all."""
    floor = math.floor
    sq = real * real - inc2_b
    reach = math.sqrt(0.0 if 0.0 > sq else sq)
    lin = real - inc_b
    if lin > reach:
        reach = lin
    band_floor = math.ceil(real / r) if banded else 0
    low = floor(reach)
    if band_floor > low:
        low = band_floor
    if 0 > low:
        low = 0
    new = floor(target - step + 1)
    if new < target * 0.5:  # a margin of a large step falls no further than half the target
        new = floor(target * 0.5)  # (S0 at worst, the cut then crawling at F = fz z S)
    if low > new:
        new = low
    top_b = floor(target)
    if low <= top_b:
        if top_b < new:
            new = top_b
    else:
        new = low
    if 0 < cur - new < step:  # a forced fall smaller than a step: a full step, unless
        # the spindle gets less than the fz band (ratio ``band``) short of it in the block
        # (the rest of such a fall runs on into the blocks after it, where no F was planned
        # for it: fz leaves its band there), or it would end at S0 or below (without
        # --min-rpm): then onto the target, or as far as the spindle gets
        full = cur - step
        # (never below this block's own band floor: a full step there takes fz out of its
        # band within the block, by 0.003 % in a case of test_properties' random runs)
        if full >= band_floor and full > 0 and low <= full * band:
            new = full
        else:  # a smaller fall: onto the target (vc), as far as the spindle gets
            new = low if low > top_b else top_b
    return float(new)


def _items(a: np.ndarray, dtype) -> memoryview:
    """A read-only view of ``a``'s items as Python objects (floats, bools), like a list."""
    return memoryview(np.ascontiguousarray(a, dtype=dtype)).toreadonly()


def snapped(rpm: np.ndarray) -> np.ndarray:
    """A profile a few ulps under an integer is that integer (exp(log(x)) != x)."""
    near = np.round(rpm)
    return np.where(np.abs(rpm - near) < 1e-9 * np.maximum(rpm, 1.0), near, rpm)

