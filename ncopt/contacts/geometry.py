"""Contact points and normals from a triangle mesh of the part.

Callers give cutter centres: ball centres, or the centres of a bull-nose's
torus core circle (programmed point + ``cutters.center_offset_mm`` along the
tool axis), and in 5 axes the tool axis per centre.  A ball's contact does not
depend on the axis (the closest point to its centre); its R_eff does.  The
bull-nose search below assumes the axis +Z.  The CC point is the mesh point
closest to the centre (fcpw's BVH finds the face, float64 numpy the point on
it), for a bull-nose to its core disc (radius R - r).

Normals (``normals=``): ``"facet"``; ``"center"`` (CC->centre: the facet
normal too wherever the CC point is inside a facet, so both jump from facet to
facet and R_eff with them); ``"phong"``: corner normals (angle-weighted vertex
normals, split where facets meet at more than ``feature_angle_deg``)
interpolated at the CC point; ``"smooth"`` (default): Newton steps on that
field to the point p whose normal passes through the centre (exact on a sphere
with exact vertex normals), at most 2x the phong/CC->centre angle away from
phong; CC->centre on sharp edges and where the two disagree by more than the
feature angle (e.g. inconsistent winding).

Measured (``bench/bench_geometry.py normals``): analytic surfaces meshed on
jittered grids, ball centres at distance R along the analytic normal.  Cells:
95th-percentile normal error, deg / worst vc overshoot R_true/R_est - 1, %
(where R_eff >= 0.2 R), at grid pitch 0.5 and 2 mm:

    surface, tool               grid | facet       center      phong       smooth
    convex sphere rho 20, D16   0.5  | 1.24 11.5   0.73  5.3   0.32  2.2   0.10  0.7
                                2.0  | 4.96 52.6   2.96 26.7   1.36 10.1   0.53  3.4
    concave bowl rho 50, D16    0.5  | 0.43  3.4   0.43  3.4   0.10  0.7   0.06  0.6
                                2.0  | 1.74 16.6   1.73 16.6   0.41  3.4   0.27  2.2
    concave fillet rho 5, D8    0.5  | 4.22 74.1   4.22 74.1   3.43 54.0   2.24 25.5
                                2.0  | 16.3  145   16.3  145   13.8 77.8   13.9 30.9
    convex fillet rho 5, D16    0.5  | 4.27 60.1   1.15  9.6   1.65 16.3   0.47  1.5
                                2.0  | 16.3  150   4.70 35.1   6.97 49.5   4.34  4.8
    gauss bump 8/12 mm, D8      0.5  | 1.15 15.5   0.89 11.6   0.27  5.0   0.15  1.4
                                2.0  | 4.61 85.6   3.61 57.9   1.57 22.6   1.33  9.9
    sharp 50 deg edge, D8       any  | 46.5  0.0   0.00  0.0   46.5  0.0   0.00  0.0

Area-weighted normals doubled the smooth errors; without the sharp-edge rule
the edge case erred 4-15 deg (p95); a 50/50 blend of CC->centre and phong was
worse than phong; unclamped Newton erred up to 12-21 deg on the concave fillet
at 0.5-1 mm (clamped: 4-8).  No method copes with a 5 mm fillet meshed at 2 mm:
report ``mesh_resolution_mm``.  Bull-nose (``... bullnose``, D8 r1): clearance
within 0.007 mm of a brute-force minimum over the disc, R_eff within 0.01 mm;
but with several bumps under a wide flat (D16 r2, egg-crate of 12.6 mm
period) the lowest can be missed (clearance up to 0.11 mm high; 15 % of the
near-contact points taken for air).  The closest-point query (fcpw) uses every
core itself (1M path-ordered points, 1M triangles: 2.6 s wall, 5.1 s CPU on 2
cores; libigl's AABB tree took 5.0 s wall, 9.8 s CPU): a thread pool spreads
only the numpy work (forked processes were slower than one: 1.27 s against
1.01 s serial and 0.67 s in two threads for 1M normals), and the queries run
in calls of up to 1M points (:meth:`MeshIndex._faces`).

fcpw and libigl are imported when a mesh is first indexed, not with ncopt: libigl
loads scipy.sparse with it (about 0.11 s of ``import ncopt.api``), which a rewrite
without a mesh never uses; with a mesh the import runs in the thread that loads it,
while the program is parsed.
"""

from __future__ import annotations

import functools
import operator
from dataclasses import dataclass

from typing import NamedTuple

import numpy as np

from ncopt.contacts import cutters
from ncopt.runtime.errors import MeshError
from ncopt.motion.modal import row_norms
from ncopt.runtime.memory import release_freed_memory
from ncopt.contacts.mesh import (EdgeLengths, Mesh, load_stl, mesh_from_triangles,  # noqa: F401
                        mesh_resolution_mm, spatial_order)
from ncopt.model import Contacts, Cutter
from ncopt.runtime.threads import available_cpus, map_in_threads

__all__ = ["NORMAL_METHODS", "Closest", "EdgeLengths", "Mesh", "MeshContacts", "MeshIndex",
           "contacts_from_mesh", "load_stl", "mesh_contacts", "mesh_from_triangles",
           "mesh_resolution_mm"]

NORMAL_METHODS = ("smooth", "phong", "center", "facet")



# ---------------------------------------------------------------- mesh and STL


class Closest(NamedTuple):
    """Closest mesh points, in query order: ``dist_mm (m,)``, ``face (m,) int64``,
    ``point_mm (m, 3)``."""

    dist_mm: np.ndarray
    face: np.ndarray
    point_mm: np.ndarray


def _closest_point_scene(mesh: Mesh):
    """fcpw's closest-point BVH over the mesh (float32 copies of V and F)."""
    import fcpw
    scene = fcpw.scene_3D()
    scene.set_object_count(1)
    scene.set_object_vertices(np.asfortranarray(mesh.V, dtype=np.float32), 0)
    scene.set_object_triangles(np.asfortranarray(mesh.F, dtype=np.int32), 0)
    scene.build(fcpw.aggregate_type.bvh_surface_area, True, False, False)
    return scene


def _closest_on_triangles(p: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Closest point to ``p[i]`` on triangle ``tri[i]`` ((m, 3) and (m, 3, 3), mm).

    The Voronoi-region walk of Ericson, Real-Time Collision Detection, 5.1.5:
    vertex, edge or interior, each case vectorised (later cases take precedence,
    as the early returns do there); a zero-area triangle gives its nearest corner.
    """
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    ab, ac = b - a, c - a
    ap, bp, cp = p - a, p - b, p - c
    d1, d2 = _dot(ab, ap), _dot(ac, ap)
    d3, d4 = _dot(ab, bp), _dot(ac, bp)
    d5, d6 = _dot(ab, cp), _dot(ac, cp)
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
        dd = _dot(d, d)
        t = np.clip(np.divide(_dot(p - a, d), dd, out=np.zeros_like(dd), where=dd > 0), 0.0, 1.0)
        q = a + t[:, None] * d
        dist = _norms(p - q)
        if best is None:
            best, best_d = q, dist
        else:
            closer = dist < best_d
            best[closer], best_d[closer] = q[closer], dist[closer]
    return best


def _norms(v: np.ndarray) -> np.ndarray:
    """Length of each row of ``v`` (m, 3): ``np.linalg.norm(v, axis=-1)``, the same sums in
    the same order, 2-3 times faster for float64 rows of 3 (:func:`ncopt.motion.interp.row_norms`)."""
    if v.ndim == 2 and v.shape[1] == 3 and v.dtype == np.float64:
        return row_norms(v)
    return np.linalg.norm(v, axis=-1)


def _unit(v: np.ndarray) -> np.ndarray:
    """Rows scaled to unit length; zero rows stay zero."""
    n = _norms(v)[..., None]
    return np.divide(v, n, out=np.zeros_like(v), where=n > 0)


def _unit_or(v: np.ndarray, fallback: np.ndarray, per: int = 1) -> None:
    """Scale rows of ``v`` to unit length in place; rows that are not finite or
    shorter than 0.5 become rows of ``fallback``: row ``i`` takes ``fallback[i // per]``
    (``per`` = 3: the corners of a face, ``v`` its (nf * 3, 3) corner rows)."""
    length = _norms(v)
    bad = ~(length >= 0.5)  # NaN too
    inf = np.flatnonzero(np.isinf(length))  # an infinite coordinate, or only huge ones
    bad[inf] = ~np.all(np.isfinite(v[inf]), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        np.divide(v, length[:, None], out=v)
    bad = np.flatnonzero(bad)
    v[bad] = fallback[bad // per]


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row dot products of (m, 3) arrays, summed ``(x + z) + y``: the order in which
    numpy 2.4's ``einsum("ij,ij->i")`` sums rows of 3 on x86-64, where this was written
    (the same bits as it gave there), written out: 1.4x faster at 65,536 rows, and no
    longer dependent on einsum's inner loops."""
    p = a * b
    s = p[:, 0] + p[:, 2]
    s += p[:, 1]
    return s


def _dot3(a: tuple, b: tuple) -> np.ndarray:
    """:func:`_dot` of vectors given as their three (m,) coordinate arrays."""
    s = a[0] * b[0]
    s += a[2] * b[2]
    s += a[1] * b[1]
    return s


def _cross3(a: tuple, b: tuple) -> tuple:
    """``np.cross`` of vectors given as their three coordinate arrays (the same sums)."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


_PRIMITIVE = operator.attrgetter("primitive_index")


class MeshIndex:
    """A mesh with its closest-point BVH and the normals the contact search needs.

    Parameters
    ----------
    mesh : Mesh
    feature_angle_deg : float
        Facets meeting at a larger angle form a sharp edge: their normals are
        not averaged, and a contact on that edge takes the CC->centre direction.
    pool_min_points : int or None
        The normal estimation of at least this many points runs chunk by chunk
        in a pool of threads (numpy releases the GIL in its loops); None: always
        serial.  Both give identical results.
    chunk_points : int
        Points per chunk: bounds the temporaries; the pool's unit of work.
    query_points : int
        Points per closest-point call (:meth:`_faces`): ~60 bytes each while it runs.
    processes : int or None
        Pool size (threads); default: the CPUs this process may use.
    corner_normals : (nf, 3, 3) float64 or None
        Normals to interpolate instead of the default ``corner_normal``.

    Attributes
    ----------
    face_normal : (nf, 3) float64
        Unit facet normals, right-hand rule over ``F`` (zero if degenerate).
    corner_normal : (nf, 3, 3) float64
        Unit normal at corner ``k`` of face ``f``: angle-weighted vertex
        normals, split (libigl ``per_corner_normals``) at sharp edges.
    feature_edge : (nf, 3) bool
        Edge ``k`` of face ``f`` (corner ``k`` to ``k+1``) is sharp or a boundary.
    """

    def __init__(self, mesh: Mesh, *, feature_angle_deg: float = 40.0,
                 pool_min_points: int | None = 200_000, chunk_points: int = 65_536,
                 query_points: int = 1 << 20, processes: int | None = None,
                 corner_normals: np.ndarray | None = None) -> None:
        if mesh.n_faces == 0:
            raise MeshError("the mesh has no triangles")
        import igl
        self.mesh = mesh
        self.feature_angle_deg = float(feature_angle_deg)
        self.pool_min_points = pool_min_points
        self.chunk_points = max(1, int(chunk_points))
        self.query_points = max(1, int(query_points))
        self.processes = int(processes or available_cpus())
        # face by corner, not (nf, 3, 3) temporaries: the mesh loads while the program
        # is parsed, so its peak adds to theirs (1M triangles: ~200 MB lower)
        V, F = mesh.V, mesh.F
        a = np.take(V, F[:, 0], axis=0)  # np.take: 3-4x faster than V[F[:, 0]]
        self.face_normal = _unit(np.cross(np.take(V, F[:, 1], axis=0) - a,
                                          np.take(V, F[:, 2], axis=0) - a))
        del a
        tt, _ = igl.triangle_triangle_adjacency(F)
        cos_limit = np.cos(np.radians(self.feature_angle_deg))
        self.feature_edge = tt < 0
        for k in range(3):
            cos_angle = _dot(self.face_normal,
                             np.take(self.face_normal, np.maximum(tt[:, k], 0), axis=0))
            self.feature_edge[:, k] |= cos_angle < cos_limit
        del tt
        # the vertices at the ends of those edges: a CC point there is on the crease too,
        # whichever of the faces around the vertex the query returns
        self.feature_vertex = np.zeros(V.shape[0], dtype=bool)
        self.feature_vertex[F[self.feature_edge]] = True
        self.feature_vertex[np.roll(F, -1, axis=1)[self.feature_edge]] = True
        cn = (self._corner_normals() if corner_normals is None else  # ours, or a copy
              np.array(corner_normals, dtype=np.float64).reshape(-1, 3, 3))
        # unit corner normals, the facet's where one is unusable: all corners as one
        # contiguous (nf * 3, 3) array (corner by corner, strided: 2x slower)
        _unit_or(cn.reshape(-1, 3), self.face_normal, per=3)
        self.corner_normal = cn
        # fcpw's BVH last: its build holds the GIL (0.5-0.7 s), which stops the parse
        # beside it; late, it overlaps less of it (dense 1M-block case, eight alternating
        # runs: parse + interpret + mesh 2.77 -> 2.68 s, median)
        self._scene = _closest_point_scene(mesh)
        release_freed_memory(force=True)  # this thread's arena: the main thread cannot reuse it

    def _corner_normals(self) -> np.ndarray:
        import igl
        V, F = self.mesh.V, self.mesh.F
        cn = np.take(igl.per_vertex_normals(V, F, igl.PER_VERTEX_NORMALS_WEIGHTING_TYPE_ANGLE),
                     F, axis=0)
        sharp = np.zeros(V.shape[0], dtype=bool)
        sharp[F[self.feature_edge]] = True
        sharp[np.roll(F, -1, axis=1)[self.feature_edge]] = True
        at_sharp = sharp[F]
        near = np.flatnonzero(np.any(at_sharp, axis=1))
        if near.size:  # a corner averages the faces at its vertex: only those faces
            split = igl.per_corner_normals(V, F[near], self.feature_angle_deg).reshape(-1, 3, 3)
            cn[near] = np.where(at_sharp[near][:, :, None], split, cn[near])
        return cn

    @functools.cached_property
    def edge_lengths(self) -> EdgeLengths:
        """:func:`ncopt.contacts.mesh.mesh_resolution_mm` of the mesh, computed once."""
        return mesh_resolution_mm(self.mesh)

    def map_chunks(self, fn, *arrays: np.ndarray, pool: bool = True) -> tuple:
        """Apply ``fn`` to consecutive row chunks of ``arrays``; concatenate in order.

        ``fn(a[lo:hi], b[lo:hi], ...)`` returns a tuple of arrays with one row per
        input row.  With ``pool`` (numpy work), large inputs run in a thread pool;
        without it (closest-point queries, which use every core themselves) chunk
        by chunk in this thread.
        """
        arrays = tuple(np.ascontiguousarray(a) for a in arrays)
        m = arrays[0].shape[0]
        bounds = [(lo, min(lo + self.chunk_points, m)) for lo in range(0, m, self.chunk_points)]
        pool = pool and self.pool_min_points is not None and m >= self.pool_min_points
        parts = map_in_threads(lambda b: fn(*(a[b[0]:b[1]] for a in arrays)), bounds,
                               self.processes if pool else 1) or [fn(*arrays)]
        return tuple(np.concatenate(col) for col in zip(*parts))

    def _faces(self, P: np.ndarray) -> np.ndarray:
        """The face holding the closest mesh point of each row of ``P (m, 3)``; -1 where
        a query point is not finite.

        fcpw's vectorised BVH (float32) answers ``query_points`` points per call.  It
        behaves as if it gave each core one contiguous run of a call's points: a call
        lasts as long as its slowest run, and few large calls keep the cores evenly
        loaded (1M spatially ordered points, 2 cores: 3.4-3.5 s in one call, 3.8-4.0 s
        in calls of 65,536).  Each point costs ~60 bytes of results while its call runs.
        """
        import fcpw
        face = np.empty(P.shape[0], dtype=np.int64)
        for lo in range(0, P.shape[0], self.query_points):
            part = P[lo:lo + self.query_points]
            found = fcpw.interaction_3D_list()
            self._scene.find_closest_points(np.asfortranarray(part, dtype=np.float32),
                                            np.full(part.shape[0], np.inf, np.float32), found)
            face[lo:lo + part.shape[0]] = np.fromiter(map(_PRIMITIVE, found), np.int64,
                                                      part.shape[0])
            del found
        return face

    def _on_faces(self, P: np.ndarray, face: np.ndarray) -> tuple:
        """(dist_mm, face, point_mm) of ``P (m, 3)`` on the faces :meth:`_faces` found.

        The point on the face and the distance are computed in float64 from the mesh
        itself, so they are as exact as the mesh (float32 only decides between faces
        whose distances differ by less than ~1e-5 relative).
        """
        lost = face < 0  # a non-finite query point: no face, no point
        face = np.where(lost, 0, face)
        point = _closest_on_triangles(P, self.mesh.corners(face))
        point[lost] = np.nan
        return _norms(P - point), face, point

    def _query(self, P: np.ndarray) -> tuple:
        """Closest mesh points of ``P (m, 3)``: (dist_mm, face, point_mm), in one go."""
        if P.shape[0] == 0:
            return np.zeros(0), np.zeros(0, np.int64), np.zeros((0, 3))
        P = np.ascontiguousarray(P, dtype=np.float64)
        return self._on_faces(P, self._faces(P))

    def closest(self, points_mm: np.ndarray) -> Closest:
        """Closest mesh point of each query point ``(m, 3)``, in order (queried in
        :func:`ncopt.contacts.mesh.spatial_order`: the same answers, faster); the faces in
        large calls, the points on them chunk by chunk in the pool."""
        P = np.asarray(points_mm, dtype=np.float64)
        order = spatial_order(P)
        P = np.take(P, order, axis=0)
        found = self.map_chunks(self._on_faces, P, self._faces(P))
        del P
        back = np.empty_like(order)
        back[order] = np.arange(order.size)
        return Closest(*(np.take(a, back, axis=0) for a in found))


# ---------------------------------------------------------------- normals


class _Frame(NamedTuple):
    """Points in their faces: ``x = p0 + u e1 + v e2``; normals ``n0 + u m1 + v m2``."""

    p0: np.ndarray
    e1: np.ndarray
    e2: np.ndarray
    n0: np.ndarray
    m1: np.ndarray
    m2: np.ndarray
    u: np.ndarray
    v: np.ndarray

    def phong(self, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Interpolated, unnormalised normal at ``(u, v)`` (linear: extrapolates)."""
        return self.n0 + u[:, None] * self.m1 + v[:, None] * self.m2


def _frame(index: MeshIndex, face: np.ndarray, x: np.ndarray) -> _Frame:
    P, N = index.mesh.corners(face), np.take(index.corner_normal, face, axis=0)
    p0, e1, e2 = P[:, 0], P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]
    d = x - p0
    d00, d01, d11, d20, d21 = _dot(e1, e1), _dot(e1, e2), _dot(e2, e2), _dot(d, e1), _dot(d, e2)
    with np.errstate(divide="ignore", invalid="ignore"):
        den = d00 * d11 - d01 * d01
        u, v = (d11 * d20 - d01 * d21) / den, (d00 * d21 - d01 * d20) / den
    return _Frame(p0, e1, e2, N[:, 0], N[:, 1] - N[:, 0], N[:, 2] - N[:, 0], u, v)


def _offset_newton(fr: _Frame, centre: np.ndarray, steps: int = 2) -> tuple:
    """Unit normal at ``p`` (face plane) with ``centre = p + t n(p)``; min barycentric of p.

    ``n`` is linear in ``(u, v)`` on a face: each Newton step on ``(u, v, t)``
    is a 3x3 solve (Cramer's rule).  A negative coordinate: ``p`` left the face.
    The vectors are taken apart into their coordinates (contiguous (m,) arrays):
    0.33 against 0.54 s for 1M points as (m, 3) rows, the same operations in the
    same order and so the same bits.
    """
    def split(a):
        return tuple(np.ascontiguousarray(a.T))

    p0, e1, e2, n0, m1, m2, c = (split(a) for a in (fr.p0, fr.e1, fr.e2, fr.n0, fr.m1, fr.m2,
                                                    centre))

    def phong(u, v):
        return tuple(n0[k] + u * m1[k] + v * m2[k] for k in range(3))

    def to_centre(u, v):  # centre - (p0 + u e1 + v e2)
        return tuple(c[k] - (p0[k] + u * e1[k] + v * e2[k]) for k in range(3))

    u, v = fr.u, fr.v
    m = phong(u, v)
    t = _dot3(to_centre(u, v), m) / _dot3(m, m)
    for _ in range(steps):
        a = tuple(e1[k] + t * m1[k] for k in range(3))
        b = tuple(e2[k] + t * m2[k] for k in range(3))
        rhs = tuple(q - t * mk for q, mk in zip(to_centre(u, v), m))
        bm = _cross3(b, m)
        with np.errstate(divide="ignore", invalid="ignore"):
            det = _dot3(a, bm)
            u = u + _dot3(rhs, bm) / det
            v = v + _dot3(a, _cross3(rhs, m)) / det
            t = t + _dot3(a, _cross3(b, rhs)) / det
        m = phong(u, v)
    bary_min = np.minimum(np.minimum(u, v), 1.0 - u - v)
    return _unit(np.stack(m, axis=1)), np.where(np.isfinite(bary_min), bary_min, -np.inf)


def _on_feature_edge(index: MeshIndex, face: np.ndarray, fr: _Frame) -> np.ndarray:
    """The CC point lies on a sharp or boundary edge of its face (or at its ends), or at
    a corner of its face that is the end of such an edge of another face (a wall's
    triangle that meets the crease above it at one corner only: its corner normal there
    is the wall's, the contact's is between the wall's and the top's)."""
    # edge k joins corners k and k+1: it is where the coordinate of corner k+2 vanishes
    opposite = np.stack([fr.v, 1.0 - fr.u - fr.v, fr.u], axis=1)
    on_edge = np.any((opposite <= 1e-6) & np.take(index.feature_edge, face, axis=0), axis=1)
    weight = np.stack([1.0 - fr.u - fr.v, fr.u, fr.v], axis=1)  # corner k's coordinate
    corner = np.take(index.feature_vertex, np.take(index.mesh.F, face, axis=0))
    return on_edge | np.any((weight >= 1.0 - 1e-6) & corner, axis=1)


def _clamp_cone(axis: np.ndarray, n: np.ndarray, max_rad: np.ndarray) -> np.ndarray:
    """Rotate unit rows ``n`` toward ``axis`` until within ``max_rad`` of it."""
    cos_a = np.clip(_dot(axis, n), -1.0, 1.0)
    perp = _unit(n - cos_a[:, None] * axis)
    clamped = np.cos(max_rad)[:, None] * axis + np.sin(max_rad)[:, None] * perp
    return np.where((np.arccos(cos_a) > max_rad)[:, None], clamped, n)


def _orient(normal: np.ndarray, toward: np.ndarray) -> np.ndarray:
    """Flip rows of ``normal`` that point away from ``toward``."""
    return np.where((_dot(normal, toward) < 0)[:, None], -normal, normal)


# How far (in multiples of the phong / CC->centre angle) Newton may move the
# normal from phong: 1 loses accuracy, 4+ lets concave near-fits blow up.
_NEWTON_CONE = 2.0


def _smooth_normal(index: MeshIndex, cl: Closest, fr: _Frame, centre: np.ndarray,
                   n_center: np.ndarray) -> np.ndarray:
    """Phong-offset normal; the CC->centre direction on sharp edges or disagreement."""
    phong = _orient(_unit(fr.phong(fr.u, fr.v)), n_center)
    cone = _NEWTON_CONE * np.arccos(np.clip(_dot(phong, n_center), -1.0, 1.0))
    normal, bary_min = _offset_newton(fr, centre)
    normal = _clamp_cone(phong, _orient(normal, n_center), cone)
    left = np.flatnonzero(bary_min < -0.05)
    if left.size:  # p left its face: redo in the face holding the closest point to p
        again = Closest(*index._query(centre[left] - normal[left] * cl.dist_mm[left, None]))
        redo = _offset_newton(_frame(index, again.face, again.point_mm), centre[left])[0]
        normal[left] = _clamp_cone(phong[left], _orient(redo, n_center[left]), cone[left])
    cos_limit = np.cos(np.radians(index.feature_angle_deg))
    use_center = (_dot(n_center, normal) < cos_limit) | ~np.all(np.isfinite(normal), axis=1)
    use_center |= _on_feature_edge(index, cl.face, fr)
    return np.where(use_center[:, None], n_center, normal)


def _contact_normal(index: MeshIndex, cl: Closest, centre: np.ndarray,
                    method: str, axis: np.ndarray | None = None) -> np.ndarray:
    """Unit normal at each CC point, oriented toward the tool."""
    n_center = _unit(centre - cl.point_mm)
    facet = np.take(index.face_normal, cl.face, axis=0)
    lost = ~np.any(n_center, axis=1)  # centre on the mesh: take the facet's, toward the tool
    up = np.array([[0.0, 0.0, 1.0]]) if axis is None else axis[lost]
    n_center[lost] = _orient(facet[lost], up)
    if method == "center":
        return n_center
    if method == "facet":
        return _orient(facet, n_center)
    fr = _frame(index, cl.face, cl.point_mm)
    if method == "phong":
        phong = _orient(_unit(fr.phong(fr.u, fr.v)), n_center)
        return np.where(np.all(np.isfinite(phong), axis=1)[:, None], phong, n_center)
    return _smooth_normal(index, cl, fr, centre, n_center)


# ---------------------------------------------------------------- bull-nose search


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
        new = _core_points(centers[rows], _unit(core[rows] - current.point_mm), flat_mm)
        moved = _norms(new - core[rows]) > 1e-3
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
        rising = _dot(core - current.point_mm, tangent) > 0
        hi, lo = np.where(rising, mid, hi), np.where(rising, lo, mid)


def _project_to_disc(index: MeshIndex, centers: np.ndarray, flat_mm: float, best: Closest,
                     best_core: np.ndarray, rows: np.ndarray) -> None:
    """Disc point above the contact (the flat bottom on a bump under the tool)."""
    for _ in range(_PROJECT):
        off = (best.point_mm - centers)[rows] * [1.0, 1.0, 0.0]
        length = np.linalg.norm(off, axis=1, keepdims=True)
        core = centers[rows] + off * np.minimum(1.0, flat_mm / np.maximum(length, 1e-12))
        _keep_nearer(best, best_core, rows, Closest(*index._query(core)), core)


def _torus_closest(index: MeshIndex, centers: np.ndarray, cutter: Cutter,
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


# ---------------------------------------------------------------- contacts


@dataclass(frozen=True)
class MeshContacts:
    """Contacts plus what the mesh says about the tool's clearance.

    Attributes
    ----------
    contacts : Contacts
        CC points (closest mesh points), normals toward the tool, ``R_eff``
        (:func:`ncopt.contacts.cutters.r_eff_mm`), ``cutting = gap_mm <= tol_mm``.
    gap_mm : (m,) float64
        Clearance of the cutter from the mesh less ``stock_mm``, mm; negative
        inside the part.  For bull-nose air points an upper bound.
    gouging : (m,) bool
        ``gap_mm < -tol_mm``: suggests a wrong tool, mesh, tool point or stock.
    face : (m,) int64
        Mesh face holding each CC point.
    """

    contacts: Contacts
    gap_mm: np.ndarray
    gouging: np.ndarray
    face: np.ndarray

    @property
    def n_gouging(self) -> int:
        return int(np.count_nonzero(self.gouging))


def _torus_chunk(centers: np.ndarray, index: MeshIndex, cutter: Cutter, band_mm: float) -> tuple:
    core, cl = _torus_closest(index, centers, cutter, band_mm)
    return (core, *cl)


def _normal_chunk(core, dist, face, point, *axis, index: MeshIndex, method: str) -> tuple:
    return (_contact_normal(index, Closest(dist, face, point), core, method,
                            axis[0] if axis else None),)


def mesh_contacts(centers_mm: np.ndarray, mesh_index: MeshIndex, cutter: Cutter,
                  tol_mm: float = 0.05, *, stock_mm: float = 0.0,
                  normals: str = "smooth", axis: np.ndarray | None = None) -> MeshContacts:
    """Contacts of a ball or bull-nose cutter with a mesh, with clearances.

    Parameters
    ----------
    centers_mm : (m, 3) float64
        Ball centres (ball) or torus core-circle centres (bull-nose), mm, in
        path order: programmed points raised by ``cutters.center_offset_mm``.
    mesh_index : MeshIndex
    cutter : Cutter
    tol_mm : float
        Contact where the clearance is within this of ``stock_mm`` (mesh
        chord error + CAM tolerance), mm.
    stock_mm : float
        Allowance the program leaves on the part, mm.
    normals : {"smooth", "phong", "center", "facet"}
        Contact normal estimate (module docstring).
    axis : (m, 3) float64 or None
        Unit tool axis at each centre (5 axes); None: +Z.  A bull-nose takes
        +Z only.

    Returns
    -------
    MeshContacts
        Air points (clearance above ``tol_mm``) are not cutting; points inside
        the part are cutting and flagged as gouging.
    """
    if normals not in NORMAL_METHODS:
        raise ValueError(f"normals must be one of {NORMAL_METHODS}, got {normals!r}")
    c = np.ascontiguousarray(centers_mm, dtype=np.float64)
    if c.ndim != 2 or c.shape[1] != 3:
        raise ValueError(f"centers_mm must be (m, 3), got {c.shape}")
    if not np.all(np.isfinite(c)):
        raise ValueError("centers_mm holds non-finite coordinates")
    if axis is not None and not cutter.is_ball and np.any(axis[:, :2]):
        raise ValueError("the bull-nose contact search takes a +Z tool axis only")
    if cutter.is_ball:
        core, cl = c, mesh_index.closest(c)
    else:  # the disc search is mostly queries: serial chunks, the library uses the cores
        work = functools.partial(_torus_chunk, index=mesh_index, cutter=cutter,
                                 band_mm=stock_mm + tol_mm)
        core, *found = mesh_index.map_chunks(work, c, pool=False)
        cl = Closest(*found)
    normal_work = functools.partial(_normal_chunk, index=mesh_index, method=normals)
    (normal,) = mesh_index.map_chunks(normal_work, core, *cl, *(() if axis is None else (axis,)))
    cc, dist, face = cl.point_mm, cl.dist_mm, cl.face
    gap = dist - cutter.corner_radius_mm - stock_mm
    contacts = Contacts(cc_mm=cc, normal=normal, r_eff_mm=cutters.r_eff_mm(cutter, normal, axis),
                        cutting=gap <= tol_mm)
    return MeshContacts(contacts=contacts, gap_mm=gap, gouging=gap < -tol_mm, face=face)


def contacts_from_mesh(centers_mm: np.ndarray, mesh_index: MeshIndex, cutter: Cutter,
                       tol_mm: float = 0.05, *, stock_mm: float = 0.0,
                       normals: str = "smooth", axis: np.ndarray | None = None) -> Contacts:
    """:func:`mesh_contacts` without the clearances (same parameters); returns Contacts."""
    return mesh_contacts(centers_mm, mesh_index, cutter, tol_mm, stock_mm=stock_mm,
                         normals=normals, axis=axis).contacts
