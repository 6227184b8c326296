"""The dialect grammars: what each reads, what each refuses (located, with the dialects that
read it), and the generic grammar as their union that reads the corpus as it always did.

The fast path against Lark for every grammar is in test_parse.py.
"""

from __future__ import annotations

import hashlib
import json
import sys
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.lark import from_lark

from ncopt.reading.dialect import DIALECTS, FANUC, GENERIC, GRBL, HEIDENHAIN, LINUXCNC, SINUMERIK
from ncopt.runtime.errors import NcoptError, NcParseError
from ncopt.model import LineKind
from ncopt.reading.parse import grammar_path, parse_text, parser

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
CORPUS = (ROOT / "../shared/corpus").resolve()
NC_SUFFIXES = {".nc", ".ngc", ".tap", ".gcode"}
CORPUS_FILES = sorted(p for p in CORPUS.rglob("*") if p.suffix.lower() in NC_SUFFIXES
                      and p.is_file()) if CORPUS.is_dir() else []
FINGERPRINTS = HERE / "corpus_words_generic.json"
ONE_DIALECT = tuple(d for d in DIALECTS if d != GENERIC)

W, B, O, P = LineKind.WORDS, LineKind.BLANK, LineKind.OPAQUE, LineKind.PERCENT


def words(prog) -> list[str]:
    return [prog.text[s:e] for s, e in zip(prog.word_start, prog.word_end)]


def read(line: str, dialect: str | None):
    return parse_text(line + "\n", "p.nc", dialect=dialect)


# ---------------------------------------------------------------- what each dialect reads ----
READS = {
    FANUC: [
        ("O1001", ["O1001"], W),
        ("O1001 (BOWL FINISH)", ["O1001"], W),
        (":1001", [], O),
        ("%", [], P),
        ("/N10 G1 X1. Y2.", ["N10", "G1", "X1.", "Y2."], W),
        ("G1 X1. Y2. ;", ["G1", "X1.", "Y2."], W),  # EOB as the manuals print it
        ("G0 Z5.;", ["G0", "Z5."], W),
        ("#100=#101+1", [], W),
        ("G1 X#1 Y[#2*2] F[#3]", ["G1", "X#1", "Y[#2*2]", "F[#3]"], W),
        ("IF[#1GT5]GOTO10", [], O),
        ("IF [#1 EQ 0] THEN #2=1", [], O),
        ("WHILE[#1LT10]DO1", [], O),
        ("END1", [], O),
        ("GOTO 20", [], O),
        ("DPRNT[X#100[53]]", [], O),
        ("G65 P9010 A1. B2.", ["G65", "P9010", "A1.", "B2."], W),
        ("N10 G43 H1 Z50. (T1 D=16 - ball end mill)", ["N10", "G43", "H1", "Z50."], W),
    ],
    SINUMERIK: [
        ("%_N_BOWL_MPF", [], P),
        ("N10 G1 X1 ; finishing", ["N10", "G1", "X1"], W),
        ("; only a comment G1 X1", [], B),
        ("CYCLE832(0.01,_FINISH,1)", [], O),
        ("TRAORI", [], O),
        ("DEF REAL X1", [], O),
        ("R1=5", [], O),
        ("S1=1000", [], O),
        ('T="BALL_D16"', [], O),
        ("G1 X=R1*2 Y10", ["G1"], O),
        ("$P_TOOLNO=1", [], O),
        ("LABEL1: G1 X1", [], O),
        (":10 G1 X1", [], O),
        ('MSG("finishing X1 Y2")', [], O),
        ("N20 T4 D1", ["N20", "T4", "D1"], W),
        ("G1 X1 A3=0.5 B3= -0 C3=.866F100", ["G1", "X1", "A3=0.5", "B3= -0", "C3=.866",
                                             "F100"], W),  # TRAORI tool vector words
        ("G1 X1 A3=R1*2", ["G1", "X1"], O),
        ("G1 X1 A4=0.5", ["G1", "X1"], O),
    ],
    LINUXCNC: [
        ("%", [], P),
        ("O1000", ["O1000"], W),  # a numbered program (M98/M99 subprograms)
        ("O1000 G1 X1", ["O1000", "G1", "X1"], W),
        ("o100 sub", [], O),
        ("o100 end sub", [], O),
        ("O102 elseif [#2 LT 2]", [], O),
        ("o<probe> call [1] [2]", [], O),
        ("O[#2 * 10] call", [], O),
        ("o#<sub> call", [], O),
        ("#<depth> = -2.5", [], W),
        ("#1 = [#2 + 3] (set)", [], W),
        ("G1 Z-[#<depth>] F[#<fscale>*225]", ["G1", "Z-[#<depth>]", "F[#<fscale>*225]"], W),
        ("G0 X EXISTS[#<a>]", ["G0", "X EXISTS[#<a>]"], W),
        ("G1 X1 ; feed", ["G1", "X1"], W),
        ("(MSG, roughing X1)", [], B),
        ("G1 X[2**3] Y[5 MOD 2]", ["G1", "X[2**3]", "Y[5 MOD 2]"], W),
    ],
    GRBL: [
        ("$H", [], O),
        ("  $X", [], O),
        ("$32=1", [], O),
        ("$J=G91 X10 F100", [], O),
        ("$$", [], O),
        ("G1 X1 F100 ; cut", ["G1", "X1", "F100"], W),
        ("(grbl) G0 Z5", ["G0", "Z5"], W),
        ("/G1 X1", ["G1", "X1"], W),  # grbl drops the '/' and runs the block
    ],
    HEIDENHAIN: [
        ("%BOWL G71 *", [], P),
        ("N10 G30 G17 X+0 Y+0 Z-40 *", ["N10", "G30", "G17", "X+0", "Y+0", "Z-40"], W),
        ("N60 G01 Z-5 F1000 M3 *", ["N60", "G01", "Z-5", "F1000", "M3"], W),
        ("N70 X+10*", ["N70", "X+10"], W),
        ("N75 X+10 *  ", ["N75", "X+10"], W),
        ("*", [], B),
        ("N80 ; finishing *", ["N80"], W),
        ("N90 G200 DRILLING", ["N90", "G200"], O),
        ("Q200=2 ;SET-UP CLEARANCE", [], O),
        ("N99999999 %BOWL G71 *", ["N99999999"], P),
    ],
}
READ_CASES = [(d, line, ws, kind) for d, rows in READS.items() for line, ws, kind in rows]


@pytest.mark.parametrize("dialect, line, expected, kind", READ_CASES)
def test_each_dialect_reads_its_constructs(dialect, line, expected, kind):
    prog = read(line, dialect)
    assert words(prog) == expected
    assert prog.line_kind.tolist() == [kind]


@pytest.mark.parametrize("dialect, line, expected, kind", READ_CASES)
def test_the_generic_grammar_reads_every_dialect_line(dialect, line, expected, kind):
    """The union: the generic grammar reads each dialect's lines, with at least its words."""
    prog = read(line, None)
    assert prog.line_kind.tolist() == [kind]
    assert set(expected) <= set(words(prog))


def test_generic_reads_a_computed_o_word_as_it_always_did():
    # the word O[..] with an unknown value and an opaque 'call': the corpus fingerprints hold it
    assert words(read("O[#2 * 10] call", None)) == ["O[#2 * 10]"]
    assert read("O[#2 * 10] call", None).opaque_reason == {0: "call"}


# --------------------------------------------------------------- what each dialect refuses ----
REFUSES = [
    # dialect, line, column, snippet, what, readers
    (FANUC, "R1=5", 3, "R1=5", "a Sinumerik R-parameter assignment", "sinumerik, heidenhain-iso"),
    (FANUC, "N10 G1 X1 R1=5 S200", 13, "R1=5 S200", "a Sinumerik R-parameter assignment",
     "sinumerik, heidenhain-iso"),
    (FANUC, 'T="BALL"', 2, 'T="BALL"', "an address assignment", "sinumerik, heidenhain-iso"),
    (FANUC, "CYCLE832(0.01,_FINISH,1)", 2, "CYCLE832(0.01,_FINISH,1)",
     "a keyword (macro statement, cycle call or label)", "sinumerik, heidenhain-iso"),
    (FANUC, "o100 sub", 7, "o100 sub", "a LinuxCNC o-word", "linuxcnc"),
    (FANUC, "o[#1] call", 8, "call", "a keyword (macro statement, cycle call or label)",
     "linuxcnc"),
    (FANUC, "G1 X#<depth>", 6, "#<depth>", "a LinuxCNC named parameter", "linuxcnc"),
    (FANUC, "$H", 1, "$H", "a '$' system command or variable", "sinumerik, grbl"),
    (FANUC, "G1 X1 Y2 *", 10, "*", "a Heidenhain ISO block end", "heidenhain-iso"),
    (FANUC, "G1 X1 A3=0.5", 9, "A3=0.5", "a Sinumerik tool vector word",
     "sinumerik, heidenhain-iso"),
    (SINUMERIK, "#1=5", 1, "#1=5", "a parameter assignment", "fanuc, linuxcnc"),
    (SINUMERIK, "G1 X[1+2]", 5, "X[1+2]", "a word with a computed value", "fanuc, linuxcnc"),
    (SINUMERIK, "G1 X#<a>", 5, "#<a>", "a LinuxCNC named parameter", "linuxcnc"),
    (SINUMERIK, "o<flowsnake> sub", 2, "o<flowsnake> sub", "a LinuxCNC o-word", "linuxcnc"),
    (SINUMERIK, "G1 X1 *", 7, "*", "a Heidenhain ISO block end", "heidenhain-iso"),
    (LINUXCNC, "R1=5", 3, "R1=5", "a Sinumerik R-parameter assignment",
     "sinumerik, heidenhain-iso"),
    (LINUXCNC, "IF[#1GT5]GOTO10", 2, "IF[#1GT5]GOTO10",
     "a keyword (macro statement, cycle call or label)", "sinumerik, fanuc, heidenhain-iso"),
    (LINUXCNC, ":1001", 1, ":1001", "a ':' program or main block number", "sinumerik, fanuc"),
    (LINUXCNC, "$P_TOOLNO=1", 1, "$P_TOOLNO=1", "a '$' system command or variable",
     "sinumerik, grbl"),
    (GRBL, "#1=5", 1, "#1=5", "a parameter assignment", "fanuc, linuxcnc"),
    (GRBL, "G1 X[1+2]", 5, "X[1+2]", "a word with a computed value", "fanuc, linuxcnc"),
    (GRBL, "G1 X1 $H", 7, "$H", "a '$' system command or variable", "sinumerik"),
    (GRBL, "o100 sub", 7, "o100 sub", "a LinuxCNC o-word", "linuxcnc"),
    (HEIDENHAIN, "#1=5", 1, "#1=5", "a parameter assignment", "fanuc, linuxcnc"),
    (HEIDENHAIN, "$H", 1, "$H", "a '$' system command or variable", "sinumerik, grbl"),
    (HEIDENHAIN, "o<probe> call", 2, "o<probe> call", "a LinuxCNC o-word", "linuxcnc"),
]


def _todo(readers: str) -> str:
    names = readers.split(", ")
    if len(names) == 1:
        return f"pass --dialect {names[0]} or --dialect generic"
    return f"pass --dialect {readers} or generic"


@pytest.mark.parametrize("dialect, line, column, snippet, what, readers", REFUSES)
def test_a_construct_of_another_dialect_is_refused_with_what_to_do(dialect, line, column,
                                                                   snippet, what, readers):
    text = "(part)\nG0 X0 Y0\n" + line + "\nG1 X1\n"
    for fast in (True, False):
        with pytest.raises(NcParseError) as info:
            parse_text(text, "part.nc", dialect=dialect, use_fast_path=fast)
        err = info.value
        assert (err.path, err.line, err.column) == ("part.nc", 3, column)
        assert err.message == (f"`{snippet}` is {what}, not read under the {dialect} dialect; "
                               f"{_todo(readers)}")
        assert err.context == f"    {line}\n    {' ' * (column - 1)}^"
        assert str(err).splitlines()[0] == f"part.nc:3:{column}: {err.message}"
        read(line, None)  # and the generic grammar reads it


def test_a_semicolon_comment_under_fanuc_says_what_the_semicolon_is_there():
    with pytest.raises(NcParseError) as info:
        parse_text("G1 X1. ; S3 is not a comment on a Fanuc\n", "f.nc", dialect=FANUC)
    assert info.value.column == 8
    assert info.value.message == (
        "`; S3 is not a comment...` is a ';' comment, which Fanuc does not have: its manuals "
        "print the end-of-block code as ';', so the text after it would be read as a block; "
        "write the comment in ( ) or pass --dialect sinumerik, heidenhain-iso, linuxcnc, grbl "
        "or generic")


def test_a_percent_line_under_grbl_says_grbl_does_not_read_it():
    with pytest.raises(NcParseError) as info:
        parse_text("%\nG1 X1\n%\n", "g.nc", dialect=GRBL)
    assert (info.value.line, info.value.column) == (1, 1)
    assert info.value.message == (
        "`%` is a '%' tape mark, which grbl does not read (it reports the line as an error); "
        "remove the line or pass --dialect sinumerik, fanuc, heidenhain-iso, linuxcnc or generic")


@pytest.mark.parametrize("dialect", ONE_DIALECT)
def test_a_line_malformed_in_every_dialect_keeps_the_plain_message(dialect):
    with pytest.raises(NcParseError) as info:
        parse_text("G1 X1.2.3\n", "m.nc", dialect=dialect)
    assert (info.value.line, info.value.column) == (1, 8)
    assert info.value.message.startswith("unexpected '.'; expected a word")


def test_the_refused_line_is_located_after_many_fast_lines():
    body = "".join(f"N{10 * i} G1 X{i}.5 Y-{i}\n" for i in range(2000))
    with pytest.raises(NcParseError) as info:
        parse_text(body + "R1=5\n" + body, "big.nc", dialect=FANUC)
    assert (info.value.line, info.value.column) == (2001, 3)


@pytest.mark.parametrize("owner, line", [(d, line) for d, line, _, _ in READ_CASES])
@pytest.mark.parametrize("dialect", ONE_DIALECT)
def test_a_refused_line_names_a_dialect_that_reads_it(owner, line, dialect):
    try:
        read(line, dialect)
    except NcParseError as err:
        assert err.line == 1 and err.column >= 1
        assert "--dialect" in err.message and err.message.endswith("generic")
        assert owner in err.message.split("; ")[-1], err.message


@pytest.mark.parametrize("dialect, end", [(HEIDENHAIN, " *"), (None, "*"), (FANUC, ";")])
def test_block_end_lines_take_the_fast_path(dialect, end):
    """A block end mark the grammar reads is not a reason to leave the fast path."""
    text = "".join(f"N{10 * i} G01 X+{i}.5 Y-{i} F1000{end}\n" for i in range(1000))
    calls = []
    prog = parse_text(text, dialect=dialect, progress=calls.append)
    assert calls == []  # progress is called per Lark line
    assert prog.n_words == 5000 and words(prog)[-1] == "F1000"
    assert np.array_equal(prog.word_start, parse_text(text, dialect=dialect,
                                                      use_fast_path=False).word_start)


# -------------------------------------------------------------------- generic = the union ----
@lru_cache(maxsize=None)
def dialect_lines(dialect: str):
    alphabet = st.characters(codec="latin-1", exclude_characters="\r\n")
    return from_lark(parser(dialect), start="line", alphabet=alphabet)


@pytest.mark.slow
@pytest.mark.parametrize("dialect", ONE_DIALECT)
@settings(max_examples=100)
@given(data=st.data())
def test_generic_reads_what_any_dialect_reads(dialect, data):
    """Every line a dialect grammar generates: the generic grammar reads it, same line kind,
    and every word the dialect reads at the same place with the same value."""
    lines = data.draw(st.lists(dialect_lines(dialect), min_size=1, max_size=3))
    text = "\n".join(lines) + "\n"
    mine, union = parse_text(text, dialect=dialect), parse_text(text)
    assert np.array_equal(mine.line_kind, union.line_kind)
    theirs = {(s, e): v for s, e, v in zip(union.word_start.tolist(), union.word_end.tolist(),
                                           union.word_value.tolist())}
    for s, e, v in zip(mine.word_start.tolist(), mine.word_end.tolist(),
                       mine.word_value.tolist()):
        assert (s, e) in theirs
        assert theirs[(s, e)] == v or (v != v and theirs[(s, e)] != theirs[(s, e)])


# ---------------------------------------------------------------------------- the corpus ----
def fingerprint(path: Path) -> str:
    """What the generic grammar reads in a file: a hash of its word and line tables, or
    ``error:line:column`` (names in the corpus's own terms, so old and new code compare)."""
    try:
        prog = parse_text(path.read_bytes().decode("latin-1"), str(path))
    except NcoptError as exc:
        return f"error:{exc.line}:{exc.column}"
    value = prog.word_value
    h = hashlib.sha256()
    for arr in (prog.word_line.astype(np.int64), prog.word_letter.astype(np.int64),
                np.where(np.isnan(value), 0.0, value), np.isnan(value),
                prog.word_start.astype(np.int64), prog.word_end.astype(np.int64),
                prog.word_num_start.astype(np.int64), prog.line_kind.astype(np.int64),
                prog.line_has_expr):
        h.update(np.ascontiguousarray(arr).tobytes())
    h.update(json.dumps(sorted(prog.opaque_reason.items())).encode())
    return h.hexdigest()


@pytest.mark.corpus
@pytest.mark.skipif(not CORPUS_FILES, reason="no corpus")
@pytest.mark.parametrize("path", CORPUS_FILES, ids=lambda p: str(p.relative_to(CORPUS)))
def test_corpus_reads_as_before(path):
    """The generic grammar reads every corpus file exactly as the single grammar of
    before the dialect grammars did (fingerprints made with that grammar), and the files
    it refused (LinuxCNC's bad/ programs among them) fail at the same line and column."""
    expected = json.loads(FINGERPRINTS.read_text())
    assert fingerprint(path) == expected[str(path.relative_to(CORPUS))]


@pytest.mark.corpus
@pytest.mark.skipif(not CORPUS_FILES, reason="no corpus")
@pytest.mark.parametrize("path", [p for p in CORPUS_FILES if p.parts[-2] != "bad"
                                  and "linuxcnc" in p.parts], ids=lambda p: p.name)
def test_linuxcnc_programs_read_under_the_linuxcnc_grammar(path):
    """LinuxCNC's own programs are the real test of its grammar."""
    prog = parse_text(path.read_bytes().decode("latin-1"), str(path), dialect=LINUXCNC)
    assert prog.n_lines > 0


@pytest.mark.skipif(not CORPUS_FILES, reason="no corpus")
def test_a_fanuc_post_reads_under_the_fanuc_grammar():
    path = CORPUS / "fusion" / "chess_engraved_box.nc"
    text = path.read_bytes().decode("latin-1")
    a, b = parse_text(text, str(path), dialect=FANUC), parse_text(text, str(path))
    assert np.array_equal(a.word_start, b.word_start)
    assert np.array_equal(a.line_kind, b.line_kind)


def test_every_grammar_file_is_found_and_imports_the_core():
    for name in DIALECTS:
        path = grammar_path(f"{name}.lark")
        assert path.parent == grammar_path("core.lark").parent
        if name != GENERIC:
            assert "%import .core (" in path.read_text()
        assert {"LETTER", "SNUMBER", "WS"} <= {t.name for t in parser(name).terminals}


if __name__ == "__main__":  # regenerate only when a change of reading is intended
    FINGERPRINTS.write_text(json.dumps(
        {str(p.relative_to(CORPUS)): fingerprint(p) for p in CORPUS_FILES}, indent=0,
        sort_keys=True) + "\n")
    sys.exit(0)


@pytest.mark.parametrize("newline", ["\n", "\r\n"])
@pytest.mark.parametrize("dialect", [SINUMERIK, GENERIC])
def test_vector_words_take_the_fast_path_as_lark_reads_them(dialect, newline):
    """TRAORI programs carry A3= B3= C3= on nearly every line: the fast path reads them
    (Lark took ~1.3 ms a line), word for word as Lark does, and leaves every other use of
    '=' to Lark."""
    lines = ["G1 X1 Y2 Z3 A3=0.1 B3=-.2 C3=0.97 F1000", "X1A3=0.5", "A3 = 0.5 B3=0",
             "G1 X1 (A3=0.5)", "G1 X1 A3=R1*2", "G1 X1 A3=0.5*2", "R1=5", "A3=1 R2=3",
             "G1 XA3=0.5" if dialect == GENERIC else "G1 X1", "G1 C3=1.F2"]
    text = newline.join(lines[:8] + lines[9:]) + newline
    fast = parse_text(text, "v.mpf", dialect=dialect)
    slow = parse_text(text, "v.mpf", dialect=dialect, use_fast_path=False)
    for name in ("word_line", "word_letter", "word_value", "word_start", "word_end",
                 "word_num_start", "line_kind"):
        assert np.array_equal(getattr(fast, name), getattr(slow, name)), name
    assert words(fast)[:8] == ["G1", "X1", "Y2", "Z3", "A3=0.1", "B3=-.2", "C3=0.97", "F1000"]
    assert fast.word_letter[4:7].tolist() == [0x81, 0x82, 0x83]
