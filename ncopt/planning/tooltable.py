"""Cutters read from the tool comments that CAM posts write.

:mod:`ncopt.planning.toolcomments` reads one comment (Fusion 360, OpenBuilds, BlenderCAM,
FreeCAD, Carbide Create, Estlcam, Mastercam, hyperMILL, SolidCAM, Vectric, free
text); here the comments of a program become its tools:

* Comments on consecutive comment-only lines that a CAM writes as parts of one
  description, and that do not contradict each other, are one description
  (FreeCAD writes ``(Tool type: endmill)`` and ``(Compensated Tool Path.
  Diameter: 3.0)``); free text stands alone.  ncopt's own stamp is no tool
  comment (its sizes are mm in every program; the planner reads it).
* A description naming a T number belongs to that tool.  One without a number
  belongs to the tool change on its own line, else to the next tool change
  with no move between them (Carbide Create writes ``(TOOL/MILL,...)`` just
  before ``M6 T121``), else to the previous one with no move between them
  (BlenderCAM writes ``T1 M06`` then its comment).  When the program has M6
  words, a tool change is an M6 block (a T word alone preselects the next
  tool); otherwise a T word.  One with moves on both sides belongs to the tool
  in force at its line, if that tool has not cut yet (Carbide Create writes
  ``(TOOL/MILL,...)`` after the first rapid moves when it writes no M6).
* Descriptions bound to no tool change serve a program that never names a
  tool, if they all agree (``UNNUMBERED``); several different ones cannot be
  told apart and serve nothing.
* A tool a description before a cut calls something else than a ball or a
  bull-nose (a flat end mill, a V-bit, a drill...) is that: this description
  wins over every other of the same tool, and among the unbound ones over
  those that disagree with it: ncopt never plans as a ball a tool the program
  says is not one.

A tool is usable by ncopt when it is a ball or a bull-nose whose corner radius
is known.  Flat end mills, drills, chamfer and engraving tools, shapes the
comment does not give, are reported and their sections left untouched.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from ncopt.model import MM_PER_INCH, Cutter, LineKind, Program
from ncopt.motion.modal import sorted_unique
from ncopt.reading.stampline import STAMP_BODY
from ncopt.planning.toolcomments import (BALL, BULL, BULL_NO_RADIUS, FLAT, OTHER, UNKNOWN, Fact,
                           may_describe_a_tool, read_comment, shape)

__all__ = ["BALL", "BULL", "BULL_NO_RADIUS", "FLAT", "OTHER", "UNKNOWN", "UNNUMBERED",
           "ToolInfo", "parse_tool_comment", "tool_comments", "tool_table", "cutter_for"]

UNNUMBERED = -1  # "( Cutter is assumed to be a 10mm ball nose )": no T number given


@dataclass(frozen=True)
class ToolInfo:
    """One tool as the program's comments describe it.

    Attributes
    ----------
    number : int
        T number, or :data:`UNNUMBERED`.
    kind : str
        BALL, BULL, FLAT, OTHER, UNKNOWN (the comment gives no shape) or
        BULL_NO_RADIUS.
    diameter, corner_radius : float
        In ``unit``; ``corner_radius`` is NaN where not known.
    line : int
        1-based line of the comment that gives the diameter.
    text : str
        That comment's text.
    teeth : int or None
        Number of teeth the comments give; None: not given (the caller assumes
        a number and must say so).
    teeth_line : int or None
        1-based line of the comment that gives ``teeth``.
    unit : str or None
        "mm" or "inch" where the comment says so (``6 mm``, ``1/4"``, a
        fraction); None: the program's units.
    source : str
        Which format read it: "Fusion 360", "Mastercam", ..., "free text".
    """

    number: int
    kind: str
    diameter: float
    corner_radius: float
    line: int
    text: str
    teeth: int | None = None
    teeth_line: int | None = None
    unit: str | None = None
    source: str = "free text"

    def cutter(self, teeth: int, scale_to_mm: float = 1.0, tool_point: str = "tip") -> Cutter:
        """The cutter in mm; ``scale_to_mm`` converts the program's units (used when
        the comment states no unit of its own)."""
        scale = {"mm": 1.0, "inch": MM_PER_INCH}.get(self.unit, scale_to_mm)
        return Cutter(self.diameter * scale, teeth, self.corner_radius * scale, tool_point)

    def teeth_source(self) -> str:
        """Where the tooth count comes from: ``line N`` or ``assumed``."""
        return f"line {self.teeth_line}" if self.teeth is not None else "assumed"

    def refusal(self) -> str:
        """Why ncopt does not plan this tool (for a kind other than BALL and BULL)."""
        return {FLAT: "a flat end mill",
                UNKNOWN: "a tool whose shape the comment does not give",
                BULL_NO_RADIUS: "a bull-nose whose corner radius the comment does not give",
                }.get(self.kind, "not a ball or bull-nose")


@dataclass(frozen=True)
class _Described:
    """A description before binding: the merged fact and its lines (0-based)."""

    fact: Fact
    first: int
    last: int
    size_line: int
    text: str
    teeth_line: int | None


def parse_tool_comment(text: str, line: int) -> ToolInfo | None:
    """A ToolInfo from one comment's text (1-based ``line``), or None if it is no tool."""
    fact = read_comment(text)
    if fact is None:
        return None
    return _info(_Described(fact, line - 1, line - 1, line - 1, text,
                            line - 1 if fact.teeth is not None else None), fact.number)


def _info(desc: _Described, number: int | None) -> ToolInfo | None:
    fact = desc.fact
    if fact.diameter is None or fact.diameter <= 0:
        return None
    if fact.number is None and fact.kind_word is None and not fact.tool_word:
        return None  # "(Xcen=0 Ycen=0 Dia=10)", "( X=96 mm, Y=120 mm )": no tool
    kind, corner = shape(fact)
    teeth_line = None if desc.teeth_line is None else desc.teeth_line + 1
    return ToolInfo(UNNUMBERED if number is None else number, kind, fact.diameter,
                    float("nan") if corner is None else corner, desc.size_line + 1, desc.text,
                    fact.teeth, teeth_line, fact.unit, fact.source)


_COMMENT_IN_TEXT = re.compile(r"\(([^()\r\n]*)\)|;([^\r\n]*)")
# ncopt's own stamp (ncopt.reading.stamp) names the cutter in mm whatever the program's units;
# the planner reads it there, never as a tool comment
# the lines of an ncopt stamp: its own data, never a tool description
_NCOPT_STAMP = re.compile(r"\s*" + STAMP_BODY)


def tool_comments(prog: Program) -> list[ToolInfo]:
    """Every tool the program's comments describe, in order, with its T number if known."""
    return [info for info, _, _ in _bound_descriptions(prog)]


def tool_table(prog: Program) -> dict[int, ToolInfo]:
    """Tools described in the program's comments, by T number.

    A description naming its T number wins over one bound to a tool change by
    its place, one on the tool change's own line over one before or after it;
    among equals the first wins.  ``UNNUMBERED`` holds the descriptions bound
    to no tool change when they all agree.  Over all that, a description before a
    cut that says the tool is no ball or bull-nose (``REFUSED_KINDS``) wins.
    """
    table: dict[int, tuple[ToolInfo, int]] = {}
    loose: list[ToolInfo] = []
    refused: dict[int, ToolInfo] = {}  # the first "not a ball" before a cut, per tool
    for info, rank, cut_after in _bound_descriptions(prog):
        if cut_after and info.kind in REFUSED_KINDS:
            refused.setdefault(info.number, info)
        if info.number == UNNUMBERED:
            loose.append(info)
        elif info.number not in table or rank < table[info.number][1]:
            table[info.number] = (info, rank)
    out = {number: info for number, (info, _) in table.items()}
    agreed = _agreed(loose, _inch_program(prog))
    if agreed is not None:
        out[UNNUMBERED] = agreed
    for number, info in refused.items():
        if number not in out or out[number].kind not in REFUSED_KINDS:
            out[number] = info  # the program says it is no ball: never planned as one
    return out


# kinds a description gives that no other one of the same tool can overrule
REFUSED_KINDS = (FLAT, OTHER)


def _bound_descriptions(prog: Program) -> list[tuple[ToolInfo, int, bool]]:
    """(tool, rank, a cut follows) of every description: rank 0 names its T number, 1 is
    on the tool change's line, 2 next to it, 3 is before the first cut of the tool in
    force, 4 bound to none."""
    lines = _comment_lines(prog)
    if not lines:
        return []
    events = _Events(prog)
    out = []
    for desc in _descriptions(prog, lines):
        number, rank = desc.fact.number, 0
        if number is None:
            number, rank = events.tool_for(desc.first, desc.last)
        info = _info(desc, number)
        if info is not None:
            out.append((info, rank, events.cut_after(desc.last)))
    return out


def cutter_for(table: dict[int, ToolInfo], tool: int, n_tools: int) -> ToolInfo | None:
    """The description of T``tool``; an unnumbered one serves a single-tool program."""
    if tool in table:
        return table[tool]
    if n_tools <= 1 and UNNUMBERED in table:
        return table[UNNUMBERED]
    return None


# ----------------------------------------------------------------- helpers ----
def _comment_lines(prog: Program) -> list[tuple[int, list[str]]]:
    """(0-based line, comment texts) of every line holding a comment that may describe a
    tool (one pass of a regular expression over the text, then a quick test per comment)."""
    text = prog.text
    if "(" not in text and ";" not in text:
        return []
    found: list[tuple[int, str]] = []
    spans = _comment_spans(prog)
    # the distinct comments first (findall runs in C): a comment repeated on every block
    # ("; pt", "(pass 3)") is judged once, and where none may describe a tool, as in most
    # long programs, no match is visited one by one
    judged: dict[str, bool] = {}
    for lo, hi in spans:
        for pair in set(_COMMENT_IN_TEXT.findall(text, lo, hi)):
            for body in pair:
                if body not in judged:
                    judged[body] = bool(body and may_describe_a_tool(body)
                                        and not _NCOPT_STAMP.match(body))
    wanted = [body for body, tool in judged.items() if tool]
    if not wanted:
        return []
    # the lines where such a comment's text occurs (found in C), each read again whole: the
    # same matches as every match of every span, in order (no match crosses a line end)
    hits = []
    for body in wanted:
        at = text.find(body)
        while at >= 0:
            hits.append(at)
            at = text.find(body, at + 1)
    hit_lines = np.searchsorted(prog.line_start, sorted(hits), side="right") - 1
    hit_lines = sorted_unique(hit_lines)
    for line in hit_lines[hit_lines < prog.n_lines].tolist():
        lo, hi = int(prog.line_start[line]), int(prog.line_start[line + 1])
        for m in _COMMENT_IN_TEXT.finditer(text, lo, hi):
            body = m.group(1) if m.group(1) is not None else m.group(2)
            if judged.get(body):
                found.append((m.start(), body))
    if not found:
        return []
    lines = np.searchsorted(prog.line_start, [pos for pos, _ in found], side="right") - 1
    trailer = (prog.line_kind[np.minimum(lines, prog.n_lines - 1)] == LineKind.TRAILER).tolist()
    out: list[tuple[int, list[str]]] = []
    for line, (_, body), after_end in zip(lines.tolist(), found, trailer):
        if line >= prog.n_lines or after_end:
            continue
        if out and out[-1][0] == line:
            out[-1][1].append(body)
        else:
            out.append((line, [body]))
    return out


def lines_with_comment_marks(prog: Program) -> np.ndarray:
    """The 0-based lines holding a ``(`` or ``;`` (where a comment may be), sorted: one
    pass over the text's bytes, for the readers of tool descriptions and operation names."""
    raw = np.frombuffer(prog.text.encode("latin-1"), dtype=np.uint8)
    marks = np.flatnonzero((raw == ord("(")) | (raw == ord(";")))
    lines = sorted_unique(np.searchsorted(prog.line_start, marks, side="right") - 1)
    return lines[lines < prog.n_lines]


def _comment_spans(prog: Program) -> list[tuple[int, int]]:
    """(start, end) offsets of the runs of consecutive lines holding a '(' or ';'.

    No comment match crosses a line end, so the matches within these spans are the
    matches in the whole text; a finishing program has comments on a few lines only,
    and the regular expression then scans those, not every byte (1M lines: 0.15 s)."""
    lines = lines_with_comment_marks(prog)
    if lines.size == 0:
        return []
    first = lines[np.concatenate(([True], np.diff(lines) > 1))]
    last = lines[np.concatenate((np.diff(lines) > 1, [True]))]
    return list(zip(prog.line_start[first].tolist(), prog.line_start[last + 1].tolist()))


def _descriptions(prog: Program, lines) -> list[_Described]:
    """Facts of the comments, merged over consecutive comment-only lines."""
    only_comments = _comment_only(prog)
    out: list[_Described] = []
    current: _Described | None = None
    for line, texts in lines:
        for text in texts:
            fact = read_comment(text)
            if fact is None:
                continue
            here = _Described(fact, line, line, line, text,
                              line if fact.teeth is not None else None)
            joinable = (current is not None and _partial(fact) and _partial(current.fact)
                        and only_comments[line] and only_comments[current.last]
                        and line - current.last <= 1)
            merged = current.fact.merged(fact) if joinable else None
            if merged is None:
                if current is not None:
                    out.append(current)
                current = here
                continue
            size_new = current.fact.diameter is None and fact.diameter is not None
            current = _Described(merged, current.first, line,
                                 line if size_new else current.size_line,
                                 text if size_new else current.text,
                                 current.teeth_line if current.teeth_line is not None
                                 else here.teeth_line)
    if current is not None:
        out.append(current)
    return out


def _partial(fact: Fact) -> bool:
    """A fact a CAM writes over several comments (FreeCAD's type and diameter lines);
    free text and numbered descriptions stand alone."""
    return fact.number is None and fact.source != "free text"


def _comment_only(prog: Program) -> np.ndarray:
    """(n_lines,) bool: the line holds no word but N (a comment line)."""
    words = np.zeros(prog.n_lines, dtype=bool)
    words[prog.word_line[prog.word_letter != ord("N")]] = True
    return ~words & (prog.line_kind != LineKind.OPAQUE)


class _Events:
    """Tool changes, moves and cuts of a program, by line."""

    def __init__(self, prog: Program) -> None:
        letter, line, value = prog.word_letter, prog.word_line, prog.word_value
        n = prog.n_lines
        self.move = np.zeros(n, dtype=bool)
        self.move[line[np.isin(letter, np.frombuffer(b"XYZABC", dtype=np.uint8))]] = True
        self.cuts_before = np.cumsum(self.move & _feed_mode(prog))  # cuts on lines 0..i
        t_value = np.full(n, np.nan)
        t = letter == ord("T")
        t_value[line[t]] = value[t]
        m6 = np.zeros(n, dtype=bool)
        m6[line[(letter == ord("M")) & (value == 6.0)]] = True
        if m6.any():  # the tool in force at each M6: its T may stand on an earlier line
            idx = np.where(np.isnan(t_value), -1, np.arange(n))
            np.maximum.accumulate(idx, out=idx)
            in_force = np.where(idx >= 0, t_value[np.maximum(idx, 0)], np.nan)
            self.change = np.flatnonzero(m6 & ~np.isnan(in_force))
            self.number = in_force[self.change]
        else:
            self.change = np.flatnonzero(~np.isnan(t_value))
            self.number = t_value[self.change]
        self.moves_before = np.cumsum(self.move)  # moves on lines 0..i

    def tool_for(self, first: int, last: int) -> tuple[int | None, int]:
        """(T number, rank) of the tool change a description on lines first..last
        belongs to: rank 1 on its own lines, 2 next to it, 3 the tool in force that has
        not cut since its change, (None, 4) none."""
        if self.change.size == 0:
            return None, 4
        k = int(np.searchsorted(self.change, first))
        if k < self.change.size and self.change[k] <= last:
            return int(self.number[k]), 1
        if k < self.change.size and not self._moves_between(last, int(self.change[k])):
            return int(self.number[k]), 2
        if k > 0 and not self._moves_between(int(self.change[k - 1]), first):
            return int(self.number[k - 1]), 2
        if k > 0 and self.cuts_before[first] == self.cuts_before[int(self.change[k - 1])]:
            return int(self.number[k - 1]), 3
        return None, 4

    def cut_after(self, line: int) -> bool:
        """Whether a line after ``line`` cuts (a feed move or a canned cycle)."""
        return bool(self.cuts_before[-1] > self.cuts_before[line])

    def _moves_between(self, a: int, b: int) -> bool:
        """Whether a line strictly between a and b moves an axis."""
        return b - a > 1 and self.moves_before[b - 1] - self.moves_before[a] > 0


# G codes of the motion group (RS-274 group 1): those that cut, and those that do not
_CUTTING_G = (1.0, 2.0, 3.0, 81.0, 82.0, 83.0, 84.0, 85.0, 86.0, 87.0, 88.0, 89.0)
_MOTION_G = (0.0, 80.0) + _CUTTING_G


def _feed_mode(prog: Program) -> np.ndarray:
    """(n_lines,) bool: a move on the line would cut (G1, G2, G3 or a canned cycle in
    force; a program starts in no cutting mode)."""
    sel = (prog.word_letter == ord("G")) & np.isin(prog.word_value, _MOTION_G)
    mode = np.full(prog.n_lines, -1, dtype=np.int64)
    mode[prog.word_line[sel]] = np.isin(prog.word_value[sel], _CUTTING_G)  # the line's last
    idx = np.where(mode >= 0, np.arange(prog.n_lines), -1)
    np.maximum.accumulate(idx, out=idx)
    return (idx >= 0) & (mode[np.maximum(idx, 0)] == 1)


def _inch_program(prog: Program) -> bool:
    g = prog.word_letter == ord("G")
    return bool(np.any(prog.word_value[g] == 20.0))


def _agreed(loose: list[ToolInfo], inch: bool) -> ToolInfo | None:
    """One description for every loose one, if they agree; None if none or they differ.

    Sizes compare in mm (a description without a unit is in the program's);
    a shape or tooth count one of them does not give does not disagree.
    """
    if not loose:
        return None
    best = loose[0]
    for other in loose[1:]:
        if not np.isclose(_diameter_mm(other, inch), _diameter_mm(best, inch), rtol=1e-6):
            return None
        if UNKNOWN not in (best.kind, other.kind) and best.kind != other.kind:
            return None
        if None not in (best.teeth, other.teeth) and best.teeth != other.teeth:
            return None
        if best.kind == UNKNOWN and other.kind != UNKNOWN:
            best = other  # a later one names the shape the first did not
    return best


def _diameter_mm(info: ToolInfo, inch: bool) -> float:
    scale = {"mm": 1.0, "inch": MM_PER_INCH}.get(info.unit, MM_PER_INCH if inch else 1.0)
    return info.diameter * scale
