"""Input a control would refuse, refused at its line and column with the reason.

Two kinds of checks, both raising :class:`~ncopt.runtime.errors.NcParseError`
(``file:line:col: what is wrong; what to do`` and a caret context of at most
:data:`CONTEXT_CHARS` characters of the line):

:func:`check_text`, on the file's bytes before any line is parsed:

* UTF-16 and UTF-32 files (a byte order mark, or every other byte NUL):
  controls read one byte per character; ncopt would see every character
  followed by a NUL.
* Line ends of CR alone (classic Mac OS): LinuxCNC reads a CR as a blank, so
  the whole file is one block to it, and to ncopt one line.
* Heidenhain conversational programs (Klartext, ``0 BEGIN PGM NAME MM``):
  another language than ISO G-code.
* A UTF-8 byte order mark (BOM): LinuxCNC refuses it (``Bad character '\\357'
  used``, checked with rs274), Fanuc, Sinumerik, Heidenhain and grbl document
  no reading of it, and it must stay the first bytes of the file, where
  ncopt's stamp line goes.  Refused with what to do (save without BOM), rather
  than read and written back somewhere a control would see it.

:func:`check_words`, on the table of words, for what LinuxCNC's reader refuses
(checked with rs274, messages quoted below):

* The same letter twice in a block (``G1 X1 X2``: "Multiple x words on one
  line"; grbl too: error 25, "Repeated g-code word found in block").  No Fanuc
  or Sinumerik manual at hand says which of the two values they would take,
  and ncopt cannot know it either.
  Several G and M words are normal (different modal groups; the interpreter
  checks the groups), and so are several H words on Sinumerik (its auxiliary
  functions; ncopt reads no H word).  A Fanuc macro call (G65, G66) may repeat
  I, J and K (argument specification II): its block is not checked.
* A number with an exponent (``S1e3``): NC numbers have none; the text reads
  as ``S1`` followed by an ``E3`` word ("E word with no G70, G76, M66, M67 or
  M68 to use it").  In a block with one of those codes the E word is the code's
  own (``m66e0l0``: M66 E0 L0, as rs274 reads it), and so is it in a Fanuc macro
  call (G65, G66: E is the argument #8).
"""

from __future__ import annotations

import re

import numpy as np

from ncopt.runtime.errors import NcParseError
from ncopt.model import MM_PER_INCH, LineKind, Program

CONTEXT_CHARS = 120  # the caret context shows at most this much of a line
UTF8_BOM = b"\xef\xbb\xbf"
_KLARTEXT = re.compile(r"[ \t]*\d*[ \t]*BEGIN[ \t]+PGM[ \t]+\S+[ \t]+(?:MM|INCH)\b[^\r\n]*",
                       re.I)
_KLARTEXT_BLOCK = re.compile(r"[ \t]*\d+[ \t]+(?:L[ \t]+[XYZABCIJK][+-]|LBL\b|CALL[ \t]+LBL|"
                             r"TOOL[ \t]+CALL|CYCL[ \t]+DEF|BLK[ \t]+FORM|FN[ \t]*\d+:|CC[ \t]|"
                             r"END[ \t]+PGM)", re.I)
_MULTIPLE_OK_TABLE = np.zeros(256, dtype=bool)  # letters a block may hold several of
_MULTIPLE_OK_TABLE[np.frombuffer(b"GMH", dtype=np.uint8)] = True
# the bit of each letter code in a line's mask of letters (A: bit 0): none for the letters
# a block may hold several of, nor for codes outside A-Z (numpy shifts them out: 0)
_LETTER_BITS = np.where(_MULTIPLE_OK_TABLE, np.uint32(0),
                        np.left_shift(np.uint32(1),
                                      np.arange(256, dtype=np.uint32) - np.uint32(ord("A"))))


def caret_context(src: str, col: int) -> str:
    """The line and a caret under 1-based column ``col`` (a tab is one column).

    At most :data:`CONTEXT_CHARS` characters around the column are shown,
    with ``...`` where the line goes on; control characters show as ``?``
    (a CR or an escape code must not reach the terminal).
    """
    shown = re.sub(r"[\x00-\x1f\x7f-\x9f]", "?", src.expandtabs(1))
    at = max(col - 1, 0)
    if len(shown) > CONTEXT_CHARS:
        lo = max(0, min(at - CONTEXT_CHARS // 2, len(shown) - CONTEXT_CHARS))
        hi = lo + CONTEXT_CHARS
        head, tail = ("..." if lo > 0 else ""), ("..." if hi < len(shown) else "")
        shown, at = head + shown[lo:hi] + tail, len(head) + at - lo
    return f"    {shown}\n    {' ' * at}^"


def refuse_at(path: str, text: str, start: int, line: int, column: int,
              message: str) -> NcParseError:
    """An NcParseError at 1-based ``line``/``column``; ``start``: offset of the line."""
    end = text.find("\n", start)
    src = text[start:end if end >= 0 else len(text)].rstrip("\r")
    return NcParseError(message, path=path, line=line, column=column,
                        context=caret_context(src, column))


# ------------------------------------------------------------------ the text ----
def check_text(data: bytes, text: str, path: str) -> None:
    """Refuse what no control reads as G-code.

    ``data`` is the file, ``text`` the same decoded as latin-1.
    """
    wide = _wide_encoding(data)
    if wide:
        raise NcParseError(f"the file is {wide} text (several bytes per character), which NC "
                           "controls do not read; save it as ASCII or UTF-8 and run ncopt "
                           "again", path=path, line=1, column=1)
    if data.startswith(UTF8_BOM):
        raise NcParseError("the file starts with a UTF-8 byte order mark (BOM), which LinuxCNC "
                           "refuses (\"Bad character used\") and ncopt would have to keep "
                           "before its stamp line; save the file as UTF-8 without BOM (or "
                           "ASCII) and run ncopt again", path=path, line=1, column=1)
    if b"\r" in data and b"\n" not in data:
        column = text.index("\r") + 1
        raise refuse_at(path, text, 0, 1, column,
                        "the lines end with CR alone (classic Mac OS line ends), so the whole "
                        "file is one line to ncopt, and one block to LinuxCNC; save it with LF "
                        "or CR LF line ends")
    _check_klartext(text, path)


def _wide_encoding(data: bytes) -> str | None:
    """'UTF-16' or 'UTF-32' when the file is in one of them, else None."""
    if data[:4] in (b"\xff\xfe\x00\x00", b"\x00\x00\xfe\xff"):
        return "UTF-32"
    if data[:2] in (b"\xff\xfe", b"\xfe\xff"):
        return "UTF-16"
    head = np.frombuffer(data[:4096].lstrip(b"\x00"), dtype=np.uint8)  # tape leaders are NULs
    if head.size < 8:
        return None
    even, odd = head[0::2] == 0, head[1::2] == 0
    if (odd.mean() > 0.9 and even.mean() < 0.1) or (even.mean() > 0.9 and odd.mean() < 0.1):
        return "UTF-16"
    return None


def _check_klartext(text: str, path: str) -> None:
    """Refuse a Heidenhain conversational program at its ``BEGIN PGM`` line."""
    pos = 0
    for line_no in range(1, 6):  # the header is the first line; allow a few blank ones
        end = text.find("\n", pos)
        src = text[pos:end if end >= 0 else len(text)].rstrip("\r")
        if src.strip():
            m = _KLARTEXT.match(src)
            if m:
                raise refuse_at(path, text, pos, line_no, 1,
                                f"`{_snippet(m.group(0).strip())}` starts {klartext_what()}")
            return
        if end < 0:
            return
        pos = end + 1


def klartext_what() -> str:
    """What a Heidenhain conversational program is, and what to do with it."""
    return ("a Heidenhain conversational (Klartext) program, not ISO/DIN G-code; ncopt reads "
            "G-code only: post the program as ISO (DIN/ISO), e.g. with the CAM system's "
            "Heidenhain ISO post-processor")


def looks_like_klartext(src: str) -> bool:
    """Whether a line refused by the grammar is a Heidenhain conversational block."""
    return _KLARTEXT_BLOCK.match(src) is not None or _KLARTEXT.match(src) is not None


def _snippet(text: str, limit: int = 48) -> str:
    return text if len(text) <= limit else text[:limit - 3] + "..."


# ----------------------------------------------------------------- the words ----
def check_words(prog: Program, macro_calls: np.ndarray | None = None) -> None:
    """Refuse the first (by position) duplicate word or number with an exponent.

    ``macro_calls``: (n_lines,) bool, the blocks that call a Fanuc macro (G65,
    G66), whose arguments may repeat; found from literal G words when None.
    """
    if macro_calls is None:
        macro_calls = np.zeros(prog.n_lines, dtype=bool)
        g = (prog.word_letter == ord("G")) & np.isin(prog.word_value, (65.0, 66.0))
        macro_calls[prog.word_line[g]] = True
    dup = _first_duplicate(prog, macro_calls)
    found = [k for k in (dup, _first_exponent(prog, macro_calls), _first_infinite(prog))
             if k is not None]
    if not found:
        return
    k = min(found, key=lambda item: item[0])
    word, message = k
    line = int(prog.word_line[word])
    start = int(prog.line_start[line])
    column = int(prog.word_start[word]) - start + 1
    raise refuse_at(prog.path, prog.text, start, line + 1, column, message)


def _first_infinite(prog: Program) -> tuple[int, str] | None:
    """A number too large for any control (a float of 310 digits reads as infinity)."""
    bad = np.flatnonzero(np.isinf(prog.word_value))
    if bad.size == 0:
        return None
    k = int(bad[0])
    return k, (f"'{_word_text(prog, k)}' is a number beyond any control's range; check the "
               "program at this word")


def _first_duplicate(prog: Program, macro_calls: np.ndarray) -> tuple[int, str] | None:
    """(index of the second word, message) of the first letter repeated in a block.

    Each checked word is one bit (its letter) of a line's mask: a line whose
    bits sum to more than their OR holds a letter twice.  Only those lines are
    then looked at word by word.
    """
    if prog.n_words < 2:
        return None
    line_ok = (prog.line_kind == LineKind.WORDS) & ~macro_calls
    bits = np.take(_LETTER_BITS, prog.word_letter)  # take: a table of 256, no per-word shift
    line = prog.word_line
    starts = np.flatnonzero(np.concatenate(([True], line[1:] != line[:-1])))
    total = np.add.reduceat(bits.astype(np.uint64), starts)
    union = np.bitwise_or.reduceat(bits, starts)
    twice = np.flatnonzero((total != union) & line_ok[line[starts]])  # a mask per line
    if twice.size == 0:
        return None
    lo = int(starts[twice[0]])
    hi = int(starts[twice[0] + 1]) if twice[0] + 1 < starts.size else prog.n_words
    seen: dict[int, int] = {}
    for k in range(lo, hi):
        letter = int(prog.word_letter[k])
        if _MULTIPLE_OK_TABLE[letter] or not line_ok[line[k]]:
            continue
        if letter in seen:
            a, b = _word_text(prog, seen[letter]), _word_text(prog, k)
            name = chr(letter)
            return k, (f"`{a}` and `{b}` on one line: a block takes one {name} word (LinuxCNC "
                       f"refuses it: \"Multiple {name.lower()} words on one line\"); keep the "
                       "one you mean and delete the other")
        seen[letter] = k
    return None


# the codes whose block takes an E word (LinuxCNC's list, rs274: "E word with no G70, G76,
# M66, M67 or M68 to use it"), the values of their words
_E_USERS = (("G", (70.0, 76.0)), ("M", (66.0, 67.0, 68.0)))


def _first_exponent(prog: Program, macro_calls: np.ndarray) -> tuple[int, str] | None:
    """(index, message) of the first number written with an exponent (``S1e3``), on a
    line whose codes take no E word (``macro_calls``: (n_lines,) bool, lines calling a
    Fanuc macro, whose E is an argument)."""
    e_words = np.flatnonzero(prog.word_letter == ord("E"))
    e_words = e_words[e_words > 0]
    if e_words.size == 0:
        return None
    takes_e = macro_calls.copy()
    for letter, codes in _E_USERS:
        users = (prog.word_letter == ord(letter)) & np.isin(prog.word_value, codes)
        takes_e[prog.word_line[users]] = True
    e_words = e_words[~takes_e[prog.word_line[e_words]]]
    prev = e_words - 1
    glued = (prog.word_line[prev] == prog.word_line[e_words]) & \
        (prog.word_end[prev] == prog.word_start[e_words]) & np.isfinite(prog.word_value[prev])
    for e in e_words[glued].tolist():
        exponent = prog.text[prog.word_start[e] + 1:prog.word_end[e]]
        if not re.fullmatch(r"[+-]?[0-9]+", exponent):
            continue  # E0.5: an E word with its own value (an extruder), not an exponent
        p = e - 1
        written = prog.text[prog.word_start[p]:prog.word_end[e]]
        number = prog.text[prog.word_num_start[p]:prog.word_end[e]]
        letter = chr(prog.word_letter[p])
        try:
            meant = letter + np.format_float_positional(float(number), trim="-")
        except ValueError:
            continue
        return p, (f"`{written}` is a number with an exponent, which NC words do not have: it "
                   f"reads as `{_word_text(prog, p)}` followed by an E word; write the value "
                   f"out (`{meant}`)")
    return None


def _word_text(prog: Program, k: int) -> str:
    return _snippet(prog.text[prog.word_start[k]:prog.word_end[k]], 24)


# ---------------------------------------------------- values of the interpreter ----
# The interpreter calls these with its per-line table of values (``lines.value(c)``,
# ``lines.present(c)``: (n_lines,) arrays, expressions evaluated).

# below this radius LinuxCNC refuses an arc as "Zero-radius arc" (rs274: 0.00005 inch
# passes, 0.00004 fails; 0.002 mm passes, 0.0011 mm fails)
MIN_ARC_RADIUS_MM = 0.00005 * MM_PER_INCH
# centre offsets of an arc in G17, G18, G19, and the one across the plane
_IN_PLANE = {170.0: ("IJ", "K", "G17 (XY)"), 180.0: ("KI", "J", "G18 (XZ)"),
             190.0: ("JK", "I", "G19 (YZ)")}
# LinuxCNC's words: "Negative f word used", "Negative spindle speed used"
_SIGNED = (("F", "a negative feed rate", "a feed rate is positive"),
           ("S", "a negative spindle speed", "the direction is M3 or M4, S is positive"))


def check_signs(prog: Program, lines, executed: np.ndarray) -> None:
    """F and S below zero on an executed line, refused at the word; then an inverse-time
    move without its own F (:func:`check_inverse_time_feeds`)."""
    for letter, what, why in _SIGNED:
        value = lines.value(letter)
        bad = np.flatnonzero(executed & (np.nan_to_num(value, nan=0.0) < 0))
        if bad.size:
            line = int(bad[0])
            k = np.flatnonzero((prog.word_line == line) & (prog.word_letter == ord(letter)))[-1]
            word = _word_text(prog, int(k))
            _raise_at_word(prog, int(k), f"`{word}` is {what} ({value[line]:g}); {why}: fix "
                           f"the {letter} word")
    check_inverse_time_feeds(prog, lines, executed)


# G codes x10 (as ncopt.motion.modal, which this layer may not import; tests hold them
# equal): the motion group, and the codes whose axis words are no move's target (but G53,
# a move in machine coordinates)
MOTION_GROUP = {0, 10, 20, 30, 330, 382, 383, 384, 385, 730, 760, 800, 810, 820, 830, 840,
                850, 860, 870, 880, 890}
NOT_A_MOVE = {280, 300, 920, 921, 922, 923, 520, 100, 281, 301, 680, 682, 683, 684, 2680,
              50, 51, 52, 53, 62, 510, 511, 720, 500, 501, 270, 290, 310, 331, 1100, 1110, 1120}


def check_inverse_time_feeds(prog: Program, lines, executed: np.ndarray) -> None:
    """A G1, G2 or G3 move in inverse time (G93) without an F word on its own line,
    refused at the line: there F is 1 / minutes of that move alone, and LinuxCNC refuses
    the move ("F word missing with inverse time g1 move", "... arc move": checked with
    rs274, also for a G1 without axis words and a G53 move); an F on an earlier line,
    even the G93 line's own, does not carry over.  A move ncopt could not plan, so it
    is not planned with a feed the control would never run."""
    feed_mode = _in_force(lines.g_group({930, 940, 950}), 940.0)
    if not (executed & (feed_mode == 930)).any():
        return
    motion = _in_force(lines.g_group(MOTION_GROUP), np.nan)
    moves = lines.has_g({10, 20, 30}) | (np.isin(motion, [10, 20, 30])
                                          & lines.present_any("XYZABCUVWIJKR")
                                          & ~lines.has_g(NOT_A_MOVE))
    bad = np.flatnonzero(executed & (feed_mode == 930) & moves & ~lines.present("F")
                         & (prog.line_kind == LineKind.WORDS))
    if bad.size:
        arc = motion[bad[0]] in (20, 30)
        _raise_at_line(prog, int(bad[0]), "inverse-time (G93) move without its own F word "
                       "(F is 1/minutes there, of each move alone): give the move's F "
                       f"(LinuxCNC refuses it: \"F word missing with inverse time "
                       f"{'arc' if arc else 'g1'} move\")")


def _in_force(codes: np.ndarray, initial: float) -> np.ndarray:
    """(n_lines,) the code of a modal group in force on each line (its own included):
    the last one given, ``initial`` before any."""
    given = ~np.isnan(codes)
    last = np.maximum.accumulate(np.where(given, np.arange(codes.size), -1))
    return np.where(last >= 0, codes[np.maximum(last, 0)], initial)


def check_arc_centres(prog: Program, lines, arc: np.ndarray, *, plane: np.ndarray,
                      incremental: np.ndarray, inch: np.ndarray) -> None:
    """Arc centres a control refuses whatever the start point.

    ``arc`` (n_lines,) bool: executed arc moves; ``plane``: 170/180/190 in
    force; ``incremental``: G91.1 in force; ``inch``: G20 in force.  Refuses
    a non-zero offset across the plane (``J`` in G18; FreeCAD writes ``K0.000``
    on G17 arcs, which no control minds) and a zero radius: ``R0``, or
    incremental offsets of zero (the centre on the start point).
    """
    if not arc.any():  # every check below is of an arc (a finishing program may have none)
        return
    tol = np.where(inch, MIN_ARC_RADIUS_MM / MM_PER_INCH, MIN_ARC_RADIUS_MM)
    tol = tol * (1.0 - 1e-9)  # a radius of exactly the limit passes
    has_ijk = lines.present("I") | lines.present("J") | lines.present("K")
    # a word whose value the interpreter cannot know (a parameter set elsewhere) is NaN
    unknown = np.zeros(arc.shape, dtype=bool)
    for letter in "IJKR":
        unknown |= lines.present(letter) & np.isnan(lines.value(letter))
    arc = arc & ~unknown
    bad = arc & lines.present("R") & ~has_ijk & (np.abs(np.nan_to_num(lines.value("R"))) < tol)
    for code, ((u, v), across, name) in _IN_PLANE.items():
        wrong = np.flatnonzero(arc & (plane == code) & (np.nan_to_num(lines.value(across)) != 0))
        if wrong.size:
            _raise_at_line(prog, int(wrong[0]), f"{across} word on an arc in the {name} plane, "
                           f"whose centre is given by {u} and {v}; correct the offsets or the "
                           "plane")
        radius = np.hypot(np.nan_to_num(lines.value(u)), np.nan_to_num(lines.value(v)))
        bad |= arc & has_ijk & incremental & (plane == code) & (radius < tol)
    if bad.any():
        _raise_at_line(prog, int(np.flatnonzero(bad)[0]), "zero-radius arc: the centre is on "
                       "the start point (R0, or I, J, K of 0); correct the arc (LinuxCNC "
                       "refuses it: \"Zero-radius arc\")")


def _raise_at_word(prog: Program, k: int, message: str) -> None:
    line = int(prog.word_line[k])
    start = int(prog.line_start[line])
    raise refuse_at(prog.path, prog.text, start, line + 1, int(prog.word_start[k]) - start + 1,
                    message)


def _raise_at_line(prog: Program, line: int, message: str) -> None:
    raise refuse_at(prog.path, prog.text, int(prog.line_start[line]), line + 1, 1, message)
