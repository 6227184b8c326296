"""R_eff measured from a tilted tool axis (the paper's eq. (1) with any e): the closed form
for a ball, and rotation equivariance of everything that depends on the axis (a part
and its toolpath turned together, with the axis, give the same R_eff)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ncopt.api import rewrite_text
from ncopt.model import Job
from ncopt.runtime.errors import NothingToPlan
from ncopt.model import Cutter, CuttingData, Machine
from ncopt.contacts.pathnormals import path_normals, tilt_from_axis
from ncopt.contacts.remaining import r_eff_material_mm
from ncopt.contacts.cutters import r_eff_mm

BALL = Cutter(10.0, 2)
BULL = Cutter(10.0, 2, corner_radius_mm=2.0)
UNIT = st.lists(st.floats(-1, 1), min_size=3, max_size=3).filter(
    lambda v: np.linalg.norm(v) > 0.2).map(lambda v: np.array(v) / np.linalg.norm(v))


def rotation(rng) -> np.ndarray:
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.linalg.det(q))


@given(UNIT, UNIT)
def test_ball_r_eff_is_r_sin_of_the_angle_between_normal_and_axis(n, e):
    got = r_eff_mm(BALL, n[None], e[None])[0]
    # |n x e| = sin(angle): the distance of the contact point (centre - R n) from the axis
    # (1e-6 mm: sqrt(1 - c^2) of a c rounded near 1 is good to ~1e-8 relative of R)
    assert got == pytest.approx(5.0 * np.linalg.norm(np.cross(n, e)), abs=1e-6)


@given(UNIT)
def test_bull_nose_r_eff_with_an_axis(n):
    e = np.array([0.0, np.sin(0.3), np.cos(0.3)])
    c = np.clip(np.dot(n, e), -1, 1)
    assert r_eff_mm(BULL, n[None], e[None])[0] == pytest.approx(3.0 + 2.0 * np.sqrt(1 - c * c))


def test_no_axis_is_plus_z_bit_for_bit(rng):
    n = rng.normal(size=(50, 3))
    n /= np.linalg.norm(n, axis=1)[:, None]
    z = np.tile([0.0, 0.0, 1.0], (50, 1))
    assert np.array_equal(r_eff_mm(BALL, n), r_eff_mm(BALL, n, z))


def test_remaining_material_turns_with_the_part(rng):
    n = rng.normal(size=(200, 3)) + [0, 0, 2]
    n /= np.linalg.norm(n, axis=1)[:, None]
    d = rng.normal(size=(200, 3))
    rot = rotation(rng)
    axis = np.tile(rot[:, 2], (200, 1))
    for cutter in (BALL, BULL):
        for along in ("normal", "axis"):
            flat = r_eff_material_mm(cutter, n, d, 0.3, along)
            turned = r_eff_material_mm(cutter, n @ rot.T, d @ rot.T, 0.3, along, axis)
            assert np.allclose(flat, turned, atol=1e-9)


def test_path_normals_turn_with_the_toolpath(rng):
    """Ball centres over z = 0.02 (x^2 - y^2) in zig-zag passes, and the same turned
    (the tool axis with them): the normals turn with them."""
    xs = np.arange(-10, 10.01, 0.7)
    pts = []
    for i, y in enumerate(np.arange(-6, 6.01, 1.0)):
        row = xs if i % 2 == 0 else xs[::-1]
        pts.append(np.column_stack((row, np.full(row.shape, y), 0.02 * (row ** 2 - y ** 2))))
    pts = np.vstack(pts)
    pts[:, :2] += rng.uniform(-0.05, 0.05, (len(pts), 2))  # no ties among the neighbours
    path = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))))
    cutting = np.ones(len(pts), bool)
    rot = rotation(rng)
    flat = path_normals(pts, path, cutting, workers=1)
    axis = np.tile(rot[:, 2], (len(pts), 1))
    turned = path_normals(pts @ rot.T, path, cutting, workers=1, axis=axis)
    assert np.array_equal(flat.confidence, turned.confidence)
    assert np.allclose(flat.normal @ rot.T, turned.normal, atol=1e-9)
    tilt = np.full(len(pts), np.radians(3.0))
    assert np.allclose(tilt_from_axis(flat.normal, tilt) @ rot.T,
                       tilt_from_axis(turned.normal, tilt, axis), atol=1e-9)


def test_a_tilted_bull_nose_is_left_untouched():
    text = ("G21 G90 G94\nS4000 M3\nG0 X0 Y0 Z5\nG1 Z0 F500\nG43.5 H1\n"
            + "".join(f"G1 X{i} I0 J0.5 K0.866\n" for i in range(1, 6)))
    job = Job(machine=Machine(227, 18000), cutter=BULL, cutting=CuttingData(150, 0.08))
    with pytest.raises(NothingToPlan) as info:
        rewrite_text(text, job, "t.nc")
    assert str(info.value) == ("t.nc: nothing to plan: the program (lines 1-10): a bull-nose "
                               "with a tilted tool axis: ncopt plans 5-axis moves with "
                               "ball-end mills only")
