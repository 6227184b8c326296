"""A mesh made ready for the contact search (:class:`MeshIndex`): its closest-point BVH,
facet and corner normals, sharp edges, and the chunked, threaded queries on them.

fcpw and libigl are imported when a mesh is first indexed, not with ncopt: libigl
loads scipy.sparse with it (about 0.11 s of ``import ncopt.api``), which a rewrite
without a mesh never uses; with a mesh the import runs in the thread that loads it,
while the program is parsed.
"""

from __future__ import annotations

import functools
import operator

import numpy as np

from ncopt.contacts.closest import Closest, closest_on_triangles, closest_point_scene
from ncopt.contacts.mesh import EdgeLengths, Mesh, mesh_resolution_mm, spatial_order
from ncopt.contacts.rows import dot, norms, unit, unit_or
from ncopt.runtime.errors import MeshError
from ncopt.runtime.memory import release_freed_memory
from ncopt.runtime.threads import available_cpus, map_in_threads


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
        import igl  # deferred until a mesh is indexed (module docstring)
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
        self.face_normal = unit(np.cross(np.take(V, F[:, 1], axis=0) - a,
                                         np.take(V, F[:, 2], axis=0) - a))
        del a
        tt, _ = igl.triangle_triangle_adjacency(F)
        cos_limit = np.cos(np.radians(self.feature_angle_deg))
        self.feature_edge = tt < 0
        for k in range(3):
            cos_angle = dot(self.face_normal,
                            np.take(self.face_normal, np.maximum(tt[:, k], 0), axis=0))
            self.feature_edge[:, k] |= cos_angle < cos_limit
        del tt
        # the vertices at the ends of those edges: a CC point there is on the crease too,
        # whichever of the faces around the vertex the query returns
        self.feature_vertex = np.zeros(V.shape[0], dtype=bool)
        self.feature_vertex[F[self.feature_edge]] = True
        self.feature_vertex[np.roll(F, -1, axis=1)[self.feature_edge]] = True
        if corner_normals is None:
            self.corner_normal = self._corner_normals()
        else:  # a copy, made unit, the facet's where one is unusable: all corners as one
            # contiguous (nf * 3, 3) array (corner by corner, strided: 2x slower)
            cn = np.array(corner_normals, dtype=np.float64).reshape(-1, 3, 3)
            unit_or(cn.reshape(-1, 3), self.face_normal, per=3)
            self.corner_normal = cn
        # fcpw's BVH last: its build holds the GIL (0.5-0.7 s), which stops the parse
        # beside it; late, it overlaps less of it (dense 1M-block case, eight alternating
        # runs: parse + interpret + mesh 2.77 -> 2.68 s, median)
        self._scene = closest_point_scene(mesh)
        release_freed_memory(force=True)  # this thread's arena: the main thread cannot reuse it

    def _corner_normals(self) -> np.ndarray:
        """Unit normals ``(nf, 3, 3)`` at the corners of each face, the facet's where one
        is unusable (shorter than 0.5 or not finite before scaling: ``rows.unit_or``).

        A corner away from sharp edges takes its vertex's normal: the vertex normals are
        scaled once (nv rows) and then copied to their corners, not scaled corner by
        corner (3 nf rows, ~6 times as many: the same divisions, so the same bits).
        """
        import igl  # deferred until a mesh is indexed (module docstring)
        V, F = self.mesh.V, self.mesh.F
        vn = igl.per_vertex_normals(V, F, igl.PER_VERTEX_NORMALS_WEIGHTING_TYPE_ANGLE)
        unit_or(vn, np.full((1, 3), np.nan), per=len(vn))  # unusable rows: NaN (row 0)
        cn = np.take(vn, F, axis=0)
        del vn
        lost = np.flatnonzero(np.isnan(cn[:, :, 0]).ravel())
        if lost.size:
            cn.reshape(-1, 3)[lost] = self.face_normal[lost // 3]
        at_sharp = self.feature_vertex[F]
        near = np.flatnonzero(np.any(at_sharp, axis=1))
        if near.size:  # a corner averages the faces at its vertex: only those faces
            split = igl.per_corner_normals(V, F[near], self.feature_angle_deg).reshape(-1, 3)
            unit_or(split, self.face_normal[near], per=3)
            split = split.reshape(-1, 3, 3)
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
        import fcpw  # deferred until a mesh is indexed (module docstring)
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
        point = closest_on_triangles(P, self.mesh.corners(face))
        point[lost] = np.nan
        return norms(P - point), face, point

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
