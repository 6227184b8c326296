"""The comments that name a program's operations, as CAM posts write them.

FreeCAD's ``(Begin operation: ...)``, Estlcam's ``(No. 1: ...)``, ``( OPERATION= ... )``,
keyed names (hyperMILL's ``JOB:``, ``; Operation: ...``, ``(TOOLPATH NAME: ...)``), and
the short comments that open an operation: Fusion's ``(PARALLEL1)`` after a blank line or
before the tool call, names framed by dashes.  :mod:`ncopt.planning.operations` splits
the program at them.

The stamp an earlier rewrite left (:mod:`ncopt.reading.stamp`) is ncopt's, no CAM notice
and no name: its lines are read as if absent, so an operation keeps its name in ncopt's
rewrite of a program (``--operations NAME`` plans the same operation again).
"""

from __future__ import annotations

import re

import numpy as np

from ncopt.model import LineKind, Program
from ncopt.planning.toolcomments import read_comment
from ncopt.planning.tooltable import lines_with_comment_marks
from ncopt.reading.stamp import read_stamps

_FREECAD = re.compile(r"^\s*\(\s*Begin operation:\s*(.*?)\s*\)\s*$", re.I)
_ESTLCAM = re.compile(r"^\s*\(\s*No\.\s*\d+\s*:\s*(.*?)\s*\)\s*$", re.I)
# ``( OPERATION=  ROUGH7  Z LEVEL  SRF_MILL1  )`` (the LinuxCNC 5-axis demos' post)
_OPERATION_IS = re.compile(r"^\s*\(\s*OPERATION\s*=\s*([^()]*?)\s*\)\s*$", re.I)
# a keyed name: hyperMILL's ``*   - JOB: 68: FreePar12_...`` (``;`` or ``( )`` in its
# G-code posts), ``; Operation: CAVITY_MILL``, ``(TOOLPATH NAME: Finish)``
_KEYED = re.compile(r"^[\s*-]*(?:OPERATION(?:\s+NAME)?|OP\s*NAME|TOOLPATH(?:\s+NAME)?|JOB)"
                    r"\s*:\s*(?:\d+\s*:\s*)?(\S.*?)\s*$", re.I)
_COMMENT_ONLY = re.compile(r"^\s*(?:N[0-9.]+\s*)?\(\s*([^()]*?)\s*\)\s*$|^\s*;\s*(.*?)\s*$")
_DASHES = re.compile(r"^\s*\(\s*[-=*]{4,}\s*\)\s*$|^\s*;\s*-*\s*-{4,}\s*$")
_NOT_AN_OPERATION = re.compile(
    r"^(?:T\d+\b.*D\s*=|TOOL\b|MSG|ncopt\b|Begin\b|Finish\b|Path:|Block-|Exported|Post Processor|"
    r"Output Time|End\b|Required tools|Machining time|Created by|Project\b|FILENAME|Tool\b)",
    re.I)
_WORDS_ONLY = re.compile(r"^(?:[A-Z]\s*[-+]?\d+(?:\.\d*)?\s*)+$", re.I)  # "( M6 T2 )": code
# a sentence, not a name: it ends with a stop or a comma, holds "word, word" or "key: value",
# or runs over six words (Fusion's notices: "(When using Fusion for Personal Use, the
# feedrate of rapid)", "(Aviso: uso personal...)", "(Using high feed G1 F5000. instead of G0.)")
# (the six words are counted by str.split: the pattern (?:\S+\s+){6}\S, searched, is
# quadratic in a long word: a 100 kB comment line took 75 s)
_SENTENCE = re.compile(r"[.,;:!?]\s*$|\w,\s|\w:\s|personal\s+use|uso\s+personal|"
                       r"subscription|suscripci", re.I)


def operation_comments(prog: Program) -> dict[int, str]:
    """0-based line -> operation name, for the comments that start an operation.

    A name is a comment-only line in the forms CAM systems write (FreeCAD's ``Begin
    operation:``, Estlcam's ``No. 1:``, ``OPERATION=``, keyed ``JOB:`` names), or a short
    comment that is no sentence and no tool description: the first such one of a block of
    comment lines that opens after a blank line or a tool call, or that a tool call
    follows, or that notices or a tool's description open (Fusion writes a blank line,
    its notices, the name, the tool call); one framed by dashes; the last line before a
    tool call.  The stamp's lines are skipped: the lines either side of it are neighbours."""
    found: dict[int, str] = {}
    near = _Neighbours(frozenset(read_stamps(prog).lines))
    block: list[tuple[int, str | None, bool]] = []  # consecutive comment-only lines
    comment_only = _comment_only_lines(prog)
    lines = lines_with_comment_marks(prog)
    # a comment after the words of a block ("G1 X1 ; pt") names nothing: not visited
    for i in lines[comment_only[lines]].tolist():
        if i in near.stamp:
            continue
        if block and block[-1][0] != near.before(i):
            _block_names(prog, near, block, found)
            block = []
        line = prog.line_text(i)
        direct = _named(line)
        if direct:
            found[i] = direct
            block.append((i, None, False))
        else:
            block.append((i, *_name_or_notice(line)))
    if block:
        _block_names(prog, near, block, found)
    return found


class _Neighbours:
    """The lines next to a line, the stamp's lines (0-based, ``stamp``) passed over."""

    def __init__(self, stamp: frozenset[int]):
        self.stamp = stamp

    def before(self, i: int) -> int:
        """The line before line ``i`` (-1: none)."""
        i -= 1
        while i in self.stamp:
            i -= 1
        return i

    def after(self, i: int) -> int:
        """The line after line ``i`` (``n_lines``: none)."""
        i += 1
        while i in self.stamp:
            i += 1
        return i


def _named(line: str) -> str | None:
    """The name a comment line gives in a CAM system's own form, or None."""
    m = _FREECAD.match(line) or _ESTLCAM.match(line)
    if m:
        return m.group(1) or None
    m = _OPERATION_IS.match(line)
    if m and m.group(1):
        return " ".join(m.group(1).split())
    m = _KEYED.match(_body(line))
    return m.group(1) if m and len(m.group(1)) <= 80 else None


def _body(line: str) -> str:
    """The text of a comment-only line, without its parentheses or semicolon."""
    m = _COMMENT_ONLY.match(line)
    return ((m.group(1) if m.group(1) is not None else m.group(2)) or "").strip() if m else ""


def _name_or_notice(line: str) -> tuple[str | None, bool]:
    """(the comment's text if it may name an operation (short, no sentence, no tool),
    whether it is a notice or a tool's description, which a name may follow)."""
    name = _body(line)
    if not name or _DASHES.match(line) or _WORDS_ONLY.match(name):
        return None, False
    fact = read_comment(name)
    tool = _NOT_AN_OPERATION.match(name) is not None or (fact is not None
                                                          and fact.diameter is not None)
    if tool or len(name.split(None, 6)) > 6 or _SENTENCE.search(name):  # "(1/4 BALL ENDMILL)", "(3mm Endmill001)": no name
        return None, True
    return (None if len(name) > 48 or "=" in name else name), False


def _block_names(prog: Program, near: _Neighbours, block: list, found: dict) -> None:
    """Mark the names of one block of consecutive comment-only lines."""
    first, last = block[0][0], block[-1][0]
    names = [(i, name) for i, name, _ in block if name]
    if not names:
        return
    before_call = _before_tool_call(prog, near, last)
    after_notices = names[0][0] > first and all(
        notice for i, _, notice in block if i < names[0][0])  # Fusion's notices, then the name
    if (_after_blank(prog, near, first) or _after_tool_call(prog, near, first) or before_call
            or after_notices):
        found.setdefault(*names[0])
    for i, name in names:
        if _framed(prog, near, i):
            found.setdefault(i, name)
    if before_call and names[-1][0] == last:
        found.setdefault(*names[-1])  # the line before the tool call names what follows


def _comment_only_lines(prog: Program) -> np.ndarray:
    """(n_lines,) bool: the line holds a comment (or nothing) and no word but a block
    number; for every line at once (one search of the word table per comment line cost
    3 ms at 1M blocks: 14 s for a program with a comment every 200 lines)."""
    other = np.zeros(prog.n_lines, dtype=bool)
    other[prog.word_line[prog.word_letter != ord("N")]] = True
    kind = prog.line_kind
    return (kind == LineKind.BLANK) | ((kind == LineKind.WORDS) & ~other)


def _framed(prog: Program, near: _Neighbours, i: int) -> bool:
    """Between dashed comment lines (CAMWorks / SolidWorks CAM)."""
    j = near.before(i)
    return j >= 0 and i < prog.n_lines - 1 and bool(_DASHES.match(prog.line_text(j)))


def _after_blank(prog: Program, near: _Neighbours, i: int) -> bool:
    j = near.before(i)
    return j >= 0 and not prog.line_text(j).strip()


_TOOL_CALL = re.compile(r"^\s*(?:N[0-9.]+\s*)?(?:T\s*\d+\s*M0?6|M0?6\s*T\s*\d+|T\s*\d+)\b", re.I)


def _after_tool_call(prog: Program, near: _Neighbours, i: int) -> bool:
    j = near.before(i)
    return j >= 0 and bool(_TOOL_CALL.match(prog.line_text(j)))


def _before_tool_call(prog: Program, near: _Neighbours, i: int) -> bool:
    """A tool call on one of the two lines after line ``i`` (the first not blank)."""
    j = i
    for _ in range(2):
        j = near.after(j)
        if j >= prog.n_lines:
            break
        text = prog.line_text(j)
        if text.strip():
            return bool(_TOOL_CALL.match(text))
    return False
