"""A part with vertical walls and a spherical top, its exact mesh, and a Fusion-like
parallel finishing program over it (D6 ball): each pass runs over the top, down the wall,
along the floor at the wall's foot to the next pass, and up the wall again, all at the
cutting feed, as Fusion 360's parallel passes over a tall part do (the corpus's
``more2/fusion-haas-es_1001.nc``).

The part: a cylinder of radius ``RC_MM`` standing on a floor at ``Z_FLOOR_MM``, its top a
spherical cap (sphere radius ``RS_MM``) meeting the wall at z = 0.  The toolpath is the
exact drop of the ball onto that part (the ball centre on the offset surface), so the wall
descents are truly vertical and the ball's side touches the wall all the way down.
"""

from __future__ import annotations

import math

import numpy as np

RC_MM = 20.0  # cylinder radius
RS_MM = 40.0  # sphere radius of the top
Z_FLOOR_MM = -15.0
Z0_MM = -math.sqrt(RS_MM ** 2 - RC_MM ** 2)  # the sphere's centre: the cap meets the wall at z=0
R_OUT_MM = 45.0  # the floor's outer edge
TOOL_R_MM = 3.0
S_RPM = 5000
F_MM_MIN = 1000.0
PLUNGE_F_MM_MIN = 333.33


# ---------------------------------------------------------------------------- the mesh
def _profile(step_mm: float) -> np.ndarray:
    """(k, 2) (r, z) along the meridian: cap from the apex, wall, floor."""
    a_edge = math.asin(RC_MM / RS_MM)
    n_cap = max(int(math.ceil(RS_MM * a_edge / step_mm)), 2)
    a = np.linspace(0.0, a_edge, n_cap + 1)
    cap = np.column_stack((RS_MM * np.sin(a), Z0_MM + RS_MM * np.cos(a)))
    cap[-1] = (RC_MM, 0.0)
    n_wall = max(int(math.ceil(-Z_FLOOR_MM / step_mm)), 2)
    wall = np.column_stack((np.full(n_wall + 1, RC_MM), np.linspace(0.0, Z_FLOOR_MM, n_wall + 1)))
    n_floor = max(int(math.ceil((R_OUT_MM - RC_MM) / step_mm)), 2)
    floor = np.column_stack((np.linspace(RC_MM, R_OUT_MM, n_floor + 1),
                             np.full(n_floor + 1, Z_FLOOR_MM)))
    return np.vstack((cap, wall[1:], floor[1:]))


def part_mesh(step_mm: float = 0.4, sectors: int = 720) -> tuple[np.ndarray, np.ndarray]:
    """The part as a surface of revolution: (V (nv, 3) mm, F (nf, 3)), facing up/out."""
    prof = _profile(step_mm)[1:]  # the apex is the fan's centre
    t = np.linspace(0.0, 2 * math.pi, sectors, endpoint=False)
    ring = np.column_stack((np.repeat(prof[:, 0], sectors) * np.tile(np.cos(t), len(prof)),
                            np.repeat(prof[:, 0], sectors) * np.tile(np.sin(t), len(prof)),
                            np.repeat(prof[:, 1], sectors)))
    apex = np.array([[0.0, 0.0, Z0_MM + RS_MM]])
    V = np.vstack((apex, ring))
    j = np.arange(sectors)
    nxt = (j + 1) % sectors
    faces = [np.column_stack((np.zeros(sectors, dtype=np.int64), 1 + j, 1 + nxt))]
    for i in range(len(prof) - 1):
        a, b = 1 + i * sectors, 1 + (i + 1) * sectors
        faces.append(np.column_stack((a + j, b + j, b + nxt)))
        faces.append(np.column_stack((a + j, b + nxt, a + nxt)))
    return V, np.vstack(faces)


# ------------------------------------------------------------------- the drop-cutter
def centre_z_mm(x_mm: np.ndarray, y_mm: float) -> np.ndarray:
    """The ball centre's height where the ball of radius TOOL_R_MM dropped at (x, y)
    first touches the part (the maximum over the cap, the wall's top edge and the floor)."""
    R = TOOL_R_MM
    d = np.hypot(x_mm, y_mm)
    z = np.full(d.shape, -np.inf)
    on_cap = d <= RC_MM * (RS_MM + R) / RS_MM  # the contact lies within the cap
    z = np.where(on_cap, Z0_MM + np.sqrt(np.maximum((RS_MM + R) ** 2 - d ** 2, 0.0)), z)
    near_edge = np.abs(d - RC_MM) <= R
    z = np.maximum(z, np.where(near_edge, np.sqrt(np.maximum(R ** 2 - (d - RC_MM) ** 2, 0.0)),
                               -np.inf))
    z = np.maximum(z, np.where(d >= RC_MM, Z_FLOOR_MM + R, -np.inf))
    return z


def _fmt(v: float) -> str:
    """Fusion's number style: 3 decimals, trailing zeros dropped, the point kept."""
    s = f"{v:.3f}".rstrip("0")
    return "0." if s in ("-0.", "0.") else s


def pass_points(y_mm: float, step_mm: float, forward: bool) -> np.ndarray:
    """(k, 3) tool-tip points of one pass at ``y_mm``, from the floor at one wall's foot,
    up it, over the top and down the other wall to the floor."""
    R = TOOL_R_MM
    x_w = math.sqrt((RC_MM + R) ** 2 - y_mm ** 2)  # where the ball's side meets the wall
    n = int(math.ceil(2 * x_w / step_mm))
    x = np.linspace(-x_w, x_w, n + 1)
    x[0], x[-1] = -x_w, x_w
    z = centre_z_mm(x, y_mm) - R
    z[0] = z[-1] = 0.0 - R  # the top of the wall: the ball's centre level with its edge
    floor = Z_FLOOR_MM
    pts = np.vstack(([[-x_w, y_mm, floor]], np.column_stack((x, np.full_like(x, y_mm), z)),
                     [[x_w, y_mm, floor]]))
    return pts if forward else pts[::-1]


def program(stepover_mm: float = 0.5, step_mm: float = 0.3, y_max_mm: float = 19.0) -> str:
    """The finishing program, Fusion's Haas-style post form (``%``, ``O``, N numbers,
    ``G43 H1``, tool comment ``(T1 D=6. CR=3. - ... - ball end mill)``)."""
    ys = np.arange(-y_max_mm, y_max_mm + 1e-9, stepover_mm)
    lines = ["%", "O01001", "(T1 D=6. CR=3. - ZMIN=-15. - ball end mill)",
             "N10 G90 G94 G17", "N15 G21", "", "(PARALLEL2)", "N25 T1 M6",
             f"N30 S{S_RPM} M3", "N35 G17 G90 G94", "N40 G54", "N45 M8"]
    n = 50
    first = pass_points(float(ys[0]), step_mm, True)
    start = first[0] - (1.0, 0.0, 0.0)
    lines += [f"N{n} G0 X{_fmt(start[0])} Y{_fmt(start[1])}",
              f"N{n + 5} G43 Z16. H1",
              f"N{n + 10} G1 Z{_fmt(Z0_MM + RS_MM + 2.0)} F{_fmt(F_MM_MIN)}",
              f"N{n + 15} Z{_fmt(Z_FLOOR_MM)} F{PLUNGE_F_MM_MIN:.2f}",
              f"N{n + 20} X{_fmt(first[0, 0])} F{_fmt(F_MM_MIN)}"]
    n += 25
    prev = first[0]
    for i, y in enumerate(ys):
        pts = pass_points(float(y), step_mm, i % 2 == 0)
        for p in pts:
            words = [f"{a}{_fmt(v)}" for a, v, u in zip("XYZ", p, prev) if _fmt(v) != _fmt(u)]
            if words:
                lines.append(f"N{n} " + " ".join(words))
                n += 5
            prev = p
    lines += [f"N{n} G0 Z16.", f"N{n + 5} M9", f"N{n + 10} M5", f"N{n + 15} G28 G91 Z0.",
              f"N{n + 20} G90", f"N{n + 25} M30", "%"]
    return "\n".join(lines) + "\n"


def write(folder) -> tuple:
    """Write ``wallpart.nc`` and ``wallpart.stl`` into ``folder``: their paths."""
    from pathlib import Path

    from conftest import load_module

    folder = Path(folder)
    nc, stl = folder / "wallpart.nc", folder / "wallpart.stl"
    nc.write_text(program(), encoding="ascii", newline="\n")
    V, F = part_mesh()
    load_module("samples/make_bowl.py", "make_bowl_for_wallpart").write_stl(
        stl, V, F, name="ncopt wall part")
    return nc, stl
