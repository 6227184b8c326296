"""Text -> :class:`~ncopt.model.Program`: every word with its character span.

``grammars/gcode.lark`` is the single definition of the syntax.  Plain word
blocks (``N120 G1 X-84.512 Y-80.000 Z-2.345``), which are nearly all of a
finishing program, take a vectorised fast path whose character classes are
derived from the grammar's LETTER, SNUMBER and WS terminals; every other line
goes through Lark.  Tests check that both give the same words on every corpus
line and on generated lines.
"""

from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path

import numpy as np
from lark import Lark, Token, Tree
from lark.exceptions import UnexpectedInput

from .errors import NcParseError
from .model import LineKind, Program

# byte classes of the fast path
_SPACE, _LETTER, _DIGIT, _SIGN, _POINT, _NL, _OTHER = range(7)
_MAX_NUMBER_CHARS = 32


def grammar_path(name: str = "gcode.lark") -> Path:
    """Where the grammar lives: inside the installed package, else the source tree."""
    here = Path(__file__).resolve().parent
    for folder in (here / "grammars", here.parent / "grammars"):
        if (folder / name).is_file():
            return folder / name
    raise FileNotFoundError(f"grammar {name} not found next to {here}")


@lru_cache(maxsize=None)
def parser() -> Lark:
    """The LALR parser of one source line (built once per process)."""
    return Lark(grammar_path().read_text(encoding="utf-8"), parser="lalr",
                propagate_positions=True, maybe_placeholders=False)


@lru_cache(maxsize=None)
def byte_classes() -> np.ndarray:
    """(256,) int8 class of every byte, derived from the grammar's terminals."""
    terms = {t.name: re.compile(t.pattern.to_regexp()) for t in parser().terminals}
    letter, number, ws = terms["LETTER"], terms["SNUMBER"], terms["WS"]
    table = np.full(256, _OTHER, dtype=np.int8)
    for code in range(256):
        ch = chr(code)
        if ws.fullmatch(ch):
            table[code] = _SPACE
        elif letter.fullmatch(ch):
            table[code] = _LETTER
        elif number.fullmatch(ch):
            table[code] = _DIGIT
        elif number.fullmatch("1" + ch) and number.fullmatch(ch + "1"):
            table[code] = _POINT
        elif number.fullmatch(ch + "1"):
            table[code] = _SIGN
    return table


_TAPE_MARK = re.compile(r"(?m)^[ \t]*(?:[Nn][0-9.]*[ \t]*)?%")


def _trailer_start(text: str, line_start: np.ndarray) -> int:
    """First line after the closing ``%`` (controls read nothing after it)."""
    marks = []
    pos = text.find("%")
    while pos >= 0 and len(marks) < 2:  # '%' is rare: look only where it stands
        bol = text.rfind("\n", 0, pos) + 1
        m = _TAPE_MARK.match(text, bol)
        if m and m.end() == pos + 1:
            marks.append(bol)
        pos = text.find("%", pos + 1)
    if not marks:
        return line_start.shape[0] - 1
    opening = text[: marks[0]].strip() == ""
    closing = marks[1] if opening and len(marks) == 2 else (None if opening else marks[0])
    if closing is None:
        return line_start.shape[0] - 1
    return int(np.searchsorted(line_start, closing, side="right"))


def parse_text(text: str, path: str = "<input>", *, use_fast_path: bool = True,
               progress=None) -> Program:
    """Parse a whole program.

    Parameters
    ----------
    text : str
        The file decoded as latin-1 (so offsets are byte offsets).
    path : str
        Name used in error messages.

    Raises
    ------
    NcParseError
        For the first malformed line, with line, column and a caret context.
    """
    raw = np.frombuffer(text.encode("latin-1"), dtype=np.uint8)
    if raw.shape[0] == 0:
        return _empty(path, text)
    line_start, content_end = _split_lines(raw)
    n_lines = line_start.shape[0] - 1
    fast, blank, words = _fast_path_chunked(raw, line_start, content_end)
    trailer = np.arange(n_lines) >= _trailer_start(text, line_start)
    if not use_fast_path:  # every line through Lark: the reference the fast path is tested against
        fast = np.zeros(n_lines, dtype=bool)
        blank = blank & False
    words = tuple(w[~trailer[words[0]] & fast[words[0]]] for w in words)
    fast &= ~trailer
    blank &= ~trailer
    kind = np.where(blank, LineKind.BLANK, LineKind.WORDS).astype(np.int8)
    kind[trailer] = LineKind.TRAILER
    has_expr = np.zeros(n_lines, dtype=bool)
    slow = np.flatnonzero(~fast & ~blank & ~trailer)
    opaque, exprs, slow_words = {}, {}, []
    for i in slow.tolist():
        lo, hi = int(line_start[i]), int(content_end[i])
        line_kind, items = _parse_slow_line(text, lo, hi, i, path)
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
    return _assemble(path, text, line_start, kind, has_expr, words, slow_words, opaque, exprs)


def _empty(path: str, text: str) -> Program:
    """A program with no lines at all (an empty file)."""
    i32, i64 = np.zeros(0, np.int32), np.zeros(0, np.int64)
    return Program(path=path, text=text, line_start=np.zeros(1, np.int64),
                   line_kind=np.zeros(0, np.int8), line_has_expr=np.zeros(0, bool),
                   word_line=i32, word_letter=np.zeros(0, np.uint8),
                   word_value=np.zeros(0, np.float64), word_start=i64, word_end=i64,
                   word_num_start=i64)


def _split_lines(raw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Line starts (n+1,) and the end of each line's content before \\r\\n or \\n."""
    nl = np.flatnonzero(raw == 10)
    starts = np.concatenate(([0], nl + 1)).astype(np.int64)
    if starts[-1] != raw.shape[0] or raw.shape[0] == 0:
        starts = np.concatenate((starts, [raw.shape[0]]))
    ends = starts[1:].copy()
    n = ends.shape[0]
    if n == 0:
        return np.zeros(1, np.int64), np.zeros(0, np.int64)
    drop = (ends > starts[:-1]) & (raw[np.maximum(ends - 1, 0)] == 10)
    ends[drop] -= 1
    cr = (ends > starts[:-1]) & (raw[np.maximum(ends - 1, 0)] == 13) & drop
    ends[cr] -= 1
    return starts, ends


FAST_CHUNK_LINES = 65536  # per-byte work arrays stay small (tens of MB, not GB)


def _fast_path_chunked(raw, line_start, content_end):
    """:func:`_fast_path` over chunks of lines, results joined (same words, less memory)."""
    n_lines = line_start.shape[0] - 1
    if n_lines <= FAST_CHUNK_LINES:
        return _fast_path(raw, line_start, content_end)
    fast, blank, parts = [], [], []
    for a in range(0, n_lines, FAST_CHUNK_LINES):
        b = min(a + FAST_CHUNK_LINES, n_lines)
        base = int(line_start[a])
        f, bl, w = _fast_path(raw[base:int(line_start[b])], line_start[a:b + 1] - base,
                              content_end[a:b] - base)
        fast.append(f)
        blank.append(bl)
        parts.append((w[0] + a, w[1], w[2], w[3] + base, w[4] + base, w[5] + base))
    words = tuple(np.concatenate([p[k] for p in parts]) for k in range(6))
    return np.concatenate(fast), np.concatenate(blank), words


def _fast_path(raw, line_start, content_end):
    """Vectorised word extraction for lines of only LETTER SNUMBER pairs.

    Returns (fast (n,) bool, blank (n,) bool, words) where words is a tuple of
    arrays (line, letter, value, start, end, num_start) for the fast lines.
    """
    n_lines = line_start.shape[0] - 1
    cls = byte_classes()[raw]
    line_of = np.repeat(np.arange(n_lines, dtype=np.int32), np.diff(line_start))
    in_content = np.arange(raw.shape[0]) < np.repeat(content_end, np.diff(line_start))
    cls = np.where(in_content, cls, _NL)
    bad = np.zeros(n_lines, dtype=bool)
    bad[line_of[cls == _OTHER]] = True
    idx = np.flatnonzero((cls != _SPACE) & (cls != _NL) & (cls != _OTHER))
    cc, ln = cls[idx], line_of[idx]
    has_tok = np.zeros(n_lines, dtype=bool)
    has_tok[ln] = True
    is_letter = cc == _LETTER
    is_num = ~is_letter
    same_prev = np.zeros(idx.shape[0], dtype=bool)
    same_prev[1:] = ln[1:] == ln[:-1]
    prev_num = np.zeros_like(same_prev)
    prev_num[1:] = is_num[:-1]
    run_start = is_num & ~(same_prev & prev_num)
    cont = is_num & ~run_start
    gap = np.zeros_like(same_prev)
    gap[1:] = (idx[1:] - idx[:-1]) != 1
    bad[ln[cont & gap]] = True  # "1 0": two numbers, the grammar rejects it
    prev_letter = np.zeros_like(same_prev)
    prev_letter[1:] = is_letter[:-1]
    bad[ln[run_start & ~(same_prev & prev_letter)]] = True  # number without letter
    next_start = np.zeros_like(same_prev)
    next_start[:-1] = run_start[1:] & same_prev[1:]
    bad[ln[is_letter & ~next_start]] = True  # letter without number
    bad[ln[cont & (cc == _SIGN)]] = True  # sign inside a number
    run_id = np.cumsum(run_start) - 1
    n_runs = int(run_start.sum())
    num_idx = np.flatnonzero(is_num)
    rid = run_id[num_idx]
    points = np.bincount(rid, weights=(cc[num_idx] == _POINT), minlength=n_runs)
    digits = np.bincount(rid, weights=(cc[num_idx] == _DIGIT), minlength=n_runs)
    length = np.bincount(rid, minlength=n_runs)
    run_first = np.flatnonzero(run_start)
    run_line = ln[run_first]
    bad_run = (points > 1) | (digits < 1) | (length > _MAX_NUMBER_CHARS)
    bad[run_line[bad_run]] = True
    blank = ~has_tok & ~bad
    fast = has_tok & ~bad
    keep = fast[run_line]
    num_start = idx[run_first][keep].astype(np.int64)
    num_len = length[keep]
    letter_pos = idx[run_first - 1][keep].astype(np.int64)
    letter = raw[letter_pos] & 0xDF  # upper case ASCII
    values = _parse_numbers(raw, num_start, num_len)
    words = (run_line[keep].astype(np.int32), letter.astype(np.uint8), values,
             letter_pos, num_start + num_len, num_start)
    return fast, blank, words


def _parse_numbers(raw, start, length) -> np.ndarray:
    """Float values of number texts ``raw[start:start+length]`` (vectorised)."""
    if start.shape[0] == 0:
        return np.zeros(0, dtype=np.float64)
    width = int(length.max())
    cols = np.arange(width)
    pos = start[:, None] + cols[None, :]
    chars = np.where(cols[None, :] < length[:, None], raw[np.minimum(pos, raw.shape[0] - 1)], 32)
    return chars.astype(np.uint8).view(f"S{width}").ravel().astype(np.float64)


def _parse_slow_line(text: str, lo: int, hi: int, line_no: int, path: str):
    """Parse one line with Lark. Returns (LineKind, items)."""
    src = text[lo:hi]
    try:
        tree = parser().parse(src)
    except UnexpectedInput as exc:
        col = getattr(exc, "column", 1) or 1
        raise NcParseError(_describe(exc, src), path=path, line=line_no + 1, column=col,
                           context=_caret(src, col)) from None
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
        elif child.data in ("number_word", "expr_word"):
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
    if node.data == "number_word":
        num = node.children[1]
        return (line_no, ord(str(letter_tok).upper()), float(num), start, end, offset + num.start_pos)
    value = node.children[1]
    vstart = value.meta.start_pos if isinstance(value, Tree) else value.start_pos
    return (line_no, ord(str(letter_tok).upper()), float("nan"), start, end, offset + vstart)


def _describe(exc: UnexpectedInput, src: str) -> str:
    col = (getattr(exc, "column", 1) or 1) - 1
    ch = src[col] if 0 <= col < len(src) else ""
    if "(" in src and src.count("(") != src.count(")"):
        return "unbalanced comment parentheses; close every '(' with ')' on the same line"
    if ch:
        return (f"unexpected {ch!r}; expected a word such as X1.5, a comment in ( ) or after ;, "
                "or fix the line")
    return "line ends in the middle of a word or expression; complete or remove it"


def _caret(src: str, col: int) -> str:
    shown = src.expandtabs(1)
    return f"    {shown}\n    {' ' * max(col - 1, 0)}^"


def _assemble(path, text, line_start, kind, has_expr, fast_words, slow_words, opaque, exprs):
    if slow_words:
        cols = list(zip(*slow_words))
        slow = (np.array(cols[0], np.int32), np.array(cols[1], np.uint8),
                np.array(cols[2], np.float64), np.array(cols[3], np.int64),
                np.array(cols[4], np.int64), np.array(cols[5], np.int64))
        merged = [np.concatenate((a, b)) for a, b in zip(fast_words, slow)]
        order = np.argsort(merged[3], kind="stable")
        merged = [m[order] for m in merged]
    else:
        merged = list(fast_words)
    return Program(path=path, text=text, line_start=line_start, line_kind=kind,
                   line_has_expr=has_expr, word_line=merged[0], word_letter=merged[1],
                   word_value=merged[2], word_start=merged[3], word_end=merged[4],
                   word_num_start=merged[5], opaque_reason=opaque, line_exprs=exprs)


def read_program(path: str | Path, data: bytes | None = None) -> Program:
    """Read and parse a program file (or ``data`` given for it)."""
    if data is None:
        data = Path(path).read_bytes()
    return parse_text(data.decode("latin-1"), str(path))
