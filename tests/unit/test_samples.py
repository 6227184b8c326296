"""Tests of the sample-data generators: samples/make_bowl.py and bench/make_case.py."""

import importlib.util
import re
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
R = 8.0  # D16 ball of the paper's machining test


def _load(rel, name):
    spec = importlib.util.spec_from_file_location(name, ROOT / rel)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def mb():
    return _load("samples/make_bowl.py", "make_bowl_under_test")


@pytest.fixture(scope="module")
def rng():
    return np.random.default_rng(20230901)


def _random_xy(rng, n, half=93.0):
    """Random tool positions plus the special places: axis, flat bottom, wall, rim, land."""
    xy = rng.uniform(-half, half, size=(n, 2))
    special = np.array([[0.0, 0.0], [1e-9, 0.0], [0.3, -0.2], [42.5, 0.0], [75.6, 0.0],
                        [0.0, -80.0], [84.0, 0.0], [85.0, 0.0], [86.0, 0.0], [60.0, 60.0],
                        [-93.0, 93.0], [77.0, 3.0]])
    return np.vstack((special, xy))


# ------------------------------------------------------------------------- surface ----
def test_profile_shape(mb):
    r = np.linspace(0.0, 95.0, 190001)
    f = mb.bowl_profile_z_mm(r)
    slope_deg = np.degrees(np.arctan(np.abs(mb.bowl_profile_slope(r))))
    assert 20.0 <= -f.min() <= 30.0
    assert f[0] == f.min()  # deepest on the axis
    assert np.all(np.diff(f) >= 0.0)  # monotone wall, no bumps
    assert slope_deg.max() >= 55.0
    assert 70.0 <= r[slope_deg.argmax()] <= 85.0  # steep near the rim
    assert slope_deg[r <= 42.5].max() < 5.0  # flat over the central half of the diameter
    land = r >= 85.0
    assert np.all(f[land] == 0.0) and np.all(slope_deg[land] == 0.0)
    assert np.all(mb.bowl_profile_curvature_per_mm(r[land]) == 0.0)
    assert np.all(f <= 0.0)


def test_profile_is_c2(mb):
    # value, slope and curvature continuous at the rim and the derivatives consistent
    for rr in (mb.RIM_RADIUS_MM, 0.0):
        a = np.array([rr - 1e-6, rr + 1e-6])
        assert abs(np.diff(mb.bowl_profile_z_mm(a))[0]) < 1e-9
        assert abs(np.diff(mb.bowl_profile_slope(a))[0]) < 1e-6
        assert abs(np.diff(mb.bowl_profile_curvature_per_mm(a))[0]) < 1e-5
    r = np.linspace(0.0, 95.0, 38001)
    h = r[1] - r[0]
    f = mb.bowl_profile_z_mm(r)
    fp = mb.bowl_profile_slope(r)
    fpp = mb.bowl_profile_curvature_per_mm(r)
    np.testing.assert_allclose((f[2:] - f[:-2]) / (2 * h), fp[1:-1], atol=1e-5)
    # (f''' jumps at the rim, so the central difference of f' is off by ~h there)
    np.testing.assert_allclose((fp[2:] - fp[:-2]) / (2 * h), fpp[1:-1], atol=1e-3)
    away = np.abs(r[1:-1] - mb.RIM_RADIUS_MM) > 0.01
    assert np.abs((fp[2:] - fp[:-2]) / (2 * h) - fpp[1:-1])[away].max() < 1e-5
    # one contact point for the D16 ball: concave radius of curvature > R everywhere
    kappa = fpp / (1.0 + fp**2) ** 1.5
    assert 1.0 / kappa.max() > 2 * R


def test_normal_matches_finite_differences(mb, rng):
    xy = _random_xy(rng, 500)
    x, y = xy[:, 0], xy[:, 1]
    h = 1e-5
    dzdx = (mb.bowl_z_mm(x + h, y) - mb.bowl_z_mm(x - h, y)) / (2 * h)
    dzdy = (mb.bowl_z_mm(x, y + h) - mb.bowl_z_mm(x, y - h)) / (2 * h)
    fd = np.column_stack((-dzdx, -dzdy, np.ones_like(x)))
    fd /= np.linalg.norm(fd, axis=1, keepdims=True)
    n = mb.bowl_normal(x, y)
    assert n.shape == (len(x), 3)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(n, fd, atol=1e-7)
    assert np.all(n[:, 2] > 0.3)  # up, out of the material
    # radial symmetry: the normal leans away from the axis on the wall
    wall = np.hypot(x, y) < 85.0
    assert np.all(n[wall, 0] * x[wall] + n[wall, 1] * y[wall] <= 1e-15)


# ------------------------------------------------------------------- drop-cutter ----
def test_drop_matches_dense_meridian_max(mb, rng):
    xy = _random_xy(rng, 300)
    tip = mb.drop_ball_tip_z_mm(xy[:, 0], xy[:, 1], R)
    assert tip.shape == (len(xy),)
    r = np.hypot(xy[:, 0], xy[:, 1])
    t = np.linspace(-R, R, 40001)
    ball = np.sqrt(np.maximum(R * R - t * t, 0.0))
    ref = (mb.bowl_profile_z_mm(r[:, None] + t[None, :]) + ball).max(axis=1) - R
    # never below a sampled lower bound (no gouging), and the samples get within 1e-5 of it
    assert np.all(tip >= ref - 1e-9)
    assert np.all(tip - ref < 1e-5)
    # flat land: the tip sits on it; bottom of the bowl: on the surface at the axis
    assert mb.drop_ball_tip_z_mm(90.0, 0.0, R) == 0.0
    assert mb.drop_ball_tip_z_mm(0.0, 0.0, R) == pytest.approx(-mb.DEPTH_MM, abs=1e-12)


def test_drop_ball_touches_and_never_gouges(mb, rng):
    xy = _random_xy(rng, 300)
    x, y = xy[:, 0], xy[:, 1]
    tip, contact, normal = mb.drop_ball_contact(x, y, R)
    np.testing.assert_array_equal(tip, mb.drop_ball_tip_z_mm(x, y, R))
    centre = np.column_stack((x, y, tip + R))
    # the contact lies on the surface, at distance R from the centre, along the normal
    np.testing.assert_allclose(contact[:, 2], mb.bowl_z_mm(contact[:, 0], contact[:, 1]), atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(centre - contact, axis=1), R, atol=1e-6)
    np.testing.assert_allclose(normal, mb.bowl_normal(contact[:, 0], contact[:, 1]), atol=1e-12)
    np.testing.assert_allclose(centre - R * normal, contact, atol=1e-6)
    # dense polar sampling of the surface under the ball: no point closer than R
    rho = np.sqrt(np.linspace(0.0, 1.0, 161))[None, :, None] * R
    ang = np.linspace(0.0, 2 * np.pi, 241)[None, None, :]
    for c in np.array_split(np.arange(len(x)), 6):
        px = x[c, None, None] + rho * np.cos(ang)
        py = y[c, None, None] + rho * np.sin(ang)
        d2 = (px - x[c, None, None]) ** 2 + (py - y[c, None, None]) ** 2
        d2 += (mb.bowl_z_mm(px, py) - (tip[c] + R)[:, None, None]) ** 2
        assert np.sqrt(d2.min(axis=(1, 2))).min() >= R - 1e-9
    # fine local sampling around the contact: the minimum distance is R (it touches)
    g = np.linspace(-0.02, 0.02, 41)
    px = contact[:, 0, None, None] + g[None, :, None]
    py = contact[:, 1, None, None] + g[None, None, :]
    d = np.sqrt((px - x[:, None, None]) ** 2 + (py - y[:, None, None]) ** 2
                + (mb.bowl_z_mm(px, py) - centre[:, 2, None, None]) ** 2).min(axis=(1, 2))
    assert np.all(d >= R - 1e-9)
    assert np.all(d <= R + 1e-4)


def test_drop_broadcasts_and_chunks(mb):
    x = np.linspace(-90.0, 90.0, 70001)  # more than one internal chunk
    tip = mb.drop_ball_tip_z_mm(x, 0.0, R)
    np.testing.assert_allclose(tip, tip[::-1], atol=1e-9)  # symmetric about the axis
    grid = mb.drop_ball_tip_z_mm(np.array([[0.0], [50.0]]), np.array([0.0, 30.0]), R)
    assert grid.shape == (2, 2)
    assert grid[1, 0] == pytest.approx(mb.drop_ball_tip_z_mm(50.0, 0.0, R))


# --------------------------------------------------------------------------- mesh ----
def test_mesh_vertices_on_surface(mb):
    V, F = mb.bowl_mesh(5.0)
    n = 38  # 190 mm / 5 mm
    assert V.dtype == np.float64 and F.dtype == np.int64
    assert V.shape == ((n + 1) ** 2, 3) and F.shape == (2 * n * n, 3)
    assert np.abs(V[:, :2]).max() == pytest.approx(mb.HALF_WIDTH_MM)
    np.testing.assert_array_equal(V[:, 2], mb.bowl_z_mm(V[:, 0], V[:, 1]))
    tri = V[F]
    nz = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])[:, 2]
    assert np.all(nz > 0.0)  # counter-clockwise from above: facet normals point up
    assert np.unique(np.sort(F, axis=1), axis=0).shape[0] == len(F)


def test_write_stl_is_deterministic(mb, tmp_path):
    from stl import mesh as stl_mesh

    V, F = mb.bowl_mesh(10.0)
    a, b = tmp_path / "a.stl", tmp_path / "b.stl"
    assert mb.write_stl(a, V, F) == 84 + 50 * len(F)
    mb.write_stl(b, V, F)
    assert a.read_bytes() == b.read_bytes()
    m = stl_mesh.Mesh.from_file(str(a))
    np.testing.assert_allclose(m.vectors, V[F], atol=1e-4)


def test_sample_stl(mb):
    from stl import mesh as stl_mesh

    path = ROOT / "samples" / "bowl.stl"
    assert path.stat().st_size <= 6_000_000
    m = stl_mesh.Mesh.from_file(str(path), calculate_normals=False)
    n = int(round(2 * mb.HALF_WIDTH_MM / mb.SAMPLE_MESH_STEP_MM))
    assert len(m.vectors) == 2 * n * n == 113288
    assert path.stat().st_size == 84 + 50 * len(m.vectors)
    v = m.vectors.reshape(-1, 3).astype(np.float64)
    np.testing.assert_allclose(v[:, 2], mb.bowl_z_mm(v[:, 0], v[:, 1]), atol=1e-4)
    assert np.all(m.normals[:, 2] > 0.0)
    np.testing.assert_allclose(np.linalg.norm(m.normals, axis=1), 1.0, atol=1e-6)


# ------------------------------------------------------------------------ program ----
def _parse(text):
    """Blocks as (N, words dict, modal X Y Z after the block)."""
    pos = {"X": None, "Y": None, "Z": None}
    out = []
    for line in text.splitlines():
        if line.startswith(";"):
            continue
        words = dict(re.findall(r"([A-Z])(-?\d+(?:\.\d+)?)", line))
        for k in "XYZ":
            if k in words:
                pos[k] = float(words[k])
        out.append((line, words, tuple(pos.values())))
    return out


@pytest.fixture(scope="module")
def sample_text():
    return (ROOT / "samples" / "bowl.mpf").read_text(encoding="ascii")


def test_sample_program_is_deterministic(mb, sample_text):
    assert mb.make_program() == sample_text


def test_sample_program_format(mb, sample_text):
    lines = sample_text.splitlines()
    assert lines[0].startswith(";")
    blocks = _parse(sample_text)
    nums = [int(w["N"]) for _, w, _ in blocks]
    assert nums[0] == 100 and np.all(np.diff(nums) == 2)
    assert [b[0] for b in blocks[:3]] == ["N100 T04 D01", "N102 G55", "N104 S1393 M03"]
    assert blocks[3][0].startswith("N106 G0 X") and "Z15.000" in blocks[3][0]
    assert [b[0].split(" ", 1)[1] for b in blocks[-3:]] == ["M09", "M05", "M30"]
    assert blocks[-4][0].split(" ", 1)[1].startswith("G0 Z")
    g1 = [line for line, _, _ in blocks if " G1 " in line]
    assert len(g1) == 1 and g1[0].endswith("F279")
    assert sum(" F" in line for line, _, _ in blocks) == 1
    for line, _, _ in blocks:
        for value in re.findall(r"[XYZ](-?[\d.]+)", line):
            assert re.fullmatch(r"-?\d+\.\d{3}", value), line
        assert "  " not in line and not line.endswith(" ")
    # the cutting points: one per block after the approach, up to the retract
    cut = blocks[6:-4]
    pts = np.array([p for _, _, p in cut])
    assert len(blocks) == 6 + len(pts) + 4
    assert 20_000 < len(blocks) < 30_000
    # tool-tip heights from the exact drop-cutter, within the 3-decimal rounding of X, Y, Z
    zt = mb.drop_ball_tip_z_mm(pts[:, 0], pts[:, 1], R)
    dzdx = mb.drop_ball_tip_z_mm(pts[:, 0] + 1e-4, pts[:, 1], R) - zt
    dzdy = mb.drop_ball_tip_z_mm(pts[:, 0], pts[:, 1] + 1e-4, R) - zt
    grad = np.hypot(dzdx, dzdy) / 1e-4
    assert np.all(np.abs(pts[:, 2] - zt) <= 5e-4 + 5e-4 * np.sqrt(2) * grad + 1e-9)
    # zig-zag: constant Y along a pass, 1.6 mm stepover, alternating X direction
    ys, starts = np.unique(pts[:, 1], return_index=True)
    np.testing.assert_allclose(np.diff(ys), 1.6, atol=1.5e-3)
    assert ys[0] == pytest.approx(-ys[-1]) and ys[-1] > mb.RIM_RADIUS_MM
    order = np.argsort(starts)
    bounds = list(np.sort(starts)) + [len(pts)]
    for k, (lo, hi) in enumerate(zip(bounds[:-1], bounds[1:])):
        dx = np.diff(pts[lo:hi, 0])
        assert np.all(dx > 0) if k % 2 == 0 else np.all(dx < 0)
        seg = np.linalg.norm(np.diff(pts[lo:hi], axis=0), axis=1)
        assert seg.max() <= 0.75 + 2e-3 and seg.min() >= 0.5
        assert pts[lo, 2] == 0.0 and pts[hi - 1, 2] == 0.0  # passes start and end on the land
    assert np.all(np.diff(ys[order]) > 0)  # passes in order of increasing Y
    # the passes cover the bowl rim to rim
    assert pts[:, 0].min() < -mb.RIM_RADIUS_MM and pts[:, 0].max() > mb.RIM_RADIUS_MM


def test_make_program_scales(mb):
    text = mb.make_program(stepover_mm=8.0, step_mm=2.0, rpm=2000, feed=400)
    blocks = _parse(text)
    assert "N104 S2000 M03" in text and " G1 Z3.000 F400" in text
    layout = mb.toolpath_layout(R, 8.0, 2.0)
    assert len(blocks) == mb.count_blocks(layout)


def test_bench_case_small(tmp_path):
    mc = _load("bench/make_case.py", "make_case_under_test")
    info = mc.make_case(tmp_path, n_blocks=30_000, n_triangles=20_000)
    assert abs(info["blocks"] - 30_000) / 30_000 < 0.02
    assert abs(info["triangles"] - 20_000) / 20_000 < 0.02
    text = Path(info["mpf"]).read_text(encoding="ascii")
    assert sum(line.startswith("N") for line in text.splitlines()) == info["blocks"]
    assert Path(info["stl"]).stat().st_size == 84 + 50 * info["triangles"]
