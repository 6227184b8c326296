"""The Lark path of the parse: a line the fast path does not read whole, parsed by the
dialect's grammar into its words, expressions and opaque head, or refused with a located
error (:mod:`ncopt.reading.parseerror`)."""

from __future__ import annotations

import numpy as np
from lark import Token, Tree
from lark.exceptions import UnexpectedInput

from ncopt.model import VECTOR_WORD_CODES, LineKind
from ncopt.reading.grammar import RADIUS_CODE, lark_parser
from ncopt.reading.parseerror import describe, other_dialect
from ncopt.reading.refuse import caret_context
from ncopt.runtime.errors import NcParseError


def parse_slow_line(text: str, lo: int, hi: int, line_no: int, path: str, name: str):
    """Parse one line with Lark in the grammar ``name``. Returns (LineKind, items)."""
    src = text[lo:hi]
    try:
        tree = lark_parser(name).parse(src)
    except UnexpectedInput as exc:
        col = getattr(exc, "column", 1) or 1
        what = other_dialect(src, col, name) or describe(exc, src, name)
        raise NcParseError(what, path=path, line=line_no + 1, column=col,
                           context=caret_context(src, col)) from None
    line = tree.children[0]
    items, kind = [], LineKind.WORDS
    for child in line.children:
        if isinstance(child, Token):
            continue
        if child.data == "tape_mark":
            kind = LineKind.PERCENT
        elif child.data == "opaque":
            kind = LineKind.OPAQUE
            head = str(child.children[0]).strip()
            items.append(("opaque", head.rstrip("= \t")))
        elif child.data in ("number_word", "expr_word", "vector_word", "radius_word"):
            items.append(("word", _word_record(child, lo, line_no)))
            if child.data == "expr_word":
                items.append(("expr", None, ("word", lo + child.meta.start_pos, child.children[1])))
        elif child.data == "assign":
            items.append(("expr", None, ("assign", child.children[0], child.children[1])))
    return kind, items


def _word_record(node: Tree, offset: int, line_no: int) -> tuple:
    letter_tok = node.children[0]
    start = offset + letter_tok.start_pos
    end = offset + node.meta.end_pos
    if node.data in ("number_word", "vector_word", "radius_word"):
        num = node.children[1]
        code = (VECTOR_WORD_CODES[str(letter_tok)[0].upper()] if node.data == "vector_word"
                else RADIUS_CODE if node.data == "radius_word" else ord(str(letter_tok).upper()))
        return (line_no, code, float(num), start, end, offset + num.start_pos)
    value = node.children[1]
    vstart = value.meta.start_pos if isinstance(value, Tree) else value.start_pos
    return (line_no, ord(str(letter_tok).upper()), float("nan"), start, end, offset + vstart)


def parse_slow_lines(text: str, line_start: np.ndarray, content_end: np.ndarray,
                     slow: np.ndarray, kind: np.ndarray, path: str, name: str, progress=None):
    """Parse the lines ``slow`` (0-based) with Lark in the grammar ``name``, setting their
    ``kind`` in place; ``progress`` is called with each line's number.

    Returns (n_lines,) bool the lines with expressions, {line: head} of the opaque lines,
    {line: (parsed expression, ...)} and the word records of those lines.
    """
    has_expr = np.zeros(line_start.shape[0] - 1, dtype=bool)
    opaque, exprs, slow_words = {}, {}, []
    for i in slow.tolist():
        lo, hi = int(line_start[i]), int(content_end[i])
        line_kind, items = parse_slow_line(text, lo, hi, i, path, name)
        kind[i] = LineKind.BLANK if not items and line_kind == LineKind.WORDS else line_kind
        for item in items:
            if item[0] == "word":
                slow_words.append(item[1])
            elif item[0] == "opaque":
                opaque[i] = item[1]
        parsed = tuple(it[2] for it in items if it[0] == "expr")
        if parsed:
            exprs[i] = parsed
            has_expr[i] = True
        if progress is not None:
            progress(i)
    return has_expr, opaque, exprs, slow_words
