"""Plan -> edits -> new text, spliced into the original.

Splice, never re-print: every change is an :class:`~ncopt.model.Edit` of one
S or F word (or an appended word), applied from the end backwards.  With no
edits the output is the input, byte for byte.
"""

from __future__ import annotations

import math
import re
from collections import Counter
from dataclasses import dataclass

import numpy as np

from ncopt.runtime.errors import VerificationError
from ncopt.runtime.memory import release_freed_memory
from ncopt.model import Edit, LineKind, Program

S_CODE, F_CODE = ord("S"), ord("F")


@dataclass(frozen=True, eq=False)
class Edits:
    """Many edits as columns (a rewrite makes ~1M; one object each would cost seconds).

    start, end : (k,) int64 character offsets; text : k replacement strings;
    s_words, f_words : how many S and F words the edits write (an appended
    ``" S1500 F300"`` writes one of each).
    """

    start: np.ndarray
    end: np.ndarray
    text: list
    s_words: int = 0
    f_words: int = 0

    @staticmethod
    def of(edits=(), s_words: int = 0, f_words: int = 0) -> "Edits":
        """From single :class:`Edit` s (or ``(start, end, text)`` tuples)."""
        edits = list(edits)
        return Edits(np.array([e[0] for e in edits], dtype=np.int64),
                     np.array([e[1] for e in edits], dtype=np.int64),
                     [e[2] for e in edits], s_words, f_words)

    def __len__(self) -> int:
        return len(self.text)

    def __getitem__(self, i: int) -> Edit:
        return Edit(int(self.start[i]), int(self.end[i]), self.text[i])

    def __iter__(self):
        return map(Edit, self.start.tolist(), self.end.tolist(), self.text)

    def __add__(self, other) -> "Edits":
        if not isinstance(other, Edits):
            other = Edits.of(other)
        return Edits(np.concatenate((self.start, other.start)),
                     np.concatenate((self.end, other.end)), self.text + other.text,
                     self.s_words + other.s_words, self.f_words + other.f_words)


@dataclass(frozen=True)
class WordStyle:
    """How the program writes a number: decimals, trailing point, separator."""

    decimals: int = 0
    trailing_point: bool = False
    separator: str = " "
    s_before_f: bool = True

    def format(self, value: float) -> str:
        return self.format_all([value])[0]

    def format_all(self, values) -> list[str]:
        """Many numbers at once (a rewrite writes ~1M)."""
        distinct, code = self.format_distinct(values)
        return np.array(distinct, dtype=object)[code].tolist()

    def format_distinct(self, values) -> tuple[list[str], np.ndarray]:
        """(texts, code): each distinct text once, and the index of each value's text.

        A rewrite writes ~1M numbers but a few thousand distinct ones: each is
        formatted once.  Values are told apart by what is formatted (the rounded
        integer; else the float's bits, so -0.0 and 0.0 stay apart)."""
        values = np.asarray(values, float)
        if self.decimals == 0:
            dot = "." if self.trailing_point else ""
            distinct, code = _distinct(np.round(values).astype(np.int64))
            return [f"{v}{dot}" for v in distinct.tolist()], code
        spec = f".{self.decimals}f"
        distinct, code = _distinct(values.view(np.int64))
        return [format(v, spec) for v in distinct.view(np.float64).tolist()], code

    def quantize_down(self, value: float) -> float:
        """Largest representable value <= value (so fz never exceeds its target)."""
        scale = 10.0 ** self.decimals
        return math.floor(value * scale + 1e-9) / scale


def _distinct(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """np.unique(keys, return_inverse=True), by a table where the keys span a short
    range (an S or F value: no sort), else by a radix sort where they span less than
    2**32 (an (S, F) pair of :func:`_insertions`: 800k keys over 24M values took 0.17 s
    through np.unique's comparison sort, 0.03 s so)."""
    if keys.size == 0:
        return keys, np.zeros(0, dtype=np.intp)
    lo, hi = int(keys.min()), int(keys.max())
    if hi - lo > 4 * keys.size + 1024:
        if hi - lo >= 1 << 32 or keys.dtype.kind not in "iu":
            return np.unique(keys, return_inverse=True)
        return _distinct_radix(keys, lo)
    present = np.zeros(hi - lo + 1, dtype=bool)
    present[keys - lo] = True
    rank = np.cumsum(present, dtype=np.intp) - 1
    return np.flatnonzero(present) + lo, rank[keys - lo]


def _distinct_radix(keys: np.ndarray, lo: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_distinct` of integer ``keys`` whose range from their minimum ``lo`` fits in
    32 bits: sorted by their low 16 bits, then stably by their high 16 (numpy's stable
    sort of 16-bit integers is a radix sort, linear in the keys)."""
    rel = (keys - lo).astype(np.uint32)
    order = np.argsort((rel & 0xFFFF).astype(np.uint16), kind="stable")
    order = order[np.argsort((rel[order] >> 16).astype(np.uint16), kind="stable")]
    ordered = keys[order]
    first = np.empty(ordered.size, dtype=bool)
    first[0] = True
    np.not_equal(ordered[1:], ordered[:-1], out=first[1:])
    inverse = np.empty(keys.size, dtype=np.intp)
    inverse[order] = np.cumsum(first, dtype=np.intp) - 1
    return ordered[first], inverse


_NUM = re.compile(r"[+-]?(\d*)(?:\.(\d*))?$")


def detect_style(prog: Program, letter: int, default_decimals: int = 0) -> WordStyle:
    """The most common way the program writes ``letter`` words, and its separator."""
    sel = np.flatnonzero(prog.word_letter == letter)[:2000]
    styles = Counter()
    for w in sel.tolist():
        text = prog.text[prog.word_num_start[w]:prog.word_end[w]]
        m = _NUM.match(text.strip())
        if not m:
            continue
        frac = m.group(2)
        styles[(len(frac) if frac else 0, frac == "")] += 1
    decimals, trailing = styles.most_common(1)[0][0] if styles else (default_decimals, False)
    return WordStyle(decimals=decimals, trailing_point=trailing, separator=_separator(prog),
                     s_before_f=_s_before_f(prog))


def _separator(prog: Program) -> str:
    """' ' if the program separates words by blanks, '' for ``N40G90X1.`` style."""
    n = min(prog.n_words, 5000)
    line, starts, ends = prog.word_line[:n], prog.word_start[:n], prog.word_end[:n]
    same = line[1:] == line[:-1]
    if not same.any():
        return " "
    gaps = starts[1:][same] - ends[:-1][same]
    return " " if np.mean(gaps > 0) >= 0.5 else ""


def _s_before_f(prog: Program) -> bool:
    s_lines = prog.word_line[prog.word_letter == S_CODE]
    f_lines = prog.word_line[prog.word_letter == F_CODE]
    both = np.intersect1d(s_lines, f_lines)[:100]
    if both.size == 0:
        return True
    votes = 0
    for line in both.tolist():
        sel = prog.word_line == line
        s_pos = prog.word_start[sel & (prog.word_letter == S_CODE)][0]
        f_pos = prog.word_start[sel & (prog.word_letter == F_CODE)][0]
        votes += 1 if s_pos < f_pos else -1
    return votes >= 0


@dataclass(frozen=True)
class Targets:
    """What the rewritten program must have in force at each block.

    line : (nb,) int, source line of each moving block, increasing
    s_value : (nb,) float, spindle speed to be in force (NaN: don't care)
    f_value : (nb,) float, feed in program units to be in force (NaN: don't care)
    """

    line: np.ndarray
    s_value: np.ndarray
    f_value: np.ndarray


def plan_edits(prog: Program, targets: Targets, s_style: WordStyle,
               f_style: WordStyle, editable: np.ndarray | None = None,
               f_kept: np.ndarray | None = None) -> Edits:
    """Edits that make S and F in force equal the targets, word by word.

    ``editable`` (n_lines,) bool: the lines whose words may change or get new ones
    (default: every word line).  A target on a line that may not be edited is met by a
    word on the last editable line before it; where there is none, VerificationError.
    ``f_kept`` (n_lines,) bool: lines whose own F word is the program's and stays (an F
    on a rapid, ``G0 Z5 F4800``): it holds its value, the feed move after it gets its
    own F where it needs another, and the line takes no second F.
    """
    if editable is None:
        editable = prog.line_kind == LineKind.WORDS
    editable = editable & (prog.line_kind == LineKind.WORDS)
    edits = Edits.of()
    appended = {}
    for code, values, style in ((S_CODE, targets.s_value, s_style),
                                (F_CODE, targets.f_value, f_style)):
        kept = np.zeros(prog.n_lines, dtype=bool)
        if code == F_CODE and f_kept is not None:
            kept[prog.word_line[prog.word_letter == code]] = True  # lines with an F word
            kept &= f_kept
        edits += _replace_words(prog, code, targets.line, values, style, editable & ~kept)
        appended[code] = _append_words(prog, code, targets.line, values, style, editable,
                                       kept)
    return edits + _insertions(prog, appended, s_style)


def _consumers(line: np.ndarray, values: np.ndarray):
    use = ~np.isnan(values)
    return line[use], values[use]


def _replace_words(prog, code, line, values, style, editable) -> Edits:
    """Existing words on editable lines take the target of the first consumer at or
    after them."""
    c_line, c_val = _consumers(line, values)
    words = np.flatnonzero(prog.word_letter == code)
    words = words[editable[prog.word_line[words]]]
    if words.size == 0 or c_line.size == 0:
        return Edits.of()
    # np.searchsorted(c_line, word lines, side="left"), by a table per line
    nxt = _first_at_or_after(c_line, prog.n_lines)[prog.word_line[words]]
    ok = nxt < c_line.shape[0]
    words, new = words[ok], c_val[nxt[ok]]
    old = prog.word_value[words]
    change = ~_says_exactly(old, new, style)  # NaN (an expression) always changes
    words, new, old = words[change], new[change], old[change]
    # an expression value ([#<fscale>*225], #1) is replaced whole, after the letter
    start = np.where(np.isnan(old), prog.word_start[words] + 1, prog.word_num_start[words])
    n = int(words.size)
    return Edits(start.astype(np.int64), prog.word_end[words].astype(np.int64),
                 style.format_all(new), n if code == S_CODE else 0, n if code == F_CODE else 0)


def _append_words(prog, code, line, values, style, editable, kept=None):
    """Consumers whose target differs from what is in force get a new word.

    In force at a consumer: its own word (rewritten to the target); else the last
    word since the previous consumer, which is rewritten to this target unless it
    stands on a line that may not be edited (left alone: its own value holds); else
    the previous consumer's target.  The new word goes on the consumer's line, or where
    that may not be edited, on the last editable line after the previous consumer (and
    after a word that is left alone).  ``kept``: lines whose own word is left alone though
    the line may be edited (it takes no second word).
    """
    if kept is not None and kept.any():
        editable = editable & ~kept
    c_line, c_val = _consumers(line, values)
    if c_line.size == 0:
        return c_line, ([], np.zeros(0, dtype=np.intp))
    sel = np.flatnonzero(prog.word_letter == code)
    if sel.size == 0:  # no such word anywhere: every change of target needs one
        prev = np.concatenate(([np.nan], c_val[:-1]))
        need = ~_same_formatted(c_val, prev, style)
        floor = np.concatenate(([-1], c_line[:-1]))[need]
        return _carriers(prog, c_line[need], floor, editable, code), \
            style.format_distinct(c_val[need])
    w_line = prog.word_line[sel]
    w_opaque = ~editable[w_line]
    w_val = prog.word_value[sel]
    own = np.isin(c_line, w_line[~w_opaque])
    # the last word at or before the consumer's line: a word on its own line that may not
    # be edited holds its own value there
    last = _last_at_or_before(w_line, prog.n_lines)[c_line]
    prev_line = np.concatenate(([-1], c_line[:-1]))
    has = last >= 0
    np.maximum(last, 0, out=last)
    last_line = w_line[last]
    between = has & (last_line > prev_line)
    opaque_between = between & w_opaque[last]
    previous = np.concatenate(([np.nan], c_val[:-1]))  # a target, written by the style
    settled = own | (between & ~opaque_between)
    same = _same_formatted(c_val, previous, style)
    # a word left alone holds its own value; an expression there (S#<rpm>) holds what
    # the program computes, which ncopt did not change
    at = np.flatnonzero(opaque_between)
    opaque_val = w_val[last[at]]  # a word left as the program has it
    same[at] = _says_exactly(opaque_val, c_val[at], style) | np.isnan(opaque_val)
    need = ~settled & ~same
    floor = np.where(opaque_between, last_line, prev_line)[need]
    return _carriers(prog, c_line[need], floor, editable, code), style.format_distinct(c_val[need])


def _last_at_or_before(lines: np.ndarray, n_lines: int) -> np.ndarray:
    """(n_lines,) index of the last of the sorted ``lines`` at or before each line, -1
    where none is: np.searchsorted(lines, line, side="right") - 1 for every line at once."""
    table = np.full(n_lines, -1, dtype=np.int64)
    last = np.flatnonzero(np.append(lines[1:] != lines[:-1], True)) if lines.size else lines
    table[lines[last]] = last
    return np.maximum.accumulate(table)


def _first_at_or_after(lines: np.ndarray, n_lines: int) -> np.ndarray:
    """(n_lines,) index of the first of the sorted ``lines`` at or after each line,
    ``lines.size`` where none is: np.searchsorted(lines, line, side="left") for every line."""
    table = np.full(n_lines, lines.size, dtype=np.int64)
    first = np.flatnonzero(np.append(True, lines[1:] != lines[:-1])) if lines.size else lines
    table[lines[first]] = first
    return np.minimum.accumulate(table[::-1])[::-1]


def _carriers(prog, lines: np.ndarray, floor: np.ndarray, editable: np.ndarray, code: int):
    """Where each needed word goes: its consumer's line if editable, else the last
    editable line after ``floor`` and before it; VerificationError where there is none."""
    if lines.size == 0 or editable[lines].all():
        return lines
    can = np.zeros(prog.n_lines, dtype=bool)
    can[prog.word_line] = True
    can &= editable
    last_can = np.maximum.accumulate(np.where(can, np.arange(prog.n_lines), -1))
    at = np.where(editable[lines], lines, last_can[np.maximum(lines - 1, 0)])
    bad = np.flatnonzero(at <= floor)
    if bad.size:
        line = int(lines[bad[0]])
        raise VerificationError(
            f"the program's own {chr(code)} cannot be put back in force before this line "
            "without editing a line ncopt leaves alone; nothing written", prog.path, line + 1)
    return at


def _says_exactly(old: np.ndarray, new: np.ndarray, style: WordStyle) -> np.ndarray:
    """Does a word worth ``old`` already say ``new`` as the style would write it?
    (F60.1 does not say F60, even where the program writes F without decimals.)"""
    scale = 10.0 ** style.decimals
    written = np.round(new * scale) / scale
    with np.errstate(invalid="ignore"):
        tol = 1e-9 * np.maximum(np.abs(written), 1.0)
        # the program's own value kept as the target (F333.3 in an F-without-decimals
        # post) is already right as it stands
        return (np.abs(old - written) <= tol) | (np.abs(old - new) <= tol)


def _same_formatted(a: np.ndarray, b: np.ndarray, style: WordStyle) -> np.ndarray:
    """Would a and b be written the same (to the style's precision)?"""
    scale = 10.0 ** style.decimals
    with np.errstate(invalid="ignore"):
        return (np.round(a * scale) == np.round(b * scale)) & ~np.isnan(a) & ~np.isnan(b)


def _insertions(prog, appended: dict, style) -> Edits:
    """New words go after the last word of their line, S before F unless the post differs.

    ``appended`` maps S_CODE / F_CODE to (lines, (texts, code)): lines increasing, the
    distinct formatted values and the index of each line's (see
    :meth:`WordStyle.format_distinct`).  Each distinct (S, F) pair's text is built once."""
    (s_lines, (s_texts, s_code)), (f_lines, (f_texts, f_code)) = appended[S_CODE], appended[F_CODE]
    if len(s_lines) + len(f_lines) == 0:
        return Edits.of()
    mark = np.zeros(prog.n_lines + 1, dtype=bool)
    mark[s_lines] = True
    mark[f_lines] = True
    lines = np.flatnonzero(mark)
    sep = style.separator
    # per line, the index of its S text and of its F text; the last of each: none
    s_at = np.full(lines.size, len(s_texts), dtype=np.int64)
    rank = np.cumsum(mark) - 1  # where each marked line stands in ``lines``
    s_at[rank[s_lines]] = s_code
    f_at = np.full(lines.size, len(f_texts), dtype=np.int64)
    f_at[rank[f_lines]] = f_code
    pairs, code = _distinct(s_at * (len(f_texts) + 1) + f_at)
    s_part = [f"{sep}S{t}" for t in s_texts] + [""]
    f_part = [f"{sep}F{t}" for t in f_texts] + [""]
    s_of, f_of = np.divmod(pairs, len(f_texts) + 1)
    joined = ([s_part[a] + f_part[b] for a, b in zip(s_of.tolist(), f_of.tolist())]
              if style.s_before_f else
              [f_part[b] + s_part[a] for a, b in zip(s_of.tolist(), f_of.tolist())])
    texts = np.array(joined, dtype=object)[code].tolist()
    last_word = _last_at_or_before(prog.word_line, prog.n_lines + 1)[lines]
    on_line = (last_word >= 0) & (prog.word_line[np.maximum(last_word, 0)] == lines)
    at = np.where(on_line, prog.word_end[np.maximum(last_word, 0)], prog.line_start[lines])
    at = at.astype(np.int64)
    return Edits(at, at.copy(), texts, len(s_lines), len(f_lines))


SPLICE_BLOCK = 65536  # edits joined at a time by apply_edits


def apply_edits(text: str, edits) -> str:
    """Splice edits (:class:`Edits` or a sequence of :class:`Edit`) into text.

    They may not overlap; insertions at one point keep their order.
    """
    if not isinstance(edits, Edits):
        edits = Edits.of(edits)
    if len(edits) == 0:
        return text
    order = np.lexsort((edits.end, edits.start))  # stable: insertions keep their order
    start, end = edits.start[order], edits.end[order]
    clash = np.flatnonzero(start[1:] < end[:-1])
    if clash.size:
        raise VerificationError(f"overlapping edits at offset {int(start[clash[0] + 1])}")
    # kept text, edit, kept text, ..., edit, kept text: filled by slices, not appends, and
    # joined a block of edits at a time, so that the Python ints and strings of only one
    # block are alive at once (~1M edits: ~150 MB less at the splice, a rewrite's peak)
    n = len(order)
    pieces = []
    for lo in range(0, n, SPLICE_BLOCK):
        hi = min(lo + SPLICE_BLOCK, n)
        parts = [""] * (2 * (hi - lo))
        keep_from = ([0] if lo == 0 else []) + end[max(lo - 1, 0):hi - 1].tolist()
        parts[0::2] = [text[a:b] for a, b in zip(keep_from, start[lo:hi].tolist())]
        parts[1::2] = list(map(edits.text.__getitem__, order[lo:hi].tolist()))
        pieces.append("".join(parts))
    pieces.append(text[int(end[-1]):])
    del parts
    out = "".join(pieces)
    del pieces
    release_freed_memory(force=True)  # the leftovers of the planning and the edits: the
    # verification, the peak of a rewrite, reuses the address space, not its pages
    return out


def masked(prog: Program) -> str:
    """The program text with every S and F word (and the blanks before it) removed."""
    sel = np.flatnonzero((prog.word_letter == S_CODE) | (prog.word_letter == F_CODE))
    if sel.size == 0:
        return prog.text
    text = prog.text
    # the removals are in order and apart (one may start where the previous one ends);
    # the blanks before a word go with it, back to the previous removed word at most.
    # A block of removals at a time, from the end of the one before it: the bytes of one
    # block are alive at once, not the whole text's (its bytes, a mask of them and the
    # kept ones: ~90 MB at 1M blocks, at the verification, a rewrite's peak)
    pieces, base = [], 0
    for lo in range(0, sel.size, MASK_BLOCK):
        words = sel[lo:lo + MASK_BLOCK]
        start, end = prog.word_start[words] - base, prog.word_end[words] - base
        floor = np.concatenate(([0], end[:-1]))
        raw = np.frombuffer(text[base:base + int(end[-1])].encode("latin-1"), dtype=np.uint8)
        pieces.append(_kept_bytes(raw, start, end, floor).tobytes().decode("latin-1"))
        base += int(end[-1])
    pieces.append(text[base:])
    return "".join(pieces)


MASK_BLOCK = 65536  # S and F words removed at a time by masked


def _kept_bytes(raw, start, end, floor) -> np.ndarray:
    """``raw`` without the bytes from each ``start`` (moved back over the blanks before
    it, down to its ``floor`` at most) to its ``end``; the last end is the end of ``raw``."""
    back = np.flatnonzero(start > floor)
    while back.size:
        back = back[(raw[start[back] - 1] == 32) | (raw[start[back] - 1] == 9)]
        start[back] -= 1
        back = back[start[back] > floor[back]]
    # kept, removed, kept, ..., kept, removed
    bounds = np.empty(2 * start.size + 1, dtype=np.int64)
    bounds[0] = 0
    bounds[1::2], bounds[2::2] = start, end
    kept = np.zeros(2 * start.size, dtype=bool)
    kept[0::2] = True
    return raw[np.repeat(kept, np.diff(bounds))]
