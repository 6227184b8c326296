"""Regenerate the meshes and the input programs of the writing stage's golden cases
(tests/golden/writing/, read by tests/test_golden.py).

    python tests/golden/make_golden.py                          # meshes and inputs
    python -m pytest tests/test_golden.py --update-golden       # then the expected files

Everything is deterministic.  The parts are analytic, so the programs carry the exact
drop-cutter tool positions and the meshes carry vertices exactly on the surfaces:

* dome: a sphere cap (radius 40 mm, top at z = 12) on the plane z = 0;
* ridge: a cylinder (radius 30 mm, axis along X at z = -20, top at z = 10) on z = 0.

Drop-cutter on a sphere or cylinder of radius Rs (distance d of the tool axis from the
surface's axis, in the plane across it): a torus of tube radius r whose tube circle has
radius a = R - r touches where the tube centre is Rs + r from the surface axis; the flat
disc of radius a touches the highest surface point under it.  For a ball a = 0, r = R.

Expected outputs are ncopt's own output, inspected by eye when generated: a regression
guard, not a proof of correctness.
"""

from __future__ import annotations

import importlib.util
import shlex
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
MESHES = HERE / "meshes"
CASES = HERE / "writing"

DOME_R, DOME_CZ = 40.0, -28.0
RIDGE_R, RIDGE_CZ = 30.0, -20.0


def _make_bowl():
    spec = importlib.util.spec_from_file_location("make_bowl", ROOT / "samples" / "make_bowl.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


# ------------------------------------------------------------------ surfaces ----
def dome_z(x, y):
    rho2 = np.asarray(x) ** 2 + np.asarray(y) ** 2
    return np.maximum(DOME_CZ + np.sqrt(np.maximum(DOME_R ** 2 - rho2, 0.0)), 0.0)


def ridge_z(x, y):
    y = np.asarray(y) + 0.0 * np.asarray(x)
    return np.maximum(RIDGE_CZ + np.sqrt(np.maximum(RIDGE_R ** 2 - y ** 2, 0.0)), 0.0)


def drop_tip(d, surface_r, cz, radius, corner):
    """Tool-tip height of a ball (corner == radius) or bull-nose over a sphere/cylinder."""
    a = radius - corner
    e = np.maximum(np.abs(d) - a, 0.0)
    torus = cz + np.sqrt((surface_r + corner) ** 2 - e ** 2) - corner
    if a <= 0:
        return torus
    disc = cz + np.sqrt(np.maximum(surface_r ** 2 - e ** 2, 0.0))
    return np.maximum(torus, disc)


def grid_mesh(xs, ys, zfun):
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    V = np.column_stack((X.ravel(), Y.ravel(), zfun(X, Y).ravel()))
    nx, ny = len(xs), len(ys)
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1), indexing="ij")
    v00 = (i * ny + j).ravel()
    v10, v01 = v00 + ny, v00 + 1
    v11 = v10 + 1
    F = np.vstack((np.column_stack((v00, v10, v11)), np.column_stack((v00, v11, v01))))
    return V, F


def write_meshes() -> None:
    mb = _make_bowl()
    MESHES.mkdir(exist_ok=True)
    g = np.linspace(-30.0, 30.0, 31)  # 2 mm grid: chord error 0.0125 mm on the dome
    mb.write_stl(MESHES / "dome.stl", *grid_mesh(g, g, dome_z), name="ncopt golden dome")
    gx = np.linspace(-30.0, 30.0, 7)  # straight along X
    gy = np.linspace(-30.0, 30.0, 61)  # 1 mm across the ridge
    mb.write_stl(MESHES / "ridge.stl", *grid_mesh(gx, gy, ridge_z), name="ncopt golden ridge")


# ------------------------------------------------------------------ programs ----
def _zigzag(pass_values, along, dome: bool, radius, corner):
    """Points (x, y, z) of zig-zag passes: constant pass_value, varying along."""
    pts = []
    for k, v in enumerate(pass_values):
        run = along if k % 2 == 0 else along[::-1]
        if dome:
            x, y = run, np.full_like(run, v)
            z = drop_tip(np.hypot(x, y), DOME_R, DOME_CZ, radius, corner)
        else:  # ridge passes run across the ridge: along Y at constant X
            x, y = np.full_like(run, v), run
            z = drop_tip(y, RIDGE_R, RIDGE_CZ, radius, corner)
        pts += list(zip(x.tolist(), y.tolist(), z.tolist()))
    return pts


def dome_fanuc() -> tuple[str, list[str], str]:
    """Fanuc-style post: % / O number, N numbers, spaces, F with a trailing point."""
    pts = _zigzag(np.arange(-15.0, 15.01, 2.0), np.arange(-18.0, 18.01, 1.5), True, 5.0, 5.0)
    lines = ["%", "O1000 (DOME FINISH)", "(T1 D=10 CR=5 - BALL END MILL)", "G21 G90 G17",
             "T1 M6", "S3000 M3", f"G0 X{pts[0][0]:.3f} Y{pts[0][1]:.3f} Z25.", "G43 H1 Z20.",
             f"G1 Z{pts[0][2] + 2:.3f} F600."]
    lines += [f"X{x:.3f} Y{y:.3f} Z{z:.3f}" for x, y, z in pts]
    lines += ["G0 Z25.", "M5", "M30"]
    body = [f"N{10 * (i + 1)} {line}" if line[0] in "GTSXM" else line
            for i, line in enumerate(lines[2:])]
    text = "\n".join(lines[:2] + body + ["%"]) + "\n"
    args = ["--mesh", "../../meshes/dome.stl", "--diameter", "10", "--teeth", "2",
            "--accel", "150", "--max-rpm", "12000", "--vc", "90", "--fz", "0.05"]
    return text, args, "input.nc"


def ridge_inch_crlf() -> tuple[str, list[str], str]:
    """Inch program without blanks, CRLF line endings, F with one decimal, forward planner."""
    pts = _zigzag(np.arange(-20.0, 20.01, 2.5), np.arange(-15.0, 15.01, 1.0), False, 5.0, 5.0)
    inch = [(x / 25.4, y / 25.4, z / 25.4) for x, y, z in pts]
    lines = ["(RIDGE - INCH - NO BLANKS)", "N10G20G90G17", "N20T2M6", "N30S2500M3",
             f"N40G0X{inch[0][0]:.4f}Y{inch[0][1]:.4f}Z1.", f"N50G1Z{inch[0][2] + 0.1:.4f}F20.0"]
    n = 60
    for x, y, z in inch:
        lines.append(f"N{n}X{x:.4f}Y{y:.4f}Z{z:.4f}")
        n += 10
    lines += [f"N{n}G0Z1.", f"N{n + 10}M5", f"N{n + 20}M30"]
    text = "\r\n".join(lines) + "\r\n"
    args = ["--mesh", "../../meshes/ridge.stl", "--diameter", "10", "--teeth", "2",
            "--accel", "100", "--max-rpm", "10000", "--vc", "80", "--fz", "0.04",
            "--planner", "forward"]
    return text, args, "input.tap"


def dome_bull_sinumerik() -> tuple[str, list[str], str]:
    """Sinumerik-style: ; comments, DEF and CYCLE832 lines, T="name", a bull-nose, an arc."""
    pts = _zigzag(np.arange(-14.0, 14.01, 2.0), np.arange(-16.0, 16.01, 1.6), True, 5.0, 2.0)
    pts = [(y, x, z) for x, y, z in pts]  # passes along Y
    lines = ["; dome finish with a bull-nose D10 R2", "DEF REAL SAFE", "SAFE=25",
             "CYCLE832(0.01,_FINISH,1)", "G17 G90", 'T="BULL_D10_R2"', "M6", "D1",
             "S4000 M3", f"G0 X{pts[0][0]:.3f} Y{pts[0][1]:.3f} Z25",
             f"G1 Z{pts[0][2] + 2:.3f} F800"]
    lines += [f"X{x:.3f} Y{y:.3f} Z{z:.3f}" for x, y, z in pts]
    x0, y0 = pts[-1][0], pts[-1][1]
    lines += ["G0 Z25", f"G2 X{x0 + 10:.3f} Y{y0:.3f} I5 J0 F2000 ; an arc in the air",
              "M5", "M30"]
    text = "\n".join(lines) + "\n"
    args = ["--mesh", "../../meshes/dome.stl", "--diameter", "10", "--corner-radius", "2",
            "--teeth", "3", "--accel", "100", "--max-rpm", "10000", "--vc", "120",
            "--fz", "0.04", "--min-rpm-step", "25"]
    return text, args, "input.mpf"


def dome_nomesh() -> tuple[str, list[str], str]:
    """tests/programs.py's dome (8 x 8 points), planned without a mesh: the normals come
    from the toolpath."""
    spec = importlib.util.spec_from_file_location("programs", ROOT / "tests" / "programs.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    args = ["--diameter", "6", "--teeth", "2", "--accel", "227", "--max-rpm", "15000"]
    return module.dome(8).decode("latin-1"), args, "input.nc"


CASE_FUNCS = {"dome_fanuc": dome_fanuc, "ridge_inch_crlf": ridge_inch_crlf,
              "dome_bull_sinumerik": dome_bull_sinumerik, "dome_nomesh": dome_nomesh}


def write_inputs() -> None:
    for name, make in CASE_FUNCS.items():
        folder = CASES / name
        folder.mkdir(parents=True, exist_ok=True)
        text, args, filename = make()
        (folder / filename).write_bytes(text.encode("latin-1"))
        (folder / "args").write_text(shlex.join(args) + "\n")


if __name__ == "__main__":
    write_meshes()
    write_inputs()
