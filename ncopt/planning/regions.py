"""Which lines a rewrite may touch, and whose plan sets each block's S and F.

ncopt changes S and F only inside the operations it plans and on the link moves that
carry the spindle into them and back to the program's own speed before the next cut it
does not plan.  Everything else is *fixed*: it runs with the program's own S and F, so
those must be in force there, and its lines come out byte for byte.

A *fixed consumer* is an executed line that uses the S and F in force and that ncopt
does not plan: a feed move of an operation left alone (or one it cannot place), a
canned cycle, a subprogram or macro call, a line it does not interpret, a block-delete
line.  The lines between two fixed consumers (or a tool change) form a *run*; a run
that holds a planned block is editable, but for the lines ncopt may never edit
(subprogram bodies, lines after the program end, block-delete lines, lines it does not
interpret, lines whose S or F is an expression).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ncopt.model import LineKind, Motion, Program, Toolpath
from ncopt.motion.tcp import tcp_switches
from ncopt.planning.schedule import BlockIndex

S_CODE, F_CODE = ord("S"), ord("F")


@dataclass(frozen=True)
class Scope:
    """What a rewrite may touch.

    editable : (n_lines,) bool, lines whose S and F words may change or be added
    fixed : (n_lines,) bool, executed lines that must run with the program's S and F
        (the fixed consumers)
    owner : (nb,) int32, per moving block: the planned operation whose plan sets its S
        and F (an index into the operations), -1 where the program's own stay
    demoted : (nb,) bool, planned blocks that keep the program's S and F because they
        are the last place where the spindle can be brought back to the program's speed
        before a fixed line that follows at once
    """

    editable: np.ndarray
    fixed: np.ndarray
    owner: np.ndarray
    demoted: np.ndarray


def scope(prog: Program, tp: Toolpath, idx: BlockIndex, point_op: np.ndarray,
          ops: list) -> Scope:
    """``point_op``: (n,) the planned operation each toolpath point is planned by (-1:
    not planned); ``ops``: the operations (their spans and tools).

    Only lines inside a planned operation's own span are ever edited: its approach and
    retract (the link moves that carry the spindle into it and back to the program's
    speed) are part of it; the next operation's lines are not.  Its blocks of another
    tool (before its tool change) keep the program's S and F."""
    ls = tp.lines
    n = prog.n_lines
    planned_line = np.zeros(n, dtype=bool)
    sel = point_op >= 0
    planned_line[tp.line[sel]] = True
    feed_line = np.zeros(n, dtype=bool)
    feed_line[tp.line[1:][tp.motion[1:] >= Motion.LINEAR]] = True
    never = never_edited(prog, tp)
    fixed = ls.executed & ~planned_line & (feed_line | ls.canned | ls.call
                                           | (never & ~tcp_switches(prog)))
    fixed &= ~((prog.line_kind == LineKind.BLANK) & ~ls.block_delete)
    run = np.cumsum(fixed)
    active = np.zeros(int(run[-1]) + 1 if n else 1, dtype=bool)
    active[run[planned_line]] = True
    span_op = np.full(n, -1, dtype=np.int64)
    for k, op in enumerate(ops):
        if op.planned:
            span_op[op.first_line:op.last_line + 1] = k
    inside = active[run] & (span_op >= 0)
    editable = (inside & ~fixed & ~never & ls.executed) | planned_line
    b_line = idx.line
    owner = np.where(inside[b_line], span_op[b_line], -1).astype(np.int32)
    op_tool = np.array([o.tool for o in ops] or [-1], dtype=np.int64)
    other_tool = (owner >= 0) & (op_tool[np.maximum(owner, 0)] != ls.tool[b_line])
    owner[other_tool] = -1
    demoted = _demoted(prog, idx, run, planned_line, editable, fixed, owner)
    return Scope(editable, fixed, owner, demoted)


def never_edited(prog: Program, tp: Toolpath) -> np.ndarray:
    """(n_lines,) bool: lines whose S/F ncopt never changes: block-delete lines, lines it
    does not interpret, lines whose S or F word is an expression or parameter."""
    ls = tp.lines
    out = ls.block_delete | (prog.line_kind == LineKind.OPAQUE)
    sf = (prog.word_letter == S_CODE) | (prog.word_letter == F_CODE)
    expr = sf & np.isnan(prog.word_value)
    out[prog.word_line[expr]] = True
    return out


def _demoted(prog, idx, run, planned_line, editable, fixed, owner) -> np.ndarray:
    """The last planned block of a run that a block or line of someone else (a fixed
    line, a block of no planned operation) follows with no line between where a word
    could bring the spindle back: it keeps the program's S and F."""
    nb = idx.line.shape[0]
    demoted = np.zeros(nb, dtype=bool)
    b_planned = planned_line[idx.line]
    if not b_planned.any():
        return demoted
    b_run = run[idx.line]
    pb = np.flatnonzero(b_planned)
    last = pb[np.concatenate((b_run[pb][1:] != b_run[pb][:-1], [True]))]
    has_words = np.zeros(prog.n_lines, dtype=bool)
    has_words[prog.word_line] = True
    carrier = editable & has_words & (prog.line_kind == LineKind.WORDS)
    carriers = np.cumsum(carrier)
    fixed_lines = np.flatnonzero(fixed)
    for b in last.tolist():
        line = int(idx.line[b])
        k = np.searchsorted(fixed_lines, line, side="right")
        nxt = int(fixed_lines[k]) if k < fixed_lines.size else prog.n_lines
        other = np.flatnonzero(owner[b + 1:] != owner[b])
        if other.size:
            nxt = min(nxt, int(idx.line[b + 1 + other[0]]))
        if nxt < prog.n_lines and carriers[nxt - 1] - carriers[line] == 0:
            demoted[b] = True  # no line between to carry a word
    return demoted
