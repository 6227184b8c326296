"""The bull-nose contact search: the point of the cutter's core disc (radius R - r, tool
axis +Z) nearest the mesh, by closest-point queries from seeds on the disc
(:func:`torus_closest`)."""

from __future__ import annotations

import numpy as np

from ncopt.contacts.closest import Closest
from ncopt.contacts.meshindex import MeshIndex
from ncopt.contacts.rows import dot, norms, unit
from ncopt.model import Cutter


def _core_points(centers: np.ndarray, normal: np.ndarray, flat_mm: float) -> np.ndarray:
    """Ring point facing a contact: ``centre - (R - r) unit(n_xy)`` (the side the
    surface rises); the centre itself where ``n_xy ~ 0`` (the flat bottom touches)."""
    nxy = normal * np.array([1.0, 1.0, 0.0])
    length = np.linalg.norm(nxy, axis=1, keepdims=True)
    return centers - flat_mm * np.divide(nxy, length, out=np.zeros_like(nxy),
                                         where=length > 1e-9)


def _keep_nearer(best: Closest, best_core: np.ndarray, rows: np.ndarray, got: Closest,
                 core: np.ndarray) -> None:
    """Where ``got`` (for ``rows``, queried at ``core``) is nearer, update ``best`` in place."""
    better = got.dist_mm < best.dist_mm[rows]
    sel = rows[better]
    best.dist_mm[sel], best.face[sel] = got.dist_mm[better], got.face[better]
    best.point_mm[sel], best_core[sel] = got.point_mm[better], core[better]


def _ring_points(centers: np.ndarray, radius_mm: float, az: np.ndarray) -> np.ndarray:
    return centers + radius_mm * np.stack([np.cos(az), np.sin(az), 0.0 * az], axis=-1)


# Search effort near contact: fixed-point steps, ring and half-radius seeds,
# azimuth bisections, projections onto the disc (about 21 queries a point).
_FIXED, _RING, _INNER, _HALVINGS, _PROJECT = 2, 8, 4, 4, 2


def _fixed_point(index: MeshIndex, centers: np.ndarray, flat_mm: float, best: Closest,
                 best_core: np.ndarray, rows: np.ndarray) -> None:
    """Ring point facing the contact normal, repeated (exact on a plane)."""
    core, current = centers.copy(), Closest(*(a[rows] for a in best))
    for _ in range(_FIXED):
        new = _core_points(centers[rows], unit(core[rows] - current.point_mm), flat_mm)
        moved = norms(new - core[rows]) > 1e-3
        core[rows] = new
        rows = rows[moved]
        if rows.size == 0:
            return
        current = Closest(*index._query(core[rows]))
        _keep_nearer(best, best_core, rows, current, core[rows])


def _seeded_ring_search(index: MeshIndex, centers: np.ndarray, flat_mm: float,
                        best: Closest, best_core: np.ndarray, rows: np.ndarray) -> None:
    """Seeds on the ring and at half radius; bisect the best ring bracket on d dist/d az."""
    c = centers[rows]
    az = 2.0 * np.pi * np.arange(_RING) / _RING
    inner = 2.0 * np.pi * np.arange(_INNER) / max(_INNER, 1) + np.pi / _RING
    seeds = np.concatenate([_ring_points(c[None], flat_mm, az[:, None] + 0 * rows),
                            _ring_points(c[None], 0.5 * flat_mm, inner[:, None] + 0 * rows)])
    got = Closest(*(a.reshape(len(seeds), rows.size, *a.shape[1:])
                    for a in index._query(seeds.reshape(-1, 3))))
    pick = (np.argmin(got.dist_mm, axis=0), np.arange(rows.size))
    _keep_nearer(best, best_core, rows, Closest(*(a[pick] for a in got)), seeds[pick])
    mid = az[np.argmin(got.dist_mm[:_RING], axis=0)]
    lo, hi = mid - np.pi / _RING, mid + np.pi / _RING
    for _ in range(_HALVINGS):
        mid = 0.5 * (lo + hi)
        core = _ring_points(c, flat_mm, mid)
        current = Closest(*index._query(core))
        _keep_nearer(best, best_core, rows, current, core)
        tangent = np.stack([-np.sin(mid), np.cos(mid), 0.0 * mid], axis=1)
        rising = dot(core - current.point_mm, tangent) > 0
        hi, lo = np.where(rising, mid, hi), np.where(rising, lo, mid)


def _project_to_disc(index: MeshIndex, centers: np.ndarray, flat_mm: float, best: Closest,
                     best_core: np.ndarray, rows: np.ndarray) -> None:
    """Disc point above the contact (the flat bottom on a bump under the tool)."""
    for _ in range(_PROJECT):
        off = (best.point_mm - centers)[rows] * [1.0, 1.0, 0.0]
        length = np.linalg.norm(off, axis=1, keepdims=True)
        core = centers[rows] + off * np.minimum(1.0, flat_mm / np.maximum(length, 1e-12))
        _keep_nearer(best, best_core, rows, Closest(*index._query(core)), core)


def torus_closest(index: MeshIndex, centers: np.ndarray, cutter: Cutter,
                  band_mm: float) -> tuple[np.ndarray, Closest]:
    """Point of the core disc nearest the mesh, and its closest mesh points.

    The clearance is a minimum over the disc (radius R - r), so each disc
    point queried bounds it from above: keep the nearest.  The fixed point
    alone cycles where the slope is low and the surface curved across the
    ring, and never finds a second bump: seeds, an azimuth search and
    projections follow where the clearance could be below ``band_mm``.
    """
    flat_mm = cutter.radius_mm - cutter.corner_radius_mm
    best = Closest(*index._query(centers))
    best_core = centers.copy()
    near = np.flatnonzero(best.dist_mm - flat_mm - cutter.corner_radius_mm < band_mm)
    if near.size:
        for step in (_fixed_point, _seeded_ring_search, _project_to_disc):
            step(index, centers, flat_mm, best, best_core, near)
    return best_core, best
