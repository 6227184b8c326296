"""Which control a program was posted for, and what its numbers mean there.

Each dialect has a list of telling marks (regular expressions over the text);
the one with the most distinct marks wins, ties broken by the order below.
The result is reported with the marks that decided it, so a user can see why.

The names are also the grammar names of :func:`ncopt.reading.parse.parser`.  On a
Fanuc control a number without a decimal point can mean least input
increments (``X1000`` = 1 mm): :func:`decimal_point_issue` finds the words
whose value depends on it, :func:`apply_decimal_point` reads them in the
convention the machine uses, :func:`resolve_decimal_point` does both.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from ncopt.runtime.errors import NcParseError, UsageError
from ncopt.model import Program
from ncopt.reading.refuse import caret_context

SINUMERIK, FANUC, LINUXCNC, GRBL, HEIDENHAIN, GENERIC = (
    "sinumerik", "fanuc", "linuxcnc", "grbl", "heidenhain-iso", "generic")
DIALECTS = (SINUMERIK, FANUC, HEIDENHAIN, LINUXCNC, GRBL, GENERIC)

class Mark(NamedTuple):
    """A construct that tells a control: ``only`` when no other dialect reads it.

    ``alone``: whether the mark may choose its dialect without another of its marks.
    Fanuc's ``G43 H``, ``G28 G91``, ``#1=`` and ``M98 P`` are in LinuxCNC's and grbl's
    programs as well, which read ``X10`` as 10 mm where the Fanuc dialect refuses it
    for its missing decimal point: they name the control only beside a mark that tells it.
    """

    name: str
    pattern: str
    only: bool
    alone: bool = True


_MARKS = {
    SINUMERIK: [
        Mark("%_N_NAME_MPF header", r"^%_N_\w+_(?:MPF|SPF)", True),
        Mark("CYCLE8xx( call", r"\bCYCLE8\d\d\s*\(", True),
        Mark("G641/G642 continuous path", r"\bG64[12]\b", True),
        Mark('T="NAME" tool call', r"\bT\s*=\s*\"", True),
        Mark("DEF REAL/INT/BOOL", r"^[ \t]*(?:N\d+\s*)?DEF\s+(?:REAL|INT|BOOL)", True),
        Mark("TRAORI/TRAFOOF", r"\bTRAORI\b|\bTRAFOOF\b", True),
        Mark("MSG( message", r"\bMSG\s*\(", True),
        Mark("R1= parameter", r"^[ \t]*(?:N\d+\s*)?R\d+\s*=", True),
        Mark("S1= spindle speed", r"\bS1\s*=", True),
        Mark("T1 D1 block", r"^[ \t]*(?:N\d+\s+)?T\d+\s+D\d+\s*$", False),
        # an arc's radius as CR=: Siemens' own word (outside a comment: Fusion writes
        # "(T1 D=6. CR=3. ...)" in its tool comments for every control)
        Mark("CR= arc radius", r"^(?:[^(;\n]|\([^)\n]*\))*?\bCR\s*=\s*[-+]?[.\d]", True),
    ],
    FANUC: [
        # a program number line: grbl refuses an O word, LinuxCNC 2.9 reads one as the label
        # of a Fanuc-style M98 subprogram (its own o-words, o100 sub, are no program number);
        # also after a UTF-8 byte order mark (read as latin-1)
        Mark("O1234 program number",
             r"^(?:\xef\xbb\xbf)?[ \t]*O\d{3,5}\b(?![ \t]*[A-Za-z][ \t]*[A-Za-z])", False),
        Mark("G43 H length offset", r"\bG43\s*H\d+|\bG43\s*Z[-\d.]+\s*H\d+", False, False),
        Mark("G28 G91 return", r"\bG28\s*G91|\bG91\s*G28", False, False),  # grbl's too
        Mark("G05.1 AI contour", r"\bG0?5\.1\b", True),
        Mark("#100= macro variable", r"^[ \t]*#\d+\s*=", False, False),  # LinuxCNC's too
        Mark("IF[..]GOTO", r"\bIF\s*\[.*\]\s*GOTO", True),
        Mark("M98 P subprogram call", r"\bM98\s*P", False, False),  # LinuxCNC 2.9 reads M98
        Mark("G65 P macro call", r"\bG65\s*P", True),
        # LinuxCNC refuses both ("Unknown m code used: M29", "Unknown g code used"), grbl too
        Mark("M29 rigid tapping", r"\bM29\b", True),
        Mark("G54.1 P work offset", r"\bG54\.1\s*P", True),
    ],
    LINUXCNC: [
        Mark("o-word sub/call/if",
             r"^[ \t]*[oO]\s*(?:\d+|<[^>]+>)\s+(?:sub|call|if|while|do|repeat)\b", True),
        Mark("#<named> parameter", r"#<[^>]+>", True),
        Mark("G64 P path tolerance", r"\bG64\s*P", True),
        Mark("(MSG, / (DEBUG, / (PRINT, comment", r"\(\s*(?:MSG|DEBUG|PRINT)\s*,", True),
        Mark("M2 end", r"^[ \t]*(?:N\d+\s*)?M2\s*$", False),
    ],
    GRBL: [
        Mark("$ system command", r"^[ \t]*\$[A-Z]", True),
        Mark("'grbl' in a comment", r"\bgrbl\b", False),
        Mark("laser mode M3/M4", r"\bM[67]\b.*laser|\blaser\b.*\bM[34]\b", False),
        Mark("$H homing", r"\$H\b", True),
    ],
    HEIDENHAIN: [
        Mark("%NAME G71 * header", r"^[ \t]*%\w+\s+G7[01]\s*\*", True),
        Mark("* block end", r"\*\s*$", True),
        Mark("N.. G98/G99 label", r"\bN\d+\s+G9[89]\b", False),
    ],
}
# what a dialect cannot read at all: a ';' comment with text is no Fanuc end of block
# (a ';' inside ( ) is comment text: "(MACHINE; TOYODA)")
_EXCLUDED_BY = {FANUC: re.compile(r"^(?:[^(;\n]|\([^)\n]*\))*;[ \t]*[^\s;]", re.M)}
_COMPILED = {k: [re.compile(m.pattern, re.I | re.M) for m in v] for k, v in _MARKS.items()}
_SAMPLE_CHARS = 400_000  # headers and the first blocks tell; no need to scan 30 MB
# Text every match of a mark contains (one of, upper case): a mark whose text is not
# in the sample cannot match, and its regular expression is not run (each costs
# ~16 ms on 400 kB; most marks are absent from most programs).
_NEEDS = {
    SINUMERIK: [("%_N_",), ("CYCLE8",), ("G64",), ("=",), ("DEF",), ("TRAORI", "TRAFOOF"),
                ("MSG",), ("=",), ("=",), ("D",), ("CR",)],
    FANUC: [("O",), ("G43",), ("G28",), ("5.1",), ("#",), ("GOTO",), ("M98",), ("G65",),
            ("M29",), ("G54.1",)],
    LINUXCNC: [("O",), ("#<",), ("G64",), ("MSG", "DEBUG", "PRINT"), ("M2",)],
    GRBL: [("$",), ("GRBL",), ("LASER",), ("$H",)],
    HEIDENHAIN: [("%",), ("*",), ("G9",)],
}


@dataclass(frozen=True)
class Detected:
    """The dialect and the marks that decided it (their names, see :class:`Mark`)."""

    name: str
    marks: tuple[str, ...]


def detect(text: str) -> Detected:
    """Guess the control dialect of a program from the marks of each dialect.

    A mark only one dialect has (``G64 P`` of LinuxCNC, ``IF[..]GOTO`` of
    Fanuc) counts before any mark several share (``G43 H``, which LinuxCNC
    reads as well as Fanuc): the dialect with the most marks of its own wins,
    then the one with the most marks, then the first in :data:`DIALECTS`.  A
    dialect that cannot read something in the program (Fanuc and a ``;``
    comment) is not chosen, nor one whose marks are all in other controls'
    programs too (a grbl file's ``G28 G91 Z0``, a LinuxCNC file's ``G43 H1``:
    see :class:`Mark`).  No mark: generic.
    """
    sample = text[:_SAMPLE_CHARS] + "\n" + text[-20_000:]
    upper = sample.upper()
    best, best_score, best_marks = GENERIC, (0, 0), ()
    for name in DIALECTS[:-1]:
        excluded = _EXCLUDED_BY.get(name)
        if excluded is not None and excluded.search(sample):
            continue
        found = [m for m, rx, need in zip(_MARKS[name], _COMPILED[name], _NEEDS[name])
                 if any(t in upper for t in need) and rx.search(sample)]
        score = (sum(m.only for m in found), len(found))
        if score > best_score and any(m.alone for m in found):
            best, best_score, best_marks = name, score, tuple(m.name for m in found)
    return Detected(best, best_marks)


# ------------------------------------------------------------- units by G code ----
# Sinumerik's G700 and G710 select inch and metric for the lengths and the feed F alike
# (Siemens: "G700: inch dimensional notation, also for feed F"): what G20 and G21 mean
# elsewhere, and the interpreter reads them so.  G70 and G71 select the unit of the lengths
# only: F stays in the machine's basic system, set in its machine data, which a program
# does not say; they keep their codes, and the moves under G70 are left as programmed (G70
# is a finishing cycle on a Fanuc lathe and in LinuxCNC, inch in Heidenhain ISO).  No other
# control has G700 or G710: the generic grammar reads them as Sinumerik does.
_SINUMERIK_UNITS = {700.0: 20.0, 710.0: 21.0}
UNIT_CODES = {SINUMERIK: _SINUMERIK_UNITS, GENERIC: _SINUMERIK_UNITS}


def read_unit_codes(letter: np.ndarray, value: np.ndarray, dialect: str) -> None:
    """Give the G words that select units the codes the interpreter reads (in place).

    ``letter`` (n_words,) uint8 letter codes, ``value`` (n_words,) float64 values of a
    program read in the grammar ``dialect``: G700 becomes 20, G710 21 (see
    :data:`UNIT_CODES`).  The words' text and spans are not changed.
    """
    codes = UNIT_CODES.get(dialect)
    if not codes:
        return
    g = np.flatnonzero(letter == ord("G"))  # a few G words among many: work on those
    g_value = value[g]
    for code, meaning in codes.items():
        g_value[g_value == code] = meaning
    value[g] = g_value


# ------------------------------------------------------ Fanuc decimal point ----
CALCULATOR, IS_B, IS_C = "calculator", "is-b", "is-c"
DECIMAL_POINT_CONVENTIONS = (CALCULATOR, IS_B, IS_C)
"""How a Fanuc control reads an address value written without a decimal point.

``calculator``
    Calculator-type input (parameter 3401#0 DPI = 1): ``X1000`` is 1000 mm
    (or inch, or degrees), as LinuxCNC, grbl, Sinumerik and Heidenhain read it.
``is-b``, ``is-c``
    Standard input (DPI = 0): the value counts least input increments of the
    increment system, IS-B (0.001 mm, 0.0001 inch, 0.001 deg) or IS-C
    (0.0001 mm, 0.00001 inch, 0.0001 deg): ``X1000`` is 1.000 mm under IS-B.

A value written with a decimal point (``X1000.``, ``F279.``) means the same
in all three, and so does a zero.
"""

_DECIMAL_ADDRESSES = frozenset(b"XYZUVWIJKQRABCF")  # Fanuc: addresses that take a point
_ROTARY = frozenset(b"ABC")
_CYCLES = (73.0, 74.0, 76.0, 81.0, 82.0, 83.0, 84.0, 85.0, 86.0, 87.0, 88.0, 89.0)
_MOTION_AND_CYCLES = (0.0, 1.0, 2.0, 3.0, 80.0) + _CYCLES  # G80 and G0-G3 end a cycle
# units per least input increment (metric mm or deg, inch) of each increment
# system: dividing by an exact integer keeps X1000 -> 1.0 and A90 -> 0.09 exact
_PER_UNIT = {IS_B: (1000.0, 10000.0), IS_C: (10000.0, 100000.0)}


class DecimalPointIssue(NamedTuple):
    """A word whose value depends on the decimal point convention (1-based line, column)."""

    line: int
    column: int
    message: str


def decimal_point_issue(program: Program, dialect: str | None,
                        convention: str | None = None) -> DecimalPointIssue | None:
    """The first word whose value ncopt cannot know without the decimal point convention.

    Only the Fanuc dialect has the two conventions (see
    :data:`DECIMAL_POINT_CONVENTIONS`); every other dialect reads values as
    written.  With ``convention`` given there is no issue: apply it with
    :func:`apply_decimal_point`.  Otherwise an issue is a non-zero number
    written without a decimal point at an address that takes one (axes X Y Z
    U V W A B C, arc and cycle data I J K Q R, dwell X) or an F word whose
    unit differs between the conventions: in G94 feed per minute F counts
    1 mm/min in both (F279 is 279 mm/min), but 0.01 inch/min in inch under
    standard input; in G95 feed per revolution it counts least input
    increments (0.001 mm/rev under IS-B), in G93 inverse time 0.001 1/min.
    Words with a computed value (``X#1``, ``X[#1*2]``) are not concerned: a
    macro variable holds a value with its decimal point.

    Returns
    -------
    DecimalPointIssue or None
        Line and column of the word (1-based, a tab is one column) and a
        message ``what is wrong; what to do``.
    """
    _check_convention(convention)
    if dialect != FANUC or convention is not None:
        return None
    state = _word_state(program)
    ambiguous = _without_point(program) & (program.word_value != 0.0)
    f_word = program.word_letter == ord("F")
    metric_g94 = (state.feed_mode == 94.0) & ~state.inch
    ambiguous &= ~(f_word & metric_g94)
    hits = np.flatnonzero(ambiguous)
    if hits.size == 0:
        return None
    k = int(hits[0])
    line = int(program.word_line[k])
    column = int(program.word_start[k] - program.line_start[line]) + 1
    word = program.text[program.word_start[k]:program.word_end[k]]
    scaled = float(program.word_value[k] / _divisors(program, state, IS_B)[k])
    unit = _unit(program, state, k)
    message = (f"`{word}` has no decimal point: a Fanuc control reads it as "
               f"{program.word_value[k]:g} {unit} with calculator-type input (DPI=1) but "
               f"{scaled:g} {unit} in least input increments (DPI=0, IS-B); pass "
               "--decimal-point calculator, is-b or is-c as the machine is set up, or write the "
               "values with a decimal point")
    return DecimalPointIssue(line + 1, column, message)


def apply_decimal_point(program: Program, convention: str) -> Program:
    """The program with its values read in a decimal point ``convention``.

    ``calculator`` returns the program unchanged.  ``is-b`` and ``is-c``
    multiply every number written without a decimal point at an address that
    takes one by its least input increment, in the program's units: axis,
    arc and cycle words by 0.001 mm or 0.0001 inch (IS-B), rotary axes A B C
    by 0.001 deg, dwell X (G4) by 0.001 s, F by 1 mm/min or 0.01 inch/min
    in G94, 0.001 mm/rev or 0.0001 inch/rev in G95 and 0.001 1/min in G93
    (IS-C: a tenth of each, except F in G94 and G93).  Units and feed modes
    are followed from the G20/G21 and G93/G94/G95 words of the program,
    starting in G21 and G94.  Word spans and text are not changed.
    """
    _check_convention(convention)
    if convention == CALCULATOR:
        return program
    state = _word_state(program)
    divisor = np.where(_without_point(program), _divisors(program, state, convention), 1.0)
    return replace(program, word_value=program.word_value / divisor)


def resolve_decimal_point(program: Program, dialect: str | None,
                          convention: str | None = None) -> Program:
    """The program's values as the control reads them, or a located error.

    :func:`decimal_point_issue` then :func:`apply_decimal_point`: for the
    Fanuc dialect without a ``convention`` and with a word whose value depends
    on it, raises :class:`~ncopt.runtime.errors.NcParseError` at that word (exit code
    3 in the CLI); otherwise returns the program read in ``convention``
    (unchanged when it is None or ``calculator``).  ``is-b``/``is-c`` for a
    program of another dialect raise :class:`~ncopt.runtime.errors.UsageError`: no
    other control reads increments, and a machine profile's setting must not
    shrink a Sinumerik program's geometry a thousandfold.
    """
    check_convention_applies(dialect, convention, program.path)
    issue = decimal_point_issue(program, dialect, convention)
    if issue is not None:
        context = caret_context(program.line_text(issue.line - 1), issue.column)
        raise NcParseError(issue.message, path=program.path, line=issue.line,
                           column=issue.column, context=context)
    return program if convention is None else apply_decimal_point(program, convention)


def check_convention_applies(dialect: str | None, convention: str | None,
                             path: str | None = None) -> None:
    """Raise UsageError for ``is-b``/``is-c`` with a dialect other than Fanuc."""
    _check_convention(convention)
    if convention not in (None, CALCULATOR) and dialect != FANUC:
        raise UsageError(f"--decimal-point {convention} is how a Fanuc control reads values; "
                         f"this program is read as {dialect or GENERIC}: give --dialect fanuc if "
                         "it runs on a Fanuc control, else leave --decimal-point out", path)


def _check_convention(convention: str | None) -> None:
    if convention is not None and convention not in DECIMAL_POINT_CONVENTIONS:
        raise UsageError(f"--decimal-point must be one of {', '.join(DECIMAL_POINT_CONVENTIONS)}, "
                         f"not {convention!r}")


class _WordState(NamedTuple):
    inch: np.ndarray  # (n_words,) bool: G20 in force at the word's line
    feed_mode: np.ndarray  # (n_words,) float: 93, 94 or 95
    dwell: np.ndarray  # (n_words,) bool: the word's line holds G4


def _word_state(program: Program) -> _WordState:
    """Units and feed mode in force at every word (a G code acts on its whole line)."""
    n = program.n_lines
    g = program.word_letter == ord("G")
    value = program.word_value
    units = _ffill_lines(n, program.word_line, g & np.isin(value, (20.0, 21.0)), value, 21.0)
    feed = _ffill_lines(n, program.word_line, g & np.isin(value, (93.0, 94.0, 95.0)), value, 94.0)
    dwell = np.zeros(n, dtype=bool)
    dwell[program.word_line[g & (value == 4.0)]] = True
    line = program.word_line
    return _WordState(units[line] == 20.0, feed[line], dwell[line])


def _ffill_lines(n_lines: int, word_line, mask, value, initial: float) -> np.ndarray:
    """(n_lines,) last value of the masked words of each line, carried forward."""
    per_line = np.full(n_lines, np.nan)
    per_line[word_line[mask]] = value[mask]  # in word order: the last one of a line wins
    idx = np.where(np.isnan(per_line), 0, np.arange(n_lines))
    np.maximum.accumulate(idx, out=idx)
    filled = per_line[idx]
    filled[np.isnan(filled)] = initial
    return filled


def _without_point(program: Program) -> np.ndarray:
    """(n_words,) bool: a number written without '.' at an address that takes a point."""
    letter = program.word_letter
    value = program.word_value
    cand = np.isin(letter, list(_DECIMAL_ADDRESSES)) & np.isfinite(value)
    cand &= value == np.floor(np.where(cand, value, 0.0))
    k_word = cand & (letter == ord("K"))
    if k_word.any():  # in a drilling cycle K counts repeats, a whole number in every convention
        g = letter == ord("G")
        motion = _ffill_lines(program.n_lines, program.word_line,
                              g & np.isin(value, _MOTION_AND_CYCLES), value, 0.0)
        cand[k_word & np.isin(motion[program.word_line], _CYCLES)] = False
    # words that are no lengths beside these codes: G05.1 Q1 R5 (AI contour control) a mode
    # and a level, G51 X Y Z I J K (scaling) the factors
    for code, letters in ((5.1, b"QR"), (51.0, b"IJK")):
        words = cand & np.isin(letter, list(letters))
        if words.any():
            lines = np.unique(program.word_line[(letter == ord("G")) & (value == code)])
            cand[words & np.isin(program.word_line, lines)] = False
    idx = np.flatnonzero(cand)
    if idx.size == 0:
        return cand
    raw = np.frombuffer(program.text.encode("latin-1"), dtype=np.uint8)
    start, end = program.word_num_start[idx], program.word_end[idx]
    point = np.zeros(idx.size, dtype=bool)
    for k in range(int((end - start).max())):  # numbers are short: a few passes
        pos = start + k
        point |= (pos < end) & (raw[np.minimum(pos, raw.shape[0] - 1)] == ord("."))
    cand[idx[point]] = False
    return cand


def _divisors(program: Program, state: _WordState, convention: str) -> np.ndarray:
    """(n_words,) increments per unit of the program (mm, inch, deg, s, mm/min...)."""
    metric, inch = _PER_UNIT[convention]
    letter = program.word_letter
    linear = np.where(state.inch, inch, metric)
    per_unit = np.where(np.isin(letter, list(_ROTARY)), metric, linear)
    per_unit = np.where((letter == ord("X")) & state.dwell, metric, per_unit)  # G4 X: seconds
    feed = np.select([state.feed_mode == 93.0, state.feed_mode == 95.0, state.inch],
                     [1000.0, linear, 100.0], 1.0)
    return np.where(letter == ord("F"), feed, per_unit)


def _unit(program: Program, state: _WordState, k: int) -> str:
    letter = chr(program.word_letter[k])
    inch = bool(state.inch[k])
    if letter == "F":
        return {93.0: "1/min (G93)", 95.0: "inch/rev (G95)" if inch else "mm/rev (G95)"}.get(
            float(state.feed_mode[k]), "inch/min" if inch else "mm/min")
    if letter in "ABC":
        return "deg"
    if letter == "X" and state.dwell[k]:
        return "s"
    return "inch" if inch else "mm"
