"""Part meshes: STL reading (binary and ASCII), vertex merging, resolution.

Split from :mod:`ncopt.contacts.geometry`, which builds the closest-point index and the
contacts on these meshes.  Lengths in mm.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ncopt.runtime.errors import MeshError
from ncopt.motion.modal import row_norms

_STL_READ_ERRORS = (ValueError, RuntimeError, AssertionError, OSError, IndexError, UnicodeError)


@dataclass(frozen=True)
class Mesh:
    """An indexed triangle mesh (libigl's names).

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

    def corners(self, face: np.ndarray) -> np.ndarray:
        """Corner positions ``(m, 3, 3)`` of the faces ``face (m,)``: ``V[F[face]]``, by
        ``np.take`` (3-4x faster than fancy indexing for 300k random faces)."""
        return np.take(self.V, np.take(self.F, face, axis=0), axis=0)


def mesh_from_triangles(tri_mm: np.ndarray, merge_tol_mm: float = 1e-6) -> Mesh:
    """Index a triangle soup, merging corners that round to the same point.

    Parameters
    ----------
    tri_mm : (nf, 3, 3) float
        Corners of each triangle, mm (STL order).
    merge_tol_mm : float
        Pitch of the rounding grid.

    Returns
    -------
    Mesh
        Shared corners are shared vertices; triangles that collapse are dropped.
        Vertices in the order of their grid points (x, then y, then z), each at
        its first corner in the file.
    """
    pts = np.asarray(tri_mm).reshape(-1, 3)
    if pts.dtype not in (np.float32, np.float64):  # the same values: compared bit for bit
        pts = pts.astype(np.float64)
    # An STL repeats each point ~6 times, bit for bit: the rounding and the sort by
    # grid point run on the distinct points only.
    order, run, first = _same_bits(pts)
    # distinct points in file order (the stable sort below then keeps the first corner of
    # each grid point first): marked in the file's rows, not sorted (no two runs share
    # their first row); by_file[r]: the place of run r's first row among them
    is_first = np.zeros(pts.shape[0], dtype=bool)
    is_first[first] = True
    by_file = np.take(np.cumsum(is_first) - 1, first)
    first = np.flatnonzero(is_first)
    del is_first
    key = np.empty((first.size, 3), dtype=np.int64)
    for c in range(3):
        key[:, c] = np.round(np.take(pts[:, c], first).astype(np.float64) / merge_tol_mm)
    by_key = np.lexsort((key[:, 2], key[:, 1], key[:, 0]))
    key = key[by_key]
    new = np.ones(len(by_key), dtype=bool)
    new[1:] = np.any(key[1:] != key[:-1], axis=1)
    del key
    vertex = np.empty(len(by_key), dtype=np.int64)  # of each distinct point, in file order
    vertex[by_key] = np.cumsum(new) - 1
    run_vertex = np.take(vertex, by_file)
    del vertex, by_file
    F = np.empty(pts.shape[0], dtype=np.int64)
    F[order] = run_vertex[run]
    F = F.reshape(-1, 3)
    del order, run, run_vertex
    keep = (F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 2] != F[:, 0])
    return Mesh(V=pts[first[by_key[new]]], F=F[keep])


# odd 64-bit multipliers (golden ratio, xxHash primes) mixing a point's 32-bit words
_MIX = np.array([0x9E3779B97F4A7C15, 0xC2B2AE3D27D4EB4F, 0x165667B19E3779F9,
                 0x27D4EB2F165667C5, 0xFF51AFD7ED558CCD, 0xC4CEB9FE1A85EC53], dtype=np.uint64)


def _same_bits(pts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rows with the same bytes: ``(order, run, first)``.

    ``order`` sorts the rows by a hash of their bytes (its high bits, then the row
    number); ``run[i]`` numbers the run of equal rows that ``order[i]`` is in,
    ``first[r]`` is the smallest row of run ``r``.  A run never holds two different
    rows; rows whose hashes collide may split a run in two (harmless to
    :func:`mesh_from_triangles`, which merges by grid point afterwards).  The rows are
    gathered whole (numpy 2.4: 0.07 s for 3M, against 0.13 s column by column), then
    compared column by column.
    """
    n = pts.shape[0]
    if n == 0:
        return (np.zeros(0, dtype=np.int64),) * 3
    words = np.ascontiguousarray(pts).view(np.uint32).reshape(n, -1)
    h = np.zeros(n, dtype=np.uint64)
    for c in range(words.shape[1]):
        h ^= words[:, c].astype(np.uint64) * _MIX[c % _MIX.size]
    # the hash's high bits with the row in the low ones, sorted: the rows in hash order
    # (an argsort of the hashes took 4x as long: 0.15 against 0.04 s for 3M rows)
    bits = np.uint64(max(1, (n - 1).bit_length()))
    h >>= bits
    h <<= bits
    h |= np.arange(n, dtype=np.uint64)
    h.sort()
    h &= (np.uint64(1) << bits) - np.uint64(1)
    order = h.view(np.int64)
    del h
    new = np.zeros(n, dtype=bool)
    new[0] = True
    rows = np.take(words, order, axis=0)
    for c in range(words.shape[1]):
        col = rows[:, c]
        new[1:] |= col[1:] != col[:-1]
    del col, rows
    run = np.cumsum(new) - 1
    return order, run, np.minimum.reduceat(order, np.flatnonzero(new))


# binary STL: an 80-byte header, a little-endian uint32 count, then 50 bytes a triangle
_STL_HEADER_BYTES, _STL_RECORD_BYTES = 84, 50


def _stl_mode(path: Path) -> str:
    """``"binary"`` or ``"ascii"``, the binary layout checked against the file size
    (numpy-stl is lenient)."""
    size = path.stat().st_size
    with path.open("rb") as fh:
        head = fh.read(_STL_HEADER_BYTES)
    count = int.from_bytes(head[80:84], "little") if len(head) == _STL_HEADER_BYTES else -1
    if count >= 0 and size == _STL_HEADER_BYTES + _STL_RECORD_BYTES * count:
        return "binary"
    if head.lstrip().lower().startswith(b"solid"):
        return "ascii"
    if size < _STL_HEADER_BYTES:
        raise MeshError("file too short for an STL; export the part as STL", path=str(path))
    raise MeshError(f"binary STL header says {count} triangles but the file has {size} "
                    "bytes (truncated or not an STL); export the part again", path=str(path))


def _stl_triangles(path: Path, mode: str) -> np.ndarray:
    """Corners ``(nf, 3, 3)`` float32 of every triangle (of every solid of an ASCII file),
    read by numpy-stl (imported when a mesh is read, ~30 ms)."""
    from stl import Mode
    from stl import mesh as stl_mesh
    parts = list(stl_mesh.Mesh.from_multi_file(
        str(path), calculate_normals=False, mode=Mode.BINARY if mode == "binary" else Mode.ASCII))
    return (parts[0].vectors if len(parts) == 1 else
            np.concatenate([m.vectors for m in parts]) if parts else np.zeros((0, 3, 3)))


def load_stl(path: str | os.PathLike, merge_tol_mm: float = 1e-6) -> Mesh:
    """Read a binary or ASCII STL file (every solid of an ASCII file).

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
        Missing, unreadable or truncated file, no triangles, non-finite
        coordinates.  ``str(err)`` starts with the path.
    """
    p = Path(path)
    if not p.is_file():
        raise MeshError("no such file; check the mesh path", path=str(p))
    mode = _stl_mode(p)
    try:
        tri = _stl_triangles(p, mode)
    except _STL_READ_ERRORS as exc:
        raise MeshError(f"not a readable STL file ({exc}); export the part again",
                        path=str(p)) from exc
    if tri.shape[0] == 0:
        raise MeshError("the STL holds no triangles; export the part again", path=str(p))
    if not np.all(np.isfinite(tri)):
        raise MeshError("the STL holds non-finite coordinates; export it again", path=str(p))
    mesh = mesh_from_triangles(tri, merge_tol_mm)
    if mesh.n_faces == 0:
        raise MeshError("every triangle of the STL is degenerate", path=str(p))
    return mesh


def spatial_order(points_mm: np.ndarray, cell_mm: float = 0.5) -> np.ndarray:
    """Indices that sort points along a Z-order (Morton) curve of ``cell_mm`` cells.

    Closest-point queries in this order run through the BVH with warm caches: the
    paper's programs put points 0.75 mm apart along passes a fraction of a mm apart,
    and in path order fcpw took 12.6-12.9 s CPU for 1M of them, in this order 7.0-8.5
    s (points 0.11 mm apart: 9.2-9.7 s either way).  Coordinates wrap every 2^21
    cells (1 km at 0.5 mm): the order stays a permutation.
    """
    if points_mm.shape[0] == 0:
        return np.zeros(0, dtype=np.int64)
    # a cell for every point, whatever its coordinates: a non-finite or huge one casts to
    # some integer (on x86-64 the same for all: 0 after the mask), and the order only
    # decides how fast the queries run (without np.nan_to_num: 0.09 -> 0.07 s at 1M)
    with np.errstate(invalid="ignore"):
        g = np.floor((points_mm - points_mm.min(axis=0)) / cell_mm).astype(np.int64)
    g &= 0x1FFFFF
    code = np.zeros(points_mm.shape[0], dtype=np.int64)
    for axis in range(3):
        x = g[:, axis]
        x = (x | (x << 32)) & 0x1F00000000FFFF
        x = (x | (x << 16)) & 0x1F0000FF0000FF
        x = (x | (x << 8)) & 0x100F00F00F00F00F
        x = (x | (x << 4)) & 0x10C30C30C30C30C3
        x = (x | (x << 2)) & 0x1249249249249249
        code |= x << axis
    return np.argsort(code, kind="stable")


_EDGE_CHUNK = 1 << 17  # faces per chunk of mesh_resolution_mm: ~10 MB of temporaries


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
        Over all triangle edges, mm.  Facets of edge ``h`` on a radius ``rho``
        differ by about ``h / rho`` rad; facet normals err by up to half that.
    """
    V, F = mesh.V, mesh.F
    lengths = np.empty((3, F.shape[0]))  # edge k from corner k to k+1, corner by corner
    for lo in range(0, F.shape[0], _EDGE_CHUNK):  # temporaries of a chunk only
        f = F[lo:lo + _EDGE_CHUNK]
        corner = [np.take(V, f[:, k], axis=0) for k in range(3)]
        for k in range(3):  # np.linalg.norm's sums
            lengths[k, lo:lo + f.shape[0]] = row_norms(corner[k] - corner[(k + 1) % 3])
    lengths = lengths.ravel()
    if lengths.size == 0:
        return EdgeLengths(0.0, 0.0, 0.0)
    med, p95 = np.percentile(lengths, [50.0, 95.0])
    return EdgeLengths(float(med), float(p95), float(lengths.max()))


# ---------------------------------------------------------------- chunks and the pool
