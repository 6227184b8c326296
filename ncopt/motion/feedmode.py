"""Inverse-time feed (G93): what a block's F stands for, both ways.

In G93 (RS-274, LinuxCNC, Fanuc; the 5-axis demos of LinuxCNC use it) the F
word of a block is ``1 / minutes`` of that block: the tip moves its path
length L in ``1 / F`` minutes, so it runs at ``F L`` mm/min.  ncopt plans that
tip feed like a G94 feed (fz = F_tip / (z S)) and writes back the same factor
on the block's own word: ``F_new = F_old x F_tip_new / F_tip_old = F_tip_new / L``.
F in G93 has no unit of length, so inch programs need no conversion.  Every
G93 feed block carries its own F: the controls refuse one without, and so does
ncopt, at its line (``ncopt.reading.refuse.check_inverse_time_feeds``); a block
whose F ncopt still cannot read is not planned.  A rotary-only move (L = 0)
keeps its F, in G93 as in G94 (there F is degrees per minute); having no tip
feed, a G93 one carries its F word itself where the toolpath holds feeds.
"""

from __future__ import annotations

import numpy as np

G93, G94, G95 = 930, 940, 950


def tip_feed_mm_min(feed_mode: np.ndarray, f_word: np.ndarray, feed_mm_min: np.ndarray,
                    length_mm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The tip feed of each move and whether it can be planned.

    Parameters
    ----------
    feed_mode : (m,) the feed mode of each move (G code x10)
    f_word : (m,) the F word on the move's own line (NaN where none)
    feed_mm_min : (m,) the feed in force read as mm/min (what G94 means)
    length_mm : (m,) tip path length of each move (a whole arc)

    Returns
    -------
    (m,) float64 mm/min (the F word of a rotary-only G93 move), (m,) bool (False: a
    G93 move without its own F)
    """
    inverse = feed_mode == G93
    if not inverse.any():
        return feed_mm_min, np.ones(feed_mode.shape, dtype=bool)
    feed = np.where(inverse, np.where(length_mm > 0, f_word * length_mm, f_word), feed_mm_min)
    return feed, ~inverse | ~np.isnan(f_word)


def inverse_time_words(f_tip_mm_min: np.ndarray, length_mm: np.ndarray) -> np.ndarray:
    """G93 F words (1 / minutes) that give blocks of ``length_mm`` the tip feeds given
    (a block of no length: the value given, its own word)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(length_mm > 0, f_tip_mm_min / length_mm, f_tip_mm_min)
