"""Closed-form checks of the cutter shapes (ncopt.tools)."""

from __future__ import annotations

import numpy as np
import pytest

from ncopt.model import Cutter
from ncopt.tools import center_offset_mm, r_eff_mm, required_rpm

BALL = Cutter(diameter_mm=16.0, teeth=2)
BULL = Cutter(diameter_mm=16.0, teeth=2, corner_radius_mm=2.0)


def tilted(deg: float) -> np.ndarray:
    """Unit normal of a plane tilted by ``deg`` about the Y axis, as a (1, 3) row."""
    a = np.radians(deg)
    return np.array([[np.sin(a), 0.0, np.cos(a)]])


def test_ball_on_horizontal_plane_cuts_at_the_tip():
    assert r_eff_mm(BALL, tilted(0.0))[0] == 0.0


def test_ball_on_45_degree_plane():
    assert r_eff_mm(BALL, tilted(45.0))[0] == pytest.approx(8.0 / np.sqrt(2.0), rel=1e-12)


def test_ball_on_vertical_wall_cuts_at_full_radius():
    assert r_eff_mm(BALL, tilted(90.0))[0] == pytest.approx(8.0, rel=1e-12)


def test_ball_depends_only_on_the_tilt_not_its_direction():
    a = np.radians(30.0)
    normals = np.array([[np.sin(a) * np.cos(t), np.sin(a) * np.sin(t), np.cos(a)]
                        for t in np.linspace(0, 2 * np.pi, 7)])
    np.testing.assert_allclose(r_eff_mm(BALL, normals), 4.0, rtol=1e-12)


def test_bull_nose_on_horizontal_plane_is_the_flat_radius():
    assert r_eff_mm(BULL, tilted(0.0))[0] == pytest.approx(8.0 - 2.0)


def test_bull_nose_on_30_degree_slope():
    assert r_eff_mm(BULL, tilted(30.0))[0] == pytest.approx(6.0 + 2.0 * 0.5, rel=1e-12)


def test_rounding_beyond_unit_length_is_clipped():
    assert r_eff_mm(BALL, np.array([[0.0, 0.0, 1.0 + 1e-15]]))[0] == 0.0


def test_r_eff_is_vectorised_and_checks_shape():
    normals = np.vstack([tilted(d) for d in (0, 30, 60, 90)])
    np.testing.assert_allclose(r_eff_mm(BALL, normals),
                               8.0 * np.sin(np.radians([0, 30, 60, 90])), atol=1e-12)
    with pytest.raises(ValueError, match=r"\(m, 3\)"):
        r_eff_mm(BALL, np.zeros(3))


def test_center_offset():
    assert center_offset_mm(BALL) == 8.0
    assert center_offset_mm(BULL) == 2.0
    assert center_offset_mm(Cutter(16.0, 2, tool_point="center")) == 0.0
    with pytest.raises(ValueError, match="tool_point"):
        center_offset_mm(Cutter(16.0, 2, tool_point="shank"))


def test_required_rpm_matches_the_paper_d16_example():
    # D16 ball at full radius, vc 70 m/min -> S 1392.6 (METHOD.md)
    assert required_rpm(np.array([8.0]), 70.0)[0] == pytest.approx(1392.6, abs=0.05)


def test_required_rpm_is_inverse_in_radius_and_infinite_at_the_tip():
    s = required_rpm(np.array([0.0, 1.0, 2.0]), 100.0)
    assert s[0] == np.inf
    assert s[1] == pytest.approx(2.0 * s[2])
