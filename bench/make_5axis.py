"""Generate 5-axis ball-end finishing cases with their exact part meshes.

A dome (convex sphere) and a bowl (concave sphere), finished with a D10 ball in
zig-zag passes along X, the tool tilted from the surface normal by a lead angle
(toward the feed direction) and a tilt angle (sideways), each varying 5-25 deg:
slowly along the whole path (``variation="sweep"``, 0.5 mm blocks), or as functions of
the place, several sweeps within every pass (``"flowline"``, 1 mm blocks, the axis
turning up to 5.5 deg a block; :data:`FLOWLINE`).  The ball touches the analytic
surface exactly at every CL point (a sphere's contact does not depend on its axis), so
the program and the mesh agree to the mesh's chord error (0.5 mm grid on a 60 mm
sphere: 0.0005 mm).

Three styles of the same toolpath:

* ``traori``: Sinumerik, ``TRAORI`` with tool vectors ``A3= B3= C3=``;
* ``g43.5``: Fanuc, ``G43.5`` with tool vectors ``I J K``;
* ``xyzac-trt``: LinuxCNC with rotary angles for table A (about X) carrying
  table C, ISO 841 (``ncopt.motion.kinematics``): ``A = acos(ez)``, ``C = atan2(ex,
  -ey)`` (unwrapped along the path); G94, or G93 (inverse time) with
  ``feed="g93"``.

Closed forms: at a contact with unit normal ``n`` the axis is ``e = cos(l)
cos(t) n + sin(l) u + cos(l) sin(t) v`` (``u`` the feed direction in the
tangent plane, ``v = n x u``), so ``R_eff = R sqrt(1 - cos^2 l cos^2 t)``.

``python bench/make_5axis.py [OUT_DIR] [--small] [--flowline]`` writes ``dome_*.nc``,
``bowl_*.nc`` in every style (with ``--flowline`` also ``dome_flowline_*.nc``,
``bowl_flowline_*.nc``) and ``dome.stl``, ``bowl.stl`` (default ``/tmp/ncopt_5axis``).
"""

from __future__ import annotations


import os
import sys
from dataclasses import dataclass

import numpy as np

SPHERE_MM = 60.0  # radius of the dome's and the bowl's sphere
BALL_MM = 5.0  # D10
STYLES = ("traori", "g43.5", "xyzac-trt")


@dataclass(frozen=True)
class Case:
    """One toolpath: CL points (tool tips), tool axes, contacts and pass ids, (m, ...) arrays.

    ``r_eff_mm`` is the exact effective radius at each CL point; ``variation`` how lead
    and tilt vary (:func:`make_case`).
    """

    kind: str
    tip_mm: np.ndarray
    axis: np.ndarray
    contact_mm: np.ndarray
    normal: np.ndarray
    pass_id: np.ndarray
    r_eff_mm: np.ndarray
    variation: str = "sweep"


def surface(kind: str, x: np.ndarray, y: np.ndarray):
    """z (mm) and the unit normal (toward the tool) of the dome or the bowl at (x, y)."""
    r2 = x * x + y * y
    root = np.sqrt(SPHERE_MM ** 2 - r2)
    if kind == "dome":  # the sphere's top at z = 0
        z = root - SPHERE_MM
        n = np.stack((x, y, root), axis=-1)
    elif kind == "bowl":  # its bottom at z = 0
        z = SPHERE_MM - root
        n = np.stack((-x, -y, root), axis=-1)
    else:
        raise ValueError(f"kind must be dome or bowl, not {kind!r}")
    return z, n / SPHERE_MM


def angles_deg(s_mm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lead and tilt along the path length, each sweeping 5-25 deg."""
    return 15.0 + 10.0 * np.sin(s_mm / 23.0), 15.0 + 10.0 * np.cos(s_mm / 37.0)


# The flowline case: lead and tilt functions of the place on the part, each sweeping 5-25
# deg within every pass, lead over LEAD_PERIOD_MM and tilt over TILT_PERIOD_MM along X
# (up to 3.9 and 2.4 deg/mm; the passes shift their phases).  LinuxCNC's 5-axis demos turn
# the axis 0.3-0.6 deg/mm at the median and 1.8-6 deg/mm at the 90th percentile, their
# blocks 0.4-1.1 mm at the median: FLOWLINE's 1 mm blocks turn it 3 deg at the median,
# 5.5 at most (the sweep case's 0.5 mm blocks: 0.5 and 0.9).
LEAD_PERIOD_MM, TILT_PERIOD_MM = 16.0, 26.0
FLOWLINE = dict(variation="flowline", step_mm=1.0)


def flowline_angles_deg(x_mm: np.ndarray, y_mm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lead and tilt (deg) at the contact (x, y): each sweeps 5-25 deg along every pass."""
    lead = 15.0 + 10.0 * np.sin(2.0 * np.pi * x_mm / LEAD_PERIOD_MM + y_mm / 7.0)
    tilt = 15.0 + 10.0 * np.sin(2.0 * np.pi * x_mm / TILT_PERIOD_MM + 1.3 + y_mm / 5.0)
    return lead, tilt


def make_case(kind: str, half_mm: float = 30.0, step_mm: float = 0.5,
              stepover_mm: float = 0.8, variation: str = "sweep") -> Case:
    """Zig-zag passes along X over [-half, half]^2, the ball on the surface.

    ``variation``: ``"sweep"``, lead and tilt along the whole path's length
    (:func:`angles_deg`, a slow sweep: at most 0.43 deg/mm); ``"flowline"``, functions
    of the place (:func:`flowline_angles_deg`, several sweeps per pass)."""
    xs = np.arange(-half_mm, half_mm + 1e-9, step_mm)
    ys = np.arange(-half_mm, half_mm + 1e-9, stepover_mm)
    pts, ids, feed = [], [], []
    for j, y in enumerate(ys):
        row = xs if j % 2 == 0 else xs[::-1]
        pts.append(np.column_stack((row, np.full(row.shape, y))))
        ids.append(np.full(row.shape, j))
        feed.append(np.tile([1.0 if j % 2 == 0 else -1.0, 0.0, 0.0], (row.size, 1)))
    xy, pass_id, f = np.vstack(pts), np.concatenate(ids), np.vstack(feed)
    z, n = surface(kind, xy[:, 0], xy[:, 1])
    contact = np.column_stack((xy, z))
    u = f - np.sum(f * n, axis=1)[:, None] * n
    u /= np.linalg.norm(u, axis=1)[:, None]
    v = np.cross(n, u)
    s = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(contact, axis=0), axis=1))))
    if variation == "sweep":
        lead, tilt = (np.radians(a) for a in angles_deg(s))
    elif variation == "flowline":
        lead, tilt = (np.radians(a) for a in flowline_angles_deg(xy[:, 0], xy[:, 1]))
    else:
        raise ValueError(f"variation must be sweep or flowline, not {variation!r}")
    e = (np.cos(lead) * np.cos(tilt))[:, None] * n + np.sin(lead)[:, None] * u \
        + (np.cos(lead) * np.sin(tilt))[:, None] * v
    tip = contact + BALL_MM * n - BALL_MM * e
    r_eff = BALL_MM * np.sqrt(1.0 - (np.cos(lead) * np.cos(tilt)) ** 2)
    return Case(kind, tip, e, contact, n, pass_id, r_eff, variation)


def rotary_angles(axis: np.ndarray) -> np.ndarray:
    """(m, 3) A B C (deg) of xyzac-trt for unit axes, C unwrapped along the path."""
    a = np.degrees(np.arccos(np.clip(axis[:, 2], -1.0, 1.0)))
    c = np.unwrap(np.arctan2(axis[:, 0], -axis[:, 1]))
    return np.column_stack((a, np.zeros_like(a), np.degrees(c)))


LEAD_MM = 2.0  # lead-in and lead-out ramps: this long along the pass, 0.3 mm above it
CLEAR_MM = 10.0  # rapids this high above the ramps' far ends


@dataclass(frozen=True)
class Moves:
    """The program's moves in order, (q, ...) arrays; move i ends at ``tip_mm[i]``.

    rapid : the move is a G0;  ramp : a lead-in or lead-out G1 (touches at one end)
    axis : unit tool axis at the end;  angles_deg : xyzac-trt A B C at the end
    """

    tip_mm: np.ndarray
    axis: np.ndarray
    angles_deg: np.ndarray
    rapid: np.ndarray
    ramp: np.ndarray


def moves(case: Case) -> Moves:
    """Every pass with a ramp onto its start and off its end, rapids between.

    A ramp holds the tool axis of the pass's end and runs LEAD_MM along the pass's
    direction there, rising 0.3 mm along the normal: the direction of the tips' first or
    last chord in the sweep case; in the flowline case that of the ball centres' (the
    surface's), as CAM leads in and out: there the axis turns up to 5.5 deg a block and
    the tips' chord leaves the ball centres' by 8 deg at the median, 19 at most, so a
    ramp along it would dive into the part or leave it steeply."""
    ang = rotary_angles(case.axis)
    tips, axes, angs, rapid, ramp = [], [], [], [], []

    def add(p, k, is_rapid=False, is_ramp=False):
        tips.append(p), axes.append(case.axis[k]), angs.append(ang[k])
        rapid.append(is_rapid), ramp.append(is_ramp)

    bounds = np.flatnonzero(np.diff(case.pass_id, prepend=-1, append=-1) != 0)
    for a, b in zip(bounds[:-1], bounds[1:] - 1):  # pass from point a to point b
        t, n = case.tip_mm, case.normal
        c = t + BALL_MM * case.axis if case.variation == "flowline" else t
        back = t[a] - LEAD_MM * _unit(c[a + 1] - c[a]) + 0.3 * n[a]
        ahead = t[b] + LEAD_MM * _unit(c[b] - c[b - 1]) + 0.3 * n[b]
        add(back + [0, 0, CLEAR_MM], a, is_rapid=True)
        add(back, a, is_rapid=True)
        for k in range(a, b + 1):
            add(t[k], k, is_ramp=(k == a))
        add(ahead, b, is_ramp=True)
        add(ahead + [0, 0, CLEAR_MM], b, is_rapid=True)
    return Moves(np.array(tips), np.array(axes), np.array(angs), np.array(rapid),
                 np.array(ramp))


def _unit(v):
    return v / np.linalg.norm(v)


def _orientation(style: str, e: np.ndarray, angles: np.ndarray) -> str:
    if style == "traori":
        return f" A3={e[0]:.6f} B3={e[1]:.6f} C3={e[2]:.6f}"
    if style == "g43.5":
        return f" I{e[0]:.6f} J{e[1]:.6f} K{e[2]:.6f}"
    return f" A{angles[0]:.4f} C{angles[2]:.4f}"


HEAD = {"traori": ["; ncopt 5-axis case", "G17 G71 G90 G94", "T1 D1", "S{s} M3", "TRAORI",
                   "ORIWKS", "ORIVECT"],
        "g43.5": ["%", "O5001 (NCOPT 5-AXIS CASE)", "G17 G21 G90 G94", "T1 M6", "S{s} M3",
                  "G43.5 H1"],
        "xyzac-trt": ["(ncopt 5-axis case)", "M428", "G17 G21 G90 G94", "T1 M6", "S{s} M3"]}
TAIL = {"traori": ["TRAFOOF", "M30"], "g43.5": ["G49", "M30", "%"], "xyzac-trt": ["M429", "M2"]}


def program(case: Case, style: str, feed: str = "g94", f_mm_min: float = 1000.0,
            s_rpm: int = 3000) -> str:
    """The case as an NC program in ``style``; ``feed``: ``g94`` or ``g93`` (inverse time:
    every feed block's F is 1 / its minutes at ``f_mm_min``)."""
    if style not in STYLES:
        raise ValueError(f"style must be one of {STYLES}")
    mv = moves(case)
    out = [line.format(s=s_rpm) for line in HEAD[style]]
    inverse, mode = feed == "g93", None
    for i in range(mv.tip_mm.shape[0]):
        x, y, z = mv.tip_mm[i]
        ori = _orientation(style, mv.axis[i], mv.angles_deg[i])
        if mv.rapid[i]:
            if inverse and mode == "G93":
                out.append("G94")
                mode = "G94"
            out.append(f"G0 X{x:.4f} Y{y:.4f} Z{z:.4f}{ori}")
            continue
        words = f"G1 X{x:.4f} Y{y:.4f} Z{z:.4f}{ori}"
        if inverse:
            if mode != "G93":
                out.append("G93")
                mode = "G93"
            minutes = np.linalg.norm(mv.tip_mm[i] - mv.tip_mm[i - 1]) / f_mm_min
            words += f" F{1.0 / minutes:.4f}"
        elif mv.rapid[i - 1]:
            words += f" F{f_mm_min:.0f}"
        out.append(words)
    return "\n".join(out + TAIL[style]) + "\n"


def mesh(kind: str, half_mm: float = 40.0, pitch_mm: float = 0.5):
    """Vertices and faces of the surface on a square grid (winding: normals up)."""
    g = np.arange(-half_mm, half_mm + 1e-9, pitch_mm)
    gx, gy = np.meshgrid(g, g, indexing="xy")
    z, _ = surface(kind, gx, gy)
    V = np.column_stack((gx.ravel(), gy.ravel(), z.ravel()))
    n = g.size
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="xy")
    a = (j * n + i).ravel()
    F = np.vstack((np.column_stack((a, a + 1, a + n + 1)), np.column_stack((a, a + n + 1, a + n))))
    return V, F


def write_stl(path, V, F) -> None:
    """Binary STL (numpy-stl), fixed header."""
    from stl import mesh as stl_mesh

    m = stl_mesh.Mesh(np.zeros(F.shape[0], dtype=stl_mesh.Mesh.dtype))
    m.vectors[:] = V[F]
    m.update_normals()
    m.save(str(path), update_normals=False)


def case_args(variation: str = "sweep", small: bool = False,
              step_mm: float | None = None) -> dict:
    """make_case's arguments for a variation (the flowline case in its 1 mm blocks) at the
    full or the small (test) size; ``step_mm``: another block length."""
    args = dict(FLOWLINE) if variation == "flowline" else dict(variation=variation)
    if small:
        args.update(half_mm=8.0, step_mm=1.0, stepover_mm=1.5)
    if step_mm is not None:
        args["step_mm"] = step_mm
    return args


def case_name(kind: str, variation: str = "sweep") -> str:
    """The file names' stem: ``dome``, or ``dome_flowline`` for the flowline case."""
    return kind if variation == "sweep" else f"{kind}_{variation}"


def write_cases(out_dir: str, small: bool = False, variation: str = "sweep",
                step_mm: float | None = None) -> list[str]:
    """Every kind in every style (and xyzac-trt in G93), and the meshes; returns paths."""
    os.makedirs(out_dir, exist_ok=True)
    size = dict(half_mm=8.0, step_mm=1.0, stepover_mm=1.5) if small else {}
    written = []
    for kind in ("dome", "bowl"):
        case = make_case(kind, **case_args(variation, small, step_mm))
        stem = case_name(kind, variation)
        for style in STYLES:
            name = os.path.join(out_dir, f"{stem}_{style}.nc")
            with open(name, "w", newline="\n") as fh:
                fh.write(program(case, style))
            written.append(name)
        name = os.path.join(out_dir, f"{stem}_xyzac-trt_g93.nc")
        with open(name, "w", newline="\n") as fh:
            fh.write(program(case, "xyzac-trt", feed="g93"))
        written.append(name)
        V, F = mesh(kind, half_mm=(size.get("half_mm", 30.0) + 10.0))
        name = os.path.join(out_dir, f"{kind}.stl")
        write_stl(name, V, F)
        written.append(name)
    return written


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    out = args[0] if args else "/tmp/ncopt_5axis"
    for var in ("sweep", "flowline") if "--flowline" in sys.argv else ("sweep",):
        for path in write_cases(out, small="--small" in sys.argv, variation=var):
            print(path, os.path.getsize(path), "bytes")
    print(f"lead and tilt 5-25 deg, D{2 * BALL_MM:g} ball, sphere radius {SPHERE_MM:g} mm; "
          f"chord error of the 0.5 mm mesh {0.5 ** 2 / (8 * SPHERE_MM):.4f} mm", file=sys.stderr)

