"""The replay's table of moves: per move (toolpath points 1..n-1), how long it is, how
long it takes at the machine's real feed, when it starts, the spindle speed it heads for
and whether the spindle starts there (the control then waits for speed).

F is constant over a block (capped at ``Machine.max_feed_mm_min``); rapids run at
``Machine.rapid_mm_min``; a move from an unknown position takes no time.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ncopt.model import Job, Motion, Program, Toolpath
from ncopt.motion.linestate import spindle_starts_through

__all__ = ["FEED_MOTIONS", "Moves", "feed_tools", "move_table"]

FEED_MOTIONS = (Motion.LINEAR, Motion.ARC_CW, Motion.ARC_CCW)


@dataclass(frozen=True)
class Moves:
    """Per move (toolpath points 1..n-1), (nm,) arrays."""

    line: np.ndarray  # 1-based source line
    length_mm: np.ndarray  # 0 for moves from an unknown position
    dt_s: np.ndarray
    t0_s: np.ndarray  # start time
    d0_mm: np.ndarray  # start distance
    speed_mm_min: np.ndarray  # real F (rapid rate for rapids; NaN when unknown)
    target_rpm: np.ndarray  # speed the spindle heads for (0 when off)
    start: np.ndarray  # the spindle starts at this move: the control waits for speed
    rapid: np.ndarray
    feed: np.ndarray
    known: np.ndarray
    candidate: np.ndarray  # known feed move of the evaluated tool


def move_table(prog: Program, tp: Toolpath, job: Job, tool_mask: np.ndarray) -> Moves:
    """The moves of ``tp`` on ``job.machine``; ``tool_mask``: (nm,) the moves of the tool
    evaluated (its known feed moves are the candidates for a cut)."""
    m = job.machine
    motion, known = tp.motion[1:], tp.known[1:]
    rapid = motion == Motion.RAPID
    feed = np.isin(motion, FEED_MOTIONS)
    speed = np.where(rapid, m.rapid_mm_min, np.minimum(tp.feed_mm_min[1:], m.max_feed_mm_min))
    speed = np.where(known & (rapid | feed), speed, np.nan)
    length = np.where(known, tp.seg_len_mm[1:], 0.0)
    ok = np.isfinite(speed) & (speed > 0)
    dt = np.where(ok, 60.0 * length / np.where(ok, speed, 1.0), 0.0)
    on = tp.spindle_on[1:] if tp.spindle_on is not None else tp.spindle_rpm[1:] > 0
    s = tp.spindle_rpm[1:]
    target = np.where(on & (s > 0), np.clip(s, m.min_rpm, m.max_rpm), 0.0)
    start = on & _spindle_starts(prog, tp)
    candidate = feed & known & tool_mask
    return Moves(line=tp.line[1:].astype(np.int64) + 1, length_mm=length, dt_s=dt,
                 t0_s=_starts(dt), d0_mm=_starts(length), speed_mm_min=speed,
                 target_rpm=target, start=start, rapid=rapid, feed=feed, known=known,
                 candidate=candidate)


def _spindle_starts(prog: Program, tp: Toolpath) -> np.ndarray:
    """(nm,) bool: an M3/M4 starts the stopped spindle at or before this move (since the last)."""
    starts = spindle_starts_through(prog)
    move_line = tp.line.astype(np.int64)  # point 0 has line -1: count from the top
    return starts[move_line[1:] + 1] > starts[move_line[:-1] + 1]


def _starts(x: np.ndarray) -> np.ndarray:
    """Running total before each element (start times or distances), 0 first."""
    return np.concatenate(([0.0], np.cumsum(x)[:-1])) if x.size else x.copy()


def feed_tools(tp: Toolpath) -> list[int]:
    """The T numbers of the program's known feed moves, in ascending order."""
    feed = np.isin(tp.motion[1:], FEED_MOTIONS) & tp.known[1:]
    return np.unique(tp.tool[1:][feed]).tolist()
