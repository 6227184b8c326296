"""Number texts -> float values, vectorised: the numbers of the parser's fast path.

A number is ``[sign] digits [. digits]`` (the grammar's SNUMBER as the fast path reads
it).  Up to 15 digits they are read by integer arithmetic on the digits, exactly as
``float()`` reads them; longer ones through numpy's string conversion.
"""

from __future__ import annotations

import numpy as np

__all__ = ["MAX_NUMBER_CHARS", "EXACT_DIGITS", "run_sums", "number_values", "parse_numbers"]

MAX_NUMBER_CHARS = 32  # a longer number is left to Lark


def run_sums(upto, values, run_at, run_last):
    """Sum of ``values`` over each run, from their running sum ``upto`` (which may wrap
    around: the difference of two int64 sums is exact while the run's own sum fits)."""
    return upto[run_last] - upto[run_at] + values[run_at]


# Up to 15 digits the digits read as an integer are exact in a float64 (< 2**53), and
# so is 10**k for every k <= 15: their quotient, one IEEE division, is the correctly
# rounded value of the text, which is what float() gives (Clinger's fast path).
EXACT_DIGITS = 15
_POW10_INT = 10 ** np.arange(EXACT_DIGITS + 1, dtype=np.int64)
_POW10 = 10.0 ** np.arange(MAX_NUMBER_CHARS + 1)


def number_values(chars, is_digit, digits_upto, run_at, run_last, point_at, point_run):
    """Float values of the number runs (``[sign] digits [. digits]``, consecutive in
    ``chars`` from ``run_at`` to ``run_last``, one after the other, covering ``chars``),
    exact for runs of up to 15 digits (the caller reads longer ones otherwise).
    ``digits_upto``: running count of digits; ``point_at``: where the points are,
    ``point_run``: in which run."""
    if run_at.size == 0:
        return np.zeros(0, dtype=np.float64)
    # per character: the digits after it in its run (a digit's power of ten; at the
    # point, the number of decimals)
    after = np.repeat(digits_upto[run_last], run_last + 1 - run_at)
    after -= digits_upto
    np.minimum(after, EXACT_DIGITS, out=after)
    term = np.take(_POW10_INT, after)  # take: half the time of _POW10_INT[after]
    term *= (chars - ord("0")) * is_digit  # 0 at the sign and the point
    # the runs are consecutive and cover ``chars``: one sum per run, each < 10**16
    mantissa = np.add.reduceat(term, run_at)
    decimals = np.zeros(run_at.size, dtype=np.int64)
    decimals[point_run] = after[point_at]
    values = mantissa / _POW10[decimals]
    np.negative(values, out=values, where=chars[run_at] == ord("-"))
    return values


def parse_numbers(raw, start, length) -> np.ndarray:
    """Float values of number texts ``raw[start:start+length]`` (vectorised)."""
    if start.shape[0] == 0:
        return np.zeros(0, dtype=np.float64)
    width = int(length.max())
    cols = np.arange(width)
    pos = start[:, None] + cols[None, :]
    chars = np.where(cols[None, :] < length[:, None], raw[np.minimum(pos, raw.shape[0] - 1)], 32)
    return chars.astype(np.uint8).view(f"S{width}").ravel().astype(np.float64)
