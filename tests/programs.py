"""Small generated programs for the tests of files, faults and the command line."""

from __future__ import annotations

import math


def dome(n: int = 10, rev: int = 0, spindle: bool = True) -> bytes:
    """A zig-zag finish over a dome (n x n points, D6 ball work, S4000 F800): plans in a few
    tens of ms; n=60 gives a rewrite (132 KB) larger than a pipe holds.  ``rev`` changes the
    dome (another CAM output); without ``spindle`` there is nothing to plan."""
    lines = [f"(dome rev {rev})", "G21 G90 G94 G17", "T1 M6", "S4000 M3" if spindle else "M5",
             "G0 X-10 Y-10 Z15"]
    for i in range(n):
        y = -10 + 20 * i / (n - 1)
        xs = [-10 + 20 * k / (n - 1) for k in range(n)]
        for j, x in enumerate(xs if i % 2 == 0 else xs[::-1]):
            z = 10 - (x * x + y * y) / (40 + rev)
            lines.append(f"G1 X{x:.3f} Y{y:.3f} Z{z:.3f}" + (" F800" if i == j == 0 else ""))
    return ("\n".join(lines + ["G0 Z20", "M30"]) + "\n").encode()


MM_PER_INCH = 25.4
#: tool-tip heights of the surfaces :func:`surface` machines, (x, y) mm -> z mm
SURFACES = {
    "dome": lambda x, y: 10 - (x * x + y * y) / 40,
    "saddle": lambda x, y: 5 + (x * x - y * y) / 60,
    "waves": lambda x, y: 5 + 2 * math.sin(x / 3) * math.cos(y / 5),
}


def _program_text(lines: list[str], crlf: bool) -> bytes:
    return ((("\r\n" if crlf else "\n").join(lines)) + ("\r\n" if crlf else "\n")).encode()


def _xyz(x: float, y: float, z: float, inch: bool) -> str:
    """Axis words of a point given in mm, in the program's unit (3 decimals in mm, 4 in
    inch, as posts write them)."""
    if inch:
        return f"X{x / MM_PER_INCH:.4f} Y{y / MM_PER_INCH:.4f} Z{z / MM_PER_INCH:.4f}"
    return f"X{x:.3f} Y{y:.3f} Z{z:.3f}"


def surface(shape: str = "dome", n: int = 8, *, inch: bool = False, lifts: bool = False,
            crlf: bool = False, numbered: bool = False, s_rpm: int = 4000,
            f_mm_min: float = 800.0, plunge_mm_min: float | None = None) -> bytes:
    """A zig-zag finish over one of :data:`SURFACES` (n x n points over 20 x 20 mm, D6
    ball work, one tool T1): a stay-down path, or with ``lifts`` one pass per row, each
    reached by a rapid above it and a plunge (at ``plunge_mm_min``, default the cutting
    feed), so that passes have moves between them (``--s-changes between-passes``).

    ``inch``: the same path in G20 (F in inch/min); ``crlf``: CR LF line ends;
    ``numbered``: N words.  The cutting feed ``f_mm_min`` is on the first cutting move
    only (modal), the spindle speed ``s_rpm`` on the spindle start."""
    tip = SURFACES[shape]
    unit = MM_PER_INCH if inch else 1.0
    feed = f"F{f_mm_min / unit:.{1 if inch else 0}f}"
    plunge = f"F{(plunge_mm_min or f_mm_min) / unit:.{1 if inch else 0}f}"
    clear = f"Z{15 / unit:.4f}" if inch else "Z15.000"
    body = [f"(surface {shape} {n}x{n}{' inch' if inch else ''})",
            f"{'G20' if inch else 'G21'} G90 G94 G17", "T1 M6", f"S{s_rpm} M3"]
    rows = []
    for i in range(n):
        y = -10 + 20 * i / (n - 1)
        xs = [-10 + 20 * k / (n - 1) for k in range(n)]
        rows.append([(x, y, tip(x, y)) for x in (xs if i % 2 == 0 else xs[::-1])])
    body.append("G0 " + _xyz(*rows[0][0][:2], 15, inch))
    for i, row in enumerate(rows):
        if lifts and i > 0:
            body += ["G0 " + clear, "G0 " + _xyz(*row[0][:2], 15, inch)]
        if lifts or i == 0:
            body.append(f"G1 {_xyz(*row[0], inch)} {plunge}")
            if plunge != feed:
                body.append(f"G1 {_xyz(*row[1], inch)} {feed}")
                row = row[1:]
            row = row[1:]
        body += [f"G1 {_xyz(x, y, z, inch)}" for x, y, z in row]
    body += ["G0 " + clear, "M5", "M30"]
    if numbered:
        body = [line if line.startswith("(") else f"N{10 * (k + 1)} {line}"
                for k, line in enumerate(body)]
    return _program_text(body, crlf)


def bowl_strip(tip_z, ys=(44.0, 52.0, 60.0), step_mm: float = 2.0, *, inch: bool = False,
               radius_mm: float = 8.0, s_rpm: int = 1393, f_mm_min: float = 279.0,
               crlf: bool = False, center: bool = False) -> bytes:
    """A few passes of the sample bowl's finish (samples/make_bowl.py): zig-zag passes in
    X-Z at the given Y (mm) from x = -90 to 90 mm, over the land, down the wall and across
    the bottom, linked on the land at the cutting feed; ``tip_z(x, y, radius_mm)`` is the
    exact drop-cutter of the bowl (``make_bowl.drop_ball_tip_z_mm``).  D16 ball (radius
    8 mm), S1393 F279 (vc 70 m/min, fz 0.1 mm with 2 teeth) unless told otherwise; passes
    parallel to X, so a mesh of the bowl covers every contact.  ``center``: the program
    moves the ball's centre (``--tool-point center``), ``radius_mm`` above its tip."""
    import numpy as np

    unit = MM_PER_INCH if inch else 1.0
    feed = f"F{f_mm_min / unit:.{2 if inch else 0}f}"
    xs = np.arange(-90.0, 90.0 + 1e-9, step_mm)
    body = [f"(bowl strip, {len(ys)} passes{' inch' if inch else ''})",
            f"{'G20' if inch else 'G21'} G90 G94 G17", "T4 M6", f"S{s_rpm} M3"]
    x0 = xs[0]
    lift = radius_mm if center else 0.0
    body.append("G0 " + _xyz(x0, ys[0], 15 + lift, inch))
    body.append(f"G1 {_xyz(x0, ys[0], 3 + lift, inch)} {feed}")
    for i, y in enumerate(ys):
        row = xs if i % 2 == 0 else xs[::-1]
        z = tip_z(row, np.full(row.shape, y), radius_mm) + (radius_mm if center else 0.0)
        body += [f"G1 {_xyz(float(x), y, float(h), inch)}" for x, h in zip(row, z)]
    body += ["G0 " + _xyz(float(row[-1]), ys[-1], 15 + lift, inch), "M5", "M30"]
    return _program_text(body, crlf)
