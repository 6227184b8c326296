"""Text -> :class:`~ncopt.model.Program`: every word with its character span.

The grammars in ``grammars/`` are the single definition of the syntax: one per
dialect (``fanuc.lark``, ``sinumerik.lark``, ...), each importing the common
core ``core.lark``, and ``generic.lark``, the union of them, read when no
dialect is named.  Plain word blocks (``N120 G1 X-84.512 Y-80.000 Z-2.345``),
which are nearly all of a finishing program, take a vectorised fast path whose
character classes are derived from the grammar's LETTER, SNUMBER and WS
terminals (and BLOCK_END, a block end mark such as Heidenhain's ``*``)
(:mod:`ncopt.reading.fastpath`); every other line goes through Lark
(:mod:`ncopt.reading.lineparse`).  Tests check that both give the same words on
every corpus line and on generated lines, for every grammar.

A line one dialect's grammar refuses but another reads (``R1=5`` under
``fanuc``) gives an error that names the construct and the dialects that read it
(:mod:`ncopt.reading.parseerror`).
What no grammar should be asked to read (UTF-16 files, a byte order mark,
CR-only line ends, Heidenhain conversational programs) is refused first by
:func:`ncopt.reading.refuse.check_text`.

The program runs from its opening ``%`` (after a header of blank and comment
lines, if any) to its closing one; the lines after that are read by no control
and by no grammar here (``LineKind.TRAILER``), with a warning
(:mod:`ncopt.reading.tapemarks`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ncopt.model import LineKind, Program
from ncopt.reading.dialect import read_unit_codes
from ncopt.reading.fastpath import (before_block_end, fast_path_chunks, joined, offset_dtype,
                                    split_lines, vector_codes, vector_words_read_plain)
from ncopt.reading.fastcomments import comment_forms
from ncopt.reading.grammar import byte_classes, dialect_name, fast_tables, grammar_path, parser
from ncopt.reading.lineparse import parse_slow_lines
from ncopt.reading.refuse import check_text
from ncopt.reading.tapemarks import trailer_start
from ncopt.runtime.memory import release_freed_memory

__all__ = ["grammar_path", "dialect_name", "parser", "byte_classes", "parse_text", "read_program"]


def parse_text(text: str, path: str = "<input>", *, dialect: str | None = None,
               use_fast_path: bool = True, progress=None) -> Program:
    """Parse a whole program.

    Parameters
    ----------
    text : str
        The file decoded as latin-1 (so offsets are byte offsets).
    path : str
        Name used in error messages.
    dialect : str or None
        One of :data:`ncopt.reading.dialect.DIALECTS`: the program is read with that
        dialect's grammar and a construct of another dialect is an error.
        ``None`` (or ``"generic"``) reads every dialect's constructs.
    use_fast_path : bool
        False sends every line through Lark (the reference the fast path is
        tested against).
    progress : callable or None
        Called with the 0-based line number of every line Lark parses.

    Raises
    ------
    NcParseError
        For the first malformed line, with line, column and a caret context;
        for a file no grammar reads (see :func:`ncopt.reading.refuse.check_text`).
    UsageError
        For an unknown dialect name.
    """
    name = dialect_name(dialect)
    data = text.encode("latin-1")
    check_text(data, text, path)
    raw = np.frombuffer(data, dtype=np.uint8)
    if raw.shape[0] == 0:
        return _empty(path, text)
    line_start, content_end = split_lines(raw)
    n_lines = line_start.shape[0] - 1
    classes, block_end = fast_tables(name)
    scan, address_at = vector_words_read_plain(text, raw, line_start, content_end, name)
    chunks = fast_path_chunks(scan, line_start,
                              before_block_end(raw, line_start, content_end, block_end),
                              classes, comment_forms(name))
    pos = offset_dtype(raw.shape[0])
    del data, raw, scan  # the text's bytes (and their copy, if any): not needed by the join
    fast, blank, words = joined(chunks, pos)
    if address_at is not None:
        words = vector_codes(words, address_at)
    trailer = np.zeros(n_lines, dtype=bool)
    trailer[trailer_start(text, line_start, name, path):] = True
    if not use_fast_path:  # every line through Lark: the reference the fast path is tested against
        fast = np.zeros(n_lines, dtype=bool)
        blank = blank & False
    if trailer.any() or not use_fast_path:  # else every word is on a fast line already
        keep = ~trailer[words[0]] & fast[words[0]]
        if not keep.all():
            words = tuple(w[keep] for w in words)
    fast &= ~trailer
    blank &= ~trailer
    kind = np.where(blank, LineKind.BLANK, LineKind.WORDS).astype(np.int8)
    kind[trailer] = LineKind.TRAILER
    slow = np.flatnonzero(~fast & ~blank & ~trailer)
    has_expr, opaque, exprs, slow_words = parse_slow_lines(text, line_start, content_end, slow,
                                                           kind, path, name, progress)
    prog = _assemble(path, text, line_start, kind, has_expr, words, slow_words, opaque, exprs)
    read_unit_codes(prog.word_letter, prog.word_value, name)  # Sinumerik G700: inch, as G20
    release_freed_memory()  # the byte-level temporaries of 1M lines: hundreds of MB
    return prog


def _empty(path: str, text: str) -> Program:
    """A program with no lines at all (an empty file)."""
    i32, i64 = np.zeros(0, np.int32), np.zeros(0, np.int64)
    return Program(path=path, text=text, line_start=np.zeros(1, np.int64),
                   line_kind=np.zeros(0, np.int8), line_has_expr=np.zeros(0, bool),
                   word_line=i32, word_letter=np.zeros(0, np.uint8),
                   word_value=np.zeros(0, np.float64), word_start=i64, word_end=i64,
                   word_num_start=i64)


def _assemble(path, text, line_start, kind, has_expr, fast_words, slow_words, opaque, exprs):
    if slow_words:
        cols = list(zip(*slow_words))
        pos = fast_words[3].dtype  # the offsets' (ncopt.reading.fastpath.offset_dtype)
        slow = (np.array(cols[0], np.int32), np.array(cols[1], np.uint8),
                np.array(cols[2], np.float64), np.array(cols[3], pos),
                np.array(cols[4], pos), np.array(cols[5], pos))
        merged = [np.concatenate((a, b)) for a, b in zip(fast_words, slow)]
        order = np.argsort(merged[3], kind="stable")
        merged = [m[order] for m in merged]
    else:
        merged = list(fast_words)
    return Program(path=path, text=text, line_start=line_start, line_kind=kind,
                   line_has_expr=has_expr, word_line=merged[0], word_letter=merged[1],
                   word_value=merged[2], word_start=merged[3], word_end=merged[4],
                   word_num_start=merged[5], opaque_reason=opaque, line_exprs=exprs)


def read_program(path: str | Path, data: bytes | None = None, *,
                 dialect: str | None = None) -> Program:
    """Read and parse a program file (or ``data`` given for it), see :func:`parse_text`."""
    if data is None:
        data = Path(path).read_bytes()
    return parse_text(data.decode("latin-1"), str(path), dialect=dialect)
