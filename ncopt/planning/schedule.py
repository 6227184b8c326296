"""Required speed -> spindle-limited S profile -> F per block.

Works on *blocks* (source lines that move), because a control applies S and
F per block.  Units: S in RPM, lengths in mm, F in mm/min, accelerations in
RPM/s.  The constraint of docs/method.md ("The spindle limit"), |d(S^2)/ds| <= K = 2*60*a/(fz*z), is
applied per block as |S_b^2 - S_(b-1)^2| <= K*L_b, so the ramp of a block
finishes inside it while F stays constant (:mod:`ncopt.planning.spindle`: the
blocks and these limits; :mod:`ncopt.planning.emission`: the profile's S words).

Deviation from docs/method.md, and why: a block's speed S_b is applied at its
start and the spindle ramps from S_(b-1) during the block, so the spindle
runs between both values inside block b.  vc therefore stays at or below its
target only if *both* are at most the block's requirement: the look-ahead
cap of block b is min(req_b, req_(b+1)).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ncopt.model import CuttingData, Machine, PlanOptions
from ncopt.motion.modal import ffill
from ncopt.planning.emission import Emitted, emit_rpm
from ncopt.planning.spindle import (Blocks, Profile, increments, k_rpm2_per_mm, max_speed_ratio,
                                    speed_limits)
from ncopt.runtime.errors import PlanningError

MAX_ITERATIONS = 200
# Profiles that agree to a ten-thousandth of an RPM are the same (S words are integers).
CONVERGED_RPM = 1e-4
# The profile keeps this share of the spindle's S^2 rate and of the fz band in
# reserve, so that integer S words (rounded toward the limits) can always follow
# it, even through a long deceleration at the full rate.
PLAN_MARGIN = 0.01


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
    cutting = blocks.cutting & blocks.planned
    s, ratio_inc = _solve(cap, inc_s2, inc_s, cutting, ratio, s_low_cut, opts)
    # the reserve is kept at each block's own speed where a cut is planned below the lowest
    # requirement: a fall toward a block ncopt leaves at a lower S (the program's own) takes
    # the cuts before it there, where 2 RPM are more of each block's ratio (a chain of falls
    # each rounded up by < 1 RPM ran 1.1 RPM over the profile at 552.9 RPM); the real speed
    # after a block ncopt leaves is bounded as before (:func:`_after_fixed`)
    if cutting.any() and s_low_cut is not None and float(s[cutting].min()) < s_low_cut - 1e-9:
        base = np.minimum(s, np.concatenate((s[:1], s[:-1])))  # the slower end of each link
        s, _ = _solve(cap, inc_s2, inc_s, cutting, ratio, np.minimum(base, s_low_cut), opts,
                      ratio_inc)
    s = np.maximum(s, np.minimum(s_lo, cap))
    s = _after_fixed(s, blocks, inc_s2, inc_s, ratio_inc, machine.max_rpm)  # with the reserve
    return Profile(s_rpm=s, cap_rpm=cap, k_rpm2_per_mm=k)


def _solve(cap, inc_s2, inc_s, cutting, ratio, s_reserve, opts, fallback=None):
    """(profile, per-block log-ratio budget): the largest profile under ``cap`` within the
    spindle's increments and the fz band's per-block ``ratio``, less a reserve of 2 RPM at
    ``s_reserve`` (RPM, or (nb,) RPM per block) for the rounding of integer S words
    (:func:`lookahead`).  ``fallback``: a per-block budget found before, kept where the
    band leaves no reserve at ``s_reserve``; without it such a band is a PlanningError."""
    # integer S words round each fall up by < 1 RPM: the profile keeps 2 RPM at the lowest
    # cutting speed in reserve per block, so the words never lag behind it
    if fallback is not None:
        budget = np.log(ratio) * (1.0 - PLAN_MARGIN) - 2.0 / np.maximum(s_reserve, 1e-300)
        budget = np.where(budget > 0, budget, fallback)
    else:
        budget = np.log(ratio) * (1.0 - PLAN_MARGIN) - (2.0 / s_reserve if s_reserve else 0.0)
        if budget <= 0:
            raise PlanningError(f"an fz band of {100 * opts.fz_tolerance:g} % is too narrow "
                                f"for integer S words at {s_reserve:.0f} RPM; widen --fz-band")
    ratio_inc = np.where(cutting, budget, np.inf)
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
    return s, ratio_inc


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
                         selected, rapid_mm_min: float, counted_at_sample=None) -> Blocks:
    """Per block: length, lowest required S along it (both end points and every
    sample between), cutting, and the duration of non-cutting blocks.

    ``req_at_sample`` is inf where a sample does not cut or where the contact is
    at the tool tip (R_eff = 0): the cap at S_max takes over there.
    ``counted_at_sample``: the samples whose requirement counts (default: those that
    cut; :func:`ncopt.contacts.locate.with_onsets` adds the last sample before a contact
    begins or after it ends).
    """
    n = seg_len_mm.shape[0]
    counted = cutting_at_sample if counted_at_sample is None else counted_at_sample
    req = np.where(counted, req_at_sample, np.inf)
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
