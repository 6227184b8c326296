"""Comments on the fast path: ``N120 G1 X-84.512 ; PASS 3``, ``G1 X1 (pt) Y2``, ``/N10 X1``.

A comment holds no word, so a line with comments gives the words the same line gives
without them, as long as each comment stands where the grammar lets one stand.  Which
comments a dialect has comes from its grammar's terminals: ``COMMENT`` (``( )``, no ``(``
inside) in every grammar, ``EOL_COMMENT`` (``;`` to the end of the line) where the grammar
uses it (not Fanuc's, where ``;`` ends a block), ``SLASH`` (block delete) first on a line.

:func:`mark_comments` rewrites the byte classes of one chunk of lines: the first byte of a
comment becomes ``SEP`` (it separates tokens: a letter before it or a number after it is
not a word, as in the grammar), the rest blanks; a leading ``/`` becomes ``SLASH``.  A line
whose parentheses do not pair up before its first ``;`` is left as it is (its ``(`` ``)``
stay OTHER, so Lark reads it).  The fast path is tested against Lark per grammar
(tests/unit/test_parse.py): comments, near misses and generated lines.
"""

from __future__ import annotations

import re
from functools import lru_cache
from typing import NamedTuple

import numpy as np

from ncopt.reading.grammar import SEP, SLASH, SPACE, lark_parser


class CommentForms(NamedTuple):
    """The comments a grammar reads: ``( )`` and ``;`` to the end of the line."""

    paren: bool
    eol: bool


@lru_cache(maxsize=None)
def comment_forms(name: str) -> CommentForms:
    """What the grammar ``name`` reads as comments, checked against its own terminals."""
    terms = {t.name: re.compile(t.pattern.to_regexp()) for t in lark_parser(name).terminals}
    paren, eol = terms.get("COMMENT"), terms.get("EOL_COMMENT")
    paren_ok = (paren is not None and paren.fullmatch("(a;b *)") is not None
                and paren.fullmatch("(a(b)") is None and paren.fullmatch("(a)b)") is None)
    eol_ok = eol is not None and eol.fullmatch("; a (b) * ;") is not None
    return CommentForms(paren_ok, eol_ok)


def _first_per_line(pos: np.ndarray, line_start: np.ndarray, content_end: np.ndarray):
    """(n_lines,) offset of the first of the sorted ``pos`` in each line's content, else
    the content end."""
    first = content_end.copy()
    if pos.size:
        line = np.searchsorted(line_start, pos, side="right") - 1
        inside = pos < content_end[line]
        line, pos = line[inside], pos[inside]
        lead = np.ones(line.size, dtype=bool)
        lead[1:] = line[1:] != line[:-1]
        first[line[lead]] = pos[lead]
    return first


def _paired(raw, line_start, first_semi, n_lines):
    """(opens, closes, unpaired (n_lines,) bool): the ``( )`` pairs before each line's
    first ``;``, and the lines where they do not alternate ( ) ( ) ... properly."""
    opens, closes = np.flatnonzero(raw == 40), np.flatnonzero(raw == 41)
    unpaired = np.zeros(n_lines, dtype=bool)
    if opens.size == 0 and closes.size == 0:
        return opens, closes, unpaired
    pos = np.concatenate((opens, closes))
    kind = np.concatenate((np.ones(opens.size, np.int8), np.full(closes.size, -1, np.int8)))
    order = np.argsort(pos, kind="stable")
    pos, kind = pos[order], kind[order]
    line = np.searchsorted(line_start, pos, side="right") - 1
    before = pos < first_semi[line]
    pos, kind, line = pos[before], kind[before], line[before]
    same_prev = np.zeros(pos.size, dtype=bool)
    same_prev[1:] = line[1:] == line[:-1]
    last = np.ones(pos.size, dtype=bool)
    last[:-1] = line[:-1] != line[1:]
    prev = np.zeros(pos.size, dtype=np.int8)
    prev[1:] = kind[:-1]
    # an open after nothing or after a close; a close right after an open; no open last
    ok = np.where(kind == 1, ~same_prev | (prev == -1), same_prev & (prev == 1))
    ok &= ~(last & (kind == 1))
    unpaired[line[~ok]] = True
    good = ~unpaired[line]
    return pos[good & (kind == 1)], pos[good & (kind == -1)], unpaired


def mark_comments(cls: np.ndarray, raw: np.ndarray, line_start: np.ndarray,
                  content_end: np.ndarray, forms: CommentForms) -> None:
    """Rewrite ``cls`` (the byte classes of ``raw``, in place) for the comments and block
    delete marks of the lines (``line_start`` (n+1,), ``content_end`` (n,) byte offsets)."""
    n_lines = line_start.shape[0] - 1
    if n_lines == 0:
        return
    _leading_slash(cls, raw, line_start, content_end)
    if not (forms.paren or forms.eol):
        return
    semis = np.flatnonzero(raw == 59) if forms.eol else np.zeros(0, np.int64)
    first_semi = _first_per_line(semis, line_start, content_end)
    if forms.paren:
        opens, closes, unpaired = _paired(raw, line_start, first_semi, n_lines)
    else:
        opens = closes = np.zeros(0, np.int64)
        unpaired = np.zeros(n_lines, dtype=bool)
    eol_lines = np.flatnonzero((first_semi < content_end) & ~unpaired)
    starts = np.concatenate((opens, first_semi[eol_lines]))
    if starts.size == 0:
        return
    ends = np.concatenate((closes + 1, content_end[eol_lines]))
    depth = np.zeros(raw.shape[0] + 1, dtype=np.int32)
    np.add.at(depth, starts, 1)
    np.add.at(depth, ends, -1)
    inside = np.cumsum(depth[:-1], dtype=np.int32) > 0
    # a carriage return inside a comment is no comment character in any grammar (COMMENT,
    # EOL_COMMENT stop at \r): it keeps its class, and Lark reads (and refuses) the line
    inside &= raw != 13
    cls[inside] = SPACE
    cls[starts] = SEP


def _leading_slash(cls, raw, line_start, content_end) -> None:
    """A ``/`` first on its line (after blanks) is the block delete mark: SLASH."""
    slashes = np.flatnonzero(raw == 47)
    if slashes.size == 0:
        return
    line = np.searchsorted(line_start, slashes, side="right") - 1
    inside = slashes < content_end[line]
    slashes, start = slashes[inside], line_start[line[inside]]
    first = slashes == start
    for k in np.flatnonzero(~first).tolist():  # blanks before it: rare, looked at one by one
        first[k] = bool(np.all(cls[start[k]:slashes[k]] == SPACE))
    cls[slashes[first]] = SLASH
