"""ncopt.motion.orientation: everything that tilts the tool is read; a move whose tool axis
ncopt cannot know is left as programmed, with a located reason."""

from __future__ import annotations

import numpy as np
import pytest

from ncopt.api import rewrite_text
from ncopt.model import Job
from ncopt.runtime.errors import NcoptError, NothingToPlan
from ncopt.motion.interp import interpret
from ncopt.model import Cutter, CuttingData, Machine
from ncopt.reading.parse import parse_text

# the programs here are a few straight lines: planned whatever their geometry says
JOB = Job(machine=Machine(227, 15000), cutter=Cutter(10, 2), cutting=CuttingData(150, 0.08),
          operations=("all",))
HEAD = "G21 G90 G94 G17 M428\nS4000 M3\nG0 X0 Y0 Z5 A0 C0\nG1 Z0 F500\n"  # lines 0-3


def run(text: str, dialect: str | None = None, **kw):
    return interpret(parse_text(text, "t.nc", dialect=dialect), **kw)


def planned_lines(tp) -> dict:
    """{0-based line: planned?} of every move but the first (whose start is unknown)."""
    return {int(l): bool(k) for l, k in zip(tp.line[2:], tp.known[2:])}


def warning_for(tp, line: int) -> str:
    """The warning whose located stretch holds 1-based ``line``."""
    for w in tp.warnings:
        where = w.split(": not planned")[0].rsplit(":", 1)[-1]
        a, _, b = where.partition("-")
        if a.isdigit() and int(a) <= line <= int(b or a):
            return w
    raise AssertionError(f"no warning for line {line}: {tp.warnings}")


def test_a_three_axis_program_reads_no_orientation():
    tp = run(HEAD + "G1 X10 Y5\nX20\n")
    assert all(planned_lines(tp).values())
    assert tp.warnings == ()


def test_rotary_axes_at_zero_leave_the_tool_vertical():
    tp = run("G0 X0 Y0 Z5 A0. C0.\n" + HEAD[:-1] + "\nG1 X10 C0\nX20\n")
    assert all(planned_lines(tp).values())


def test_tilting_rotary_moves_are_not_planned_without_kinematics():
    tp = run(HEAD + "G1 X10\n"  # 4 planned
             "G1 X20 A10 C30\n"  # 5 tilts the tool: not planned
             "G1 X30\n"  # 6 still tilted
             "G1 X40 A0 C0\n"  # 7 ends vertical but starts tilted
             "G1 X50\n")  # 8 vertical again
    p = planned_lines(tp)
    assert p[4] and p[8]
    assert not p[5] and not p[6] and not p[7]
    w = warning_for(tp, 6)
    assert w == ("t.nc:6-8: not planned (the rotary axes (A, C) tilt the tool and no "
                 "kinematics is given; pass --kinematics xyzac-trt, xyzac-head-table or "
                 "xyzac-trt-linuxcnc as the machine is built); S/F left as programmed")


def test_a_rotary_only_move_is_a_move_and_keeps_its_feed():
    text = (HEAD + "G1 X10 Y0\n"  # 4 planned: its F is rewritten
            "G1 A20\n"  # 5 turns the tool on the spot: F500 in force as programmed
            "G1 A0\n"  # 6
            "G1 X20\n")  # 7 planned
    tp = run(text)
    assert 5 in planned_lines(tp) and 6 in planned_lines(tp)
    rows = np.flatnonzero(tp.line == 5)
    assert tp.seg_len_mm[rows].sum() == 0.0
    result = rewrite_text(text, JOB, "t.nc")
    lines = result.text.splitlines()
    t = result.targets
    assert t.f_value[list(t.line).index(5)] == 500.0
    assert "F" in lines[5] or "F500" in lines[4]  # the programmed feed is restored


@pytest.mark.parametrize("event, reason", [
    ("G28", "after G28/G30 (line 6)"),
    ("M98 P100", "after a subprogram or macro call (line 6)"),
    ("G92 A0", "after the A word of line 6"),
])
def test_rotary_position_lost_until_stated_again(event, reason):
    tp = run(HEAD + "G1 X10 A5\nG1 X11 A0\n"  # 4-5
             f"{event}\n"  # 6 (1-based 7): loses the rotary position
             "G0 X0 Y0 Z5\nG1 Z0\n"  # 7-8 not planned: where is A?
             "G1 X5 A0 C0\n"  # 9 ends known, starts unknown
             "G1 X6\n")  # 10 planned
    p = planned_lines(tp)
    assert not p[8] and not p[9] and p[10]
    assert reason.replace("line 6", "line 7") in warning_for(tp, 9)


def test_an_unknown_rotary_value_is_not_planned():
    tp = run(HEAD + "G1 X10 A#7\nG1 X20 Y0 Z0 A0\nG1 X30\n")
    p = planned_lines(tp)
    assert not p[4] and not p[5] and p[6]


@pytest.mark.parametrize("ijk, expected", [("I0 J0 K1", None), ("I0 J0.5 K0.866", (0, .5, .866)),
                                           ("I0.1 K1", (0.1, 0, 1))])
def test_g43_5_tool_vectors_are_read(ijk, expected):
    tp = run(HEAD + "G43.5 H1\nG1 X10 " + ijk + "\nG1 X20\nG49\nG1 X30 Z1\n")
    p = planned_lines(tp)
    assert p[6] and p[8]
    if expected is None:
        assert p[5] and tp.tool_axis is None
        return
    e = np.array(expected) / np.linalg.norm(expected)
    at = {int(l): a for l, a in zip(tp.line, tp.tool_axis)}
    assert np.allclose(at[5], e) and np.allclose(at[6], e)  # the vector holds
    assert np.allclose(at[8], [0, 0, 1])  # G49 ends the vector mode
    assert tp.kinematics == "vector"


def test_sinumerik_vectors_are_read_under_traori():
    text = ("G0 X0 Y0 Z5\nS4000 M3\nG1 Z0 F500\nTRAORI\n"  # 0-3
            "G1 X10 Y0 Z0 A3=0 B3=0.5 C3=0.866\n"  # 4: the first move under TRAORI
            "G1 X11 Y0 Z0\n"  # 5 the vector holds
            "G1 X12 B3=1 C3=1\n"  # 6 A3 left out: 0
            "TRAFOOF\nG0 Z5\nG0 X0 Y0 Z0\nG1 X1\n")  # 7-10
    tp = run(text, dialect="sinumerik")
    p = planned_lines(tp)
    assert p[5] and p[6] and p[10]
    at = {int(l): a for l, a in zip(tp.line, tp.tool_axis)}
    assert np.allclose(at[5], np.array([0, 0.5, 0.866]) / np.linalg.norm([0, .5, .866]))
    assert np.allclose(at[6], np.array([0, 1, 1]) / np.sqrt(2))
    assert np.allclose(at[10], [0, 0, 1])


def test_sinumerik_vectors_without_traori_are_not_planned():
    tp = run(HEAD + "G1 X10 A3=0 B3=0.5 C3=0.866\nG1 X11\n", dialect="sinumerik")
    p = planned_lines(tp)
    assert not p[4] and not p[5]
    assert "A3= B3= C3= without TRAORI" in warning_for(tp, 6)


def test_a_zero_tool_vector_is_a_located_error():
    with pytest.raises(NcoptError) as info:
        run(HEAD + "G43.5 H1\nG1 X10 I0 J0 K0\n")
    assert str(info.value).startswith("t.nc:6:1: the tool vector (G43.5 I J K) has no "
                                      "direction; give the tool axis")


@pytest.mark.parametrize("tilt, reset, dialect", [
    ("G68.2 X0 Y0 Z0 I0 J30 K0", "G69", None),
    ("CYCLE800(1,\"TC1\",200000,57,0,0,0,0,30,0,0,0,0,-1,100,1)", "CYCLE800()\nG0 A0 B0 C0",
     "sinumerik"),
    ("ROT X=30", "ROT", "sinumerik"),
    ("AROT Y=-10", "TRANS", "sinumerik"),
    ("TCARR=1", "TCARR=0\nG0 A0 B0 C0", "sinumerik"),
    ("PLANE SPATIAL SPA+0 SPB+45 SPC+0 STAY", "PLANE RESET STAY\nG0 A0 B0 C0",
     "heidenhain-iso"),
])
def test_tilted_working_planes_are_not_planned_until_reset(tilt, reset, dialect):
    n_tilt = tilt.count("\n") + 1
    text = (HEAD.replace("A0 C0", "A0 B0 C0") + "G1 X5\n" + tilt + "\nG0 X0 Y0 Z5\nG1 Z0\nG1 X10\n" + reset +
            "\nG0 X0 Y0 Z5\nG1 Z0\nG1 X10\n")
    tp = run(text, dialect=dialect)
    p = planned_lines(tp)
    a = 5 + n_tilt  # the first line after the tilt
    assert p[4]
    assert not p[a + 1] and not p[a + 2]
    b = a + 3 + reset.count("\n") + 1
    assert p[b + 1] and p[b + 2], (tp.warnings, p)
    assert ("not planned (G68.2 without G53.1" if tilt.startswith("G68.2") else
            "not planned (a ") in warning_for(tp, a + 3)


def test_a_rotation_about_the_tool_axis_does_not_tilt():
    tp = run(HEAD + "ROT Z=30\nG0 X0 Y0 Z5\nG1 Z0\nG1 X10\n", dialect="sinumerik")
    assert planned_lines(tp)[7]


def test_a_program_that_only_tilts_has_nothing_to_plan():
    text = "G21 G90 G94\nS4000 M3\nG0 X0 Y0 Z5 A15 C30\nG1 Z0 F500\nG1 X10\nG1 X20 C40\n"
    with pytest.raises(NothingToPlan) as info:
        rewrite_text(text, JOB, "t.nc")
    assert str(info.value).startswith("t.nc: nothing to plan")


def test_a_tilted_move_keeps_the_programs_s_and_f():
    text = "G21 G90 G94 M428\nS4000 M3\nG0 X0 Y0 Z5 A0 C0\nG1 Z0 F500\nG1 X10\nG1 X20 A10 C5\nG1 X30\n"
    result = rewrite_text(text, JOB, "t.nc")
    out = result.text.splitlines()
    assert out[-2:] == text.splitlines()[-2:]  # the tilted lines, byte for byte
    before, after = run(text), run(result.text)
    for tp in (before, after):  # the S and F in force there: the program's own
        last = tp.line == tp.line.max()
        assert np.all(tp.spindle_rpm[last] == 4000) and np.all(tp.feed_mm_min[last] == 500)
    assert any(w.startswith("t.nc:6-7: not planned (the rotary axes") for w in
               result.summary.warnings)
