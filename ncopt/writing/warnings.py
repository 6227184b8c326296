"""The rewrite's warnings, each located (``path:line: ...``), as the summary gives them."""

from __future__ import annotations

import numpy as np

from ncopt.contacts.locate import below_top_mm
from ncopt.model import Job, Machine, Program, Toolpath
from ncopt.planning.opplan import OpPlan
from ncopt.planning.plans import Work
from ncopt.planning.schedule import BlockIndex
from ncopt.reading.stamp import read_stamps
from ncopt.writing.edits import Targets
from ncopt.writing.targets import feed_after


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
    for p in work.plans:
        out.extend(_plan_notes(prog, tp, idx, work, p, job))
    return tuple(out)


def _plan_notes(prog: Program, tp: Toolpath, idx: BlockIndex, work: Work, p: OpPlan,
                job: Job) -> list[str]:
    """One plan's warnings: cutting blocks below the machine's lowest speed, above their
    target after an S ncopt could not plan, kept for F words too coarse, planned without
    a known contact, and blocks off the cutting feed scaled with S."""
    out = _below_min_rpm(prog, idx, work, p, job.machine)
    if p.over_target[0]:
        op = work.ops[p.op]
        out.append(f"{prog.path}: {op.name} (T{p.tool}): vc up to {p.over_target[1]:.1f} % "
                   f"above its target on {p.over_target[0]} cutting blocks, where the "
                   "spindle is still falling from an S that ncopt could not plan")
    if p.coarse_lines is not None and p.coarse_lines.size:
        op = work.ops[p.op]
        first = int(p.coarse_lines[0]) + 1
        out.append(f"{prog.path}:{first}: {op.name}: {p.coarse_lines.size} cutting blocks keep "
                   "their S and F: their feed is too low for the resolution of the "
                   "program's F words to hold fz within its band (write F with more "
                   "decimals to plan them)")
    out.extend(_unknown_warning(prog, tp, work, p))
    if p.reduced.any():
        op = work.ops[p.op]
        out.append(f"{prog.path}: {op.name}: {int(p.reduced.sum())} blocks off the cutting "
                   f"feed {p.cutting_feed_mm_min:g} mm/min or in the air (plunges, ramps, "
                   "lead-ins, links) keep the program's feed per tooth: F scaled with S")
    return out


def _below_min_rpm(prog: Program, idx: BlockIndex, work: Work, p: OpPlan,
                   machine: Machine) -> list[str]:
    """Cutting blocks that need a lower S than the machine's lowest (--min-rpm): vc runs
    above its target there, and the rewrite says where and by how much."""
    c = p.blocks.cutting & p.blocks.planned
    need = p.blocks.req_rpm
    low = np.flatnonzero(c & (need < machine.min_rpm))
    if low.size == 0 or not machine.min_rpm > 0:
        return []
    worst = 100.0 * (machine.min_rpm / float(np.min(need[low])) - 1.0)
    lines = np.unique(idx.line[p.window[0] + low])
    return [f"{prog.path}:{int(lines[0]) + 1}: {work.ops[p.op].name} (T{p.tool}): "
            f"{low.size} cutting block{'s' if low.size > 1 else ''} (lines "
            f"{line_ranges(lines)}) need less than the machine's lowest speed "
            f"{machine.min_rpm:g} RPM: vc up to {worst:+.1f} % above its target there (lower "
            "--min-rpm if the spindle can turn slower)"]


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
