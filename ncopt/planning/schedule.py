"""Required speed -> spindle-limited S profile -> F per block.

Works on *blocks* (source lines that move), because a control applies S and
F per block.  Units: S in RPM, lengths in mm, F in mm/min, accelerations in
RPM/s.  The constraint of METHOD.md, |d(S^2)/ds| <= K = 2*60*a/(fz*z), is
applied per block as |S_b^2 - S_(b-1)^2| <= K*L_b, so the ramp of a block
finishes inside it while F stays constant.

Deviation from METHOD.md, and why: a block's speed S_b is applied at its
start and the spindle ramps from S_(b-1) during the block, so the spindle
runs between both values inside block b.  vc therefore stays at or below its
target only if *both* are at most the block's requirement: the look-ahead
cap of block b is min(req_b, req_(b+1)).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ncopt.runtime.errors import PlanningError
from ncopt.motion.modal import ffill
from ncopt.model import CuttingData, Machine, PlanOptions

MAX_ITERATIONS = 200
# Profiles that agree to a ten-thousandth of an RPM are the same (S words are integers).
CONVERGED_RPM = 1e-4
# The profile keeps this share of the spindle's S^2 rate and of the fz band in
# reserve, so that integer S words (rounded toward the limits) can always follow
# it, even through a long deceleration at the full rate.
PLAN_MARGIN = 0.01


@dataclass(frozen=True)
class Blocks:
    """The program's moving blocks in order, (nb,) arrays.

    length_mm : path length of the block
    req_rpm : lowest required spindle speed along the block (inf: no requirement)
    cutting : the block cuts (has a requirement and is planned)
    planned : ncopt may set the block's S/F
    time_s : duration of non-cutting blocks at their own feed or the rapid rate
    fixed_rpm : programmed S in force (used for blocks that are not planned)
    spindle_start : the spindle (re)starts at this block (M3/M4 after a stop or a tool
        change): the control brings it to speed, nothing carries over from before
    running : the spindle turns during the block
    k_limited : the spindle's change over the block is bounded by the feed it would have
        at the target fz (S^2 by K*L, as in a cut) rather than by its own duration: the
        feed moves of a planned operation, whose F ncopt sets from S (default: cutting)
    k_scale : per block, the share of K*L that applies (default 1): a block whose F
        follows S at a higher feed per revolution than the target's is faster, so the
        spindle changes less over it
    """

    length_mm: np.ndarray
    req_rpm: np.ndarray
    cutting: np.ndarray
    planned: np.ndarray
    time_s: np.ndarray
    fixed_rpm: np.ndarray
    spindle_start: np.ndarray | None = None
    running: np.ndarray | None = None
    k_limited: np.ndarray | None = None
    k_scale: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = self.length_mm.shape[0]
        if self.spindle_start is None:
            object.__setattr__(self, "spindle_start", np.zeros(n, dtype=bool))
        if self.running is None:
            object.__setattr__(self, "running", np.ones(n, dtype=bool))



@dataclass(frozen=True)
class Profile:
    """Planned spindle speed per block (real-valued, before emission), RPM."""

    s_rpm: np.ndarray
    cap_rpm: np.ndarray
    k_rpm2_per_mm: float


def max_speed_ratio(opts: PlanOptions, cut: CuttingData, teeth: int, s_low_rpm: float) -> float:
    """Largest ratio of the highest to the lowest real spindle speed within one block.

    F is constant in a block while the spindle ramps, so fz spans
    [F/(z S_hi), F/(z S_lo)]; F is also rounded down to ``opts.f_quantum_mm_min``,
    which at the plan's lowest feed (fz z S_low) takes up to q = quantum / F_low
    off fz.  Keeping fz within +-tol gives, with r = S_hi/S_lo:

    * ``below`` (F = fz z S_lo):  r <= (1 - q) / (1 - tol)
    * ``centred`` (F = fz z 2 S_lo S_hi / (S_lo + S_hi)):  r <= (1 + tol - 2q) / (1 - tol)
    """
    tol = opts.fz_tolerance
    if s_low_rpm is None:  # nothing cuts: no fz to hold
        s_low_rpm = float("inf")
    q = opts.f_quantum_mm_min / (cut.fz_mm * teeth * max(s_low_rpm, 1.0))
    if opts.fz_policy not in ("centred", "below"):
        raise PlanningError(f"unknown fz policy {opts.fz_policy!r}; use centred or below")
    r = (1.0 + tol - 2.0 * q) / (1.0 - tol) if opts.fz_policy == "centred" else (1.0 - q) / (1.0 - tol)
    if r <= 1.0:
        raise PlanningError(f"F words of {opts.f_quantum_mm_min:g} mm/min resolution cannot hold "
                            f"fz within {100 * tol:g} % at F {cut.fz_mm * teeth * s_low_rpm:.0f} "
                            "mm/min; write F with more decimals or widen the band")
    return r


def k_rpm2_per_mm(machine: Machine, cut: CuttingData, teeth: int) -> float:
    """K = 2 * 60 * a / (fz z): the largest change of S^2 per mm of cut."""
    return 2.0 * 60.0 * machine.accel_rpm_s / (cut.fz_mm * teeth)


def speed_limits(machine: Machine, cut: CuttingData, teeth: int) -> tuple[float, float]:
    """Lowest and highest S the plan may use: machine range and the F_max cap."""
    s_hi = machine.max_rpm
    if np.isfinite(machine.max_feed_mm_min):
        s_hi = min(s_hi, machine.max_feed_mm_min / (cut.fz_mm * teeth))
    return machine.min_rpm, s_hi


def increments(blocks: Blocks, machine: Machine, k: float) -> tuple[np.ndarray, np.ndarray]:
    """How far the spindle may change during each block.

    Returns
    -------
    inc_s2 : (nb,) RPM^2, cutting blocks: K*L (inf elsewhere)
    inc_s : (nb,) RPM, other blocks: a*T over their whole duration T (inf for cutting)
    """
    ramp = machine.accel_rpm_s * blocks.time_s
    limited = blocks.cutting if blocks.k_limited is None else blocks.k_limited
    k_len = k * blocks.length_mm if blocks.k_scale is None else k * blocks.length_mm * blocks.k_scale
    inc_s2 = np.where(limited & ~blocks.spindle_start, k_len, np.inf)
    inc_s = np.where(limited | blocks.spindle_start, np.inf, ramp)
    return inc_s2, inc_s


def caps(blocks: Blocks, s_lo: float, s_hi: float, lookahead: bool) -> np.ndarray:
    """(nb,) upper bound on the commanded S of each block, RPM."""
    req = np.clip(blocks.req_rpm, s_lo, s_hi)
    cap = np.where(blocks.cutting, req, np.nan)
    if lookahead:  # the spindle still runs at S_b during block b+1's ramp
        nxt = np.concatenate((cap[1:], [np.nan]))
        cap = np.where(blocks.cutting, np.fmin(cap, nxt), cap)
    # non-cutting blocks head for the next cut's speed (then the last one's)
    cap = _bfill(cap)
    cap = ffill(cap, s_hi)
    fixed = ~blocks.planned
    cap[fixed] = np.clip(blocks.fixed_rpm[fixed], 0.0, None)
    return cap


def lookahead(blocks: Blocks, machine: Machine, cut: CuttingData, teeth: int,
              opts: PlanOptions) -> Profile:
    """The largest profile under the caps that obeys the spindle limit both ways.

    Forward and backward running minima in S^2 (``numpy.minimum.accumulate``),
    alternated with the same passes in log S for the per-block speed ratio that
    keeps the real fz within ``opts.fz_tolerance``; they converge to the
    greatest profile that satisfies all constraints.
    """
    k = k_rpm2_per_mm(machine, cut, teeth)
    s_lo, s_hi = speed_limits(machine, cut, teeth)
    cap = caps(blocks, s_lo, s_hi, lookahead=True)
    inc_s2, inc_s = increments(blocks, machine, k * (1.0 - PLAN_MARGIN))
    inc_s = inc_s * (1.0 - PLAN_MARGIN)
    s_low_cut = _lowest_cut_cap(cap, blocks)
    ratio = max_speed_ratio(opts, cut, teeth, s_low_cut)
    # integer S words round each fall up by < 1 RPM: the profile keeps 2 RPM at the lowest
    # cutting speed in reserve per block, so the words never lag behind it
    budget = np.log(ratio) * (1.0 - PLAN_MARGIN) - (2.0 / s_low_cut if s_low_cut else 0.0)
    if budget <= 0:
        raise PlanningError(f"an fz band of {100 * opts.fz_tolerance:g} % is too narrow for "
                            f"integer S words at {s_low_cut:.0f} RPM; widen --fz-band")
    ratio_inc = np.where(blocks.cutting & blocks.planned, budget, np.inf)
    s = cap.copy()
    # the chains depend on the increments alone: found once, used by every iteration
    ch_s2, ch_s, ch_ratio = _chains(inc_s2), _chains(inc_s), _chains(ratio_inc)
    for _ in range(MAX_ITERATIONS):
        before = s
        s = np.sqrt(np.maximum(_two_way_min_on(s * s, ch_s2), 0.0))
        s = np.minimum(s, _two_way_min_on(s, ch_s))
        s = np.minimum(s, np.exp(_two_way_min_on(np.log(np.maximum(s, 1e-300)), ch_ratio)))
        if np.allclose(s, before, rtol=1e-12, atol=CONVERGED_RPM):
            break
    s = np.maximum(s, np.minimum(s_lo, cap))
    s = _after_fixed(s, blocks, inc_s2, inc_s, ratio_inc, machine.max_rpm)  # with the reserve
    return Profile(s_rpm=s, cap_rpm=cap, k_rpm2_per_mm=k)


def _after_fixed(s, blocks, inc_s2, inc_s, ratio_inc, max_rpm):
    """Blocks ncopt does not plan run at the program's own S, and the spindle falls
    from there only as fast as it can: the profile is the real speed that results
    (the envelope), never below it after such a block.  Where it lies above the
    requirement, vc exceeds its target; the summary reports it."""
    fixed = ~blocks.planned & blocks.running
    if not fixed.any():
        return s
    env = np.where(fixed, blocks.fixed_rpm, 0.0)
    # the chains depend on the increments alone: found once, used by every iteration
    ch_s2, ch_s, ch_ratio = _chains(inc_s2), _chains(inc_s), _chains(ratio_inc)
    for _ in range(MAX_ITERATIONS):
        before = env
        env = np.sqrt(np.maximum(_two_way_max_forward(env * env, ch_s2), 0.0))
        env = np.maximum(env, _two_way_max_forward(env, ch_s))
        env = np.maximum(env, np.exp(_two_way_max_forward(np.log(np.maximum(env, 1e-300)),
                                                          ch_ratio)))
        if np.allclose(env, before, rtol=1e-12, atol=CONVERGED_RPM):
            break
    return np.where(blocks.planned, np.minimum(np.maximum(s, env), max_rpm), env)


def _two_way_max_forward(x: np.ndarray, chains) -> np.ndarray:
    """The smallest y >= x with y_b >= y_(b-1) - inc_b (a fall at most inc per block);
    an infinite inc restarts the chain.  ``chains``: :func:`_chains` of inc."""
    return -_two_way_min_forward(-x, chains)


def _two_way_min_forward(x: np.ndarray, chains) -> np.ndarray:
    """The largest y <= x with y_b <= y_(b-1) + inc_b (the forward pass alone);
    ``chains``: :func:`_chains` of inc."""
    out = x.copy()
    if chains is None:
        return out
    idx, seg, cum = chains
    out[idx] = cum + _segment_running_min(x[idx] - cum, seg, reverse=False)
    return out


def _lowest_cut_cap(cap: np.ndarray, blocks: Blocks) -> float | None:
    cut = cap[blocks.cutting & blocks.planned]
    return float(cut.min()) if cut.size else None


def forward(blocks: Blocks, machine: Machine, cut: CuttingData, teeth: int,
            opts: PlanOptions) -> Profile:
    """The paper's flow chart: each block takes the required speed clipped to
    what the spindle can reach from the previous block, both ways.

    The recurrence ``x_b = clip(req_b, x_(b-1) - inc_b, x_(b-1) + inc_b)`` is
    solved by vectorised sweeps: a rising pass (running minimum) and a falling
    pass (running maximum) give a start inside the solution's envelope, then
    Jacobi sweeps run to the exact fixed point.
    """
    k = k_rpm2_per_mm(machine, cut, teeth)
    s_lo, s_hi = speed_limits(machine, cut, teeth)
    cap = caps(blocks, s_lo, s_hi, lookahead=False)
    inc_s2, inc_s = increments(blocks, machine, k)
    # one S^2 budget per block: a non-cutting block's a*T taken at its cap (upper bound
    # of the change in S^2 over it is (2 cap + aT) aT)
    inc = np.where(np.isfinite(inc_s2), inc_s2, (2 * cap + inc_s) * inc_s)
    x = forward_clip(cap * cap, inc)
    return Profile(s_rpm=np.sqrt(np.maximum(x, 0.0)), cap_rpm=cap, k_rpm2_per_mm=k)


def forward_clip(req: np.ndarray, inc: np.ndarray) -> np.ndarray:
    """Solve x_b = clip(req_b, x_(b-1) - inc_b, x_(b-1) + inc_b), x_0 = req_0."""
    n = req.shape[0]
    if n == 0:
        return req.copy()
    cum = np.cumsum(np.where(np.isfinite(inc), inc, 0.0))
    x = cum + np.minimum.accumulate(req - cum)  # rises limited
    x = -cum + np.maximum.accumulate(x + cum)  # falls limited
    for _ in range(n + 1):
        prev = np.concatenate(([req[0]], x[:-1]))
        new = np.clip(req, prev - inc, prev + inc)
        new[0] = req[0]
        if np.array_equal(new, x):
            break
        x = new
    return x


def _chains(inc: np.ndarray):
    """Blocks linked to a neighbour (inc_b finite links b-1 and b), as
    (indices, chain id, cumulative inc within the chain); None when no block is.

    Blocks alone in their chain stay out, so that the per-chain offsets of the
    accumulations stay small (a million one-block chains cost precision)."""
    n = inc.shape[0]
    brk = ~np.isfinite(inc)
    if n:
        brk[0] = True
    chained = ~brk | np.concatenate((~brk[1:], [False]))
    if not chained.any():
        return None
    idx = np.flatnonzero(chained)
    link = ~brk[idx]
    start = ~link
    seg = np.cumsum(start) - 1
    cum = np.cumsum(np.where(link, inc[idx], 0.0))
    cum -= cum[np.flatnonzero(start)][seg]
    return idx, seg, cum


def _two_way_min(x: np.ndarray, inc: np.ndarray) -> np.ndarray:
    """The largest y <= x with y_b <= y_(b-1) + inc_b and y_b <= y_(b+1) + inc_(b+1).

    Both passes are running minima: forward ``y_b = C_b + min_(j<=b)(x_j - C_j)``,
    backward ``y_b = -C_b + min_(j>=b)(y_j + C_j)`` with C the cumulative sum of
    inc.  An infinite inc_b removes the constraint between b-1 and b: the sums
    restart there.
    """
    return _two_way_min_on(x, _chains(inc))


def _two_way_min_on(x: np.ndarray, chains) -> np.ndarray:
    """:func:`_two_way_min` with ``chains``, :func:`_chains` of inc, found already."""
    out = x.copy()
    if chains is None:
        return out
    idx, seg, cum = chains
    fwd = cum + _segment_running_min(x[idx] - cum, seg, reverse=False)
    out[idx] = -cum + _segment_running_min(fwd + cum, seg, reverse=True)
    return out


def _segment_running_min(v: np.ndarray, seg: np.ndarray, reverse: bool) -> np.ndarray:
    """Running minimum restarting at each new segment id (forward or backward)."""
    if seg[-1] == 0:
        return np.minimum.accumulate(v[::-1])[::-1] if reverse else np.minimum.accumulate(v)
    big = 2.0 * (float(np.max(v) - np.min(v)) + 1.0)
    off = seg * big if reverse else -seg * big  # earlier-scanned segments never win
    if reverse:
        return np.minimum.accumulate((v + off)[::-1])[::-1] - off
    return np.minimum.accumulate(v + off) - off


def _bfill(a: np.ndarray) -> np.ndarray:
    return ffill(a[::-1])[::-1]


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

    ``s_lo``, ``s_hi`` (RPM): the speed limits of :func:`speed_limits`.  No S word
    asks for more than ``s_hi``, even where the profile follows a spindle still
    falling from a higher S the program keeps (the fall is then as fast as the
    spindle allows, and F is capped by the feed limit anyway).
    """
    # the arrays are read and written through memoryviews: their items are Python floats
    # and bools as with tolist(), without building lists of 1M objects first (and the
    # outputs without np.array() of such lists): 0.2 of the 0.85 s at 1M blocks
    s_plan = _items(_snapped(profile.s_rpm), np.float64)
    inc_s2, inc_s = (_items(a, np.float64) for a in incs)
    cutting = _items(blocks.cutting & blocks.planned, bool)
    fixed = _items(~blocks.planned, bool)
    fixed_rpm = blocks.fixed_rpm  # read only in fixed blocks: no list of 1M floats
    starts = _items(blocks.spindle_start, bool)
    step = opts.min_rpm_step
    lo_int = math.ceil(s_lo)
    # the spindle's lowest speed wins over the feed-limited top (F is capped there anyway)
    top = max(math.floor(s_hi), lo_int) if math.isfinite(s_hi) else math.inf
    n = len(s_plan)
    out = np.zeros(n), np.zeros(n), np.zeros(n)  # S commanded, lowest and highest real speed
    cmd_out, low_out, high_out = (memoryview(a) for a in out)
    interval_s = opts.min_s_interval_ms / 1000.0
    timed = interval_s > 0  # else the clock since the last S word never matters
    length, time_free = ((_items(blocks.length_mm, np.float64),
                          _items(blocks.time_s, np.float64)) if timed else (None, None))
    floor, sqrt, inf = math.floor, math.sqrt, math.inf
    band = not math.isinf(ratio)
    cur = real = None
    since_s, close = inf, 0
    # One pass, one block at a time; the helpers' logic (rise, fall, ramp) is written
    # inline because the loop runs once per block (1M blocks: ~2x faster than calls), and
    # so are min() and max(): ``b if b > a else a`` is max(a, b) exactly (the first of
    # equals, NaN alike, the same type), ``b if b < a else a`` min(a, b), at a third of
    # the cost of the builtin call.
    for b, target, fixed_b, start_b, cut_b, inc2_b, inc_b in zip(range(n), s_plan, fixed, starts,
                                                                cutting, inc_s2, inc_s):
        before = cur
        if fixed_b:
            cur = float(fixed_rpm[b])
            if not cur > 0:  # the program runs this block with no S in force
                real = None
        elif cur is None or start_b or not cur > 0:  # a (re)start: the control brings it up
            cur = real = float(min(max(floor(target), lo_int), top))
        elif real == cur and cur <= target < cur + step:  # holding steady: nothing to do
            cmd_out[b] = low_out[b] = high_out[b] = cur
            if timed:
                since_s += (60.0 * length[b] / (feed_per_rev_mm * max(cur, 1.0))
                            if cut_b and feed_per_rev_mm > 0 else time_free[b])
            continue
        else:
            r = ratio if cut_b else inf
            if target >= cur + step:  # rise; the fz band bounds it by the real speed
                up = real * r
                up = floor(up if up < target else target)
                new = float(up) if up >= cur + step else cur
                if cut_b and band and new < real:
                    # above the command, the real speed still falls (from a faster S
                    # the program keeps): the fz band bounds that fall as any other
                    up = float(math.ceil(real / r))
                    if up > new:
                        new = up
                    if 0 < new - cur < step:  # target >= cur + step: vc stays under it
                        new = cur + step
            elif target < cur:  # fall now, with margin against chatter
                # the spindle limit may leave the real speed up to 1 RPM above an integer
                # command (the ramp tracking keeps the real value); the fz band may not
                # be crossed at all
                sq = real * real - inc2_b
                reach = sqrt(0.0 if 0.0 > sq else sq)
                lin = real - inc_b
                if lin > reach:
                    reach = lin
                band_floor = math.ceil(real / r) if cut_b and band else 0
                low = floor(reach)
                if band_floor > low:
                    low = band_floor
                if 0 > low:
                    low = 0
                new = floor(target - step + 1)
                if low > new:
                    new = low
                top_b = floor(target)
                if low <= top_b:
                    if top_b < new:
                        new = top_b
                else:
                    new = low
                if 0 < cur - new < step:  # a forced fall smaller than a step: a full step
                    new = cur - step
                    if band_floor > new:
                        new = band_floor
                new = float(new)
            else:
                new = cur
            if cut_b and band:
                # a command above the real speed (the spindle still rising, e.g. after the
                # program's own S) may let it rise by no more than the fz band in the block
                ceiling = floor(real * r)
                if new > real and new > ceiling:
                    new = float(ceiling)
                    if abs(new - cur) < step:  # keep changes of at least one step
                        new = cur if cur <= ceiling else cur - step
            cur = lo_int if lo_int > new else new
            if cur > top:  # a step from the previous command, or else the limit itself
                cur = before if before <= top and top - before < step else float(top)
            if timed:
                if cur > before and since_s < interval_s:
                    cur = before  # the control is still taking the previous S word
                elif cur < before and since_s < interval_s:
                    close += 1
        start = cur if real is None else real
        if start == cur:
            real = cur
        elif cur > start:  # toward the command: S^2 moves by at most inc_s2 (cutting), S by inc_s
            real = cur
            sq = sqrt(start * start + inc2_b)
            if sq < real:
                real = sq
            lin = start + inc_b
            if lin < real:
                real = lin
        else:
            real = cur
            sq = start * start - inc2_b
            sq = sqrt(0.0 if 0.0 > sq else sq)
            if sq > real:
                real = sq
            lin = start - inc_b
            if lin > real:
                real = lin
        if start < real:
            cmd_out[b], low_out[b], high_out[b] = cur, start, real
        else:
            cmd_out[b], low_out[b], high_out[b] = cur, real, start
        if timed:
            if cur != before:
                since_s = 0.0
            lowest = start if start < real else real
            since_s += (60.0 * length[b] / (feed_per_rev_mm * max(lowest, 1.0))
                        if cut_b and feed_per_rev_mm > 0 else time_free[b])
    return Emitted(*out, close)


def _items(a: np.ndarray, dtype) -> memoryview:
    """A read-only view of ``a``'s items as Python objects (floats, bools), like a list."""
    return memoryview(np.ascontiguousarray(a, dtype=dtype)).toreadonly()


def _snapped(rpm: np.ndarray) -> np.ndarray:
    """A profile a few ulps under an integer is that integer (exp(log(x)) != x)."""
    near = np.round(rpm)
    return np.where(np.abs(rpm - near) < 1e-9 * np.maximum(rpm, 1.0), near, rpm)


def feeds(s_low: np.ndarray, s_high: np.ndarray, blocks: Blocks, cut: CuttingData, teeth: int,
          max_feed_mm_min: float, policy: str = "centred") -> np.ndarray:
    """F per cutting block (mm/min) from the real spindle speeds in the block.

    ``centred``: the harmonic mean of the lowest and highest speed puts fz's
    excursions symmetrically inside the band; ``below``: the lowest speed.
    """
    s_ref = s_low if policy == "below" else 2.0 * s_low * s_high / np.maximum(s_low + s_high, 1e-9)
    f = np.minimum(cut.fz_mm * teeth * s_ref, max_feed_mm_min)
    return np.where(blocks.cutting & blocks.planned, f, np.nan)


@dataclass(frozen=True)
class BlockIndex:
    """Which toolpath points make each moving block (one source line each).

    line : (nb,) source line of each block;  first_point : (nb,) its first point
    """

    line: np.ndarray
    first_point: np.ndarray


def block_index(line_of_point: np.ndarray) -> BlockIndex:
    """Group toolpath points 1..n-1 into blocks by source line."""
    n = line_of_point.shape[0]
    if n < 2:
        return BlockIndex(np.zeros(0, np.int32), np.zeros(0, np.int64))
    starts = np.flatnonzero(np.diff(line_of_point[1:]) != 0) + 2
    first = np.concatenate(([1], starts)).astype(np.int64)
    return BlockIndex(line_of_point[first], first)


def blocks_from_contacts(idx: BlockIndex, seg_len_mm, motion, feed_mm_min, known, spindle_on,
                         spindle_rpm, req_at_sample, cutting_at_sample, sample_point,
                         selected, rapid_mm_min: float) -> Blocks:
    """Per block: length, lowest required S along it (both end points and every
    sample between), cutting, and the duration of non-cutting blocks.

    ``req_at_sample`` is inf where a sample does not cut or where the contact is
    at the tool tip (R_eff = 0): the cap at S_max takes over there.
    """
    n = seg_len_mm.shape[0]
    req = np.where(cutting_at_sample, req_at_sample, np.inf)
    seg_min = np.full(n, np.inf)
    np.minimum.at(seg_min, sample_point, req)
    cut_pt = np.zeros(n, dtype=bool)
    np.logical_or.at(cut_pt, sample_point, cutting_at_sample)
    last = np.concatenate((np.flatnonzero(np.diff(sample_point)), [sample_point.size - 1]))
    end_req = np.full(n, np.inf)
    end_req[sample_point[last]] = req[last]
    point_req = np.minimum(seg_min, np.concatenate(([np.inf], end_req[:-1])))
    fp = idx.first_point
    length = np.add.reduceat(seg_len_mm[1:], fp - 1)
    block_req = np.minimum.reduceat(point_req[1:], fp - 1)
    block_cut = np.logical_or.reduceat(cut_pt[1:], fp - 1)
    rapid = motion[fp] == 0
    speed = np.where(rapid, rapid_mm_min, np.nan_to_num(feed_mm_min[fp], nan=rapid_mm_min))
    time_s = 60.0 * length / np.maximum(speed, 1e-9)
    cutting = block_cut & selected[fp]
    # rapids and air moves let the spindle ramp; a rapid needs no known start
    free = ~selected[fp] & spindle_on[fp] & (rapid | known[fp])
    running = spindle_on[fp]
    start = running & ~np.concatenate(([False], running[:-1]))
    return Blocks(length_mm=length, req_rpm=block_req, cutting=cutting,
                  planned=selected[fp] | free, time_s=time_s, fixed_rpm=spindle_rpm[fp],
                  spindle_start=start, running=running)


def plan(blocks: Blocks, machine: Machine, cut: CuttingData, teeth: int,
         opts: PlanOptions) -> tuple[Emitted, np.ndarray, Profile]:
    """Profile -> integer S commands (RPM) -> F (mm/min) per block."""
    if opts.planner not in ("lookahead", "forward"):
        raise PlanningError(f"unknown planner {opts.planner!r}")
    if opts.s_changes not in (None, "anywhere"):  # between passes: ncopt.planning.passes
        raise PlanningError(f"S changes {opts.s_changes!r} are not planned here")
    planner_fn = lookahead if opts.planner == "lookahead" else forward
    profile = planner_fn(blocks, machine, cut, teeth, opts)
    incs = increments(blocks, machine, profile.k_rpm2_per_mm)
    s_lo, s_hi = speed_limits(machine, cut, teeth)
    ratio = max_speed_ratio(opts, cut, teeth, _lowest_cut_cap(profile.cap_rpm, blocks))
    em = emit_rpm(profile, blocks, incs, opts, s_lo, ratio, cut.fz_mm * teeth, s_hi)
    f = feeds(em.s_low_rpm, em.s_high_rpm, blocks, cut, teeth, machine.max_feed_mm_min,
              opts.fz_policy)
    return em, f, profile
