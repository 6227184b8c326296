"""Normals from the toolpath alone, against analytic surfaces (issue: within 2 deg median and
5 deg at the 95th percentile on zig-zag finishing with stepover <= 0.2 D)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from ncopt.api import rewrite_text
from ncopt.model import Job
from ncopt.contacts.geometry import MeshIndex, load_stl
from ncopt.motion.interp import interpret
from ncopt.model import Cutter, Machine
from ncopt.reading.parse import read_program
from ncopt.contacts.pathnormals import CONFIDENT, NO_CROSS, ONE_SIDED, path_normals

ROOT = Path(__file__).resolve().parents[2]


def wave(x, y):
    """Crests, valleys and saddles: z = 5 sin(2 pi x / 50) cos(2 pi y / 50) mm."""
    w = 2 * np.pi / 50
    return 5 * np.sin(w * x) * np.cos(w * y)


def wave_normal(x, y):
    w = 2 * np.pi / 50
    fx = 5 * w * np.cos(w * x) * np.cos(w * y)
    fy = -5 * w * np.sin(w * x) * np.sin(w * y)
    n = np.stack((-fx, -fy, np.ones_like(fx)), axis=-1)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def drop_ball(x, y, r, f, rings=24, spokes=72, refine=3):
    """Ball centres touching z = f(x, y) from above, and the contact points (numerical
    drop-cutter: the highest sphere over a polar grid of the footprint, refined)."""
    rho = r * np.sqrt(np.linspace(0, 1, rings))[None, :, None]
    phi = np.linspace(0, 2 * np.pi, spokes, endpoint=False)[None, None, :]
    px = x[:, None, None] + rho * np.cos(phi)
    py = y[:, None, None] + rho * np.sin(phi)
    zc = f(px, py) + np.sqrt(np.maximum(r * r - rho ** 2, 0.0))
    k = np.argmax(zc.reshape(len(x), -1), axis=1)
    cx, cy = px.reshape(len(x), -1)[np.arange(len(x)), k], py.reshape(len(x), -1)[np.arange(len(x)), k]
    span = r / rings * 2
    for _ in range(refine):  # a finer square grid around the best point
        g = np.linspace(-span, span, 15)
        qx, qy = np.broadcast_arrays(cx[:, None, None] + g[None, :, None],
                                     cy[:, None, None] + g[None, None, :])
        d2 = (qx - x[:, None, None]) ** 2 + (qy - y[:, None, None]) ** 2
        z = np.where(d2 <= r * r, f(qx, qy) + np.sqrt(np.maximum(r * r - d2, 0.0)), -np.inf)
        k = np.argmax(z.reshape(len(x), -1), axis=1)
        cx, cy = qx.reshape(len(x), -1)[np.arange(len(x)), k], qy.reshape(len(x), -1)[np.arange(len(x)), k]
        span /= 7
    d2 = (cx - x) ** 2 + (cy - y) ** 2
    zc = f(cx, cy) + np.sqrt(r * r - d2)
    return np.column_stack((x, y, zc)), np.column_stack((cx, cy, f(cx, cy)))


def zigzag(stepover, step, half=45.0):
    xs = np.arange(-half, half + 1e-9, step)
    rows = []
    for i, y in enumerate(np.arange(-half, half + 1e-9, stepover)):
        row = xs if i % 2 == 0 else xs[::-1]
        rows.append(np.column_stack((row, np.full(row.shape, y))))
    return np.vstack(rows)


def angles_deg(a, b):
    return np.degrees(np.arccos(np.clip(np.sum(a * b, axis=1), -1.0, 1.0)))


def test_saddles_and_crests_within_2_deg_median_5_deg_p95():
    r = 4.0  # D8 ball, stepover 1.6 mm = 0.2 D
    xy = zigzag(1.6, 0.5)
    centres, cc = drop_ball(xy[:, 0], xy[:, 1], r, wave)
    path = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(centres, axis=0), axis=1))))
    est = path_normals(centres, path, np.ones(len(centres), bool))
    err = angles_deg(est.normal, wave_normal(cc[:, 0], cc[:, 1]))
    assert np.median(err) <= 2.0, np.median(err)
    assert np.percentile(err, 95) <= 5.0, np.percentile(err, 95)
    assert est.stepover_mm == pytest.approx(1.6, rel=0.05)
    assert np.mean(est.confidence == CONFIDENT) > 0.9  # one-sided: edge passes, pass ends


@pytest.fixture(scope="module")
def bowl():
    spec = importlib.util.spec_from_file_location("make_bowl", ROOT / "samples" / "make_bowl.py")
    mb = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mb)
    return mb


def test_bowl_sample_within_2_deg_median_5_deg_p95(bowl):
    tp = interpret(read_program(ROOT / "samples" / "bowl.mpf"))
    cutting = (tp.motion == 1) & tp.known & (tp.xyz_mm[:, 2] < 2.9)  # not the approach
    est = path_normals(tp.xyz_mm + [0, 0, 8.0], np.cumsum(tp.seg_len_mm), cutting)
    _, _, analytic = bowl.drop_ball_contact(tp.xyz_mm[:, 0], tp.xyz_mm[:, 1], 8.0)
    err = angles_deg(est.normal, analytic)[cutting]
    assert np.median(err) <= 2.0 and np.percentile(err, 95) <= 5.0
    assert np.median(err) < 0.2  # measured 0.04 deg: a regression guard with room


def test_a_single_pass_has_no_cross_slope_and_says_so():
    x = np.linspace(0, 50, 101)
    centres = np.column_stack((x, np.zeros_like(x), 0.3 * x))  # a straight 16.7 deg ramp
    path = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(centres, axis=0), axis=1))))
    est = path_normals(centres, path, np.ones(len(x), bool))
    assert np.all(est.confidence == NO_CROSS)
    expected = np.array([-0.3, 0.0, 1.0]) / np.hypot(0.3, 1.0)
    assert np.allclose(est.normal, expected, atol=1e-9)


def test_the_first_and_last_pass_are_one_sided():
    xy = zigzag(1.0, 0.5, half=10.0)
    centres = np.column_stack((xy, np.full(len(xy), 5.0)))  # a flat: normal +Z
    path = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(centres, axis=0), axis=1))))
    est = path_normals(centres, path, np.ones(len(xy), bool))
    edge = np.isclose(np.abs(xy[:, 1]), 10.0)
    # near a pass end the short link joins the next pass to this one on the path, so
    # those points see one side only too: look between the ends
    inner = np.abs(xy[:, 0]) < 8.0
    assert np.all(est.confidence[edge & inner] == ONE_SIDED)
    assert np.all(est.confidence[~edge & inner] == CONFIDENT)
    assert np.allclose(est.normal, [0, 0, 1], atol=1e-9)


def test_mesh_free_rewrite_within_3_percent_of_the_mesh_rewrite():
    """Issue: the cutting time and the S profile without a mesh within 3 % of the rewrite
    with the exact mesh (measured: times equal to 0.01 %, S per block p95 0.65 %)."""
    text = (ROOT / "samples" / "bowl.mpf").read_bytes().decode("latin-1")
    job = Job(cutter=Cutter(16, 2), machine=Machine(227, 15000))
    with_mesh = rewrite_text(text, job, "bowl", MeshIndex(load_stl(ROOT / "samples" / "bowl.stl")))
    free = rewrite_text(text, job, "bowl")
    assert free.summary.cut_time_after_min == pytest.approx(with_mesh.summary.cut_time_after_min,
                                                            rel=0.03)
    a, b = with_mesh.plan, free.plan
    both = a.blocks.cutting & b.blocks.cutting
    ratio = b.s_cmd_rpm[both] / a.s_cmd_rpm[both] - 1.0
    assert np.percentile(np.abs(ratio), 99) <= 0.03
    assert free.summary.normals_from == "toolpath" and with_mesh.summary.normals_from == "mesh"
