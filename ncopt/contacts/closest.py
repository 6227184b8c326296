"""Closest points on a triangle mesh: fcpw's BVH over the mesh finds the face
(float32), and the point on that face is computed in float64 from the mesh itself."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ncopt.contacts.mesh import Mesh
from ncopt.contacts.rows import dot, norms


class Closest(NamedTuple):
    """Closest mesh points, in query order: ``dist_mm (m,)``, ``face (m,) int64``,
    ``point_mm (m, 3)``."""

    dist_mm: np.ndarray
    face: np.ndarray
    point_mm: np.ndarray


def closest_point_scene(mesh: Mesh):
    """fcpw's closest-point BVH over the mesh (float32 copies of V and F)."""
    import fcpw  # deferred until a mesh is indexed (see ncopt.contacts.meshindex)
    scene = fcpw.scene_3D()
    scene.set_object_count(1)
    scene.set_object_vertices(np.asfortranarray(mesh.V, dtype=np.float32), 0)
    scene.set_object_triangles(np.asfortranarray(mesh.F, dtype=np.int32), 0)
    scene.build(fcpw.aggregate_type.bvh_surface_area, True, False, False)
    return scene


def closest_on_triangles(p: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Closest point to ``p[i]`` on triangle ``tri[i]`` ((m, 3) and (m, 3, 3), mm).

    The Voronoi-region walk of Ericson, Real-Time Collision Detection, 5.1.5:
    vertex, edge or interior, each case vectorised (later cases take precedence,
    as the early returns do there); a zero-area triangle gives its nearest corner.
    """
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    ab, ac = b - a, c - a
    ap, bp, cp = p - a, p - b, p - c
    d1, d2 = dot(ab, ap), dot(ac, ap)
    d3, d4 = dot(ab, bp), dot(ac, bp)
    d5, d6 = dot(ab, cp), dot(ac, cp)
    del ap, bp, cp
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    # each case on its rows only, in place (np.where over all rows was 2x slower)
    with np.errstate(divide="ignore", invalid="ignore"):
        den = va + vb + vc
        out = a + (vb / den)[:, None] * ab + (vc / den)[:, None] * ac  # interior
        on = np.flatnonzero((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0))  # edge BC
        t = (d4[on] - d3[on]) / ((d4[on] - d3[on]) + (d5[on] - d6[on]))
        out[on] = b[on] + t[:, None] * (c[on] - b[on])
        on = np.flatnonzero((vb <= 0) & (d2 >= 0) & (d6 <= 0))  # edge AC
        out[on] = a[on] + (d2[on] / (d2[on] - d6[on]))[:, None] * ac[on]
        on = np.flatnonzero((d6 >= 0) & (d5 <= d6))  # corner C
        out[on] = c[on]
        on = np.flatnonzero((vc <= 0) & (d1 >= 0) & (d3 <= 0))  # edge AB
        out[on] = a[on] + (d1[on] / (d1[on] - d3[on]))[:, None] * ab[on]
    on = np.flatnonzero((d3 >= 0) & (d4 <= d3))  # corner B
    out[on] = b[on]
    on = np.flatnonzero((d1 <= 0) & (d2 <= 0))  # corner A
    out[on] = a[on]
    bad = ~np.all(np.isfinite(out), axis=1) & np.all(np.isfinite(p), axis=1)
    if np.any(bad):  # a zero-area triangle: the nearest point of its three edges
        out[bad] = _closest_on_edges(p[bad], tri[bad])
    return out


def _closest_on_edges(p: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Closest point to ``p[i]`` on the three edge segments of ``tri[i]``."""
    best, best_d = None, None
    for i, j in ((0, 1), (1, 2), (2, 0)):
        a, d = tri[:, i], tri[:, j] - tri[:, i]
        dd = dot(d, d)
        t = np.clip(np.divide(dot(p - a, d), dd, out=np.zeros_like(dd), where=dd > 0), 0.0, 1.0)
        q = a + t[:, None] * d
        dist = norms(p - q)
        if best is None:
            best, best_d = q, dist
        else:
            closer = dist < best_d
            best[closer], best_d[closer] = q[closer], dist[closer]
    return best
