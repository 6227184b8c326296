"""``math.hypot`` of many pairs at once, bit for bit, in numpy.

The arcs' radii and lengths are Python's ``math.hypot`` of each pair (the one-arc
reference, :func:`ncopt.motion.arcs.arc_points`, takes them so).  That is not the C
library's ``hypot`` (``np.hypot``, which differs in the last bit now and then): it is
CPython's ``vector_norm``, made of exact steps, which numpy's elementwise IEEE arithmetic
repeats to the bit: scaling by a power of two, exact squares (Dekker's split and
product), compensated sums, a square root and its differential correction.  Pairs the
steps could round otherwise (an infinity, a NaN, a subnormal largest value, or a part so
much smaller than the other that its square's low half would underflow) are given to
``math.hypot`` itself: none in a real program.
"""

from __future__ import annotations

import math

import numpy as np

_VELTKAMP = 134217729.0  # 2**27 + 1: splits a double into two 26-bit halves (Dekker)
_TINY_SCALED = 2.0 ** -450  # a scaled part below this: its square's low half may underflow
_SMALLEST_NORMAL = 2.0 ** -1022


def _square(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(hi, lo), hi + lo = x * x exactly: Dekker's mul12 of x by itself (CPython's dl_mul
    of (x, x), term for term; hi * lo + lo * hi is one product doubled, exactly)."""
    t = x * _VELTKAMP
    hi = t - x
    np.subtract(t, hi, out=hi)  # t - (t - x)
    lo = np.subtract(x, hi, out=t)
    p = hi * hi
    q = np.multiply(hi, lo, out=hi)
    q += q
    z = p + q
    zz = np.subtract(p, z, out=p)
    zz += q
    lo *= lo
    zz += lo
    return z, zz


def _norms(ax: np.ndarray, ay: np.ndarray, top: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """vector_norm of (ax[i], ay[i]) (absolute values, finite, the larger one ``top``
    normal), and the power of two each pair was scaled by."""
    _, exponent = np.frexp(top)
    np.negative(exponent, out=exponent)
    scale = np.ldexp(1.0, exponent)
    # the first part: csum = 1.0 + hi, frac1 = 0.0 + lo, frac2 = 0.0 + (1.0 - csum) + hi
    hi, frac1 = _square(ax * scale)
    csum = hi + 1.0
    frac2 = 1.0 - csum
    frac2 += hi
    # the second part
    hi, lo = _square(ay * scale)
    frac1 += lo
    total = csum + hi
    np.subtract(csum, total, out=csum)  # csum - total, then + hi: the sum's low part
    csum += hi
    frac2 += csum
    csum = total
    # h = sqrt(csum - 1.0 + (frac1 + frac2))
    h = csum - 1.0
    h += frac1 + frac2
    np.sqrt(h, out=h)
    # dl_mul(-h, h) is the negated square of h: its parts subtracted
    hi, lo = _square(h)
    total = csum - hi
    np.subtract(csum, total, out=csum)
    csum -= hi
    frac2 += csum
    frac1 -= lo
    # x = total - 1.0 + (frac1 + frac2); h += x / (2.0 * h); h / scale
    total -= 1.0
    frac1 += frac2
    total += frac1
    twice = h + h
    total /= twice
    h += total
    h /= scale
    return h, scale


def hypot(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``math.hypot(x[i], y[i])`` for every i (float64 arrays of one shape), the same bits.

    Where every ``y`` is 0 it is ``|x|``: vector_norm's exact sum of squares is then
    x * x, whose square root it corrects to |x| itself (checked on 40M values)."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    ax, ay = np.abs(x), np.abs(y)
    if not ay.any():
        return ax
    top = np.maximum(ax, ay)
    low = np.minimum(ax, ay)
    with np.errstate(all="ignore"):  # the pairs that would raise go to math.hypot below
        out, scale = _norms(ax, ay, top)
        odd = ~(top < math.inf) | ~(low == low) | ((top < _SMALLEST_NORMAL) & (top > 0.0))
        odd |= (low > 0.0) & (low * scale < _TINY_SCALED)
    out[top == 0.0] = 0.0
    for i in np.flatnonzero(odd).tolist():
        out[i] = math.hypot(float(x.flat[i]), float(y.flat[i]))
    return out
