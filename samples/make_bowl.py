"""Generate the bowl-mould sample data: an analytic surface, its STL and a finishing program.

The part imitates the bowl mould of the paper's machining test (Vavruska et al. 2023,
sections 5-6; see docs/method.md): a surface of revolution with a large, nearly
flat bottom, steep walls near the rim and a flat top land around it, finished with a D16
ball-end mill (R = 8 mm, z = 2, vc = 70 m/min, fz = 0.1 mm -> S1393, F279) in zig-zag passes
in the X-Z plane with the stepover along Y.

Surface (all lengths in mm, ``r = sqrt(x**2 + y**2)``)::

    z = f(r) = -DEPTH_MM * (1 - (r / RIM_RADIUS_MM)**EXPONENT)**3    for r <  RIM_RADIUS_MM
    z = f(r) = 0                                                     for r >= RIM_RADIUS_MM

with ``DEPTH_MM = 25``, ``RIM_RADIUS_MM = 85`` and ``EXPONENT = 10``. Because the exponent is
even, ``f`` is a polynomial in ``r**2`` inside the rim (smooth through the axis), and the
triple root at the rim makes value, slope and curvature vanish there: the surface is C2
everywhere. Properties: depth 25 mm, 170 mm across at the rim, steepest wall 55.7 deg at
r = 75.6 mm, slope < 1.6 deg for r <= 44.9 mm and < 5 deg for r <= 51 mm (a large flat
bottom), smallest concave radius of curvature 10.8 mm (> R, so a D16 ball has a single
contact point), smallest convex radius 3.8 mm (the rounded rim edge), flat land out to +-95 mm.

Why 25 mm deep: the paper gives no dimensions of its bowl, but its own figures fix the
path length: 53 min per layer at F279 is 14.8 m of path, and 2.34 dm^2 at a 1.6 mm stepover
is 14.6 m: its passes are barely longer than their projection, so the bowl is shallow.
At 25 mm our layer takes 59 min at F279 (40 mm deep gave 65 min).

Everything is deterministic: running ``python samples/make_bowl.py`` rewrites
``samples/bowl.stl`` and ``samples/bowl.mpf`` byte for byte. The module can also be loaded
with :mod:`importlib` from its file path; ``bench/make_case.py`` does that for the large case.
"""

from __future__ import annotations

import math
import os
import sys
import time

import numpy as np

# --------------------------------------------------------------------------- surface ----
RIM_RADIUS_MM = 85.0
"""Radius of the rim, where the bowl meets the flat land (mm)."""
DEPTH_MM = 25.0
"""Depth of the bowl below the land (mm)."""
EXPONENT = 10
"""Even exponent of the profile; larger makes the bottom flatter and the walls steeper."""
HALF_WIDTH_MM = 95.0
"""Half the side of the square the mesh covers (the land extends to |x|, |y| <= 95 mm)."""

# ------------------------------------------------------------------ paper tool and cut ----
TOOL_RADIUS_MM = 8.0
"""D16 ball-end mill of the paper's machining test."""
TEETH = 2
CUTTING_SPEED_M_PER_MIN = 70.0
FEED_PER_TOOTH_MM = 0.1
RPM = 1393
"""Nominal spindle speed: 1000 * 70 / (2 pi 8) = 1392.6 RPM."""
FEED_MM_PER_MIN = 279
"""Nominal feed: 0.1 * 2 * 1393 = 278.6 mm/min."""
BOUNDARY_RADIUS_MM = 87.0
"""Passes end on the land at this distance from the axis (2 mm outside the rim)."""

SAMPLE_MESH_STEP_MM = 0.8
"""Nominal grid step of the committed ``bowl.stl`` (238 x 238 cells, 113288 triangles)."""

_HERE = os.path.dirname(os.path.abspath(__file__))


def _ipow(a, n):
    """``a**n`` for a non-negative integer n by repeated squaring (faster than np.power)."""
    result = None
    base = a
    while n:
        if n & 1:
            result = base if result is None else result * base
        n >>= 1
        if n:
            base = base * base
    return np.ones_like(a) if result is None else result


def _profile_f(r2):
    """Profile height ``f`` (mm) as a function of ``r2 = r**2`` (only the height, for speed)."""
    u2 = np.minimum(np.asarray(r2, dtype=np.float64) * (1.0 / RIM_RADIUS_MM**2), 1.0)
    w = 1.0 - _ipow(u2, EXPONENT // 2)
    return (-DEPTH_MM) * (w * w * w)


def _profile_parts(r2):
    """Return ``(f, q, fpp)`` of the profile as functions of ``r2 = r**2``.

    ``f`` is the height (mm), ``q = f'(r) / r`` (1/mm, so that grad z = q * (x, y) without a
    division by r) and ``fpp = f''(r)`` (1/mm). All three are zero on the land.
    """
    half = EXPONENT // 2
    u2 = np.minimum(np.asarray(r2, dtype=np.float64) * (1.0 / RIM_RADIUS_MM**2), 1.0)
    um2 = _ipow(u2, half - 1)  # u**(p-2)
    v = um2 * u2  # u**p
    w = 1.0 - v  # 0 on the land (u2 clipped to 1), so f, q and fpp vanish there
    c = 3.0 * DEPTH_MM * EXPONENT / RIM_RADIUS_MM**2
    f = (-DEPTH_MM) * (w * w * w)
    q = c * um2 * w * w
    fpp = c * um2 * w * ((EXPONENT - 1) * w - 2.0 * EXPONENT * v)
    return f, q, fpp


def bowl_profile_z_mm(r_mm):
    """Height of the bowl profile at a distance from the axis.

    Parameters
    ----------
    r_mm : array_like
        Distance from the bowl axis (mm). Negative values are mirrored (f is even).

    Returns
    -------
    numpy.ndarray
        ``f(r)`` (mm): ``-DEPTH_MM * (1 - (r/RIM_RADIUS_MM)**EXPONENT)**3`` inside the rim,
        0 on the land.
    """
    r = np.asarray(r_mm, dtype=np.float64)
    return _profile_f(r * r) + 0.0  # + 0.0 turns -0.0 on the land into 0.0


def bowl_profile_slope(r_mm):
    """First derivative ``df/dr`` of the profile (dimensionless, tangent of the slope angle).

    Parameters
    ----------
    r_mm : array_like
        Distance from the axis (mm); for negative values the derivative of ``f(|r|)`` with
        respect to the signed coordinate is returned (odd in r).

    Returns
    -------
    numpy.ndarray
        ``f'(r)``; ``degrees(arctan(f'))`` is the wall angle against the XY plane.
    """
    r = np.asarray(r_mm, dtype=np.float64)
    return r * _profile_parts(r * r)[1]


def bowl_profile_curvature_per_mm(r_mm):
    """Second derivative ``d2f/dr2`` of the profile (1/mm), continuous everywhere.

    Parameters
    ----------
    r_mm : array_like
        Distance from the axis (mm).

    Returns
    -------
    numpy.ndarray
        ``f''(r)``; positive where the meridian is concave (valley), negative on the
        rounded rim edge, zero on the land and at the rim itself.
    """
    r = np.asarray(r_mm, dtype=np.float64)
    return _profile_parts(r * r)[2]


def bowl_z_mm(x_mm, y_mm):
    """Height of the bowl mould surface.

    Parameters
    ----------
    x_mm, y_mm : array_like
        Coordinates (mm), broadcast against each other. The bowl axis is the Z axis, the
        land is at z = 0.

    Returns
    -------
    numpy.ndarray
        Surface height z (mm), same shape as the broadcast inputs.
    """
    x = np.asarray(x_mm, dtype=np.float64)
    y = np.asarray(y_mm, dtype=np.float64)
    return _profile_f(x * x + y * y) + 0.0


def bowl_normal(x_mm, y_mm):
    """Unit surface normal pointing out of the material (up, toward the tool).

    Parameters
    ----------
    x_mm, y_mm : array_like
        Coordinates (mm), broadcast against each other.

    Returns
    -------
    numpy.ndarray
        Array of shape ``broadcast_shape + (3,)`` (``(n, 3)`` for 1-D input) with
        ``n = (-dz/dx, -dz/dy, 1) / |...|``; ``n_z > 0`` everywhere.
    """
    x, y = np.broadcast_arrays(np.asarray(x_mm, dtype=np.float64), np.asarray(y_mm, dtype=np.float64))
    q = _profile_parts(x * x + y * y)[1]
    gx = q * x
    gy = q * y
    inv = 1.0 / np.sqrt(1.0 + gx * gx + gy * gy)
    return np.stack((-gx * inv, -gy * inv, inv), axis=-1)


# ------------------------------------------------------------------------------ mesh ----
def bowl_mesh(step_mm, half_width_mm=HALF_WIDTH_MM):
    """Triangulate the surface over the square ``|x|, |y| <= half_width_mm``.

    A regular grid with ``n = round(2 * half_width_mm / step_mm)`` cells per side (the real
    step is ``2 * half_width_mm / n``), each cell split into two triangles with the diagonal
    alternating in a checkerboard pattern. Vertices lie exactly on the analytic surface;
    triangles are counter-clockwise seen from above, so facet normals point up (out of
    the material).

    Parameters
    ----------
    step_mm : float
        Nominal grid step (mm); the edge length along X and Y.
    half_width_mm : float, optional
        Half the side of the covered square (mm).

    Returns
    -------
    V : numpy.ndarray
        ``(nv, 3)`` float64 vertex coordinates (mm), ``nv = (n + 1)**2``.
    F : numpy.ndarray
        ``(nf, 3)`` int64 vertex indices, ``nf = 2 * n**2``.
    """
    n = max(1, int(round(2.0 * half_width_mm / step_mm)))
    g = np.linspace(-half_width_mm, half_width_mm, n + 1)
    X, Y = np.meshgrid(g, g, indexing="ij")  # vertex (i, j) -> index i * (n + 1) + j
    V = np.column_stack((X.ravel(), Y.ravel(), bowl_z_mm(X, Y).ravel()))
    i, j = np.meshgrid(np.arange(n, dtype=np.int64), np.arange(n, dtype=np.int64), indexing="ij")
    i = i.ravel()
    j = j.ravel()
    v00 = i * (n + 1) + j
    v10 = v00 + (n + 1)  # +x
    v01 = v00 + 1  # +y
    v11 = v10 + 1
    even = ((i + j) % 2 == 0)[:, None]
    t1 = np.where(even, np.column_stack((v00, v10, v11)), np.column_stack((v00, v10, v01)))
    t2 = np.where(even, np.column_stack((v00, v11, v01)), np.column_stack((v10, v11, v01)))
    F = np.empty((2 * n * n, 3), dtype=np.int64)
    F[0::2] = t1
    F[1::2] = t2
    return V, F


def write_stl(path, V, F, name="ncopt bowl mould"):
    """Write a triangle mesh as a binary STL with numpy-stl.

    The 80-byte header is fixed (no time stamp), so equal meshes give equal files.
    Facet normals are the unit normals of the triangles (counter-clockwise winding).

    Parameters
    ----------
    path : str or os.PathLike
        Output file.
    V : numpy.ndarray
        ``(nv, 3)`` vertex coordinates (mm).
    F : numpy.ndarray
        ``(nf, 3)`` vertex indices.
    name : str, optional
        Text put into the header.

    Returns
    -------
    int
        Number of bytes written (``84 + 50 * nf``).
    """
    from stl import mesh as stl_mesh

    header = ("binary STL: " + name)[:80].ljust(80)

    class _FixedHeaderMesh(stl_mesh.Mesh):
        def get_header(self, name):  # noqa: D401 - numpy-stl hook
            return header

    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    data = np.zeros(len(F), dtype=stl_mesh.Mesh.dtype)
    tri = V[F]
    nrm = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(nrm, axis=1, keepdims=True)
    nrm = np.divide(nrm, length, out=np.zeros_like(nrm), where=length > 0)
    data["vectors"] = tri
    data["normals"] = nrm
    del tri, nrm
    m = _FixedHeaderMesh(data, calculate_normals=False)
    m.save(os.fspath(path), mode=2, update_normals=False)  # 2 = stl.Mode.BINARY
    return os.path.getsize(path)


# ------------------------------------------------------------------ ball drop-cutter ----
_DROP_SAMPLES = 33  # angles sampled over the lower half of the ball before refining
_DROP_CHUNK = 65536


def _drop_meridian(r, radius_mm):
    """Exact drop of a ball onto the profile along the radial line at distance ``r``.

    The contact lies in the meridian plane through the tool axis (for a fixed distance from
    the bowl axis the surface height is constant and the ball is highest where that circle
    is nearest to the tool axis). Parametrise the lower half of the ball by the angle
    ``phi`` from the tool axis: the point of the ball ``(r + R sin(phi), zc - R cos(phi))``
    touches the surface at the maximum over phi of ``g(phi) = f(r + R sin(phi)) + R cos(phi)``
    which is the ball-centre height ``zc``. Sample phi densely, then a safeguarded Newton
    iteration on ``g'(phi) = 0`` (bisection fallback inside the bracket of the best sample).

    Returns ``(zc, phi)`` with ``zc`` the ball-centre height (mm) and ``phi`` the contact
    angle (rad, positive when the contact lies farther from the bowl axis than the tool
    axis).
    """
    R = float(radius_mm)
    r = np.asarray(r, dtype=np.float64)
    K = _DROP_SAMPLES
    phis = np.linspace(-0.5 * np.pi, 0.5 * np.pi, K)
    sin_k = R * np.sin(phis)
    cos_k = R * np.cos(phis)
    S = r[:, None] + sin_k[None, :]
    G = _profile_f(S * S)
    G += cos_k[None, :]
    k = np.argmax(G, axis=1)
    g_best = G[np.arange(len(r)), k]
    del S, G
    a = phis[np.maximum(k - 1, 0)]
    b = phis[np.minimum(k + 1, K - 1)]
    phi = phis[k]
    for _ in range(60):
        sn = np.sin(phi)
        cs = np.cos(phi)
        s = r + R * sn
        _, q, fpp = _profile_parts(s * s)
        fp = s * q
        gp = R * (cs * fp - sn)
        gpp = R * (R * cs * cs * fpp - sn * fp - cs)
        up = gp > 0.0
        a = np.where(up, phi, a)
        b = np.where(up, b, phi)
        with np.errstate(divide="ignore", invalid="ignore"):
            newton = phi - gp / gpp
        ok = (gpp < 0.0) & (newton >= a) & (newton <= b)
        new = np.where(ok, newton, 0.5 * (a + b))
        done = np.max(np.abs(new - phi), initial=0.0) < 1e-13
        phi = new
        if done:
            break
    s = r + R * np.sin(phi)
    zc = _profile_f(s * s) + R * np.cos(phi)
    zc = np.maximum(zc, g_best)  # the refined maximum can only be higher than a sample
    return zc, phi


def drop_ball_contact(x_mm, y_mm, radius_mm=TOOL_RADIUS_MM):
    """Exact drop-cutter of a ball-end mill on the analytic bowl, with the contact.

    Parameters
    ----------
    x_mm, y_mm : array_like
        Tool-axis position (mm), broadcast against each other (3-axis: axis along +Z).
    radius_mm : float, optional
        Ball radius R (mm).

    Returns
    -------
    tip_z_mm : numpy.ndarray
        Height of the tool tip (ball centre z - R) where the ball touches the surface
        without gouging it, shape of the broadcast inputs. Accurate to ~1e-9 mm.
    contact_mm : numpy.ndarray
        ``shape + (3,)``: the contact point on the surface (mm). On the axis of the bowl
        (r = 0) and on flat areas the contact is directly below the tip.
    normal : numpy.ndarray
        ``shape + (3,)``: the outward unit surface normal at the contact, equal to
        ``(ball centre - contact) / R``.
    """
    x, y = np.broadcast_arrays(np.asarray(x_mm, dtype=np.float64), np.asarray(y_mm, dtype=np.float64))
    shape = x.shape
    x = x.ravel()
    y = y.ravel()
    R = float(radius_mm)
    n = x.size
    tip = np.empty(n)
    contact = np.empty((n, 3))
    for lo in range(0, n, _DROP_CHUNK):
        hi = min(n, lo + _DROP_CHUNK)
        xc = x[lo:hi]
        yc = y[lo:hi]
        r = np.hypot(xc, yc)
        zc, phi = _drop_meridian(r, R)
        t = R * np.sin(phi)
        safe = r > 0.0
        rs = np.where(safe, r, 1.0)
        ux = np.where(safe, xc / rs, 1.0)
        uy = np.where(safe, yc / rs, 0.0)
        contact[lo:hi, 0] = xc + t * ux
        contact[lo:hi, 1] = yc + t * uy
        tip[lo:hi] = zc - R
    contact[:, 2] = bowl_z_mm(contact[:, 0], contact[:, 1])
    normal = bowl_normal(contact[:, 0], contact[:, 1])
    return tip.reshape(shape), contact.reshape(shape + (3,)), normal.reshape(shape + (3,))


def drop_ball_tip_z_mm(x_mm, y_mm, radius_mm=TOOL_RADIUS_MM):
    """Tool-tip height of a ball-end mill dropped onto the analytic bowl.

    Parameters
    ----------
    x_mm, y_mm : array_like
        Tool-axis position (mm), broadcast against each other.
    radius_mm : float, optional
        Ball radius R (mm).

    Returns
    -------
    numpy.ndarray
        z of the tool tip (= ball centre z - R, mm) with the ball touching the surface
        and never penetrating it, ``max over t in [-R, R] of f(|r + t|) + sqrt(R**2 - t**2)
        - R`` along the radial line; vectorised, chunked, ~1e-9 mm accurate.
    """
    x, y = np.broadcast_arrays(np.asarray(x_mm, dtype=np.float64), np.asarray(y_mm, dtype=np.float64))
    r = np.hypot(x, y).ravel()
    out = np.empty(r.size)
    for lo in range(0, r.size, _DROP_CHUNK):
        hi = min(r.size, lo + _DROP_CHUNK)
        out[lo:hi] = _drop_meridian(r[lo:hi], radius_mm)[0] - float(radius_mm)
    return out.reshape(x.shape)


# ------------------------------------------------------------------------- toolpath ----
def pass_y_positions_mm(stepover_mm=1.6, boundary_radius_mm=BOUNDARY_RADIUS_MM):
    """Y of the zig-zag passes: multiples of the stepover, symmetric, one pass at Y = 0.

    Parameters
    ----------
    stepover_mm : float
        Distance between passes along Y (mm).
    boundary_radius_mm : float
        Passes lie inside the circle of this radius; the outermost pass keeps 0.5 mm to it.

    Returns
    -------
    numpy.ndarray
        Increasing Y values (mm).
    """
    k = int(math.floor((boundary_radius_mm - 0.5) / stepover_mm + 1e-9))
    return stepover_mm * np.arange(-k, k + 1, dtype=np.float64)


def toolpath_layout(radius_mm=TOOL_RADIUS_MM, stepover_mm=1.6, step_mm=0.75,
                    boundary_radius_mm=BOUNDARY_RADIUS_MM, oversample=4):
    """X positions of the points of every zig-zag pass (no exact drop yet).

    Each pass at constant Y runs between the two points where it crosses the boundary
    circle (on the flat land, where the tip height is exactly 0). Points are spaced evenly
    in 3-D arc length of the tool-tip curve, about ``step_mm`` apart (never more), using a
    tabulated tip height; even passes run toward +X, odd ones toward -X.

    Parameters
    ----------
    radius_mm : float
        Ball radius (mm).
    stepover_mm : float
        Distance between passes along Y (mm).
    step_mm : float
        Largest distance between consecutive points along a pass (mm).
    boundary_radius_mm : float
        Radius of the circle the passes end on (mm).
    oversample : int
        Fine samples per ``step_mm`` used to measure the arc length.

    Returns
    -------
    list of (float, numpy.ndarray)
        ``(y_mm, x_mm)`` per pass in machining order.
    """
    r_tab = np.linspace(0.0, boundary_radius_mm + 1.0, int((boundary_radius_mm + 1.0) / 0.02) + 1)
    z_tab = drop_ball_tip_z_mm(r_tab, 0.0, radius_mm)
    out = []
    fine = step_mm / oversample
    for i, y in enumerate(pass_y_positions_mm(stepover_mm, boundary_radius_mm)):
        X = math.sqrt(max(boundary_radius_mm**2 - y * y, 0.0))
        m = max(2, int(math.ceil(2.0 * X / fine)) + 1)
        xf = np.linspace(-X, X, m)
        zf = np.interp(np.hypot(xf, y), r_tab, z_tab)
        cum = np.concatenate(([0.0], np.cumsum(np.hypot(np.diff(xf), np.diff(zf)))))
        nseg = max(1, int(math.ceil(cum[-1] / step_mm - 1e-9)))
        xs = np.interp(np.linspace(0.0, cum[-1], nseg + 1), cum, xf)
        xs[0], xs[-1] = -X, X
        if i % 2:
            xs = xs[::-1].copy()
        out.append((float(y), xs))
    return out


def count_blocks(layout):
    """Number of NC blocks :func:`make_program` writes for a layout.

    Parameters
    ----------
    layout : list of (float, numpy.ndarray)
        Output of :func:`toolpath_layout`.

    Returns
    -------
    int
        Blocks with an N number (6 set-up blocks, one per toolpath point, 4 at the end).
    """
    return 6 + sum(len(xs) for _, xs in layout) + 4


def toolpath_points(radius_mm=TOOL_RADIUS_MM, stepover_mm=1.6, step_mm=0.75,
                    boundary_radius_mm=BOUNDARY_RADIUS_MM):
    """Tool-tip points of the zig-zag finishing toolpath, in machining order.

    Parameters
    ----------
    radius_mm, stepover_mm, step_mm, boundary_radius_mm : float
        See :func:`toolpath_layout`.

    Returns
    -------
    xyz_mm : numpy.ndarray
        ``(n, 3)`` tool-tip positions (mm) from the exact drop-cutter.
    pass_index : numpy.ndarray
        ``(n,)`` int64 index of the pass of each point; consecutive points of one pass
        share Y, the first point of each later pass is reached by a link move on the land.
    """
    layout = toolpath_layout(radius_mm, stepover_mm, step_mm, boundary_radius_mm)
    x = np.concatenate([xs for _, xs in layout])
    y = np.concatenate([np.full(len(xs), yv) for yv, xs in layout])
    idx = np.concatenate([np.full(len(xs), i, dtype=np.int64) for i, (_, xs) in enumerate(layout)])
    z = drop_ball_tip_z_mm(x, y, radius_mm)
    return np.column_stack((x, y, z)), idx


def _fmt_words(letter, vals_um, changed):
    return [f" {letter}{v / 1000:.3f}" if c else "" for v, c in zip(vals_um.tolist(), changed.tolist())]


def make_program(radius_mm=TOOL_RADIUS_MM, stepover_mm=1.6, step_mm=0.75, feed=FEED_MM_PER_MIN,
                 rpm=RPM, boundary_radius_mm=BOUNDARY_RADIUS_MM, clearance_z_mm=15.0,
                 approach_mm=3.0, tool="T04 D01", work_offset="G55", first_n=100, n_step=2,
                 title="ncopt sample: bowl mould finishing (Vavruska et al. 2023, sections 5-6)"):
    """Sinumerik-840D-style finishing program for the bowl, as in the paper's listing.

    Layout::

        ; header comments
        N100 T04 D01
        N102 G55
        N104 S1393 M03
        N106 G0 X.. Y.. Z15.000         rapid above the first point
        N108 M08
        N110 G1 Z3.000 F279             feed approach (modal G1 and F from here on)
        N112 Z0.000                     plunge onto the first point (on the land)
        N114 X.. Z..                    zig-zag passes in X-Z at constant Y ...
        N.. X.. Y.. (Z..)               link to the next pass: a short feed move on the land
        ...
        N.. G0 Z15.000 / M09 / M05 / M30

    Points are tool-tip positions from the exact drop-cutter; coordinates have 3 decimals
    and a word is written only when its value changes (modal axes, like a CAM post).

    Parameters
    ----------
    radius_mm : float
        Ball radius (mm); the sample uses the paper's D16 ball, R = 8.
    stepover_mm : float
        Distance between passes along Y (mm).
    step_mm : float
        Largest 3-D distance between points along a pass (mm).
    feed : int
        Feed rate F (mm/min) of the approach block, modal for the whole cut.
    rpm : int
        Spindle speed S (RPM).
    boundary_radius_mm : float
        Passes start and end on the land at this distance from the bowl axis (mm).
    clearance_z_mm : float
        Height of the rapid approach and the final retract (mm).
    approach_mm : float
        Height above the first point where the feed approach ends (mm).
    tool : str
        Tool-change block words.
    work_offset : str
        Work offset block word.
    first_n, n_step : int
        First block number and increment.
    title : str
        First header comment.

    Returns
    -------
    str
        Program text, ``\\n`` line endings, ending with a newline.
    """
    pts, _ = toolpath_points(radius_mm, stepover_mm, step_mm, boundary_radius_mm)
    um = np.rint(pts * 1000.0).astype(np.int64)
    xi, yi, zi = um[:, 0], um[:, 1], um[:, 2]
    x0, y0, z0 = (v / 1000 for v in (int(xi[0]), int(yi[0]), int(zi[0])))
    n_prog = len(pts) + 10
    header = [
        f"; {title}",
        "; generated by samples/make_bowl.py (deterministic; do not edit by hand)",
        f"; surface: z = -{DEPTH_MM:g}*(1-(r/{RIM_RADIUS_MM:g})^{EXPONENT})^3 mm for r < {RIM_RADIUS_MM:g}, "
        f"z = 0 on the land, r = sqrt(x^2+y^2)",
        f"; tool: {tool.split()[0]} ball end mill D{2 * radius_mm:g} (R {radius_mm:g} mm), z {TEETH}; "
        f"S{rpm} F{feed}",
        f"; strategy: zig-zag passes in the X-Z plane, stepover {stepover_mm:g} mm along Y, "
        f"<= {step_mm:g} mm between points",
        f"; coordinates: tool tip (ball centre - R), work offset {work_offset}; {n_prog} blocks",
    ]
    nums = iter(range(first_n, first_n + n_step * (n_prog + 1), n_step))
    lines = header + [
        f"N{next(nums)} {tool}",
        f"N{next(nums)} {work_offset}",
        f"N{next(nums)} S{rpm} M03",
        f"N{next(nums)} G0 X{x0:.3f} Y{y0:.3f} Z{clearance_z_mm:.3f}",
        f"N{next(nums)} M08",
        f"N{next(nums)} G1 Z{z0 + approach_mm:.3f} F{feed}",
    ]
    chunks = ["\n".join(lines)]
    # modal state after the approach block
    px, py, pz = int(xi[0]), int(yi[0]), int(np.rint((z0 + approach_mm) * 1000))
    n_first = next(nums)
    CH = 100_000
    for lo in range(0, len(pts), CH):
        hi = min(len(pts), lo + CH)
        cx = xi[lo:hi] != np.concatenate(([px], xi[lo:hi - 1]))
        cy = yi[lo:hi] != np.concatenate(([py], yi[lo:hi - 1]))
        cz = zi[lo:hi] != np.concatenate(([pz], zi[lo:hi - 1]))
        none = ~(cx | cy | cz)
        cz |= none  # never write an empty block: repeat Z if a point does not move
        px, py, pz = int(xi[hi - 1]), int(yi[hi - 1]), int(zi[hi - 1])
        ns = [f"N{n}" for n in range(n_first + n_step * lo, n_first + n_step * hi, n_step)]
        wx = _fmt_words("X", xi[lo:hi], cx)
        wy = _fmt_words("Y", yi[lo:hi], cy)
        wz = _fmt_words("Z", zi[lo:hi], cz)
        chunks.append("\n".join([a + b + c + d for a, b, c, d in zip(ns, wx, wy, wz)]))
        del ns, wx, wy, wz
    nums = iter(range(n_first + n_step * len(pts), n_first + n_step * (len(pts) + 4), n_step))
    chunks.append("\n".join([
        f"N{next(nums)} G0 Z{clearance_z_mm:.3f}",
        f"N{next(nums)} M09",
        f"N{next(nums)} M05",
        f"N{next(nums)} M30",
    ]))
    return "\n".join(chunks) + "\n"


def write_text(path, text):
    """Write text with ``\\n`` line endings (ASCII); return the size in bytes."""
    with open(path, "w", encoding="ascii", newline="\n") as fh:
        fh.write(text)
    return os.path.getsize(path)


def main(out_dir=_HERE):
    """Write ``bowl.stl`` and ``bowl.mpf`` into ``out_dir`` (default: this file's folder).

    Parameters
    ----------
    out_dir : str
        Output folder.

    Returns
    -------
    dict
        Paths, sizes and counts of what was written.
    """
    t0 = time.perf_counter()
    V, F = bowl_mesh(SAMPLE_MESH_STEP_MM)
    stl_path = os.path.join(out_dir, "bowl.stl")
    stl_bytes = write_stl(stl_path, V, F)
    text = make_program()
    mpf_path = os.path.join(out_dir, "bowl.mpf")
    mpf_bytes = write_text(mpf_path, text)
    n_blocks = sum(1 for line in text.splitlines() if line.startswith("N"))
    step = 2.0 * HALF_WIDTH_MM / round(2.0 * HALF_WIDTH_MM / SAMPLE_MESH_STEP_MM)
    info = dict(stl=stl_path, stl_bytes=stl_bytes, triangles=len(F), mesh_step_mm=step,
                mpf=mpf_path, mpf_bytes=mpf_bytes, blocks=n_blocks, seconds=time.perf_counter() - t0)
    print(f"wrote {stl_path}: {len(F)} triangles, grid step {step:.4f} mm "
          f"(diagonal {step * math.sqrt(2):.4f} mm), {stl_bytes} bytes")
    print(f"wrote {mpf_path}: {n_blocks} blocks, {mpf_bytes} bytes ({info['seconds']:.2f} s)")
    return info


if __name__ == "__main__":
    main(*sys.argv[1:2])
