"""ncopt.reading.refuse: input a control would refuse, refused at its line and column with the reason.

Each refusal is checked against LinuxCNC's rs274 where it is installed (tests/judge.py):
what ncopt refuses, rs274 refuses too; what ncopt accepts as legitimate (several M or G
words of different groups), rs274 accepts.
"""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from ncopt.runtime.errors import NcoptError, NcParseError
from ncopt.motion.interp import interpret
from ncopt.reading.parse import parse_text
from ncopt.reading.refuse import CONTEXT_CHARS, caret_context

from judge import RS274, canon


def read(text: str, dialect: str | None = None):
    return interpret(parse_text(text, "p.nc", dialect=dialect))


def refusal(text: str, dialect: str | None = None) -> NcoptError:
    with pytest.raises(NcoptError) as info:
        read(text, dialect)
    return info.value


def rs274_refuses(text: str) -> str:
    """rs274's error message for a program, or '' when it reads it."""
    try:
        canon(text)
    except RuntimeError as exc:
        return str(exc)
    return ""


needs_rs274 = pytest.mark.skipif(RS274 is None, reason="rs274 not installed")

# (program, line, column, start of ncopt's message, rs274's message)
REFUSED = [
    ("G1 X1 X2 F100\nM2\n", 1, 7, "`X1` and `X2` on one line: a block takes one X word",
     "Multiple x words on one line"),
    ("G0 X0\nG1 X1 F100 F200\nM2\n", 2, 12, "`F100` and `F200` on one line",
     "Multiple f words on one line"),
    ("S1000 S2000 M3\nM2\n", 1, 7, "`S1000` and `S2000` on one line",
     "Multiple s words on one line"),
    ("T1 T2 M6\nM2\n", 1, 4, "`T1` and `T2` on one line", "Multiple t words on one line"),
    ("G1 x1 Y2 X3 F100\nM2\n", 1, 10, "`x1` and `X3` on one line", "Multiple x words"),
    ("S1e3 M3\nM2\n", 1, 1, "`S1e3` is a number with an exponent, which NC words do not "
     "have: it reads as `S1` followed by an E word; write the value out (`S1000`)",
     "E word with no G70, G76, M66, M67 or M68 to use it"),
    ("G1 X1.5E-3 F100\nM2\n", 1, 4, "`X1.5E-3` is a number with an exponent", "E word"),
    ("G1 X1 F-279\nM2\n", 1, 7, "`F-279` is a negative feed rate (-279); a feed rate is "
     "positive: fix the F word", "Negative f word used"),
    ("S-1000 M3\nM2\n", 1, 1, "`S-1000` is a negative spindle speed", "Negative spindle speed"),
    ("#1=-5\nG1 X1 F#1\nM2\n", 2, 7, "`F#1` is a negative feed rate (-5)", "Negative f word"),
    ("F100\nG2 X0 Y0 R0\nM2\n", 2, 1, "zero-radius arc: the centre is on the start point",
     "Current point same as end point of arc"),
    ("F100\nG2 X1 Y1 I0 J0\nM2\n", 2, 1, "zero-radius arc", "Zero-radius arc"),
    ("G21 F100\nG2 X0.0022 Y0 I0.0011 J0\nM2\n", 2, 1, "zero-radius arc", "Zero-radius arc"),
    ("G20 F100\nG2 X0.00008 Y0 I0.00004 J0\nM2\n", 2, 1, "zero-radius arc", "Zero-radius arc"),
    ("G0 X0 Y0 Z0\nF100\nG2 X2 Y0 I0.001 J0\nM2\n", 3, 1, "zero-radius arc", "Zero-radius arc"),
    ("F100\nG18 G2 X1 Z1 I0.5 J0.5\nM2\n", 2, 1, "J word on an arc in the G18 (XZ) plane, "
     "whose centre is given by K and I", "J word given for arc in xz plane"),
]

# what a control reads: several M or G words of different groups, arcs at LinuxCNC's
# smallest radius
ACCEPTED = [
    "G1 X1 Y1 F100 M3 M8\nM2\n",
    "G0 G90 G21 G17 X1\nM2\n",
    "F100\nG2 X1 Y1 I0.5 J0.5\nM2\n",
    "G21 F100\nG2 X0.004 Y0 I0.002 J0\nM2\n",
    "G20 F100\nG2 X0.0001 Y0 I0.00005 J0\nM2\n",
]


@pytest.mark.parametrize("text, line, column, message, _", REFUSED)
def test_refused_at_its_line_and_column_with_the_reason(text, line, column, message, _):
    err = refusal(text)
    assert (err.path, err.line, err.column) == ("p.nc", line, column)
    assert str(err).startswith(f"p.nc:{line}:{column}: {message}")
    assert "; " in str(err).splitlines()[0]  # what is wrong; what to do
    src = text.splitlines()[line - 1]
    if isinstance(err, NcParseError):
        assert err.context == caret_context(src, column)


@needs_rs274
@pytest.mark.parametrize("text, line, column, _, rs274_says", REFUSED)
def test_linuxcnc_refuses_them_too(text, line, column, _, rs274_says):
    said = rs274_refuses(text)
    assert rs274_says in said and text.splitlines()[line - 1] in said


@pytest.mark.parametrize("text", ACCEPTED)
def test_what_a_control_reads_is_read(text):
    read(text)


@needs_rs274
@pytest.mark.parametrize("text", ACCEPTED)
def test_linuxcnc_reads_them_too(text):
    assert rs274_refuses(text) == ""


@pytest.mark.parametrize("text", [
    "F100\nG2 X1 Y1 I0.5 J0.5 K0\n",  # FreeCAD writes K0.000 on every G17 arc
    "G1 X10 E0.5 F100\n",  # an E word with its own value: no exponent
    "G65 P9010 I1 J1 K1 I2 J2 K2\n",  # Fanuc macro argument specification II
    "N10 G43 H1 H2 Z5\n",  # several H functions on Sinumerik; ncopt reads no H
    "G1 X1 Y2 F100 (X3 X4)\n",  # a comment holds no words
])
def test_what_ncopt_leaves_to_the_control(text):
    read(text)


def test_a_value_ncopt_cannot_know_is_not_refused():
    # #1300 is set by a subroutine ncopt does not follow: J is unknown, not zero
    read("O100 sub\n#1300=2\nO100 endsub\nF100\nG2 Y[0 - 2 * #1300] J[0-#1300]\n")


def test_the_first_refusal_in_the_file_is_reported():
    err = refusal("G1 X1 F100\nG1 Y1 Y2\nS1e3\nG1 Z1 Z2\n")
    assert (err.line, err.column) == (2, 7)


@given(st.lists(st.sampled_from("XYZIJKFSTPQRDEABC"), min_size=2, max_size=8))
def test_a_block_with_a_repeated_letter_is_refused_at_the_second(letters):
    block = " ".join(f"{c}{i + 1}" for i, c in enumerate(letters))
    repeats = [i for i, c in enumerate(letters) if c in letters[:i]]
    text = f"G0 X0 Y0 Z0\n{block}\n"
    if not repeats:
        return
    with pytest.raises(NcParseError) as info:
        read(text)
    second = repeats[0]
    assert info.value.line == 2
    assert info.value.column == len(" ".join(f"{c}{i + 1}" for i, c in
                                             enumerate(letters[:second]))) + 2


def test_a_long_block_with_a_repeated_letter_is_refused():
    err = refusal(f"G0 {'M8 ' * 40}X1 Y2 X3\n")
    assert "`X1` and `X3`" in str(err)


# ------------------------------------------------------------------ encodings ----
@pytest.mark.parametrize("data, name", [
    ("G1 X1\n".encode("utf-16"), "UTF-16"),
    ("G1 X1\n".encode("utf-16-be"), "UTF-16"),
    ("G1 X1 F100\nM2\n".encode("utf-16-le"), "UTF-16"),
    ("G1 X1\n".encode("utf-32"), "UTF-32"),
])
def test_wide_encodings_are_refused_by_name(data, name):
    with pytest.raises(NcParseError) as info:
        parse_text(data.decode("latin-1"), "p.nc")
    assert str(info.value) == (f"p.nc:1:1: the file is {name} text (several bytes per "
                               "character), which NC controls do not read; save it as ASCII "
                               "or UTF-8 and run ncopt again")


def test_a_tape_leader_of_nul_bytes_is_no_utf16():
    prog = parse_text("\x00" * 50 + "\n%\nG1 X1\n%\n", "p.nc")
    assert prog.text[prog.word_start[0]:prog.word_end[0]] == "G1"


@pytest.mark.parametrize("dialect", [None, "linuxcnc", "fanuc", "sinumerik"])
def test_a_byte_order_mark_is_refused_with_what_to_do(dialect):
    text = "\ufeff%\nO1000\nG1 X1 F100\n%\n".encode("utf-8").decode("latin-1")
    with pytest.raises(NcParseError) as info:
        parse_text(text, "p.nc", dialect=dialect)
    assert str(info.value) == ("p.nc:1:1: the file starts with a UTF-8 byte order mark (BOM), "
                               "which LinuxCNC refuses (\"Bad character used\") and ncopt "
                               "would have to keep before its stamp line; save the file as "
                               "UTF-8 without BOM (or ASCII) and run ncopt again")


def test_a_byte_order_mark_inside_the_file_is_named():
    with pytest.raises(NcParseError) as info:
        parse_text("G1 X1\n\xef\xbb\xbfG1 X2\n", "p.nc")
    assert str(info.value).startswith("p.nc:2:1: a UTF-8 byte order mark inside the file")


@needs_rs274
def test_rs274_refuses_a_byte_order_mark():
    assert "Bad character" in rs274_refuses("\xef\xbb\xbfG1 X1 F100\nM2\n")


def test_a_file_of_cr_line_ends_is_refused_with_a_short_context():
    text = "G1 X1 F100\r" * 4000
    with pytest.raises(NcParseError) as info:
        parse_text(text, "p.nc")
    head, shown, caret = str(info.value).splitlines()
    assert head == ("p.nc:1:11: the lines end with CR alone (classic Mac OS line ends), so "
                    "the whole file is one line to ncopt, and one block to LinuxCNC; save it "
                    "with LF or CR LF line ends")
    assert shown == "    " + ("G1 X1 F100?" * 11)[:CONTEXT_CHARS] + "..."
    assert caret == "    " + " " * 10 + "^"


def test_a_stray_cr_is_named():
    with pytest.raises(NcParseError) as info:
        parse_text("G1 X1\r\rG2 X1\n", "p.nc")
    assert str(info.value).startswith("p.nc:1:6: a carriage return (CR) inside the line")


def test_nested_parentheses_print_one_line_of_context():
    text = "G1 X1 " + "(" * 200_000 + ")" * 200_000 + "\n"
    with pytest.raises(NcParseError) as info:
        parse_text(text, "p.nc")
    message = str(info.value)
    assert message.splitlines()[0] == ("p.nc:1:7: a comment inside a comment: controls do "
                                       "not nest parentheses (LinuxCNC: \"Nested comment "
                                       "found\"); remove the inner ( )")
    assert len(message) < 400


@pytest.mark.parametrize("col", [1, 5, 60, 61, 62, 500, 939, 1000])
def test_the_caret_context_is_capped_and_points_at_the_column(col):
    src = "".join(chr(48 + i % 43) for i in range(1000))
    shown, caret = caret_context(src, col).splitlines()
    assert len(shown) <= 4 + 3 + CONTEXT_CHARS + 3
    assert shown[caret.index("^")] == src[col - 1]


def test_control_characters_never_reach_the_terminal():
    shown, caret = caret_context("G1 X1 \x1b[31m?\r", 12).splitlines()
    assert shown == "    G1 X1 ?[31m??" and caret.index("^") == 4 + 11


def test_a_byte_that_is_not_text_is_named_by_its_code():
    with pytest.raises(NcParseError) as info:
        parse_text("G1 X1 \xff\n", "p.nc")
    assert "unexpected byte 0xFF;" in str(info.value)


# ------------------------------------------------------------------- Klartext ----
KLARTEXT = ("0 BEGIN PGM W5269NS01007C26 MM\n1 ; PROJECT\n2 BLK FORM 0.1 Z X-498 Y-184 Z60\n"
            "3 TOOL CALL \"GB02001000250301\" Z S17950\n4 L X+0.0 Y+0.0 R0 FMAX M92\n"
            "5 END PGM W5269NS01007C26 MM\n")
KLARTEXT_WHAT = ("a Heidenhain conversational (Klartext) program, not ISO/DIN G-code; ncopt "
                 "reads G-code only: post the program as ISO (DIN/ISO), e.g. with the CAM "
                 "system's Heidenhain ISO post-processor")


@pytest.mark.parametrize("dialect", [None, "heidenhain-iso", "fanuc"])
def test_a_klartext_program_is_refused_by_name(dialect):
    with pytest.raises(NcParseError) as info:
        parse_text(KLARTEXT, "w.h", dialect=dialect)
    assert str(info.value).splitlines()[0] == \
        f"w.h:1:1: `0 BEGIN PGM W5269NS01007C26 MM` starts {KLARTEXT_WHAT}"


def test_a_klartext_block_without_its_header_is_named():
    with pytest.raises(NcParseError) as info:
        parse_text("G0 X0\n15 L X+10 Y+5 R0 FMAX\n", "p.nc")
    assert str(info.value).splitlines()[0] == f"p.nc:2:1: the line is a block of {KLARTEXT_WHAT}"


def test_heidenhain_iso_is_no_klartext():
    prog = parse_text("%BOWL G71 *\nN10 G01 X+10 Y+5 F1000 M3 *\nN99999999 %BOWL G71 *\n",
                      "b.i")
    assert prog.n_words == 7  # N10 G01 X+10 Y+5 F1000 M3, N99999999
