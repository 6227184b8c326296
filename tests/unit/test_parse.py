"""ncopt.reading.parse: words and their spans, opaque lines, located errors, fast path == Lark.

The fast path must agree with Lark for every grammar: the generic one and each
dialect's (tests/unit/test_dialect_grammars.py tests what each dialect reads).
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.lark import from_lark

from ncopt.reading.dialect import DIALECTS, GENERIC
from ncopt.runtime.errors import NcoptError, NcParseError, UsageError
from ncopt.model import LineKind
from ncopt.reading.parse import byte_classes, parse_text, parser

ROOT = Path(__file__).resolve().parents[2]
CORPUS = (ROOT / "../shared/corpus").resolve()
NC_SUFFIXES = {".nc", ".ngc", ".tap", ".gcode"}
CORPUS_FILES = sorted(p for p in CORPUS.rglob("*") if p.suffix.lower() in NC_SUFFIXES
                      and p.is_file()) if CORPUS.is_dir() else []

# None is the generic grammar
GRAMMARS = (None,) + tuple(d for d in DIALECTS if d != GENERIC)
SMALL_CORPUS_FILES = [p for p in CORPUS_FILES if p.stat().st_size < 100_000]

WORD_ARRAYS = ("word_line", "word_letter", "word_value", "word_start", "word_end",
               "word_num_start")
LINE_ARRAYS = ("line_start", "line_kind", "line_has_expr")


def words(prog):
    """[(letter, value, word text, value text)] of a program, in order."""
    return [(chr(c), float(v), prog.text[s:e], prog.text[n:e])
            for c, v, s, e, n in zip(prog.word_letter, prog.word_value, prog.word_start,
                                     prog.word_end, prog.word_num_start)]


def both_paths(text: str, path: str = "<t>", dialect: str | None = None):
    """Parse with the fast path and with Lark only; both must give the same result."""
    results = []
    for fast in (True, False):
        try:
            results.append(parse_text(text, path, dialect=dialect, use_fast_path=fast))
        except NcParseError as exc:
            results.append(exc)
    assert_same_parse(*results)
    return results[0]


def assert_same_parse(a, b) -> None:
    if isinstance(a, NcParseError) or isinstance(b, NcParseError):
        assert isinstance(a, NcParseError) and isinstance(b, NcParseError), (a, b)
        assert (a.line, a.column, str(a)) == (b.line, b.column, str(b))
        return
    for name in WORD_ARRAYS + LINE_ARRAYS:
        x, y = getattr(a, name), getattr(b, name)
        assert x.shape == y.shape, name
        assert x.dtype == y.dtype, name
        assert np.array_equal(x, y, equal_nan=x.dtype.kind == "f"), name
    assert a.opaque_reason == b.opaque_reason


# ------------------------------------------------------------------ numbers and words ----
@pytest.mark.parametrize("number, value", [
    ("1", 1.0), ("1.", 1.0), (".5", 0.5), ("-0.25", -0.25), ("+3", 3.0), ("-.5", -0.5),
    ("0", 0.0), ("007.250", 7.25), ("-0", 0.0), ("123456.789", 123456.789),
])
@pytest.mark.parametrize("letter", ["X", "x", "F"])
def test_number_formats(letter, number, value):
    prog = both_paths(f"{letter}{number}\n")
    assert words(prog) == [(letter.upper(), value, f"{letter}{number}", number)]
    assert prog.line_kind.tolist() == [LineKind.WORDS]
    assert not prog.line_has_expr.any()


@pytest.mark.parametrize("line, expected", [
    ("N40G90", [("N", 40.0, "N40"), ("G", 90.0, "G90")]),
    ("G1X1.Y2", [("G", 1.0, "G1"), ("X", 1.0, "X1."), ("Y", 2.0, "Y2")]),
    ("X 447.29", [("X", 447.29, "X 447.29")]),
    ("X\t-1.5 Y +2", [("X", -1.5, "X\t-1.5"), ("Y", 2.0, "Y +2")]),
    ("  g01   x-84.512y-80.z-2.345  ", [("G", 1.0, "g01"), ("X", -84.512, "x-84.512"),
                                        ("Y", -80.0, "y-80."), ("Z", -2.345, "z-2.345")]),
    ("N10 O1000", [("N", 10.0, "N10"), ("O", 1000.0, "O1000")]),
    ("O1000", [("O", 1000.0, "O1000")]),
    ("o1000 (PROGRAM NAME)", [("O", 1000.0, "o1000")]),
    ("/N10 G1 X1", [("N", 10.0, "N10"), ("G", 1.0, "G1"), ("X", 1.0, "X1")]),
])
def test_word_lines(line, expected):
    prog = both_paths(line + "\n")
    assert [w[:3] for w in words(prog)] == expected
    assert prog.line_kind.tolist() == [LineKind.WORDS]


@pytest.mark.parametrize("line, expected, kind", [
    ("G1 X1 (comment Y5) Y2 ; S3 eol", ["G1", "X1", "Y2"], LineKind.WORDS),
    ("G1X1(no blank)Y2", ["G1", "X1", "Y2"], LineKind.WORDS),
    ("(only a comment with X1 inside)", [], LineKind.BLANK),
    ("; only a comment G1 X1", [], LineKind.BLANK),
    ("(a)(b) ;c", [], LineKind.BLANK),
    ("   \t ", [], LineKind.BLANK),
    ("", [], LineKind.BLANK),
    ("G0 Z5;retract", ["G0", "Z5"], LineKind.WORDS),
])
def test_comments_are_not_words(line, expected, kind):
    prog = both_paths(line + "\n")
    assert [w[2] for w in words(prog)] == expected
    assert prog.line_kind.tolist() == [kind]


def test_tape_marks_and_trailer():
    text = "%\nO1000\nG1 X1 F100\nN5040%\nG1 X999 (after the closing mark)\nnot even G-code\n"
    prog = both_paths(text)
    assert prog.line_kind.tolist() == [LineKind.PERCENT, LineKind.WORDS, LineKind.WORDS,
                                       LineKind.PERCENT, LineKind.TRAILER, LineKind.TRAILER]
    # nothing after the closing % is read: no X999 word, and garbage is no error
    assert "X999" not in [w[2] for w in words(prog)]
    assert [w[2] for w in words(prog)] == ["O1000", "G1", "X1", "F100", "N5040"]


def test_single_percent_line_is_a_tape_mark():
    prog = both_paths("%\n")
    assert prog.line_kind.tolist() == [LineKind.PERCENT]
    assert prog.n_words == 0


# ---------------------------------------------------------------------- opaque lines ----
@pytest.mark.parametrize("line, reason", [
    ("CYCLE832(0.01,_FINISH,1)", "CYCLE832"),
    ("DEF REAL X1", "DEF"),
    ('T="NAME"', "T"),
    ('T = "BALL_D16"', "T"),
    ("R1=5", "R1"),
    ("S1=1000", "S1"),
    ("IF[#1GT5]GOTO10", "IF"),
    ("WHILE[#1LT10]DO1", "WHILE"),
    ("MSG(\"finishing X1 Y2\")", "MSG"),
    ("$P_TOOLNO=1", "$P_TOOLNO"),
])
def test_opaque_lines_have_no_words(line, reason):
    prog = both_paths(line + "\n")
    assert prog.line_kind.tolist() == [LineKind.OPAQUE]
    assert prog.n_words == 0  # DEF REAL X1 declares X1; it is not an X word
    assert prog.opaque_reason == {0: reason}


@pytest.mark.parametrize("line", ["o100 sub", "O100 SUB", "o<probe> call [1]", "o100 endsub",
                                  "o101 if [#1 GT 2]"])
def test_linuxcnc_o_word_control_lines_are_opaque(line):
    prog = both_paths(line + "\n")
    assert prog.line_kind.tolist() == [LineKind.OPAQUE]
    assert prog.n_words == 0


def test_words_before_an_opaque_tail_keep_their_spans():
    text = "N10 G1 X1 R1=5 S200\n"
    prog = both_paths(text)
    assert prog.line_kind.tolist() == [LineKind.OPAQUE]
    # the opaque part runs to the end of the line: S200 inside it is not a word
    assert [w[2] for w in words(prog)] == ["N10", "G1", "X1"]


@pytest.mark.parametrize("line", ["#1=5", "#1 = [#2 + 3]", "#<depth>=-2.5", "#[1+2]=7"])
def test_fanuc_and_linuxcnc_assignments_parse_as_assignments(line):
    prog = both_paths(line + "\n")
    assert prog.line_kind.tolist() == [LineKind.WORDS]
    assert prog.line_has_expr.tolist() == [True]
    assert [item[0] for item in prog.line_exprs[0]] == ["assign"]
    assert prog.n_words == 0


@pytest.mark.parametrize("line, word, value_text", [
    ("G1 X#1", "X#1", "#1"),
    ("G1 X[1+2]", "X[1+2]", "[1+2]"),
    ("G1 Z-[#<depth>]", "Z-[#<depth>]", "-[#<depth>]"),
    ("F[#<fscale>*225]", "F[#<fscale>*225]", "[#<fscale>*225]"),
    ("X SIN[30]", "X SIN[30]", "SIN[30]"),
])
def test_expression_words(line, word, value_text):
    prog = both_paths(line + "\n")
    w = [x for x in words(prog) if x[2] == word]
    assert len(w) == 1, words(prog)
    assert np.isnan(w[0][1])  # the value is only known after evaluation
    assert prog.line_has_expr.tolist() == [True]
    assert prog.text[int(prog.word_start[-1]) + 1:int(prog.word_end[-1])].strip() == value_text


# -------------------------------------------------------------------------- spans ----
def test_spans_on_a_realistic_block():
    text = "N120 G1 X-84.512 Y-80.000 Z-2.345 F279.\r\n"
    prog = both_paths(text)
    for letter, _, word, value in words(prog):
        assert word[0].upper() == letter and word.endswith(value)
    assert [w[2] for w in words(prog)] == ["N120", "G1", "X-84.512", "Y-80.000", "Z-2.345",
                                           "F279."]
    assert prog.line_start.tolist() == [0, len(text)]


def test_line_table_with_crlf_and_no_final_newline():
    text = "G0 X1\r\nG1 Y2\r\n\r\nZ3"
    prog = both_paths(text)
    assert prog.line_start.tolist() == [0, 7, 14, 16, len(text)]
    assert prog.word_line.tolist() == [0, 0, 1, 1, 3]
    assert [prog.line_text(i) for i in range(prog.n_lines)] == ["G0 X1", "G1 Y2", "", "Z3"]
    assert prog.newline == "\r\n"


@pytest.mark.parametrize("dialect", GRAMMARS)
@pytest.mark.parametrize("text", ["G1 X1 ; a\rb\n", "G1 X1 (a\rb)\n", "G1 X1 ; a\r\rb\r\n"])
def test_a_carriage_return_inside_a_comment_is_refused_by_both_paths(dialect, text):
    """No grammar's comment holds a lone CR: the fast path must not mask it as one."""
    result = both_paths(text, dialect=dialect)
    if ";" in text and dialect == "fanuc":  # ";" ends Fanuc's block: no comment at all
        return
    assert isinstance(result, NcParseError), (dialect, text)


# ------------------------------------------------------------------ located errors ----
@pytest.mark.parametrize("text, line, column", [
    ("G1 X1.2.3\n", 1, 8),  # ".3" is a second number after X1.2
    ("G0 X0\nG1 X 1 0\n", 2, 8),  # "0" is a number without a letter
    ("G0 X0\nG1 X1\nG1 X1 (open\n", 3, 7),  # the comment never closes
    ("%\nO1\n(ok)\nG1 X1 (a(b)\n", 4, 7),  # nested parentheses
    ("G1 X1\r\nG1 X1 Y2 *3\r\n", 2, 10),  # "*" cannot start a word
    ("\tG1 X1 Y\n", 1, 8),  # a letter without a number; a tab is one column
])
def test_malformed_lines_raise_located_errors(text, line, column):
    with pytest.raises(NcParseError) as info:
        parse_text(text, "part.nc")
    err = info.value
    assert isinstance(err, NcoptError)
    assert (err.path, err.line, err.column) == ("part.nc", line, column)
    src = text.splitlines()[line - 1]
    assert err.context == f"    {src.expandtabs(1)}\n    {' ' * (column - 1)}^"
    first = str(err).splitlines()[0]
    assert first.startswith(f"part.nc:{line}:{column}: ")
    assert "; " in first  # what is wrong; what to do
    assert str(err).splitlines()[1:] == err.context.splitlines()
    # the Lark-only path reports the same place
    with pytest.raises(NcParseError) as again:
        parse_text(text, "part.nc", use_fast_path=False)
    assert (again.value.line, again.value.column) == (line, column)


def test_error_line_counts_every_fast_line_before_it():
    body = "".join(f"N{10 * i} G1 X{i}.5 Y-{i}\n" for i in range(500))
    with pytest.raises(NcParseError) as info:
        parse_text(body + "G1 X1 Y2 Y\n" + body, "big.nc")
    assert info.value.line == 501
    assert info.value.column == 10


def test_caret_points_at_the_reported_column():
    text = "G1 X1\nN20 G1 X5 ?Y3\n"
    with pytest.raises(NcParseError) as info:
        parse_text(text)
    err = info.value
    shown, caret = err.context.splitlines()
    assert shown[caret.index("^")] == "?"
    assert err.column == text.splitlines()[1].index("?") + 1


# --------------------------------------------------- fast path == Lark: the corpus ----
@lru_cache(maxsize=None)
def _corpus_text(path: Path) -> str:
    return path.read_bytes().decode("latin-1")


@pytest.mark.corpus
def test_corpus_is_there():
    assert len(CORPUS_FILES) >= 100, CORPUS


@pytest.mark.corpus
@pytest.mark.parametrize("path", CORPUS_FILES, ids=lambda p: str(p.relative_to(CORPUS)))
def test_fast_path_equals_lark_on_corpus(path):
    both_paths(_corpus_text(path), str(path))


@pytest.mark.corpus
@pytest.mark.parametrize("dialect", GRAMMARS[1:])
@pytest.mark.parametrize("path", SMALL_CORPUS_FILES, ids=lambda p: str(p.relative_to(CORPUS)))
def test_fast_path_equals_lark_on_corpus_per_dialect(path, dialect):
    """Programs of other dialects fail: at the same line and column on both paths."""
    both_paths(_corpus_text(path), str(path), dialect)


def test_fast_path_takes_the_plain_blocks_of_a_real_program():
    """The equality above is only worth something if the fast path does the work."""
    text = _corpus_text(CORPUS / "camotics" / "flower_mold.nc")
    calls = []
    parse_text(text, progress=calls.append)  # progress is called per Lark line
    n_lines = text.count("\n")
    assert len(calls) < 0.1 * n_lines


# ------------------------------------------- fast path == Lark: generated lines ----
LATIN1_LINE = st.characters(codec="latin-1", exclude_characters="\r\n")


@lru_cache(maxsize=None)
def grammar_lines(dialect: str | None):
    """Lines generated from a grammar (built once per grammar)."""
    return from_lark(parser(dialect), start="line", alphabet=LATIN1_LINE)


@pytest.mark.slow
@pytest.mark.parametrize("dialect", GRAMMARS)
@settings(max_examples=150)
@given(data=st.data(), newline=st.sampled_from(["\n", "\r\n"]))
def test_fast_path_equals_lark_on_grammar_lines(dialect, data, newline):
    lines = data.draw(st.lists(grammar_lines(dialect), min_size=1, max_size=4))
    text = newline.join(lines) + newline
    result = both_paths(text, dialect=dialect)
    # every line the grammar generates is valid
    assert not isinstance(result, NcParseError), (text, result)


NUMBER = st.one_of(
    st.integers(-99999, 99999).map(str),
    st.decimals(-10000, 10000, places=4, allow_nan=False, allow_infinity=False).map(str),
    st.from_regex(r"[+-]?(?:[0-9]{1,6}\.?[0-9]{0,5}|\.[0-9]{1,5})", fullmatch=True),
)
BLANKS = st.sampled_from(["", "", " ", "  ", "\t", " \t"])


@st.composite
def word_lines(draw):
    """A plain word block and the exact text of each of its words."""
    parts, expected, pos = [draw(BLANKS)], [], 0
    pos = len(parts[0])
    for _ in range(draw(st.integers(1, 8))):
        letter = draw(st.sampled_from("GXYZFSNMIJKTgxyzfs"))
        inner = draw(st.sampled_from(["", "", " ", "\t"]))
        number = draw(NUMBER)
        word = f"{letter}{inner}{number}"
        expected.append((letter.upper(), float(number), word, number, pos))
        pos += len(word)
        gap = draw(BLANKS)
        parts += [word, gap]
        pos += len(gap)
    return "".join(parts), expected


@pytest.mark.slow
@pytest.mark.parametrize("dialect", GRAMMARS)
@settings(max_examples=100)
@given(st.lists(word_lines(), min_size=1, max_size=5), st.sampled_from(["\n", "\r\n"]),
       st.booleans())
def test_generated_word_lines_spans_and_values(dialect, lines, newline, final_newline):
    text = newline.join(line for line, _ in lines) + (newline if final_newline else "")
    prog = both_paths(text, dialect=dialect)
    assert not isinstance(prog, NcParseError)
    offset, got = 0, words(prog)
    expected = []
    for i, (line, exp) in enumerate(lines):
        for letter, value, word, number, pos in exp:
            expected.append((letter, value, word, number, offset + pos, i))
        offset += len(line) + len(newline)
    assert len(got) == len(expected)
    for (letter, value, word, number, start, line_no), g, s, ln in zip(
            expected, got, prog.word_start.tolist(), prog.word_line.tolist()):
        assert g[0] == letter and g[2] == word and g[3] == number
        assert g[1] == pytest.approx(value, rel=1e-15, abs=0)
        assert s == start and ln == line_no


# up to the fast path's 32 characters: 15 digits and fewer are read by integer arithmetic,
# more by the string conversion; both must be float()'s value to the last bit (-0 too)
LONG_NUMBER = st.from_regex(r"[+-]?(?:[0-9]{1,20}\.?[0-9]{0,10}|\.[0-9]{1,25})", fullmatch=True)


@pytest.mark.slow
@settings(max_examples=300)
@given(st.lists(LONG_NUMBER, min_size=1, max_size=40))
def test_fast_path_values_are_float_to_the_bit(numbers):
    text = "".join(f"X{n}\n" for n in numbers)
    prog = parse_text(text)
    assert prog.n_words == len(numbers)
    expected = np.array([float(n) for n in numbers])
    assert np.array_equal(prog.word_value.view(np.uint64), expected.view(np.uint64)), numbers


NEAR_MISS = st.text(st.sampled_from("GXSFgx0123456789.+- \t#[]=()%;/O*$:\r\x00\x7f\xa0"),
                    max_size=24)


@pytest.mark.slow
@pytest.mark.parametrize("dialect", GRAMMARS)
@settings(max_examples=300)
@given(st.lists(NEAR_MISS, min_size=1, max_size=4))
def test_fast_path_equals_lark_on_near_miss_lines(dialect, lines):
    """Lines that are almost word blocks: the fast path must refuse exactly what Lark refuses."""
    both_paths("\n".join(lines) + "\n", dialect=dialect)


@pytest.mark.parametrize("dialect", GRAMMARS)
def test_every_grammar_has_the_fast_path_byte_classes(dialect):
    """The fast path reads the same bytes as words in every grammar: they share the core."""
    assert np.array_equal(byte_classes(dialect), byte_classes(None))
    letters = [chr(c) for c in range(256) if byte_classes(dialect)[c] == 1]
    assert "".join(letters) == "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz"


@pytest.mark.parametrize("dialect", ["generic", None])
def test_generic_is_the_default_grammar(dialect):
    assert parser(dialect) is parser()
    text = "N10 G1 X1 R1=5\n#1=2\nG1 X#1 ; c\n$H\nG0 Z5 *\n"
    a, b = parse_text(text, dialect=dialect), parse_text(text)
    assert_same_parse(a, b)


def test_unknown_dialect_is_a_usage_error():
    with pytest.raises(UsageError, match="unknown dialect 'haas'; use one of sinumerik, fanuc"):
        parse_text("G1 X1\n", dialect="haas")


# ------------------------------------------ comments and block delete on the fast path ----
COMMENT_TEXT = st.text(st.sampled_from("abcXYZ019 .,:*;=#[]-+/"), max_size=12)


@st.composite
def commented_lines(draw, eol: bool):
    """A word block with ( ) comments between its words, maybe a leading block delete mark
    and, where the grammar reads them, a ';' comment at its end."""
    _, expected = draw(word_lines())
    out = []
    for tok in (w[2] for w in expected):  # each word's own text ("X 1.5" stays whole)
        out.append(tok)
        if draw(st.booleans()):
            out.append("(" + draw(COMMENT_TEXT).replace("(", "").replace(")", "") + ")")
    text = " ".join(out)
    if draw(st.booleans()):
        text = draw(st.sampled_from(["/", " /", "/ "])) + text
    if eol and draw(st.booleans()):
        text += draw(st.sampled_from([";", " ;", " ; "])) + draw(COMMENT_TEXT)
    return text


@pytest.mark.slow
@pytest.mark.parametrize("dialect", GRAMMARS)
@settings(max_examples=150)
@given(data=st.data(), newline=st.sampled_from(["\n", "\r\n"]))
def test_commented_word_lines_read_the_same_on_both_paths(dialect, data, newline):
    from ncopt.reading.fastcomments import comment_forms
    from ncopt.reading.grammar import dialect_name

    eol = comment_forms(dialect_name(dialect)).eol
    lines = data.draw(st.lists(commented_lines(eol), min_size=1, max_size=5))
    text = newline.join(lines) + newline
    prog = both_paths(text, dialect=dialect)
    assert not isinstance(prog, NcParseError), (text, prog)


@pytest.mark.parametrize("dialect", ["sinumerik", "linuxcnc", "heidenhain-iso", None])
@pytest.mark.parametrize("comment", [" ; PASS 3", " (PASS 3)", " (a) (b)"])
def test_the_fast_path_takes_commented_blocks(dialect, comment):
    """Lark reads none of a program whose every block carries a comment or a block
    delete mark (a few milliseconds a line there; microseconds here)."""
    end = " *" if dialect == "heidenhain-iso" else ""
    blocks = [f"N{10 * i} G1 X{i * 0.5:.3f} Y-{i:d}.25 F800{comment}{end}" for i in range(1, 400)]
    blocks += [f"/N{10 * i} X{i}{end}" for i in range(400, 420)]
    blocks += ["(a comment alone)", "; a comment alone" if dialect != "fanuc" else "(x)"]
    text = "\n".join(blocks) + "\n"
    calls = []
    prog = parse_text(text, dialect=dialect, progress=calls.append)
    assert calls == []
    reference = parse_text(text, dialect=dialect, use_fast_path=False)
    assert np.array_equal(prog.word_value, reference.word_value)
    assert np.array_equal(prog.word_start, reference.word_start)
    assert np.array_equal(prog.line_kind, reference.line_kind)
    assert prog.line_kind[-2:].tolist() == [LineKind.BLANK, LineKind.BLANK]


def test_comments_that_do_not_pair_up_go_to_lark():
    """'( ... ; ... )' before a ';', an unclosed '(', a stray ')': left to the grammar."""
    for line, words in (("G1 X1 (a ; b) Y2", 3), ("G1 X1 (a", None), ("G1 X1 a)", None)):
        calls = []
        try:
            prog = parse_text(line + "\n", progress=calls.append)
        except NcParseError:
            assert words is None, line
            continue
        assert calls == [0] and prog.n_words == words, line
