"""Toolpath -> contacts: where the cutter touches the part, per sample point.

With a mesh, the planner's samples are every block end and, inside a move, only
where the geometry asks for them (:mod:`ncopt.contacts.sampling`), and the contacts come
from closest-point queries (:mod:`ncopt.contacts.geometry`); a 5-axis toolpath is sampled
evenly, at most ``AXIS_SAMPLE_MM`` apart.  Without a mesh, the CL points
themselves are the samples and the normals come from the toolpath's own shape
(:mod:`ncopt.contacts.pathnormals`); between two points the normal is their
interpolation, so no interior samples are needed.  ``sample_points`` spaces
samples evenly (the simulator's), at most ``MAX_SAMPLES_PER_MOVE`` per move.

The cutter centre is the programmed point moved ``tools.center_offset_mm``
along the tool axis: +Z, or in 5 axes ``Toolpath.tool_axis`` (between two
points the blend of theirs, :func:`sample_axes`), and R_eff is measured from
that axis.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ncopt.contacts.geometry import MeshIndex, mesh_contacts
from ncopt.motion.kinematics import KINEMATICS, blend
from ncopt.runtime.memory import release_freed_memory
from ncopt.model import Method, Contacts, Cutter, Toolpath
from ncopt.contacts.pathnormals import NO_CROSS, ONE_SIDED, ONE_SIDED_TILT_DEG, PathNormals
from ncopt.contacts.pathnormals import across as across_axis
from ncopt.contacts.pathnormals import contacts_from_path, tilt_from_axis
from ncopt.contacts.remaining import r_eff_material_mm
from ncopt.contacts.runends import end_normals
from ncopt.contacts.touchedges import with_touch_edges
from ncopt.contacts.sampling import Probe, Refinement, adaptive_samples
from ncopt.contacts.cutters import center_offset_mm, r_eff_mm


# With a tilted tool the contact moves along the ball within a block as the axis turns,
# and a ramp onto or off the surface touches along a few tenths of a mm only: 5-axis
# toolpaths are sampled at least this finely with a mesh (the D10 dome of
# bench/make_5axis.py: 1 mm left vc +1.1 % and a lead-out at fz -57 %; 0.25 mm: +0.4 %).
AXIS_SAMPLE_MM = 0.25
# Without a mesh, R_eff inside a move comes from its ends' normals blended and the axis the
# control turns between them; where the axis turns, R_eff can peak inside the move (rotary
# angles turned linearly bulge off the great circle, most where A is near 0 and C swings:
# +0.5 % mid-block on the xyzac-trt flowline bowl of bench/make_5axis.py).  Such moves are
# sampled every this many degrees of turn (at most MAX_INSIDE pieces), and their ends
# planned with the largest R_eff found.
INSIDE_TURN_DEG = 1.0
MAX_INSIDE = 32
# Without a mesh, a plunge or retract is proved to be in the air where its lower end stays
# above the highest point the tool cuts, less this (a plunge that ends where the cut
# begins, at its top, touches the part only there).
AIR_CLEARANCE_MM = 0.01
# With a mesh, a cut along the surface this many cutter radii from every face, below the top
# of the cut, is not taken for air (the mesh may lack that part): _air_below_the_top
AIR_FAR = 0.25

# Evenly spaced samples stop at this many per move: a longer move is sampled every
# length / MAX_SAMPLES_PER_MOVE (10 m at 0.1 mm; memory stays bounded by the moves).
MAX_SAMPLES_PER_MOVE = 100_000


@dataclass(frozen=True)
class Sampled:
    """Contacts and, per sample, the index of the toolpath point whose move it is on."""

    contacts: Contacts
    point: np.ndarray  # (m,) int
    estimate: PathNormals | None = None  # mesh-free only
    gap_mm: np.ndarray | None = None  # (m,) with a mesh: clearance of the cutter, mm (< 0 inside)
    axis: np.ndarray | None = None  # (m, 3) unit tool axis per sample; None: +Z
    # (m,) bool: planned at the cutter's largest radius, the contact being unknown
    # (without a mesh, :func:`unknown_contact`; with one, :func:`_air_below_the_top`)
    unknown: np.ndarray | None = None
    top_mm: float = float("inf")  # the highest point the cuts reach (mm, along up)
    up: np.ndarray | None = None  # (3,) the direction of top_mm (up_vector)


def samples_per_move(tp: Toolpath, sample_mm: float) -> np.ndarray:
    """(n-1,) evenly spaced samples of each move: at most ``sample_mm`` apart, at
    least one, at most ``MAX_SAMPLES_PER_MOVE``."""
    seg = np.linalg.norm(np.diff(tp.xyz_mm, axis=0), axis=1)
    return np.clip(np.ceil(seg / sample_mm), 1, MAX_SAMPLES_PER_MOVE).astype(np.int64)


def sample_fractions(tp: Toolpath, sample_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """Per sample: the toolpath point whose move it lies on, and how far along (0..1].

    Samples are at most ``sample_mm`` apart (``length / MAX_SAMPLES_PER_MOVE`` on a
    longer move) and end on each CL point; the first sample is point 0 itself
    (fraction 1).
    """
    n_per = samples_per_move(tp, sample_mm)
    point = np.concatenate(([0], np.repeat(np.arange(1, tp.n), n_per)))
    offsets = np.concatenate(([0], np.cumsum(n_per)))
    k = np.arange(1, offsets[-1] + 1) - np.repeat(offsets[:-1], n_per)
    frac = np.concatenate(([1.0], k / np.repeat(n_per, n_per)))
    return point, frac


def sample_points(tp: Toolpath, sample_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """Points along every move, at most ``sample_mm`` apart (see
    :func:`sample_fractions`), ending on each CL point.

    Returns xyz (m, 3) in mm and, per sample, the index of the toolpath point
    whose move it lies on (point 0 for the start point).
    """
    point, frac = sample_fractions(tp, sample_mm)
    a = tp.xyz_mm[np.maximum(point - 1, 0)]
    b = tp.xyz_mm[point]
    return a + (b - a) * frac[:, None], point


def sample_axes(tp: Toolpath, sample_mm: float) -> np.ndarray | None:
    """Unit tool axis at each sample of :func:`sample_points` (m, 3), blended between
    the points' axes as a TCP control moves it; None for a 3-axis toolpath."""
    if tp.tool_axis is None:
        return None
    point, frac = sample_fractions(tp, sample_mm)
    return axes_between(tp, np.maximum(point - 1, 0), point, frac)


def axes_between(tp: Toolpath, a: np.ndarray, b: np.ndarray, frac: np.ndarray) -> np.ndarray:
    """(m,) unit tool axes ``frac`` of the way from point ``a`` to point ``b``: rotary angles
    turned linearly where the kinematics gave both ends (as the control turns them),
    else the normalised blend of the end vectors (a vector along its great circle)."""
    e = blend(tp.tool_axis[a], tp.tool_axis[b], frac)
    if tp.tool_angles_deg is not None:
        a0, a1 = tp.tool_angles_deg[a], tp.tool_angles_deg[b]
        turn = np.isfinite(a0).all(axis=1) & np.isfinite(a1).all(axis=1) & (a0 != a1).any(axis=1)
        if turn.any():
            ang = a0[turn] + (a1[turn] - a0[turn]) * np.asarray(frac)[turn, None]
            e[turn] = KINEMATICS[tp.kinematics].tool_axis(ang)
    return e


def centre_offsets(tp: Toolpath, cutter: Cutter, axis: np.ndarray | None) -> np.ndarray:
    """(3,) or (m, 3): from the programmed point to the cutter centre, mm."""
    off = center_offset_mm(cutter)
    return np.array([0.0, 0.0, off]) if axis is None else off * axis


def path_contacts_at_samples(tp: Toolpath, cutter: Cutter, selected: np.ndarray,
                             sample_mm: float, group: np.ndarray | None = None) -> Contacts:
    """Mesh-free contacts on the samples of :func:`sample_points`: the per-point
    estimate, R_eff interpolated along each move (as the planner assumes).

    ``group``: (n,) int per toolpath point (e.g. its operation): each group's normals
    are estimated from its own moves only, and its samples take them (a roughing
    level beside a finishing pass is not the surface that pass finishes); samples of
    no selected group take the first one's."""
    point, frac = sample_fractions(tp, sample_mm)
    prev = np.maximum(point - 1, 0)
    ids = np.unique(group[selected]) if group is not None and selected.any() else ()
    if len(ids) <= 1:
        parts = [(selected, slice(None))]
    else:
        at = group[point]
        parts = [(selected & (group == g), (at == g) | (~np.isin(at, ids) if k == 0 else False))
                 for k, g in enumerate(ids.tolist())]
    r = np.empty(point.shape)
    normal = np.empty((point.size, 3))
    cutting = np.empty(point.shape, dtype=bool)
    xyz, _ = sample_points(tp, sample_mm)
    for sel, rows in parts:
        sampled = contacts_for(tp, cutter, sel, None, sample_mm, 0.0)
        at_points = sampled.contacts
        p, q, f = point[rows], prev[rows], frac[rows]
        r[rows] = at_points.r_eff_mm[q] * (1.0 - f) + at_points.r_eff_mm[p] * f
        normal[rows] = at_points.normal[q] * (1.0 - f)[:, None] + at_points.normal[p] * f[:, None]
        # where the contact is unknown (a plunge from above), only the samples at or below
        # the top of the cut can touch the part
        above = sampled.unknown[p] & (xyz[rows] @ sampled.up >= sampled.top_mm
                                      - AIR_CLEARANCE_MM)
        cutting[rows] = at_points.cutting[p] & ~above
    normal /= np.maximum(np.linalg.norm(normal, axis=1), 1e-12)[:, None]
    cc = xyz + centre_offsets(tp, cutter, sample_axes(tp, sample_mm)) \
        - cutter.corner_radius_mm * normal
    return Contacts(cc_mm=cc, normal=normal, r_eff_mm=r, cutting=cutting)


def mesh_contacts_at_samples(tp: Toolpath, cutter: Cutter, mesh_index: MeshIndex,
                             sample_mm: float, tol_mm: float) -> Contacts:
    """Contacts from the mesh on every sample of :func:`sample_points` (the simulator's
    evenly spaced samples: an original and its rewrite can share them)."""
    xyz, _ = sample_points(tp, sample_mm)
    axis = sample_axes(tp, sample_mm)
    return mesh_contacts(xyz + centre_offsets(tp, cutter, axis), mesh_index, cutter, tol_mm,
                         axis=axis).contacts


def unknown_contact(tp: Toolpath, selected: np.ndarray, air: np.ndarray,
                    estimate: PathNormals, up: np.ndarray, top_mm: float) -> np.ndarray:
    """(n,) bool: the points of ``selected`` feed moves whose contact the toolpath cannot
    tell, without a mesh.

    Two kinds: a plunge, retract or wall descent (:func:`air_moves`: no neighbouring
    pass to fit a normal to) that is not proved to be in the air, and a cut with no
    neighbouring pass at all (``NO_CROSS``: its slope across the path is unknown).  A
    move is proved to be in the air only where it stays above everything the tool cuts
    (its lower end at most ``AIR_CLEARANCE_MM`` under the highest point of the other
    cuts: a plunge that ends where the cut begins touches only there): a Fusion parallel
    pass over a tall part runs down the part's side and along the floor at its foot at
    the cutting feed, and the ball's side touches the wall all the way.  ``up``,
    ``top_mm``: :func:`up_vector` and :func:`top_of_cut`.
    """
    h = tp.xyz_mm @ up
    cuts = selected & ~air
    low = np.minimum(h, np.concatenate((h[:1], h[:-1])))  # the lower end of each move
    above = low >= top_mm - AIR_CLEARANCE_MM
    return (selected & air & ~above) | (cuts & (estimate.confidence == NO_CROSS))


def up_vector(tp: Toolpath, selected: np.ndarray) -> np.ndarray:
    """(3,) the direction "above the cut" is measured along: the tool axis where it is the
    same on every ``selected`` point (3 axes, 3+2), else Z (simultaneous 5 axes: the test
    is then the machine's Z, not a proof along every axis)."""
    axis = tp.tool_axis
    if axis is None:
        return np.array([0.0, 0.0, 1.0])
    rows = axis[selected]
    if rows.shape[0] and np.all(np.abs(rows - rows[0]) < 1e-9):
        return rows[0] / np.linalg.norm(rows[0])
    return np.array([0.0, 0.0, 1.0])


def top_of_cut(tp: Toolpath, selected: np.ndarray, air: np.ndarray, up: np.ndarray) -> float:
    """The highest tool point (mm, along ``up``) of the ``selected`` moves that are not
    plunges or retracts (``air``): above it a move is in the air, without a mesh."""
    return float(np.max(tp.xyz_mm[selected & ~air] @ up, initial=-np.inf))


def below_top_mm(tp: Toolpath, points: np.ndarray, top_mm: float,
                 up: np.ndarray) -> np.ndarray:
    """(k,) length (mm) of the moves ending at ``points`` that lies below the top of the
    cut (``top_mm`` along ``up``, less ``AIR_CLEARANCE_MM``): the part of a plunge from
    above the part that can touch it."""
    h1 = tp.xyz_mm[points] @ up
    h0 = tp.xyz_mm[np.maximum(points - 1, 0)] @ up
    lo, hi = np.minimum(h0, h1), np.maximum(h0, h1)
    span = hi - lo
    level = top_mm - AIR_CLEARANCE_MM
    frac = np.where(span > 1e-12, np.clip((level - lo) / np.where(span > 1e-12, span, 1.0),
                                          0.0, 1.0), (lo < level).astype(float))
    return tp.seg_len_mm[points] * frac


def _at_largest_radius(contacts: Contacts, unknown: np.ndarray, cutter: Cutter,
                       axis: np.ndarray | None) -> Contacts:
    """The contacts with the ``unknown`` points planned where the cutter cuts at its
    largest radius (a normal across the tool axis: R_eff = R, the lowest S): whatever
    the real contact there, vc stays at or below its target."""
    if not unknown.any():
        return contacts
    at = np.flatnonzero(unknown)
    across = (np.tile([1.0, 0.0, 0.0], (at.size, 1)) if axis is None
              else across_axis(axis[at]))  # +X for +Z
    normal, r_eff, cc = contacts.normal.copy(), contacts.r_eff_mm.copy(), contacts.cc_mm.copy()
    centre = cc[at] + cutter.corner_radius_mm * normal[at]
    normal[at] = across
    r_eff[at] = r_eff_mm(cutter, across, None if axis is None else axis[at])
    cc[at] = centre - cutter.corner_radius_mm * across
    cutting = contacts.cutting | unknown
    return Contacts(cc_mm=cc, normal=normal, r_eff_mm=r_eff, cutting=cutting)


def air_moves(tp: Toolpath) -> np.ndarray:
    """(n,) bool: feed moves that cannot be cutting when no mesh says otherwise:
    plunges and retracts (within 11 deg of vertical, or of the tool axis at their end).

    Other air moves are planned like cuts: with no neighbouring pass their
    normal is that of the move itself, which can only make them run faster.
    """
    d = np.diff(tp.xyz_mm, axis=0)
    length = np.maximum(np.linalg.norm(d, axis=1), 1e-12)
    air = np.abs(d[:, 2]) > 0.98 * length
    if tp.tool_axis is not None:  # 5 axes: also along the tilted tool (retract along the axis)
        air |= np.abs(np.einsum("ij,ij->i", d, tp.tool_axis[1:])) > 0.98 * length
    return np.concatenate(([False], air))


def contacts_for(tp: Toolpath, cutter: Cutter, selected: np.ndarray, mesh_index: MeshIndex | None,
                 sample_mm: float, tol_mm: float, method: Method = Method(),
                 stock_mm: float = 0.0, *, r_floor_mm: float = 0.0) -> Sampled:
    """Contacts of ``cutter`` along the toolpath, from the mesh if there is one
    (``stock_mm``: the allowance the program leaves on the mesh).

    With a mesh: every block end of the ``selected`` moves and, inside them, samples
    where the geometry asks for them (:mod:`ncopt.contacts.sampling`; ``sample_mm`` is the
    longest interval between samples where the tool cuts; below ``r_floor_mm`` the
    requirement is capped at S_max, so R_eff differences there need no samples).
    A 5-axis toolpath is sampled evenly, at most ``AXIS_SAMPLE_MM`` apart: the
    contact moves along the ball as the axis turns, which the adaptive refinement
    (built on a fixed axis) does not look for.
    """
    # the interpreter's leftovers (outside a rewrite); a rewrite keeps them for the contacts
    # to reuse, with a mesh too: forced here, the ~300 MB handed back were faulted in again
    # at once (system time +0.1-0.2 s) and the peak was no lower (paper case with the
    # mesh, 976-1017 MB kept against 996-1012 MB handed back)
    release_freed_memory(force=False)
    if mesh_index is not None and tp.tool_axis is not None:
        sample_mm = min(sample_mm, AXIS_SAMPLE_MM)
        xyz, point = sample_points(tp, sample_mm)
        axis = sample_axes(tp, sample_mm)
        found = mesh_contacts(xyz + centre_offsets(tp, cutter, axis), mesh_index, cutter, tol_mm,
                              stock_mm=stock_mm, axis=axis)
        sampled = Sampled(with_touch_edges(found.contacts, found.gap_mm, tol_mm), point,
                          gap_mm=found.gap_mm, axis=axis)
    elif mesh_index is not None:
        offset = centre_offsets(tp, cutter, None)
        ref = Refinement(coarse_mm=sample_mm, r_floor_mm=r_floor_mm, contact_tol_mm=tol_mm)
        got = adaptive_samples(tp.xyz_mm + offset, selected,
                               _mesh_probe(mesh_index, cutter, tol_mm, stock_mm), ref)
        p = got.probe
        sampled = Sampled(Contacts(cc_mm=p.cc_mm, normal=p.normal, r_eff_mm=p.r_eff_mm,
                                   cutting=p.cutting), got.point, gap_mm=p.gap_mm)
        sampled = _air_below_the_top(tp, cutter, selected, sampled, got.frac)
    else:
        air = air_moves(tp)
        cutting = selected & ~air
        if tp.tool_axis is None:
            centres = tp.xyz_mm + centre_offsets(tp, cutter, None)
            contacts, estimate = contacts_from_path(centres, np.cumsum(tp.seg_len_mm), cutting,
                                                    cutter)
        else:
            contacts, estimate = _path_contacts_5axis(tp, cutter, cutting)
        up = up_vector(tp, selected)
        top = top_of_cut(tp, selected, air, up)
        unknown = unknown_contact(tp, selected, air, estimate, up, top)
        sampled = Sampled(_at_largest_radius(contacts, unknown, cutter, tp.tool_axis),
                          np.arange(tp.n), estimate, axis=tp.tool_axis, unknown=unknown,
                          top_mm=top, up=up)
    if method.name == "material":
        sampled = replace(sampled, contacts=_with_material(tp, cutter, sampled, method))
    release_freed_memory(force=mesh_index is not None)
    return sampled


def _air_below_the_top(tp: Toolpath, cutter: Cutter, selected: np.ndarray, sampled: Sampled,
                       frac: np.ndarray) -> Sampled:
    """With a mesh (3 axes): the samples of cuts along the surface (not plunges or
    retracts) that the mesh puts far in the air (more than AIR_FAR cutter radii from
    every face) though they run below the top of the cut it touches.  A mesh that lacks
    part of the part (half of it, a floor) would have them planned as air, the spindle free (a half bowl: vc +787 %); they are planned where the
    cutter cuts at its full radius, as a contact the toolpath cannot show without a mesh.
    With the whole part, only a few samples of links and lead-ins are so."""
    c, point = sampled.contacts, sampled.point
    surface = (selected & ~air_moves(tp))[point]
    z = tp.xyz_mm[:, 2]
    before = np.maximum(point - 1, 0)
    height = z[before] + frac * (z[point] - z[before])
    touching = c.cutting & surface
    if not touching.any():
        return sampled
    top = float(height[touching].max())
    # farther from every face than a quarter of the cutter's radius: a block's chord over a
    # hollow of the part stays nearer (6 mm blocks over the wave of tests/unit/test_sampling:
    # 0.45 mm) and stays air; a part the mesh lacks is farther
    far = sampled.gap_mm > AIR_FAR * cutter.radius_mm
    unknown = surface & ~c.cutting & far & (height < top - AIR_CLEARANCE_MM)
    if not unknown.any():
        return sampled
    return replace(sampled, contacts=_at_largest_radius(c, unknown, cutter, None),
                   unknown=unknown, top_mm=top, up=np.array([0.0, 0.0, 1.0]))


def _path_contacts_5axis(tp: Toolpath, cutter: Cutter, cutting: np.ndarray):
    """Mesh-free contacts with a tilted axis: normals from the ball centres, along the
    centres' own path (the tip's is longer or shorter where the axis turns); one-sided
    normals planned steeper (as contacts_from_path), the ends of runs of cuts as
    :func:`ncopt.contacts.runends.end_normals` says, and the largest R_eff inside the
    moves that turn the axis (:func:`_inside_turns`) planned at their ends where it
    exceeds both."""
    centres = tp.xyz_mm + centre_offsets(tp, cutter, tp.tool_axis)
    est, end_tilt = end_normals(centres, cutting, tp.tool_axis)
    tilt = np.where(est.confidence == ONE_SIDED, np.radians(ONE_SIDED_TILT_DEG), 0.0)
    tilt = np.maximum(tilt, end_tilt)
    r_eff = r_eff_mm(cutter, tilt_from_axis(est.normal, tilt, tp.tool_axis), tp.tool_axis)
    # the start of a move plans it too (the end of the one before): only a peak above both
    # ends is carried, to the end
    peak = _inside_turns(tp, cutter, est.normal, tilt, cutting)
    before = np.concatenate(([0.0], r_eff[:-1]))
    r_eff = np.where(peak > np.maximum(r_eff, before), peak, r_eff)
    contacts = Contacts(cc_mm=centres - cutter.corner_radius_mm * est.normal,
                        normal=est.normal, r_eff_mm=r_eff, cutting=cutting.copy())
    return contacts, est


def _inside_turns(tp: Toolpath, cutter: Cutter, normal: np.ndarray, tilt: np.ndarray,
                  cutting: np.ndarray) -> np.ndarray:
    """(n,) the largest R_eff (mm) inside each cutting move between two cutting points
    that turns the tool axis (0 elsewhere), sampled every ``INSIDE_TURN_DEG`` of its turn:
    the axis as the control turns it, the tilt blended from the ends, the normal blended
    from the ends and turned with the ball centre where it leaves their chord (at the
    curvature the ends' normals show along the move)."""
    peak = np.zeros(tp.n)
    k = np.flatnonzero(cutting[1:] & cutting[:-1]) + 1
    e0, e1 = tp.tool_axis[k - 1], tp.tool_axis[k]
    turn = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", e0, e1), -1.0, 1.0)))
    if tp.tool_angles_deg is not None:
        swing = np.abs(tp.tool_angles_deg[k] - tp.tool_angles_deg[k - 1]).sum(axis=1)
        turn = np.maximum(turn, np.nan_to_num(swing))
    pieces = np.clip(np.ceil(turn / INSIDE_TURN_DEG), 1, MAX_INSIDE).astype(np.int64)
    k, pieces = k[pieces > 1], pieces[pieces > 1]
    if k.size == 0:
        return peak
    end = np.repeat(k, pieces - 1)
    first = np.repeat(np.cumsum(pieces - 1) - (pieces - 1), pieces - 1)
    frac = (np.arange(end.size) - first + 1) / np.repeat(pieces, pieces - 1)
    axis = axes_between(tp, end - 1, end, frac)
    f = frac[:, None]
    n = normal[end - 1] * (1.0 - f) + normal[end] * f
    n /= np.maximum(np.linalg.norm(n, axis=1), 1e-12)[:, None]
    # the ball centre leaves the chord of the end centres as the axis turns (by 0.2 mm where
    # C swings 160 deg at A 3 deg): the normal follows it by the curvature along the move
    off = center_offset_mm(cutter)
    p0, p1 = tp.xyz_mm[end - 1], tp.xyz_mm[end]
    c0, c1 = p0 + off * tp.tool_axis[end - 1], p1 + off * tp.tool_axis[end]
    away = p0 * (1.0 - f) + p1 * f + off * axis - (c0 * (1.0 - f) + c1 * f)
    away -= np.einsum("ij,ij->i", away, n)[:, None] * n
    chord = c1 - c0
    bend = np.einsum("ij,ij->i", normal[end] - normal[end - 1], chord) \
        / np.maximum(np.einsum("ij,ij->i", chord, chord), 1e-12)
    n += bend[:, None] * away
    n /= np.maximum(np.linalg.norm(n, axis=1), 1e-12)[:, None]
    t = tilt[end - 1] * (1.0 - frac) + tilt[end] * frac
    np.maximum.at(peak, end, r_eff_mm(cutter, tilt_from_axis(n, t, axis), axis))
    return peak


def _mesh_probe(mesh_index: MeshIndex, cutter: Cutter, tol_mm: float, stock_mm: float = 0.0):
    """The query :func:`ncopt.contacts.sampling.adaptive_samples` makes of the mesh."""
    flat_mm = cutter.radius_mm - cutter.corner_radius_mm

    def query(centers_mm: np.ndarray) -> Probe:
        mc = mesh_contacts(centers_mm, mesh_index, cutter, tol_mm, stock_mm=stock_mm)
        c = mc.contacts
        # a bull-nose's clearance is searched over its disc near the part only; the
        # centre's distance less the disc radius bounds it from below everywhere
        return Probe(c.r_eff_mm, c.normal, c.cc_mm, mc.gap_mm - flat_mm, c.cutting,
                     mc.gap_mm)

    return query


def _with_material(tp: Toolpath, cutter: Cutter, sampled: Sampled, method: Method) -> Contacts:
    """R_eff from the remaining material, with each sample's direction of motion."""
    d = (np.take(tp.xyz_mm, sampled.point, axis=0)
         - np.take(tp.xyz_mm, np.maximum(sampled.point - 1, 0), axis=0))
    r = r_eff_material_mm(cutter, sampled.contacts.normal, d, method.ap_mm, method.along,
                          sampled.axis)
    return replace(sampled.contacts, r_eff_mm=r)


def with_onsets(cutting: np.ndarray) -> np.ndarray:
    """(m,) the samples that cut, and the sample just before a contact begins and just
    after it ends.  With a mesh the sampling locates a contact's start to within two of
    its finest intervals (:mod:`ncopt.contacts.sampling`), and R_eff runs on between the
    samples on either side: the contact may begin with the R_eff of the sample that does
    not cut yet (a ball rolling onto an edge or a rim; a sample 0.1 mm into the contact
    took 0.78 mm where the cutting samples said 0.73), so that sample's requirement counts
    too, keeping vc at or below its target where the onset lies between them."""
    cut = np.asarray(cutting, dtype=bool)
    out = cut.copy()
    out[:-1] |= cut[1:]
    out[1:] |= cut[:-1]
    return out
