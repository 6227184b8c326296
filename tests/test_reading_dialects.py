"""Forms of real programs the reading stage refused or misread (the issue "Right where it
plans"): Sinumerik ``CR=`` radius arcs, Fanuc 30i macro variables, marks that LinuxCNC and
grbl programs share with Fanuc's, Sinumerik's ``G700`` inch, LinuxCNC's compact
``m66e0l0``, and the lines before the opening ``%`` and after the closing one.

Each test quotes the form the real program uses; LinuxCNC's own interpreter (rs274) is the
judge where it reads the form too.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from typer.testing import CliRunner

from ncopt.api import rewrite_text
from ncopt.model import Job
from ncopt.cli.app import Exit, app
from ncopt.reading.dialect import FANUC, LINUXCNC, SINUMERIK, detect
from ncopt.runtime.errors import NcoptError, NcParseError
from ncopt.planning.inspection import inspect_text
from ncopt.motion.interp import interpret
from ncopt.model import Cutter, LineKind, Machine, Motion
from ncopt.reading.parse import parse_text
from ncopt.writing.edits import masked

from judge import RS274, canon
from programs import dome

ROOT = Path(__file__).resolve().parents[1]
CORPUS = (ROOT / "../shared/corpus").resolve()
CR_FILE = CORPUS / "more2" / "sinumerik-cr-arcs_test.mpf"
JOB = Job(machine=Machine(accel_rad_s2=227.0, max_rpm=15000.0), cutter=Cutter(6.0, 2))
REWRITE = ["--diameter", "6", "--accel", "227", "--max-rpm", "15000"]
needs_corpus = pytest.mark.skipif(not CR_FILE.is_file(), reason="no corpus")
needs_rs274 = pytest.mark.skipif(RS274 is None, reason="rs274 (linuxcnc-uspace) not installed")


def invoke(args):
    runner = CliRunner(env={"NO_COLOR": "1", "TERM": "dumb", "COLUMNS": "100"})
    result = runner.invoke(app, [str(a) for a in args], catch_exceptions=False)
    assert "Traceback" not in result.stderr
    return result


def words(prog, line: int | None = None) -> list[tuple[str, str, float]]:
    """(text, letter, value) of every word (of one 0-based line)."""
    sel = np.arange(prog.n_words) if line is None else np.flatnonzero(prog.word_line == line)
    return [(prog.text[prog.word_start[k]:prog.word_end[k]], chr(prog.word_letter[k]),
             float(prog.word_value[k])) for k in sel.tolist()]


def arc_feeds(text: str) -> list[list[float]]:
    """rs274's ARC_FEED calls: end (2), centre (2), turns, axis end, ... per arc."""
    return [[float(v) for v in args.split(",")] for name, args in canon(text).motion
            if name == "ARC_FEED"]


# ------------------------------------------------------------ Sinumerik CR= arcs ----
@needs_corpus
@pytest.mark.parametrize("dialect", [None, SINUMERIK])
def test_the_real_cr_arc_reads_as_its_radius(dialect):
    """``N000009 G03 X-22.313 Y19.749 CR=4. F250.`` (line 9, where ncopt said "arc with
    none of I, J, K or R"): CR=4. is the arc's radius, its F250. a word ncopt may rewrite."""
    prog = parse_text(CR_FILE.read_bytes().decode("latin-1"), str(CR_FILE), dialect=dialect)
    assert words(prog, 8) == [("N000009", "N", 9.0), ("G03", "G", 3.0), ("X-22.313", "X", -22.313),
                              ("Y19.749", "Y", 19.749), ("CR=4.", "R", 4.0), ("F250.", "F", 250.0)]
    assert prog.line_kind[8] == LineKind.WORDS
    assert "C" not in {w[1] for w in words(prog)}  # no CR became a C (rotary axis) word


@needs_corpus
@needs_rs274
def test_the_real_cr_arcs_are_the_arcs_rs274_draws_from_the_same_radius():
    """The program's first operation (lines 1-24: ``G03 ... CR=4.`` and ``G02 X-31.999
    Y-1.349 CR=4.``) against rs274 reading the same blocks with LinuxCNC's R word, whose
    radius and sign mean what Siemens gives CR= ("CR=+...: angle less than or equal to 180
    deg, CR=-...: more than 180 deg"): every point ncopt follows lies on rs274's circle,
    the arc turns rs274's way and ends where it ends."""
    head = "\n".join(CR_FILE.read_text(encoding="latin-1").splitlines()[:24]) + "\n"
    tp = interpret(parse_text(head, str(CR_FILE)))
    arcs = arc_feeds(head.replace("CR=", "R") + "M2\n")
    lines = np.unique(tp.line[np.isin(tp.motion, [Motion.ARC_CW, Motion.ARC_CCW])])
    assert lines.tolist() == [8, 17] and len(arcs) == 2
    for line, arc in zip(lines.tolist(), arcs):
        rows = np.flatnonzero(tp.line == line)
        pts = tp.xyz_mm[np.concatenate(([rows[0] - 1], rows))][:, :2]  # from the start point
        centre = np.array(arc[2:4])
        assert np.allclose(np.hypot(*(pts - centre).T), 4.0, atol=1e-4)  # CR=4.
        assert np.allclose(pts[-1], arc[0:2], atol=1e-9)
        u, v = (pts[:-1] - centre).T, (pts[1:] - centre).T
        turn = np.sign(u[0] * v[1] - u[1] * v[0])  # +1 counter-clockwise
        assert np.all(turn == arc[4])  # rs274: 1 for G3, -1 for G2
        assert int(tp.motion[rows[0]]) == (Motion.ARC_CCW if arc[4] > 0 else Motion.ARC_CW)


@needs_rs274
@pytest.mark.parametrize("cr, rs", [("34.913", "34.913"), ("-34.913", "-34.913"),
                                    ("+34.913", "34.913")])
def test_the_sign_of_cr_picks_the_short_or_the_long_arc(cr, rs):
    """Siemens' own example (Programming Manual, Fundamentals, 12/2019, p. 192):
    ``N10 G0 X67.5 Y80.511`` / ``N20 G3 X17.203 Y38.029 CR=34.913 F500``; with CR=- the
    same end point is reached the long way round (more than 180 deg)."""
    text = f"G17 G90 G71\nG0 X0 Y0 Z0\nN10 G0 X67.5 Y80.511\nN20 G3 X17.203 Y38.029 CR={cr} F500\n"
    tp = interpret(parse_text(text, dialect=SINUMERIK))
    rows = np.flatnonzero(tp.line == 3)
    assert rows.size > 10  # followed point by point
    sweep = float(tp.seg_len_mm[rows].sum()) / 34.913
    assert (sweep > math.pi) == cr.startswith("-")
    arc = arc_feeds(f"G17 G90 G21\nG0 X67.5 Y80.511\nG3 X17.203 Y38.029 R{rs} F500\nM2\n")[0]
    pts = tp.xyz_mm[rows][:, :2]
    assert np.allclose(np.hypot(*(pts - np.array(arc[2:4])).T), 34.913, atol=1e-3)


numbers = st.decimals(min_value=-999, max_value=999, places=3, allow_nan=False).map(
    lambda d: format(d, "f")).filter(lambda s: s not in ("0.000", "-0.000"))


@given(r=numbers, before=st.sampled_from(["", " ", "\t "]), after=st.sampled_from(["", " "]),
       cr=st.sampled_from(["CR", "cr", "Cr"]))
def test_a_cr_word_reads_the_same_on_the_fast_path_and_through_lark(r, before, after, cr):
    """``G02 X-31.999 Y-1.349 CR=4. F250.`` with any radius and blanks around '=': the
    same words, spans and values on both paths, CR= read as R with the number written."""
    text = f"N18 G02 X-31.999 Y-1.349 {cr}{before}={after}{r} F250.\n"
    for dialect in (None, SINUMERIK):
        fast, lark = (parse_text(text, dialect=dialect, use_fast_path=f) for f in (True, False))
        assert words(fast) == words(lark)
        assert words(fast)[4] == (f"{cr}{before}={after}{r}", "R", float(r))


def test_a_computed_radius_is_left_as_programmed():
    """``CR=R1`` (an R parameter): ncopt does not evaluate it; the arc is not refused, the
    line is not interpreted, and the moves after it wait for a known position."""
    text = "G17 G90 G71\nR1=4\nG0 X-26.313 Y23.749 Z0\nG03 X-22.313 Y19.749 CR=R1 F250.\n" \
           "G01 X22.313 F250.\nM30\n"
    tp = interpret(parse_text(text, "cr.mpf"))
    assert any(w.startswith("cr.mpf:4: 'CR' is not interpreted") for w in tp.warnings)
    assert not tp.known[tp.line == 4].any()


def test_fanuc_refuses_cr_and_names_the_dialect_that_reads_it():
    with pytest.raises(NcParseError) as err:
        parse_text("G03 X-22.313 Y19.749 CR=4. F250.\n", "p.nc", dialect=FANUC)
    assert (err.value.line, err.value.column) == (1, 23)  # Fanuc reads a C word, then 'R'
    assert err.value.message.startswith("`CR=4.` is a Sinumerik arc radius (CR=)")
    assert "--dialect sinumerik" in err.value.message


@needs_corpus
def test_inspect_and_rewrite_of_the_real_program_get_past_its_arcs(tmp_path):
    for extra in ([], ["--dialect", "sinumerik"]):
        shown = invoke(["inspect", CR_FILE, *extra])
        assert shown.exit_code == Exit.OK, shown.stderr
        assert "arcs 18)" in shown.stdout  # the 18 lines with CR= under G2/G3
        done = invoke(["rewrite", CR_FILE, *REWRITE, *extra, "-o", tmp_path / "out.mpf"])
        assert "arc with none" not in done.stderr
        # a 2D contour and a drilling cycle: nothing ncopt plans, as it says
        assert done.exit_code == Exit.PLANNING, done.stderr
        assert "one Z level" in done.stderr


# ------------------------------------------------------- Fanuc macro variables ----
@pytest.mark.parametrize("number", [1, 33, 100, 199, 500, 999, 5601, 98000, 98499, 100000,
                                    100001, 199999, 900000, 999999])
def test_the_variables_of_a_fanuc_30i_are_read(number):
    """Local #1-#33, common #100-#199, #500-#999 and the 30i's #98000-#98499 and
    #100000-#199999, and #900000 and up: assigned in the program, their values are known."""
    text = f"G21 G90\nG0 X0. Y0. Z5.\n#{number}=12.5\nG0 X#{number} Y0. Z5.\n"
    tp = interpret(parse_text(text, "v.nc", dialect=FANUC))
    assert tp.known[-1] and tp.xyz_mm[-1].tolist() == [12.5, 0.0, 5.0]


@pytest.mark.parametrize("value", ["#0", "#5021", "#100101"])
def test_a_variable_the_program_does_not_set_is_unknown_not_refused(value):
    """``#1=#0`` (clears #1: Fanuc's null variable), ``#1=#5021`` (a machine position):
    values only the control has; the moves that use them are not planned."""
    text = f"G21 G90\nG0 X0. Y0. Z5.\n#1={value}\nG1 X#1 F300.\nG1 Y1.\n"
    tp = interpret(parse_text(text, "v.nc"))
    assert not tp.known[tp.line == 3].any() and not tp.known[tp.line == 4].any()


@pytest.mark.parametrize("number", [-2, 90000, 99999, 98500, 200000, 1000000])
def test_a_number_no_control_has_is_refused_at_its_line(number):
    """LinuxCNC's own bad program ``#2=99999`` / ``G0 X EXISTS[###2]`` ("Parameter number
    out of range"): no Fanuc has #99999 either."""
    with pytest.raises(NcoptError) as err:
        interpret(parse_text(f"G21\n#1={number}\n#[#1]=5.\n", "v.ngc"))
    assert (err.value.line, err.value.column) == (3, 1)
    assert f"variable number {number} is out of the range of every control" in err.value.message


# -------------------------------------------------- marks LinuxCNC and grbl share ----
def grbl_dome() -> str:
    """A Fusion grbl post's form: ``G28 G91 Z0`` / ``G90`` before the tool, whole
    numbers without a decimal point (``G0 X-10 Y-10 Z15``)."""
    lines = dome().decode().splitlines()
    return "\n".join(["(grbl dome)", "G90 G94", "G17", "G21", "G28 G91 Z0", "G90",
                      *lines[1:]]) + "\n"


def linuxcnc_dome() -> str:
    """LinuxCNC's form: ``G43 H1`` after the tool change, ``X10``-style values, ``M2``."""
    lines = dome().decode().splitlines()
    return "\n".join([*lines[:3], "G43 H1", *lines[3:-1], "M2"]) + "\n"


@pytest.mark.parametrize("make", [grbl_dome, linuxcnc_dome])
def test_shared_marks_alone_do_not_make_a_program_fanuc(make, tmp_path):
    """``G28 G91 Z0`` (grbl) and ``G43 H1`` (LinuxCNC) made these programs Fanuc, which
    then refused ``Z15`` for its missing decimal point; their controls read it as 15 mm."""
    text = make()
    assert detect(text).name != FANUC
    assert not any("decimal point" in w for w in inspect_text(text, "p.nc").warnings)
    path = tmp_path / "p.nc"
    path.write_text(text)
    done = invoke(["rewrite", path, *REWRITE, "-o", tmp_path / "out.nc"])
    assert done.exit_code == Exit.OK, done.stderr


def test_a_mark_of_fanuc_s_own_still_makes_it_fanuc():
    """``M29 S500`` before a tapping cycle (the SolidWorks Fanuc post of the corpus):
    LinuxCNC refuses it ("Unknown m code used: M29"), grbl too."""
    text = grbl_dome().replace("G28 G91 Z0", "G28 G91 Z0\nM29 S500")
    assert detect(text).name == FANUC
    assert detect("O1000\nG43 H1 Z50.\nG28 G91 Z0.\n").name == FANUC  # a program number


# ---------------------------------------------------------- Sinumerik G700 inch ----
def inch_dome(units: str) -> str:
    """The dome in inch (4 decimals), F in inch/min, ``units`` on the first block."""
    out = []
    for line in dome().decode().splitlines():
        line = re.sub(r"([XYZ])(-?[\d.]+)", lambda m: f"{m[1]}{float(m[2]) / 25.4:.4f}", line)
        out.append(line.replace("G21", units).replace("F800", "F31.5"))
    return "\n".join(out) + "\n"


def test_g700_is_inch_for_lengths_and_feed_as_g20_is():
    """Sinumerik ``G700``: "inch dimensional notation, also for feed F".  The program with
    G700 is planned exactly as the one with G20: the same words written."""
    g700, g20 = inch_dome("G700"), inch_dome("G20")
    assert inspect_text(g700, "p.mpf", dialect=SINUMERIK).units == "inch"
    a = rewrite_text(g700, JOB, "p.mpf")
    b = rewrite_text(g20, JOB, "p.mpf")
    assert a.text.replace("G700", "G20") == b.text
    assert a.summary.cutting_blocks > 50


def test_g70_leaves_the_moves_as_programmed(tmp_path):
    """Sinumerik ``G70`` selects inch for the lengths only: F stays in the machine's basic
    system (its machine data), which the program does not say; ncopt does not guess it."""
    path = tmp_path / "p.mpf"
    path.write_text(inch_dome("G70"))
    done = invoke(["rewrite", path, *REWRITE, "-o", tmp_path / "out.mpf"])
    assert done.exit_code == Exit.PLANNING and "G70" in done.stderr
    assert not (tmp_path / "out.mpf").exists()


def test_g700_is_no_unit_under_fanuc():
    prog = parse_text("G700\nG1 X1. F10.\n", dialect=FANUC)
    assert words(prog, 0) == [("G700", "G", 700.0)]


# -------------------------------------------------------- LinuxCNC's m66e0l0 ----
@needs_rs274
def test_compact_m66_reads_as_rs274_reads_it():
    """``m66e0l0``: M66 E0 L0 (wait on analog input 0, no wait), not a number with an
    exponent; rs274 runs it.  ``S1e3`` is still refused: no code of its block takes E."""
    text = "G21\nm66e0l0\nG0 X1\nM2\n"
    prog = parse_text(text, dialect=LINUXCNC)
    assert words(prog, 1) == [("m66", "M", 66.0), ("e0", "E", 0.0), ("l0", "L", 0.0)]
    interpret(prog)
    canon(text)  # raises if rs274 refuses it
    with pytest.raises(NcParseError, match="`S1e3` is a number with an exponent"):
        interpret(parse_text("G21\nS1e3 M3\nM2\n"))
    with pytest.raises(RuntimeError, match="E word with no G70, G76, M66, M67 or M68"):
        canon("G21\nS1e3 M3\nM2\n")


# -------------------------------------------------- lines around the '%' marks ----
def fanuc_dome() -> str:
    """The dome as a Fanuc post writes it: ``%``, ``O1001``, values with a point, ``%``."""
    body = re.sub(r"([XYZF]-?\d+)(?![\d.])", r"\1.", dome().decode())
    return f"%\nO1001\n{body}%\n"


headers = st.lists(st.sampled_from(["", "(PROGRAM FROM FUSION)", "  (T1 D=6. CR=3.)", "\t",
                                    "(A)(B)", "; header"]), min_size=1, max_size=4)


@given(header=headers)
def test_a_header_before_the_opening_percent_is_read_and_the_program_after_it(header):
    """Comment and blank lines before the first ``%`` (``(PROGRAM FROM FUSION)`` / ``%`` /
    ``O1001``): the program after it reads as it does without them (it read nothing)."""
    plain = fanuc_dome()
    head = "\n".join(header) + "\n"
    prog, ref = parse_text(head + plain), parse_text(plain)
    shift = len(head)
    assert words(prog)[-len(words(ref)):] == words(ref)
    assert np.array_equal(prog.word_start[-ref.n_words:], ref.word_start + shift)
    kinds = prog.line_kind[len(header):]
    assert np.array_equal(kinds, ref.line_kind)
    assert not np.any(prog.line_kind == LineKind.TRAILER)


@pytest.mark.parametrize("header", ["(PROGRAM FROM FUSION)\n", "\n", "\n\n(POST 4.2)\n\n"])
def test_rewrite_reads_past_a_header_and_keeps_every_byte_of_it(header, tmp_path):
    """``(PROGRAM FROM FUSION)`` before the ``%`` made ncopt read 0 blocks ("no feed
    moves"); a blank line there ended in exit 6 ("changed more than S and F")."""
    text = header + fanuc_dome()
    src, out = tmp_path / "p.nc", tmp_path / "out.nc"
    src.write_text(text)
    done = invoke(["rewrite", src, *REWRITE, "-o", out])
    assert done.exit_code == Exit.OK, done.stderr
    written = out.read_text()
    stamp = [line for line in written.splitlines(keepends=True) if line.startswith("(ncopt ")]
    assert len(stamp) == 6  # four lines of header, two for the one operation
    kept = written.replace("".join(stamp), "", 1)
    assert kept.startswith(header + "%\nO1001\n")  # the header byte for byte
    assert masked(parse_text(kept)) == masked(parse_text(text))  # only S and F changed
    assert kept != text


def test_lines_after_the_closing_percent_get_a_located_warning(tmp_path):
    text = fanuc_dome() + "(after the end)\nG1 X5\n"
    n = text.count("\n")
    path = tmp_path / "p.nc"
    path.write_text(text)
    where = f"{path}:{n - 1}-{n}: after the closing '%' (line {n - 2})"
    assert any(w.startswith(where) for w in inspect_text(text, str(path)).warnings)
    done = invoke(["rewrite", path, *REWRITE, "-o", tmp_path / "out.nc"])
    assert done.exit_code == Exit.OK and f"warning: {where}" in done.stderr
    assert (tmp_path / "out.nc").read_text().endswith("%\n(after the end)\nG1 X5\n")
    assert not any("closing" in w for w in inspect_text(fanuc_dome() + "\n\n", "q.nc").warnings)


@needs_rs274
def test_linuxcnc_refuses_a_comment_before_the_percent_as_rs274_does():
    text = "(HEADER)\n%\nG0 X1\nM2\n%\n"
    with pytest.raises(NcParseError) as err:
        parse_text(text, "p.ngc", dialect=LINUXCNC)
    assert (err.value.line, err.value.column) == (2, 1)
    assert "Bad character '%' used" in err.value.message
    with pytest.raises(RuntimeError, match="Bad character '%' used"):
        canon(text)
    assert parse_text("\n%\nG0 X1\nM2\n%\n", dialect=LINUXCNC).n_words == 3  # blank: read
    canon("\n%\nG0 X1\nM2\n%\n")


def test_a_cr_arc_marks_sinumerik_and_a_fusion_tool_comment_does_not():
    """``N000009 G03 X-22.313 Y19.749 CR=4. F250.`` (more2/sinumerik-cr-arcs_test.mpf, no
    other Siemens mark) is Siemens' own syntax; Fusion writes ``CR=`` in every tool comment
    (``(T1 D=6. CR=3. - ZMIN=-69.203 - fresa con punta de bola)``), for every control."""
    from ncopt.reading.dialect import detect

    assert detect("N000001 G40 G17 G90\nN000009 G03 X-22.313 Y19.749 CR=4. F250.\n"
                  ).name == "sinumerik"
    assert detect("(T1 D=6. CR=3. - ZMIN=-69.203 - fresa con punta de bola)\nG1 X1 F100\n"
                  ).name == "generic"
    corpus = Path(__file__).resolve().parents[1].parent / "shared" / "corpus" / "more2"
    real = (corpus / "sinumerik-cr-arcs_test.mpf").read_text("latin-1")
    assert detect(real).name == "sinumerik"


def test_no_dialect_mark_reaches_over_blank_lines_from_a_line_start():
    """A mark that began with ``^\\s*`` (multiline) swallowed every blank line after each
    blank line and tried again: quadratic in a run of blank lines (20,000 blank lines in
    the sample: 9.9 s of the rewrite in the dialect's detection; 100,000 took minutes).  A
    mark is a construct of one line: it starts with blanks of that line only."""
    from ncopt.reading.dialect import _MARKS

    for marks in _MARKS.values():
        for mark in marks:
            assert not re.match(r"\^(?:\(\?:[^)]*\)\?)?\\s", mark.pattern), mark
    from ncopt.reading.dialect import detect

    text = "\n" * 3 + "DEF REAL X\nG1 X1 F100\n"
    assert detect(text).name == "sinumerik"
    assert detect("\n\n\n" + "\n".join(["G1 X1 F100"] * 3) + "\n" + "\n" * 5000).name == "generic"
