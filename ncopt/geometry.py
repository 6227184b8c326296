"""Contact points and normals from a triangle mesh of the part.

Three-axis tools (axis ``+Z``).  The caller gives cutter centres: the ball
centre of a ball-end mill, or the centre of the torus core circle of a
bull-nose (programmed point + ``tools.center_offset_mm``).  A libigl AABB tree
finds the closest mesh point to each centre; that point is the CC point.

Normals
-------
A faceted mesh has piecewise-constant facet normals, and the direction from
the CC point to the centre is the facet normal wherever the closest point lies
inside a facet: both jump from facet to facet, and so does ``R_eff``.
``normals="smooth"`` (the default) interpolates area-weighted per-corner
normals (libigl ``per_corner_normals``: faces meeting at more than
``feature_angle_deg`` are not averaged, so sharp part edges stay sharp) and
takes one or two Newton steps on that normal field to the point ``p`` whose
smoothed normal passes through the centre (``centre = p + t n(p)``).  For a
sphere with exact vertex normals this is exact at any mesh size.  Where the CC
point lies on a feature edge (the cutter rolls over a sharp edge) or the
smoothed normal disagrees with the CC->centre direction by more than the
feature angle (e.g. inconsistent facet winding) the CC->centre direction is
used.  ``"phong"`` is the plain interpolation at the CC point, ``"center"`` the
CC->centre direction, ``"facet"`` the facet normal.

MEASUREMENTS_PLACEHOLDER
"""

from __future__ import annotations

import functools
import multiprocessing
import os
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import igl
import numpy as np
from stl import Mode
from stl import mesh as stl_mesh

from ncopt import tools
from ncopt.errors import MeshError
from ncopt.model import Contacts, Cutter

__all__ = [
    "NORMAL_METHODS",
    "Closest",
    "EdgeLengths",
    "Mesh",
    "MeshContacts",
    "MeshIndex",
    "contacts_from_mesh",
    "load_stl",
    "mesh_contacts",
    "mesh_from_triangles",
    "mesh_resolution_mm",
]

NORMAL_METHODS = ("smooth", "phong", "center", "facet")

_STL_READ_ERRORS = (ValueError, RuntimeError, AssertionError, OSError, IndexError, UnicodeError)


# ---------------------------------------------------------------- mesh and STL


@dataclass(frozen=True)
class Mesh:
    """An indexed triangle mesh (libigl's ``V``, ``F`` naming).

    Attributes
    ----------
    V : (nv, 3) float64
        Vertex positions, mm.
    F : (nf, 3) int64
        Vertex indices of each triangle, counter-clockwise seen from outside.
    """

    V: np.ndarray
    F: np.ndarray

    def __post_init__(self) -> None:
        V = np.ascontiguousarray(self.V, dtype=np.float64)
        F = np.ascontiguousarray(self.F, dtype=np.int64)
        if V.ndim != 2 or V.shape[1] != 3:
            raise ValueError(f"V must be (nv, 3), got {V.shape}")
        if F.ndim != 2 or F.shape[1] != 3:
            raise ValueError(f"F must be (nf, 3), got {F.shape}")
        if F.size and (F.min() < 0 or F.max() >= V.shape[0]):
            raise ValueError("F refers to vertices that do not exist")
        object.__setattr__(self, "V", V)
        object.__setattr__(self, "F", F)

    @property
    def n_faces(self) -> int:
        return int(self.F.shape[0])


def mesh_from_triangles(tri_mm: np.ndarray, merge_tol_mm: float = 1e-6) -> Mesh:
    """Index a triangle soup, merging vertices that coincide.

    Parameters
    ----------
    tri_mm : (nf, 3, 3) float
        Corner positions of each triangle, mm (STL order).
    merge_tol_mm : float
        Vertices are merged when they round to the same point on a grid of this
        pitch, so shared corners become shared vertices and vertex normals can
        be computed.

    Returns
    -------
    Mesh
        Triangles that collapse to a segment or a point after merging are dropped.
    """
    pts = np.asarray(tri_mm, dtype=np.float64).reshape(-1, 3)
    key = np.round(pts / merge_tol_mm).astype(np.int64)
    order = np.lexsort(key.T[::-1])
    sorted_key = key[order]
    new = np.ones(len(order), dtype=bool)
    new[1:] = np.any(sorted_key[1:] != sorted_key[:-1], axis=1)
    group = np.cumsum(new) - 1
    inverse = np.empty(len(order), dtype=np.int64)
    inverse[order] = group
    V = pts[order[new]]
    F = inverse.reshape(-1, 3)
    keep = (F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 2] != F[:, 0])
    return Mesh(V=V, F=F[keep])


def _stl_mode(path: Path) -> Mode:
    """Binary or ASCII, checked against the file size (numpy-stl is lenient)."""
    size = path.stat().st_size
    with path.open("rb") as fh:
        head = fh.read(84)
    count = int.from_bytes(head[80:84], "little") if len(head) == 84 else -1
    if count >= 0 and size == 84 + 50 * count:
        return Mode.BINARY
    if head.lstrip().lower().startswith(b"solid"):
        return Mode.ASCII
    if size < 84:
        raise MeshError("file too short for an STL; export the part as STL", path=str(path))
    raise MeshError(f"binary STL header says {count} triangles but the file size is {size} "
                    "bytes (truncated or not an STL); export the part again", path=str(path))


def load_stl(path: str | os.PathLike, merge_tol_mm: float = 1e-6) -> Mesh:
    """Read a binary or ASCII STL file (all solids of an ASCII file).

    Parameters
    ----------
    path : str or path-like
    merge_tol_mm : float
        See :func:`mesh_from_triangles`.

    Returns
    -------
    Mesh
        Coordinates in the file's units, taken as mm.

    Raises
    ------
    MeshError
        The file is missing, unreadable, truncated, has no triangles or
        non-finite coordinates.  ``str(err)`` starts with the path.
    """
    p = Path(path)
    if not p.is_file():
        raise MeshError("no such file; check the mesh path", path=str(p))
    mode = _stl_mode(p)
    try:
        parts = list(stl_mesh.Mesh.from_multi_file(str(p), calculate_normals=False, mode=mode))
    except _STL_READ_ERRORS as exc:
        raise MeshError(f"not a readable STL file ({exc}); export the part again",
                        path=str(p)) from exc
    tri = np.concatenate([m.vectors for m in parts]) if parts else np.zeros((0, 3, 3))
    if tri.shape[0] == 0:
        raise MeshError("the STL holds no triangles; export the part again", path=str(p))
    if not np.all(np.isfinite(tri)):
        raise MeshError("the STL holds non-finite coordinates; export the part again",
                        path=str(p))
    mesh = mesh_from_triangles(tri, merge_tol_mm)
    if mesh.n_faces == 0:
        raise MeshError("every triangle of the STL is degenerate", path=str(p))
    return mesh


class EdgeLengths(NamedTuple):
    """Triangle edge lengths of a mesh, mm: compare them with the tool radius."""

    median_mm: float
    p95_mm: float
    max_mm: float


def mesh_resolution_mm(mesh: Mesh) -> EdgeLengths:
    """How coarse a mesh is: median, 95th percentile and largest edge length.

    Parameters
    ----------
    mesh : Mesh

    Returns
    -------
    EdgeLengths
        Over all triangle edges (interior edges count twice), mm.  With an edge
        length ``h`` on a surface of curvature radius ``rho`` adjacent facets
        differ by about ``h / rho`` rad; facet normals err by up to half that.
    """
    P = mesh.V[mesh.F]
    lengths = np.linalg.norm(P - np.roll(P, -1, axis=1), axis=2).ravel()
    if lengths.size == 0:
        return EdgeLengths(0.0, 0.0, 0.0)
    med, p95 = np.percentile(lengths, [50.0, 95.0])
    return EdgeLengths(float(med), float(p95), float(lengths.max()))


# ---------------------------------------------------------------- chunks and the pool


class Closest(NamedTuple):
    """Closest mesh points of query points, in query order.

    dist_mm : (m,) float64, face : (m,) int64, point_mm : (m, 3) float64
    """

    dist_mm: np.ndarray
    face: np.ndarray
    point_mm: np.ndarray


# Set only inside forked pool workers: the function and points they share.
_WORKER: tuple | None = None


def _worker_init(fn, points: np.ndarray) -> None:
    # Runs in the child; with fork the arguments are inherited, never pickled.
    global _WORKER
    _WORKER = (fn, points)


def _worker_run(bounds: tuple[int, int]) -> tuple:
    fn, points = _WORKER
    return fn(points[bounds[0] : bounds[1]])


def _fork_context():
    """The fork start method on POSIX systems that have it; None elsewhere or in a worker."""
    if _WORKER is not None or os.name != "posix":
        return None
    if "fork" not in multiprocessing.get_all_start_methods():
        return None
    return multiprocessing.get_context("fork")


def _available_cpus() -> int:
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def _unit(v: np.ndarray) -> np.ndarray:
    """Rows scaled to unit length; zero rows stay zero."""
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.divide(v, n, out=np.zeros_like(v), where=n > 0)


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", a, b)


class MeshIndex:
    """A mesh with its AABB tree and the normals the contact search needs.

    Parameters
    ----------
    mesh : Mesh
    feature_angle_deg : float
        Facets meeting at a larger angle form a sharp edge: their normals are
        not averaged, and a contact on that edge takes the CC->centre direction.
    pool_min_points : int or None
        Work on at least this many points runs chunk by chunk in a pool of
        forked processes (POSIX; serial elsewhere); None: always serial.  Both
        give identical results.  libigl's query is itself multi-threaded, so
        the pool only spreads the numpy work (see the module docstring).
    chunk_points : int
        Points per chunk: bounds the temporaries, unit of work for the pool.
    processes : int or None
        Pool size; default: the CPUs this process may use.
    corner_normals : (nf, 3, 3) float64 or None
        Normals to interpolate instead of the default ones (see below).

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
                 processes: int | None = None,
                 corner_normals: np.ndarray | None = None) -> None:
        if mesh.n_faces == 0:
            raise MeshError("the mesh has no triangles")
        self.mesh = mesh
        self.feature_angle_deg = float(feature_angle_deg)
        self.pool_min_points = pool_min_points
        self.chunk_points = max(1, int(chunk_points))
        self.processes = int(processes or _available_cpus())
        self._tree = igl.AABB()
        self._tree.init(mesh.V, mesh.F)
        P = mesh.V[mesh.F]
        self.face_normal = _unit(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]))
        self.feature_edge = self._feature_edges()
        if corner_normals is None:
            corner_normals = self._corner_normals()
        cn = np.asarray(corner_normals, dtype=np.float64).reshape(-1, 3, 3)
        bad = ~np.all(np.isfinite(cn), axis=2) | (np.linalg.norm(cn, axis=2) < 0.5)
        self.corner_normal = np.where(bad[:, :, None], self.face_normal[:, None, :], _unit(cn))

    def _feature_edges(self) -> np.ndarray:
        tt, _ = igl.triangle_triangle_adjacency(self.mesh.F)
        fn = self.face_normal
        cos_angle = np.einsum("fj,fkj->fk", fn, fn[np.maximum(tt, 0)])
        return (tt < 0) | (cos_angle < np.cos(np.radians(self.feature_angle_deg)))

    def _corner_normals(self) -> np.ndarray:
        # angle weights measured twice as accurate as area weights (module docstring)
        V, F = self.mesh.V, self.mesh.F
        cn = igl.per_vertex_normals(V, F, igl.PER_VERTEX_NORMALS_WEIGHTING_TYPE_ANGLE)[F]
        sharp = np.zeros(V.shape[0], dtype=bool)
        sharp[F[self.feature_edge]] = True
        sharp[np.roll(F, -1, axis=1)[self.feature_edge]] = True
        if np.any(sharp):
            split = igl.per_corner_normals(V, F, self.feature_angle_deg).reshape(-1, 3, 3)
            cn = np.where(sharp[F][:, :, None], split, cn)
        return cn

    def map_chunks(self, fn, points: np.ndarray) -> tuple:
        """Apply ``fn`` to consecutive chunks of ``points``; concatenate in order.

        ``fn(points[lo:hi])`` returns a tuple of arrays with one row per point.
        Large inputs run in the fork pool (``fn`` is inherited, not pickled).
        """
        P = np.ascontiguousarray(points, dtype=np.float64)
        m = P.shape[0]
        bounds = [(lo, min(lo + self.chunk_points, m)) for lo in range(0, m, self.chunk_points)]
        pool = (self.pool_min_points is not None and m >= self.pool_min_points
                and self.processes > 1 and len(bounds) > 1)
        ctx = _fork_context() if pool else None
        if ctx is None:
            parts = [fn(P[lo:hi]) for lo, hi in bounds] or [fn(P)]
        else:
            with ctx.Pool(min(self.processes, len(bounds)), _worker_init, (fn, P)) as workers:
                parts = workers.map(_worker_run, bounds, chunksize=1)
        return tuple(np.concatenate(col) for col in zip(*parts))

    def _query(self, P: np.ndarray) -> tuple:
        if P.shape[0] == 0:
            return np.zeros(0), np.zeros(0, np.int64), np.zeros((0, 3))
        sqr, face, point = self._tree.squared_distance(self.mesh.V, self.mesh.F, P)
        return np.sqrt(np.maximum(sqr, 0.0)), face.astype(np.int64), point

    def closest(self, points_mm: np.ndarray) -> Closest:
        """Closest mesh point of each query point, in chunks, in query order.

        Parameters
        ----------
        points_mm : (m, 3) float64

        Returns
        -------
        Closest
        """
        return Closest(*self.map_chunks(self._query, points_mm))


# ---------------------------------------------------------------- normals


class _Frame(NamedTuple):
    """Face frame at points: ``x = p0 + u e1 + v e2``; corner normals ``n0 + u m1 + v m2``."""

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
    P = index.mesh.V[index.mesh.F[face]]
    N = index.corner_normal[face]
    p0, e1, e2 = P[:, 0], P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]
    d = x - p0
    d00, d01, d11 = _dot(e1, e1), _dot(e1, e2), _dot(e2, e2)
    d20, d21 = _dot(d, e1), _dot(d, e2)
    with np.errstate(divide="ignore", invalid="ignore"):
        den = d00 * d11 - d01 * d01
        u, v = (d11 * d20 - d01 * d21) / den, (d00 * d21 - d01 * d20) / den
    return _Frame(p0, e1, e2, N[:, 0], N[:, 1] - N[:, 0], N[:, 2] - N[:, 0], u, v)


def _offset_newton(fr: _Frame, centre: np.ndarray, steps: int = 2) -> tuple:
    """Point ``p`` of the face plane with ``centre = p + t n(p)``, ``n`` the Phong field.

    ``n`` is linear in ``(u, v)`` on a face, so each Newton step on
    ``(u, v, t)`` is a 3x3 solve (Cramer's rule, vectorised).

    Returns
    -------
    normal : (m, 3) float64
        Unit smoothed normal at ``p``.
    bary_min : (m,) float64
        Smallest barycentric coordinate of ``p``: < 0 where ``p`` left the face.
    """
    u, v = fr.u, fr.v
    m = fr.phong(u, v)
    t = _dot(centre - (fr.p0 + u[:, None] * fr.e1 + v[:, None] * fr.e2), m) / _dot(m, m)
    for _ in range(steps):
        a, b = fr.e1 + t[:, None] * fr.m1, fr.e2 + t[:, None] * fr.m2
        rhs = centre - (fr.p0 + u[:, None] * fr.e1 + v[:, None] * fr.e2) - t[:, None] * m
        bm = np.cross(b, m)
        with np.errstate(divide="ignore", invalid="ignore"):
            det = _dot(a, bm)
            u = u + _dot(rhs, bm) / det
            v = v + _dot(a, np.cross(rhs, m)) / det
            t = t + _dot(a, np.cross(b, rhs)) / det
        m = fr.phong(u, v)
    bary_min = np.minimum(np.minimum(u, v), 1.0 - u - v)
    return _unit(m), np.where(np.isfinite(bary_min), bary_min, -np.inf)


def _on_feature_edge(index: MeshIndex, face: np.ndarray, fr: _Frame,
                     eps: float = 1e-6) -> np.ndarray:
    """The CC point lies on a sharp or boundary edge of its face (or at its ends)."""
    # edge k joins corners k and k+1: it is where the coordinate of corner k+2 vanishes
    opposite = np.stack([fr.v, 1.0 - fr.u - fr.v, fr.u], axis=1)
    return np.any((opposite <= eps) & index.feature_edge[face], axis=1)


def _clamp_cone(axis: np.ndarray, n: np.ndarray, max_rad: np.ndarray) -> np.ndarray:
    """Rotate unit rows ``n`` toward ``axis`` until within ``max_rad`` of it."""
    cos_a = np.clip(_dot(axis, n), -1.0, 1.0)
    over = np.arccos(cos_a) > max_rad
    perp = _unit(n - cos_a[:, None] * axis)
    clamped = np.cos(max_rad)[:, None] * axis + np.sin(max_rad)[:, None] * perp
    return np.where(over[:, None], clamped, n)


def _orient(normal: np.ndarray, toward: np.ndarray) -> np.ndarray:
    """Flip rows of ``normal`` that point away from ``toward``."""
    return np.where((_dot(normal, toward) < 0)[:, None], -normal, normal)


# The Newton correction may move the normal away from the Phong normal at the
# CC point by at most this many times the angle between that and the
# CC->centre direction: where a concave surface nearly fits the tool (R ~ rho)
# the solve amplifies vertex-normal errors (measured: k = 2 bounds the worst
# cases and keeps the median gain; module docstring).
_NEWTON_CONE = 2.0


def _smooth_normal(index: MeshIndex, cl: Closest, fr: _Frame, centre: np.ndarray,
                   n_center: np.ndarray) -> np.ndarray:
    """Phong-offset normal; the CC->centre direction on sharp edges or disagreement."""
    phong = _orient(_unit(fr.phong(fr.u, fr.v)), n_center)
    cone = _NEWTON_CONE * np.arccos(np.clip(_dot(phong, n_center), -1.0, 1.0))
    normal, bary_min = _offset_newton(fr, centre)
    normal = _clamp_cone(phong, _orient(normal, n_center), cone)
    left = np.flatnonzero(bary_min < -0.05)
    if left.size:
        # p left its face: restart in the face holding the closest point to p
        again = Closest(*index._query(centre[left] - normal[left] * cl.dist_mm[left, None]))
        redo = _offset_newton(_frame(index, again.face, again.point_mm), centre[left])[0]
        normal[left] = _clamp_cone(phong[left], _orient(redo, n_center[left]), cone[left])
    cos_limit = np.cos(np.radians(index.feature_angle_deg))
    use_center = (_dot(n_center, normal) < cos_limit) | ~np.all(np.isfinite(normal), axis=1)
    use_center |= _on_feature_edge(index, cl.face, fr)
    return np.where(use_center[:, None], n_center, normal)


def _contact_normal(index: MeshIndex, cl: Closest, centre: np.ndarray,
                    method: str) -> np.ndarray:
    """Unit normal at each CC point, oriented toward the tool."""
    n_center = _unit(centre - cl.point_mm)
    facet = index.face_normal[cl.face]
    # centre on the mesh (deep gouge): no direction; take the facet's, upward
    lost = ~np.any(n_center, axis=1)
    n_center[lost] = _orient(facet[lost], np.array([[0.0, 0.0, 1.0]]))
    if method == "center":
        return n_center
    if method == "facet":
        return _orient(facet, n_center)
    fr = _frame(index, cl.face, cl.point_mm)
    if method == "phong":
        phong = _orient(_unit(fr.phong(fr.u, fr.v)), n_center)
        return np.where(np.all(np.isfinite(phong), axis=1)[:, None], phong, n_center)
    return _smooth_normal(index, cl, fr, centre, n_center)


# ---------------------------------------------------------------- contacts


@dataclass(frozen=True)
class MeshContacts:
    """Contacts plus what the mesh says about the tool's clearance.

    Attributes
    ----------
    contacts : Contacts
        CC points (the closest mesh points), normals toward the tool, ``R_eff``
        from :func:`ncopt.tools.r_eff_mm`, ``cutting = gap_mm <= tol_mm``.
    gap_mm : (m,) float64
        Distance from the cutter surface to the mesh less ``stock_mm``, mm;
        negative where the cutter is inside the part.
    gouging : (m,) bool
        ``gap_mm < -tol_mm``.  Any such point suggests a wrong tool, mesh,
        tool point or stock allowance.
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


def _core_points(centers: np.ndarray, normal: np.ndarray, flat_mm: float) -> np.ndarray:
    """Torus core point facing a contact of normal ``normal``.

    The torus touches a surface on the side where it rises, i.e. at
    ``centre - (R - r) unit(n_xy)``; with ``n_xy ~ 0`` (the flat bottom
    touches) the core point is the centre itself.
    """
    nxy = normal * np.array([1.0, 1.0, 0.0])
    length = np.linalg.norm(nxy, axis=1, keepdims=True)
    return centers - flat_mm * np.divide(nxy, length, out=np.zeros_like(nxy),
                                         where=length > 1e-9)


def _torus_descend(index: MeshIndex, centers: np.ndarray, core: np.ndarray, flat_mm: float,
                   iterations: int) -> tuple[np.ndarray, Closest]:
    """Fixed-point iteration from ``core``; the best core point seen and its closest points.

    The clearance is a minimum over the core disc, so each core point visited
    bounds it from above: keep the smallest.
    """
    core = core.copy()
    best = current = Closest(*index._query(core))
    best_core = core.copy()
    active = np.arange(len(centers))
    for _ in range(iterations):
        new = _core_points(centers[active], _unit(core[active] - current.point_mm), flat_mm)
        moved = np.linalg.norm(new - core[active], axis=1) > _CORE_STEP_MM
        core[active] = new
        active = active[moved]
        if active.size == 0:
            break
        current = Closest(*index._query(core[active]))
        better = current.dist_mm < best.dist_mm[active]
        sel = active[better]
        best.dist_mm[sel], best.face[sel] = current.dist_mm[better], current.face[better]
        best.point_mm[sel], best_core[sel] = current.point_mm[better], core[sel]
    return best_core, best


_CORE_STEP_MM = 1e-3
_MIRROR = "all"


def _torus_closest(index: MeshIndex, centers: np.ndarray, flat_mm: float,
                   iterations: int) -> tuple[np.ndarray, Closest]:
    """Core-circle point nearest the mesh: descend from the centre, then from the mirror.

    Where the surface rises on both sides (a valley) the first descent may
    settle on the higher side; a second one from the opposite side of the ring
    finds the other contact.
    """
    core, cl = _torus_descend(index, centers, centers, flat_mm, iterations)
    off = np.flatnonzero(np.linalg.norm(core - centers, axis=1) > _CORE_STEP_MM)
    if _MIRROR == "none" or off.size == 0:
        return core, cl
    if _MIRROR == "near":
        probe = Closest(*index._query(2.0 * centers[off] - core[off]))
        off = off[probe.dist_mm < cl.dist_mm[off] + 0.5 * flat_mm]
    core2, cl2 = _torus_descend(index, centers[off], 2.0 * centers[off] - core[off], flat_mm,
                                iterations)
    better = cl2.dist_mm < cl.dist_mm[off]
    sel = off[better]
    core[sel], cl.dist_mm[sel], cl.face[sel] = core2[better], cl2.dist_mm[better], cl2.face[better]
    cl.point_mm[sel] = cl2.point_mm[better]
    return core, cl


def _contacts_chunk(centers: np.ndarray, index: MeshIndex, cutter: Cutter, normals: str,
                    iterations: int) -> tuple:
    """CC points, normals, distances and faces of one chunk of centres."""
    if cutter.is_ball:
        core, cl = centers, Closest(*index._query(centers))
    else:
        flat_mm = cutter.radius_mm - cutter.corner_radius_mm
        core, cl = _torus_closest(index, centers, flat_mm, iterations)
    normal = _contact_normal(index, cl, core, normals)
    return cl.point_mm, normal, cl.dist_mm, cl.face


def mesh_contacts(centers_mm: np.ndarray, mesh_index: MeshIndex, cutter: Cutter,
                  tol_mm: float = 0.05, *, stock_mm: float = 0.0, normals: str = "smooth",
                  torus_iterations: int = 8) -> MeshContacts:
    """Contacts of a ball or bull-nose cutter with a mesh, with clearances.

    Parameters
    ----------
    centers_mm : (m, 3) float64
        Ball centres (ball) or torus core-circle centres (bull-nose), mm, in
        path order: programmed points raised by ``tools.center_offset_mm``.
    mesh_index : MeshIndex
    cutter : Cutter
    tol_mm : float
        The cutter touches the part where its clearance is within this of
        ``stock_mm`` (mesh chord error + CAM tolerance), mm.
    stock_mm : float
        Allowance the program leaves on the part, mm.
    normals : {"smooth", "phong", "center", "facet"}
        Contact normal estimate (module docstring).
    torus_iterations : int
        Fixed-point iterations of the bull-nose contact search.

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
    work = functools.partial(_contacts_chunk, index=mesh_index, cutter=cutter,
                             normals=normals, iterations=torus_iterations)
    cc, normal, dist, face = mesh_index.map_chunks(work, c)
    gap = dist - cutter.corner_radius_mm - stock_mm
    contacts = Contacts(cc_mm=cc, normal=normal, r_eff_mm=tools.r_eff_mm(cutter, normal),
                        cutting=gap <= tol_mm)
    return MeshContacts(contacts=contacts, gap_mm=gap, gouging=gap < -tol_mm, face=face)


def contacts_from_mesh(centers_mm: np.ndarray, mesh_index: MeshIndex, cutter: Cutter,
                       tol_mm: float = 0.05, *, stock_mm: float = 0.0,
                       normals: str = "smooth") -> Contacts:
    """Contacts of a cutter with a mesh: :func:`mesh_contacts` without the clearances.

    Parameters
    ----------
    centers_mm : (m, 3) float64
        Ball centres or torus core-circle centres, mm.
    mesh_index : MeshIndex
    cutter : Cutter
    tol_mm, stock_mm, normals
        As for :func:`mesh_contacts`.

    Returns
    -------
    Contacts
    """
    return mesh_contacts(centers_mm, mesh_index, cutter, tol_mm, stock_mm=stock_mm,
                         normals=normals).contacts
