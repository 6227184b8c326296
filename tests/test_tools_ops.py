"""Tools and operation names as programs write them: a tool the program calls no ball is
never planned, a free-text size is the diameter only where the text says so, and an
operation name is found after any block of comments (the issue "Right where it plans").

Every program here is built the way a CAM post writes it; the real lines are quoted from
the corpus programs they come from.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ncopt.api import Job, rewrite_text
from ncopt.errors import NothingToPlan
from ncopt.model import Cutter, Machine
from ncopt.parse import parse_text
from ncopt.tooltable import BALL, FLAT, OTHER, UNNUMBERED, parse_tool_comment, tool_table

MACHINE = Machine(accel_rad_s2=227.0, max_rpm=15000.0)
JOB = Job(machine=MACHINE)
KB63 = "more2/carbidecreate-vcarve_KB-63.nc"
V_BIT = "TOOL/MILL,0.0250,0,10.0000,30.0"  # KB-63 line 9: D, corner radius, height, 30 deg


def corpus_text(corpus_dir, name: str) -> str:
    return (corpus_dir / name).read_bytes().decode("latin-1")


def dome_passes(step_mm: float = 0.6, passes: int = 12, f: int = 1000) -> list[str]:
    """A zig-zag finish over a dome (the tip of a D6 ball), mm: Z follows the surface."""
    out, y0 = [], -step_mm * passes / 2
    for i in range(passes):
        y = y0 + i * step_mm
        xs = np.linspace(-10.0, 10.0, 21)
        for x in (xs if i % 2 == 0 else xs[::-1]):
            out.append(f"X{x:.3f} Y{y:.3f} Z{10.0 - (x * x + y * y) / 120.0:.3f}"
                       + (f" F{f}" if not out else ""))
    return out


# ------------------------------------------------ 1. a tool that is no ball ----
def test_the_carbide_create_v_bit_after_the_first_moves_is_the_cutting_tool(corpus_dir):
    """KB-63 has ``(TOOL/MILL,0.1,0.05,0.000,0)`` in its header (which alone reads as a
    0.1 mm ball) and ``(TOOL/MILL,0.0250,0,10.0000,30.0)`` on line 9, after
    ``G0X0.000Y0.000Z0.000`` and before its first cut: a 30 deg V-bit (taper angle 30).
    The two disagree; the V-bit, which says the tool is no ball, decides."""
    info = tool_table(parse_text(corpus_text(corpus_dir, KB63)))[UNNUMBERED]
    assert (info.kind, info.line, info.text, info.source) == (OTHER, 9, V_BIT, "Carbide Create")


def test_the_v_carve_is_left_and_asks_for_no_diameter(corpus_dir):
    """It used to ask for --diameter (the descriptions disagreed: no tool) and, given one,
    planned the V-carve as a ball (S 15000 -> 24000)."""
    text = corpus_text(corpus_dir, KB63)
    with pytest.raises(NothingToPlan) as exc:
        rewrite_text(text, JOB, KB63)
    why = str(exc.value)
    assert V_BIT in why and "not a ball or bull-nose" in why
    assert "give --diameter" not in why
    assert not any(op.planned for op in exc.value.operations)


def test_diameter_does_not_turn_the_v_bit_into_a_ball(corpus_dir):
    text = corpus_text(corpus_dir, KB63)
    with pytest.raises(NothingToPlan) as exc:
        rewrite_text(text, replace(JOB, cutter=Cutter(6.0, 2)), KB63)
    why = str(exc.value)
    assert f"({V_BIT}, line 9)" in why and "--shape ball" in why


def test_the_command_line_leaves_the_v_carve_with_its_line(corpus_dir, tmp_path):
    from typer.testing import CliRunner

    from ncopt.cli import app
    out = tmp_path / "out.nc"
    run = CliRunner().invoke(app, ["rewrite", str(corpus_dir / KB63), "--accel", "227",
                                   "--max-rpm", "15000", "--diameter", "6", "-o", str(out)])
    assert run.exit_code == 5 and not out.exists()
    assert f"{V_BIT}, line 9" in run.stderr


def test_the_shapeoko_ball_keeps_working(corpus_dir):
    """``(TOOL/MILL,0.7937,0.39687,1.000,0.0)`` before ``M6 T121``: corner radius half the
    diameter, no taper: a 1/32" ball (0.7937 mm), whatever the header's placeholder says."""
    table = tool_table(parse_text(corpus_text(corpus_dir, "more/carbidecreate_shapeoko_tag.nc")))
    assert (table[121].kind, table[121].diameter, table[121].line) == (BALL, 0.7937, 8)


def test_a_v_bit_after_the_tool_change_and_its_first_rapids_is_that_tool():
    """Carbide Create's form with an M6: the V-bit comment after ``M6 T102`` and a rapid
    move, before the first cut, describes T102 (it used to describe no tool)."""
    text = ("%\n(TOOL/MILL,0.1,0.05,0.000,0)\nG21\nG90\nM6 T102\nM3 S15000\nG0X0.000Y0.000Z5.000\n"
            "(TOOL/MILL,0.03,0.00,6.35,45.00)\nG1Z-1.0F300\nX10.0\nM30\n")
    info = tool_table(parse_text(text))[102]
    assert (info.kind, info.line) == (OTHER, 8)


def test_a_comment_after_the_last_cut_describes_no_cutting_tool():
    """A V-bit named after every cut (the next job's tool) does not refuse the ball; with
    the two disagreeing no description serves the program (ncopt asks)."""
    text = ("(BALL 6 MM)\nG21\nG0 X0 Y0 Z5\nG1 Z0 F300\nX10\nG0 Z5\n(60deg. 1/2\" V bit)\n"
            "M30\n")
    assert UNNUMBERED not in tool_table(parse_text(text))


def test_a_ball_named_with_its_number_and_a_flat_end_mill_at_its_tool_change():
    """Two descriptions of T1 contradict each other: the one that says flat end mill
    wins over the numbered ball (it used to lose by rank), so T1 is never planned."""
    text = ("(T1 D=6 CR=3 - ZMIN=0 - ball end mill)\nG21\nT1 M6\n(6MM FLAT END MILL)\n"
            "S6000 M3\nG0 X0 Y0 Z5\nG1 Z0 F300\nX10\nM30\n")
    info = tool_table(parse_text(text))[1]
    assert (info.kind, info.text) == (FLAT, "6MM FLAT END MILL")


NOT_A_BALL = [  # how real programs describe cutters ncopt does not plan
    "(T1 D=8. CR=0. TAPER=118DEG - ZMIN=-21. - DRILL)",  # Fusion (chess_engraved_box.nc)
    "(T1 D=6 CR=0 - ZMIN=0 - flat end mill)",  # Fusion
    "(T1 D=6 CR=0 TAPER=45DEG - ZMIN=0 - chamfer mill)",  # Fusion, a chamfer mill
    "(TOOL/MILL,0.0250,0,10.0000,30.0)",  # Carbide Create V-bit (KB-63)
    "(Tool change - D = 3.0 mm type VCARVE flutes 1)",  # BlenderCAM
    "(  Tool #1: Flat End Mill 3 Flutes, Diam = 3mm, Len = 15.00mm)",  # OpenBuilds
    "(T1|1/4 SPOT DRILL|H1)",  # Mastercam
    "(60deg. 1/2\" V bit)",  # free text (pygcode corpus)
    "(TOOL: V-BIT {90 DEG 0.5\"})",  # free text (pygcode corpus)
    "(ENGRAVER D=0.5MM 30DEG)",
]
HEAD = ["%", "G21 G90 G94", "T1 M6", "S6000 M3", "G0 X-13. Y-3.6", "Z15.", "G1 Z10.5 F333"]


@given(st.sampled_from(NOT_A_BALL), st.integers(1, len(HEAD) - 1))
def test_a_tool_the_program_calls_no_ball_before_its_cuts_is_never_planned(comment, at):
    """A ball description (Fusion's, numbered) and, anywhere before the first cut, one
    that says the tool is something else: the tool is left, and the summary names the
    other description; no ``--diameter`` is asked for."""
    head = HEAD[:1] + ["(T1 D=6 CR=3 - ZMIN=0 - ball end mill)"] + HEAD[1:]
    lines = head[:at + 1] + [comment] + head[at + 1:] + dome_passes() + ["G0 Z15.", "M30", "%"]
    text = "\n".join(lines) + "\n"
    assert tool_table(parse_text(text))[1].text == comment[1:-1]
    with pytest.raises(NothingToPlan) as exc:
        rewrite_text(text, JOB)
    assert comment[1:-1].strip() in str(exc.value) and "give --diameter" not in str(exc.value)


def test_the_same_program_with_the_ball_alone_is_planned():
    """The control for the property above: its program plans when nothing says no ball."""
    head = HEAD[:1] + ["(T1 D=6 CR=3 - ZMIN=0 - ball end mill)"] + HEAD[1:]
    text = "\n".join(head + dome_passes() + ["G0 Z15.", "M30", "%"]) + "\n"
    (plan,) = rewrite_text(text, JOB).plans
    assert plan.cutter.diameter_mm == 6.0 and plan.cutter.is_ball
