"""The length-weighted median: the feed, the speed or the step most of a cut runs at."""

from __future__ import annotations

import numpy as np


def weighted_median(values: np.ndarray, weight: np.ndarray, *, unweighted_middle: bool = False,
                    in_order: bool = True) -> float:
    """The value at which the running sum of ``weight`` (say each move's length, mm), over
    ``values`` in ascending order, first reaches half its total.  NaN for no values.

    ``unweighted_middle``: where the weights add up to 0 (every move a point), the middle
    value by count (the operation's own S and feed are still wanted); else NaN (no step,
    no typical feed).  ``in_order``: equal values are summed in their given order (a
    stable sort); False: in the order numpy's default sort leaves them.  The order of a
    sum can round it either way where half the weight falls exactly at the end of a run
    of equal values: each caller keeps the order it was written with, so that no output
    changes."""
    if values.size == 0:
        return float("nan")
    order = np.argsort(values, kind="stable") if in_order else np.argsort(values)
    cum = np.cumsum(weight[order])
    if cum[-1] <= 0:
        return float(values[order][len(values) // 2]) if unweighted_middle else float("nan")
    return float(values[order][np.searchsorted(cum, 0.5 * cum[-1])])
