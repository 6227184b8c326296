"""The geometry an operation is classified by (:mod:`ncopt.planning.operations`).

Points about R/2 apart along an operation's feed moves, with the whole operation as
context: whether another pass runs near each (a finishing stepover), whether the nearest
other pass lies straight above or below (the same contour retraced at another depth: a
vertical wall), and for the samples at constant Z whether their grid cell is surrounded
at its level (an area is cleared) and how far up the next level is.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ncopt.contacts.kdtree import cKDTree
from ncopt.contacts.pathnormals import OTHER_PASS_RATIO
from ncopt.model import Toolpath
from ncopt.motion.modal import row_norms

SLOPE = 0.03  # |dz|/ds above which a move is sloped (1.7 deg)
MAX_SAMPLES = 60000
RETRACE_SAMPLES = 15000  # samples judged for vertical walls (each looks at 48 moves)
VERTICAL = 0.98  # the nearest other pass this close to straight above: a retraced contour


@dataclass(frozen=True)
class Samples:
    """Points about R/2 apart along one operation's feed moves, (m,) arrays."""

    xyz: np.ndarray  # (m, 3) mm
    s_mm: np.ndarray  # path length along the operation's feed moves
    weight_mm: np.ndarray  # path length each sample stands for
    sloped: np.ndarray
    point: np.ndarray  # toolpath point whose move the sample is on


def samples(tp: Toolpath, points: np.ndarray, spacing_mm: float) -> Samples:
    """Samples ``spacing_mm`` apart along the moves ending at ``points`` (indices into the
    toolpath), taken one after the other; at most ``MAX_SAMPLES`` (the spacing grows for
    long operations), so a million blocks cost no more than a few thousand.

    5 axes: with one tilted tool axis over them (3+2) the moves are seen in a frame whose
    Z is that axis (levels and slopes along the tool); where the axis turns (simultaneous
    5-axis) a move with the tool tilted follows the surface, whatever its tip's Z."""
    a, b = np.take(tp.xyz_mm, points - 1, axis=0), np.take(tp.xyz_mm, points, axis=0)
    turning = np.zeros(points.shape, dtype=bool)
    frame = _tool_frame(tp, points)
    if frame is not None:
        a, b = a @ frame.T, b @ frame.T
    elif tp.tool_axis is not None and points.size:
        turning = np.any(np.abs(tp.tool_axis[points][:, :2]) > 1e-9, axis=1)
    d = b - a
    length = row_norms(d)
    cum = np.concatenate(([0.0], np.cumsum(length)))
    total = float(cum[-1])
    spacing = max(spacing_mm, total / MAX_SAMPLES, 1e-3)
    s = (np.arange(max(int(total / spacing), 1)) + 0.5) * spacing
    s = s[s < total] if total > 0 else np.zeros(0)
    seg = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, max(points.size - 1, 0))
    frac = (s - cum[seg]) / np.maximum(length[seg], 1e-12)
    xyz = a[seg] + d[seg] * frac[:, None]
    sloped = (np.abs(d[:, 2]) > SLOPE * np.maximum(length, 1e-12)) | turning
    weight = np.full(s.shape, spacing)
    return Samples(xyz, s, weight, sloped[seg], points[seg])


def _tool_frame(tp: Toolpath, points: np.ndarray) -> np.ndarray | None:
    """The rotation into the frame whose Z is the one tool axis of the moves ending at
    ``points`` (3+2), None for +Z or a turning axis."""
    if tp.tool_axis is None or not points.size:
        return None
    e = tp.tool_axis[points]
    if not np.allclose(e, e[0], atol=1e-9) or np.allclose(e[0], (0.0, 0.0, 1.0), atol=1e-9):
        return None
    return _to_axis(e[0])


def _to_axis(e: np.ndarray) -> np.ndarray:
    """A rotation taking the unit vector ``e`` to +Z (the identity for +Z)."""
    z = np.array([0.0, 0.0, 1.0])
    v, c = np.cross(e, z), float(np.dot(e, z))
    if np.linalg.norm(v) < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    k = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return np.eye(3) + k + k @ k / (1.0 + c)


def neighbour_pass(sm: Samples, radius_mm: float) -> np.ndarray:
    """(m,) bool: another pass runs within ``radius_mm`` of the sample."""
    m = sm.xyz.shape[0]
    if m < 2:
        return np.zeros(m, dtype=bool)
    k = min(12, m)
    dist, j = cKDTree(sm.xyz).query(sm.xyz, k=k, distance_upper_bound=radius_mm, workers=-1)
    ok = np.isfinite(dist)
    j = np.where(ok, j, 0)
    other = ok & (np.abs(sm.s_mm[j] - sm.s_mm[:, None]) > OTHER_PASS_RATIO * np.maximum(dist, 1e-9))
    return other.any(axis=1)


def retraced(tp: Toolpath, geo: np.ndarray, sm: Samples, radius_mm: float) -> np.ndarray:
    """(m,) bool, for the constant-Z samples: the nearest point of another pass lies
    straight above or below them (the same contour retraced at another depth: a vertical
    wall).  The nearest point on the other pass's moves, not its nearest sample: a CAM
    writes each level with its own points."""
    out = np.zeros(sm.xyz.shape[0], dtype=bool)
    flat = np.flatnonzero(~sm.sloped)
    if flat.size == 0 or geo.size < 2:
        return out
    a, b = np.take(tp.xyz_mm, geo - 1, axis=0), np.take(tp.xyz_mm, geo, axis=0)
    frame = _tool_frame(tp, geo)  # 3+2: the samples are in the tool's frame, so the moves too
    if frame is not None:
        a, b = a @ frame.T, b @ frame.T
    length = row_norms(b - a)
    s_end = np.cumsum(length)
    stride = max(1, -(-flat.size // RETRACE_SAMPLES))  # every stride-th sample judged
    idx = flat[::stride]
    _, vertical = _other_pass(cKDTree(b), a, b, length, s_end, sm, idx,
                              min(24, geo.size), radius_mm)  # a dense contour: own points first
    out[flat] = vertical[np.arange(flat.size) // stride]  # its neighbours along the path alike
    return out


def _other_pass(tree, a, b, length, s_end, sm: Samples, idx: np.ndarray, k: int,
                radius_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """For the samples ``idx``: is another pass within ``radius_mm`` among the moves at
    the ``k`` nearest points, and is the nearest such one straight above or below."""
    q = sm.xyz[idx]
    _, j = tree.query(q, k=k, workers=-1)
    j = j.reshape(idx.size, -1)
    seg = np.concatenate((j, np.minimum(j + 1, b.shape[0] - 1)), axis=1)  # both moves at a point
    sa, sb = a[seg], b[seg]
    d = sb - sa
    t = np.clip(np.einsum("mkc,mkc->mk", q[:, None, :] - sa, d) /
                np.maximum(np.einsum("mkc,mkc->mk", d, d), 1e-24), 0.0, 1.0)
    off = sa + d * t[..., None] - q[:, None, :]
    dist = np.linalg.norm(off, axis=2)
    s_c = s_end[seg] - length[seg] * (1.0 - t)
    other = (dist <= radius_mm) & (np.abs(s_c - sm.s_mm[idx][:, None]) >
                                   OTHER_PASS_RATIO * np.maximum(dist, 1e-9))
    best = np.argmin(np.where(other, dist, np.inf), axis=1)
    rows = np.arange(idx.size)
    near = off[rows, best]
    found = other[rows, best]
    return found, found & (np.abs(near[:, 2]) > VERTICAL * np.maximum(dist[rows, best], 1e-12))


@dataclass(frozen=True)
class Levels:
    """Per sample at constant Z: is its grid cell surrounded at its level, and how far
    up is the next level over the same cell (inf: none)."""

    interior: np.ndarray
    step_mm: np.ndarray


def levels(sm: Samples, cell_mm: float) -> Levels:
    flat = ~sm.sloped
    m = sm.xyz.shape[0]
    interior, step = np.zeros(m, dtype=bool), np.full(m, np.inf)
    if not flat.any():
        return Levels(interior, step)
    z = np.round(sm.xyz[flat, 2] / 0.002).astype(np.int64)
    cx = np.floor(sm.xyz[flat, 0] / cell_mm).astype(np.int64)
    cy = np.floor(sm.xyz[flat, 1] / cell_mm).astype(np.int64)
    cx -= cx.min() - 1
    cy -= cy.min() - 1
    zl = z - z.min()
    w = int(cy.max()) + 2
    h = int(cx.max()) + 2
    cell = cx * w + cy
    key = zl * (h * w) + cell
    uniq = np.unique(key)
    near = [uniq + dk for dk in (w, -w, 1, -1)]
    inner = np.logical_and.reduce([np.isin(k, uniq) for k in near])
    interior[flat] = inner[np.searchsorted(uniq, key)]
    # the next level up over the same cell: the next (cell, level) pair in sorted order
    top = int(zl.max()) + 1
    pairs, inv = np.unique(cell * top + zl, return_inverse=True)
    p_cell, p_z = pairs // top, pairs % top
    nxt = np.full(pairs.size, np.inf)
    nxt[:-1] = np.where(p_cell[1:] == p_cell[:-1], (p_z[1:] - p_z[:-1]) * 0.002, np.inf)
    step[flat] = nxt[inv.ravel()]
    return Levels(interior, step)
