"""The fast path of the parse: plain word blocks (``N120 G1 X-84.512 Y-80.000 Z-2.345``),
nearly all of a finishing program, read by vectorised numpy work over the bytes.

Its byte classes come from the grammar's LETTER, SNUMBER and WS terminals (and
BLOCK_END), its address words (``A3=``, ``CR=``) from the grammar's own terminals
(:mod:`ncopt.reading.grammar`); a line it cannot read whole goes to Lark.  Tests check
that both give the same words on every corpus line and on generated lines.
"""

from __future__ import annotations

import numpy as np

from ncopt.model import VECTOR_WORD_CODES
from ncopt.reading.fastcomments import CommentForms, mark_comments
from ncopt.reading.grammar import (DIGIT, LETTER, NL, OTHER, POINT, SEP, SIGN, SLASH, SPACE,
                                   address_patterns)
from ncopt.reading.numtext import (EXACT_DIGITS, MAX_NUMBER_CHARS, number_values, parse_numbers,
                                   run_sums)
from ncopt.runtime.memory import release_freed_memory, working_memory
from ncopt.runtime.threads import available_cpus, map_in_threads


def split_lines(raw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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


def before_block_end(raw, line_start, content_end, block_end) -> np.ndarray:
    """End of each line's content without a final block end mark (``G1 X1 *``)."""
    if not block_end.any():
        return content_end
    last = raw[np.maximum(content_end - 1, 0)]
    marked = (content_end > line_start[:-1]) & block_end[last]
    return content_end - marked


def vector_words_read_plain(text, raw, line_start, content_end, name):
    """The bytes the fast path scans, with each address word of more than a letter read
    as a plain word: the Sinumerik vector word ``A3=0.5`` as ``A  0.5`` (its '3' and '='
    as blanks), the arc radius ``CR=5`` as ``C  5``; and (start, letter code) of each.

    The grammar's own terminals (VECTOR_ADDRESS, RADIUS_ADDRESS) find them, line by line,
    on the lines that hold an '=', where a token starts (line start, or after a character
    no name continues with); a line the fast path then takes is plain words, so every
    match is a word Lark reads the same (the fast path is tested against Lark).  TRAORI
    programs have one on nearly every line: through Lark they took 0.26-1.3 ms a line.
    """
    patterns = address_patterns(name)
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


def vector_codes(words, address_at):
    """The fast path's words with the letter codes of the address words (``A3=``,
    ``CR=``): ``address_at`` (starts sorted, codes) from :func:`vector_words_read_plain`."""
    line, letter, value, start, end, num_start = words
    starts, codes = address_at
    starts = starts.astype(start.dtype, copy=False)  # searched in the words' own dtype
    k = np.minimum(np.searchsorted(starts, start), starts.size - 1)
    at = starts[k] == start
    if at.any():
        letter = letter.copy()
        letter[at] = codes[k[at]]
    return line, letter, value, start, end, num_start


# Per-byte work arrays stay small; two threads hold one chunk each.  1M lines of a
# rewritten program: 65536 lines 1.8 s and +615 MB, 16384 lines 1.2 s and +420 MB.
FAST_CHUNK_LINES = 16384


def fast_path_chunked(raw, line_start, content_end, classes, comments: CommentForms):
    """:func:`_fast_path` over chunks of lines, results joined (same words, less memory):
    :func:`joined` :func:`fast_path_chunks`."""
    return joined(fast_path_chunks(raw, line_start, content_end, classes, comments))


def fast_path_chunks(raw, line_start, content_end, classes, comments: CommentForms) -> list:
    """:func:`_fast_path` over chunks of lines: a list of (first line, first byte, fast,
    blank, words), the words' lines and offsets from the chunk's first line and byte
    (int32 where the chunk is shorter than 2 GB: a third less memory until they are
    joined); :func:`joined` makes the program's arrays of them.  ``raw`` is not needed
    by the join: a caller that drops it first joins with its memory free.

    The chunks run in a pool of threads: the work is numpy loops over bytes, which
    release the GIL (1M lines: 1.9 s serial, 1.1-1.3 s in two threads).
    """
    n_lines = line_start.shape[0] - 1
    if n_lines <= FAST_CHUNK_LINES:
        return [(0, 0) + _fast_path(raw, line_start, content_end, classes, comments,
                                    offset_dtype(raw.shape[0]))]

    def chunk(a: int):
        b = min(a + FAST_CHUNK_LINES, n_lines)
        base, top = int(line_start[a]), int(line_start[b])
        pos = np.int32 if top - base < 2**31 else np.int64
        return (a, base) + _fast_path(raw[base:top], line_start[a:b + 1] - base,
                                      content_end[a:b] - base, classes, comments, pos)

    with working_memory():  # each chunk's temporaries reuse the freed ones of the last
        return map_in_threads(chunk, range(0, n_lines, FAST_CHUNK_LINES), _THREADS)


def offset_dtype(n_bytes: int):
    """The dtype of the words' character offsets in a text of ``n_bytes``: int32 below
    2 GiB (a third less memory for the program's words than int64), else int64."""
    return np.int32 if n_bytes < 2**31 else np.int64


def joined(chunks: list, pos=np.int64):
    """(fast, blank, words) of the program from :func:`fast_path_chunks`: the chunks'
    flags and words one after the other, lines and offsets counted from the program's
    start (words: line int32, letter uint8, value float64, start, end, number start of
    dtype ``pos``, :func:`offset_dtype` of the text).  The list is emptied as it is read."""
    if len(chunks) == 1:  # the whole program, from its start
        fast, blank, words = chunks.pop()[2:]
        return fast, blank, tuple(w if k < 3 else w.astype(pos, copy=False)
                                  for k, w in enumerate(words))
    fast = np.concatenate([c[2] for c in chunks])
    blank = np.concatenate([c[3] for c in chunks])
    parts = [[c[0], c[1]] + list(c[4]) for c in chunks]
    chunks.clear()
    total = sum(p[2].shape[0] for p in parts)
    words = []
    # field by field, each chunk's part freed
    for k, dtype in enumerate((np.int32, np.uint8, np.float64, pos, pos, pos)):
        out = np.empty(total, dtype=dtype)  # once copied: the peak holds one field twice
        at = 0
        for p in parts:
            w, n = p[k + 2], p[k + 2].shape[0]
            if k in (1, 2):  # letters and values
                out[at:at + n] = w
            else:  # lines and offsets, from the chunk's first line and byte
                np.add(w, dtype(p[0] if k == 0 else p[1]), out=out[at:at + n])
            p[k + 2] = None
            at += n
        words.append(out)
        release_freed_memory()  # (unless a rewrite holds its memory: then it is reused)
    return fast, blank, tuple(words)


# Two threads take most of the gain; more would multiply the chunks' memory (and
# batch runs one process per job).
_THREADS = min(2, available_cpus())


def _fast_path(raw, line_start, content_end, classes, comments: CommentForms, pos=np.int64):
    """Vectorised word extraction for lines of only LETTER SNUMBER pairs.

    ``classes`` is the (256,) byte class table of the grammar, ``comments`` the comments
    it reads (:mod:`ncopt.reading.fastcomments`: they separate words, hold none).  Returns
    (fast (n,) bool, blank (n,) bool, words) where words is a tuple of
    arrays (line, letter, value, start, end, num_start) for the fast lines; ``pos``: the
    dtype of the offsets (int32 for a chunk shorter than 2 GB).
    """
    n_lines = line_start.shape[0] - 1
    cls = np.take(classes, raw)  # take: 2.5x faster than classes[raw] for uint8 raw
    line_of = np.repeat(np.arange(n_lines, dtype=np.int32), np.diff(line_start))
    # the bytes after each line's content (its line end, a block end mark: a few at
    # most) read as line ends
    tail = line_start[1:] - content_end
    for k in range(int(tail.max()) if n_lines else 0):
        cls[content_end[tail > k] + k] = NL
    mark_comments(cls, raw, line_start, content_end, comments)
    bad = np.zeros(n_lines, dtype=bool)
    bad[line_of[cls == OTHER]] = True
    idx = np.flatnonzero((cls != SPACE) & (cls != NL) & (cls != OTHER))
    cc, ln = cls[idx], line_of[idx]
    is_letter = cc == LETTER
    is_sep = cc >= SEP  # a comment or the block delete mark: no word, a separator
    is_num = ~is_letter & ~is_sep
    same_prev = np.zeros(idx.shape[0], dtype=bool)
    same_prev[1:] = ln[1:] == ln[:-1]
    bad[ln[(cc == SLASH) & same_prev]] = True  # block delete only first on the line
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
    bad[ln[cont & (cc == SIGN)]] = True  # sign inside a number
    # a run's characters are consecutive among the number characters, from its start
    # to the next run's: counts per run are sums over those slices
    num_idx = np.flatnonzero(is_num)
    cc_num = cc[num_idx]
    run_at = np.flatnonzero(run_start[num_idx])
    length = np.diff(np.append(run_at, num_idx.size))
    run_last = run_at + length - 1
    is_digit = cc_num == DIGIT
    point_at = np.flatnonzero(cc_num == POINT)
    point_run = np.searchsorted(run_at, point_at, side="right") - 1
    digits_upto = np.cumsum(is_digit, dtype=np.int32)
    digits = run_sums(digits_upto, is_digit, run_at, run_last)
    run_first = num_idx[run_at]
    run_line = ln[run_first]
    # lines with a word token (a comment alone: a blank line), marked by their numbers: a
    # token on a line without a number is a letter without one, and the line is bad
    has_tok = np.zeros(n_lines, dtype=bool)
    has_tok[run_line] = True
    bad_run = (digits < 1) | (length > MAX_NUMBER_CHARS)
    bad_run[point_run[1:][point_run[1:] == point_run[:-1]]] = True  # two points
    bad[run_line[bad_run]] = True
    blank = ~has_tok & ~bad
    fast = has_tok & ~bad
    keep = fast[run_line]
    num_start = idx[run_first][keep].astype(pos)
    num_len = length[keep].astype(pos)
    letter_pos = idx[run_first - 1][keep].astype(pos)
    letter = raw[letter_pos] & 0xDF  # upper case ASCII
    values = number_values(raw[idx[num_idx]], is_digit, digits_upto, run_at, run_last,
                           point_at, point_run)[keep]
    long = np.flatnonzero(digits[keep] > EXACT_DIGITS)
    if long.size:
        values[long] = parse_numbers(raw, num_start[long], num_len[long])
    words = (run_line[keep].astype(np.int32), letter.astype(np.uint8), values,
             letter_pos, num_start + num_len, num_start)
    return fast, blank, words
