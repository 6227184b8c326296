"""Text -> :class:`~ncopt.model.Program`: every word with its character span.

The grammars in ``grammars/`` are the single definition of the syntax: one per
dialect (``fanuc.lark``, ``sinumerik.lark``, ...), each importing the common
core ``core.lark``, and ``generic.lark``, the union of them, read when no
dialect is named.  Plain word blocks (``N120 G1 X-84.512 Y-80.000 Z-2.345``),
which are nearly all of a finishing program, take a vectorised fast path whose
character classes are derived from the grammar's LETTER, SNUMBER and WS
terminals (and BLOCK_END, a block end mark such as Heidenhain's ``*``); every
other line goes through Lark.  Tests check that both give the same words on
every corpus line and on generated lines, for every grammar.

A line one dialect's grammar refuses but another reads (``R1=5`` under
``fanuc``) gives an error that names the construct and the dialects that read it.
What no grammar should be asked to read (UTF-16 files, a byte order mark,
CR-only line ends, Heidenhain conversational programs) is refused first by
:func:`ncopt.reading.refuse.check_text`.

The program runs from its opening ``%`` (after a header of blank and comment
lines, if any) to its closing one; the lines after that are read by no control
and by no grammar here (``LineKind.TRAILER``), with a warning
(:func:`unread_lines_warning`).
"""

from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path

import numpy as np
from lark import Lark, Token, Tree
from lark.exceptions import UnexpectedInput

from ncopt.reading.dialect import DIALECTS, FANUC, GENERIC, GRBL, LINUXCNC, read_unit_codes
from ncopt.runtime.errors import NcParseError, UsageError
from ncopt.runtime.memory import release_freed_memory, working_memory
from ncopt.model import VECTOR_WORD_CODES, LineKind, Program
from ncopt.reading.numtext import EXACT_DIGITS, MAX_NUMBER_CHARS, number_values, parse_numbers, run_sums
from ncopt.reading.refuse import caret_context, check_text, klartext_what, looks_like_klartext, refuse_at
from ncopt.runtime.threads import available_cpus, map_in_threads

__all__ = ["caret_context", "grammar_path", "dialect_name", "parser", "byte_classes",
           "parse_text", "read_program", "unread_lines_warning"]

# byte classes of the fast path
_SPACE, _LETTER, _DIGIT, _SIGN, _POINT, _NL, _OTHER = range(7)


def grammar_path(name: str = "generic.lark") -> Path:
    """Where a grammar lives: inside the installed package, else the source tree."""
    here = Path(__file__).resolve().parent.parent  # the ncopt package
    for folder in (here / "grammars", here.parent / "grammars"):
        if (folder / name).is_file():
            return folder / name
    raise FileNotFoundError(f"grammar {name} not found next to {here}")


def dialect_name(dialect: str | None) -> str:
    """The grammar name of a dialect: ``None`` means the generic grammar."""
    if dialect is None:
        return GENERIC
    if dialect not in DIALECTS:
        raise UsageError(f"unknown dialect {dialect!r}; use one of {', '.join(DIALECTS)}")
    return dialect


@lru_cache(maxsize=None)
def _parser(name: str) -> Lark:
    # Lark.open resolves the grammar's relative %import .core next to the file
    return Lark.open(str(grammar_path(f"{name}.lark")), parser="lalr",
                     propagate_positions=True, maybe_placeholders=False)


def parser(dialect: str | None = None) -> Lark:
    """The LALR parser of one source line in a dialect (built once per process)."""
    return _parser(dialect_name(dialect))


@lru_cache(maxsize=None)
def _fast_tables(name: str) -> tuple[np.ndarray, np.ndarray]:
    """(256,) int8 class and (256,) bool block-end mark of every byte, from the terminals."""
    terms = {t.name: re.compile(t.pattern.to_regexp()) for t in _parser(name).terminals}
    letter, number, ws = terms["LETTER"], terms["SNUMBER"], terms["WS"]
    block_end = terms.get("BLOCK_END")
    table = np.full(256, _OTHER, dtype=np.int8)
    ends = np.zeros(256, dtype=bool)
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
        ends[code] = block_end is not None and block_end.fullmatch(ch) is not None
    ends &= table == _OTHER  # a byte the fast path reads as a word is never a block end
    return table, ends


def byte_classes(dialect: str | None = None) -> np.ndarray:
    """(256,) int8 class of every byte, derived from the grammar's terminals."""
    return _fast_tables(dialect_name(dialect))[0]


_TAPE_MARK = re.compile(r"(?m)^[ \t]*(?:[Nn][0-9.]*[ \t]*)?%")
# what may stand before the opening '%': a header of blank lines, tape leader (NULs,
# DELs) and comment lines, ( ) or ';' (a CAM system's "(PROGRAM FROM FUSION)")
_BLANKS = r"[ \t\f\v\r\x00-\x08\x0e-\x1f\x7f]*"
_HEADER = re.compile(rf"(?:{_BLANKS}(?:\([^()\r\n]*\){_BLANKS})*(?:;[^\r\n]*)?\n)*{_BLANKS}")
_LEADER = re.compile(r"[\s\x00-\x08\x0e-\x1f\x7f]*")


def _trailer_start(text: str, line_start: np.ndarray, name: str, path: str) -> int:
    """First line after the closing ``%`` (controls read nothing after it).

    The first ``%`` opens the program when only a header stands before it (see
    :data:`_HEADER`), else it closes it.  Under the LinuxCNC dialect a header with a
    comment before the opening ``%`` is refused, as rs274 refuses it.
    """
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
    opening = _HEADER.fullmatch(text, 0, marks[0]) is not None
    if opening and name == LINUXCNC and _LEADER.fullmatch(text, 0, marks[0]) is None:
        line = int(np.searchsorted(line_start, marks[0], side="right"))
        raise refuse_at(path, text, marks[0], line, text.index("%", marks[0]) - marks[0] + 1,
                        "`%` after comment lines: LinuxCNC reads a '%' only as the first line "
                        "that is not blank (rs274: \"Bad character '%' used\"); move the "
                        "comments below the '%'")
    closing = marks[1] if opening and len(marks) == 2 else (None if opening else marks[0])
    if closing is None:
        return line_start.shape[0] - 1
    return int(np.searchsorted(line_start, closing, side="right"))


def unread_lines_warning(prog: Program) -> str | None:
    """``path:first-last: ...`` for the lines after the closing ``%`` that hold more than
    blanks: no control reads them, nor does ncopt (it keeps them byte for byte)."""
    trailer = np.flatnonzero(prog.line_kind == LineKind.TRAILER)
    if trailer.size == 0 or _LEADER.fullmatch(prog.text, int(prog.line_start[trailer[0]])):
        return None  # blank lines, a tape trailer of NULs or a DOS end of file (Ctrl-Z)
    filled = [i for i in trailer.tolist() if not _LEADER.fullmatch(prog.line_text(i))]
    return (f"{prog.path}:{filled[0] + 1}-{filled[-1] + 1}: after the closing '%' (line "
            f"{int(trailer[0])}): no control reads these lines, and ncopt does not either; "
            "they are kept as they are")


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
    line_start, content_end = _split_lines(raw)
    n_lines = line_start.shape[0] - 1
    classes, block_end = _fast_tables(name)
    scan, address_at = _vector_words_read_plain(text, raw, line_start, content_end, name)
    fast, blank, words = _fast_path_chunked(scan, line_start,
                                            _before_block_end(raw, line_start, content_end,
                                                              block_end), classes)
    if address_at is not None:
        words = _vector_codes(words, address_at)
    trailer = np.arange(n_lines) >= _trailer_start(text, line_start, name, path)
    if not use_fast_path:  # every line through Lark: the reference the fast path is tested against
        fast = np.zeros(n_lines, dtype=bool)
        blank = blank & False
    keep = ~trailer[words[0]] & fast[words[0]]
    if not keep.all():
        words = tuple(w[keep] for w in words)
    fast &= ~trailer
    blank &= ~trailer
    kind = np.where(blank, LineKind.BLANK, LineKind.WORDS).astype(np.int8)
    kind[trailer] = LineKind.TRAILER
    has_expr = np.zeros(n_lines, dtype=bool)
    slow = np.flatnonzero(~fast & ~blank & ~trailer)
    opaque, exprs, slow_words = {}, {}, []
    for i in slow.tolist():
        lo, hi = int(line_start[i]), int(content_end[i])
        line_kind, items = _parse_slow_line(text, lo, hi, i, path, name)
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
    prog = _assemble(path, text, line_start, kind, has_expr, words, slow_words, opaque, exprs)
    read_unit_codes(prog.word_letter, prog.word_value, name)  # Sinumerik G700: inch, as G20
    release_freed_memory()  # the byte-level temporaries of 1M lines: hundreds of MB
    return prog


# Address words whose address is more than a letter, read as words with a letter code of
# their own: the grammar's terminal and the code of each (None: by the letter, see
# VECTOR_WORD_CODES).  CR= is the radius of an arc: R's code (the R-format arc: the same
# radius, and the same sign for the arc of more than 180 degrees).
RADIUS_CODE = ord("R")
_ADDRESS_WORDS = (("VECTOR_ADDRESS", None), ("RADIUS_ADDRESS", RADIUS_CODE))


@lru_cache(maxsize=None)
def _address_patterns(name: str) -> tuple:
    """(pattern, code) of the grammar's address word terminals (``A3=``, ``CR=`` before a
    number), of those it has: see :data:`_ADDRESS_WORDS`."""
    terms = {t.name: t for t in _parser(name).terminals}
    return tuple((re.compile(terms[t].pattern.to_regexp()), code)
                 for t, code in _ADDRESS_WORDS if t in terms)


def _vector_words_read_plain(text, raw, line_start, content_end, name):
    """The bytes the fast path scans, with each address word of more than a letter read
    as a plain word: the Sinumerik vector word ``A3=0.5`` as ``A  0.5`` (its '3' and '='
    as blanks), the arc radius ``CR=5`` as ``C  5``; and (start, letter code) of each.

    The grammar's own terminals (VECTOR_ADDRESS, RADIUS_ADDRESS) find them, line by line,
    on the lines that hold an '=', where a token starts (line start, or after a character
    no name continues with); a line the fast path then takes is plain words, so every
    match is a word Lark reads the same (the fast path is tested against Lark).  TRAORI
    programs have one on nearly every line: through Lark they took 0.26-1.3 ms a line.
    """
    patterns = _address_patterns(name)
    eq = np.flatnonzero(raw == ord("=")) if patterns else np.zeros(0, np.int64)
    if eq.size == 0:
        return raw, None
    scan, found = raw.copy(), []
    for i in np.unique(np.searchsorted(line_start, eq, side="right") - 1).tolist():
        lo = int(line_start[i])
        for pattern, code in patterns:
            for m in pattern.finditer(text, lo, int(content_end[i])):
                # after a letter, digit or '_' Lark may read a longer token (X1A3= is an
                # address assignment): such lines are left to Lark
                before = text[m.start() - 1] if m.start() > lo else " "
                if before.isalnum() or before == "_":
                    continue
                scan[m.start() + 1:m.end()] = ord(" ")
                letter = text[m.start()].upper()
                found.append((m.start(), VECTOR_WORD_CODES[letter] if code is None else code))
    if not found:
        return raw, None
    found.sort()
    return scan, (np.array([f[0] for f in found], np.int64),
                  np.array([f[1] for f in found], np.uint8))


def _vector_codes(words, address_at):
    """The fast path's words with the letter codes of the address words (``A3=``,
    ``CR=``): ``address_at`` (starts sorted, codes) from :func:`_vector_words_read_plain`."""
    line, letter, value, start, end, num_start = words
    starts, codes = address_at
    k = np.minimum(np.searchsorted(starts, start), starts.size - 1)
    at = starts[k] == start
    if at.any():
        letter = letter.copy()
        letter[at] = codes[k[at]]
    return line, letter, value, start, end, num_start


def _before_block_end(raw, line_start, content_end, block_end) -> np.ndarray:
    """End of each line's content without a final block end mark (``G1 X1 *``)."""
    if not block_end.any():
        return content_end
    last = raw[np.maximum(content_end - 1, 0)]
    marked = (content_end > line_start[:-1]) & block_end[last]
    return content_end - marked


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


# Per-byte work arrays stay small; two threads hold one chunk each.  1M lines of a
# rewritten program: 65536 lines 1.8 s and +615 MB, 16384 lines 1.2 s and +420 MB.
FAST_CHUNK_LINES = 16384


def _fast_path_chunked(raw, line_start, content_end, classes):
    """:func:`_fast_path` over chunks of lines, results joined (same words, less memory).

    The chunks run in a pool of threads: the work is numpy loops over bytes, which
    release the GIL (1M lines: 1.9 s serial, 1.1-1.3 s in two threads).
    """
    n_lines = line_start.shape[0] - 1
    if n_lines <= FAST_CHUNK_LINES:
        return _fast_path(raw, line_start, content_end, classes)

    def chunk(a: int):
        b = min(a + FAST_CHUNK_LINES, n_lines)
        base = int(line_start[a])
        f, bl, w = _fast_path(raw[base:int(line_start[b])], line_start[a:b + 1] - base,
                              content_end[a:b] - base, classes)
        return f, bl, (w[0] + a, w[1], w[2], w[3] + base, w[4] + base, w[5] + base)

    with working_memory():  # each chunk's temporaries reuse the freed ones of the last
        done = map_in_threads(chunk, range(0, n_lines, FAST_CHUNK_LINES), _THREADS)
    fast, blank = np.concatenate([d[0] for d in done]), np.concatenate([d[1] for d in done])
    parts = [list(d[2]) for d in done]
    del done
    words = []
    for k in range(6):  # field by field, each chunk's part freed once joined: the peak
        words.append(np.concatenate([p[k] for p in parts]))  # holds one field twice, not six
        for p in parts:
            p[k] = None
        release_freed_memory()  # (unless a rewrite holds its memory: then it is reused)
    return fast, blank, tuple(words)


# Two threads take most of the gain; more would multiply the chunks' memory (and
# batch runs one process per job).
_THREADS = min(2, available_cpus())


def _fast_path(raw, line_start, content_end, classes):
    """Vectorised word extraction for lines of only LETTER SNUMBER pairs.

    ``classes`` is the (256,) byte class table of the grammar.  Returns
    (fast (n,) bool, blank (n,) bool, words) where words is a tuple of
    arrays (line, letter, value, start, end, num_start) for the fast lines.
    """
    n_lines = line_start.shape[0] - 1
    cls = np.take(classes, raw)  # take: 2.5x faster than classes[raw] for uint8 raw
    line_of = np.repeat(np.arange(n_lines, dtype=np.int32), np.diff(line_start))
    # the bytes after each line's content (its line end, a block end mark: a few at
    # most) read as line ends
    tail = line_start[1:] - content_end
    for k in range(int(tail.max()) if n_lines else 0):
        cls[content_end[tail > k] + k] = _NL
    bad = np.zeros(n_lines, dtype=bool)
    bad[line_of[cls == _OTHER]] = True
    idx = np.flatnonzero((cls != _SPACE) & (cls != _NL) & (cls != _OTHER))
    cc, ln = cls[idx], line_of[idx]
    is_letter = cc == _LETTER
    is_num = ~is_letter
    same_prev = np.zeros(idx.shape[0], dtype=bool)
    same_prev[1:] = ln[1:] == ln[:-1]
    has_tok = np.zeros(n_lines, dtype=bool)
    has_tok[ln[~same_prev]] = True  # the first token of each line that has one
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
    # a run's characters are consecutive among the number characters, from its start
    # to the next run's: counts per run are sums over those slices
    num_idx = np.flatnonzero(is_num)
    cc_num = cc[num_idx]
    run_at = np.flatnonzero(run_start[num_idx])
    length = np.diff(np.append(run_at, num_idx.size))
    run_last = run_at + length - 1
    is_digit = cc_num == _DIGIT
    point_at = np.flatnonzero(cc_num == _POINT)
    point_run = np.searchsorted(run_at, point_at, side="right") - 1
    digits_upto = np.cumsum(is_digit, dtype=np.int32)
    digits = run_sums(digits_upto, is_digit, run_at, run_last)
    run_first = num_idx[run_at]
    run_line = ln[run_first]
    bad_run = (digits < 1) | (length > MAX_NUMBER_CHARS)
    bad_run[point_run[1:][point_run[1:] == point_run[:-1]]] = True  # two points
    bad[run_line[bad_run]] = True
    blank = ~has_tok & ~bad
    fast = has_tok & ~bad
    keep = fast[run_line]
    num_start = idx[run_first][keep].astype(np.int64)
    num_len = length[keep]
    letter_pos = idx[run_first - 1][keep].astype(np.int64)
    letter = raw[letter_pos] & 0xDF  # upper case ASCII
    values = number_values(raw[idx[num_idx]], is_digit, digits_upto, run_at, run_last,
                           point_at, point_run)[keep]
    long = np.flatnonzero(digits[keep] > EXACT_DIGITS)
    if long.size:
        values[long] = parse_numbers(raw, num_start[long], num_len[long])
    words = (run_line[keep].astype(np.int32), letter.astype(np.uint8), values,
             letter_pos, num_start + num_len, num_start)
    return fast, blank, words


def _parse_slow_line(text: str, lo: int, hi: int, line_no: int, path: str, name: str):
    """Parse one line with Lark in the grammar ``name``. Returns (LineKind, items)."""
    src = text[lo:hi]
    try:
        tree = _parser(name).parse(src)
    except UnexpectedInput as exc:
        col = getattr(exc, "column", 1) or 1
        what = _other_dialect(src, col, name) or _describe(exc, src, name)
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


def _describe(exc: UnexpectedInput, src: str, name: str) -> str:
    col = (getattr(exc, "column", 1) or 1) - 1
    ch = src[col] if 0 <= col < len(src) else ""
    if looks_like_klartext(src):
        return f"the line is a block of {klartext_what()}"
    if "(" in src and src.count("(") != src.count(")"):
        return "unbalanced comment parentheses; close every '(' with ')' on the same line"
    inner = src.find("(", col + 1)
    if ch == "(" and 0 <= inner < src.find(")", col + 1):
        return ("a comment inside a comment: controls do not nest parentheses (LinuxCNC: "
                "\"Nested comment found\"); remove the inner ( )")
    if ch == "\r":
        return ("a carriage return (CR) inside the line: the file mixes line ends (CR alone, "
                "or CR CR LF); save it with LF or CR LF line ends")
    if src.startswith("\xef\xbb\xbf", col):
        return ("a UTF-8 byte order mark inside the file (files joined together?); delete "
                "the three bytes EF BB BF")
    if ch:
        after = " or after ;" if any(t.name == "EOL_COMMENT" for t in _parser(name).terminals) \
            else ""
        what = repr(ch) if " " <= ch <= "~" else f"byte 0x{ord(ch):02X}"
        return (f"unexpected {what}; expected a word such as X1.5, a comment in ( ){after}, "
                "or fix the line")
    return "line ends in the middle of a word or expression; complete or remove it"


# ------------------------------------------------ constructs of other dialects ----
# What a construct of the generic grammar is, by the name of its tree node or of
# the head token of an opaque node.
_CONSTRUCTS = {
    "KEYWORD": "a keyword (macro statement, cycle call or label)",
    "ADDRESS_ASSIGN": "an address assignment",
    "O_WORD": "a LinuxCNC o-word",
    "DOLLAR": "a '$' system command or variable",
    "COLON": "a ':' program or main block number",
    "assign": "a parameter assignment",
    "expr_word": "a word with a computed value",
    "vector_word": "a Sinumerik tool vector word",
    "radius_word": "a Sinumerik arc radius (CR=)",
    "named_param": "a LinuxCNC named parameter",
    "eol_comment": "a ';' comment",
    "block_end": "a Heidenhain ISO block end",
    "tape_mark": "a '%' tape mark",
}
_R_PARAMETER = re.compile(r"R[0-9]+[ \t]*=", re.I)
_SNIPPET_CHARS = 24


def _other_dialect(src: str, col: int, name: str) -> str | None:
    """Why ``src`` is refused under dialect ``name`` although another dialect reads it."""
    if name == GENERIC:
        return None
    try:
        tree = _parser(GENERIC).parse(src)
    except UnexpectedInput:
        return None  # malformed in every dialect
    found = _construct_at(tree.children[0], col - 1)
    if found is None:
        return None
    kind, start, end = found
    snippet = src[start:end].strip()
    if len(snippet) > _SNIPPET_CHARS:
        snippet = snippet[:_SNIPPET_CHARS - 3] + "..."
    what = _CONSTRUCTS[kind]
    if kind == "ADDRESS_ASSIGN" and _R_PARAMETER.match(snippet):
        what = "a Sinumerik R-parameter assignment"
    readers = [d for d in DIALECTS if d not in (name, GENERIC) and _reads(d, src, col - 1, found)]
    todo = (f"pass --dialect {readers[0]} or --dialect {GENERIC}" if len(readers) == 1 else
            f"pass --dialect {', '.join(readers)} or {GENERIC}" if readers else
            f"pass --dialect {GENERIC}")
    if kind == "eol_comment" and name == FANUC:
        return (f"`{snippet}` is {what}, which Fanuc does not have: its manuals print the "
                "end-of-block code as ';', so the text after it would be read as a block; "
                f"write the comment in ( ) or {todo}")
    if kind == "tape_mark" and name == GRBL:
        return (f"`{snippet}` is {what}, which grbl does not read (it reports the line as an "
                f"error); remove the line or {todo}")
    return f"`{snippet}` is {what}, not read under the {name} dialect; {todo}"


def _construct_at(line: Tree, index: int) -> tuple[str, int, int] | None:
    """(kind, start, end) of the innermost construct of :data:`_CONSTRUCTS` at ``index``."""
    items = [c for c in line.children if _span(c) is not None]
    at = [c for c in items if _span(c)[0] <= index < _span(c)[1]]
    after = [c for c in items if _span(c)[0] >= index]
    node = (at or after or items[-1:] or [None])[0]
    found = None
    while node is not None:
        kind = _kind(node)
        if kind is not None:
            found = (kind, *_span(node))
        inner = [c for c in getattr(node, "children", ()) if _span(c) is not None
                 and _span(c)[0] <= index < _span(c)[1]]
        node = inner[0] if inner else None
    return found


def _span(node) -> tuple[int, int] | None:
    if isinstance(node, Token):
        return (node.start_pos, node.end_pos) if node.start_pos is not None else None
    if node.meta.empty:
        return None
    return node.meta.start_pos, node.meta.end_pos


_SAME_KIND = {"MACRO_STATEMENT": "KEYWORD", "O_WORD_COMPUTED": "O_WORD"}


def _kind(node) -> str | None:
    if isinstance(node, Token):
        return None
    if node.data == "opaque":
        head = node.children[0].type
        return _SAME_KIND.get(head, head)
    return node.data if node.data in _CONSTRUCTS else None


def _reads(dialect: str, src: str, index: int, construct: tuple[str, int, int]) -> bool:
    """Whether ``dialect`` reads ``src`` with ``construct`` (kind, start, end) at ``index``.

    Also when it reads the construct as part of a larger one of its own
    (LinuxCNC's ``o[#1] call`` holds the keyword ``call``).
    """
    try:
        tree = _parser(dialect).parse(src)
    except UnexpectedInput:
        return False
    found = _construct_at(tree.children[0], index)
    if found is None:
        return False
    kind, start, end = construct
    return found[0] == kind or (found[1] <= start and found[2] >= end)


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


def read_program(path: str | Path, data: bytes | None = None, *,
                 dialect: str | None = None) -> Program:
    """Read and parse a program file (or ``data`` given for it), see :func:`parse_text`."""
    if data is None:
        data = Path(path).read_bytes()
    return parse_text(data.decode("latin-1"), str(path), dialect=dialect)
