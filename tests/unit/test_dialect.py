"""ncopt.reading.dialect: the Fanuc decimal point convention, found and applied."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ncopt.reading.dialect import (CALCULATOR, DECIMAL_POINT_CONVENTIONS, DIALECTS, FANUC, IS_B, IS_C,
                           LINUXCNC, apply_decimal_point, decimal_point_issue, detect,
                           resolve_decimal_point)
from ncopt.runtime.errors import NcParseError, UsageError
from ncopt.planning.inspection import inspect_text
from ncopt.motion.interp import interpret
from ncopt.reading.parse import parse_text

ROOT = Path(__file__).resolve().parents[2]
CORPUS = (ROOT / "../shared/corpus").resolve()

PROGRAM = ("%\nO1000\nG21 G94\nG0 X0 Y0.\nG1 X1000 Y-2500 F300\nG4 X1500\nG20\n"
           "G1 X100 F100\nG95 F20 A90\nG93 G1 X1. F5\n%\n")


def values(prog) -> list[tuple[str, float]]:
    return [(chr(c), float(v)) for c, v in zip(prog.word_letter, prog.word_value)]


def issue_of(text: str, dialect: str = FANUC, convention: str | None = None):
    return decimal_point_issue(parse_text(text, "f.nc"), dialect, convention)


# ------------------------------------------------------------------------ the issue ----
def test_an_axis_word_without_a_point_is_located_and_explained():
    issue = issue_of(PROGRAM)
    assert (issue.line, issue.column) == (5, 4)
    assert issue.message == (
        "`X1000` has no decimal point: a Fanuc control reads it as 1000 mm with "
        "calculator-type input (DPI=1) but 1 mm in least input increments (DPI=0, IS-B); "
        "pass --decimal-point calculator, is-b or is-c as the machine is set up, or write "
        "the values with a decimal point")
    line, column, message = issue  # unpacks as (line, column, message)
    assert message.startswith("`X1000`")


@pytest.mark.parametrize("dialect", [d for d in DIALECTS if d != FANUC])
def test_other_dialects_read_values_as_written(dialect):
    assert issue_of(PROGRAM, dialect) is None


@pytest.mark.parametrize("convention", DECIMAL_POINT_CONVENTIONS)
def test_a_known_convention_leaves_no_issue(convention):
    assert issue_of(PROGRAM, FANUC, convention) is None


@pytest.mark.parametrize("text", [
    "G90 G0 X10. Y-2.5 Z.5\nG1 X10.25 F279\nG1 X0 Y0 Z0 F300\n",  # points, zeros, F in G94 mm
    "G1 X#1 Y[#2*2] F[#3]\n",  # computed values: a variable holds its decimal point
    "M3 S12000\nT4 M6\nG43 H4 Z50.\nN100 G54 P1\n",  # integer addresses
    "G1 X1.5 (X1000 in a comment)\n",
])
def test_programs_that_mean_the_same_in_every_convention(text):
    assert issue_of(text) is None


@pytest.mark.parametrize("text, word, unit, calc, inc", [
    ("G20\nG1 X1. F100\n", "F100", "inch/min", "100", "1"),
    ("G95\nG1 X1. F20\n", "F20", "mm/rev (G95)", "20", "0.02"),
    ("G93 G1 X1. F5\n", "F5", "1/min (G93)", "5", "0.005"),
    ("G0 A90\n", "A90", "deg", "90", "0.09"),
    ("G4 X1500\n", "X1500", "s", "1500", "1.5"),
    ("G20\nG0 Z2\n", "Z2", "inch", "2", "0.0002"),
    ("G2 X1. Y1. R5\n", "R5", "mm", "5", "0.005"),
])
def test_words_whose_unit_depends_on_the_convention(text, word, unit, calc, inc):
    issue = issue_of(text)
    assert issue is not None
    assert issue.message.startswith(
        f"`{word}` has no decimal point: a Fanuc control reads it as {calc} {unit} with "
        f"calculator-type input (DPI=1) but {inc} {unit} in least input increments")


def test_the_column_counts_a_tab_as_one():
    issue = issue_of("G1 X1.\n\tG1\tY20\n")
    assert (issue.line, issue.column) == (2, 5)


def test_an_unknown_convention_is_a_usage_error():
    with pytest.raises(UsageError, match="--decimal-point must be one of calculator, is-b, is-c"):
        issue_of(PROGRAM, FANUC, "dpi")
    with pytest.raises(UsageError):
        apply_decimal_point(parse_text(PROGRAM), "increment")


# -------------------------------------------------------------------- the convention ----
def test_calculator_reads_values_as_written():
    prog = parse_text(PROGRAM)
    assert apply_decimal_point(prog, CALCULATOR) is prog


@pytest.mark.parametrize("convention, expected", [
    (IS_B, {"X1000": 1.0, "Y-2500": -2.5, "F300": 300.0, "X1500": 1.5, "X100": 0.01,
            "F100": 1.0, "F20": 0.002, "A90": 0.09, "X1.": 1.0, "F5": 0.005}),
    (IS_C, {"X1000": 0.1, "Y-2500": -0.25, "F300": 300.0, "X1500": 0.15, "X100": 0.001,
            "F100": 1.0, "F20": 0.0002, "A90": 0.009, "X1.": 1.0, "F5": 0.005}),
])
def test_least_input_increments(convention, expected):
    prog = parse_text(PROGRAM)
    out = apply_decimal_point(prog, convention)
    got = {prog.text[s:e]: float(v) for s, e, v in zip(out.word_start, out.word_end,
                                                        out.word_value)}
    assert {k: got[k] for k in expected} == expected  # exact: 90/10000, not 90*0.0001
    # integer addresses and zeros keep their values, spans and text are untouched
    assert got["O1000"] == 1000.0 and got["G21"] == 21.0 and got["X0"] == 0.0
    for name in ("word_start", "word_end", "word_line", "word_letter", "line_kind"):
        assert np.array_equal(getattr(out, name), getattr(prog, name))
    assert out.text == prog.text


def test_a_g_code_acts_on_its_whole_line():
    out = apply_decimal_point(parse_text("X1000 G20\nX1000\nG21\nX1000\n"), IS_B)
    assert [v for c, v in values(out) if c == "X"] == [0.1, 0.1, 1.0]


def test_the_interpreter_sees_the_increments():
    text = "G21 G90 G17\nG0 X0 Y0 Z5000\nG1 Z-1500 F300\nG1 X25000 Y12500\n"
    tp = interpret(apply_decimal_point(parse_text(text), IS_B))
    assert tp.xyz_mm[-1].tolist() == [25.0, 12.5, -1.5]
    assert np.nanmax(tp.feed_mm_min) == 300.0


# ------------------------------------------------------------- resolve: one call ----
def test_resolve_refuses_an_unknown_convention_with_a_located_error():
    prog = parse_text("G21\nG0 X0 Y0\n\tG1 X25000 F300\n", "part.nc", dialect=FANUC)
    with pytest.raises(NcParseError) as info:
        resolve_decimal_point(prog, FANUC)
    err = info.value
    assert (err.path, err.line, err.column) == ("part.nc", 3, 5)
    assert err.context == "    " + " G1 X25000 F300" + "\n    " + " " * 4 + "^"
    assert str(err).startswith("part.nc:3:5: `X25000` has no decimal point")


@pytest.mark.parametrize("dialect, convention, x", [
    (FANUC, IS_B, 25.0), (FANUC, IS_C, 2.5), (FANUC, CALCULATOR, 25000.0),
    (LINUXCNC, None, 25000.0), (None, None, 25000.0), (LINUXCNC, CALCULATOR, 25000.0),
])
def test_resolve_reads_the_values_in_the_convention(dialect, convention, x):
    prog = parse_text("G1 X25000 F300\n", "part.nc")
    out = resolve_decimal_point(prog, dialect, convention)
    assert values(out)[1] == ("X", x)
    if convention in (None, CALCULATOR):
        assert out is prog


# ---------------------------------------------------------------- real programs ----
@pytest.mark.skipif(not CORPUS.is_dir(), reason="no corpus")
def test_a_real_fanuc_post_writes_every_value_with_a_point():
    text = (CORPUS / "fusion" / "chess_engraved_box.nc").read_bytes().decode("latin-1")
    assert detect(text).name == FANUC
    assert decimal_point_issue(parse_text(text, dialect=FANUC), FANUC) is None


@pytest.mark.skipif(not CORPUS.is_dir(), reason="no corpus")
def test_a_program_with_integer_axes_is_flagged_when_it_is_fanuc():
    """Newfangled Wizard's Mach3 program (``G00 G43 H7 Z2``, ``X0 Y0``): a lone G43 H, which
    LinuxCNC and Mach3 programs have too, no longer makes it Fanuc; named Fanuc, its
    values without a decimal point are flagged."""
    path = CORPUS / "pygcode" / "Circular Pocket.tap"
    text = path.read_bytes().decode("latin-1")
    assert detect(text).name == "generic"
    issue = decimal_point_issue(parse_text(text, str(path)), FANUC)
    assert issue is not None and issue.message.endswith("with a decimal point")


def test_inspect_reports_the_issue_and_reads_a_given_convention():
    text = "G21 G90\nG0 X0 Y0 Z5.\nG1 Z-1. F300\nG1 X25000 Y12500\n"
    info = inspect_text(text, "f.nc", dialect=FANUC)
    assert info.warnings[0].startswith("f.nc:4:4: `X25000` has no decimal point")
    assert info.cut_length_mm > 27000  # read as written: 25 m
    known = inspect_text(text, "f.nc", dialect=FANUC, decimal_point=IS_B)
    assert not any("decimal point" in w for w in known.warnings)
    assert known.cut_length_mm == pytest.approx(6.0 + np.hypot(25.0, 12.5))


@pytest.mark.parametrize("dialect", [LINUXCNC, None, "sinumerik"])
def test_increments_are_refused_for_a_program_of_another_control(dialect):
    """A machine profile's is-b must not shrink a non-Fanuc program's geometry 1000 times."""
    prog = parse_text("G1 X1000 F300\n", "part.mpf")
    with pytest.raises(UsageError, match="--decimal-point is-b is how a Fanuc control"):
        resolve_decimal_point(prog, dialect, IS_B)
    with pytest.raises(UsageError, match="give --dialect fanuc"):
        inspect_text("G1 X1000 F300\n", "part.mpf", dialect=dialect, decimal_point=IS_C)


def test_k_counts_repeats_in_a_drilling_cycle():
    """Fanuc G81..G89 K3: three holes, in every convention; K of an arc is a length."""
    text = "%\nO1\nG21 G90\nG81 X1. Y1. Z-2. R1. K3 F100\nX5.\nG80\nG3 X2. Y0. I1. K2\n%\n"
    issue = issue_of(text)
    assert issue is not None and (issue.line, issue.column) == (7, 16)  # the arc's K2, not K3
    prog = apply_decimal_point(parse_text(text), IS_B)
    assert ("K", 3.0) in values(prog) and ("K", 0.002) in values(prog)


# ------------------------------------------------------------------ detection ----
@pytest.mark.parametrize("text, name", [
    # a construct only LinuxCNC has beats one Fanuc shares with LinuxCNC (the Fusion
    # LinuxCNC post: G43 Z.. H1 and G64 P.. Q..)
    ("%\n(R8S)\nN10 G90 G94 G17 G91.1\nN15 G20\nN45 G64 P0.0004 Q0.0004\nN60 G43 Z0.64 H1\n",
     LINUXCNC),
    ("O1000\nG43 H1 Z50.\nG28 G91 Z0.\n", FANUC),  # shared marks alone still tell Fanuc
    # one mark of its own each: then the most marks (O, G43 H, IF GOTO against #<...>)
    ("O1000\nG43 H1 Z50.\nIF [#1 GT 5] GOTO 10\n#<depth> = 2\n", FANUC),
    ("G43 H1 Z5.0 M08 ; TCP on\nM30\n", "generic"),  # a ';' comment: Fanuc cannot read it
    ("O1000 (MACHINE; TOYODA FH1250)\nG43 H1 Z5.\n", FANUC),  # ';' inside ( ) is text
    ("\ufeffO1000\nG43 H1 Z5.\n".encode("utf-8").decode("latin-1"), FANUC),  # after a BOM
    ("G1 X1 Y2\n", "generic"),
])
def test_the_dialect_is_told_by_the_constructs_only_it_has(text, name):
    assert detect(text).name == name


def test_the_marks_are_named_for_the_user():
    found = detect("N45 G64 P0.0004 Q0.0004\nN60 G43 Z0.64 H1\nM2\n")
    assert (found.name, found.marks) == ("linuxcnc", ("G64 P path tolerance", "M2 end"))


@pytest.mark.skipif(not CORPUS.is_dir(), reason="no corpus")
@pytest.mark.parametrize("name, dialect", [
    ("more/fusion-linuxcnc-inch_r8s.ngc", LINUXCNC),
    ("more/solidworks-fanuc_CGIP11719.nc", FANUC),
    ("fusion/chess_engraved_box.nc", FANUC),
    ("linuxcnc/3D_Chips.ngc", LINUXCNC),
    ("linuxcnc/5axis/boat-xyzbc.ngc", "generic"),  # G43 H, and ';' comments Fanuc has not
])
def test_corpus_programs_are_told_right(name, dialect):
    assert detect((CORPUS / name).read_bytes().decode("latin-1")).name == dialect


def test_ai_contour_control_mode_and_level_need_no_decimal_point():
    """``G05.1 Q1 R5`` (Fanuc AI contour control on, precision level 5) and ``G05.1 Q0``:
    Q and R are a mode and a level, the same in every convention; they were refused as
    lengths ("`Q1` has no decimal point"). A Q of a drilling cycle still is a length."""
    aicc = "%\nO1\nG21 G90 G17\nG05.1 Q1 R5\nG0 X1. Y2.\nG05.1 Q0\nM30\n%\n"
    assert decimal_point_issue(parse_text(aicc, "f.nc"), FANUC) is None
    peck = "%\nO1\nG21 G90 G17\nG83 X1. Y2. Z-3. R1. Q1 F100.\nG80\nM30\n%\n"
    issue = decimal_point_issue(parse_text(peck, "f.nc"), FANUC)
    assert issue is not None and issue.message.startswith("`Q1` has no decimal point")


def test_scaling_factors_need_no_decimal_point():
    """``G51 X0. Y0. Z0. I500 J500 K500``: I J K are the axes' scale factors, not lengths."""
    text = "%\nO1\nG21 G90 G17\nG51 X0. Y0. Z0. I500 J500 K500\nG0 X1. Y2.\nG50\nM30\n%\n"
    assert decimal_point_issue(parse_text(text, "f.nc"), FANUC) is None
