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

from .model import LineKind, Motion, Program, Toolpath
from .planner import BlockIndex

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
          op_tool: np.ndarray) -> Scope:
    """``point_op``: (n,) the planned operation each toolpath point is planned by (-1:
    not planned); ``op_tool``: the T number of each operation.

    A run goes on across a tool change: where the next tool has no S word of its own,
    the program's S must be back in force before its first cut.  Blocks of another tool
    in a run keep the program's S and F (their lines may only carry a word back)."""
    ls = tp.lines
    n = prog.n_lines
    planned_line = np.zeros(n, dtype=bool)
    line_op = np.full(n, -1, dtype=np.int64)
    sel = point_op >= 0
    planned_line[tp.line[sel]] = True
    line_op[tp.line[sel]] = point_op[sel]
    feed_line = np.zeros(n, dtype=bool)
    feed_line[tp.line[1:][tp.motion[1:] >= Motion.LINEAR]] = True
    never = never_edited(prog, tp)
    fixed = ls.executed & ~planned_line & (feed_line | ls.canned | ls.call | never)
    fixed &= ~((prog.line_kind == LineKind.BLANK) & ~ls.block_delete)
    run = np.cumsum(fixed)
    active = np.zeros(int(run[-1]) + 1 if n else 1, dtype=bool)
    active[run[planned_line]] = True
    editable = active[run] & ~fixed & ~never & ls.executed & ~planned_line
    editable |= planned_line
    owner = _owners(idx, run, line_op, active)
    other_tool = (owner >= 0) & (op_tool[np.maximum(owner, 0)] != ls.tool[idx.line])
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


def _owners(idx: BlockIndex, run: np.ndarray, line_op: np.ndarray, active: np.ndarray) -> np.ndarray:
    """Per block: the operation of the next planned block in its run (the approach), else
    of the previous one (the retract); -1 outside active runs."""
    b_run = run[idx.line]
    b_op = line_op[idx.line].astype(np.float64)
    b_op[b_op < 0] = np.nan
    nb = b_op.shape[0]
    out = np.full(nb, -1, dtype=np.int32)
    if nb == 0:
        return out
    nxt = _fill_within(b_op[::-1], b_run[::-1])[::-1]
    prv = _fill_within(b_op, b_run)
    pick = np.where(np.isnan(nxt), prv, nxt)
    ok = active[b_run] & ~np.isnan(pick)
    out[ok] = pick[ok].astype(np.int32)
    return out


def _fill_within(values: np.ndarray, group: np.ndarray) -> np.ndarray:
    """Forward fill of NaNs that never crosses into another group (groups contiguous)."""
    n = values.shape[0]
    i = np.arange(n)
    i[np.isnan(values)] = -1
    np.maximum.accumulate(i, out=i)
    start = np.flatnonzero(np.concatenate(([True], group[1:] != group[:-1])))
    first = start[np.searchsorted(start, np.arange(n), side="right") - 1]
    ok = i >= first
    out = np.full(n, np.nan)
    out[ok] = values[i[ok]]
    return out


def _demoted(prog, idx, run, planned_line, editable, fixed, owner) -> np.ndarray:
    """The last planned block of a run that a fixed line follows with no line between
    where a word could bring the spindle back: it keeps the program's S and F."""
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
        if k == fixed_lines.size:
            continue  # nothing fixed follows
        nxt = int(fixed_lines[k])
        if carriers[nxt - 1] - carriers[line] == 0:  # no line between to carry a word
            demoted[b] = True
    return demoted
