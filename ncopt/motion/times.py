"""How long a program's moves take: one definition for every command.

``inspect``, ``rewrite``, ``batch`` and ``simulate`` all report the *cutting time* as
the time of every feed move (G1, G2, G3) whose start and end the interpreter knows, at
its programmed F (capped at the machine's highest feed when one is known).  Moves from an
unknown position (after G28, a subprogram call...) and per-revolution feeds (G95) are not
timed; the count of such moves is reported instead.  An inverse-time (G93) move is
timed by the tip feed its F stands for (``ncopt.motion.feedmode``): its block lasts 1 / F
minutes, a rotary-only one too.
"""

from __future__ import annotations

import numpy as np

from ncopt.model import Motion, Toolpath

FEED_MOTIONS = (Motion.LINEAR, Motion.ARC_CW, Motion.ARC_CCW)


def feed_minutes(tp: Toolpath, feed_mm_min: np.ndarray | None = None,
                 max_feed_mm_min: float = float("inf")) -> np.ndarray:
    """(n,) minutes of each timed feed move (0 elsewhere).

    ``feed_mm_min``: (n,) the F in force per point (default: the program's own).
    """
    f = tp.feed_mm_min if feed_mm_min is None else feed_mm_min
    f = np.minimum(f, max_feed_mm_min)
    timed = np.isin(tp.motion, FEED_MOTIONS) & tp.known & (f > 0)
    timed[0] = False
    out = np.zeros(tp.n)
    out[timed] = tp.seg_len_mm[timed] / f[timed]
    if tp.inverse_time is not None:  # a rotary-only G93 block: F is its own word
        turn = timed & tp.inverse_time & (tp.seg_len_mm == 0)
        out[turn] = 1.0 / f[turn]
    return out


def untimed_moves(tp: Toolpath) -> int:
    """Feed moves the cutting time leaves out (position, G93/G95 or F not known)."""
    feed = np.isin(tp.motion, FEED_MOTIONS)
    feed[0] = False
    bad = feed & ~(tp.known & (tp.feed_mm_min > 0))
    return int(np.unique(tp.line[bad]).size)
