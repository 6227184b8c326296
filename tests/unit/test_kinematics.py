"""ncopt.motion.kinematics: each named kinematics against an independent derivation (rotation
matrices for ISO 841, LinuxCNC's own forward kinematics for its variants), the blend
between block ends, G68.2's frame."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ncopt.runtime.errors import UsageError
from ncopt.motion.kinematics import KINEMATICS, NAMES, blend, check_name, euler_zxz, tilt_deg

ANGLE = st.floats(-360, 360, allow_nan=False)


def rx(t):
    c, s = math.cos(t), math.sin(t)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def ry(t):
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rz(t):
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


Z = np.array([0.0, 0.0, 1.0])


def axis(name, a=0.0, b=0.0, c=0.0):
    return KINEMATICS[name].tool_axis(np.array([[a, b, c]]))[0]


# ---------------------------------------------------- ISO 841: e = Rz(C) R_tilt z ----
@given(ANGLE, ANGLE, ANGLE)
def test_iso_variants_are_the_composed_rotations(a, b, c):
    A, B, C = np.radians([a, b, c])
    ac = rz(C) @ rx(A) @ Z
    bc = rz(C) @ ry(B) @ Z
    for name in ("xyzac-trt", "xyzac-head-table"):
        assert np.allclose(axis(name, a, b, c), ac, atol=1e-12)
    for name in ("xyzbc-trt", "xyzbc-head-table", "xyzbc-head-head"):
        assert np.allclose(axis(name, a, b, c), bc, atol=1e-12)


def test_iso_directions_by_hand():
    # A+90 turns the tool (right-hand rule about +X) from +Z to -Y; C+90 then to +X
    assert np.allclose(axis("xyzac-trt", a=90), [0, -1, 0])
    assert np.allclose(axis("xyzac-trt", a=90, c=90), [1, 0, 0])
    # B+90 about +Y: from +Z to +X
    assert np.allclose(axis("xyzbc-trt", b=90), [1, 0, 0])
    assert np.allclose(axis("xyzbc-trt", b=30, c=180), [-0.5, 0, math.sqrt(3) / 2])


# ------------------------------------------- LinuxCNC: its own forward kinematics ----
def xyzac_forward(j, con, rot=(3.0, -2.0, 5.0), dy=1.5, dz=2.0, dt=4.0):
    """src/emc/kinematics/trtfuncs.c xyzacKinematicsForward (part-frame position of the
    joint position j = (x, y, z, a, c)), transcribed."""
    x, y, z, a, c = j
    xr, yr, zr = rot
    dz = dz + dt
    a, c = math.radians(a), math.radians(c)
    px = (math.cos(c) * (x - xr) - con * math.sin(c) * math.cos(a) * (y - dy - yr)
          + math.sin(c) * math.sin(a) * (z - dz - zr) - con * math.sin(c) * dy + xr)
    py = (con * math.sin(c) * (x - xr) + math.cos(c) * math.cos(a) * (y - dy - yr)
          - con * math.cos(c) * math.sin(a) * (z - dz - zr) + math.cos(c) * dy + yr)
    pz = con * math.sin(a) * (y - dy - yr) + math.cos(a) * (z - dz - zr) + dz + zr
    return np.array([px, py, pz])


def xyzbc_forward(j, con, rot=(3.0, -2.0, 5.0), dx=1.5, dz=2.0, dt=4.0):
    """trtfuncs.c xyzbcKinematicsForward, transcribed; j = (x, y, z, b, c)."""
    x, y, z, b, c = j
    xr, yr, zr = rot
    dz = dz + dt
    b, c = math.radians(b), math.radians(c)
    px = (math.cos(c) * math.cos(b) * (x - dx - xr) - con * math.sin(c) * (y - yr)
          + con * math.cos(c) * math.sin(b) * (z - dz - zr) + math.cos(c) * dx + xr)
    py = (con * math.sin(c) * math.cos(b) * (x - dx - xr) + math.cos(c) * (y - yr)
          + math.sin(c) * math.sin(b) * (z - dz - zr) + con * math.sin(c) * dx + yr)
    pz = -con * math.sin(b) * (x - dx - xr) + math.cos(b) * (z - dz - zr) + dz + zr
    return np.array([px, py, pz])


def fiveaxis_tip(j, pivot=250.0):
    """src/emc/kinematics/5axiskins.c forward: tip = joints + (0, 0, L) + s2r(L, C, 180-B)."""
    x, y, z, b, c = j
    t, p = math.radians(c), math.radians(180.0 - b)
    r = pivot * np.array([math.sin(p) * math.cos(t), math.sin(p) * math.sin(t), math.cos(p)])
    return np.array([x, y, z + pivot]) + r, np.array([x, y, z + pivot])


@given(ANGLE, ANGLE, st.floats(-50, 50), st.floats(-50, 50), st.floats(-50, 50))
def test_linuxcnc_variants_are_the_joint_z_direction_of_its_kinematics(r1, c, x, y, z):
    """The spindle (joint Z) moves along the tool axis: the part-frame image of a joint +Z
    step is e (tip toward the spindle)."""
    for con, ac, bc in ((-1.0, "xyzac-trt-linuxcnc", "xyzbc-trt-linuxcnc"),
                        (1.0, "xyzac-trt", "xyzbc-trt")):
        d = xyzac_forward((x, y, z + 1, r1, c), con) - xyzac_forward((x, y, z, r1, c), con)
        assert np.allclose(axis(ac, a=r1, c=c), d, atol=1e-9)
        d = xyzbc_forward((x, y, z + 1, r1, c), con) - xyzbc_forward((x, y, z, r1, c), con)
        assert np.allclose(axis(bc, b=r1, c=c), d, atol=1e-9)
    tip, pivot = fiveaxis_tip((x, y, z, r1, c))
    e = (pivot - tip) / np.linalg.norm(pivot - tip)
    assert np.allclose(axis("xyzbc-5axis-linuxcnc", b=r1, c=c), e, atol=1e-9)


def test_every_kinematics_is_vertical_at_zero_and_unit_everywhere():
    rng = np.random.default_rng(3)
    angles = rng.uniform(-200, 200, (50, 3))
    for kin in KINEMATICS.values():
        assert np.allclose(kin.tool_axis(np.zeros((1, 3))), [[0, 0, 1]])
        assert np.allclose(np.linalg.norm(kin.tool_axis(angles), axis=1), 1.0)
        assert set(kin.axes) <= set("ABC") and len(kin.axes) == 2


def test_names_and_unknown_name():
    assert check_name("xyzac-trt") == "xyzac-trt" and check_name(None) is None
    assert "vector" in NAMES
    with pytest.raises(UsageError) as info:
        check_name("xyzac")
    assert str(info.value).startswith("--kinematics must be one of xyzac-trt, ")
    assert str(info.value).endswith(", vector, not 'xyzac'")


# ------------------------------------------------------------------ between ends ----
@given(st.lists(st.floats(-1, 1), min_size=6, max_size=6), st.floats(0, 1))
def test_blend_runs_on_the_great_circle(v, f):
    e0, e1 = np.array(v[:3]), np.array(v[3:])
    if np.linalg.norm(e0) < 0.1 or np.linalg.norm(e1) < 0.1:
        return
    e0, e1 = e0 / np.linalg.norm(e0), e1 / np.linalg.norm(e1)
    if np.dot(e0, e1) < -0.99:
        return
    m = blend(e0[None], e1[None], np.array([f]))[0]
    assert abs(np.linalg.norm(m) - 1) < 1e-12
    assert abs(np.dot(m, np.cross(e0, e1))) < 1e-9  # in the plane of both
    assert np.allclose(blend(e0[None], e1[None], np.array([0.0]))[0], e0)
    assert np.allclose(blend(e0[None], e1[None], np.array([1.0]))[0], e1)


def test_tilt_and_g68_2_frame():
    assert np.allclose(tilt_deg(np.array([[0, 0, 1], [1, 0, 0], [0, -0.5, math.sqrt(.75)]])),
                       [0, 90, 30])
    r = euler_zxz(0, 30, 0)
    assert np.allclose(r @ Z, [0, -0.5, math.sqrt(3) / 2])  # the plane's Z: tilted about X
    r = euler_zxz(90, 30, -90)
    assert np.allclose(r @ Z, [0.5, 0, math.sqrt(3) / 2])  # turned to tilt about Y
    assert np.allclose(r @ r.T, np.eye(3))
