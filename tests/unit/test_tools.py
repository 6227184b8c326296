"""Closed-form checks of the cutter shapes (ncopt.contacts.cutters)."""

from __future__ import annotations

import numpy as np
import pytest

from ncopt.model import Cutter
from ncopt.contacts.cutters import center_offset_mm, r_eff_mm, required_rpm

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
    # D16 ball at full radius, vc 70 m/min -> S 1392.6 (docs/method.md)
    assert required_rpm(np.array([8.0]), 70.0)[0] == pytest.approx(1392.6, abs=0.05)


def test_required_rpm_is_inverse_in_radius_and_infinite_at_the_tip():
    s = required_rpm(np.array([0.0, 1.0, 2.0]), 100.0)
    assert s[0] == np.inf
    assert s[1] == pytest.approx(2.0 * s[2])


# ------------------------------------------------------------- tool comments ----
# One real-looking comment per CAM system (from its post-processor or real output), and
# what it says: (T number or UNNUMBERED, kind, diameter, corner radius or None, teeth,
# unit or None for the program's, source).
from ncopt.reading.parse import parse_text  # noqa: E402
from ncopt.planning.tooltable import (BULL_NO_RADIUS, FLAT, OTHER, UNKNOWN, UNNUMBERED,  # noqa: E402
                             ToolInfo, cutter_for, parse_tool_comment, tool_comments, tool_table)
from ncopt.planning.tooltable import BALL as BALL_NOSE, BULL as BULL_NOSE  # noqa: E402  (shapes)

CAM_COMMENTS = [
    ("T1 D=8 CR=4 - ZMIN=-19.999 - ball end mill",
     (1, BALL_NOSE, 8.0, 4.0, None, None, "Fusion 360")),
    ("T2 D=9.525 CR=0. - ZMIN=-10. - FLAT END MILL",
     (2, FLAT, 9.525, 0.0, None, None, "Fusion 360")),
    ("T5 D=6 CR=0.5 - ZMIN=-3 - bull nose end mill",
     (5, BULL_NOSE, 6.0, 0.5, None, None, "Fusion 360")),
    ("T11 D=8. CR=0. TAPER=118DEG - ZMIN=-21. - DRILL",
     (11, OTHER, 8.0, 0.0, None, None, "Fusion 360")),
    ("T6 D=6 CR=1 - ZMIN=-3 - radius mill",  # Fusion's corner-rounding cutter
     (6, OTHER, 6.0, 1.0, None, None, "Fusion 360")),
    ("  Tool #4: Flat End Mill 3 Flutes, Diam = 3mm, Len = 15.00mm",
     (4, FLAT, 3.0, 0.0, 3, "mm", "OpenBuilds (Fusion 360)")),
    ("  Tool #2: Ball End Mill 2 Flutes, Diam = 0.25in, Len = 1.00in",
     (2, BALL_NOSE, 0.25, 0.125, 2, "inch", "OpenBuilds (Fusion 360)")),
    ("Tool: D = 3.0 mm type END flutes 2", (UNNUMBERED, FLAT, 3.0, 0.0, 2, "mm", "BlenderCAM")),
    ("Tool: D = 0.125'' type BALLNOSE flutes 2",
     (UNNUMBERED, BALL_NOSE, 0.125, 0.0625, 2, "inch", "BlenderCAM")),
    ("Tool: D = 6.0 mm type BULLNOSE flutes 4",  # BlenderCAM writes no corner radius
     (UNNUMBERED, BULL_NO_RADIUS, 6.0, None, 4, "mm", "BlenderCAM")),
    ("Tool change - D = 3.0 mm type VCARVE flutes 1",
     (UNNUMBERED, OTHER, 3.0, None, 1, "mm", "BlenderCAM")),
    ("TOOL/MILL,0.7937,0.39687,1.000,0.0",  # Carbide Create: D, r, height, taper angle
     (UNNUMBERED, BALL_NOSE, 0.7937, 0.39685, None, None, "Carbide Create")),
    ("TOOL/MILL,3.17, 0.00, 12.70, 0.00",
     (UNNUMBERED, FLAT, 3.17, 0.0, None, None, "Carbide Create")),
    ("TOOL/MILL,6.35, 1.00, 19.05, 0.00",
     (UNNUMBERED, BULL_NOSE, 6.35, 1.0, None, None, "Carbide Create")),
    ("TOOL/MILL,0.03, 0.00, 6.35, 45.00",  # a V-bit: a taper angle
     (UNNUMBERED, OTHER, 0.03, 0.0, None, None, "Carbide Create")),
    ("HSS, 2-Flute Endmill, 2mm", (UNNUMBERED, FLAT, 2.0, 0.0, 2, "mm", "free text")),  # Estlcam
    ("HSS, 2-Flute Ballnose, 3mm", (UNNUMBERED, BALL_NOSE, 3.0, 1.5, 2, "mm", "free text")),
    (" 1/16 FLAT ENDMILL TOOL - 1 DIA. OFF. - 1 LEN. - 1 DIA. - .0625",
     (1, FLAT, 0.0625, 0.0, None, None, "Mastercam")),
    (" T1 | 1/4 FLAT ENDMILL | H1 | D1 | TOOL DIA. - .25 ",  # D1: an offset, no size
     (1, FLAT, 0.25, 0.0, None, None, "Mastercam")),
    ("T9|5/8 BALL ENDMILL|H18", (9, BALL_NOSE, 0.625, 0.3125, None, "inch", "Mastercam")),
    ("T3|1/2 BULL ENDMILL .03 RAD|H3|D3|TOOL DIA. - .5",
     (3, BULL_NOSE, 0.5, 0.03, None, None, "Mastercam")),
    ("T15|3'' FACE MILL / SHELL MILL|H15|D15|TOOL DIA. - 3.25",
     (15, OTHER, 3.25, None, None, None, "Mastercam")),
    ("T1579871377 | FRA-SP0140-G2R1-N-ES-L25_H63K6L120X / DM=2 CR=1 TL=145",
     (1579871377, BALL_NOSE, 2.0, 1.0, None, None, "hyperMILL")),
    ("TOOL 1   DIA 10.0000", (1, UNKNOWN, 10.0, None, None, None, "free text")),  # SolidCAM
    (" T1 = Ball Nose 3 mm ", (1, BALL_NOSE, 3.0, 1.5, None, "mm", "free text")),  # Vectric
    (' T2 = End Mill 1/4" ', (2, FLAT, 0.25, 0.0, None, "inch", "free text")),
    (" T3 = Radiused End Mill 6 mm ", (3, BULL_NO_RADIUS, 6.0, None, None, "mm", "free text")),
    ("T4 BALL D16 R8 z2", (4, BALL_NOSE, 16.0, 8.0, 2, None, "free text")),
    (" T1 = Ball Mill 4 mm ", (1, BALL_NOSE, 4.0, 2.0, None, "mm", "free text")),
    ("T02 ID=002  DIA-0.5000  TOOL END MILL", (2, FLAT, 0.5, 0.0, None, None, "free text")),
    (" Cutter is assumed to be a 10mm ball nose ",
     (UNNUMBERED, BALL_NOSE, 10.0, 5.0, None, "mm", "free text")),
    ("for 1/8\"dia cutter or 'V' cutter", (UNNUMBERED, UNKNOWN, 0.125, None, None, "inch",
                                            "free text")),
]


def summary(info: ToolInfo) -> tuple:
    corner = None if np.isnan(info.corner_radius) else round(info.corner_radius, 6)
    return (info.number, info.kind, info.diameter, corner, info.teeth, info.unit, info.source)


@pytest.mark.parametrize("text, expected", CAM_COMMENTS, ids=[c[1][-1] + ":" + c[0][:24]
                                                             for c in CAM_COMMENTS])
def test_a_cam_systems_tool_comment(text, expected):
    info = parse_tool_comment(text, 7)
    assert info is not None and summary(info) == expected
    assert info.line == 7 and info.text == text
    assert info.teeth_line == (7 if expected[4] is not None else None)


@pytest.mark.parametrize("text", [
    "Xcen=0 Ycen=0 Dia=10",  # a pocket's diameter
    " X=96 mm, Y=120 mm, Z=6 mm ",  # the stock
    "Sample interval: 1.0", "Step over %: 20.0",  # FreeCAD operation data
    "PROGRAM NAME - HELLOWORLD", "",
])
def test_comments_that_are_no_tool(text):
    assert parse_tool_comment(text, 1) is None


def test_a_bare_r_never_makes_an_end_mill_a_ball():
    # "R5" may be the radius of a D10 end mill: the shape stays flat, nothing is guessed
    assert parse_tool_comment("T2 END MILL D10 R5", 1).kind == FLAT
    assert parse_tool_comment("T2 D10 R5", 1).kind == UNKNOWN
    assert parse_tool_comment("T2 D10 CR=5", 1).kind == BALL_NOSE  # an explicit corner radius


def test_contradictions_give_no_shape():
    assert parse_tool_comment("T1 D=8 CR=1 - ZMIN=0 - ball end mill", 1).kind == UNKNOWN
    assert parse_tool_comment("T1 D=8 CR=5 - ZMIN=0 - bull nose end mill", 1).kind == UNKNOWN
    assert parse_tool_comment("T1 D=8 CR=0.5 TAPER=3DEG - ZMIN=0 - ball end mill",
                              1).kind == OTHER  # a tapered ball


def test_the_cutter_is_in_mm_whatever_the_comment_says():
    inch = parse_tool_comment("T9|5/8 BALL ENDMILL|H18", 1)
    assert inch.cutter(2, scale_to_mm=1.0).diameter_mm == pytest.approx(15.875)
    mm = parse_tool_comment(" T1 = Ball Nose 3 mm ", 1)
    assert mm.cutter(2, scale_to_mm=25.4).diameter_mm == pytest.approx(3.0)
    program_units = parse_tool_comment("T1 D=0.75 CR=0.375 - ZMIN=0 - BALL END MILL", 1)
    c = program_units.cutter(3, scale_to_mm=25.4)
    assert (c.diameter_mm, c.corner_radius_mm, c.teeth) == pytest.approx((19.05, 9.525, 3))


def test_the_tooth_count_says_where_it_comes_from():
    given = parse_tool_comment("  Tool #4: Flat End Mill 3 Flutes, Diam = 3mm, Len = 15mm", 12)
    assert (given.teeth, given.teeth_source()) == (3, "line 12")
    fusion = parse_tool_comment("T1 D=8 CR=4 - ZMIN=-19.999 - ball end mill", 3)
    assert (fusion.teeth, fusion.teeth_source()) == (None, "assumed")


def test_why_a_tool_is_not_planned():
    def why(text):
        return parse_tool_comment(text, 1).refusal()
    assert why("T2 D=5 CR=0 - ZMIN=0 - flat end mill") == "a flat end mill"
    assert why("TOOL 1 DIA 10.") == "a tool whose shape the comment does not give"
    assert why("Tool: D = 6.0 mm type BULLNOSE flutes 4") == \
        "a bull-nose whose corner radius the comment does not give"
    assert why("T11 D=8. CR=0. TAPER=118DEG - ZMIN=-21. - DRILL") == "not a ball or bull-nose"


# ---------------------------------------------------- comments -> tools of a program ----
def table_of(text: str) -> dict:
    return {t: summary(i)[1:4] for t, i in tool_table(parse_text(text, "p.nc")).items()}


def test_carbide_create_describes_the_tool_change_that_follows():
    text = ("%\n(TOOL/MILL,0.1,0.05,0.000,0)\nG21\nG0X0Y0Z10\n(TOOL/MILL,0.7937,0.39687,1.000,"
            "0.0)\nM6 T121\nM3 S2344\nG1Z-0.095F125.7\n")
    assert table_of(text) == {121: (BALL_NOSE, 0.7937, 0.39685),
                              UNNUMBERED: (BALL_NOSE, 0.1, 0.05)}


def test_blendercam_describes_the_tool_change_before_it():
    text = ("G21\nT1 M06\n(Tool: D = 3.0 mm type BALLNOSE flutes 2)\nS12000 M03\nG0 X0 Y0\n"
            "G1 Z-1 F100\nT2 M06\n(Tool: D = 6.0 mm type END flutes 2)\nG1 X5\n")
    assert table_of(text) == {1: (BALL_NOSE, 3.0, 1.5), 2: (FLAT, 6.0, 0.0)}


def test_a_comment_on_the_tool_change_line_wins_over_one_beside_it():
    text = "(Xcen=0 Ycen=0 Dia=10)\n(BALL 6 MM)\nM6 T7(TOOL DIA. 4 BALL)\nG1 X1 F10\n"
    assert table_of(text) == {7: (BALL_NOSE, 4.0, 2.0)}


def test_a_numbered_description_wins_over_a_bound_one():
    text = "(BALL 6 MM)\n(T7 BALL D8)\nM6 T7\nG1 X1 F10\n"
    assert table_of(text) == {7: (BALL_NOSE, 8.0, 4.0)}


def test_with_m6_a_t_word_alone_only_preselects():
    text = "T1 M6\nT2\n(BALL 6 MM)\nG0 X0 Y0\nG1 Z-1 F100\nM6\n"
    assert table_of(text) == {1: (BALL_NOSE, 6.0, 3.0)}


def test_freecad_describes_one_tool_over_several_lines():
    text = ("(TC: 3mm Endmill)\n( M6 T2 )\nM3 S10000\n(Surface)\n(Tool type: ballend)\n"
            "(Compensated Tool Path. Diameter: 3.0)\n(Sample interval: 1.0)\nG0 Z5\n")
    infos = tool_comments(parse_text(text, "f.nc"))
    assert [summary(i)[1:4] for i in infos] == [(FLAT, 3.0, 0.0), (BALL_NOSE, 3.0, 1.5)]
    assert (infos[1].line, infos[1].source) == (6, "FreeCAD")
    assert UNNUMBERED not in tool_table(parse_text(text, "f.nc"))  # flat or ball: unknown


def test_unnumbered_descriptions_that_agree_serve_the_program():
    text = "(3mm Endmill)\n(Tool type: endmill)\n(Compensated Tool Path. Diameter: 3.0)\nG1 X1\n"
    assert table_of(text) == {UNNUMBERED: (FLAT, 3.0, 0.0)}


def test_free_text_on_neighbouring_lines_is_not_merged():
    text = ("; tool: T04 ball end mill D16 (R 8 mm), z 2\n; stepover 1.6 mm along Y\n"
            "; coordinates: tool tip (ball centre - R)\nT4 M6\n")
    assert table_of(text) == {4: (BALL_NOSE, 16.0, 8.0)}


def test_ncopts_own_stamp_is_no_tool_comment():
    text = "(ncopt 0.1.0 T1 vc=70.0 fz=0.1 D=19.05 r=9.525 z=2 - S and F rewritten)\n" \
           "(T1 D=0.75 CR=0.375 - ZMIN=0 - BALL END MILL)\nG20\nT1 M6\n"
    assert table_of(text) == {1: (BALL_NOSE, 0.75, 0.375)}


def test_an_unnumbered_tool_serves_a_single_tool_program_only():
    table = tool_table(parse_text("(BALL 6 MM)\nG1 X1\n", "p.nc"))
    assert cutter_for(table, UNNUMBERED, 1).diameter == 6.0
    assert cutter_for(table, 3, 2) is None


# what the program's owner reads: the right shape and size for every program of more/ and
# fusion/ (Klartext is refused before its comments are read)
CORPUS_TOOLS = {
    "more/carbidecreate_shapeoko_tag.nc": {121: (BALL_NOSE, 0.7937, 0.39685),
                                           UNNUMBERED: (BALL_NOSE, 0.1, 0.05)},
    "more/estlcam_Enclosure.nc": {UNNUMBERED: (FLAT, 2.0, 0.0)},
    "more/freecad_Starlink_suport.nc": {UNNUMBERED: (FLAT, 3.0, 0.0)},
    "more/fusion-generic_Nozzle_OP_A.nc": {1: (FLAT, 3.175, 0.0), 3: (BALL_NOSE, 2.0, 1.0)},
    "more/fusion-linuxcnc-inch_r8s.ngc": {1: (BALL_NOSE, 0.75, 0.375)},
    "more/solidworks-fanuc_CGIP11719.nc": {2: (FLAT, 0.5, 0.0), 5: (OTHER, 0.25, None),
                                           23: (OTHER, 0.3937, None), 4: (OTHER, 0.5, None)},
    "fusion/BowlTest.nc": {1: (BALL_NOSE, 8.0, 4.0)},
    "fusion/chess_engraved_box.nc": {1: (OTHER, 100.0, 0.0), 2: (FLAT, 5.0, 0.0),
                                     3: (BALL_NOSE, 1.5, 0.75), 4: (FLAT, 10.0, 0.0),
                                     9: (FLAT, 3.0, 0.0), 11: (OTHER, 8.0, 0.0)},
}


@pytest.mark.parametrize("name", sorted(CORPUS_TOOLS))
def test_the_corpus_programs_give_their_tools(corpus_dir, name):
    text = (corpus_dir / name).read_bytes().decode("latin-1")
    got = table_of(text)
    expected = CORPUS_TOOLS[name]
    assert {t: got.get(t) for t in expected} == expected
    if name.startswith("more/solidworks"):
        assert len(got) == 19 and all(k[0] == OTHER for t, k in got.items() if t != 2)
    else:
        assert got == expected


def test_the_estlcam_tool_list_gives_its_teeth(corpus_dir):
    text = (corpus_dir / "more" / "estlcam_Enclosure.nc").read_bytes().decode("latin-1")
    info = tool_table(parse_text(text))[UNNUMBERED]
    assert (info.teeth, info.teeth_source()) == (2, "line 14")
