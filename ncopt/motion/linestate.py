"""What the writer needs to know of every source line (:class:`ncopt.model.LineState`):
whether it runs, the tool, S and F in force and whether they are known, block delete,
canned cycles and calls."""

from __future__ import annotations

import re

import numpy as np

from ncopt.model import LineState, Program
from ncopt.motion.flow import l_calls, unread_opaque
from ncopt.motion.linetable import LineTable
from ncopt.motion.modal import CANNED, ffill
from ncopt.motion.modalstate import Modal

_BLOCK_DELETE = re.compile(r"\s*(?:N[0-9.]+\s*)?/")


def block_delete_lines(prog: Program) -> np.ndarray:
    """(n_lines,) bool: lines that start with the block-delete slash ``/``."""
    out = np.zeros(prog.n_lines, dtype=bool)
    if "/" not in prog.text:
        return out
    raw = np.frombuffer(prog.text.encode("latin-1"), dtype=np.uint8)
    slash = np.flatnonzero(raw == ord("/"))
    for i in np.unique(np.searchsorted(prog.line_start, slash, side="right") - 1).tolist():
        out[i] = bool(_BLOCK_DELETE.match(prog.line_text(i)))
    return out


def _calls(prog: Program, lines: LineTable, modal: Modal) -> np.ndarray:
    """(n_lines,) bool: lines that hand control to code ncopt does not read (a
    subprogram or macro call, a return, flow control, a line it does not interpret)."""
    call = lines.has_m({98, 99}) | lines.has_g({650, 660})
    call |= l_calls(lines, modal)
    for i, reason in prog.opaque_reason.items():
        if unread_opaque(reason):
            call[i] = True
    return call


def _known_after(n: int, word: np.ndarray, value: np.ndarray, lost: np.ndarray) -> np.ndarray:
    """(n,) bool: the value in force is a word the program states (1), or was lost (0) at
    a ``lost`` line or a word whose value is unknown, until the next known word."""
    code = np.full(n, np.nan)
    code[word] = np.where(np.isnan(value[word]), 0.0, 1.0)
    code[lost] = 0.0
    return ffill(code, 1.0) == 1.0


def line_state(prog: Program, lines: LineTable, modal: Modal, executed: np.ndarray) -> LineState:
    """The state of every source line the writer needs (:class:`ncopt.model.LineState`)."""
    n = lines.n
    block_delete = block_delete_lines(prog)
    call = _calls(prog, lines, modal) & executed
    s_word, f_word = lines.present("S") & executed, lines.present("F") & executed
    s_known = _known_after(n, s_word, lines.value("S"), call | (block_delete & s_word))
    f_known = _known_after(n, f_word, lines.value("F"), call | (block_delete & f_word))
    return LineState(executed=executed, tool=modal.tool.astype(np.int32),
                     s_rpm=modal.spindle_rpm, f_prog=modal.feed, s_known=s_known,
                     f_known=f_known, block_delete=block_delete,
                     canned=np.isin(modal.motion, list(CANNED)) & executed, call=call)


def spindle_starts_through(prog: Program) -> np.ndarray:
    """(n_lines + 1,) int: how many times an M3/M4 has started the stopped spindle (after
    M2, M5 or M30, or at the top) up to each line; index 0 is before the first line, so a
    point's count is ``out[line + 1]`` (point 0, line -1: 0).  The spindle check of the
    rewrite and the simulator's move table count the starts alike."""
    m = prog.word_letter == ord("M")
    line, code = prog.word_line[m], prog.word_value[m]
    state = np.full(prog.n_lines, np.nan)
    state[line[np.isin(code, (2, 5, 30))]] = 0.0
    state[line[np.isin(code, (3, 4))]] = 1.0
    before = np.concatenate(([0.0], ffill(state, 0.0)[:-1]))
    starts = np.zeros(prog.n_lines + 1, dtype=np.int64)
    starts[1:] = np.cumsum((state == 1.0) & (before == 0.0))
    return starts
