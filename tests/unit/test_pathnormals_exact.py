"""The toolpath normals are computed the same, bit for bit, however they are chunked and
threaded: against a plain reference (the arithmetic of ncopt.contacts.pathnormals before it was
reorganised for speed: one chunk, no threads, numpy's default passes), on toolpaths with
ties among the neighbours, breaks, repeated points, plunges, signed zeros and 5-axis
tool axes."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial import cKDTree

import ncopt.contacts.pathfit as pf
import ncopt.contacts.pathnormals as pn
from ncopt.motion.modal import row_norms
from ncopt.model import Cutter
from ncopt.contacts.cutters import r_eff_mm


def up_part(v, axis):
    """Each row's component along the tool axis (+Z when None)."""
    return v[:, 2] if axis is None else np.einsum("ij,ij->i", v, axis)


def reference(centers, path, cutting, axis=None, k=pn.K_NEIGHBOURS):
    """(normal, confidence, stepover_mm, planning normal) as the first implementation
    computed them."""
    m = centers.shape[0]
    normal = np.tile([0.0, 0.0, 1.0], (m, 1)) if axis is None else axis.copy()
    confidence = np.zeros(m, dtype=np.int8)
    idx = np.flatnonzero(cutting)
    if idx.size >= 2:
        pts, s = centers[idx], path[idx]
        d = np.diff(pts, axis=0)
        seg = np.linalg.norm(d, axis=1)
        jump = np.abs(np.diff(s) - seg) > 1e-6
        unit = d / np.maximum(seg, 1e-12)[:, None]
        unit[jump | (seg < 1e-9)] = np.nan
        t = (np.nan_to_num(np.vstack((unit[:1] * np.nan, unit)))
             + np.nan_to_num(np.vstack((unit, unit[:1] * np.nan))))
        norm = np.linalg.norm(t, axis=1)
        t /= np.maximum(norm, 1e-12)[:, None]
        t[norm < 1e-9] = [1.0, 0.0, 0.0]
        dist, nb = cKDTree(pts).query(pts, k=min(k + 1, idx.size))
        dist, nb = dist[:, 1:], nb[:, 1:]
        other = np.abs(s[nb] - s[:, None]) > pn.OTHER_PASS_RATIO * dist + 1e-9
        up_ax = None if axis is None else axis[idx]
        up = np.array([0.0, 0.0, 1.0]) if up_ax is None else up_ax
        u = np.cross(t, up)
        vertical = np.linalg.norm(u, axis=1) < 1e-6
        u[vertical] = [1.0, 0.0, 0.0] if up_ax is None else pn.across(up_ax[vertical])
        u /= np.maximum(np.linalg.norm(u, axis=1), 1e-12)[:, None]
        v = np.cross(u, t)
        v[up_part(v, up_ax) < 0] *= -1.0
        off = pts[nb] - pts[:, None, :]
        a = np.einsum("mkj,mj->mk", off, u)
        b = np.einsum("mkj,mj->mk", off, v)
        w = np.where(other, 1.0 / np.maximum(dist, 1e-9) ** 2, 0.0)
        saa, sbb, sab = (w * a * a).sum(1), (w * b * b).sum(1), (w * a * b).sum(1)
        half = 0.5 * (saa - sbb)
        lam = 0.5 * (saa + sbb) - np.sqrt(half * half + sab * sab)
        alpha, beta = sab, lam - saa
        small = np.hypot(alpha, beta) < 1e-12 * np.maximum(saa + sbb, 1e-300)
        alpha, beta = np.where(small, 0.0, alpha), np.where(small, 1.0, beta)
        n = alpha[:, None] * u + beta[:, None] * v
        n /= np.maximum(np.linalg.norm(n, axis=1), 1e-12)[:, None]
        n[up_part(n, up_ax) < 0] *= -1.0
        has = other.any(axis=1)
        n[~has] = v[~has]
        two = (other & (a > 0)).any(axis=1) & (other & (a < 0)).any(axis=1)
        normal[idx] = n
        confidence[idx] = np.where(~has, pn.NO_CROSS, np.where(two, pn.CONFIDENT, pn.ONE_SIDED))
        near = np.where(other, dist, np.inf).min(axis=1)
    else:
        near = np.array([np.inf])
    stepover = float(np.median(near[np.isfinite(near)])) if np.isfinite(near).any() else np.nan
    return normal, confidence, stepover


def reference_tilt(normal, angle_rad, axis=None):
    """tilt_from_axis as first written."""
    if axis is not None:
        c = np.clip(np.einsum("ij,ij->i", normal, axis), -1.0, 1.0)
        side = normal - c[:, None] * axis
        hn = np.linalg.norm(side, axis=1)
        side = np.where(hn[:, None] > 1e-12, side / np.maximum(hn, 1e-12)[:, None],
                        pn.across(axis))
        polar = np.arccos(c) + angle_rad
        return np.cos(polar)[:, None] * axis + np.sin(polar)[:, None] * side
    polar = np.arccos(np.clip(normal[:, 2], -1.0, 1.0)) + angle_rad
    horiz = normal[:, :2]
    hn = np.linalg.norm(horiz, axis=1)
    direction = np.where(hn[:, None] > 1e-12, horiz / np.maximum(hn, 1e-12)[:, None], [1.0, 0.0])
    out = np.empty_like(normal)
    out[:, :2] = direction * np.sin(polar)[:, None]
    out[:, 2] = np.cos(polar)
    return out


def toolpath(rng, rows=7, step=0.5, stepover=1.2, jitter=0.0):
    """Zig-zag passes over a bowl (a regular grid: equal distances, so ties), with a
    repeated point, a plunge, a break in the path and a few non-cutting points."""
    xs = np.arange(-6.0, 6.0 + 1e-9, step)
    passes = []
    for i in range(rows):
        x = xs if i % 2 == 0 else xs[::-1]
        y = np.full(x.shape, (i - rows // 2) * stepover)
        passes.append(np.column_stack((x, y, 0.02 * (x * x + y * y))))
    pts = np.vstack(passes)
    pts[:, :2] += rng.uniform(-jitter, jitter, (len(pts), 2))
    pts = np.insert(pts, 10, pts[10], axis=0)  # a repeated point
    at = len(pts) * 2 // 3
    pts = np.insert(pts, at, pts[at] + [0.0, 0.0, 2.0], axis=0)  # a plunge
    pts[pts == 0.0] = -0.0  # signed zeros where the grid crosses the axes
    path = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))))
    path[len(path) // 2:] += 40.0  # a break: the path goes elsewhere and comes back
    cutting = np.ones(len(pts), bool)
    cutting[[0, 5, len(pts) - 3]] = False
    return pts, path, cutting


def tilted_axes(rng, n):
    a = np.column_stack((rng.uniform(-0.3, 0.3, (n, 2)), np.ones(n)))
    a[::9] = [0.0, 0.0, 1.0]
    return a / np.linalg.norm(a, axis=1)[:, None]


def bits(x):
    return np.asarray(x, dtype=np.float64).view(np.uint64)


def assert_same(got, want):
    assert np.array_equal(bits(got.normal), bits(want[0]))
    assert np.array_equal(got.confidence, want[1])
    assert np.array_equal(bits(got.stepover_mm), bits(want[2]))


@pytest.mark.parametrize("five_axis", [False, True])
@pytest.mark.parametrize("chunk,workers", [(pn.CHUNK, 1), (7, 2), (64, 2), (10**6, 2)])
def test_chunks_and_threads_give_the_reference_bits(monkeypatch, five_axis, chunk, workers):
    rng = np.random.default_rng(3)
    pts, path, cutting = toolpath(rng)
    axis = tilted_axes(rng, len(pts)) if five_axis else None
    want = reference(pts, path, cutting, axis)
    monkeypatch.setattr(pn, "CHUNK", chunk)
    got = pn.path_normals(pts, path, cutting, workers=workers, axis=axis)
    assert np.mean(got.confidence == pn.CONFIDENT) > 0.5  # the cross fit did run
    assert_same(got, want)


@pytest.mark.parametrize("five_axis", [False, True])
def test_contacts_from_path_plans_with_the_reference_normals(monkeypatch, five_axis):
    rng = np.random.default_rng(4)
    pts, path, cutting = toolpath(rng, jitter=0.05)
    axis = tilted_axes(rng, len(pts)) if five_axis else None
    normal, confidence, _ = reference(pts, path, cutting, axis)
    cutter = Cutter(16.0, 2)
    monkeypatch.setattr(pn, "CHUNK", 11)
    contacts, est = pn.contacts_from_path(pts, path, cutting, cutter, axis)
    assert np.array_equal(bits(contacts.normal), bits(normal))
    assert np.array_equal(bits(contacts.cc_mm), bits(pts - cutter.corner_radius_mm * normal))
    tilt = np.where(confidence == pn.ONE_SIDED, np.radians(pn.ONE_SIDED_TILT_DEG), 0.0)
    assert np.array_equal(bits(contacts.r_eff_mm),
                          bits(r_eff_mm(cutter, reference_tilt(normal, tilt, axis), axis)))


@pytest.mark.parametrize("five_axis", [False, True])
def test_tilt_from_axis_has_the_reference_bits(five_axis):
    rng = np.random.default_rng(6)
    n = rng.normal(size=(5000, 3))
    n[::5, :2] = 0.0  # along the axis: no horizontal direction
    n[::7, 0] = -0.0
    n /= np.linalg.norm(n, axis=1)[:, None]
    axis = tilted_axes(rng, len(n)) if five_axis else None
    if five_axis:
        n[::5] = axis[::5]
    angle = rng.choice([0.0, np.radians(3.0), 0.4], len(n))
    assert np.array_equal(bits(pn.tilt_from_axis(n, angle, axis)),
                          bits(reference_tilt(n, angle, axis)))


@given(seed=st.integers(0, 2**32 - 1), rows=st.integers(1, 6),
       step=st.sampled_from([0.25, 0.5, 0.7]), jitter=st.sampled_from([0.0, 0.01, 0.2]),
       five_axis=st.booleans(), chunk=st.integers(1, 50))
def test_any_toolpath_gives_the_reference_bits(seed, rows, step, jitter, five_axis, chunk):
    rng = np.random.default_rng(seed)
    pts, path, cutting = toolpath(rng, rows=rows, step=step, jitter=jitter)
    cutting &= rng.random(len(pts)) > 0.1
    axis = tilted_axes(rng, len(pts)) if five_axis else None
    want = reference(pts, path, cutting, axis)
    saved = pn.CHUNK
    try:
        pn.CHUNK = chunk
        got = pn.path_normals(pts, path, cutting, workers=2, axis=axis)
    finally:
        pn.CHUNK = saved
    assert_same(got, want)


def test_row_norms_have_the_bits_of_numpys_norm():
    rng = np.random.default_rng(5)
    v = rng.normal(size=(20000, 3)) * rng.choice([1e-300, 1e-8, 1.0, 1e8, 1e300], (20000, 3))
    v[::7, 1] = -0.0
    v[::11] = 0.0
    with np.errstate(over="ignore", under="ignore"):
        assert np.array_equal(bits(row_norms(v)), bits(np.linalg.norm(v, axis=1)))


@pytest.mark.parametrize("k", list(range(1, 20)) + [24, 25, 40, 129, 200])
@pytest.mark.parametrize("m", [1, 3, 500])
def test_rank_sums_have_the_bits_of_numpys_row_sums(k, m):
    rng = np.random.default_rng(k * 1000 + m)
    t = rng.normal(size=(m, k)) * rng.choice([1e-300, 1e-8, 1.0, 1e8], (m, k))
    t[rng.random((m, k)) < 0.3] = -0.0
    t[rng.random((m, k)) < 0.1] = 0.0
    t[::4] = -0.0  # rows of negative zeros only: numpy's sum is +0.0
    assert np.array_equal(bits(pf.rank_sums(np.ascontiguousarray(t.T))), bits(t.sum(axis=1)))


def test_projections_have_the_bits_of_einsum():
    rng = np.random.default_rng(8)
    off = rng.normal(size=(3000, 12, 3)) * rng.choice([1e-8, 1.0, 1e8], (3000, 12, 3))
    off[::5, :, 1] = -0.0
    u = rng.normal(size=(3000, 3))
    got = pf._project(*(np.ascontiguousarray(off[..., j].T) for j in range(3)),
                      np.ascontiguousarray(u.T))
    want = np.einsum("mkj,mj->mk", off, u).T
    assert np.array_equal(got, want)  # as numbers: the sign of a zero may differ (_project)
    assert np.array_equal(bits(got[got != 0.0]), bits(want[want != 0.0]))


@pytest.mark.parametrize("five_axis", [False, True])
def test_small_chunks_give_the_same_bits(monkeypatch, five_axis):
    """The points fitted chunk by chunk in two threads: the reference's bits."""
    rng = np.random.default_rng(10)
    pts, path, cutting = toolpath(rng, jitter=0.02)
    axis = tilted_axes(rng, len(pts)) if five_axis else None
    want = reference(pts, path, cutting, axis)
    monkeypatch.setattr(pn, "CHUNK", 13)
    assert_same(pn.path_normals(pts, path, cutting, workers=2, axis=axis), want)
