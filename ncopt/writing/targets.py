"""The S and F the output puts in force, per block: the plans' where they own a block,
the program's own elsewhere and at every fixed line that does not move (a canned cycle,
a call), and the words' style and resolution.  What :func:`ncopt.writing.edits.plan_edits`
writes, and what the verification and the summary's times read back."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ncopt.model import MM_PER_INCH, Machine, Motion, Program, Toolpath
from ncopt.motion.feedmode import inverse_time_words
from ncopt.motion.times import feed_minutes
from ncopt.planning.plans import Work
from ncopt.planning.regions import Scope
from ncopt.planning.schedule import BlockIndex
from ncopt.writing.edits import F_CODE, S_CODE, Targets, WordStyle, detect_style


def word_styles(prog: Program, tp: Toolpath, idx: BlockIndex) -> tuple[WordStyle, WordStyle, float]:
    """How the program writes its S and F words, and the resolution of its F words in
    mm/min (the planner's feed quantum): inch/min F gets two decimals at least, and a
    G93 word's resolution is that of its longest block."""
    s_style = detect_style(prog, S_CODE)
    f_style = detect_style(prog, F_CODE, default_decimals=1)
    inch = tp.line_inch is not None and bool(tp.line_inch.any())
    if inch and f_style.decimals < 2:
        f_style = replace(f_style, decimals=2, trailing_point=False)  # inch/min needs them
    quantum = 10.0 ** -f_style.decimals * (MM_PER_INCH if inch else 1.0)
    return s_style, f_style, max(quantum, _inverse_time_quantum(tp, idx, f_style))


def block_targets(tp: Toolpath, idx: BlockIndex, work: Work, f_style: WordStyle) -> Targets:
    """S and F to be in force per block: planned where an operation's plan owns the
    block, else the program's own; and the program's own at every fixed line that does
    not move (a canned cycle, a call), so that it is in force there too.

    A G93 block's F is 1 / minutes: the planned tip feed over its length
    (``ncopt.motion.feedmode``).  A rotary-only block (no length) keeps its F."""
    fp = idx.first_point
    ls = tp.lines
    inch = tp.line_inch[idx.line] if tp.line_inch is not None else np.zeros(fp.shape, bool)
    unit = np.where(inch, MM_PER_INCH, 1.0)
    feed_move = tp.motion[fp] != Motion.RAPID
    s_value = tp.spindle_rpm[fp].astype(np.float64)
    f_value = np.where(feed_move, tp.feed_mm_min[fp] / unit, np.nan)
    s_value[~(s_value > 0) | ~ls.s_known[idx.line]] = np.nan  # never write S0
    f_value[~ls.f_known[idx.line]] = np.nan
    scale = 10.0 ** f_style.decimals
    g93, length = _inverse_time_blocks(tp, idx)
    if g93 is not None:
        f_value = np.where(g93 & ls.f_known[idx.line],
                           inverse_time_words(tp.feed_mm_min[fp], length), f_value)
    for p in work.plans:
        lo, hi = p.window
        planned = p.blocks.planned
        s_value[lo:hi] = np.where(planned, p.s_cmd_rpm, s_value[lo:hi])
        word = p.f_mm_min / unit[lo:hi]
        if g93 is not None:
            word = np.where(g93[lo:hi], inverse_time_words(p.f_mm_min, length[lo:hi]), word)
        # never above fz; a value a rounding error short of a written one is that one
        planned_f = np.floor(word * scale + 1e-6) / scale
        # the program's own F, kept by the plan, stays as it is written (F333.33 with F
        # words of the post's usual F1000. style)
        own = f_value[lo:hi]
        planned_f = np.where(np.abs(word - own) <= 1e-9 * np.abs(own), own, planned_f)
        moves = p.blocks.length_mm > 0  # a rotary-only block keeps its F
        f_value[lo:hi] = np.where(np.isfinite(p.f_mm_min) & moves, planned_f, f_value[lo:hi])
    f_value[~(f_value > 0)] = np.nan  # never F0 or below (controls reject it)
    return Targets(line=idx.line, s_value=s_value, f_value=f_value)


def _inverse_time_blocks(tp: Toolpath, idx: BlockIndex) -> tuple:
    """(nb,) bool: the block is in G93, and (nb,) its length in mm; (None, None) if none is."""
    if tp.inverse_time is None:
        return None, None
    fp = idx.first_point
    return tp.inverse_time[fp], np.add.reduceat(tp.seg_len_mm[1:], fp - 1)


def _inverse_time_quantum(tp: Toolpath, idx: BlockIndex, f_style: WordStyle) -> float:
    """The feed resolution (mm/min) of the G93 words: the word's own resolution times the
    longest G93 feed block (0 when there is none)."""
    g93, length = _inverse_time_blocks(tp, idx)
    if g93 is None or not np.any(g93 & tp.known[idx.first_point]):
        return 0.0
    return 10.0 ** -f_style.decimals * float(np.max(length[g93 & tp.known[idx.first_point]]))


def with_fixed_lines(tp: Toolpath, idx: BlockIndex, scope: Scope, targets: Targets) -> Targets:
    """The block targets and the fixed lines that do not move (canned cycles, calls):
    consumers of the program's own S and F, which must be in force there too."""
    ls = tp.lines
    extra = np.flatnonzero(scope.fixed)
    extra = extra[~np.isin(extra, idx.line)]
    if extra.size == 0:
        return targets
    # a call uses what is in force when it starts: known unless lost before its line
    prev = np.maximum(extra - 1, 0)
    s_known = np.where(ls.call[extra], ls.s_known[prev] | (extra == 0), ls.s_known[extra])
    f_known = np.where(ls.call[extra], ls.f_known[prev] | (extra == 0), ls.f_known[extra])
    s_x = np.where(s_known & (ls.s_rpm[extra] > 0), ls.s_rpm[extra], np.nan)
    f_x = np.where(f_known & (ls.f_prog[extra] > 0), ls.f_prog[extra], np.nan)
    line = np.concatenate((targets.line, extra))
    order = np.argsort(line, kind="stable")
    return Targets(line[order], np.concatenate((targets.s_value, s_x))[order],
                   np.concatenate((targets.f_value, f_x))[order])


def feed_after(tp: Toolpath, idx: BlockIndex, targets: Targets) -> np.ndarray:
    """(n,) F in force per point after the rewrite, mm/min (from the targets)."""
    on_block = np.isin(targets.line, idx.line)
    f_block = targets.f_value[on_block]  # program units, the blocks' order
    unit = np.where(tp.line_inch[idx.line], MM_PER_INCH, 1.0) if tp.line_inch is not None else 1.0
    g93, length = _inverse_time_blocks(tp, idx)
    if g93 is not None:  # a G93 word is 1 / minutes: the tip feed is the word x the length
        unit = np.where(g93, length, unit)
    f_block = f_block * unit
    out = tp.feed_mm_min.copy()
    counts = np.diff(np.concatenate((idx.first_point, [tp.n])))
    per_point = np.repeat(f_block, counts)
    ok = np.isfinite(per_point)
    sl = slice(int(idx.first_point[0]), tp.n) if idx.first_point.size else slice(0, 0)
    out[sl] = np.where(ok, per_point, out[sl])
    return out


def cut_minutes(tp: Toolpath, idx: BlockIndex, targets: Targets,
                machine: Machine) -> tuple[np.ndarray, np.ndarray]:
    """Minutes of every move before and after the rewrite (:mod:`ncopt.motion.times`), for the
    stamp and the summary alike."""
    cap = machine.max_feed_mm_min
    return feed_minutes(tp, None, cap), feed_minutes(tp, feed_after(tp, idx, targets), cap)


def rapid_lines(tp: Toolpath, n_lines: int) -> np.ndarray:
    """(n_lines,) bool: the lines that move at the rapid rate (G0): their F words are the
    program's, never rewritten."""
    out = np.zeros(n_lines, dtype=bool)
    rapid = tp.line[(tp.motion == Motion.RAPID) & (tp.line >= 0)]
    out[rapid] = True
    return out
