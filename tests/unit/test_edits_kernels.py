"""The vectorised helpers of the splice (ncopt.writing.edits) against their plain
numpy references: the same arrays, dtypes included."""

from __future__ import annotations

import numpy as np
import pytest

from ncopt.writing.edits import _distinct


@pytest.mark.parametrize("n,span", [(1, 1), (7, 3), (2000, 5000), (50_000, 24_389_368),
                                    (3000, 2**32 - 1), (40, 2**40)])
def test_distinct_is_numpy_unique(n, span):
    """Short ranges (the table), wide ones (the radix sort) and wider (np.unique)."""
    rng = np.random.default_rng(n)
    keys = rng.integers(0, span, n, dtype=np.int64) - span // 2
    keys[: n // 3] = keys[0]  # repeated keys, as the (S, F) pairs of a program
    got, ref = _distinct(keys), np.unique(keys, return_inverse=True)
    for a, b in zip(got, ref):
        assert a.dtype == b.dtype and a.shape == b.shape
        assert np.array_equal(a, b)


def test_distinct_of_nothing():
    keys, inverse = _distinct(np.zeros(0, dtype=np.int64))
    assert keys.size == 0 and inverse.size == 0 and inverse.dtype == np.intp


def _masked_reference(prog) -> str:
    """masked as one pass over the whole text's bytes (its first form)."""
    from ncopt.writing.edits import F_CODE, S_CODE
    sel = np.flatnonzero((prog.word_letter == S_CODE) | (prog.word_letter == F_CODE))
    if sel.size == 0:
        return prog.text
    raw = np.frombuffer(prog.text.encode("latin-1"), dtype=np.uint8)
    start, end = prog.word_start[sel], prog.word_end[sel]
    floor = np.concatenate(([0], end[:-1]))
    back = np.flatnonzero(start > floor)
    while back.size:
        back = back[(raw[start[back] - 1] == 32) | (raw[start[back] - 1] == 9)]
        start[back] -= 1
        back = back[start[back] > floor[back]]
    bounds = np.empty(2 * sel.size + 2, dtype=np.int64)
    bounds[0], bounds[-1] = 0, raw.size
    bounds[1:-1:2], bounds[2:-1:2] = start, end
    kept = np.zeros(2 * sel.size + 1, dtype=bool)
    kept[0::2] = True
    return raw[np.repeat(kept, np.diff(bounds))].tobytes().decode("latin-1")


@pytest.mark.parametrize("block", [1, 2, 3, 65536])
def test_masked_in_blocks_is_one_pass(monkeypatch, block):
    """Blocks of removals of every size give the text one pass over all its bytes gives:
    blanks and tabs before S and F words, words side by side, at the start and the end."""
    import ncopt.writing.edits as edits
    from ncopt.reading.parse import parse_text

    rng = np.random.default_rng(block)
    lines = ["S1000 F200", "G1 X1 \t S1200", "X2 F300 S1300", "", "(comment) S5", "X3",
             "  F100  ", "G1X1S2F3", "N10 G1 X-1.5 Y2 \tF250.5", "M3 S800"]
    text = "\n".join(rng.choice(lines, 400).tolist()) + "\nS9 F9"
    prog = parse_text(text)
    monkeypatch.setattr(edits, "MASK_BLOCK", block)
    assert edits.masked(prog) == _masked_reference(prog)
