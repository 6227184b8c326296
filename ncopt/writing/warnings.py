"""The rewrite's warnings, each located (``path:line: ...``), as the summary gives them.

The vc excess they state is measured on a replay of the S and F words written, on
simulate's model of the spindle (:func:`real_top_rpm`), against each block's own
requirement: what simulate finds on the output."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ncopt.contacts.locate import below_top_mm
from ncopt.model import Job, Machine, Motion, Program, Toolpath
from ncopt.motion.linestate import spindle_starts_through
from ncopt.planning.opplan import OpPlan
from ncopt.planning.plans import Work
from ncopt.planning.schedule import BlockIndex
from ncopt.planning.spindle import speed_limits
from ncopt.reading.stamp import read_stamps
from ncopt.writing.edits import Targets
from ncopt.writing.targets import feed_after

#: a cutting block runs above its target where its real spindle is this share above what
#: it needs (S words are integers, the real speed a float)
OVER_SHARE = 1e-3


def plan_warnings(prog: Program, tp: Toolpath, idx: BlockIndex, work: Work,
                  job: Job) -> tuple[str, ...]:
    """What the summary warns of, located: a stamp that names no spindle, a --diameter read
    as mm in an inch program, S above the machine's, and per plan what
    :func:`_plan_notes` finds."""
    out = []
    stamps = read_stamps(prog)
    if len(stamps) and stamps.spindle is None:
        out.append(f"{prog.path}:{stamps.lines[0] + 1}: the stamp of an earlier ncopt does not "
                   "say which spindle its S and F were planned for: planned again as if for "
                   "this one; for another machine, rewrite the original program")
    inch = tp.line_inch is not None and bool(tp.line_inch.any())
    if inch and job.cutter is not None and job.diameter_bare and job.cutter.diameter_mm < 2.0:
        d = job.cutter.diameter_mm
        out.append(f"{prog.path}: --diameter {d:g} is read as mm (a {d:g} mm cutter) but the "
                   f"program is in inches: for a {d:g} inch cutter pass --diameter {d:g}in")
    for p in work.plans:
        s0 = p.s0_rpm
        if s0 > job.machine.max_rpm:
            op = work.ops[p.op]
            reached = p.cutting.vc_m_min * job.machine.max_rpm / s0
            out.append(f"{prog.path}: {op.name}: the program's S{s0:.0f} is above the machine's "
                       f"{job.machine.max_rpm:.0f} RPM: it was written for a faster spindle; "
                       f"at {job.machine.max_rpm:.0f} RPM vc reaches {reached:.1f} of its "
                       f"{p.cutting.vc_m_min:.1f} m/min where the cutter cuts at its full diameter")
    top = real_top_rpm(prog, tp, idx, work.plans, job.machine) if work.plans else None
    for p in work.plans:
        out.extend(_plan_notes(prog, tp, idx, work, p, job, top[p.window[0]:p.window[1]]))
    return tuple(out)


def _plan_notes(prog: Program, tp: Toolpath, idx: BlockIndex, work: Work, p: OpPlan,
                job: Job, top_rpm: np.ndarray) -> list[str]:
    """One plan's warnings: cutting blocks below the machine's lowest speed, above their
    target after an S ncopt could not plan, kept for F words too coarse, planned without
    a known contact, and blocks off the cutting feed scaled with S.  ``top_rpm``: the
    highest real spindle speed over each block of its window (:func:`real_top_rpm`)."""
    out = _below_min_rpm(prog, idx, work, p, job.machine, top_rpm)
    count, worst = _above_target(p, job.machine, top_rpm)
    if count:
        op = work.ops[p.op]
        out.append(f"{prog.path}: {op.name} (T{p.tool}): vc up to {worst:.1f} % "
                   f"above its target on {count} cutting blocks, where the "
                   "spindle is still falling from an S that ncopt could not plan")
    if p.coarse_lines is not None and p.coarse_lines.size:
        op = work.ops[p.op]
        first = int(p.coarse_lines[0]) + 1
        out.append(f"{prog.path}:{first}: {op.name}: {p.coarse_lines.size} cutting blocks keep "
                   "their S and F: their feed is too low for the resolution of the "
                   "program's F words to hold fz within its band (write F with more "
                   "decimals to plan them)")
    out.extend(_unknown_warning(prog, tp, work, p))
    scaled = int((p.reduced & p.blocks.cutting).sum())  # in the air F stays as written
    if scaled:
        op = work.ops[p.op]
        out.append(f"{prog.path}: {op.name}: {scaled} block{'s' if scaled > 1 else ''} off "
                   f"the cutting feed {p.cutting_feed_mm_min:g} mm/min (plunges, ramps, "
                   f"lead-ins into the part) keep{'' if scaled > 1 else 's'} the program's "
                   "feed per tooth: F scaled with S")
    return out


def _below_min_rpm(prog: Program, idx: BlockIndex, work: Work, p: OpPlan,
                   machine: Machine, top_rpm: np.ndarray) -> list[str]:
    """Cutting blocks that need a lower S than the machine's lowest (--min-rpm): vc runs
    above its target there, and the rewrite says where and by how much: the most the
    real spindle (``top_rpm``, still falling there or at the lowest speed) runs above
    what a block needs."""
    c = p.blocks.cutting & p.blocks.planned
    need = p.blocks.req_rpm
    low = np.flatnonzero(c & (need < machine.min_rpm))
    if low.size == 0 or not machine.min_rpm > 0:
        return []
    worst = 100.0 * (max(machine.min_rpm / float(np.min(need[low])),
                         float(np.max(top_rpm[low] / need[low]))) - 1.0)
    lines = np.unique(idx.line[p.window[0] + low])
    return [f"{prog.path}:{int(lines[0]) + 1}: {work.ops[p.op].name} (T{p.tool}): "
            f"{low.size} cutting block{'s' if low.size > 1 else ''} (lines "
            f"{line_ranges(lines)}) need less than the machine's lowest speed "
            f"{machine.min_rpm:g} RPM: vc up to {worst:+.1f} % above its target there (lower "
            "--min-rpm if the spindle can turn slower)"]


def _above_target(p: OpPlan, machine: Machine, top_rpm: np.ndarray) -> tuple[int, float]:
    """Cutting blocks where the real spindle (``top_rpm``) runs above the lowest S ncopt
    could plan there (the requirement within the machine's range and the feed cap): it
    is still falling from an S that ncopt could not plan.  (count, worst vc excess %),
    the excess against the requirement itself, as simulate measures vc; at least the
    planner's own figures (``OpPlan.over_target``, on the spindle speeds it tracked)."""
    c = p.blocks.cutting & p.blocks.planned
    need = p.blocks.req_rpm
    s_lo, s_hi = speed_limits(machine, p.cutting, p.cutter.teeth)
    with np.errstate(divide="ignore", invalid="ignore"):
        excess = top_rpm / need - 1.0
    over = c & (excess > OVER_SHARE) & (top_rpm > np.clip(need, s_lo, s_hi) * (1 + OVER_SHARE))
    worst = float(100.0 * excess[over].max()) if over.any() else 0.0
    return max(int(over.sum()), p.over_target[0]), max(worst, p.over_target[1])


def real_top_rpm(prog: Program, tp: Toolpath, idx: BlockIndex, plans: Sequence[OpPlan],
                 machine: Machine) -> np.ndarray:
    """(nb,) the highest real spindle speed (RPM) over each moving block of the rewrite,
    replayed as simulate replays it (``ncopt.simulate.spindle``): the speed ramps at the
    machine's acceleration toward the S in force (within the machine's range; 0 while
    the spindle is off) and the control waits for speed where the spindle starts; a
    block lasts as long as its moves at the F the rewrite writes (capped at the feed
    limit; rapids at the rapid rate).  The planner tracked the spindle on its own model
    (F = fz z S on a cut), which a plunge, whose F is never raised, outlasts: a spindle
    still rising toward a high S gets there on it."""
    fp = idx.first_point
    s_block = tp.spindle_rpm[fp].astype(np.float64)
    f_block = tp.feed_mm_min[fp].astype(np.float64)
    for p in plans:  # as ncopt.writing.targets.block_targets puts them in force
        lo, hi = p.window
        s_block[lo:hi] = np.where(p.blocks.planned, p.s_cmd_rpm, s_block[lo:hi])
        f_block[lo:hi] = np.where(np.isfinite(p.f_mm_min) & (p.blocks.length_mm > 0),
                                  p.f_mm_min, f_block[lo:hi])
    on = tp.spindle_on[fp] if tp.spindle_on is not None else s_block > 0
    target = np.where(on & (s_block > 0), np.clip(s_block, machine.min_rpm, machine.max_rpm),
                      0.0)
    start = on & _spindle_starts(prog, tp, fp)
    reach = machine.accel_rpm_s * _block_seconds(tp, idx, f_block, machine)
    return _ramp_tops(target, start, reach)


def _spindle_starts(prog: Program, tp: Toolpath, fp: np.ndarray) -> np.ndarray:
    """(nb,) bool: an M3/M4 starts the stopped spindle (after M2, M5 or M30) since the
    move before the block's first, as ``ncopt.simulate.movetable`` finds the starts."""
    starts = spindle_starts_through(prog)
    point_line = tp.line.astype(np.int64) + 1  # point 0 has line -1: count from the top
    return starts[point_line[fp]] > starts[point_line[fp - 1]]


def _block_seconds(tp: Toolpath, idx: BlockIndex, f_block: np.ndarray,
                   machine: Machine) -> np.ndarray:
    """(nb,) seconds of each block's moves at ``f_block`` (mm/min, capped at the feed
    limit), rapids at the rapid rate, moves from an unknown position in no time (as
    ``ncopt.simulate.movetable`` times them)."""
    fp = idx.first_point
    first = int(fp[0])
    counts = np.diff(np.concatenate((fp, [tp.n])))
    motion = tp.motion[first:]
    rapid = motion == Motion.RAPID
    feed = np.isin(motion, (Motion.LINEAR, Motion.ARC_CW, Motion.ARC_CCW))
    speed = np.where(rapid, machine.rapid_mm_min,
                     np.minimum(np.repeat(f_block, counts), machine.max_feed_mm_min))
    ok = tp.known[first:] & (rapid | feed) & np.isfinite(speed) & (speed > 0)
    dt = np.where(ok, 60.0 * tp.seg_len_mm[first:] / np.where(ok, speed, 1.0), 0.0)
    return np.add.reduceat(dt, fp - first)


def _ramp_tops(target: np.ndarray, start: np.ndarray, reach: np.ndarray) -> np.ndarray:
    """(nb,) the highest speed over each block of a spindle that ramps toward each
    block's ``target`` by at most its ``reach`` (RPM), from 0, at ``target`` at once
    where it ``start``s.

    Most blocks reach their target from the one before's (guessed for all at once); the
    rest, where a ramp lags behind its S words and carries from block to block, are
    walked one by one until the spindle is at its S again (the same float operations
    as a walk over every block, so the same result)."""
    w0 = np.where(start, target, np.concatenate(([0.0], target[:-1])))
    short = np.where(w0 < target, w0 + reach < target, w0 - reach > target)
    out = np.maximum(w0, target)
    tops = memoryview(out)
    tv, sv, rv = (memoryview(np.ascontiguousarray(a)) for a in (target, start, reach))
    n, until = len(tv), 0
    for b in np.flatnonzero(short).tolist():
        if b < until:  # walked already, in the lag before
            continue
        w = float(w0[b])
        while True:
            t, r = tv[b], rv[b]
            if sv[b]:
                w = t
            w_in = w
            if w < t:
                w = w + r if w + r < t else t
            elif w > t:
                w = w - r if w - r > t else t
            tops[b] = w if w > w_in else w_in
            b += 1
            if w == t or b == n:
                break
        until = b
    return out


def _unknown_warning(prog: Program, tp: Toolpath, work: Work, p: OpPlan) -> list[str]:
    """Where a plan without a mesh could not see the contact: one located warning."""
    pct, unknown = unknown_share(tp, work, work.point_op == p.op)
    if not unknown.any():
        return []
    lines = np.unique(tp.line[unknown])
    op = work.ops[p.op]
    where = f"{prog.path}:{int(lines[0]) + 1}: {op.name} (T{p.tool}): {pct:.1f} % of the cut " \
        f"({lines.size} blocks: lines {line_ranges(lines)})"
    if (work.fits or {}).get(p.tool) is not None:  # a mesh, which has no part there
        return [f"{where} runs below the top of the cut where the mesh has no part: planned "
                "as if the cutter cut at its full diameter, so vc stays at or below its target "
                "there; check that the mesh is the whole part (a floor, a side missing)"]
    return [f"{where} runs where the toolpath cannot show the contact (down or up a wall, a "
            "plunge below the top of the cut, a pass with no neighbour): planned as if the "
            "cutter cut at its full diameter, so vc stays at or below its target there; give "
            "--mesh to plan it exactly"]


def unknown_share(tp: Toolpath, work: Work, points: np.ndarray) -> tuple[float, np.ndarray]:
    """Without a mesh, over the cut of ``points`` (mask): (percent of its length planned
    at the cutter's full radius for want of a known contact, (n,) mask of those points)."""
    unknown = np.zeros(tp.n, dtype=bool)
    cut_mm = np.zeros(tp.n)  # each move's length that can touch the part
    for view in work.views.values():
        sampled = view.sampled
        if sampled.unknown is None:
            continue
        mine = points & (tp.tool == view.tool)
        # per toolpath point (the move ending there): a mesh's samples come several a move
        new_pt = np.zeros(tp.n, dtype=bool)
        np.logical_or.at(new_pt, sampled.point, sampled.unknown)
        cut_pt = np.zeros(tp.n, dtype=bool)
        np.logical_or.at(cut_pt, sampled.point, sampled.contacts.cutting)
        known = np.flatnonzero(cut_pt & ~new_pt & mine)
        cut_mm[known] = tp.seg_len_mm[known]
        new = np.flatnonzero(new_pt & mine)
        cut_mm[new] = below_top_mm(tp, new, sampled.top_mm, sampled.up)
        unknown[new] = True
    total = float(cut_mm.sum())
    pct = 100.0 * float(cut_mm[unknown].sum()) / total if total > 0 else 0.0
    return pct, unknown


def spindle_check_inputs(tp: Toolpath, idx: BlockIndex, work: Work, targets: Targets,
                         job: Job) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What the simulator's spindle check (``ncopt.simulate.replay.lagging_blocks``) reads
    of a rewrite, (n,) per toolpath point: the S commanded (RPM), the F in force (mm/min),
    and the feed per revolution of the target fz (mm) on every move of a planned block
    whose F, at the S commanded for it, means that fz (within twice the band: a plunge at
    its own feed per tooth is off target by design, not because the spindle lags); NaN
    on the others, which the check leaves."""
    n = tp.n
    counts = np.diff(np.concatenate((idx.first_point, [n])))
    start = int(idx.first_point[0]) if idx.first_point.size else n
    s_pt = tp.spindle_rpm.copy()
    s_block = np.where(np.isfinite(targets.s_value), targets.s_value,
                       tp.spindle_rpm[idx.first_point])
    s_pt[start:] = np.repeat(s_block, counts)
    rev_block = np.full(idx.first_point.shape[0], np.nan)
    for p in work.plans:
        lo, hi = p.window
        rev_block[lo:hi][p.blocks.planned] = p.cutting.fz_mm * p.cutter.teeth
    rev = np.full(n, np.nan)
    rev[start:] = np.repeat(rev_block, counts)
    f_pt = feed_after(tp, idx, targets)
    band = job.options.fz_tolerance
    with np.errstate(divide="ignore", invalid="ignore"):
        meant = np.abs(np.minimum(f_pt, job.machine.max_feed_mm_min) / (s_pt * rev) - 1.0)
    rev = np.where(meant <= 2.0 * band, rev, np.nan)
    return s_pt, f_pt, rev


def lag_warning(prog: Program, tp: Toolpath, bad: np.ndarray,
                band: float) -> tuple[tuple[str, ...], tuple[int, ...]]:
    """The spindle check's finding: ``bad``, the moves where the spindle cannot follow the
    S words written (fz leaves its +-``band`` share), as (one warning, 1-based lines)."""
    if bad.size == 0:
        return (), ()
    lines = np.unique(tp.line[bad])
    return ((f"{prog.path}:{int(lines[0]) + 1}: the spindle cannot follow the S words at "
             f"{lines.size} cutting block{'s' if lines.size > 1 else ''} (lines "
             f"{line_ranges(lines)}; simulated at its acceleration): fz leaves its "
             f"+-{100 * band:g} % band while it catches up",),
            tuple(int(x) + 1 for x in lines))


def line_ranges(lines: np.ndarray, shown: int = 3) -> str:
    """``19-21, 88, 102-140 and 12 more`` from sorted 0-based line numbers."""
    if lines.size == 0:
        return ""
    breaks = np.flatnonzero(np.diff(lines) > 1)
    starts = np.concatenate(([lines[0]], lines[breaks + 1]))
    ends = np.concatenate((lines[breaks], [lines[-1]]))
    parts = [f"{a + 1}" if a == b else f"{a + 1}-{b + 1}"
             for a, b in zip(starts[:shown].tolist(), ends[:shown].tolist())]
    more = f" and {starts.size - shown} more" if starts.size > shown else ""
    return ", ".join(parts) + more
