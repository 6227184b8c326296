"""Benchmarks and accuracy study for ``ncopt.contacts.geometry``.

    python bench/bench_geometry.py speed     # 1M-triangle mesh, 1M ball centres
    python bench/bench_geometry.py normals   # contact-normal error vs mesh size
    python bench/bench_geometry.py bullnose  # bull-nose clearance vs brute force
    python bench/bench_geometry.py load [--stl PATH] [--rounds N]  # the mesh thread, step by step

``speed`` prints seconds for: building a grid mesh, writing and loading it as
a binary STL, the closest-point BVH, the MeshIndex (tree + normals + sharp edges),
closest-point queries and normals serial vs thread pool, the full contact search, and the
peak resident memory of this process and of its pool children.

``load`` times what ``api.rewrite_file``'s mesh thread does, step by step, on an STL
(default: the 1M-triangle mesh of ``bench/bench_rewrite.py``, generated there if
missing): read + merge vertices, the fcpw BVH alone, the MeshIndex (BVH, normals,
sharp edges), the edge lengths; then the closest points of 1M ball centres 8 mm
above its surface.  Median and minimum over ``--rounds`` of wall and CPU seconds:
run it on two checkouts, alternating, to compare them on a busy machine.

``normals`` meshes analytic surfaces at several edge lengths (jittered
parameter grids, vertices exactly on the surface), puts ball centres at
distance R along the analytic normal, and compares the contact normal of each
method with the analytic one: angle error (median, 95th percentile, max, in
degrees) and the vc overshoot it would cause, ``R_eff,true / R_eff,est - 1``
(95th percentile and max, %, over contacts with ``R_eff,true >= 0.2 R``).

``bullnose`` places a D8 r1 bull-nose in contact with a curved surface along
the analytic normal and compares the clearance found by the contact search
with a brute-force minimum over the core disc (ring every 2 deg, inner
circles every 10 deg); it also checks ``R_eff`` against the analytic value.
Then a D16 r2 over egg-crates (several bumps under the flat: the hard case)
at random heights near contact: clearance misses and misclassified points.
"""

from __future__ import annotations

import argparse
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from ncopt.contacts import closest, geometry  # noqa: E402
from ncopt.contacts import cutters
from ncopt.model import Cutter  # noqa: E402

# ---------------------------------------------------------------- meshing


def grid_faces(ns: int, nt: int) -> np.ndarray:
    """Two triangles per cell of an ``ns x nt`` vertex grid (row-major), CCW from +Z."""
    i, j = np.meshgrid(np.arange(ns - 1), np.arange(nt - 1), indexing="ij")
    a = (i * nt + j).ravel()
    b, c, d = a + nt, a + nt + 1, a + 1
    return np.concatenate([np.c_[a, b, c], np.c_[a, c, d]]).astype(np.int64)


def param_grid(s_range, t_range, h, rng, jitter=0.2):
    """Jittered parameter grid of pitch ``h`` (edges stay on the boundary)."""
    s = np.linspace(*s_range, max(2, int(round((s_range[1] - s_range[0]) / h)) + 1))
    t = np.linspace(*t_range, max(2, int(round((t_range[1] - t_range[0]) / h)) + 1))
    S, T = np.meshgrid(s, t, indexing="ij")
    S[1:-1, 1:-1] += rng.uniform(-jitter, jitter, S[1:-1, 1:-1].shape) * (s[1] - s[0])
    T[1:-1, 1:-1] += rng.uniform(-jitter, jitter, T[1:-1, 1:-1].shape) * (t[1] - t[0])
    return S, T


# ---------------------------------------------------------------- analytic surfaces
# each: (name, R_mm, surface(s, t) -> (xyz, normal), s_range, t_range, sample s_range, t_range)


def sphere_cap(rho, concave):
    def surf(x, y):
        w = np.sqrt(rho**2 - x**2 - y**2)
        z = rho - w if concave else w
        n = np.stack([x, y, -w if concave else w], -1) * (-1 if concave else 1) / rho
        return np.stack([x, y, z], -1), n
    return surf


def fillet(rho, concave):
    def surf(s, y):
        th = np.clip(s / rho, 0.0, None)
        x = np.where(s < 0, s, rho * np.sin(th))
        z = np.where(s < 0, 0.0, (rho - rho * np.cos(th)) * (1 if concave else -1))
        n = np.stack([np.sin(th) * (-1 if concave else 1), 0 * s, np.cos(th)], -1)
        return np.stack([x, y, z], -1), n
    return surf


def gauss_bump(a_mm, s_mm):
    def surf(x, y):
        z = a_mm * np.exp(-(x**2 + y**2) / s_mm**2)
        gx, gy = -2 * x / s_mm**2 * z, -2 * y / s_mm**2 * z
        n = np.stack([-gx, -gy, np.ones_like(z)], -1)
        return np.stack([x, y, z], -1), n / np.linalg.norm(n, axis=-1, keepdims=True)
    return surf


def chamfer_edge(angle_deg):
    """Flat top (x < 0) meeting a slope going down at ``angle_deg``: a sharp edge."""
    t = np.tan(np.radians(angle_deg))

    def surf(x, y):
        z = np.where(x < 0, 0.0, -t * x)
        n = np.where((x < 0)[..., None], [0.0, 0.0, 1.0],
                     [np.sin(np.radians(angle_deg)), 0.0, np.cos(np.radians(angle_deg))])
        return np.stack([x, y, z], -1), n * np.ones_like(x)[..., None]
    return surf


CASES = [
    ("convex sphere rho 20, R 4", 4.0, sphere_cap(20, False), (-13, 13), (-13, 13), 12.0),
    ("convex sphere rho 20, R 8", 8.0, sphere_cap(20, False), (-13, 13), (-13, 13), 12.0),
    ("concave bowl rho 50, R 8", 8.0, sphere_cap(50, True), (-32, 32), (-32, 32), 28.0),
    ("concave fillet rho 5, R 4", 4.0, fillet(5, True), (-6, 6.5), (-10, 10), None),
    ("convex fillet rho 5, R 8", 8.0, fillet(5, False), (-6, 6.5), (-10, 10), None),
    ("gauss bump A 8 s 12, R 4", 4.0, gauss_bump(8, 12), (-25, 25), (-25, 25), 18.0),
]


def sample_contacts(case, n, rng):
    """True contact points and normals inside the meshed region, away from its border."""
    _, R, surf, sr, tr, disc = case
    if disc is None:  # fillets: s from the flat into the arc up to 70 deg
        s = rng.uniform(-2.0, 5.0 * np.radians(70.0), n)
        t = rng.uniform(tr[0] + 3, tr[1] - 3, n)
    else:
        r = disc * np.sqrt(rng.uniform(0, 1, n))
        a = rng.uniform(0, 2 * np.pi, n)
        s, t = r * np.cos(a), r * np.sin(a)
    return surf(s, t)


def chamfer_contacts(R, angle_deg, n, rng):
    """Centres over the top, over the slope and rolling over the edge (true n known)."""
    phi = np.radians(rng.uniform(-10.0, angle_deg + 10.0, n))
    phi_c = np.clip(phi, 0.0, np.radians(angle_deg))
    n_true = np.stack([np.sin(phi_c), 0 * phi, np.cos(phi_c)], -1)
    # distance along the face from the edge for the off-edge ones
    off = np.where(phi < 0, phi, np.where(phi > phi_c, phi - phi_c, 0.0)) * 10.0
    p = np.stack([np.where(phi < 0, off, off * np.cos(phi_c)), rng.uniform(-5, 5, n),
                  np.where(phi > phi_c, -off * np.sin(phi_c), 0.0)], -1)
    return p, n_true, p + R * n_true


# ---------------------------------------------------------------- normal study


def angle_deg(a, b):
    return np.degrees(np.arccos(np.clip((a * b).sum(1), -1.0, 1.0)))


def error_stats(n_est, n_true, R):
    ang = angle_deg(n_est, n_true)
    cutter = Cutter(2 * R, 2)
    r_true, r_est = cutters.r_eff_mm(cutter, n_true), cutters.r_eff_mm(cutter, n_est)
    keep = r_true >= 0.2 * R
    with np.errstate(divide="ignore"):
        over = 100.0 * (r_true[keep] / r_est[keep] - 1.0)
    return (np.median(ang), np.percentile(ang, 95), ang.max(),
            np.percentile(over, 95), over.max())


def methods_for(mesh):
    """(label, MeshIndex, normals) variants compared for one mesh."""
    import igl

    base = geometry.MeshIndex(mesh)
    area = igl.per_corner_normals(mesh.V, mesh.F, base.feature_angle_deg)
    by_area = geometry.MeshIndex(mesh, corner_normals=area)
    no_feat = geometry.MeshIndex(mesh, feature_angle_deg=180.0)
    return [("facet", base, "facet"), ("center", base, "center"),
            ("phong", base, "phong"), ("smooth", base, "smooth"),
            ("smooth area-wt", by_area, "smooth"), ("smooth no-sharp", no_feat, "smooth")]


def study_case(label, R, mesh, centres, n_true, blend=True):
    cutter = Cutter(2 * R, 2)
    rows, got = [], {}
    for name, index, how in methods_for(mesh):
        mc = geometry.mesh_contacts(centres, index, cutter, normals=how)
        got[name] = mc.contacts.normal
        rows.append((name, *error_stats(mc.contacts.normal, n_true, R)))
    if blend:
        half = got["center"] + got["phong"]
        half /= np.linalg.norm(half, axis=1, keepdims=True)
        rows.append(("blend 50/50", *error_stats(half, n_true, R)))
    return rows


def run_normals(n_points: int, sizes: list[float]) -> None:
    rng = np.random.default_rng(7)
    print("angle error deg: median / p95 / max;  vc overshoot %: p95 / max (R_eff >= 0.2 R)")
    for case in CASES:
        for h in sizes:
            S, T = param_grid(case[3], case[4], h, rng)
            xyz, _ = case[2](S, T)
            mesh = geometry.Mesh(xyz.reshape(-1, 3), grid_faces(*S.shape))
            p, n_true = sample_contacts(case, n_points, rng)
            edges = geometry.mesh_resolution_mm(mesh)
            print(f"\n{case[0]}, grid {h} mm (edges median {edges.median_mm:.2f}, "
                  f"p95 {edges.p95_mm:.2f} mm)")
            for row in study_case(case[0], case[1], mesh, p + case[1] * n_true, n_true):
                print(f"  {row[0]:16s} {row[1]:7.3f} {row[2]:7.3f} {row[3]:7.3f}   "
                      f"{row[4]:7.2f} {row[5]:7.2f}")
    for h in sizes:
        S, T = param_grid((-8, 8), (-8, 8), h, rng, jitter=0.0)
        xyz, _ = chamfer_edge(50.0)(S, T)
        mesh = geometry.Mesh(xyz.reshape(-1, 3), grid_faces(*S.shape))
        p, n_true, c = chamfer_contacts(4.0, 50.0, n_points, rng)
        print(f"\nsharp 50 deg edge (top + slope + rolling over it), R 4, grid {h} mm")
        for row in study_case("edge", 4.0, mesh, c, n_true):
            print(f"  {row[0]:16s} {row[1]:7.3f} {row[2]:7.3f} {row[3]:7.3f}   "
                  f"{row[4]:7.2f} {row[5]:7.2f}")


# ---------------------------------------------------------------- speed


def smooth_surface(x, y):
    z = 10.0 * np.sin(x / 15.0) * np.cos(y / 20.0)
    gx = 10.0 / 15.0 * np.cos(x / 15.0) * np.cos(y / 20.0)
    gy = -10.0 / 20.0 * np.sin(x / 15.0) * np.sin(y / 20.0)
    n = np.stack([-gx, -gy, np.ones_like(z)], -1)
    return z, n / np.linalg.norm(n, axis=-1, keepdims=True)


def path_centres(n_points: int, size_mm: float, R: float, r: float | None = None) -> np.ndarray:
    """Zig-zag raster along X, stepover along Y; cutter centres touching the surface.

    Ball (``r`` None): ball centres at distance R along the normal.  Bull-nose:
    core-circle centres touching on the side where the surface rises.
    """
    passes = int(np.sqrt(n_points / 4))
    per = n_points // passes
    X = np.tile(np.linspace(0, size_mm, per), (passes, 1))
    X[1::2] = X[1::2, ::-1]
    Y = np.repeat(np.linspace(0, size_mm, passes), per).reshape(passes, per)
    z, n = smooth_surface(X.ravel(), Y.ravel())
    p = np.c_[X.ravel(), Y.ravel(), z]
    if r is None:
        return p + R * n
    ring = n * [1.0, 1.0, 0.0]
    ring /= np.maximum(np.linalg.norm(ring, axis=1, keepdims=True), 1e-12)
    return p + r * n + (R - r) * ring


def timed(label, fn, *args, repeat=1, **kw):
    """Run ``fn``; print the best wall time and this process's CPU time of that run."""
    best = (np.inf, 0.0)
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn(*args, **kw)
        best = min(best, (time.perf_counter() - t0, time.process_time() - c0))
    print(f"{label:46s} {best[0]:8.2f} s   (cpu here {best[1]:6.2f} s)")
    return out


def build_grid_mesh(n_tri: int, size_mm: float) -> geometry.Mesh:
    n = int(np.sqrt(n_tri / 2)) + 1
    x = np.linspace(0, size_mm, n)
    X, Y = np.meshgrid(x, x, indexing="ij")
    z, _ = smooth_surface(X, Y)
    return geometry.Mesh(np.c_[X.ravel(), Y.ravel(), z.ravel()], grid_faces(n, n))


def write_stl(mesh: geometry.Mesh, path: Path) -> None:
    from stl import mesh as stl_mesh

    m = stl_mesh.Mesh(np.zeros(mesh.n_faces, dtype=stl_mesh.Mesh.dtype))
    m.vectors[:] = mesh.V[mesh.F]
    m.save(str(path))


def run_speed(n_tri: int, n_points: int) -> None:

    R, size = 4.0, 200.0
    mesh = timed(f"grid mesh, {n_tri:,} triangles", build_grid_mesh, n_tri, size)
    print(f"  triangles {mesh.n_faces:,}, edges {geometry.mesh_resolution_mm(mesh)}")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "part.stl"
        timed("write binary STL (numpy-stl)", write_stl, mesh, path)
        loaded = timed("load_stl (read + merge vertices)", geometry.load_stl, path)
    print(f"  loaded {loaded.n_faces:,} triangles, {loaded.V.shape[0]:,} vertices")
    timed("fcpw BVH build alone", closest.closest_point_scene, loaded)
    index = timed("MeshIndex (tree + corner normals + edges)", geometry.MeshIndex, loaded)
    centres = timed(f"{n_points:,} path-ordered centres", path_centres, n_points, size, R)
    cutter = Cutter(2 * R, 2)
    runs = {}
    for label, threshold in (("serial", None), (f"pool of {index.processes}", 200_000)):
        index.pool_min_points = threshold
        runs[label] = timed(f"closest points, {label}", index.closest, centres, repeat=2)
        timed(f"mesh_contacts smooth, {label}", geometry.mesh_contacts, centres, index,
              cutter, repeat=2)
    serial, pooled = runs.values()
    same = all(np.array_equal(a, b) for a, b in zip(serial, pooled))
    print(f"  pool == serial: {same}; |gap| max {np.abs(serial.dist_mm - R).max():.4f} mm")
    for how in ("center", "phong", "facet"):
        timed(f"mesh_contacts normals={how!r} (pool)", geometry.mesh_contacts, centres,
              index, cutter, normals=how)
    bull = Cutter(2 * R, 2, corner_radius_mm=1.0)
    core = path_centres(n_points, size, R, bull.corner_radius_mm)
    mc = timed("mesh_contacts bull-nose D8 r1 (pool)", geometry.mesh_contacts, core, index,
               bull)
    print(f"  cutting {mc.contacts.cutting.mean():.3f}, gouging {mc.n_gouging:,} "
          "(a bull-nose placed on the rising side can gouge in hollows)")
    own = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    kids = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    print(f"peak RSS: this process {own:.0f} MB, largest pool child {kids:.0f} MB")


def run_bullnose(n_points: int) -> None:
    R, r = 4.0, 1.0
    mesh = build_grid_mesh(250_000, 200.0)
    index = geometry.MeshIndex(mesh, pool_min_points=None)
    rng = np.random.default_rng(0)
    xy = rng.uniform(20, 180, (n_points, 2))
    z, n = smooth_surface(xy[:, 0], xy[:, 1])
    n_xy = np.linalg.norm(n[:, :2], axis=1)
    ring = n * [1, 1, 0] / np.maximum(n_xy, 1e-12)[:, None]
    centres = np.c_[xy, z] + r * n + (R - r) * ring  # core centre; contact on the rising side
    cutter = Cutter(2 * R, 2, corner_radius_mm=r)
    mc = timed(f"mesh_contacts bull-nose, {n_points:,} points", geometry.mesh_contacts,
               centres, index, cutter)
    brute = np.full(n_points, np.inf)
    for rad, step in ((0, 360), (1, 10), (2, 10), (3, 2)):
        for a in np.radians(np.arange(0, 360, step)):
            probe = centres + rad * np.array([np.cos(a), np.sin(a), 0.0])
            brute = np.minimum(brute, index.closest(probe).dist_mm - r)
    miss = mc.gap_mm - brute
    print(f"clearance found - brute force, mm: median {np.median(miss):.4f}, "
          f"p99 {np.percentile(miss, 99):.4f}, max {miss.max():.4f}, "
          f"> 0.01: {np.count_nonzero(miss > 0.01)} of {n_points}")
    valid = brute > -0.005  # where the designed placement touches nowhere else
    err = np.abs(mc.contacts.r_eff_mm - (R - r + r * n_xy))[valid]
    print(f"R_eff error where the placement is a true contact ({valid.sum()} points): "
          f"median {np.median(err):.4f}, p99 {np.percentile(err, 99):.4f}, "
          f"max {err.max():.4f} mm")


def brute_clearance(index, centres, flat_mm, r_mm):
    """Minimum over the core disc, sampled: centre, inner circles, ring every 2 deg."""
    best = index.closest(centres).dist_mm - r_mm
    for rad in np.linspace(0, flat_mm, 7)[1:]:
        for a in np.radians(np.arange(0, 360, 2 if rad == flat_mm else 5)):
            probe = centres + rad * np.array([np.cos(a), np.sin(a), 0.0])
            best = np.minimum(best, index.closest(probe).dist_mm - r_mm)
    return best


def run_egg_crates(n_points: int) -> None:
    cutter, rng = Cutter(16.0, 2, corner_radius_mm=2.0), np.random.default_rng(1)
    x = np.linspace(-40, 40, 321)
    for amp, period in ((0.5, 4.0 * np.pi), (3.0, 12.0 * np.pi)):
        X, Y = np.meshgrid(x, x, indexing="ij")
        Z = amp * np.sin(2 * np.pi * X / period) * np.sin(2 * np.pi * Y / period)
        mesh = geometry.Mesh(np.c_[X.ravel(), Y.ravel(), Z.ravel()], grid_faces(321, 321))
        index = geometry.MeshIndex(mesh, pool_min_points=None)
        centres = np.c_[rng.uniform(-25, 25, (n_points, 2)), np.full(n_points, 10.0)]
        centres[:, 2] -= brute_clearance(index, centres, 6.0, 2.0) - rng.uniform(-0.1, 0.3,
                                                                                n_points)
        truth = brute_clearance(index, centres, 6.0, 2.0)
        mc = geometry.mesh_contacts(centres, index, cutter)
        near = truth <= 0.05
        miss = (mc.gap_mm - truth)[near]
        print(f"egg-crate amplitude {amp} mm, period {period:.1f} mm, D16 r2: near-contact "
              f"points {near.sum()}, clearance miss median {np.median(miss):.4f} max "
              f"{miss.max():.4f} mm, cutting misclassified "
              f"{np.count_nonzero(mc.contacts.cutting != near)} of {n_points}")


def run_load(stl: Path | None, rounds: int, n_points: int) -> None:
    if stl is None:
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        import bench_rewrite

        _, stl = bench_rewrite.case_files(Path(tempfile.gettempdir()) / "ncopt_bench",
                                          1_000_000, 1_000_000)
    mesh = geometry.load_stl(stl)
    print(f"{stl}: {mesh.n_faces:,} triangles, {mesh.V.shape[0]:,} vertices")
    rng = np.random.default_rng(0)
    face = rng.integers(0, mesh.n_faces, n_points)
    bary = rng.dirichlet(np.ones(3), n_points)
    index = geometry.MeshIndex(mesh)
    on = np.einsum("ij,ijk->ik", bary, mesh.V[mesh.F[face]])
    centres = on + 8.0 * index.face_normal[face]  # a D16 ball's centres
    del index
    steps = (("load_stl (read + merge vertices)", lambda: geometry.load_stl(stl)),
             ("fcpw BVH build alone", lambda: closest.closest_point_scene(mesh)),
             ("MeshIndex (BVH + normals + sharp edges)", lambda: geometry.MeshIndex(mesh)),
             ("mesh_resolution_mm (edge lengths)", lambda: geometry.mesh_resolution_mm(mesh)))
    times: dict[str, list] = {label: [] for label, _ in steps}
    for _ in range(rounds):
        for label, fn in steps:
            t0, c0 = time.perf_counter(), time.process_time()
            fn()
            times[label].append((time.perf_counter() - t0, time.process_time() - c0))
    index = geometry.MeshIndex(mesh)
    label = f"closest points of {n_points:,} ball centres"
    times[label] = []
    for _ in range(rounds):
        t0, c0 = time.perf_counter(), time.process_time()
        index.closest(centres)
        times[label].append((time.perf_counter() - t0, time.process_time() - c0))
    print(f"{'':46s} {'wall s median  min':>20s} {'cpu s median  min':>20s}")
    for label, t in times.items():
        a = np.array(t)
        print(f"{label:46s} {np.median(a[:, 0]):10.3f} {a[:, 0].min():7.3f} "
              f"{np.median(a[:, 1]):12.3f} {a[:, 1].min():7.3f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", choices=["speed", "normals", "bullnose", "load"], nargs="?",
                    default="speed")
    ap.add_argument("--triangles", type=int, default=1_000_000)
    ap.add_argument("--points", type=int, default=1_000_000)
    ap.add_argument("--sizes", type=float, nargs="+", default=[0.25, 0.5, 1.0, 2.0])
    ap.add_argument("--stl", type=Path, default=None, help="load: the mesh to time")
    ap.add_argument("--rounds", type=int, default=5, help="load: repetitions")
    args = ap.parse_args()
    if args.what == "load":
        run_load(args.stl, args.rounds, args.points)
    elif args.what == "speed":
        run_speed(args.triangles, args.points)
    elif args.what == "bullnose":
        run_bullnose(min(args.points, 5000))
        run_egg_crates(min(args.points, 2000))
    else:
        run_normals(min(args.points, 5000), args.sizes)


if __name__ == "__main__":
    main()
