"""What the program itself means: each operation's cutting feed and its own S, the
blocks it runs off that feed, and the cutting data it was written for (vc, fz at its
nominal diameter), or why those cannot be what the programmer meant.

For an ncopt output, whose S and F words ncopt wrote, the stamp says what the program
meant (its S0 and F0); the blocks off the cutting feed are then those whose F is not the
one ncopt writes for the stamped fz, so a second rewrite plans the same.
"""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

import numpy as np

from ncopt.model import Cutter, CuttingData, Toolpath
from ncopt.motion.modal import row_norms
from ncopt.planning import schedule
from ncopt.planning.medians import weighted_median
from ncopt.runtime.errors import PlanningError

FEED_MATCH = 1e-3  # mm/min: a block at the cutting feed
# G93: a block's tip feed is its F word (1 / minutes) times its length, both rounded in
# the program: within this share of the cutting feed it is that feed
FEED_MATCH_G93 = 1e-3
# a feed move within 26 deg of the axis (up or down: plunges, retracts, wall descents) does
# not say what the operation's cutting feed is, however long such moves are together
VERTICAL = 0.9

class Intent(NamedTuple):
    """An operation as an ncopt stamp records it (the program is an ncopt output).

    s0_rpm, f0_mm_min : its own S and cutting feed before ncopt;  spindle : (accel
    rad/s^2, max RPM) its S and F were planned for, None: not said;  s0_varies : the
    program's own S was not one value over the operation (the stamp's ``S0~``)
    """

    s0_rpm: float
    f0_mm_min: float
    spindle: tuple[float, float] | None
    s0_varies: bool


def feed_intent(blocks, feed, s_prog, mine, machine, cut, cutter, opts, intent: Intent | None,
                match=FEED_MATCH, inverse_time: np.ndarray | None = None):
    """Which blocks of the operation run at another feed than its cutting feed (read
    from its ``mine`` blocks: plunges and retracts aside).  ``inverse_time``: per block,
    whether it runs in G93 (None: no G93 in the program).

    Returns (s_ref, off_feed, F0, S0): per block the spindle speed the program's F
    refers to, and whether the block is off the cutting feed; the cutting feed F0
    (mm/min) and the operation's own S0 (RPM).  A block off the feed then gets
    ``F * S_low / s_ref``: the feed per tooth the program gives it, never more.

    For an ncopt output (``intent``: S0 and F0 from its stamp) ``s_ref`` is the lowest
    speed its own S words give the spindle in the block, and a cutting block was at the
    cutting feed where its F is the one ncopt writes for the stamped fz at those speeds:
    so a second rewrite gives the same F."""
    if intent is None:
        f0 = cutting_feed(feed, blocks.length_mm, mine, not np.isscalar(match))
        s0 = (weighted_median(s_prog[mine], blocks.length_mm[mine], unweighted_middle=True)
              if mine.any() else 0.0)
        return s_prog, np.abs(feed - f0) > match, f0, s0
    s0, f0, spindle = intent.s0_rpm, intent.f0_mm_min, intent.spindle
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
    # a cut at the stamped F0 itself is one ncopt kept as programmed (its F words too
    # coarse for the band there): on the cutting feed, as it was the first time.  A G93
    # block's feed is its length over its time word: one near F0 by chance (within the
    # resolution of the longest block's word) was kept only where its S is the program's
    # own S0 too (impeller-7bl-xyzac.ngc: F476 S1886 read as kept, F1456 on a second run)
    at_f0 = np.abs(feed - f0) <= 1.5 * q
    if inverse_time is not None:
        at_f0 &= ~inverse_time | (np.abs(s_prog - s0) <= 0.5)
    off = np.where(blocks.cutting, (np.abs(feed - expected) > 1.5 * q) & ~at_f0, ~at_f0)
    return s_ref, off, f0, s0


def cutting_feed(feed: np.ndarray, length: np.ndarray, mine: np.ndarray,
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
        return weighted_median(f[pick], length[mine][pick], unweighted_middle=True)
    values, inv = np.unique(f, return_inverse=True)
    w = np.bincount(inv.ravel(), weights=length[mine], minlength=values.size)
    return float(values[int(np.argmax(w))])


def nominal_cutting_data(tp: Toolpath, points: np.ndarray, cutter: Cutter,
                         path: str) -> CuttingData:
    """vc and fz the program itself runs at its nominal diameter (what the CAM intended):
    its S (length-weighted median) and its cutting feed over ``points``, plunges,
    retracts and other near-vertical moves aside (as :func:`ncopt.planning.opplan.plan_operation` reads the
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
    s = weighted_median(tp.spindle_rpm[idx], weight, unweighted_middle=True)
    f = cutting_feed(tp.feed_mm_min[idx], weight, np.ones(idx.size, dtype=bool),
                      tp.inverse_time is not None)
    vc = np.pi * cutter.diameter_mm * s / 1000.0
    return CuttingData(vc_m_min=vc, fz_mm=f / (cutter.teeth * s))



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
