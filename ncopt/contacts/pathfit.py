"""The cross fit of :func:`ncopt.contacts.pathnormals.path_normals`, on neighbours stored
rank by rank.

The k-d tree gives each point's ``k`` neighbours as a row, (m, k).  Here they are taken
as (k, m) arrays (row ``j``: every point's ``j``-th nearest neighbour), and the points and
neighbours as their three coordinates, (m,) and (k, m) arrays: every step is then an
operation on contiguous rows of ``m`` values.  The sums over the neighbours that numpy's
``sum(axis=1)`` and the projections that ``einsum("mkj,mj->mk")`` computed row by row are
written out in the order those calls add (:func:`rank_sums`, :func:`_project`), so the
normals have the same bits as before, in half the time (0.37 against 0.73 s for 1M points
and 12 neighbours).
"""

from __future__ import annotations

import numpy as np

from ncopt.motion.modal import row_norms

OTHER_PASS_RATIO = 3.0  # path distance > ratio * straight distance: another pass
CONFIDENT, ONE_SIDED, NO_CROSS = 2, 1, 0
# numpy adds up to this many values a row pairwise in eight running sums
_PAIRWISE_BLOCK = 128


def by_rank(a: np.ndarray) -> np.ndarray:
    """(k, m) contiguous copy of the (m, k) neighbour array ``a``."""
    return np.ascontiguousarray(a.T)


def other_pass(s: np.ndarray, a: int, nb: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """(k, m) bool: neighbour ``nb`` of point ``a + column`` lies on another pass (much
    farther along the path, ``s``, than in a straight line, ``dist``); all (k, m)."""
    along = np.take(s, nb)
    along -= s[a:a + nb.shape[1]]
    np.abs(along, out=along)
    limit = dist * OTHER_PASS_RATIO
    limit += 1e-9
    return np.greater(along, limit, out=np.empty(nb.shape, bool))


def rank_sums(t: np.ndarray) -> np.ndarray:
    """(m,) sum over the rows of ``t`` (k, m): the bits of ``t.T.sum(axis=1)`` on the
    (m, k) C-contiguous transpose.  numpy adds each row of up to 128 values from 0.0:
    fewer than 8 one after the other, else in 8 running sums (values ``j``, ``j + 8``,
    ...) combined pairwise, then the rest one by one.  The final ``+ 0.0`` is that
    start: it turns a sum of negative zeros into +0.0 and changes nothing else."""
    k = t.shape[0]
    if k == 0 or k > _PAIRWISE_BLOCK:
        return np.ascontiguousarray(t.T).sum(axis=1)
    if k < 8:
        res = t[0].copy()
        for j in range(1, k):
            res += t[j]
        res += 0.0
        return res
    r = [t[j].copy() for j in range(8)]
    done = k - k % 8
    for i in range(8, done, 8):
        for j in range(8):
            r[j] += t[i + j]
    res = r[0] + r[1]
    res += r[2] + r[3]
    right = r[4] + r[5]
    right += r[6] + r[7]
    res += right
    for j in range(done, k):
        res += t[j]
    res += 0.0
    return res


def _project(ox: np.ndarray, oy: np.ndarray, oz: np.ndarray, u: np.ndarray) -> np.ndarray:
    """(k, m) offsets dotted with the per-point (3, m) ``u``: ``(x ux + z uz) + y uy``,
    the order of ``einsum("mkj,mj->mk")`` (numpy 2.4, x86-64).  That einsum starts from
    +0.0, which only turns an all-negative-zero result positive; the results feed only
    sign tests and :func:`rank_sums` of products, where the sign of a zero is lost."""
    p = ox * u[0]
    t = oz * u[2]
    p += t
    np.multiply(oy, u[1], out=t)
    p += t
    return p


def _up(v: np.ndarray, axis: np.ndarray | None) -> np.ndarray:
    """(m,) component of each row along the tool axis (+Z when None)."""
    return v[:, 2] if axis is None else np.einsum("ij,ij->i", v, axis)


def across(axis: np.ndarray) -> np.ndarray:
    """(m, 3) unit vectors perpendicular to each tool axis (+X for +Z)."""
    u = np.cross([0.0, 1.0, 0.0], axis)
    small = row_norms(u) < 0.5
    u[small] = np.cross(axis[small], [1.0, 0.0, 0.0])
    return u / row_norms(u)[:, None]


def _flip_down(v: np.ndarray, axis: np.ndarray | None) -> None:
    """Rows of ``v`` (m, 3) pointing away from the tool axis multiplied by -1, in place."""
    np.multiply(v, -1.0, out=v, where=(_up(v, axis) < 0)[:, None])


def frame(tangent: np.ndarray, axis: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """(m, 3) unit ``u`` across the pass (horizontal) and ``v`` perpendicular to the
    tangent in its vertical plane, toward the tool (row by row: the same bits for a
    whole path as chunk by chunk)."""
    up = np.array([0.0, 0.0, 1.0]) if axis is None else axis
    u = np.cross(tangent, up)  # horizontal, across the pass
    vertical = row_norms(u) < 1e-6  # a plunge: any horizontal direction will do
    u[vertical] = [1.0, 0.0, 0.0] if axis is None else across(axis[vertical])
    u /= np.maximum(row_norms(u), 1e-12)[:, None]
    v = np.cross(u, tangent)
    _flip_down(v, axis)
    return u, v


def fit_cross(pts, u, v, xyz, nb, dist, other, axis=None):
    """Normal perpendicular to the tangent fitting the other-pass neighbours; also the
    distance to the nearest other-pass point (inf where there is none).

    pts : (m, 3) points;  u, v : (m, 3) their :func:`frame`;  xyz : (3, M) every point's
    coordinates;  nb, dist, other : (k, m) neighbours (indices into ``xyz``, nearest
    first), their distances and whether each is on another pass;  axis : (m, 3) tool
    axes, None for +Z.  Returns (m, 3) normals, (m,) int8 confidence, (m,) distances.
    """
    a, b = _offsets_across(pts, xyz, nb, u, v)
    saa, sbb, sab = _weighted_sums(a, b, dist, other)
    # smallest eigenvector of [[saa, sab], [sab, sbb]]: the direction (alpha, beta)
    # minimising sum w (alpha a + beta b)^2
    half = 0.5 * (saa - sbb)
    root = np.sqrt(half * half + sab * sab)
    lam = 0.5 * (saa + sbb) - root
    alpha, beta = sab, lam - saa
    small = _small(alpha, beta, 1e-12 * np.maximum(saa + sbb, 1e-300))
    alpha = np.where(small, 0.0, alpha)
    beta = np.where(small, 1.0, beta)
    n = alpha[:, None] * u + beta[:, None] * v
    n /= np.maximum(row_norms(n), 1e-12)[:, None]
    _flip_down(n, axis)
    has = np.logical_or.reduce(other, axis=0)
    n[~has] = v[~has]  # no other pass near: no cross-slope
    side = np.greater(a, 0.0)
    side &= other
    both = np.logical_or.reduce(side, axis=0)
    np.less(a, 0.0, out=side)
    side &= other
    both &= np.logical_or.reduce(side, axis=0)
    conf = np.where(~has, NO_CROSS, np.where(both, CONFIDENT, ONE_SIDED)).astype(np.int8)
    return n, conf, _closest(dist, other)


def _closest(dist: np.ndarray, other: np.ndarray) -> np.ndarray:
    """(m,) distance to the nearest other-pass neighbour (inf: none) of (k, m) ``dist``,
    ``other``.  The neighbours come nearest first: where the nearest is on another pass
    (most points, where the passes lie closer than the points along them) it is the
    first distance, elsewhere the least over the others."""
    closest = np.where(other[0], dist[0], np.inf)
    rest = np.flatnonzero(~other[0])
    if rest.size:
        closest[rest] = np.where(other[:, rest], dist[:, rest], np.inf).min(axis=0)
    return closest


def _offsets_across(pts, xyz, nb, u, v):
    """(k, m) offsets of the neighbours ``xyz[:, nb]`` from their points ``pts`` along
    ``u`` and along ``v`` (both (m, 3))."""
    p, ut, vt = by_rank(pts), by_rank(u), by_rank(v)
    ox = np.take(xyz[0], nb)
    ox -= p[0]
    oy = np.take(xyz[1], nb)
    oy -= p[1]
    oz = np.take(xyz[2], nb)
    oz -= p[2]
    return _project(ox, oy, oz, ut), _project(ox, oy, oz, vt)


def _small(alpha: np.ndarray, beta: np.ndarray, limit: np.ndarray) -> np.ndarray:
    """``hypot(alpha, beta) < limit``, with hypot (slow) only where ``max(|alpha|,
    |beta|)``, which hypot never falls below, is under the limit."""
    out = np.maximum(np.abs(alpha), np.abs(beta)) < limit
    rows = np.flatnonzero(out)
    if rows.size:
        out[rows] = np.hypot(alpha[rows], beta[rows]) < limit[rows]
    return out


def _weighted_sums(a, b, dist, other):
    """Per point, sum w a a, sum w b b and sum w a b with w = 1 / dist^2 on the other
    passes' neighbours, 0 elsewhere (``a``, ``b``, ``dist``, ``other``: (k, m))."""
    w = np.maximum(dist, 1e-9)
    np.multiply(w, w, out=w)
    np.divide(1.0, w, out=w)
    np.multiply(w, other, out=w)  # w is finite and >= 0 (the tree takes finite points only)
    wa = w * a
    term = wa * a
    saa = rank_sums(term)
    np.multiply(wa, b, out=term)
    sab = rank_sums(term)
    np.multiply(w, b, out=term)
    term *= b
    return saa, rank_sums(term), sab
