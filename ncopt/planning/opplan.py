"""One operation's plan: the S and F ncopt sets on the window of blocks it owns.

The window is the operation's own blocks (its cuts and the link moves of its run, see
:mod:`ncopt.planning.regions`), one block before it at the speed then commanded (so the
spindle starts from where it really is), and the first fixed block after it where the
program's own S must be back in force.  Only the blocks at the operation's cutting feed
follow the fz target; a plunge, or a ramp, lead-in or link at another feed, is scaled
with the spindle (:mod:`ncopt.planning.plans`).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace

import numpy as np

from ncopt.contacts.cutters import required_rpm
from ncopt.contacts.locate import Sampled, contacts_for, with_onsets
from ncopt.model import Cutter, CuttingData, Machine, Method, Motion, PlanOptions, Toolpath
from ncopt.motion.modal import row_norms
from ncopt.planning import passes, schedule
from ncopt.planning.intent import FEED_MATCH, FEED_MATCH_G93, VERTICAL, Intent, feed_intent
from ncopt.planning.operations import Operation
from ncopt.planning.regions import Scope
from ncopt.reading.controls import ANYWHERE, BETWEEN_PASSES
from ncopt.runtime.errors import PlanningError

PLUNGE = 0.99  # a feed move down within 8 deg of the axis plunges: fz as programmed
COARSE_MARGIN = 1.25
#: plans of one operation at most, each keeping the cuts the last found too slow for
#: the F words' resolution (:func:`plan_operation`)
COARSE_ROUNDS = 8


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
    over_target: tuple[int, float] = (0, 0.0)  # cutting blocks above their vc target, worst %
    s0_rpm: float = 0.0  # the operation's own S (the program's), for the stamp
    lines: tuple[int, int] = (0, 0)  # its (first, last) lines, 1-based, without stamp lines
    ap_mm: float = float("nan")  # roughing: the material height its contacts took (mm)
    coarse_lines: np.ndarray | None = None  # 0-based lines kept: F words too coarse for fz
    s_low_rpm: np.ndarray | None = None  # lowest real spindle speed per block of the window
    passes: int = 0  # runs of cutting blocks (ncopt.planning.passes.pass_ids)
    cut_time_min: float = 0.0  # its cutting blocks at the planned F
    other_time_min: float = float("nan")  # the same with the other --s-changes mode
    s_varies: bool = False  # the program's own S is not one value over the operation's cuts


@dataclass(frozen=True)
class ToolView:
    """What one tool's contacts give every block of the program (vc = 1 m/min)."""

    tool: int
    cutter: Cutter
    sampled: Sampled
    base: schedule.Blocks  # req_rpm per 1 m/min of vc; cutting only on its planned ops


def tool_view(tp: Toolpath, idx: schedule.BlockIndex, tool: int, cutter: Cutter,
              selected: np.ndarray, mesh_index, opts: PlanOptions, tol_mm: float,
              method: Method, rapid_mm_min: float, stock_mm: float = 0.0,
              r_floor_mm: float = 0.0) -> ToolView:
    """``r_floor_mm``: R_eff below which every operation of the tool runs at S_max
    (the mesh is sampled no finer where R_eff only changes below it)."""
    sampled = contacts_for(tp, cutter, selected, mesh_index, opts.sample_mm, tol_mm, method,
                           stock_mm, r_floor_mm=r_floor_mm)
    c = sampled.contacts
    # with a mesh, the onset of a contact lies between a sample that cuts and one that
    # does not yet: both requirements count (with_onsets)
    counted = with_onsets(c.cutting) if sampled.estimate is None else None
    base = schedule.blocks_from_contacts(
        idx, tp.seg_len_mm, tp.motion, tp.feed_mm_min, tp.known, tp.spindle_on,
        tp.spindle_rpm, required_rpm(c.r_eff_mm, 1.0), c.cutting, sampled.point, selected,
        rapid_mm_min, counted)
    return ToolView(tool, cutter, sampled, base)


def plan_operation(k: int, op: Operation, view: ToolView, cut: CuttingData, source: str,
                   tp: Toolpath, idx: schedule.BlockIndex, point_op: np.ndarray, scope: Scope,
                   cmd_rpm: np.ndarray, machine: Machine, opts: PlanOptions,
                   path: str, intent: Intent | None = None) -> OpPlan:
    """Plan operation ``k``; ``cmd_rpm`` (nb,) holds the S commanded per block so far
    (the program's, and the plans before this one): it is updated in place.

    ``intent``: (S0 RPM, F0 mm/min), the operation's own S and cutting feed as an ncopt
    stamp records them (the program is an ncopt output); None: read from the program."""
    w = _window(k, view.base, scope, idx, tp, point_op)
    win, teeth = slice(w.lo, w.end), view.cutter.teeth
    coarse = _too_coarse(view.base.req_rpm[win] * cut.vc_m_min, view.base.cutting[win] & w.planned,
                         machine, cut, teeth, opts)
    # the requirement says which feeds are too low for the F words' resolution; the plan
    # may go lower still (a ramp held by the fz band): those blocks keep theirs too, and
    # the operation is planned again around them (each round keeps more, so it ends)
    for _ in range(COARSE_ROUNDS):
        plan = _plan_window(k, op, view, cut, source, tp, idx, scope, w, coarse, cmd_rpm,
                            machine, opts, path, intent)
        late = _coarse_feeds(plan, w.mine, opts) & ~coarse
        if not late.any():
            break
        coarse = coarse | late
    cmd_rpm[win] = plan.s_cmd_rpm
    return plan


def _plan_window(k: int, op: Operation, view: ToolView, cut: CuttingData, source: str,
                 tp: Toolpath, idx: schedule.BlockIndex, scope: Scope, w: "_Window",
                 coarse: np.ndarray, cmd_rpm: np.ndarray, machine: Machine,
                 opts: PlanOptions, path: str, intent: Intent | None) -> OpPlan:
    """Plan the window ``w`` with the blocks ``coarse`` kept as programmed; ``cmd_rpm``:
    (nb,) the S commanded per block so far (read, not changed)."""
    win, teeth = slice(w.lo, w.end), view.cutter.teeth
    blocks = _window_blocks(view.base, win, w.planned & ~coarse, cut, cmd_rpm, w.mine,
                            machine.max_rpm)
    fp = idx.first_point[win]
    roles = _feed_roles(tp, fp, blocks, w.mine, view.cutter, cut, machine, opts, intent)
    blocks = replace(blocks, k_scale=_k_scale(blocks, roles, cut, teeth))
    tail = _fixed_line_after(tp, idx, scope, w.last) if w.end == w.last + 1 else None
    n = blocks.length_mm.shape[0]
    sep = _separating(tp, fp, blocks, view.sampled)
    with_tail = _with_tail(blocks, tail)
    emitted, f_mm, other_plan = _plan_both_modes(with_tail, machine, cut, teeth, opts,
                                                 _ext(sep, tail, True), path)
    s_cmd = _commands(emitted, blocks, w.mine, cmd_rpm[win], tail)[:n]
    emitted = schedule.Emitted(emitted.s_cmd_rpm[:n], emitted.s_low_rpm[:n],
                               emitted.s_high_rpm[:n], emitted.close_s_words)
    planned = blocks.planned
    reduced = w.mine & planned & (roles.off_feed | roles.plunge | ~blocks.cutting)
    # an ncopt output: its F words may have been slowed with S below S0 (F0 S/S0 then)
    up_to = 1.0 if intent is None else np.maximum(1.0, roles.s0 / np.where(
        roles.s_ref > 0, roles.s_ref, np.inf))
    feeds = lambda s_low, f_mm: _op_feeds(  # noqa: E731
        s_low, f_mm[:n], roles.feed, roles.s_ref, reduced, blocks.cutting & w.mine & planned,
        roles.plunge, machine.max_feed_mm_min, opts.fz_tolerance, up_to)
    f = feeds(emitted.s_low_rpm, f_mm)
    other = _other_mode_time(other_plan, with_tail, n, feeds, opts)
    return OpPlan(k, op.tool, view.cutter, cut, source, (w.lo, w.end), blocks, s_cmd, f,
                  reduced, roles.f0, emitted.close_s_words,
                  _over_target(blocks, emitted, machine, cut, view.cutter), roles.s0,
                  coarse_lines=idx.line[win][coarse], s_low_rpm=emitted.s_low_rpm,
                  passes=int(passes.pass_ids(blocks, sep).max(initial=-1)) + 1,
                  cut_time_min=_feed_time(blocks.length_mm, f, opts.f_quantum_mm_min),
                  other_time_min=other, s_varies=_s_varies(tp, fp, w.mine, intent))


def _s_varies(tp: Toolpath, fp: np.ndarray, mine: np.ndarray, intent: Intent | None) -> bool:
    """Whether the program's own S takes more than one value over the operation's moves
    (for an ncopt output: as its stamp says, its S words being ncopt's)."""
    if intent is not None:
        return intent.s0_varies
    s = tp.spindle_rpm[fp][mine]
    s = s[np.isfinite(s) & (s > 0)]
    return bool(s.size) and bool(s.min() != s.max())


def _coarse_feeds(plan: OpPlan, mine: np.ndarray, opts: PlanOptions) -> np.ndarray:
    """(window,) the operation's cuts at the cutting feed whose planned F is too low for
    the resolution of the program's F words to hold fz in its band (as
    :func:`_too_coarse` judges a requirement)."""
    q = opts.f_quantum_mm_min
    b = plan.blocks
    if not q > 0:
        return np.zeros(b.cutting.shape, dtype=bool)
    with np.errstate(invalid="ignore"):
        low = plan.f_mm_min <= COARSE_MARGIN * q / opts.fz_tolerance
    return b.cutting & b.planned & mine & ~plan.reduced & low


@dataclass(frozen=True)
class _Window:
    """The blocks [lo, end) one operation's plan covers.

    last : its last owned block;  mine : (end - lo,) the blocks of its own planned
    points;  planned : the blocks ncopt may set (its own, and the free moves of its run)
    """

    lo: int
    end: int
    last: int
    mine: np.ndarray
    planned: np.ndarray


def _window(k: int, base: schedule.Blocks, scope: Scope, idx: schedule.BlockIndex,
            tp: Toolpath, point_op: np.ndarray) -> _Window:
    """Operation ``k``'s window: the blocks it owns, the one before (the speed the
    spindle comes from, not planned) and the running block after, where the program's
    own speed must be back."""
    owned = np.flatnonzero(scope.owner == k)
    w0, last = int(owned[0]), int(owned[-1])
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
    return _Window(lo, w1, last, mine, planned)


def _window_blocks(base: schedule.Blocks, win: slice, planned: np.ndarray, cut: CuttingData,
                   cmd_rpm: np.ndarray, mine: np.ndarray,
                   max_rpm: float = np.inf) -> schedule.Blocks:
    """The planner's view of the window: the tool's blocks at the operation's vc, the S
    commanded so far (``cmd_rpm``) where ncopt does not plan, as the spindle runs it (at
    most ``max_rpm``)."""
    # a program's S above the machine's, on a block ncopt leaves: its spindle turns at most
    # at the machine's (the planned blocks keep their S as written: an ncopt output's are
    # replayed on the spindle they were planned for, ncopt.planning.intent)
    planned = _tie_links(planned, mine, base.running[win])
    fixed_rpm = np.where(planned, cmd_rpm[win], np.minimum(cmd_rpm[win], max_rpm))
    cutting = base.cutting[win] & planned
    return schedule.Blocks(
        length_mm=base.length_mm[win], req_rpm=base.req_rpm[win] * cut.vc_m_min,
        cutting=cutting, planned=planned, time_s=base.time_s[win],
        fixed_rpm=fixed_rpm, spindle_start=base.spindle_start[win],
        running=base.running[win], k_limited=cutting)


def _tie_links(planned: np.ndarray, mine: np.ndarray, running: np.ndarray) -> np.ndarray:
    """The blocks still planned: the link moves just before a block that keeps the
    program's S keep it too, so that the spindle the plan tracks is the one the output
    runs (planned, then written back to the program's S, they left F on the cuts after a
    spindle start planned at S5402 and run at S2000 for 3800 RPM: fz +97 %)."""
    out = planned.copy()
    link = planned & ~mine
    for i in np.flatnonzero(~planned[1:] & running[1:] & planned[:-1]).tolist():
        j = i  # block i + 1 keeps its S; so do the links before it
        while j >= 0 and link[j]:
            out[j] = False
            j -= 1
    return out


@dataclass(frozen=True)
class _FeedRoles:
    """What the program's F means on each block of a window, (nb,) arrays.

    feed : the programmed F, mm/min;  s_ref : the spindle speed it refers to, RPM;
    off_feed : the block runs off the cutting feed;  plunge : a plunge (fz as programmed);
    f0 : the cutting feed, mm/min;  s0 : the operation's own S, RPM
    """

    feed: np.ndarray
    s_ref: np.ndarray
    off_feed: np.ndarray
    plunge: np.ndarray
    f0: float
    s0: float


def _feed_roles(tp: Toolpath, fp: np.ndarray, blocks: schedule.Blocks, mine: np.ndarray,
                cutter: Cutter, cut: CuttingData, machine: Machine, opts: PlanOptions,
                intent: Intent | None) -> _FeedRoles:
    """The blocks' feeds read as :func:`ncopt.planning.intent.feed_intent` reads them,
    from the moves of the operation's own blocks that are not near the tool axis."""
    feed = tp.feed_mm_min[fp]
    plunge, vertical = _plunges(tp, fp)
    g93 = None if tp.inverse_time is None else tp.inverse_time[fp]  # per block
    match = FEED_MATCH if g93 is None else np.where(g93, FEED_MATCH_G93 * np.abs(feed),
                                                    FEED_MATCH)
    s_ref, off_feed, f0, s0 = feed_intent(
        blocks, feed, tp.spindle_rpm[fp], mine & ~vertical, machine, cut, cutter, opts, intent,
        match, g93)
    if intent is not None:
        # a plunge still at the operation's own feed kept its F while ncopt raised S: its
        # feed per revolution is the one the program gave it at its own S0, as in the
        # first rewrite (a second rewrite then plans the same).  Any other plunge where
        # the operation's S was one value (the stamp's S0=, not S0~), or in G93: its F was
        # the program's times at most S/S0 (never raised), so its feed per revolution is
        # F over the lower of S0 and the speed replayed (boat-xyzac.ngc planned 9-12 %
        # slower on a second run where read at the replayed speed).  Not where the
        # program's S varied: a plunge it gave its own faster S (S3000 where the cut runs
        # S1393) is read at neither (the output no longer holds that S).
        at_f0 = plunge & (np.abs(feed - f0) <= 1.5 * max(opts.f_quantum_mm_min, FEED_MATCH))
        lower = plunge if not intent.s0_varies else (
            np.zeros_like(plunge) if g93 is None else plunge & g93)
        s_ref = np.where(at_f0, s0, np.where(lower, np.minimum(s0, s_ref), s_ref))
    return _FeedRoles(feed, s_ref, off_feed, plunge, f0, s0)


def _plunges(tp: Toolpath, fp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(plunge, vertical) per block: the move that ends at ``fp`` goes down within
    ``PLUNGE`` of the tool axis, or up or down within ``VERTICAL`` of it."""
    d = np.take(tp.xyz_mm, fp, axis=0) - np.take(tp.xyz_mm, np.maximum(fp - 1, 0), axis=0)
    length = np.maximum(row_norms(d), 1e-12)
    down = -d[:, 2]
    if tp.tool_axis is not None:  # 5 axes: along the tool too (a plunge along a tilted axis)
        along = -np.einsum("ij,ij->i", d, np.take(tp.tool_axis, fp, axis=0))
        down = np.where(np.abs(along) > np.abs(down), along, down)
    return down > PLUNGE * length, np.abs(down) > VERTICAL * length


def _k_scale(blocks: schedule.Blocks, roles: _FeedRoles, cut: CuttingData,
             teeth: int) -> np.ndarray:
    """A cut off the cutting feed (a plunge at F1000 where the finish runs F279) goes as
    fast as its own feed per revolution: the spindle changes less over it."""
    rev = roles.feed / np.where(roles.s_ref > 0, roles.s_ref, np.nan)
    return np.where(blocks.cutting & (roles.off_feed | roles.plunge) & (rev > 0),
                    np.minimum(1.0, cut.fz_mm * teeth / np.where(rev > 0, rev, 1.0)), 1.0)


def _plan_both_modes(blocks: schedule.Blocks, machine: Machine, cut: CuttingData, teeth: int,
                     opts: PlanOptions, sep: np.ndarray | None, path: str) -> tuple:
    """(emitted, F mm/min) of the blocks in the chosen --s-changes mode, and
    :func:`_other_mode_plan`: the other mode, for its figure only, planned beside this
    one (one of the two is a per-block Python loop, the other numpy work that releases
    the GIL).  A PlanningError names the program's ``path``."""
    with ThreadPoolExecutor(1, thread_name_prefix="ncopt-other-mode") as pool:
        other_plan = pool.submit(_other_mode_plan, blocks, machine, cut, teeth, opts, sep)
        try:
            emitted, f_mm, _ = _plan_blocks(blocks, machine, cut, teeth, opts, sep)
        except PlanningError as exc:
            raise PlanningError(exc.message, exc.path or path, exc.line) from None
        other_plan = other_plan.result()
    return emitted, f_mm, other_plan


def _commands(emitted: schedule.Emitted, blocks: schedule.Blocks, mine: np.ndarray,
              cmd_rpm: np.ndarray, tail: float | None) -> np.ndarray:
    """S per block of the window (and the tail instant, when there is one): the plan's
    where ncopt plans, else ``cmd_rpm``, the S commanded so far."""
    planned = _ext(blocks.planned, tail, False)
    return _back_at_fixed(np.where(planned, emitted.s_cmd_rpm, _ext(cmd_rpm, tail, tail or 0.0)),
                          planned, _ext(mine, tail, False), _ext(blocks.running, tail, True))


def _op_feeds(s_low, f_mm, feed, s_ref, reduced, cutting, plunge, max_feed,
              tol: float = 0.0, up_to=1.0) -> np.ndarray:
    """F per block (mm/min; NaN: the program's own stays): the planner's on the cuts at
    the cutting feed; elsewhere fz as the program has it at most.  A plunge's F is never
    raised (the tip's centre does not cut: a D16 ball plunging at 3 m/min because S rose
    tenfold breaks); F in the air stays the program's (the planner counts on its time
    there, and no tooth cuts); a ramp or lead-in along the surface follows S.  Where that F is within half
    the fz band ``tol`` of the program's own, the program's F stays as it is written
    (``F333.33`` is not turned into ``F333.`` for a spindle 0.2 % slower).  ``up_to``: how
    far a plunge's F may rise over the F written (1; in an ncopt output, back to the
    program's own: a plunge an earlier plan slowed with S runs at the program's own feed
    per tooth again where S is back up)."""
    ratio = s_low / np.where(s_ref > 0, s_ref, np.nan)
    # in the air F is the program's: the tool cuts nothing there, and the plan took the
    # block's time at that F (a lower F would make a second rewrite plan another time)
    scaled = feed * np.where(cutting & ~plunge, ratio,
                             np.where(cutting, np.minimum(ratio, up_to), 1.0))
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


def _over_target(blocks, emitted, machine, cut, cutter) -> tuple[int, float]:
    """Cutting blocks where the real spindle, as the planner tracked it, stays above the
    lowest S it could plan there (the requirement within the machine's range and the
    feed cap: after the program's own S in a block ncopt could not plan, or a forward
    plan's rise): (count, worst vc excess %).  The excess is against the requirement
    itself, as simulate measures vc (a block under the feed cap's S whose spindle runs
    between the two is below its vc target, not above it).  The summary's warning
    states at least this, and what a replay of the S and F written finds
    (``ncopt.writing.warnings.real_top_rpm``): a plunge, whose F is never raised, lasts
    longer than this model's cut at F = fz z S."""
    s_lo, s_hi = schedule.speed_limits(machine, cut, cutter.teeth)
    need = blocks.req_rpm
    c = blocks.cutting & blocks.planned
    high = emitted.s_high_rpm
    with np.errstate(divide="ignore", invalid="ignore"):
        excess = high / need - 1.0
    bad = c & (excess > 1e-3) & (high > np.clip(need, s_lo, s_hi) * (1.0 + 1e-3))
    return (int(bad.sum()), float(100.0 * excess[bad].max()) if bad.any() else 0.0)
