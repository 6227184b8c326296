"""Operations -> plans: the cutter and cutting data of each planned operation, and the
S and F ncopt sets on the blocks it owns.

Operations are planned one after the other, in program order.  Each plan covers a
window of blocks: the operation's own (its cuts and the link moves of its run, see
:mod:`ncopt.planning.regions`), one block before it at the speed then commanded (so the spindle
starts from where it really is), and the first fixed block after it where the program's
own S must be back in force.  Blocks that a later operation owns are left to that one.

Feeds keep the CAM's intent (METHOD.md plans one cutting feed): only the blocks at the
operation's cutting feed follow the fz target; a plunge (at any feed), or a ramp,
lead-in or link at another feed, is scaled with the spindle (``F = F_prog * S_low / S_prog``: its feed per
tooth stays the programmed one and never rises).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace

import numpy as np

from ncopt.planning import operations
from ncopt.planning import passes
from ncopt.planning import schedule
from ncopt.planning import regions
from ncopt.reading.controls import ANYWHERE, BETWEEN_PASSES
from ncopt.contacts.locate import Sampled, contacts_for
from ncopt.model import Method
from ncopt.runtime.errors import MeshError, NothingToPlan, PlanningError, UsageError
from ncopt.model import MM_PER_INCH
from ncopt.motion.modal import row_norms
from ncopt.model import Cutter, CuttingData, Machine, Motion, PlanOptions, Program, Toolpath
from ncopt.planning.operations import CANNED, CLEARING, NO_CUT, ROUGH_LEVELS, Operation
from ncopt.planning.regions import Scope
from ncopt.reading.stamp import as_stamped, read_stamps, stamp_for, stamped_line, unstamped_line
from ncopt.contacts.cutters import required_rpm
from ncopt.planning.tooltable import BALL, BULL, cutter_for, tool_table

FEED_MATCH = 1e-3  # mm/min: a block at the cutting feed
# G93: a block's tip feed is its F word (1 / minutes) times its length, both rounded in
# the program: within this share of the cutting feed it is that feed
FEED_MATCH_G93 = 1e-3
PLUNGE = 0.99  # a feed move down within 8 deg of the axis plunges: fz as programmed
# a feed move within 26 deg of the axis (up or down: plunges, retracts, wall descents) does
# not say what the operation's cutting feed is, however long such moves are together
VERTICAL = 0.9


@dataclass(frozen=True)
class OpPlan:
    """One planned operation's S and F over its window of blocks.

    op : index into the operations;  window : (first, end) block indices
    blocks : the planner's view of the window;  s_cmd_rpm, f_mm_min : (end - first,)
    commanded S and F per block (F NaN where the program's own stays)
    reduced : (end - first,) bool, blocks at another feed than the cutting feed, scaled
    with the spindle;  cutting_feed_mm_min : the operation's programmed cutting feed
    """

    op: int
    tool: int
    cutter: Cutter
    cutting: CuttingData
    source: str
    window: tuple[int, int]
    blocks: schedule.Blocks
    s_cmd_rpm: np.ndarray
    f_mm_min: np.ndarray
    reduced: np.ndarray
    cutting_feed_mm_min: float
    close_s_words: int = 0
    over_target: tuple = (0, 0.0)
    s0_rpm: float = 0.0  # the operation's own S (the program's), for the stamp
    lines: tuple = (0, 0)  # its (first, last) lines, 1-based, numbered without stamp lines
    coarse_lines: np.ndarray | None = None  # 0-based lines kept: F words too coarse for fz
    s_low_rpm: np.ndarray | None = None  # lowest real spindle speed per block of the window
    passes: int = 0  # runs of cutting blocks (ncopt.planning.passes.pass_ids)
    cut_time_min: float = 0.0  # its cutting blocks at the planned F
    other_time_min: float = float("nan")  # the same with the other --s-changes mode


@dataclass(frozen=True)
class ToolView:
    """What one tool's contacts give every block of the program (vc = 1 m/min)."""

    tool: int
    cutter: Cutter
    sampled: Sampled
    base: schedule.Blocks  # req_rpm per 1 m/min of vc; cutting only on its planned ops


@dataclass(frozen=True)
class MeshFit:
    """How well the part's mesh fits the planned cut (with a mesh only).

    touching_pct : share of the planned feed length whose cutter touches the mesh within
        the contact tolerance;  air_pct : clear of it;  gouge_pct : inside it
    deepest_gouge_mm : how far the cutter goes into the mesh at worst (0: never)
    gouge_line, air_line : 1-based first line that gouges / is in the air (0: none)
    """

    touching_pct: float
    air_pct: float
    gouge_pct: float
    deepest_gouge_mm: float
    gouge_line: int
    air_line: int


AIR_LIMIT_PCT = 50.0  # more of the planned cut in the air: the mesh is not this part
GOUGE_LIMIT_PCT = 10.0  # more of it inside the part: wrong mesh, units, offset or stock


def mesh_fit(view: ToolView, tp: Toolpath, selected: np.ndarray, tol_mm: float) -> MeshFit | None:
    """The fit of the mesh over the samples of the ``selected`` points."""
    sm = view.sampled
    if sm.gap_mm is None:
        return None
    use = selected[sm.point] & (sm.point > 0) & _surface_moves(tp, selected)[sm.point]
    if not use.any():
        return None
    gap, line = sm.gap_mm[use], tp.line[sm.point[use]]
    air, gouge = gap > tol_mm, gap < -tol_mm
    n = float(gap.size)
    first = lambda m: int(line[np.argmax(m)]) + 1 if m.any() else 0  # noqa: E731
    return MeshFit(100.0 * float(np.sum(~air & ~gouge)) / n, 100.0 * float(air.sum()) / n,
                   100.0 * float(gouge.sum()) / n, float(max(-gap.min(), 0.0)),
                   first(gouge), first(air))


def _surface_moves(tp: Toolpath, selected: np.ndarray) -> np.ndarray:
    """(n,) bool: the selected moves that follow the surface: not plunges or retracts
    (within 25 deg of the axis), not at a reduced feed (entries, links)."""
    d = np.diff(tp.xyz_mm, axis=0, prepend=tp.xyz_mm[:1])
    length = row_norms(d)
    across = np.abs(d[:, 2]) <= 0.9 * np.maximum(length, 1e-12)
    out = selected & across
    if out.any():
        f = tp.feed_mm_min[out]
        typical = operations._weighted_median(f, tp.seg_len_mm[out])
        out &= tp.feed_mm_min >= operations.SLOW_FEED * typical
    return out


def check_fit(fit: MeshFit | None, tool: int, tol_mm: float, path: str) -> None:
    """Refuse (MeshError, exit 4) a mesh that is not the part this program cuts."""
    if fit is None or (fit.air_pct <= AIR_LIMIT_PCT and fit.gouge_pct <= GOUGE_LIMIT_PCT):
        return
    where = fit.air_line if fit.air_pct > AIR_LIMIT_PCT else fit.gouge_line
    raise MeshError(
        f"the mesh does not fit T{tool}'s cut: {fit.touching_pct:.1f} % of it touches the mesh "
        f"within {tol_mm:g} mm, {fit.air_pct:.1f} % is in the air, {fit.gouge_pct:.1f} % inside "
        f"the part (deepest {fit.deepest_gouge_mm:.3g} mm); first line that does not fit: "
        f"{where}.  Check that it is this program's part, in mm, in the program's work "
        "coordinates; for a program that leaves an allowance give --stock MM", path, where or None)


def tool_view(tp: Toolpath, idx: schedule.BlockIndex, tool: int, cutter: Cutter,
              selected: np.ndarray, mesh_index, opts: PlanOptions, tol_mm: float,
              method: Method, rapid_mm_min: float, stock_mm: float = 0.0,
              r_floor_mm: float = 0.0) -> ToolView:
    """``r_floor_mm``: R_eff below which every operation of the tool runs at S_max
    (the mesh is sampled no finer where R_eff only changes below it)."""
    sampled = contacts_for(tp, cutter, selected, mesh_index, opts.sample_mm, tol_mm, method,
                           stock_mm, r_floor_mm=r_floor_mm)
    c = sampled.contacts
    base = schedule.blocks_from_contacts(
        idx, tp.seg_len_mm, tp.motion, tp.feed_mm_min, tp.known, tp.spindle_on,
        tp.spindle_rpm, required_rpm(c.r_eff_mm, 1.0), c.cutting, sampled.point, selected,
        rapid_mm_min)
    return ToolView(tool, cutter, sampled, base)


def plan_operation(k: int, op: Operation, view: ToolView, cut: CuttingData, source: str,
                   tp: Toolpath, idx: schedule.BlockIndex, point_op: np.ndarray, scope: Scope,
                   cmd_rpm: np.ndarray, machine: Machine, opts: PlanOptions,
                   path: str, intent: tuple | None = None) -> OpPlan:
    """Plan operation ``k``; ``cmd_rpm`` (nb,) holds the S commanded per block so far
    (the program's, and the plans before this one): it is updated in place.

    ``intent``: (S0 RPM, F0 mm/min), the operation's own S and cutting feed as an ncopt
    stamp records them (the program is an ncopt output); None: read from the program."""
    owned = np.flatnonzero(scope.owner == k)
    w0, last = int(owned[0]), int(owned[-1])
    base = view.base
    nb = base.length_mm.shape[0]
    w1 = last + 1
    if w1 < nb and scope.owner[w1] < 0 and base.running[w1]:
        w1 += 1  # the program's own speed must be back here
    lo = max(w0 - 1, 0)
    win = slice(lo, w1)
    fp = idx.first_point[win]
    mine = point_op[fp] == k
    own = scope.owner[win] == k
    rapid = tp.motion[fp] == Motion.RAPID
    free = own & ~mine & base.running[win] & (rapid | tp.known[fp])
    planned = (mine & ~scope.demoted[win]) | free
    if lo < w0:
        planned[0] = False  # the block before: the speed the spindle comes from
    coarse = _too_coarse(base.req_rpm[win] * cut.vc_m_min, base.cutting[win] & planned,
                         machine, cut, view.cutter.teeth, opts)
    planned &= ~coarse
    cutting = base.cutting[win] & planned
    blocks = schedule.Blocks(
        length_mm=base.length_mm[win], req_rpm=base.req_rpm[win] * cut.vc_m_min,
        cutting=cutting, planned=planned, time_s=base.time_s[win],
        fixed_rpm=cmd_rpm[win].copy(), spindle_start=base.spindle_start[win],
        running=base.running[win], k_limited=cutting)
    feed = tp.feed_mm_min[fp]
    d = np.take(tp.xyz_mm, fp, axis=0) - np.take(tp.xyz_mm, np.maximum(fp - 1, 0), axis=0)
    length = np.maximum(row_norms(d), 1e-12)
    down = -d[:, 2]
    if tp.tool_axis is not None:  # 5 axes: along the tool too (a plunge along a tilted axis)
        along = -np.einsum("ij,ij->i", d, np.take(tp.tool_axis, fp, axis=0))
        down = np.where(np.abs(along) > np.abs(down), along, down)
    plunge = down > PLUNGE * length
    vertical = np.abs(down) > VERTICAL * length
    match = FEED_MATCH if tp.inverse_time is None else np.where(
        tp.inverse_time[fp], FEED_MATCH_G93 * np.abs(feed), FEED_MATCH)
    s_ref, off_feed, f0, s0 = _feed_intent(blocks, feed, tp.spindle_rpm[fp], mine & ~vertical,
                                           machine, cut, view.cutter, opts, intent, match)
    if intent is not None:
        # a plunge still at the operation's own feed kept its F while ncopt raised S: its
        # feed per revolution is the one the program gave it at its own S0, as in the
        # first rewrite (a second rewrite then plans the same)
        s_ref = np.where(plunge & (np.abs(feed - f0) <= 1.5 * max(opts.f_quantum_mm_min,
                                                                  FEED_MATCH)), s0, s_ref)
    # a cut off the cutting feed (a plunge at F1000 where the finish runs F279) goes as
    # fast as its own feed per revolution: the spindle changes less over it
    rev = feed / np.where(s_ref > 0, s_ref, np.nan)
    blocks = replace(blocks, k_scale=np.where(
        cutting & (off_feed | plunge) & (rev > 0),
        np.minimum(1.0, cut.fz_mm * view.cutter.teeth / np.where(rev > 0, rev, 1.0)), 1.0))
    tail = _fixed_line_after(tp, idx, scope, last) if w1 == last + 1 else None
    n = blocks.length_mm.shape[0]
    sep = _separating(tp, idx.first_point[win], blocks, view.sampled)
    with_tail, sep_tail = _with_tail(blocks, tail), _ext(sep, tail, True)
    with ThreadPoolExecutor(1, thread_name_prefix="ncopt-other-mode") as pool:
        # the other --s-changes mode, for its figure only, planned beside this one: one of
        # the two is a per-block Python loop, the other numpy work that releases the GIL
        other_plan = pool.submit(_other_mode_plan, with_tail, machine, cut,
                                 view.cutter.teeth, opts, sep_tail)
        try:
            emitted, f_mm, _ = _plan_blocks(with_tail, machine, cut, view.cutter.teeth, opts,
                                            sep_tail)
        except PlanningError as exc:
            raise PlanningError(exc.message, exc.path or path, exc.line) from None
        other_plan = other_plan.result()
    ext = lambda a, v: np.append(a, v) if tail is not None else a  # noqa: E731
    s_cmd = _back_at_fixed(np.where(ext(planned, False), emitted.s_cmd_rpm,
                                    ext(cmd_rpm[win], tail or 0.0)),
                           ext(planned, False), ext(mine, False), ext(blocks.running, True))[:n]
    emitted = schedule.Emitted(emitted.s_cmd_rpm[:n], emitted.s_low_rpm[:n],
                              emitted.s_high_rpm[:n], emitted.close_s_words)
    cmd_rpm[win] = s_cmd
    reduced = mine & planned & (off_feed | plunge | ~blocks.cutting)
    feeds = lambda s_low, f_mm: _op_feeds(  # noqa: E731
        s_low, f_mm[:n], feed, s_ref, reduced, blocks.cutting & mine & planned, plunge,
        machine.max_feed_mm_min, opts.fz_tolerance)
    f = feeds(emitted.s_low_rpm, f_mm)
    other = _other_mode_time(other_plan, with_tail, n, feeds, opts)
    return OpPlan(k, op.tool, view.cutter, cut, source, (lo, w1), blocks, s_cmd, f, reduced,
                  f0, emitted.close_s_words,
                  _over_target(blocks, emitted, machine, cut, view.cutter), s0,
                  coarse_lines=idx.line[win][coarse], s_low_rpm=emitted.s_low_rpm,
                  passes=int(passes.pass_ids(blocks, sep).max(initial=-1)) + 1,
                  cut_time_min=_feed_time(blocks.length_mm, f, opts.f_quantum_mm_min),
                  other_time_min=other)


def _op_feeds(s_low, f_mm, feed, s_ref, reduced, cutting, plunge, max_feed,
              tol: float = 0.0) -> np.ndarray:
    """F per block (mm/min; NaN: the program's own stays): the planner's on the cuts at
    the cutting feed; elsewhere fz as the program has it at most.  A plunge's F is never
    raised (the tip's centre does not cut: a D16 ball plunging at 3 m/min because S rose
    tenfold breaks), nor F in the air (the planner counts on the program's own time
    there); a ramp or lead-in along the surface follows S.  Where that F is within half
    the fz band ``tol`` of the program's own, the program's F stays as it is written
    (``F333.33`` is not turned into ``F333.`` for a spindle 0.2 % slower)."""
    ratio = s_low / np.where(s_ref > 0, s_ref, np.nan)
    scaled = feed * np.where(cutting & ~plunge, ratio, np.minimum(ratio, 1.0))
    f = np.where(reduced, np.minimum(scaled, max_feed), f_mm)
    with np.errstate(invalid="ignore", divide="ignore"):
        close = reduced & (np.abs(f / feed - 1.0) <= 0.5 * tol) & (feed <= max_feed)
    f = np.where(close, feed, f)
    return np.where(reduced | cutting, f, np.nan)


def _feed_time(length_mm: np.ndarray, f_mm_min: np.ndarray, quantum: float) -> float:
    """Minutes of the blocks whose F is set, at F as written (rounded down to the F words'
    resolution, as the targets are)."""
    ok = np.isfinite(f_mm_min) & (f_mm_min > 0)
    f = f_mm_min[ok]
    if quantum > 0:
        f = np.maximum(np.floor(f / quantum + 1e-6) * quantum, quantum)
    return float(np.sum(length_mm[ok] / f))


COARSE_MARGIN = 1.25


def _ext(a, tail, value):
    """``a`` with one more element for the tail instant (when there is one)."""
    return a if a is None or tail is None else np.append(a, value)


def _plan_blocks(blocks, machine, cut, teeth, opts, sep):
    if opts.s_changes == BETWEEN_PASSES:
        return passes.plan(blocks, machine, cut, teeth, opts, sep)
    return schedule.plan(blocks, machine, cut, teeth, opts)


def _separating(tp: Toolpath, fp: np.ndarray, blocks, sampled) -> np.ndarray | None:
    """Without a mesh, the blocks between passes that surely leave the part: rapids and
    moves that reach the top of the cut (a retract).  Near-vertical feed moves count as
    air moves there, though a raster over a steep wall cuts on them: S must not change
    on those.  With a mesh, every non-cutting block leaves the part (None)."""
    if sampled.estimate is None:
        return None
    last = np.concatenate((fp[1:] - 1, [tp.n - 1])) if fp.size else fp
    z = tp.xyz_mm[last, 2]
    top = float(np.max(z[blocks.cutting], initial=-np.inf))
    return (tp.motion[fp] == Motion.RAPID) | (z >= top - 1e-6)


def _other_mode_plan(blocks, machine, cut, teeth, opts, sep):
    """The blocks planned in the other --s-changes mode: (emitted, F mm/min), or None
    where that mode cannot hold the cutting data."""
    other = BETWEEN_PASSES if opts.s_changes in (None, ANYWHERE) else ANYWHERE
    try:
        em, f_mm, _ = _plan_blocks(blocks, machine, cut, teeth, replace(opts, s_changes=other),
                                   sep)
    except PlanningError:
        return None
    return em, f_mm


def _other_mode_time(other_plan, blocks, n, feeds, opts) -> float:
    """Minutes of the operation's blocks whose F ncopt sets, in the other --s-changes mode
    (``other_plan``: :func:`_other_mode_plan`): what the choice costs (``feeds``: the F of
    the blocks from the spindle's lowest speed and the planner's F).  NaN: that mode
    cannot hold the cutting data here."""
    if other_plan is None:
        return float("nan")
    em, f_mm = other_plan
    return _feed_time(blocks.length_mm[:n], feeds(em.s_low_rpm[:n], f_mm),
                      opts.f_quantum_mm_min)


def _fixed_line_after(tp: Toolpath, idx: schedule.BlockIndex, scope: Scope, last: int):
    """The program's S (RPM) at the first fixed line after block ``last`` that comes before
    the next block (a subprogram call, a canned cycle): it must be in force there.  None
    where the next block comes first, or the S there is not known."""
    line = int(idx.line[last])
    nxt = int(idx.line[last + 1]) if last + 1 < idx.line.shape[0] else scope.fixed.shape[0]
    hits = np.flatnonzero(scope.fixed[line + 1:nxt])
    if hits.size == 0:
        return None
    at = line + 1 + int(hits[0])
    ls = tp.lines
    known = ls.s_known[at - 1] if ls.call[at] else ls.s_known[at]
    s = float(ls.s_rpm[at])
    return s if known and s > 0 else None


def _with_tail(blocks: schedule.Blocks, tail_rpm: float | None) -> schedule.Blocks:
    """The blocks and, after them, an instant that keeps ``tail_rpm`` (a fixed line that
    does not move: the spindle must be at the program's speed when it comes)."""
    if tail_rpm is None:
        return blocks
    add = lambda a, v: np.append(a, v)  # noqa: E731
    return schedule.Blocks(
        length_mm=add(blocks.length_mm, 0.0), req_rpm=add(blocks.req_rpm, np.inf),
        cutting=add(blocks.cutting, False), planned=add(blocks.planned, False),
        time_s=add(blocks.time_s, 0.0), fixed_rpm=add(blocks.fixed_rpm, tail_rpm),
        spindle_start=add(blocks.spindle_start, False), running=add(blocks.running, True),
        k_limited=add(blocks.k_limited, False),
        k_scale=None if blocks.k_scale is None else add(blocks.k_scale, 1.0))


def _too_coarse(req_rpm, cutting, machine, cut, teeth, opts) -> np.ndarray:
    """Cutting blocks whose feed is so low that the resolution of the program's F words
    cannot hold fz within its band (F1. at a few mm/min): they keep the program's S and
    F.  The band needs F above q / tol (``schedule.max_speed_ratio``), with a margin."""
    q = opts.f_quantum_mm_min
    if not q > 0:
        return np.zeros(cutting.shape, dtype=bool)
    s_lo, s_hi = schedule.speed_limits(machine, cut, teeth)
    f_low = cut.fz_mm * teeth * np.clip(req_rpm, s_lo, s_hi)
    return cutting & (f_low <= COARSE_MARGIN * q / opts.fz_tolerance)


def _back_at_fixed(s_cmd: np.ndarray, planned: np.ndarray, mine: np.ndarray,
                   running: np.ndarray) -> np.ndarray:
    """The link moves just before a block that keeps the program's S command exactly that
    S (the emission rounds to steps of --min-rpm-step; the program's own must be in force
    when the block starts, written on those links)."""
    out = s_cmd.copy()
    link = planned & ~mine
    for i in np.flatnonzero(~planned[1:] & running[1:] & planned[:-1]).tolist():
        j = i  # block i + 1 keeps its S; walk back over the links before it
        while j >= 0 and link[j]:
            out[j] = s_cmd[i + 1]
            j -= 1
    return out


def _feed_intent(blocks, feed, s_prog, mine, machine, cut, cutter, opts, intent,
                 match=FEED_MATCH):
    """Which blocks of the operation run at another feed than its cutting feed (read
    from its ``mine`` blocks: plunges and retracts aside).

    Returns (s_ref, off_feed, F0, S0): per block the spindle speed the program's F
    refers to, and whether the block is off the cutting feed; the cutting feed F0
    (mm/min) and the operation's own S0 (RPM).  A block off the feed then gets
    ``F * S_low / s_ref``: the feed per tooth the program gives it, never more.

    For an ncopt output (``intent``: S0 and F0 from its stamp) ``s_ref`` is the lowest
    speed its own S words give the spindle in the block, and a cutting block was at the
    cutting feed where its F is the one ncopt writes for the stamped fz at those speeds:
    so a second rewrite gives the same F."""
    if intent is None:
        f0 = _cutting_feed(feed, blocks.length_mm, mine, not np.isscalar(match))
        s0 = _weighted_median(s_prog[mine], blocks.length_mm[mine]) if mine.any() else 0.0
        return s_prog, np.abs(feed - f0) > match, f0, s0
    s0, f0, spindle = intent
    if spindle is not None:  # the S and F written were planned for the stamped spindle
        machine = replace(machine, accel_rad_s2=spindle[0], max_rpm=spindle[1])
    fixed = replace(blocks, planned=np.zeros_like(blocks.planned))
    k = schedule.k_rpm2_per_mm(machine, cut, cutter.teeth)
    em = schedule.emit_rpm(schedule.Profile(fixed.fixed_rpm, fixed.fixed_rpm, k), fixed,
                          schedule.increments(fixed, machine, k), opts, machine.min_rpm,
                          float("inf"))
    s_ref = np.where(em.s_low_rpm > 0, em.s_low_rpm, s_prog)
    as_cut = replace(blocks, planned=np.ones_like(blocks.planned))
    q = max(opts.f_quantum_mm_min, 1e-9)
    expected = schedule.feeds(em.s_low_rpm, em.s_high_rpm, as_cut, cut, cutter.teeth,
                             machine.max_feed_mm_min, opts.fz_policy)
    expected = np.floor(expected / q + 1e-6) * q
    off = np.where(blocks.cutting, np.abs(feed - expected) > 1.5 * q,
                   np.abs(feed - f0) > 1.5 * q)
    return s_ref, off, f0, s0


def _cutting_feed(feed: np.ndarray, length: np.ndarray, mine: np.ndarray,
                  inverse_time: bool = False) -> float:
    """The F most of the operation's length runs at (mm/min).  With G93 in the program the
    tip feeds carry the rounding of each block's own F word: feeds within
    FEED_MATCH_G93 of each other count as one, and the feed is their weighted median."""
    f = np.round(feed[mine], 3)
    if f.size == 0:
        return float("nan")
    if inverse_time:
        key = np.round(np.log(np.maximum(f, 1e-9)) / np.log1p(FEED_MATCH_G93))
        values, inv = np.unique(key, return_inverse=True)
        w = np.bincount(inv.ravel(), weights=length[mine], minlength=values.size)
        pick = inv.ravel() == int(np.argmax(w))
        return _weighted_median(f[pick], length[mine][pick])
    values, inv = np.unique(f, return_inverse=True)
    w = np.bincount(inv.ravel(), weights=length[mine], minlength=values.size)
    return float(values[int(np.argmax(w))])


def _over_target(blocks, emitted, machine, cut, cutter) -> tuple:
    """Cutting blocks where the real spindle stays above the requirement (after the
    program's own S in a block ncopt could not plan): (count, worst vc excess %)."""
    s_lo, s_hi = schedule.speed_limits(machine, cut, cutter.teeth)
    req = np.clip(blocks.req_rpm, s_lo, s_hi)
    c = blocks.cutting & blocks.planned
    excess = emitted.s_high_rpm[c] / req[c] - 1.0
    bad = excess > 1e-3
    return (int(bad.sum()), float(100.0 * excess[bad].max()) if bad.any() else 0.0)


def nominal_cutting_data(tp: Toolpath, points: np.ndarray, cutter: Cutter,
                         path: str) -> CuttingData:
    """vc and fz the program itself runs at its nominal diameter (what the CAM intended):
    its S (length-weighted median) and its cutting feed over ``points``, plunges,
    retracts and other near-vertical moves aside (as :func:`plan_operation` reads the
    cutting feed): passes linked by long plunges at a lower F would otherwise give the
    plunge feed's fz to every cut.  Only where every move is near-vertical do they count."""
    idx = points[(tp.spindle_rpm[points] > 0) & (tp.feed_mm_min[points] > 0)]
    if idx.size == 0:
        raise PlanningError("the program gives no spindle speed or feed for its cuts; "
                            "give --vc and --fz", path)
    d = np.take(tp.xyz_mm, idx, axis=0) - np.take(tp.xyz_mm, np.maximum(idx - 1, 0), axis=0)
    up = np.abs(d[:, 2])
    if tp.tool_axis is not None:  # 5 axes: along the tool too
        up = np.maximum(up, np.abs(np.einsum("ij,ij->i", d, np.take(tp.tool_axis, idx, axis=0))))
    along = up <= VERTICAL * np.maximum(row_norms(d), 1e-12)
    if along.any():
        idx = idx[along]
    weight = tp.seg_len_mm[idx]
    s = _weighted_median(tp.spindle_rpm[idx], weight)
    f = _cutting_feed(tp.feed_mm_min[idx], weight, np.ones(idx.size, dtype=bool),
                      tp.inverse_time is not None)
    vc = np.pi * cutter.diameter_mm * s / 1000.0
    return CuttingData(vc_m_min=vc, fz_mm=f / (cutter.teeth * s))


def _weighted_median(values: np.ndarray, weight: np.ndarray) -> float:
    order = np.argsort(values, kind="stable")
    cum = np.cumsum(weight[order])
    if cum[-1] <= 0:
        return float(values[order][len(values) // 2])
    return float(values[order][np.searchsorted(cum, 0.5 * cum[-1])])


# ------------------------------------------------------------ the whole program ----
@dataclass(frozen=True)
class ToolChoice:
    """The cutter of one T number, or why ncopt cannot plan it."""

    cutter: Cutter | None
    source: str  # "options", "the tool profiles", "line N: (comment)", a stamp
    why: str = ""  # when cutter is None


@dataclass(frozen=True)
class Work:
    """Everything planned in one program."""

    ops: tuple  # Operation, in program order, with their final planned flag and reason
    scope: Scope
    plans: list  # OpPlan, in program order
    tools: dict  # T number -> ToolChoice
    views: dict  # (T number, Method) -> ToolView (the planned tools)
    point_op: np.ndarray
    fits: dict = None  # T number -> MeshFit (with a mesh)


def plannable_points(tp: Toolpath, cutting_given: bool = False) -> np.ndarray:
    """(n,) bool: feed moves ncopt can place and that run with the program's own,
    known S and F (G94, position known, spindle on, not a block-delete line).

    Where the program states no S at all (the spindle runs at a speed set at the
    machine), moves are plannable only with cutting data given (``cutting_given``) and
    only if no move it leaves alone runs without S too: ncopt could not put the
    operator's speed back before it."""
    ls = tp.lines
    feed = np.isin(tp.motion, [Motion.LINEAR, Motion.ARC_CW, Motion.ARC_CCW])
    if ls.executed.size == 0:
        return np.zeros(tp.n, dtype=bool)
    line = np.maximum(tp.line, 0)
    ok = feed & tp.known & tp.spindle_on & ls.executed[line] & ls.s_known[line]
    ok &= ls.f_known[line] & ~ls.block_delete[line]
    ok[0] = False
    no_s = ~(tp.spindle_rpm > 0)
    if not cutting_given or (feed & tp.spindle_on & no_s & ~ok)[1:].any():
        ok &= ~no_s
    return ok


def choose_cutter(job, table: dict, tool: int, n_tools: int, inch: bool,
                  stamps: dict) -> ToolChoice:
    """The cutter of T``tool``: the options, the tool profiles, the program's tool
    comment, an ncopt stamp; never a shape the program contradicts."""
    info = cutter_for(table, tool, n_tools)
    named = f"T{tool}" if tool >= 0 else "the tool"
    if job.cutter is not None:
        if info is not None and info.kind not in (BALL, BULL) and not job.shape_named:
            return ToolChoice(None, "", (
                f"the program describes {named} as {info.refusal()} ({info.text.strip()}, "
                f"line {info.line}); --diameter does not say the shape: pass --shape ball "
                "or --corner-radius if that comment is wrong"))
        return ToolChoice(job.cutter, "options")
    if tool in job.tool_library:
        return ToolChoice(job.tool_library[tool], "the tool profiles")
    if info is None:
        stamp = next((st for (t, _), st in sorted(stamps.items(), key=lambda kv: kv[1].line)
                      if t == tool), None)
        if stamp is not None:
            return ToolChoice(stamp.cutter, f"the ncopt stamp on line {stamp.line + 1}")
        return ToolChoice(None, "", "no diameter known from the program's comments: give "
                          "--diameter (and --corner-radius for a bull-nose)")
    if info.kind not in (BALL, BULL):
        return ToolChoice(None, "", f"{info.refusal()} ({info.text.strip()}, line "
                          f"{info.line}); ncopt plans ball and bull-nose cutters only")
    scale = MM_PER_INCH if inch else 1.0
    teeth = info.teeth or job.teeth
    said = (f"teeth from line {info.teeth_line}" if info.teeth is not None
            else f"{teeth} teeth assumed")
    return ToolChoice(info.cutter(teeth, scale),
                      f"line {info.line}: ({info.text.strip()}); {said}")


def plan_program(prog: Program, tp: Toolpath, idx: schedule.BlockIndex, job,
                 mesh_index) -> Work:
    """Operations, their scope and their plans; NothingToPlan where none is planned."""
    stamps = read_stamps(prog)
    plannable = plannable_points(tp, job.cutting is not None)
    choices = _choices(prog, tp, job, plannable, stamps)
    diameters = {t: c.cutter.diameter_mm for t, c in choices.items() if c.cutter is not None}
    found = _stamped_ops(prog, tp, stamps) or operations.find(prog, tp, diameters)
    ops = decide(found, choices, job, tp, plannable)
    point_op = _point_ops(tp, ops, plannable)
    cuts = {}
    for k, op in enumerate(ops):
        if op.planned:
            cuts[k] = _cutting(job, tp, point_op, k, op, choices[op.tool], stamps, prog.path)
            odd = implausible(cuts[k][0], choices[op.tool].cutter)
            if odd:
                ops[k] = replace(op, planned=False, reason=odd)
    point_op = _point_ops(tp, ops, plannable)
    op_tool = np.array([o.tool for o in ops] or [-1], dtype=np.int64)
    scope = regions.scope(prog, tp, idx, point_op, ops)
    views, plans, fits = {}, [], {}
    cmd = tp.spindle_rpm[idx.first_point].astype(np.float64)
    for k, op in enumerate(ops):
        if not op.planned or not (scope.owner == k).any():
            continue
        method = _method(op, job)
        key = (op.tool, method)
        if key not in views:
            sel = (point_op >= 0) & (op_tool[np.maximum(point_op, 0)] == op.tool)
            views[key] = tool_view(tp, idx, op.tool, choices[op.tool].cutter, sel, mesh_index,
                                   job.options, job.contact_tol_mm, method,
                                   job.machine.rapid_mm_min, job.stock_mm,
                                   _r_floor_mm(job, ops, cuts, op.tool, choices[op.tool].cutter))
            fits[op.tool] = mesh_fit(views[key], tp, sel, job.contact_tol_mm)
            check_fit(fits[op.tool], op.tool, job.contact_tol_mm, prog.path)
        cut, source = cuts[k]
        stamp = stamp_for(stamps, op.tool, _lines(stamps, op))
        intent = ((stamp.s0_rpm, stamp.f0_mm_min, getattr(stamps, "spindle", None))
                  if stamp and stamp.f0_mm_min else None)
        plans.append(replace(
            plan_operation(k, op, views[key], cut, source, tp, idx, point_op, scope, cmd,
                           job.machine, job.options, prog.path, intent),
            lines=_lines(stamps, op)))
    if not plans:
        exc = NothingToPlan(_nothing_why(ops, choices, tp), prog.path)
        exc.operations = tuple(ops)  # for reports: every operation and why it is left
        raise exc
    return Work(tuple(ops), scope, plans, choices, views, point_op, fits)


def _r_floor_mm(job, ops, cuts, tool: int, cutter: Cutter) -> float:
    """The smallest R_eff at which an operation of ``tool`` asks for less than S_max."""
    floors = [1000.0 * cut.vc_m_min
              / (2.0 * np.pi * schedule.speed_limits(job.machine, cut, cutter.teeth)[1])
              for k, (cut, _) in cuts.items() if ops[k].tool == tool]
    return min(floors, default=0.0)


def _choices(prog, tp, job, plannable, stamps) -> dict:
    tools = np.unique(tp.tool[plannable]).tolist()
    if job.tool is not None and job.tool not in tools:
        raise UsageError(f"no feed moves with tool T{job.tool}; check --tool", prog.path)
    if job.cutter is not None and len(tools) > 1 and job.tool is None:
        listed = ", ".join(f"T{t}" for t in tools)
        raise UsageError(f"the program cuts with several tools ({listed}); say which one "
                         "--diameter describes with --tool N", prog.path)
    table = tool_table(prog)
    inch = tp.line_inch is not None and bool(np.any(tp.line_inch))
    choices = {t: choose_cutter(job, table, t, len(tools), inch, stamps) for t in tools}
    return {t: _no_tilted_bull_nose(c, tp, plannable & (tp.tool == t)) for t, c in choices.items()}


def _no_tilted_bull_nose(choice: ToolChoice, tp: Toolpath, points: np.ndarray) -> ToolChoice:
    """A bull-nose whose tool axis tilts is not planned: its contact search assumes +Z,
    and without a mesh its centre path is no offset surface when the axis turns."""
    c = choice.cutter
    if c is None or c.is_ball or tp.tool_axis is None or not np.any(tp.tool_axis[points, :2]):
        return choice
    return ToolChoice(None, "", "a bull-nose with a tilted tool axis: ncopt plans 5-axis "
                      "moves with ball-end mills only")


def decide(ops: list, choices: dict, job, tp: Toolpath, plannable: np.ndarray) -> list:
    """The final choice per operation: its geometry's, unless its cutter cannot be
    planned, --tool names another, --operations overrides it, block-delete lines make
    its course unknown, or nothing of it can be placed."""
    ls = tp.lines
    wanted = _wanted(job.operations)
    out = []
    for op in ops:
        if op.kind == NO_CUT and not op.planned:  # feed moves it cannot place: say why
            located = unplannable_why(tp, op)
            if located != op.reason:
                op = replace(op, kind=operations.UNPLACED, reason=located)
        planned, why = op.planned, op.reason
        choice = choices.get(op.tool)
        base_name = op.name.split(" (part ")[0]
        if wanted is not None and op.kind != CANNED and _points(tp, op, plannable).size:
            forced = wanted == "all" or base_name.lower() in wanted or op.name.lower() in wanted
            if forced and not planned:
                planned, why = True, f"{why}; planned because --operations names it"
            elif not forced and planned:
                planned, why = False, "not named in --operations"
        if choice is not None and choice.cutter is None and op.kind not in (NO_CUT, CANNED):
            planned, why = False, choice.why
        elif choice is None and op.kind not in (NO_CUT, CANNED):
            planned, why = False, unplannable_why(tp, op)
        if planned and job.tool is not None and op.tool != job.tool:
            planned, why = False, f"another tool than T{job.tool} (--tool)"
        span = slice(op.first_line, op.last_line + 1)
        deleted = np.flatnonzero(ls.block_delete[span] & ls.executed[span])
        if deleted.size and op.kind not in (NO_CUT, CANNED):
            planned = False
            why = (f"block-delete line {op.first_line + int(deleted[0]) + 1} (/): whether it "
                   "runs is the operator's choice, so the S and F in force are not known")
        if planned and not _points(tp, op, plannable).size:
            planned, why = False, unplannable_why(tp, op)
        out.append(replace(op, planned=planned, reason=why))
    return out


def _wanted(operations_opt) -> set | str | None:
    if operations_opt is None:
        return None
    if isinstance(operations_opt, str):
        operations_opt = [operations_opt]
    names = {n.strip().lower() for n in operations_opt if n.strip()}
    return "all" if "all" in names else names


def _points(tp: Toolpath, op, plannable: np.ndarray) -> np.ndarray:
    """Toolpath points of ``op`` that ncopt can plan."""
    a, b = np.searchsorted(tp.line[1:], [op.first_line, op.last_line + 1]) + 1
    pts = np.arange(a, b)
    return pts[plannable[pts]]


def _point_ops(tp: Toolpath, ops: list, plannable: np.ndarray) -> np.ndarray:
    out = np.full(tp.n, -1, dtype=np.int64)
    for k, op in enumerate(ops):
        if op.planned:
            out[_points(tp, op, plannable)] = k
    return out


def _method(op, job) -> Method:
    """The contact method of the job; a roughing operation a user includes is planned
    where the edge meets the remaining material, ap = its step-down along the axis."""
    if op.kind in (CLEARING, ROUGH_LEVELS) and np.isfinite(op.step_mm):
        return Method("material", float(op.step_mm), "axis")
    return job.method


def _cutting(job, tp, point_op, k, op, choice, stamps, path) -> tuple:
    """The cutting data of operation ``k`` and where they come from."""
    if job.cutting is not None:
        return job.cutting, "options"
    stamp = stamp_for(stamps, op.tool, _lines(stamps, op))
    if stamp is not None:
        return stamp.cutting, f"the ncopt stamp on line {stamp.line + 1}"
    pts = np.flatnonzero(point_op == k)
    return as_stamped(nominal_cutting_data(tp, pts, choice.cutter, path)), "the program"


def _lines(stamps: dict, op) -> tuple:
    """The operation's lines as a stamp names them (1-based, without stamp lines)."""
    return (unstamped_line(stamps, op.first_line), unstamped_line(stamps, op.last_line))


def _stamped_ops(prog: Program, tp: Toolpath, stamps: dict) -> list | None:
    """An ncopt output is planned again exactly where its stamp says it was planned (its
    S and F words no longer tell roughing from finishing); None for other programs."""
    ranges = sorted({(st.lines, st.tool, st.line) for st in stamps.values() if st.lines})
    if not ranges:
        return None
    out = []
    for span in operations.spans(prog, tp):
        a = span.first_line
        for (first, last), tool, line in ranges:
            lo, hi = stamped_line(stamps, first), stamped_line(stamps, last)
            lo, hi = max(lo, span.first_line), min(hi, span.last_line)
            if lo > hi:
                continue
            if lo > a:
                out.append(_piece(tp, span, a, lo - 1, False, "not planned by the rewrite "
                                  f"that stamped this program (line {line + 1})"))
            out.append(_piece(tp, span, lo, hi, True, f"planned by the rewrite that stamped "
                              f"this program (line {line + 1})"))
            a = hi + 1
        if a <= span.last_line:
            out.append(_piece(tp, span, a, span.last_line, False, "not planned by the rewrite "
                              "that stamped this program"))
    return out


def _piece(tp: Toolpath, span, lo: int, hi: int, planned: bool, why: str) -> Operation:
    a, b = np.searchsorted(tp.line[1:], [lo, hi + 1]) + 1
    pts = np.arange(a, b)
    feed = pts[tp.motion[pts] >= Motion.LINEAR]
    tool = int(tp.tool[feed[0]]) if feed.size else int(tp.lines.tool[hi])
    name = span.name or (f"T{tool}" if tool >= 0 else "the program")
    kind = operations.STAMPED if planned else operations.NO_CUT if not feed.size else \
        operations.LEFT_BEFORE
    return Operation(name=name, tool=tool, first_line=lo, last_line=hi, kind=kind,
                     planned=planned, reason=why, name_line=span.name_line)


PLAUSIBLE_FZ_MM, PLAUSIBLE_F_MM_MIN, PLAUSIBLE_S_RPM = 1.0, 100000.0, 100000.0


def implausible(cut: CuttingData, cutter: Cutter) -> str:
    """Why cutting data cannot be what the programmer meant ("" when plausible): a
    parameter or unit slip, which ncopt must not scale."""
    s = 1000.0 * cut.vc_m_min / (np.pi * cutter.diameter_mm)
    f = cut.fz_mm * cutter.teeth * s
    if cut.fz_mm > PLAUSIBLE_FZ_MM or f > PLAUSIBLE_F_MM_MIN or s > PLAUSIBLE_S_RPM:
        return (f"implausible cutting data: S {s:.0f} RPM, F {f:.0f} mm/min, fz {cut.fz_mm:.4g} "
                f"mm (above {PLAUSIBLE_S_RPM:.0f} RPM, {PLAUSIBLE_F_MM_MIN:.0f} mm/min or "
                f"{PLAUSIBLE_FZ_MM:g} mm): check the program's S and F (parameters, units)")
    return ""


def unplannable_why(tp: Toolpath, op) -> str:
    """Why none of an operation's feed moves can be planned."""
    a, b = np.searchsorted(tp.line[1:], [op.first_line, op.last_line + 1]) + 1
    pts = np.arange(a, b)
    feed = pts[np.isin(tp.motion[pts], [Motion.LINEAR, Motion.ARC_CW, Motion.ARC_CCW])]
    if feed.size == 0:
        return op.reason
    ls = tp.lines
    line = tp.line[feed]
    located = _located_reason(tp, op)
    for bad, why in (
            (~tp.known[feed], located or "position not known (after G28/G53/G92, a call, a "
             "cycle), G95 feed or cutter compensation"),
            (~tp.spindle_on[feed], "the spindle is not on (no M3/M4)"),
            (~ls.s_known[line] | ~ls.f_known[line], "the S or F in force is not known (after a "
             "subprogram call, or an expression ncopt cannot evaluate)"),
            (~(tp.spindle_rpm[feed] > 0), "the program states no S (the spindle runs at a speed "
             "set at the machine): give --vc and --fz to plan it")):
        if bad.all():
            return why
    return "no feed move ncopt can place"


def _located_reason(tp: Toolpath, op) -> str:
    """The first located 'not planned' warning of the interpreter inside ``op``'s lines
    (the tool axis, G93 without F...), as ``line A-B: why``; "" when there is none."""
    for w in tp.warnings:
        head, sep, rest = w.partition(": not planned (")
        lines = head.rsplit(":", 1)[-1].split("-")
        if not sep or not all(x.isdigit() for x in lines):
            continue
        if op.first_line + 1 <= int(lines[-1]) and int(lines[0]) <= op.last_line + 1:
            return f"line {head.rsplit(':', 1)[-1]}: {rest.rsplit('); S/F', 1)[0]}"
    return ""


def _nothing_why(ops, choices, tp: Toolpath | None = None) -> str:
    """Why nothing is planned, operation by operation (the first few); where no
    operation cuts, the first moves the interpreter left alone and why."""
    by_reason: dict[str, list[str]] = {}  # operations with the same reason: one row
    for o in ops:
        if o.kind not in (NO_CUT,):
            by_reason.setdefault(o.reason, []).append(f"{o.name} ({o.lines})")
    if not by_reason:
        first = next((w for w in (tp.warnings if tp is not None else ())
                      if ": not planned (" in w), None)
        more = f"; the first moves left alone: {first}" if first else ""
        return f"nothing to plan (no feed moves with a running spindle and a known position{more})"
    rows = []
    for reason, names in by_reason.items():
        extra = f" and {len(names) - NAMES_PER_REASON} more" if len(names) > NAMES_PER_REASON \
            else ""
        rows.append(", ".join(names[:NAMES_PER_REASON]) + extra + f": {reason}")
    more = f"; and {len(rows) - 6} more" if len(rows) > 6 else ""
    return "nothing to plan: " + "; ".join(rows[:6]) + more


NAMES_PER_REASON = 3  # operations named before "and N more" in a "nothing to plan" row
