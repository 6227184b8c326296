"""ncopt.writing.edits (and the rewrite entry point): splicing, number styles, separators, CRLF."""

from __future__ import annotations

import re

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ncopt.api import rewrite_text
from ncopt.model import Job
from ncopt.runtime.errors import VerificationError
from ncopt.motion.interp import interpret
from ncopt.model import Cutter, CuttingData, Edit, LineKind, Machine
from ncopt.writing import edits as edits_module
from ncopt.reading.parse import parse_text
from ncopt.writing.edits import (F_CODE, S_CODE, Targets, WordStyle, apply_edits, detect_style,
                           masked, plan_edits)


def edit(text, lines, s, f):
    prog = parse_text(text)
    targets = Targets(np.array(lines), np.array(s, float), np.array(f, float))
    edits = plan_edits(prog, targets, detect_style(prog, S_CODE),
                       detect_style(prog, F_CODE, default_decimals=1))
    return apply_edits(text, edits)


# ------------------------------------------------------------------ number styles ----
@pytest.mark.parametrize("style, value, text", [
    (WordStyle(0, False), 3002.4, "3002"),
    (WordStyle(0, True), 3002.4, "3002."),
    (WordStyle(1, False), 3002.44, "3002.4"),
    (WordStyle(2, False), 12.5, "12.50"),
    (WordStyle(3, False), 0.1, "0.100"),
])
def test_word_style_format(style, value, text):
    assert style.format(value) == text


@pytest.mark.parametrize("f_word, decimals, trailing", [
    ("F279", 0, False), ("F279.", 0, True), ("F279.0", 1, False), ("F279.00", 2, False),
    ("F.5", 1, False),
])
def test_detect_style_of_feed_words(f_word, decimals, trailing):
    prog = parse_text(f"G1 X1 {f_word}\nG1 X2 {f_word}\nX3 F100.000\n")
    style = detect_style(prog, F_CODE)
    assert (style.decimals, style.trailing_point) == (decimals, trailing)  # the majority


@pytest.mark.parametrize("text, sep", [
    ("N10 G1 X1 Y2\nN20 X3\n", " "), ("N10G1X1.Y2.\nN20X3.\n", ""),
    ("G1\tX1\tY2\n", " "), ("X1\nY2\n", " "),  # one word per line: blanks by default
])
def test_separator_detection(text, sep):
    assert detect_style(parse_text(text), F_CODE).separator == sep


# ---------------------------------------------------------- edits from targets ----
def test_replace_in_place_and_append_worked_by_hand():
    text = "S1393 M3\nG1 X1 F279\nX2\nX3\nX4\n"
    out = edit(text, [1, 2, 3, 4], [1500, 1500, 1600, 1600], [300, 310, 310, 320])
    # the spindle-start S takes the first block's speed; later changes are appended
    assert out == "S1500 M3\nG1 X1 F300\nX2 F310\nX3 S1600\nX4 F320\n"


def test_appended_words_s_before_f():
    out = edit("S100 M3\nG1 X1 F50\nX2\n", [1, 2], [100, 200], [50, 60])
    assert out == "S100 M3\nG1 X1 F50\nX2 S200 F60\n"


def test_program_writing_f_before_s_gets_f_before_s():
    out = edit("G1 X0 F50 S100 M3\nG1 X1 F50 S100\nX2\n", [0, 1, 2], [100, 100, 200],
               [50, 50, 60])
    assert out.splitlines()[2] == "X2 F60 S200"


@pytest.mark.parametrize("f_word, appended", [
    ("F279", "F310"), ("F279.", "F310."), ("F279.0", "F310.0"), ("F279.00", "F310.00"),
])
def test_number_style_is_kept(f_word, appended):
    out = edit(f"S1393 M3\nG1 X1 {f_word}\nX2\n", [1, 2], [1393, 1393], [279, 310])
    assert out == f"S1393 M3\nG1 X1 {f_word}\nX2 {appended}\n"


def test_words_without_spaces_get_words_without_spaces():
    text = "N10S1393M3\nN20G1X1.F279.\nN30X2.\nN40X3.\n"
    out = edit(text, [1, 2, 3], [1393, 1500, 1500], [279, 300, 300])
    assert out == "N10S1393M3\nN20G1X1.F279.\nN30X2.S1500F300.\nN40X3.\n"


def test_crlf_line_endings_are_kept():
    text = "S1393 M3\r\nG1 X1 F279\r\nX2\r\nX3\r\n"
    out = edit(text, [1, 2, 3], [1393, 1500, 1600], [279, 300, 320])
    assert out == "S1393 M3\r\nG1 X1 F279\r\nX2 S1500 F300\r\nX3 S1600 F320\r\n"


def test_append_goes_before_a_comment():
    out = edit("S1 M3\nG1 X1 F1 ; first\nX2 (second)\n", [1, 2], [1, 2], [1, 3])
    assert out == "S1 M3\nG1 X1 F1 ; first\nX2 S2 F3 (second)\n"


def test_no_edit_when_the_value_is_written_the_same():
    text = "S1393 M3\nG1 X1 F279.\nX2\n"
    assert edit(text, [1, 2], [1393.2, 1393.4], [279.0, 279.0]) == text


def test_expression_words_are_replaced_whole():
    text = "#1=700\nS[#1*2] M3\nG1 X1 F#1\nX2\n"
    out = edit(text, [2, 3], [1500, 1500], [300, 300])
    # no number F word to copy the style from: one decimal
    assert out.splitlines()[1:3] == ["S1500 M3", "G1 X1 F300.0"]
    parse_text(out)


def test_opaque_lines_are_never_edited():
    """The grammar's promise: an opaque line is kept byte for byte."""
    text = 'S1393 M3 T="BALL_D16"\nG1 X1 F279\nX2\n'
    out = edit(text, [1, 2], [1500, 1500], [279, 279])
    assert out.splitlines()[0] == 'S1393 M3 T="BALL_D16"'
    # the new speed is then set on the first block that needs it
    prog = parse_text(out)
    s = prog.word_value[prog.word_letter == S_CODE]
    assert s[-1] == 1500


# ---------------------------------------------------------------- splicing ----
def test_apply_edits_identity_and_order():
    text = "G1 X1 F100\n"
    assert apply_edits(text, []) == text
    ins = [Edit(10, 10, " S1"), Edit(10, 10, " F2"), Edit(7, 10, "200")]
    assert apply_edits(text, ins) == "G1 X1 F200 S1 F2\n"


def _spliced_reference(text: str, edits) -> str:
    """apply_edits as a plain loop over the edits in (start, end) order."""
    out, pos = [], 0
    for e in sorted(edits, key=lambda e: (e.start, e.end)):  # stable: insertions keep order
        out += [text[pos:e.start], e.text]
        pos = e.end
    return "".join(out) + text[pos:]


@given(st.text(alphabet="GX1 \n", min_size=0, max_size=30).flatmap(lambda text: st.tuples(
    st.just(text), st.lists(st.tuples(st.integers(0, len(text)), st.integers(0, 2),
                                      st.sampled_from(["", "S1", " F20"])), max_size=12))),
       st.sampled_from([1, 2, 3, 65536]))
def test_apply_edits_is_the_plain_splice_whatever_its_block(case, block):
    text, raw = case
    edits, last = [], -1
    for at, length, new in sorted(raw):  # apart: each starts at or after the previous end
        at = max(at, last)
        end = min(at + length, len(text))
        edits.append(Edit(at, end, new))
        last = end
    old = edits_module.SPLICE_BLOCK
    edits_module.SPLICE_BLOCK = block
    try:
        assert apply_edits(text, edits) == _spliced_reference(text, edits)
    finally:
        edits_module.SPLICE_BLOCK = old


def test_overlapping_edits_raise():
    with pytest.raises(VerificationError):
        apply_edits("G1 X1 F100\n", [Edit(6, 10, "F1"), Edit(7, 8, "2")])


def test_masked_removes_s_and_f_words_with_their_blanks():
    prog = parse_text("G1 X1 S100\tF200 Y2\nN2S5F6X1\n")
    assert masked(prog) == "G1 X1 Y2\nN2X1\n"


def _masked_reference(prog) -> str:
    """masked() as a plain loop: each S/F word goes, with the blanks just before it."""
    text, out, pos = prog.text, [], 0
    for w in np.flatnonzero(np.isin(prog.word_letter, [S_CODE, F_CODE])).tolist():
        start = int(prog.word_start[w])
        while start > pos and text[start - 1] in " \t":
            start -= 1
        out.append(text[pos:start])
        pos = int(prog.word_end[w])
    return "".join(out) + text[pos:]


_WORD = st.sampled_from(["S100", "F20.5", "X1", "G1", "s7", "f.5", "(c)", "M3", "N10"])
_GAP = st.sampled_from(["", " ", "\t", "  ", " \t "])


@given(st.lists(st.lists(st.tuples(_GAP, _WORD), max_size=6), min_size=1, max_size=8),
       st.sampled_from(["\n", "\r\n"]))
def test_masked_is_the_plain_loop(lines, newline):
    text = newline.join("".join(g + w for g, w in line) for line in lines) + newline
    prog = parse_text(text)
    assert masked(prog) == _masked_reference(prog)


def test_edits_count_the_words_they_write():
    text = "G1 X1 F100\nX2\nS500 M3\nX3\n"
    prog = parse_text(text)
    targets = Targets(np.array([0, 1, 3]), np.array([np.nan, 600.0, 700.0]),
                      np.array([110.0, 120.0, 120.0]))
    edits = plan_edits(prog, targets, WordStyle(), WordStyle())
    out = apply_edits(text, edits)
    assert out == "G1 X1 F110\nX2 S600 F120\nS700 M3\nX3\n"
    assert (edits.s_words, edits.f_words) == (2, 2)


# ------------------------------------------------- the rewrite, end to end ----
JOB = Job(cutter=Cutter(16.0, 2), machine=Machine(accel_rad_s2=227.0, max_rpm=15000.0),
          cutting=CuttingData(vc_m_min=70.0, fz_mm=0.1), stamp=False)


def wall_program(mb, *, sep=" ", f_word="F279", newline="\n", inch=False, tape=False):
    """Two passes up the steep wall of the sample bowl (the requirement changes a lot)."""
    scale = 1 / 25.4 if inch else 1.0
    fmt = (lambda v: f"{v * scale:.4f}") if inch else (lambda v: f"{v:.3f}")
    lines = (["%", "O1000"] if tape else []) + [
        "(wall finish)", ("G20" if inch else "G21") + sep + "G90", "T1" + sep + "M6",
        "S1393" + sep + "M3", "G0" + sep + f"X{fmt(60)}{sep}Y{fmt(45)}{sep}Z{fmt(10)}"]
    first = True
    for i, y in enumerate((45.0, 46.5)):
        xs = np.linspace(60.0, 40.0, 25) if i % 2 else np.linspace(40.0, 60.0, 25)
        zs = mb.drop_ball_tip_z_mm(xs, np.full_like(xs, y), 8.0)
        for x, z in zip(xs.tolist(), zs.tolist()):
            words = [f"X{fmt(x)}", f"Y{fmt(y)}", f"Z{fmt(z)}"]
            if first:
                words = ["G1"] + words + [f_word]
                first = False
            lines.append(sep.join(words))
    lines += ["G0" + sep + f"Z{fmt(10)}", "M5", "M30"] + (["%"] if tape else [])
    return newline.join(lines) + newline


@pytest.fixture(scope="module")
def mb(make_bowl):
    return make_bowl


def _checked(text, index, job=JOB):
    out = rewrite_text(text, job, "wall.nc", index).text
    a, b = parse_text(text), parse_text(out)
    assert masked(b) == masked(a)
    assert np.array_equal(interpret(a).xyz_mm, interpret(b).xyz_mm)
    return out, b


def _f_words(prog):
    sel = prog.word_letter == F_CODE
    return [prog.text[n:e] for n, e in zip(prog.word_num_start[sel], prog.word_end[sel])]


@pytest.mark.parametrize("f_word, decimals, point", [
    ("F279", 0, False), ("F279.", 0, True), ("F279.0", 1, False)])
def test_rewrite_keeps_the_feed_style(mb, bowl_index, f_word, decimals, point):
    out, prog = _checked(wall_program(mb, f_word=f_word), bowl_index)
    fs = _f_words(prog)
    assert len(fs) > 5  # the wall changes the feed often
    for f in fs:
        assert f.endswith(".") == point and len(f.partition(".")[2]) == decimals, f


def test_rewrite_sets_s_on_the_spindle_start_line(mb, bowl_index):
    text = wall_program(mb)
    out, prog = _checked(text, bowl_index)
    start = [i for i in range(prog.n_lines) if "M3" in prog.line_text(i)][0]
    s_words = prog.word_value[(prog.word_letter == S_CODE) & (prog.word_line == start)]
    assert s_words.size == 1
    assert prog.line_text(start) == f"S{int(s_words[0])} M3"
    # S is on the start line in force when the first cut begins: no S word before it
    first_cut = [i for i in range(prog.n_lines) if prog.line_text(i).startswith("G1")][0]
    between = (prog.word_letter == S_CODE) & (prog.word_line > start) & \
        (prog.word_line < first_cut)
    assert not between.any()


def test_rewrite_without_spaces_appends_without_spaces(mb, bowl_index):
    out, prog = _checked(wall_program(mb, sep=""), bowl_index)
    body = [prog.line_text(i) for i in range(prog.n_lines) if prog.line_kind[i] == LineKind.WORDS]
    assert not any(" " in line for line in body)
    assert any("S" in line[1:] and line.startswith("X") for line in body)


def test_rewrite_keeps_crlf(mb, bowl_index):
    text = wall_program(mb, newline="\r\n")
    out, prog = _checked(text, bowl_index)
    assert out.count("\r\n") == out.count("\n") == text.count("\n")
    assert out != text


def test_inch_program_gets_inch_feeds(mb, bowl_index):
    """Positions in inches on a mm mesh: F words are inch/min with two decimals."""
    text = wall_program(mb, inch=True, f_word="F11.0")
    out, prog = _checked(text, bowl_index)
    fs = [float(f) for f in _f_words(prog)]
    assert len(fs) > 5
    assert all(len(f.partition(".")[2]) == 2 for f in _f_words(prog))
    # F = fz z S is at most 0.1 mm * 2 * 15000 RPM = 3000 mm/min = 118.1 inch/min
    assert max(fs) <= 3000 / 25.4 * (1 + JOB.options.fz_tolerance)
    tp = interpret(prog)
    assert np.nanmax(tp.feed_mm_min) <= 3000 * (1 + JOB.options.fz_tolerance)


def test_rewrite_twice_is_stable(mb, bowl_index):
    """A stamped output rewritten again is the same: the stamp keeps what the program's
    words no longer tell (the operation's own S and cutting feed, which blocks were
    planned).  Without a stamp a second run re-plans from the rewritten S and F."""
    job = replace(JOB, stamp=True)
    out = rewrite_text(wall_program(mb, tape=True), job, "wall.nc", bowl_index).text
    assert out != wall_program(mb, tape=True)
    assert rewrite_text(out, job, "wall.nc", bowl_index).text == out


# ------------------------------------------------------------------ the stamp ----
@pytest.mark.parametrize("tape, comment", [(True, "("), (False, "(")])
def test_stamp_is_a_block_of_short_comment_lines_after_the_tape_header(mb, bowl_index, tape,
                                                                        comment):
    """Four lines of header (version and date, source, machine, cutting time) and two per
    planned operation, each at most 72 characters, comments only, after the tape header;
    a second run that plans the same keeps it byte for byte (its date included)."""
    text = wall_program(mb, tape=tape)
    plain = rewrite_text(text, JOB, "wall.nc", bowl_index).text
    stamped = rewrite_text(text, replace(JOB, stamp=True), "wall.nc", bowl_index).text
    a, b = plain.splitlines(keepends=True), stamped.splitlines(keepends=True)
    at = 2 if tape else 0
    assert b[:at] + b[at + 6:] == a
    stamp = b[at:at + 6]
    assert all(line.startswith(comment + "ncopt ") for line in stamp)
    assert all(len(line.rstrip("\r\n")) <= 72 for line in stamp)
    assert re.fullmatch(r"\(ncopt \S+ \d{4}-\d\d-\d\d: S and F for constant vc and fz\)\n",
                        stamp[0])
    assert stamp[1] == "(ncopt from wall.nc)\n"
    assert stamp[2] == "(ncopt machine 227 rad/s2, 15000 RPM)\n"
    assert stamp[3].startswith("(ncopt cutting time ") and " -> " in stamp[3]
    assert "vc=70" in stamp[4] and "S0=" in stamp[5]
    assert parse_text("".join(stamp)).line_kind.tolist() == [LineKind.BLANK] * 6
    again = rewrite_text(stamped, replace(JOB, stamp=True), "wall.nc", bowl_index).text
    assert again == stamped


def test_stamp_uses_semicolons_in_a_semicolon_program(mb, bowl_index):
    text = wall_program(mb).replace("(wall finish)", "; wall finish")
    stamped = rewrite_text(text, replace(JOB, stamp=True), "wall.nc", bowl_index).text
    assert stamped.startswith("; ncopt ") or stamped.startswith(";ncopt ")
