"""S changes between passes only (``--s-changes between-passes``).

Controls that stop the axes at every S change (grbl in spindle mode) or wait
for the spindle before the next feed (Fanuc with the speed-arrival check,
LinuxCNC with ``spindle.0.at-speed`` wired) cannot run a program whose S
changes along the cut.  Here each pass runs at one constant S and S changes
only on the non-cutting blocks between passes (retracts, rapids, air moves),
whose time lets the spindle reach the next pass's speed.

A *pass* is a maximal run of consecutive cutting blocks (``Blocks.cutting``
and planned) that moves some length; a spindle start also begins a new one.
Runs of zero length (a move onto the point the tool is already at) are not
passes: they take no time and carry no S of their own.  Without a mesh,
"cutting" is a guess (near-vertical feed moves count as air moves, though a
raster over a steep wall cuts on them), so the caller may say which blocks
surely leave the part (``separates``: e.g. those that reach the top of the
cut); the blocks between two runs separate passes only if one of them does,
else they belong to the pass around them and S does not change there.

The speed of pass p is the largest S_p with

* S_p <= the lowest requirement along the pass (vc at or below its target
  everywhere in it), within the machine's range and the feed-limited top;
* |S_p - S_(p-1)| <= a * T_p, T_p the time of the non-cutting blocks between
  the passes (the spindle ramps in RPM at ``a`` during them): it is at speed
  when the pass starts.

These are difference constraints on a chain, so the largest solution is the
two-way running minimum of :func:`ncopt.planning.schedule._two_way_min` with increment
0 inside a pass and a*T on the blocks between passes.  F of every block of a
pass is fz z S_p, so fz holds exactly (but for the F word's rounding down).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ncopt.model import CuttingData, Machine, PlanOptions
from ncopt.motion.modal import ffill
from ncopt.planning import schedule
from ncopt.planning.emission import snapped

# per gap, 1 RPM of the spindle's reach is kept for the rounding of S to integers
_ROUNDING_RPM = 1.0


def pass_ids(blocks: schedule.Blocks, separates: np.ndarray | None = None) -> np.ndarray:
    """(nb,) int: the pass of each block, numbered from 0 in program order; -1 between passes.

    ``separates`` : (nb,) bool or None (every gap separates): blocks that surely leave the
    part; a spindle start or a block ncopt does not plan always separates.
    """
    cut = blocks.cutting & blocks.planned
    if separates is not None:
        cut = cut | _bridged(cut, separates | blocks.spindle_start | ~blocks.planned)
    prev = np.concatenate(([False], cut[:-1]))
    start = cut & (~prev | blocks.spindle_start)
    pid = np.cumsum(start) - 1
    pid[~cut] = -1
    if not cut.any():
        return pid
    length = np.bincount(pid[cut], weights=blocks.length_mm[cut])
    keep = length > 0
    renumber = np.where(keep, np.cumsum(keep) - 1, -1)
    return np.where(pid >= 0, renumber[np.maximum(pid, 0)], -1)


def _bridged(cut: np.ndarray, separates: np.ndarray) -> np.ndarray:
    """(nb,) bool: the blocks of gaps between two runs of ``cut`` that hold no separating block."""
    n = cut.shape[0]
    if n == 0 or cut.all() or not cut.any():
        return np.zeros(n, dtype=bool)
    start = np.flatnonzero(~cut & np.concatenate(([True], cut[:-1])))
    end = np.flatnonzero(~cut & np.concatenate((cut[1:], [True])))  # inclusive
    inner = (start > 0) & (end < n - 1)  # a run of cuts on both sides
    # each reduceat segment runs from a gap's start to the next gap's: its gap, then cuts
    gap_sep = np.logical_or.reduceat(~cut & separates, start)
    bridge = inner & ~gap_sep
    out = np.zeros(n + 1, dtype=np.int64)
    np.add.at(out, start[bridge], 1)
    np.add.at(out, end[bridge] + 1, -1)
    return np.cumsum(out[:-1]) > 0


def profile(blocks: schedule.Blocks, machine: Machine, cut: CuttingData, teeth: int,
            pid: np.ndarray) -> schedule.Profile:
    """The largest per-block speed that is constant over each pass (RPM, real-valued)."""
    s_lo, s_hi = schedule.speed_limits(machine, cut, teeth)
    in_pass = pid >= 0
    as_passes = replace(blocks, cutting=in_pass)
    cap = schedule.caps(as_passes, s_lo, s_hi, lookahead=False)
    reach = machine.accel_rpm_s * blocks.time_s * (1.0 - schedule.PLAN_MARGIN) - _ROUNDING_RPM
    inc = np.where(in_pass, 0.0, np.maximum(reach, 0.0))
    inc[blocks.spindle_start] = np.inf  # the control brings a starting spindle to speed
    s = schedule._two_way_min(cap, inc)
    s = np.maximum(s, np.minimum(s_lo, cap))
    free = np.full(inc.shape, np.inf)
    s = schedule._after_fixed(s, as_passes, free, np.where(in_pass, 0.0, inc), free,
                             machine.max_rpm)
    return schedule.Profile(s_rpm=s, cap_rpm=cap, k_rpm2_per_mm=schedule.k_rpm2_per_mm(
        machine, cut, teeth))


def pass_speeds(prof: schedule.Profile, blocks: schedule.Blocks, pid: np.ndarray,
                machine: Machine, opts: PlanOptions, s_lo: float, s_hi: float) -> np.ndarray:
    """(n_passes,) integer S of each pass.

    The profile rounded down, but a rise smaller than ``opts.min_rpm_step``
    keeps the previous pass's speed (vc lower, one S word fewer), and no rise
    goes further than the spindle reaches in the time between the passes.
    """
    n = int(pid.max()) + 1 if pid.size else 0
    if n == 0:
        return np.zeros(0)
    in_pass = pid >= 0
    lowest = np.full(n, np.inf)
    np.minimum.at(lowest, pid[in_pass], snapped(prof.s_rpm[in_pass]))
    lo_int = math.ceil(s_lo)
    top = max(math.floor(s_hi), lo_int) if math.isfinite(s_hi) else math.inf
    target = np.clip(np.floor(lowest), lo_int, top)
    gap_time, reset = _gaps(blocks, pid, n)
    a = machine.accel_rpm_s
    out = target.tolist()
    step = opts.min_rpm_step
    for p in range(1, n):
        if reset[p]:
            continue
        prev, want = out[p - 1], out[p]
        if want > prev:  # a rise: worth a word only from one step up, never beyond reach
            out[p] = prev if want - prev < step else min(want, math.floor(prev + a * gap_time[p]))
    return np.array(out, dtype=np.float64)


def _gaps(blocks: schedule.Blocks, pid: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Per pass: the time of the blocks between it and the previous pass (s), and
    whether the spindle restarts or the program's own S comes in between (then the
    pass does not start from the previous pass's speed)."""
    in_pass = pid >= 0
    owner = ffill(np.where(in_pass, pid + 1.0, np.nan), 0.0).astype(np.int64)
    gap = ~in_pass & (owner < n)  # blocks between pass owner-1 and pass owner
    gap_time = np.bincount(owner[gap], weights=blocks.time_s[gap], minlength=n + 1)[:n]
    breaks = gap & (blocks.spindle_start | ~blocks.planned)
    first = np.flatnonzero(np.diff(np.concatenate(([-1], pid[in_pass]))) != 0)
    reset = np.zeros(n, dtype=bool)
    reset[np.unique(owner[breaks])] = True
    reset[pid[in_pass][first][blocks.spindle_start[in_pass][first]]] = True
    reset[0] = True
    return gap_time, reset


def commands(speeds: np.ndarray, blocks: schedule.Blocks, pid: np.ndarray) -> schedule.Emitted:
    """Per block: S commanded and the lowest and highest real speed.

    A pass's blocks run at its speed (the spindle is there when the pass
    starts).  The blocks before a pass command its speed, so the one S word lands
    on the first of them after the previous pass (the longest ramp); after the
    last pass the speed holds.  Blocks ncopt does not plan keep the program's S.
    """
    in_pass = pid >= 0
    value = np.full(pid.shape, np.nan)
    value[in_pass] = speeds[pid[in_pass]]
    fixed = ~blocks.planned
    value[fixed] = blocks.fixed_rpm[fixed]
    cmd = ffill(schedule._bfill(value))
    cmd = np.where(np.isnan(cmd), 0.0, cmd)
    before = np.concatenate(([cmd[0]], cmd[:-1]))
    low = np.where(in_pass, cmd, np.minimum(before, cmd))
    high = np.where(in_pass, cmd, np.maximum(before, cmd))
    return schedule.Emitted(cmd, low, high, 0)


def plan(blocks: schedule.Blocks, machine: Machine, cut: CuttingData, teeth: int,
         opts: PlanOptions, separates: np.ndarray | None = None
         ) -> tuple[schedule.Emitted, np.ndarray, schedule.Profile]:
    """One S per pass -> F per block (mm/min): as :func:`ncopt.planning.schedule.plan` returns.

    ``separates``: see :func:`pass_ids`.
    """
    pid = pass_ids(blocks, separates)
    s_lo, s_hi = schedule.speed_limits(machine, cut, teeth)
    prof = profile(blocks, machine, cut, teeth, pid)
    em = commands(pass_speeds(prof, blocks, pid, machine, opts, s_lo, s_hi), blocks, pid)
    f = schedule.feeds(em.s_low_rpm, em.s_high_rpm, blocks, cut, teeth, machine.max_feed_mm_min,
                      "below")
    return em, f, prof
