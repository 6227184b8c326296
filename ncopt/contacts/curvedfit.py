"""The cross-slope of a mesh-free normal with the surface's curvature fitted too (5 axes).

:func:`ncopt.contacts.pathnormals.path_normals` fits the normal to the other passes'
neighbours as a straight line across the pass.  On a curved surface each neighbour lies
``kappa a^2 / 2`` off that line (``a`` its distance across), which cancels only where the
neighbours sit symmetrically on both sides; the k nearest often do not (on 2 mm blocks 0.8
mm apart the twelfth neighbour is one of four at the same distance; beside the last pass
one side has one pass, the other several), and the normal then leans by up to
``kappa a / 2`` across the pass: 0.6-0.9 deg on the R60 bowl of bench/make_5axis.py, and
where the tool is tilted 15-35 deg from the normal R_eff moves 1.5-4 % with it.  The
neighbours are taken as many on each side (``path_normals(balanced=True)``), and their
heights over the fitted plane are fitted again as

    b = p a + q a^2 + r a c + t c^2        (a across, c along the pass)

by weighted least squares (the same weights, 1 / distance^2), and the normal is turned
by the slope p.  Only where neighbours lie on both sides (the confident fits); elsewhere,
or where the fit has too few neighbours or turns the normal by more than
:data:`MAX_TURN`, the straight fit stands.
"""

from __future__ import annotations

import numpy as np

# the fit needs this many neighbours on other passes (it has four unknowns)
MIN_NEIGHBOURS = 5
# a curved fit that turns the straight one by more than this slope (tan, 1 deg) is not
# taken: the neighbours do not describe one smooth quadric there.  Across a change of
# curvature (the rim of samples/bowl.mpf, where the ball rolls from the land into the
# bowl) the quadric turned the normal 8-10 deg the wrong way; the biases it removes are a
# fraction of a degree (at most 0.9 deg on the flowline bowl's passes next to the edge)
MAX_TURN = 0.0175
# relative ridge on the normal equations' diagonal: a direction the neighbours do not
# span (all at c = 0) keeps a zero coefficient instead of a singular system
RIDGE = 1e-8


def curved_normals(pts: np.ndarray, tangent: np.ndarray, all_pts: np.ndarray,
                   nb: np.ndarray, dist: np.ndarray, other: np.ndarray, normal: np.ndarray,
                   rows: np.ndarray) -> np.ndarray:
    """(m, 3) ``normal`` refitted with curvature on ``rows`` (m,) bool.

    pts, tangent, normal : (m, 3) points, their unit tangents and straight-fit normals
    all_pts : (M, 3) every fitted point;  nb, dist, other : (m, k) neighbours' indices
    into all_pts, distances, and whether each is on another pass
    """
    out = normal.copy()
    sel = np.flatnonzero(rows)
    if sel.size == 0:
        return out
    t, n0 = tangent[sel], normal[sel]
    u = np.cross(n0, t)
    u /= np.maximum(np.linalg.norm(u, axis=1), 1e-12)[:, None]
    off = np.take(all_pts, nb[sel], axis=0)
    off -= pts[sel][:, None, :]
    a = np.einsum("qkj,qj->qk", off, u)
    b = np.einsum("qkj,qj->qk", off, n0)
    c = np.einsum("qkj,qj->qk", off, t)
    del off
    w = other[sel] / np.maximum(dist[sel], 1e-9) ** 2
    x = np.stack((a, a * a, a * c, c * c), axis=-1)
    lhs = np.einsum("qk,qki,qkj->qij", w, x, x)
    rhs = np.einsum("qk,qki,qk->qi", w, x, b)
    i = np.arange(4)
    lhs[:, i, i] *= 1.0 + RIDGE
    lhs[:, i, i] += 1e-300
    slope = np.linalg.solve(lhs, rhs[..., None])[:, 0, 0]
    ok = (other[sel].sum(axis=1) >= MIN_NEIGHBOURS) & np.isfinite(slope) \
        & (np.abs(slope) <= MAX_TURN)
    turned = n0 - slope[:, None] * u
    turned /= np.linalg.norm(turned, axis=1)[:, None]
    out[sel[ok]] = turned[ok]
    return out
