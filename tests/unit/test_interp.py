"""ncopt.motion.interp: units, distance modes, arcs with exact lengths, modal F/S, unknown positions."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ncopt.runtime.errors import NcoptError
from ncopt.motion.interp import StartState, interpret
from ncopt.motion.modal import ffill
from ncopt.model import Motion
from ncopt.reading.parse import parse_text

MM = 25.4


def run(text: str, **start):
    return interpret(parse_text(text, "t.nc"), StartState(**start) if start else StartState())


def ends(tp):
    """{0-based line: end point of the move on that line} (last point of each line)."""
    out = {}
    for i in range(1, tp.n):
        out[int(tp.line[i])] = tp.xyz_mm[i]
    return out


def line_length(tp, line: int) -> float:
    return float(tp.seg_len_mm[tp.line == line].sum())


# -------------------------------------------------------------------- units ----
def test_inch_positions_and_feeds_are_millimetres_inside():
    tp = run("G20 G90\nG0 X1 Y2 Z0.5\nG1 X2 F10\nG1 Y-1.25 F20.\n")
    e = ends(tp)
    assert np.allclose(e[1], [MM, 2 * MM, 0.5 * MM])
    assert np.allclose(e[2], [2 * MM, 2 * MM, 0.5 * MM])
    assert np.allclose(e[3], [2 * MM, -1.25 * MM, 0.5 * MM])
    assert tp.feed_mm_min[tp.line == 2].tolist() == [10 * MM]
    assert tp.feed_mm_min[tp.line == 3].tolist() == [20 * MM]
    assert line_length(tp, 3) == pytest.approx(3.25 * MM)
    assert tp.line_inch[2] and tp.line_inch[3]


def test_units_switch_mid_program():
    tp = run("G21 G0 X10 Y0 Z0\nG1 X20 F100\nG20\nG1 X1 F4\nG21\nG1 X5 F300\n")
    e = ends(tp)
    assert e[1][0] == pytest.approx(20.0)
    assert e[3][0] == pytest.approx(MM)
    assert e[5][0] == pytest.approx(5.0)
    assert tp.feed_mm_min[tp.line == 3].tolist() == [pytest.approx(4 * MM)]
    assert tp.feed_mm_min[tp.line == 5].tolist() == [300.0]
    assert line_length(tp, 3) == pytest.approx(MM - 20, abs=1e-12)


def test_start_state_inch():
    tp = run("G0 X1 Y1 Z1\nG1 X2 F1\n", inch=True)
    assert np.allclose(ends(tp)[1], [2 * MM, MM, MM])


# --------------------------------------------------------- distance modes ----
def test_incremental_stretches_add_up():
    text = ("G90 G0 X10 Y10 Z5\n"
            "G91 G1 X1 Y-2 F100\n"
            "X1\n"
            "Z-0.5\n"
            "G90 G1 X0 Y0\n"
            "G91 X-3 Y4 Z1\n"
            "G90\n"
            "X7\n")
    e = ends(run(text))
    assert np.allclose(e[1], [11, 8, 5])
    assert np.allclose(e[2], [12, 8, 5])
    assert np.allclose(e[3], [12, 8, 4.5])
    assert np.allclose(e[4], [0, 0, 4.5])
    assert np.allclose(e[5], [-3, 4, 5.5])
    assert np.allclose(e[7], [7, 4, 5.5])


def test_incremental_inch():
    e = ends(run("G20 G90 G0 X0 Y0 Z0\nG91 G1 X1 F10\nX0.5 Y0.5\n"))
    assert np.allclose(e[2], [1.5 * MM, 0.5 * MM, 0])


def test_known_after_all_axes_absolute():
    tp = run("G0 X0 Y0 Z0\nG1 X1 F100\nX2\n")
    assert tp.known[tp.line == 1].all() and tp.known[tp.line == 2].all()
    # the first move starts where the machine happened to be: not known
    assert not tp.known[tp.line == 0].any()


# ---------------------------------------------------------------------- arcs ----
def arc_rows(tp, line):
    return np.flatnonzero(tp.line == line)


def check_circle(tp, line, centre, radius, plane_axes=(0, 1)):
    a, b = plane_axes
    rows = arc_rows(tp, line)
    d = np.hypot(tp.xyz_mm[rows, a] - centre[a], tp.xyz_mm[rows, b] - centre[b])
    assert np.allclose(d, radius, atol=1e-9)
    # pieces are chords within the chord tolerance of the circle
    mids = 0.5 * (tp.xyz_mm[rows] + tp.xyz_mm[rows - 1])
    sag = radius - np.hypot(mids[:, a] - centre[a], mids[:, b] - centre[b])
    assert np.all(sag <= StartState().chord_tol_mm + 1e-12)


@pytest.mark.parametrize("code, sweep", [("G2", 3 * math.pi / 2), ("G3", math.pi / 2)])
def test_quarter_and_three_quarter_arcs_ijk(code, sweep):
    # from (10, 0) to (0, 10) around the origin: counter-clockwise (G3) is a quarter turn,
    # clockwise (G2) goes the long way round
    tp = run(f"G17 G90 G0 X10 Y0 Z0\n{code} X0 Y10 I-10 J0 F100\n")
    assert line_length(tp, 1) == pytest.approx(10 * sweep, rel=1e-12)
    assert np.allclose(tp.xyz_mm[arc_rows(tp, 1)[-1]], [0, 10, 0])
    check_circle(tp, 1, np.zeros(3), 10.0)
    assert set(tp.motion[arc_rows(tp, 1)].tolist()) == {Motion.ARC_CW if code == "G2"
                                                        else Motion.ARC_CCW}
    # the arc turns the right way: clockwise from (10, 0) first heads to negative Y
    first = tp.xyz_mm[arc_rows(tp, 1)[0]]
    assert (first[1] < 0) if code == "G2" else (first[1] > 0)


@pytest.mark.parametrize("radius_word, sweep", [("R10", math.pi / 3), ("R-10", 5 * math.pi / 3)])
@pytest.mark.parametrize("code", ["G2", "G3"])
def test_r_format_short_and_long_arcs(code, radius_word, sweep):
    # a 10 mm chord on a 10 mm radius: 60 deg the short way, 300 deg the long way
    tp = run(f"G17 G0 X0 Y0 Z0\n{code} X10 Y0 {radius_word} F100\n")
    assert line_length(tp, 1) == pytest.approx(10 * sweep, rel=1e-12)
    rows = arc_rows(tp, 1)
    assert np.allclose(tp.xyz_mm[rows[-1]], [10, 0, 0])
    # centre: below the chord for a short clockwise arc, above for a short counter-clockwise
    h = math.sqrt(100 - 25)
    above = (code == "G3") == (radius_word == "R10")
    centre = np.array([5.0, h if above else -h, 0.0])
    check_circle(tp, 1, centre, 10.0)


def test_full_circle_and_helix():
    tp = run("G17 G0 X0 Y0 Z0\nG3 X0 Y0 Z-3 I5 J0 F100\nG2 X0 Y0 I5 J0\n")
    assert line_length(tp, 1) == pytest.approx(math.hypot(2 * math.pi * 5, 3), rel=1e-12)
    assert line_length(tp, 2) == pytest.approx(2 * math.pi * 5, rel=1e-12)
    rows = arc_rows(tp, 1)
    z = tp.xyz_mm[rows, 2]
    assert np.all(np.diff(z) < 0) and z[-1] == pytest.approx(-3)  # a steady descent
    check_circle(tp, 1, np.array([5.0, 0, 0]), 5.0)


# RS-274: G2 is clockwise seen from the positive end of the axis normal to the plane;
# the planes' (first, second) axes are (X, Y), (Z, X) and (Y, Z).  Worked by hand:
# G17 from angle -90 to 0 deg clockwise: 270 deg; G18 (Z, X) from 180 to 90 deg: 90 deg;
# G19 (Y, Z) from -90 to 0 deg: 270 deg.
@pytest.mark.parametrize("plane, words, centre, axes, along, turns", [
    ("G17", "X10 Y10 Z4 I0 J10", (0, 10, 0), (0, 1), 2, 0.75),
    ("G18", "X10 Z10 Y4 I0 K10", (0, 0, 10), (2, 0), 1, 0.25),
    ("G19", "Y10 Z10 X4 J0 K10", (0, 0, 10), (1, 2), 0, 0.75),
])
def test_helical_arcs_in_each_plane(plane, words, centre, axes, along, turns):
    tp = run(f"G0 X0 Y0 Z0\n{plane} G2 {words} F100\n")
    rows = arc_rows(tp, 1)
    assert line_length(tp, 1) == pytest.approx(math.hypot(10 * 2 * math.pi * turns, 4),
                                               rel=1e-12)
    check_circle(tp, 1, np.array(centre, float), 10.0, axes)
    assert tp.xyz_mm[rows[-1], along] == pytest.approx(4.0)
    # the helix climbs evenly along the third axis
    assert np.allclose(np.diff(tp.xyz_mm[rows, along]), 4.0 / len(rows))


def test_g3_in_each_plane_is_the_other_way_round():
    for plane, words in (("G17", "X10 Y10 I0 J10"), ("G18", "X10 Z10 I0 K10"),
                         ("G19", "Y10 Z10 J0 K10")):
        g2 = run(f"G0 X0 Y0 Z0\n{plane} G2 {words} F100\n")
        g3 = run(f"G0 X0 Y0 Z0\n{plane} G3 {words} F100\n")
        assert line_length(g2, 1) + line_length(g3, 1) == pytest.approx(20 * math.pi)


def test_absolute_arc_centres_g90_1():
    tp = run("G90.1 G17 G0 X20 Y10 Z0\nG3 X10 Y20 I10 J10 F100\n")
    assert line_length(tp, 1) == pytest.approx(10 * math.pi / 2, rel=1e-12)
    check_circle(tp, 1, np.array([10.0, 10.0, 0.0]), 10.0)


def test_inch_arc_lengths():
    tp = run("G20 G17 G0 X0 Y0 Z0\nG2 X2 Y0 R1 F10\n")
    assert line_length(tp, 1) == pytest.approx(math.pi * MM, rel=1e-12)


def test_incremental_arc_end():
    tp = run("G17 G0 X10 Y0 Z0\nG91 G3 X-10 Y10 I-10 J0 F100\n")
    assert np.allclose(tp.xyz_mm[arc_rows(tp, 1)[-1]], [0, 10, 0])
    assert line_length(tp, 1) == pytest.approx(5 * math.pi, rel=1e-12)


# ------------------------------------------------------------------ modal F and S ----
def test_modal_feed_speed_and_motion():
    text = ("G0 X0 Y0 Z5\n"
            "S1200 M3\n"
            "G1 Z0 F50\n"
            "X10\n"
            "X20 F200.\n"
            "S2400\n"
            "Y10\n"
            "G0 Z5\n"
            "X0\n"
            "M5\n"
            "G1 Z0\n")
    tp = run(text)
    by_line = {int(l): i for i, l in enumerate(tp.line)}
    f = {l: tp.feed_mm_min[i] for l, i in by_line.items()}
    s = {l: tp.spindle_rpm[i] for l, i in by_line.items()}
    on = {l: bool(tp.spindle_on[i]) for l, i in by_line.items()}
    assert [f[2], f[3], f[4], f[6], f[10]] == [50, 50, 200, 200, 200]
    assert np.isnan(f[7]) and np.isnan(f[8])  # rapids have no feed
    assert [s[2], s[3], s[6], s[10]] == [1200, 1200, 2400, 2400]
    assert on[2] and on[6] and not on[10]
    assert tp.motion[by_line[3]] == Motion.LINEAR and tp.motion[by_line[8]] == Motion.RAPID


def test_tool_numbers():
    tp = run("T3 M6\nG0 X0 Y0 Z0\nG1 X1 F10\nT5\nX2\nM6\nX3\n")
    tool = {int(l): int(t) for l, t in zip(tp.line, tp.tool)}
    assert tool[2] == 3 and tool[4] == 3 and tool[6] == 5  # T5 waits for its M6


# -------------------------------------------------------- unknown positions ----
@pytest.mark.parametrize("event", ["M98 P100", "G28", "G28 G91 Z0", "G30", "M6 T2",
                                   "G92 X0", "CYCLE800()", "L100"])
def test_positions_unknown_after_events(event):
    text = ("G90 G0 X0 Y0 Z0\n"  # 0
            "G1 X1 F100\n"  # 1 known
            f"{event}\n"  # 2
            "G90 G1 X2\n"  # 3 only X stated again
            "Y3\n"  # 4
            "G1 X1 Y1 Z1\n"  # 5 all axes known at the end, the start is not
            "X2\n")  # 6 known again
    tp = run(text)
    known = {int(l): bool(k) for l, k in zip(tp.line, tp.known)}
    assert known[1]
    assert not known[3] and not known[4] and not known[5]
    assert known[6]


def test_g91_after_unknown_stays_unknown_until_absolute():
    tp = run("G0 X0 Y0 Z0\nG28\nG91 G1 X1 F10\nG90 X0 Y0 Z0\nX1\n")
    known = {int(l): bool(k) for l, k in zip(tp.line, tp.known)}
    assert not known[2] and not known[3] and known[4]


def test_expressions_are_evaluated_or_unknown():
    tp = run("#1=5\n#<d>=[#1*2]\nG0 X0 Y0 Z0\nG1 X#1 Y#<d> F100\nG1 X#2\nG1 X0 Y0 Z0\nX1\n")
    e = ends(tp)
    assert np.allclose(e[3], [5, 10, 0])
    known = {int(l): bool(k) for l, k in zip(tp.line, tp.known)}
    assert known[3] and not known[4]  # #2 is never set
    assert not known[5] and known[6]


def test_subroutine_bodies_and_lines_after_m30_do_not_move():
    text = ("o100 sub\nG1 X50 F10\no100 endsub\n"
            "G0 X0 Y0 Z0\nG1 X1 F100\nM30\nG1 X99\n")
    tp = run(text)
    assert set(tp.line.tolist()) == {-1, 3, 4}


# ----------------------------------------------------------------- errors ----
@pytest.mark.parametrize("text, line", [
    ("G0 X0 Y0 Z0\nG1 X1\n", 2),  # no feed rate
    ("G0 X0 Y0 Z0\nG1 F100 X1\nG2 X10 Y0\n", 3),  # arc without centre
    ("G0 X0 Y0 Z0\nF100\nG2 X10 Y0 I3 J0\n", 3),  # end not on the circle
    ("G0 X0 Y0 Z0\nF100\nG2 X30 Y0 R5\n", 3),  # radius too small for the chord
    ("G0 X0 Y0 Z0\nG0 G1 X1 F10\n", 2),  # two motion codes
    ("G0 X0 Y0 Z0\n#1=[1/0]\n", 2),
])
def test_errors_are_located(text, line):
    with pytest.raises(NcoptError) as info:
        run(text)
    err = info.value
    assert (err.path, err.line) == ("t.nc", line)
    assert str(err).startswith(f"t.nc:{line}:")
    assert "; " in err.message


@given(st.lists(st.one_of(st.none(), st.floats(allow_nan=False)), max_size=40),
       st.sampled_from([math.nan, 0.0, -1.0]))
def test_ffill_carries_the_last_value_forward(items, initial):
    values = np.array([math.nan if v is None else v for v in items], dtype=np.float64)
    expected, last = [], initial
    for v in values.tolist():
        last = last if math.isnan(v) else v
        expected.append(last)
    out = ffill(values, initial)
    assert out.dtype == np.float64 and out is not values
    assert np.array_equal(out, np.array(expected, dtype=np.float64), equal_nan=True)


@pytest.mark.parametrize("body, line", [
    (["G0 X0 Y0 Z5", "G1 X1 F100", "G0 G1 X2", "G20 G21 X3"], 5),  # the first such line
    (["G0 X0 Y0 Z5", "G17 G18 X1 F100"], 4),
    (["G0 X0 Y0 Z5", "M30", "G0 G1 X2"], None),  # after the program end: never run
])
def test_two_g_codes_of_one_modal_group_on_an_executed_line_are_refused(body, line):
    prog = parse_text("\n".join(["%", "G21 G90"] + body + ["M30", "%"]) + "\n")
    if line is None:
        interpret(prog)
        return
    with pytest.raises(NcoptError) as info:
        interpret(prog)
    assert info.value.line == line
    assert "two G codes from the same modal group on one line" in info.value.message


def test_ai_contour_control_is_a_mode_and_keeps_the_motion():
    """Fanuc ``G05.1 Q1 R5`` switches AI contour control on: no move, its R is a level
    (it was refused: "R word with no G code that uses it"), and the line after it still
    moves in the motion mode before it (G0 here)."""
    tp = interpret(parse_text("G21 G90\nS1000 M3\nG0 X0 Y0 Z5\nG05.1 Q1 R5\nZ1\n"
                              "G1 Z0 F100\nX10\nG05.1 Q0\nM30\n"))
    assert tp.line.tolist() == [-1, 2, 4, 5, 6]
    assert tp.motion.tolist() == [-1, Motion.RAPID, Motion.RAPID, Motion.LINEAR, Motion.LINEAR]
    assert tp.known[2:].all() and not tp.warnings  # the first move starts nowhere known


@pytest.mark.parametrize("block", ["G5.1 X20 Y0 I5 J5", "G5 X20 Y0 I5 J5 P5 Q-5",
                                   "G5.2 X20 Y0 P1 L3", "G05.1 Q2 X0 Y0 Z0"])
def test_a_spline_or_smoothing_block_with_axes_is_not_followed(block):
    """A LinuxCNC spline or NURBS block, or Fanuc's nano smoothing axis designation: ncopt
    does not follow it (the spline was read as a straight G1 to its end point), so the
    moves after it are left until a move gives every axis again, with a located warning."""
    tp = interpret(parse_text(f"G21 G90\nS1000 M3\nG0 X0 Y0 Z5\nG1 Z0 F100\nX10\n{block}\n"
                              "G1 X30 Y0\nX40 Y0 Z0\nX50\nM30\n"))
    assert 5 not in tp.line.tolist()  # the block itself is no straight move
    known = dict(zip(tp.line.tolist(), tp.known.tolist()))
    assert known[4] and not known[6] and not known[7] and known[8]
    assert tp.warnings[0].startswith("<input>:6: a spline, NURBS or smoothing block")


@pytest.mark.parametrize("between", ["G28 Z0", "T2 M6", "G81 X5 Y5 Z-3 R1 F100\nX8 Y5\nG80"])
def test_the_move_after_a_lost_position_starts_nowhere_known(between):
    """A move giving every axis right after G28, a tool change or a drilling cycle ends
    where it says but starts where ncopt does not know: it was timed and planned from the
    point before (as if G28 had not moved the machine)."""
    text = f"G21 G90\nS1000 M3\nG0 X0 Y0 Z5\nG1 Z0 F100\nX10\n{between}\nG1 X20 Y5 Z0\nX30\nM30\n"
    tp = interpret(parse_text(text))
    after = text.count("\n", 0, text.index("G1 X20"))  # 0-based line of the move after
    known = dict(zip(tp.line.tolist(), tp.known.tolist()))
    assert known[4] and not known[after] and known[after + 1]


@pytest.mark.parametrize("on, off", [("G51 X0 Y0 P500", "G50"), ("G51.1 X0", "G50.1 X0"),
                                     ("SCALE X0.5 Y0.5", "SCALE"), ("ASCALE X2 Y2", "TRANS"),
                                     ("MIRROR X0", "MIRROR"), ("AMIRROR Y0", "ROT"),
                                     ("G72 F0.5", "G50")])
def test_moves_under_a_scaling_or_mirror_image_are_not_planned(on, off):
    """Fanuc G51/G51.1 and Sinumerik SCALE/MIRROR change the geometry the program states
    (a path scaled by 0.5 is steeper, its R_eff larger: S as planned would be too fast):
    the moves under them are left with the reason; after the reset they are planned again
    once every axis is given.  They used to be planned as written (G51 even read as a move
    to its centre)."""
    text = (f"G21 G90\nS1000 M3\nG0 X0 Y0 Z5\nG1 Z0 F100\nX10\n{on}\nG1 X20 Y5 Z0\nX30\n"
            f"{off}\nG1 X40 Y5 Z0\nX50\nM30\n")
    tp = interpret(parse_text(text))
    known = dict(zip(tp.line.tolist(), tp.known.tolist()))
    assert 5 not in known and 8 not in known  # the G51/G50 lines are no moves
    assert known[4] and not known[6] and not known[7] and not known[9] and known[10]
    assert any(":7-8: not planned (scaling or a mirror image in force" in w for w in tp.warnings)
    assert not any(f"'{on.split()[0]}' is not interpreted" in w for w in tp.warnings)


@pytest.mark.parametrize("word, why", [("F=R1", "the feed is an assignment (F=...)"),
                                       ("S=R2", "the spindle speed is an assignment (S=...)")])
def test_a_computed_feed_or_speed_leaves_its_moves_with_the_reason(word, why):
    """Sinumerik ``G1 Z0 F=R1`` / ``S=R2``: ncopt does not evaluate R parameters, so the moves
    under them are left as programmed with the reason, until a plain F / S word (and the
    position is given again: ncopt reads no move on the assignment's line).  F=R1 was
    refused outright ("feed move with zero feed rate; add an F word"), and S=R2 left the
    S before it in force, as if the assignment had not been there."""
    text = (f"R1=1000\nR2=5000\nG21 G90\nS1000 M3\nG0 X0 Y0 Z5\nG1 Z0 F100\nX10\n"
            f"G1 X15 {word}\nX20 Y5\nX30 Y5 Z0 {word[0]}{'200' if word[0] == 'F' else '2000'}\n"
            "X40\nM30\n")
    tp = interpret(parse_text(text, dialect="sinumerik"))
    known = dict(zip(tp.line.tolist(), tp.known.tolist()))
    assert 7 not in known  # the line with the assignment is read as no move
    assert known[6] and not known[8] and not known[9] and known[10]
    assert any(f":9-10: not planned ({why}" in w for w in tp.warnings)
    assert not any(f"'{word[0]}' is not interpreted" in w for w in tp.warnings)


@pytest.mark.parametrize("on, off, why", [
    ("G16", "G15", "polar coordinates (G16)"),
    ("G12.1", "G13.1", "polar coordinate interpolation (G12.1)"),
    ("G07.1 C10", "G07.1 C0", "cylindrical interpolation (G07.1)"),
    ("G96 S200", "G97 S1000", "constant surface speed (G96)")])
def test_moves_under_a_mode_ncopt_does_not_read_are_left(on, off, why):
    """Under G16 X is a radius and Y an angle, under G96 S is m/min: read as written they
    were planned as Cartesian moves at S200 RPM.  Now they are left with the reason, and
    planned again after the mode is switched off and every axis given."""
    text = (f"G21 G90\nS1000 M3\nG0 X0 Y0 Z5\nG1 Z0 F100\nX10\n{on}\nG1 X20 Y5 Z0\nX30\n"
            f"{off}\nG1 X40 Y5 Z0\nX50\nM30\n")
    tp = interpret(parse_text(text))
    known = dict(zip(tp.line.tolist(), tp.known.tolist()))
    assert known[4] and not known[6] and not known[7] and known[10]
    assert any(f"-8: not planned ({why}" in w or f"-10: not planned ({why}" in w
               for w in tp.warnings)  # G07.1 C10 is read as a rotary move of its own


@pytest.mark.parametrize("text", [
    "%_N_PART_MPF\nG17 G90 G70\nS1000 M3\nG0 X0 Y0 Z0.2\nG1 Z0 F40\nX1\nY1\nM30\n",
    "%PART G70 *\nN10 G17 G90 *\nN20 S1000 M03 *\nN30 G00 X+0 Y+0 Z+0.2 *\nN40 G01 Z+0 F40 *\n"
    "N50 X+1 *\nN60 Y+1 *\nN70 M30 *\nN99999 %PART G70 *\n"])
def test_inch_by_g70_or_a_heidenhain_header_is_not_read_as_mm(text):
    """Sinumerik G70 and Heidenhain ISO's "%PART G70 *" select inch; ncopt reads units from
    G20/G21, so such a program was planned in mm (its 1 inch moves as 1 mm).  Now its moves
    are left as programmed with the reason."""
    tp = interpret(parse_text(text))
    assert not tp.known[1:].any()
    assert any("not planned (inch lengths selected by G70" in w for w in tp.warnings)


@pytest.mark.parametrize("block, moves", [("G31 X15 F50", False), ("G27 X0 Y0 Z0", False),
                                          ("G29 X10 Y0", False), ("G33.1 Z-5 K1", False),
                                          ("G111 X5 Y5", False)])
def test_special_moves_and_poles_are_no_plain_moves(block, moves):
    """A skip (G31 stops at a signal), the reference-position check and return (G27, G29)
    and rigid tapping (G33.1) were read as plain moves in the modal G1, the first planned
    as a cut; a Sinumerik pole (G111, a Haas work offset) as a move to the pole.  Now none
    is a move, and the position is lost after each."""
    text = f"G21 G90\nS1000 M3\nG0 X0 Y0 Z5\nG1 Z0 F100\nX10\n{block}\nG1 X20 Y5 Z0\nX30\nM30\n"
    tp = interpret(parse_text(text))
    known = dict(zip(tp.line.tolist(), tp.known.tolist()))
    assert 5 not in known and known[4] and known[7]
    assert known[6] == moves


@pytest.mark.parametrize("block", ["G12 I5 K10 Q2 Z-1 D1 F50", "G150 X0 Y0 Z-1 Q1 R1 F50",
                                   "G45 X5"])
def test_a_g_code_ncopt_does_not_read_is_no_move_and_loses_the_position(block):
    """Haas G12 (a circular pocket), G150 (a general pocket, R its plane), G45 (tool offset
    increase): read as a plain G1 to their axis words (G12 planned as a cut), G150 refused
    for its R word.  Now the line is no move, with a located warning, and the position is
    known again once a move gives every axis."""
    text = f"G21 G90\nS1000 M3\nG0 X0 Y0 Z5\nG1 Z0 F100\nX10\n{block}\nG1 X20 Y5 Z0\nX30\nM30\n"
    tp = interpret(parse_text(text))
    known = dict(zip(tp.line.tolist(), tp.known.tolist()))
    assert 5 not in known and known[4] and not known[6] and known[7]
    code = block.split()[0]
    assert tp.warnings[0] == f"<input>:6: {code} is a G code ncopt does not read; the moves " \
        "after it keep their S/F until the position is known again"


def test_sinumerik_g26_s_is_a_speed_limit_not_the_spindle_speed():
    tp = interpret(parse_text("G21 G90\nS1000 M3\nG26 S8000\nG0 X0 Y0 Z5\nG1 Z0 F100\nX10\n"
                              "M30\n", dialect="sinumerik"))
    assert set(tp.spindle_rpm[1:].tolist()) == {1000.0}


@pytest.mark.parametrize("first, then, lost", [("G54", "G55", True), ("G54", "G54", False),
                                               ("G54.1 P1", "G54.1 P2", True),
                                               ("G54.1 P1", "G54.1 P1", False)])
def test_a_change_of_work_offset_loses_the_position(first, then, lost):
    """After G54 -> G55 the next move is in another frame: it was planned from the point
    before in the old one.  Re-stating the offset in force (posts write G54 at every
    operation) changes nothing."""
    text = (f"G21 G90 {first}\nS1000 M3\nG0 X0 Y0 Z5\nG1 Z0 F100\nX10\n{then}\n"
            "G1 X20 Y5 Z0\nX30\nM30\n")
    tp = interpret(parse_text(text))
    known = dict(zip(tp.line.tolist(), tp.known.tolist()))
    assert known[4] and known[7] and known[6] != lost
