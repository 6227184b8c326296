"""Contacts from a mesh (ncopt.contacts.geometry): closed forms, STL reading, the pool."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import ConvexHull
from stl import Mode
from stl import mesh as stl_mesh

from ncopt.contacts import closest, geometry, rows
from ncopt.contacts import normals as mesh_normals
from ncopt.runtime.errors import MeshError
from ncopt.contacts.geometry import Mesh, MeshIndex, contacts_from_mesh, load_stl, mesh_contacts
from ncopt.model import Cutter

BALL = Cutter(diameter_mm=8.0, teeth=2)
BULL = Cutter(diameter_mm=16.0, teeth=2, corner_radius_mm=2.0)


# ---------------------------------------------------------------- test meshes


def grid_mesh(xs: np.ndarray, ys: np.ndarray, z_of_x) -> Mesh:
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    V = np.c_[X.ravel(), Y.ravel(), z_of_x(X.ravel())]
    nx, ny = len(xs), len(ys)
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1), indexing="ij")
    a = (i * ny + j).ravel()
    F = np.concatenate([np.c_[a, a + ny, a + ny + 1], np.c_[a, a + ny + 1, a + 1]])
    return Mesh(V, F)


def plane_mesh(tilt_deg: float) -> Mesh:
    """Plane through the origin, normal (sin a, 0, cos a): rises toward -X."""
    t = np.tan(np.radians(tilt_deg))
    xs = np.linspace(-20.0, 20.0, 9)
    return grid_mesh(xs, xs, lambda x: -t * x)


def plane_normal(tilt_deg: float) -> np.ndarray:
    a = np.radians(tilt_deg)
    return np.array([np.sin(a), 0.0, np.cos(a)])


def sphere_mesh(radius_mm: float, n: int) -> Mesh:
    """Closed sphere: convex hull of Fibonacci points, faces wound outward."""
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    phi = np.pi * (1.0 + 5**0.5) * k
    P = radius_mm * np.c_[np.sqrt(1 - z * z) * np.cos(phi), np.sqrt(1 - z * z) * np.sin(phi), z]
    F = ConvexHull(P).simplices.astype(np.int64)
    normal = np.cross(P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]])
    inward = (normal * P[F].mean(axis=1)).sum(axis=1) < 0
    F[inward] = F[inward][:, ::-1]
    return Mesh(P, F)


def directions(n: int, seed: int = 0, max_tilt_deg: float = 80.0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    tilt = np.radians(rng.uniform(0, max_tilt_deg, n))
    az = rng.uniform(0, 2 * np.pi, n)
    return np.c_[np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), np.cos(tilt)]


def angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.degrees(np.arccos(np.clip((a * b).sum(axis=1), -1.0, 1.0)))


@pytest.fixture(scope="module")
def sphere_index() -> MeshIndex:
    return MeshIndex(sphere_mesh(20.0, 3000))


# ---------------------------------------------------------------- closed forms


def test_ball_on_horizontal_plane_touches_at_the_tip():
    index = MeshIndex(plane_mesh(0.0))
    centres = np.array([[1.3, -2.1, 4.0], [0.0, 0.0, 4.0]])
    c = contacts_from_mesh(centres, index, BALL)
    np.testing.assert_allclose(c.normal, [[0, 0, 1]] * 2, atol=1e-12)
    np.testing.assert_allclose(c.r_eff_mm, 0.0, atol=1e-6)
    np.testing.assert_allclose(c.cc_mm, centres - [0, 0, 4.0], atol=1e-12)
    assert c.cutting.all()


@pytest.mark.parametrize("normals", geometry.NORMAL_METHODS)
def test_ball_on_45_degree_plane(normals):
    index = MeshIndex(plane_mesh(45.0))
    n = plane_normal(45.0)
    p = np.array([[2.0, 1.0, -2.0], [-3.5, 4.2, 3.5]])
    c = contacts_from_mesh(p + 4.0 * n, index, BALL, normals=normals)
    np.testing.assert_allclose(c.r_eff_mm, 4.0 / np.sqrt(2.0), rtol=1e-9)
    np.testing.assert_allclose(c.normal, [n, n], atol=1e-9)
    np.testing.assert_allclose(c.cc_mm, p, atol=1e-9)


def test_sphere_contact_normal_is_radial(sphere_index):
    u = directions(400)
    centres = (20.0 + 4.0) * u
    smooth = mesh_contacts(centres, sphere_index, BALL)
    center = mesh_contacts(centres, sphere_index, BALL, normals="center")
    # 3000 vertices on a 20 mm sphere: edges ~1.4 mm, facets ~4 deg apart
    err = angle_deg(smooth.contacts.normal, u)
    assert np.median(err) < 0.03 and np.max(err) < 0.25
    assert np.max(angle_deg(center.contacts.normal, u)) < 3.0
    assert smooth.contacts.cutting.all() and smooth.n_gouging == 0


def test_smoothing_beats_the_facets_on_a_coarse_sphere(sphere_index):
    u = directions(400, seed=1)
    centres = 28.0 * u
    err = {how: np.median(angle_deg(contacts_from_mesh(centres, sphere_index, Cutter(16.0, 2),
                                                       normals=how).normal, u))
           for how in ("facet", "center", "smooth")}
    assert err["smooth"] < 0.2 * err["center"] < err["facet"]


def test_bull_nose_on_horizontal_plane_cuts_at_the_flat_radius():
    index = MeshIndex(plane_mesh(0.0))
    centres = np.array([[1.0, 2.0, 2.0]])  # core circle 2 mm (= r) above the plane
    mc = mesh_contacts(centres, index, BULL)
    np.testing.assert_allclose(mc.contacts.r_eff_mm, 8.0 - 2.0)
    np.testing.assert_allclose(mc.contacts.cc_mm, [[1.0, 2.0, 0.0]], atol=1e-12)
    assert mc.contacts.cutting.all() and abs(mc.gap_mm[0]) < 1e-12


def test_bull_nose_on_30_degree_slope():
    index = MeshIndex(plane_mesh(30.0))
    n = plane_normal(30.0)
    p = np.array([[1.0, 0.5, -np.tan(np.radians(30.0))]])
    # contact on the rising side: core point p + r n, core centre R - r beyond it
    centres = p + 2.0 * n + 6.0 * np.array([1.0, 0.0, 0.0])
    mc = mesh_contacts(centres, index, BULL)
    np.testing.assert_allclose(mc.contacts.r_eff_mm, 6.0 + 2.0 * 0.5, rtol=1e-9)
    np.testing.assert_allclose(mc.contacts.cc_mm, p, atol=1e-9)
    np.testing.assert_allclose(mc.contacts.normal, [n], atol=1e-9)
    assert mc.contacts.cutting.all() and abs(mc.gap_mm[0]) < 1e-9


def bull_centres(p: np.ndarray, n: np.ndarray, cutter: Cutter) -> np.ndarray:
    """Core-circle centres touching at ``p`` (normal ``n``) on the side the surface rises."""
    n_xy = n * [1.0, 1.0, 0.0]
    ring = n_xy / np.maximum(np.linalg.norm(n_xy, axis=1, keepdims=True), 1e-12)
    r = cutter.corner_radius_mm
    return p + r * n + (cutter.radius_mm - r) * ring


def test_bull_nose_on_a_sphere(sphere_index):
    u = directions(300, seed=5, max_tilt_deg=70.0)
    mc = mesh_contacts(bull_centres(20.0 * u, u, BULL), sphere_index, BULL)
    expected = 6.0 + 2.0 * np.linalg.norm(u[:, :2], axis=1)
    # facets sag up to h^2 / (8 rho) ~ 0.02 mm below the sphere; near the top the
    # flat then meets the mesh up to an edge (1.4 mm, ~2 deg of tilt) away
    np.testing.assert_allclose(mc.contacts.r_eff_mm, expected, atol=0.06)
    assert np.median(np.abs(mc.contacts.r_eff_mm - expected)) < 0.005
    assert np.max(np.abs(mc.gap_mm)) < 0.03 and mc.contacts.cutting.all()


def test_bull_nose_finds_the_lowest_point_of_its_disc_on_a_saddle():
    xs = np.linspace(-30.0, 30.0, 61)
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    mesh = grid_mesh(xs, xs, lambda x: 0 * x)
    mesh = Mesh(np.c_[mesh.V[:, :2], (mesh.V[:, 0] ** 2 - mesh.V[:, 1] ** 2) / 60.0], mesh.F)
    index = MeshIndex(mesh)
    xy = np.random.default_rng(6).uniform(-12.0, 12.0, (150, 2))
    grad = xy * [1.0, -1.0] / 30.0
    n = np.c_[-grad, np.ones(len(xy))] / np.sqrt(1.0 + (grad**2).sum(1))[:, None]
    p = np.c_[xy, (xy[:, 0] ** 2 - xy[:, 1] ** 2) / 60.0]
    centres = bull_centres(p, n, BULL)
    brute = np.full(len(p), np.inf)
    for rad, step in ((0.0, 360), (2.0, 10), (4.0, 10), (6.0, 2)):
        for a in np.radians(np.arange(0, 360, step)):
            ring = centres + rad * np.array([np.cos(a), np.sin(a), 0.0])
            brute = np.minimum(brute, index.closest(ring).dist_mm - 2.0)
    gap = mesh_contacts(centres, index, BULL).gap_mm
    assert np.all(gap <= brute + 0.01)


def test_air_gouge_and_stock():
    index = MeshIndex(plane_mesh(0.0))
    centres = np.array([[0, 0, 5.0], [0, 0, 4.02], [0, 0, 3.5], [0, 0, 4.2]])
    mc = mesh_contacts(centres, index, BALL, tol_mm=0.05)
    np.testing.assert_allclose(mc.gap_mm, [1.0, 0.02, -0.5, 0.2], atol=1e-12)
    assert mc.contacts.cutting.tolist() == [False, True, True, False]
    assert mc.gouging.tolist() == [False, False, True, False]
    assert mc.n_gouging == 1
    with_stock = mesh_contacts(centres, index, BALL, tol_mm=0.05, stock_mm=0.2)
    assert with_stock.contacts.cutting.tolist() == [False, True, True, True]


def test_ball_rolling_over_a_sharp_edge_takes_the_centre_direction():
    t = np.tan(np.radians(50.0))
    index = MeshIndex(grid_mesh(np.linspace(-8, 8, 9), np.linspace(-8, 8, 9),
                                lambda x: np.where(x < 0, 0.0, -t * x)))
    phi = np.radians([5.0, 25.0, 45.0])
    n = np.c_[np.sin(phi), 0 * phi, np.cos(phi)]
    c = contacts_from_mesh(4.0 * n + [0.0, 1.5, 0.0], index, BALL)
    np.testing.assert_allclose(c.normal, n, atol=1e-9)
    np.testing.assert_allclose(c.r_eff_mm, 4.0 * np.sin(phi), atol=1e-9)


def test_inconsistent_winding_still_gives_normals_toward_the_tool():
    mesh = plane_mesh(0.0)
    F = mesh.F.copy()
    F[::2] = F[::2, ::-1]
    index = MeshIndex(Mesh(mesh.V, F))
    for how in geometry.NORMAL_METHODS:
        c = contacts_from_mesh(np.array([[0.3, 0.7, 4.0], [-5, 2, 4.0]]), index, BALL, normals=how)
        np.testing.assert_allclose(c.normal, [[0, 0, 1]] * 2, atol=1e-9)


def test_empty_and_bad_input(sphere_index):
    c = contacts_from_mesh(np.zeros((0, 3)), sphere_index, BALL)
    assert c.cc_mm.shape == (0, 3) and c.r_eff_mm.shape == (0,) and c.cutting.shape == (0,)
    with pytest.raises(ValueError, match=r"\(m, 3\)"):
        contacts_from_mesh(np.zeros((4, 2)), sphere_index, BALL)
    with pytest.raises(ValueError, match="non-finite"):
        contacts_from_mesh(np.array([[0.0, np.nan, 30.0]]), sphere_index, BALL)
    with pytest.raises(ValueError, match="normals"):
        contacts_from_mesh(np.zeros((1, 3)), sphere_index, BALL, normals="vertex")


# ---------------------------------------------------------------- chunks and the pool


def test_chunks_keep_query_order(sphere_index):
    points = 30.0 * directions(101, seed=3)
    whole = sphere_index.closest(points)
    chunked = MeshIndex(sphere_index.mesh, chunk_points=7).closest(points)
    for a, b in zip(whole, chunked):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("query_points", [1, 7, 100, 101])
def test_closest_point_calls_of_any_size_give_the_same_answers(sphere_index, query_points):
    points = 30.0 * directions(101, seed=5)
    points[13] = np.nan  # a lost point inside a call keeps its neighbours' answers
    whole = sphere_index.closest(points)
    called = MeshIndex(sphere_index.mesh, query_points=query_points,
                       chunk_points=10).closest(points)
    for a, b in zip(whole, called):
        np.testing.assert_array_equal(a, b)
    assert np.isnan(called.dist_mm[13]) and np.isfinite(np.delete(called.dist_mm, 13)).all()


def test_pool_gives_exactly_the_serial_answers(sphere_index):
    centres = 24.0 * directions(1000, seed=4)
    pooled_index = MeshIndex(sphere_index.mesh, pool_min_points=10, chunk_points=64,
                             processes=2)
    serial_index = MeshIndex(sphere_index.mesh, pool_min_points=10**9, chunk_points=64)
    for a, b in zip(pooled_index.closest(centres), serial_index.closest(centres)):
        np.testing.assert_array_equal(a, b)
    pooled = contacts_from_mesh(centres, pooled_index, BALL)
    serial = contacts_from_mesh(centres, serial_index, BALL)
    np.testing.assert_array_equal(pooled.normal, serial.normal)
    np.testing.assert_array_equal(pooled.r_eff_mm, serial.r_eff_mm)


def _newton_by_rows(fr, centre, steps=2):
    """The offset Newton written on (m, 3) rows: the reference of ``_offset_newton``."""
    dot = rows.dot
    u, v = fr.u, fr.v
    m = fr.phong(u, v)
    t = dot(centre - (fr.p0 + u[:, None] * fr.e1 + v[:, None] * fr.e2), m) / dot(m, m)
    for _ in range(steps):
        a, b = fr.e1 + t[:, None] * fr.m1, fr.e2 + t[:, None] * fr.m2
        rhs = centre - (fr.p0 + u[:, None] * fr.e1 + v[:, None] * fr.e2) - t[:, None] * m
        bm = np.cross(b, m)
        with np.errstate(divide="ignore", invalid="ignore"):
            det = dot(a, bm)
            u = u + dot(rhs, bm) / det
            v = v + dot(a, np.cross(rhs, m)) / det
            t = t + dot(a, np.cross(b, rhs)) / det
        m = fr.phong(u, v)
    bary_min = np.minimum(np.minimum(u, v), 1.0 - u - v)
    return rows.unit(m), np.where(np.isfinite(bary_min), bary_min, -np.inf)


def test_offset_newton_by_coordinates_gives_the_bits_of_rows(sphere_index):
    """The Newton steps run on coordinate arrays: the same operations in the same order
    as on (m, 3) rows, so the same bits (the rewrites' outputs depend on them)."""
    centres = 24.0 * directions(5000, seed=7, max_tilt_deg=180.0)
    centres[:50] *= 20.0 / 24.0  # next to the mesh (the sphere's facets lie inside it)
    cl = sphere_index.closest(centres)
    fr = mesh_normals.frame(sphere_index, cl.face, cl.point_mm)
    u, v = fr.u.copy(), fr.v.copy()
    u[50:60], v[60:70] = np.nan, np.inf  # a degenerate face's coordinates: NaN alike
    fr = fr._replace(u=u, v=v)
    with np.errstate(invalid="ignore"):
        got, want = mesh_normals.offset_newton(fr, centres), _newton_by_rows(fr, centres)
    assert np.isneginf(got[1][50:70]).all() and np.isfinite(got[1][:50]).all()
    for a, b in zip(got, want):
        np.testing.assert_array_equal(a, b)
    a, b = np.random.default_rng(3).normal(size=(2, 1000, 3))
    np.testing.assert_array_equal(rows.dot(a, b), (a[:, 0] * b[:, 0] + a[:, 2] * b[:, 2])
                                  + a[:, 1] * b[:, 1])


# ---------------------------------------------------------------- STL and mesh


def save_stl(mesh: Mesh, path, mode: Mode) -> None:
    m = stl_mesh.Mesh(np.zeros(mesh.F.shape[0], dtype=stl_mesh.Mesh.dtype))
    m.vectors[:] = mesh.V[mesh.F]
    m.save(str(path), mode=mode)


def test_binary_and_ascii_stl_load_the_same_mesh(tmp_path):
    mesh = grid_mesh(np.arange(5.0), np.arange(4.0), lambda x: 0.5 * x)
    save_stl(mesh, tmp_path / "part_bin.stl", Mode.BINARY)
    save_stl(mesh, tmp_path / "part_ascii.stl", Mode.ASCII)
    assert (tmp_path / "part_ascii.stl").read_bytes().startswith(b"solid")
    binary, ascii_ = load_stl(tmp_path / "part_bin.stl"), load_stl(tmp_path / "part_ascii.stl")
    assert binary.V.shape == (20, 3) and binary.F.shape == (24, 3)  # shared corners merged
    np.testing.assert_array_equal(binary.V, ascii_.V)
    np.testing.assert_array_equal(binary.F, ascii_.F)
    # the same triangles as written, up to vertex numbering
    key = lambda m: np.sort(m.V[m.F].reshape(len(m.F), -1), axis=0)  # noqa: E731
    np.testing.assert_array_equal(key(binary), key(mesh))


def test_ascii_stl_with_several_solids_loads_them_all(tmp_path):
    mesh = grid_mesh(np.arange(3.0), np.arange(3.0), lambda x: 0 * x)
    save_stl(mesh, tmp_path / "a.stl", Mode.ASCII)
    text = (tmp_path / "a.stl").read_bytes()
    lifted = text.replace(b" 0\n", b" 5\n")  # the z of every vertex line
    assert lifted != text
    (tmp_path / "two.stl").write_bytes(text + lifted)
    both = load_stl(tmp_path / "two.stl")
    assert both.F.shape == (16, 3)
    assert sorted(set(both.V[:, 2])) == [0.0, 5.0]


@pytest.mark.parametrize("content", [
    b"hello, not a mesh\n",
    b"",
    b"solid part\n  facet normal 0 0 1\n    outer loop\n      vertex 0 0 0\n      vertex 1 x 0\n",
    b"\0" * 80 + (1000).to_bytes(4, "little") + b"\0" * 120,
])
def test_bad_stl_raises_mesh_error_naming_the_file(tmp_path, content):
    path = tmp_path / "broken part.stl"
    path.write_bytes(content)
    with pytest.raises(MeshError) as err:
        load_stl(path)
    assert err.value.path == str(path)
    assert str(err.value).startswith(f"{path}: ")


def test_missing_stl_raises_mesh_error(tmp_path):
    with pytest.raises(MeshError, match="no such file"):
        load_stl(tmp_path / "nope.stl")


def test_mesh_checks_shapes_and_indices():
    with pytest.raises(ValueError, match="F refers"):
        Mesh(np.zeros((3, 3)), np.array([[0, 1, 3]]))
    with pytest.raises(ValueError, match=r"V must be"):
        Mesh(np.zeros((3, 2)), np.array([[0, 1, 2]]))


def test_mesh_resolution_of_a_unit_grid():
    res = geometry.mesh_resolution_mm(grid_mesh(np.arange(6.0), np.arange(6.0), lambda x: 0 * x))
    assert res.median_mm == pytest.approx(1.0)
    assert res.max_mm == pytest.approx(np.sqrt(2.0))
    assert 1.0 <= res.p95_mm <= np.sqrt(2.0)


def test_mesh_resolution_is_the_same_in_chunks(monkeypatch):
    # chunk by chunk (bounded temporaries) and in one go: the same lengths to the bit
    from ncopt.contacts import mesh as mesh_module
    rng = np.random.default_rng(7)
    m = grid_mesh(np.cumsum(rng.uniform(0.1, 1.0, 9)), np.cumsum(rng.uniform(0.1, 1.0, 8)),
                  lambda x: np.sin(x) * 0.3)
    monkeypatch.setattr(mesh_module, "_EDGE_CHUNK", 10**9)
    whole = geometry.mesh_resolution_mm(m)
    for chunk in (1, 7, m.n_faces - 1):
        monkeypatch.setattr(mesh_module, "_EDGE_CHUNK", chunk)
        assert geometry.mesh_resolution_mm(m) == whole


def test_a_rewrite_reports_the_mesh_median_edge(bowl_stl, tmp_path):
    # measured in the mesh's loading thread (ncopt.api)
    from ncopt import api
    from ncopt.model import Cutter, Machine
    text = Path(__file__).resolve().parents[2].joinpath("samples", "bowl.mpf").read_bytes()
    path = tmp_path / "bowl.mpf"
    path.write_bytes(text[:120_000].rsplit(b"\n", 1)[0] + b"\nM30\n")
    job = api.Job(cutter=Cutter(16.0, 2), machine=Machine(accel_rad_s2=227.0, max_rpm=15000.0))
    summary = api.rewrite_file(path, job, mesh_path=bowl_stl).summary
    expected = geometry.mesh_resolution_mm(geometry.load_stl(bowl_stl)).median_mm
    assert summary.mesh_edge_mm == expected
    assert api.rewrite_file(path, job).summary.mesh_edge_mm is None


def _merged_by_sorting_all_corners(tri: np.ndarray, tol_mm: float) -> Mesh:
    """mesh_from_triangles' contract spelled out: a vertex per grid point, in the
    order of the grid points, at the first corner on it; collapsed faces dropped."""
    pts = tri.reshape(-1, 3)
    key = np.round(pts.astype(np.float64) / tol_mm).astype(np.int64)
    order = np.lexsort((key[:, 2], key[:, 1], key[:, 0]))  # stable: file order on ties
    new = np.ones(len(order), dtype=bool)
    new[1:] = np.any(key[order][1:] != key[order][:-1], axis=1)
    vertex = np.empty(len(order), dtype=np.int64)
    vertex[order] = np.cumsum(new) - 1
    F = vertex.reshape(-1, 3)
    keep = (F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 2] != F[:, 0])
    return Mesh(pts[order[new]], F[keep])


@settings(max_examples=60)
@given(corner=st.lists(st.integers(0, 7), min_size=0, max_size=60),
       jitter=st.lists(st.sampled_from([0.0, -0.0, 1e-7, 4e-7, 5e-7, -5e-7]), min_size=3,
                       max_size=3),
       pitch=st.sampled_from([1e-7, 5e-7, 1e-6, 1.0]), seed=st.integers(0, 3),
       dtype=st.sampled_from([np.float32, np.float64]))
def test_corners_merge_by_grid_point_in_key_order(corner, jitter, pitch, seed, dtype):
    """Bit-equal corners grouped first, then grid points: the same mesh as sorting
    every corner, for corners equal, nearly equal, on either side of a grid line
    and +-0."""
    base = np.random.default_rng(seed).integers(-3, 3, size=(8, 3)) * pitch
    n = len(corner) // 3 * 3
    pts = base[corner[:n]] + np.resize(np.array(jitter), (n, 3)) * (np.arange(n) % 2)[:, None]
    tri = pts.astype(dtype).reshape(-1, 3, 3)
    ours, expected = geometry.mesh_from_triangles(tri), _merged_by_sorting_all_corners(tri, 1e-6)
    assert ours.V.tobytes() == expected.V.tobytes()
    np.testing.assert_array_equal(ours.F, expected.F)


def test_corners_merge_the_same_when_every_hash_collides(monkeypatch):
    """Equal hashes for all rows (each run then split wherever equal corners are not
    neighbours in file order): the same mesh as sorting every corner."""
    import ncopt.contacts.mesh
    rng = np.random.default_rng(7)
    tri = (rng.integers(0, 4, size=(300, 3, 3)) * 0.5).astype(np.float32)
    expected = _merged_by_sorting_all_corners(tri, 1e-6)
    monkeypatch.setattr(ncopt.contacts.mesh, "_MIX", np.zeros(6, dtype=np.uint64))
    order, run, first = ncopt.contacts.mesh._same_bits(tri.reshape(-1, 3))
    assert np.array_equal(order, np.arange(900)) and run[-1] + 1 > 64  # split: > 4^3 points
    ours = geometry.mesh_from_triangles(tri)
    assert ours.V.tobytes() == expected.V.tobytes()
    np.testing.assert_array_equal(ours.F, expected.F)


def test_corner_normals_at_sharp_vertices_are_libigls_split_normals():
    """Only the faces around a sharp vertex go to igl.per_corner_normals: their
    corners get exactly the normals of the call on the whole mesh."""
    import igl

    # a roof (ridge at 60 deg: sharp) on a gently curved, smooth skirt
    mesh = grid_mesh(np.linspace(-4, 4, 17), np.linspace(-3, 3, 7),
                     lambda x: 2.0 - 1.2 * np.abs(x) + 0.02 * x * x)
    index = MeshIndex(mesh)
    whole = igl.per_corner_normals(mesh.V, mesh.F, index.feature_angle_deg).reshape(-1, 3, 3)
    sharp = np.zeros(mesh.V.shape[0], dtype=bool)
    sharp[mesh.F[index.feature_edge]] = True
    assert 0 < sharp.sum() < mesh.V.shape[0]
    at = sharp[mesh.F]
    expected = whole[at] / np.linalg.norm(whole[at], axis=1)[:, None]
    assert index.corner_normal[at].tobytes() == expected.tobytes()
    smooth = igl.per_vertex_normals(mesh.V, mesh.F, igl.PER_VERTEX_NORMALS_WEIGHTING_TYPE_ANGLE)
    np.testing.assert_allclose(index.corner_normal[~at], smooth[mesh.F][~at], atol=1e-15)


def test_unusable_corner_normals_fall_back_to_the_facet():
    mesh = plane_mesh(30.0)
    given = np.tile(np.array([0.0, 0.0, 2.0]), (mesh.n_faces, 3, 1))
    given[0, 0], given[1, 1], given[2, 2] = [np.inf, 0.0, 0.0], np.nan, [0.3, 0.0, 0.0]
    index = MeshIndex(mesh, corner_normals=given)
    np.testing.assert_array_equal(index.corner_normal[[0, 1, 2], [0, 1, 2]],
                                  index.face_normal[[0, 1, 2]])
    keep = np.ones((mesh.n_faces, 3), dtype=bool)
    keep[[0, 1, 2], [0, 1, 2]] = False
    np.testing.assert_array_equal(index.corner_normal[keep], np.tile([0.0, 0.0, 1.0], (keep.sum(), 1)))


# ---------------------------------------------------------------- closest points against libigl


def test_closest_point_on_triangles_matches_libigl_exactly():
    """Every Voronoi region (corners, edges, interior), on random triangles, against
    libigl's own point-triangle distance."""
    import igl

    rng = np.random.default_rng(11)
    tri = rng.normal(size=(400, 3, 3))
    p = 2.0 * rng.normal(size=(400, 3))
    ours = closest.closest_on_triangles(p, tri)
    for i in range(tri.shape[0]):
        _, _, theirs = igl.point_mesh_squared_distance(p[i:i + 1], tri[i], np.array([[0, 1, 2]]))
        np.testing.assert_allclose(ours[i], theirs[0], atol=1e-12)


def test_closest_matches_brute_force_distance(sphere_index):
    """The BVH's face and the float64 point on it give libigl's exact distances, near
    the surface (ball centres) and far from it."""
    import igl

    rng = np.random.default_rng(5)
    points = np.concatenate([24.0 * directions(500, seed=6), rng.uniform(-80, 80, (500, 3))])
    got = sphere_index.closest(points)
    sq, _, _ = igl.point_mesh_squared_distance(points, sphere_index.mesh.V, sphere_index.mesh.F)
    np.testing.assert_allclose(got.dist_mm, np.sqrt(sq), atol=1e-5)
    on_face = closest.closest_on_triangles(points, sphere_index.mesh.V[sphere_index.mesh.F[got.face]])
    np.testing.assert_array_equal(on_face, got.point_mm)
    np.testing.assert_allclose(np.linalg.norm(points - got.point_mm, axis=1), got.dist_mm)


def test_a_triangle_with_two_equal_corners_gives_the_closest_point_of_its_edge():
    tri = np.array([[[0.0, 0, 0], [0.0, 0, 0], [10.0, 0, 0]]])
    p = np.array([[5.0, 1.0, 0.0]])
    np.testing.assert_allclose(closest.closest_on_triangles(p, tri), [[5.0, 0.0, 0.0]])


def test_a_non_finite_query_point_has_no_closest_point(sphere_index):
    got = sphere_index.closest(np.array([[np.nan, 0.0, 30.0], [0.0, 0.0, 30.0]]))
    assert np.isnan(got.dist_mm[0]) and np.all(np.isnan(got.point_mm[0]))
    assert np.isfinite(got.dist_mm[1])


def test_map_in_threads_keeps_order_and_runs_serially_when_asked():
    from ncopt.runtime.threads import map_in_threads

    assert map_in_threads(lambda x: x * x, range(20), 4) == [x * x for x in range(20)]
    assert map_in_threads(lambda x: x, [], 4) == []
    seen = []
    map_in_threads(seen.append, range(5), 1)
    assert seen == list(range(5))  # one thread: in order, in this thread
