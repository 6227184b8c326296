"""The fast path read in chunks of lines (their offsets int32) gives the
arrays one chunk gives, dtypes included, and one chunk gives what Lark gives."""

from __future__ import annotations

import numpy as np
import pytest

import ncopt.reading.fastpath as fastpath
from ncopt.reading.fastcomments import comment_forms
from ncopt.reading.grammar import dialect_name, fast_tables
from ncopt.reading.parse import parse_text

FIELDS = ("line_start", "line_kind", "line_has_expr", "word_line", "word_letter", "word_value",
          "word_start", "word_end", "word_num_start")

LINES = ["N10 G1 X-84.512 Y-80.000 Z-2.345 F1200", "X1.5 S12000", "", "(a comment) G0 Z5",
         "G2 X1 Y2 I0.5 J-0.5 ; arc", "  ", "/N20 X2", "M3 S1500", "X1.23456789012345678",
         "G1X1Y2Z3", "#1=5", "X[#1*2]", "; a comment line"]


def _program(n: int, seed: int) -> str:
    rng = np.random.default_rng(seed)
    return "\n".join(rng.choice(LINES, n).tolist()) + "\nM30\n"


@pytest.mark.parametrize("chunk", [1, 3, 7, 64])
def test_chunks_join_to_the_whole(monkeypatch, chunk):
    text = _program(500, chunk)
    whole = parse_text(text, "p.nc")
    monkeypatch.setattr(fastpath, "FAST_CHUNK_LINES", chunk)
    parts = parse_text(text, "p.nc")
    for name in FIELDS:
        a, b = getattr(whole, name), getattr(parts, name)
        assert a.dtype == b.dtype, name
        assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), name
    assert parts.word_start.dtype == np.int32 and parts.word_line.dtype == np.int32  # < 2 GiB


def test_chunked_fast_path_is_lark(monkeypatch):
    text = _program(300, 11)
    monkeypatch.setattr(fastpath, "FAST_CHUNK_LINES", 5)
    fast, lark = parse_text(text, "p.nc"), parse_text(text, "p.nc", use_fast_path=False)
    for name in FIELDS[3:]:
        assert np.array_equal(getattr(fast, name), getattr(lark, name),
                              equal_nan=name == "word_value"), name


@pytest.mark.parametrize("chunk", [7, 16384])
def test_offsets_of_a_text_of_2_gib_or_more_are_int64(monkeypatch, chunk):
    """int32 offsets hold a text below 2 GiB; from there on the words' offsets are int64
    (the join's dtype, tested without a 2 GiB text)."""
    assert fastpath.offset_dtype(2**31 - 1) is np.int32
    assert fastpath.offset_dtype(2**31) is np.int64
    monkeypatch.setattr(fastpath, "FAST_CHUNK_LINES", chunk)
    text = _program(200, 5)
    raw = np.frombuffer(text.encode("latin-1"), dtype=np.uint8)
    line_start, content_end = fastpath.split_lines(raw)
    classes, _ = fast_tables(dialect_name(None))
    forms = comment_forms(dialect_name(None))
    words = [fastpath.joined(fastpath.fast_path_chunks(raw, line_start, content_end, classes,
                                                       forms), pos)[2]
             for pos in (np.int32, np.int64)]
    assert [w.dtype for w in words[1][3:]] == [np.dtype(np.int64)] * 3
    assert [w.dtype for w in words[0][3:]] == [np.dtype(np.int32)] * 3
    for narrow, wide in zip(words[0], words[1]):
        assert np.array_equal(narrow, wide, equal_nan=True)
