"""Every real program of the shared corpus: parses, round-trips, interprets or fails located.

The LinuxCNC interpreter's own ``interp-tests/bad/*.ngc`` programs must be rejected, and its
``interp-tests/good/*.ngc`` accepted, as rs274 does.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest

from ncopt.runtime.errors import NcoptError, NcParseError
from ncopt.motion.interp import interpret
from ncopt.model import LineKind, Toolpath
from ncopt.reading.parse import parse_text
from ncopt.writing.edits import F_CODE, S_CODE, apply_edits, masked

ROOT = Path(__file__).resolve().parents[1]
CORPUS = (ROOT / "../shared/corpus").resolve()
NC_SUFFIXES = {".nc", ".ngc", ".tap", ".gcode"}
ALL = sorted(p for p in CORPUS.rglob("*") if p.suffix.lower() in NC_SUFFIXES and p.is_file()) \
    if CORPUS.is_dir() else []
BAD_DIR = CORPUS / "linuxcnc" / "interp-tests" / "bad"
GOOD_DIR = CORPUS / "linuxcnc" / "interp-tests" / "good"
BAD = [p for p in ALL if p.parent == BAD_DIR]
GOOD = [p for p in ALL if p.parent == GOOD_DIR]
PROGRAMS = [p for p in ALL if p.parent != BAD_DIR]


pytestmark = pytest.mark.corpus  # the corpus tier: every program of the shared corpus


def _id(p: Path) -> str:
    return str(p.relative_to(CORPUS))


@lru_cache(maxsize=None)
def raw(path: Path) -> bytes:
    return path.read_bytes()


@lru_cache(maxsize=None)
def parsed(path: Path):
    """The Program, or the NcoptError it raised (parsed once per session)."""
    try:
        return parse_text(raw(path).decode("latin-1"), str(path))
    except NcoptError as exc:
        return exc


def test_corpus_has_the_files_the_readme_lists():
    names = {_id(p) for p in ALL}
    for expected in ("linuxcnc/3D_Chips.ngc", "fusion/BowlTest.nc",
                     "fusion/chess_engraved_box.nc", "camotics/cameo.nc",
                     "camotics/flower_mold.nc", "camotics/bear.nc", "camotics/wave.gcode"):
        assert expected in names
    assert len(BAD) >= 20 and len(GOOD) >= 6
    assert len(ALL) >= 150


# ------------------------------------------------------------------- parsing ----
@pytest.mark.parametrize("path", PROGRAMS, ids=_id)
def test_program_parses(path):
    prog = parsed(path)
    assert not isinstance(prog, NcoptError), str(prog)


@pytest.mark.parametrize("path", PROGRAMS, ids=_id)
def test_round_trip_and_word_table_invariants(path):
    prog = parsed(path)
    if isinstance(prog, NcoptError):
        pytest.fail(str(prog))
    data = raw(path)
    text = data.decode("latin-1")
    assert prog.text == text
    assert apply_edits(text, []).encode("latin-1") == data  # byte for byte, no edits
    ls = prog.line_start
    assert ls[0] == 0 and ls[-1] == len(text) and np.all(np.diff(ls) > 0)
    assert prog.line_kind.shape == (prog.n_lines,) == prog.line_has_expr.shape
    # words: in order, inside their line's content, spans that start at the letter
    assert np.all(np.diff(prog.word_line) >= 0)
    assert np.all(prog.word_start[1:] >= prog.word_end[:-1])
    assert np.all(ls[prog.word_line] <= prog.word_start)
    assert np.all(prog.word_end <= ls[prog.word_line + 1])
    assert np.all(prog.word_start < prog.word_num_start)
    assert np.all(prog.word_num_start < prog.word_end)
    letters = np.frombuffer(data, np.uint8)[prog.word_start] & 0xDF
    assert np.array_equal(letters, prog.word_letter)
    assert set(np.unique(prog.line_kind[prog.word_line]).tolist()) <= {
        LineKind.WORDS, LineKind.OPAQUE, LineKind.PERCENT}
    finite = ~np.isnan(prog.word_value)
    assert np.all(np.isfinite(prog.word_value[finite]))
    # a NaN value is an expression: its line is marked as needing evaluation
    assert np.all(prog.line_has_expr[prog.word_line[~finite]])


@pytest.mark.parametrize("path", PROGRAMS, ids=_id)
def test_masked_text_drops_exactly_the_s_and_f_words(path):
    prog = parsed(path)
    if isinstance(prog, NcoptError):
        pytest.fail(str(prog))
    text = prog.text
    out = masked(prog)
    sf = (prog.word_letter == S_CODE) | (prog.word_letter == F_CODE)
    if not sf.any():
        assert out == text
        return
    removed = int(np.sum(prog.word_end[sf] - prog.word_start[sf]))
    assert len(text) - len(out) >= removed
    assert out.count("\n") == text.count("\n")  # never joins lines
    # what is left parses, and holds the same other words in the same order
    again = parse_text(out, str(path))
    keep = ~sf
    assert not np.any((again.word_letter == S_CODE) | (again.word_letter == F_CODE))
    assert np.array_equal(again.word_letter, prog.word_letter[keep])
    assert np.array_equal(again.word_value, prog.word_value[keep], equal_nan=True)
    assert np.array_equal(again.word_line, prog.word_line[keep])
    assert masked(again) == out  # masking is idempotent


# ---------------------------------------------------------------- interpreting ----
def _check_toolpath(tp: Toolpath, prog) -> None:
    n = tp.n
    assert tp.xyz_mm.shape == (n, 3) and np.all(np.isfinite(tp.xyz_mm))
    assert np.all(tp.seg_len_mm >= 0) and np.all(np.isfinite(tp.seg_len_mm))
    assert tp.line[0] == -1 and np.all(np.diff(tp.line[1:]) >= 0)
    moves = tp.line[1:]
    assert np.all(prog.line_kind[moves] == LineKind.WORDS)
    # straight moves between known points are as long as the distance between them
    # (a move from an unknown position has no meaningful length)
    known = tp.known[1:]
    straight = np.isin(tp.motion[1:], [0, 1]) & known
    d = np.linalg.norm(np.diff(tp.xyz_mm, axis=0), axis=1)
    assert np.allclose(tp.seg_len_mm[1:][straight], d[straight], rtol=1e-12, atol=1e-9)
    # an arc is never shorter than the chord between its ends (per source line); spiral
    # arcs (start and end radius differ within what the controls accept: 0.1 %, or
    # 0.07 mm on small inch arcs) are measured at one radius, hence the slack
    arc = np.isin(tp.motion, [2, 3]) & tp.known
    for line in np.unique(tp.line[arc])[:2000].tolist():
        rows = np.flatnonzero(tp.line == line)
        chord = np.linalg.norm(tp.xyz_mm[rows[-1]] - tp.xyz_mm[rows[0] - 1])
        assert tp.seg_len_mm[rows].sum() >= chord * 0.97 - 1e-9


@pytest.mark.parametrize("path", PROGRAMS, ids=_id)
def test_interpret_succeeds_or_fails_located(path):
    prog = parsed(path)
    if isinstance(prog, NcoptError):
        pytest.fail(str(prog))
    try:
        tp = interpret(prog)
    except NcoptError as exc:
        assert exc.path == str(path)
        assert exc.line is not None and 1 <= exc.line <= prog.n_lines, str(exc)
        assert str(exc).startswith(f"{path}:{exc.line}")
        return
    _check_toolpath(tp, prog)


@pytest.mark.parametrize("path", GOOD, ids=_id)
def test_linuxcnc_good_programs_are_accepted(path):
    interpret(parsed(path))


@pytest.mark.parametrize("path", BAD, ids=_id)
def test_linuxcnc_bad_programs_are_rejected_located(path):
    """rs274 rejects each of these (the first line states its message); so must ncopt."""
    prog = parsed(path)
    if isinstance(prog, NcoptError):
        exc = prog
        assert isinstance(exc, NcParseError)
    else:
        with pytest.raises(NcoptError) as info:
            interpret(prog)
        exc = info.value
    assert exc.path == str(path)
    assert exc.line is not None and exc.line >= 2  # line 1 states the expected error
    n_lines = raw(path).count(b"\n") + 1
    assert exc.line <= n_lines
