"""ncopt.planning.inspection: what it says about tools, units and dialects, as the program's owner reads it."""

from __future__ import annotations

import io
import json

from rich.console import Console

from ncopt.planning.inspection import inspect_text, render_inspection


def shown(text: str, dialect: str | None = None) -> list[str]:
    out = io.StringIO()
    render_inspection(inspect_text(text, "p.nc", dialect=dialect),
                      Console(file=out, width=200, color_system=None, highlight=False))
    return out.getvalue().splitlines()


def warnings(text: str, dialect: str | None = None) -> list[str]:
    return [w for w in inspect_text(text, "p.nc", dialect=dialect).warnings
            if "not planned" not in w]


def test_a_tool_line_says_size_unit_teeth_and_where_from():
    text = ("(T1 D=0.75 CR=0.375 - ZMIN=-0.375 - BALL END MILL)\n"
            "(  Tool #2: Flat End Mill 3 Flutes, Diam = 6mm, Len = 15.00mm)\n"
            "G20\nT1 M6\nS5000 M3\nG0 X0 Y0 Z1\nG1 Z0 F40.\n")
    lines = shown(text)
    assert "  tool T1: ball D0.75 r0.375 inch, teeth not given (line 1, Fusion 360)" in lines
    assert ("  tool T2: flat D6 r0 mm, 3 teeth (line 2, OpenBuilds (Fusion 360))" in lines)


def test_a_tool_without_corner_radius_shows_none_and_json_stays_json():
    text = "(T5 D=6 CR=0 TAPER=118DEG - ZMIN=-3 - drill)\n(T6|1/4 SPOT|H6)\nG21 S1 M3\n"
    info = inspect_text(text, "p.nc")
    row = json.loads(json.dumps(info.to_dict(), allow_nan=False))["tools"][1]
    assert row == [6, "other", 0.25, None, 2, None, None, "inch", "Mastercam"]
    assert "  tool T6: other D0.25 inch, teeth not given (line 2, Mastercam)" in shown(text)


def test_no_units_in_the_program_is_said():
    assert warnings("S1000 M3\nG1 X1 F100\n") == [
        "p.nc: no G20/G21 in the program: ncopt reads it in mm, as a control does that "
        "starts in metric; add G21 (or G20) to say which"]
    assert warnings("G21 S1000 M3\nG1 X1 F100\n") == []


def test_sinumerik_g70_is_inch_that_ncopt_would_not_see():
    text = "%_N_PART_MPF\nG70 S1000 M3\nG1 X1 F100\n"
    assert warnings(text) == [
        "p.nc: G70 selects inch for the lengths only on this control (F stays in the "
        "machine's basic unit, which the program does not say): the moves under it are left "
        "as programmed; G700 selects inch for lengths and F alike, and ncopt reads it"]
    assert warnings("%_N_PART_MPF\nG71 S1000 M3\nG1 X1 F100\n") == []


def test_tool_comments_in_inch_in_a_program_read_in_mm_are_pointed_out():
    text = "O1001\n(T23 ID=023  DIA-0.3937  10MM DRILL)\nS1 M3\nG1 X1 F10.\n"
    assert "p.nc:2: the tool comment gives D0.3937 for `10MM`: its sizes are in inch, but the " \
           "program is read in mm; check G20/G21" in warnings(text)


def test_a_program_without_s_words_is_pointed_out():
    assert "p.nc: no S word: the program never sets a spindle speed (shown as S 0 below)" \
        in warnings("G21\nM3\nG1 X1 F100\n")


def test_the_dialect_line_counts_the_named_marks():
    text = "%\nN10 G20\nN45 G64 P0.0004 Q0.0004\nN60 G43 Z0.64 H1\nN70 S5000 M3\n"
    assert shown(text)[0] == "p.nc: linuxcnc dialect (1 mark), inch, 5 lines"
    assert inspect_text(text, "p.nc").dialect_marks == ("G64 P path tolerance",)
