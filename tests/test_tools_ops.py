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

from ncopt.api import rewrite_text
from ncopt.model import Job
from ncopt.runtime.errors import NothingToPlan
from ncopt.model import Cutter, Machine
from ncopt.planning.opnames import operation_comments
from ncopt.reading.parse import parse_text
from ncopt.planning.tooltable import BALL, FLAT, OTHER, UNNUMBERED, parse_tool_comment, tool_table

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

    from ncopt.cli.app import app
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


# --------------------------------- 2. a free-text size is a diameter where it says so ----
@pytest.mark.parametrize("text, kind, diameter, unit", [
    ('1/4 BALL ENDMILL 1" FLUTE LENGTH', BALL, 0.25, "inch"),  # the issue's: read as 1"
    ('3/4 carbide endmill 3" flute length', FLAT, 0.75, "inch"),  # fusion-haas-inch_1001.nc
    ('1/2" BALL 2 FLUTE 3/4 LOC', BALL, 0.5, "inch"),
    ("1/4 BALL END MILL 1/4 SHANK 2.5 OAL", BALL, 0.25, "inch"),
    ("6MM BALL 8MM SHANK 60MM OVERALL LENGTH", BALL, 6.0, "mm"),
    ("BALL 6MM, STICKOUT 30MM", BALL, 6.0, "mm"),
    ("T2 6 BALL ENDMILL", BALL, 6.0, None),  # a leading size: the program's units
    (" T1 = Ball Nose 3 mm ", BALL, 3.0, "mm"),  # Vectric
    ("HSS, 2-Flute Endmill, 2mm", FLAT, 2.0, "mm"),  # Estlcam (estlcam_Enclosure.nc)
    ("Endmill Dia. 0.250", FLAT, 0.25, None),  # keyed (pygcode corpus)
    ('ID=022  0.2370" Reamer - 6mm slide', OTHER, 0.237, "inch"),  # solidworks-fanuc corpus
])
def test_a_free_text_diameter_is_the_size_the_text_calls_one(text, kind, diameter, unit):
    info = parse_tool_comment(text, 5)
    assert (info.kind, info.diameter, info.unit) == (kind, diameter, unit)


@pytest.mark.parametrize("text", [
    "6mm BALL 50mm",  # which is the diameter?
    "BALL ENDMILL 1\" FLUTE LENGTH",  # a length only
    "BALL SHANK 6MM",
    "BALL 6MM STICKOUT 30MM",  # the stickout 6 mm or 30 mm?
])
def test_a_ball_with_no_size_that_is_its_diameter_is_no_description(text):
    assert parse_tool_comment(text, 1) is None


_LENGTH_WORDS = ["FLUTE LENGTH", "FLUTE", "FL", "LOC", "SHANK", "OAL", "OVERALL LENGTH",
                 "LONG", "STICKOUT", "REACH", "NECK", "LENGTH OF CUT", "CUTTING LENGTH"]


@given(st.sampled_from(["1/8", "3/16", "1/4", "3/8", "1/2", "5/8", "3/4", '1"', "1 1/4"]),
       st.sampled_from(["BALL ENDMILL", "BALL NOSE", "carbide ball end mill", "FLAT ENDMILL"]),
       st.floats(0.05, 6.0).map(lambda v: round(v, 3)), st.sampled_from(_LENGTH_WORDS),
       st.sampled_from(['"', " in", "mm"]))
def test_a_length_is_never_the_diameter(size, name, length, word, mark):
    """``<fraction> <cutter> <length><unit> <length word>``: the diameter is the fraction
    in inch, whatever the length and its unit."""
    parts = size.rstrip('"').replace("/", " ").split()
    inch = float(parts[0]) if len(parts) == 1 else (
        float(parts[-2]) / float(parts[-1]) + (float(parts[0]) if len(parts) == 3 else 0.0))
    info = parse_tool_comment(f"{size} {name} {length:g}{mark} {word}", 1)
    assert (info.diameter, info.unit) == (pytest.approx(inch), "inch")


def test_the_fusion_haas_inch_program_gives_a_three_quarter_inch_end_mill(corpus_dir):
    """``(T7 D=0.75 CR=0. - ZMIN=-3.005 - FLAT END MILL)`` and, on line 5, ``(3/4 carbide
    endmill 3" flute length)``: both a 3/4" flat end mill (the second was read as 3")."""
    table = tool_table(parse_text(corpus_text(corpus_dir, "more2/fusion-haas-inch_1001.nc")))
    assert (table[7].kind, table[7].diameter) == (FLAT, 0.75)
    loose = table[UNNUMBERED]
    assert (loose.kind, loose.diameter, loose.unit, loose.line) == (FLAT, 0.75, "inch", 5)


def test_a_quarter_inch_ball_with_its_flute_length_is_planned_as_a_quarter_inch_ball():
    """An inch program whose only tool comment is ``(1/4 BALL ENDMILL 1" FLUTE LENGTH)``:
    it was planned as a 1" (25.4 mm) ball, vc four times the real one; the cutter is
    6.35 mm, and vc at the programmed S comes from it (pi * D_eff * S, D_eff <= 6.35 mm:
    at most 200 m/min at S10000)."""
    def z(x, y):
        return 0.4 - (x * x + y * y) / 4.0
    passes = []
    for i, y in enumerate(np.arange(-0.15, 0.2, 0.025)):
        xs = np.linspace(-0.4, 0.4, 21)[::(-1 if i % 2 else 1)]
        passes += [f"X{x:.4f} Y{y:.4f} Z{z(x, y):.4f}" for x in xs]
    passes[0] += " F40."
    text = "\n".join(["%", "O1000", '(1/4 BALL ENDMILL 1" FLUTE LENGTH)', "G90 G94 G17", "G20",
                      "", "(PARALLEL1)", "T1 M6", "S10000 M3", "G0 X-0.5 Y-0.15", "Z0.6",
                      "G1 Z0.3 F13.", *passes, "G0 Z0.6", "M5", "M30", "%"]) + "\n"
    (plan,) = rewrite_text(text, JOB).plans
    assert plan.cutter.diameter_mm == pytest.approx(6.35) and plan.cutter.is_ball
    assert plan.cutting.vc_m_min <= np.pi * 6.35 * 10000 / 1000 + 1e-6


@pytest.mark.parametrize("text, diameter", [
    ("T12 BALL ENDMILL", None),  # T12 is its number, not T1 and a 2
    ("T3 6 BALL", 6.0),
    ('2 FLUTE 1/4" BALL', 0.25),  # a flute count before the size is no length
    ("1/0 BALL", None),
])
def test_leading_sizes_and_numbers(text, diameter):
    info = parse_tool_comment(text, 1)
    assert (info.diameter if info else None) == diameter


# ------------------------------------------- 3. operation names after comments ----
FLAT3 = "(T3 D=6 CR=0 - ZMIN=0 - flat end mill)"
BALL1 = "(T1 D=6 CR=3 - ZMIN=0 - ball end mill)"
# Fusion's personal-use notice as more/fusion-linuxcnc-inch_r8s.ngc writes it (lines 6-9)
NOTICE = ["(WHEN USING FUSION FOR PERSONAL USE, THE FEEDRATE OF RAPID)",
          "(MOVES IS REDUCED TO MATCH THE FEEDRATE OF CUTTING MOVES,)",
          "(WHICH CAN INCREASE MACHINING TIME. UNRESTRICTED RAPID MOVES)",
          "(ARE AVAILABLE WITH A FUSION SUBSCRIPTION.)"]


def clearing(tool_call: list[str]) -> list[str]:
    """Adaptive-like clearing: concentric loops at three constant Z levels 3 mm apart."""
    out = tool_call + ["G0 X0. Y0.", "Z15."]
    for z in (6.0, 3.0, 0.0):
        out.append(f"G1 Z{z:.3f} F300")
        out += [f"X{r * np.cos(a):.3f} Y{r * np.sin(a):.3f} F1200"
                for r in np.arange(1.0, 12.0, 1.2) for a in np.linspace(0.0, 2 * np.pi, 24)]
        out.append("G0 Z15.")
    return out


def parallel(tool_call: list[str]) -> list[str]:
    return tool_call + ["G0 X-13. Y-3.6", "Z15.", "G1 Z10.5 F333", *dome_passes(), "G0 Z15."]


def two_ops(between: list[str], same_tool: bool) -> tuple[str, int]:
    """ADAPTIVE1 then, after the lines ``between`` (holding ``(PARALLEL2)``), a parallel
    finish with a ball: with T3 (a flat end mill) first, or the same ball for both.
    Returns the program and the 0-based line of the clearing's last retract."""
    tools = [BALL1] if same_tool else [FLAT3, BALL1]
    first = ["T1 M6" if same_tool else "T3 M6", "S5000 M3"]
    call = [] if same_tool or "T1 M6" in between else ["T1 M6", "S6000 M3"]
    lines = ["%", "O1000 (TEST)", *tools, "G90 G94 G17", "G21", "", "(ADAPTIVE1)",
             *clearing(first)]
    retract = len(lines) - 1
    lines += [*between, *parallel(call), "M5", "M30", "%"]
    return "\n".join(lines) + "\n", retract


FORMS = {  # the lines between the clearing's retract and the finish's moves
    "blank, notice, name": ["", *NOTICE, "(PARALLEL2)"],
    "notice, name (no blank line)": ["(Aviso: uso personal...)", "(PARALLEL2)"],
    "blank, name, notice": ["", "(PARALLEL2)", *NOTICE[:2]],
    "tool call, notice, name": ["", "T1 M6", *NOTICE[:2], "(PARALLEL2)"],
    "tool line, notice, name": ["", BALL1, "(Personal use notice: rapids at feed.)",
                                "(PARALLEL2)"],
}
CASES = [(form, same) for form in sorted(FORMS) for same in (True, False)
         if not (same and "T1 M6" in FORMS[form])]  # one tool: no second tool call


@pytest.mark.parametrize("form, same_tool", CASES,
                         ids=[f"{f}, {'one ball' if s else 'flat then ball'}" for f, s in CASES])
def test_the_finish_after_a_comment_block_is_its_own_operation_and_planned(form, same_tool):
    """The parallel finish was merged into the roughing before it (one tool: the whole
    program left as roughing) or shown by a notice's text or its T number.  It starts
    after the clearing's last retract, by its name line at the latest, and everything
    before it comes out byte for byte."""
    text, retract = two_ops(FORMS[form], same_tool)
    result = rewrite_text(text, JOB)
    rows = [(o.name, o.planned) for o in result.summary.operations]
    assert rows == [("ADAPTIVE1", False), ("PARALLEL2", True)]
    before = text.splitlines()
    start = int(result.summary.operations[1].lines.split("-")[0]) - 1  # "743-1002": 1-based
    assert retract < start <= before.index("(PARALLEL2)")
    after = [line for line in result.text.splitlines() if not line.startswith("(ncopt ")]
    assert len(after) == len(before) and after[:start] == before[:start]
    assert after[start:] != before[start:]


@pytest.mark.parametrize("lines, expected", [
    (["G0 Z15.", "", *NOTICE, "(PARALLEL2)", "T1 M6"], {6: "PARALLEL2"}),
    (["G0 Z15.", "(Aviso: uso personal...)", "(Paralelo2)", "G0 X1."], {2: "Paralelo2"}),
    (["G0 Z15.", "T1 M6", "(Using high feed G1 F5000. instead of G0.)", "(PARALLEL2)",
      "S5000 M3"], {3: "PARALLEL2"}),
    (["G0 Z15.", "", "; PARALLEL2", "T1 D1", "M6"], {2: "PARALLEL2"}),  # Sinumerik (Fusion)
    (["G0 Z15.", "; ----------------------------------",
      ";   - JOB: 68: FreePar12_FRA-SP0140-G2R1-N-ES-L25_DL:-0.3_DR:0",
      "; ----------------------------------"],
     {2: "FreePar12_FRA-SP0140-G2R1-N-ES-L25_DL:-0.3_DR:0"}),  # hyperMILL's JOB line
    (["G0 Z15.", "", "( OPERATION=  FINISH1 FLOWLINE SRF_MILL1 )", "G0 Z5."],
     {2: "FINISH1 FLOWLINE SRF_MILL1"}),  # the LinuxCNC boat demos
    (["G0 Z15.", "(Z=-1.0)", "(Layer 2)", "G1 X1. F100"], {}),  # data, then a label: no op
    (["G0 Z15.", "(Tool type: endmill)", "( M6 T2 )", "M3 S10000"], {}),  # FreeCAD: code
    (["G0 Z15.", "", "(1/4 BALL ENDMILL)", "T1 M6"], {}),  # a tool, not an operation
])
def test_operation_names_after_notices_tool_lines_and_in_other_posts_forms(lines, expected):
    text = "\n".join(lines + ["M30"]) + "\n"
    assert operation_comments(parse_text(text)) == expected


@pytest.mark.parametrize("name, line, expected", [
    ("more2/fusion-haas-es_1001.nc", 12, "Paralelo2"),  # after a blank, before N25 T1 M6
    ("more/fusion-linuxcnc-inch_r8s.ngc", 10, "PARALLEL1"),  # after the notice's G53 line
])
def test_the_corpus_operations_keep_their_names(corpus_dir, name, line, expected):
    names = operation_comments(parse_text(corpus_text(corpus_dir, name)))
    assert names.get(line) == expected
    assert not any("PERSONAL" in n.upper() for n in names.values())
