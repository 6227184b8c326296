"""The fast path read in chunks of lines (their offsets int32 until joined) gives the
arrays one chunk gives, dtypes included, and one chunk gives what Lark gives."""

from __future__ import annotations

import numpy as np
import pytest

import ncopt.reading.fastpath as fastpath
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
    assert parts.word_start.dtype == np.int64 and parts.word_line.dtype == np.int32


def test_chunked_fast_path_is_lark(monkeypatch):
    text = _program(300, 11)
    monkeypatch.setattr(fastpath, "FAST_CHUNK_LINES", 5)
    fast, lark = parse_text(text, "p.nc"), parse_text(text, "p.nc", use_fast_path=False)
    for name in FIELDS[3:]:
        assert np.array_equal(getattr(fast, name), getattr(lark, name),
                              equal_nan=name == "word_value"), name
