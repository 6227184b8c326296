"""The remaining-material method against closed forms."""

import numpy as np
import pytest

from ncopt.model import Cutter
from ncopt.contacts.remaining import r_eff_material_mm

BALL = Cutter(16.0, 2)
S45 = np.sqrt(0.5)


def one(cutter, n, d, ap=0.2, along="normal"):
    return float(r_eff_material_mm(cutter, np.array([n], float), np.array([d], float), ap, along)[0])


def test_horizontal_plane_the_point_ahead_is_the_chord_of_the_allowance():
    # tool sphere cut by the plane ap above the contact: a circle of radius sqrt(2 R ap - ap^2)
    expected = np.sqrt(2 * 8 * 0.2 - 0.2 ** 2)
    assert one(BALL, (0, 0, 1), (1, 0, 0)) == pytest.approx(expected, rel=1e-12)
    assert one(BALL, (0, 0, 1), (0, -1, 0)) == pytest.approx(expected, rel=1e-12)


def test_upward_and_downward_passes_differ_as_the_paper_reports():
    n = (-S45, 0, S45)  # a 45 deg slope rising in +X
    up = one(BALL, n, (S45, 0, S45))
    down = one(BALL, n, (-S45, 0, -S45))
    lead = np.sqrt(2 * 8 * 0.2 - 0.04)
    # X - C = (ap - R) n +- lead d: horizontal distance from the axis
    assert up == pytest.approx((7.8 + lead) * S45, rel=1e-12)
    assert down == pytest.approx((7.8 - lead) * S45, rel=1e-12)
    assert down < 8 * S45 < up  # the contact method's R sin 45 lies between


def test_offset_along_the_axis_is_the_vertical_allowance():
    n = (-S45, 0, S45)
    h = 0.2 * S45 - 8.0  # signed height of the allowance plane along n
    lead = np.sqrt(64 - h * h)
    assert one(BALL, n, (S45, 0, S45), along="axis") == pytest.approx((-h + lead) * S45, rel=1e-12)
    assert one(BALL, (0, 0, 1), (1, 0, 0), along="axis") == pytest.approx(
        one(BALL, (0, 0, 1), (1, 0, 0)), rel=1e-12)  # on a flat, axis and normal agree


def test_bull_nose_on_its_flat_bottom_cuts_at_the_torus_ahead():
    bull = Cutter(16.0, 2, 2.0)
    assert one(bull, (0, 0, 1), (1, 0, 0)) == pytest.approx(6 + np.sqrt(2 * 2 * 0.2 - 0.04))


def test_bull_nose_on_a_30_deg_slope_uses_the_tube_on_the_contact_side():
    bull = Cutter(16.0, 2, 2.0)
    s, c = np.sin(np.radians(30)), np.cos(np.radians(30))
    n = (-s, 0, c)  # rising in +X: the contact is on the +X side of the tool
    lead = np.sqrt(2 * 2 * 0.2 - 0.04)
    d = (c, 0, s)  # up the slope
    x = 6.0 + (2 - 0.2) * s + lead * c
    assert one(bull, n, d) == pytest.approx(x, rel=1e-12)


def test_bad_offset_direction_is_refused():
    with pytest.raises(ValueError, match="along"):
        one(BALL, (0, 0, 1), (1, 0, 0), along="sideways")
