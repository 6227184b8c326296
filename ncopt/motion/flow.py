"""Which lines the control runs, and the values of their computed words.

Subroutine bodies (LinuxCNC ``o.. sub`` to ``endsub``) and the lines after M2/M30 do
not run; expressions and parameter assignments are evaluated in program order, and
where flow ncopt does not follow passes (a jump, a loop, a call) nothing stays known.
"""

from __future__ import annotations

import re

import numpy as np

from ncopt.model import LineKind, Program
from ncopt.motion.linetable import LineTable
from ncopt.motion.modal import CANNED, FLOW_CONTROL, HARMLESS_OPAQUE
from ncopt.reading.expr import Params, Unknown
from ncopt.reading.tapemarks import unread_lines_warning
from ncopt.runtime.errors import NcoptError


def evaluate(prog: Program, skip: np.ndarray | None = None):
    """Evaluate expression words and assignments in program order.

    Returns word values (n_words,) with expressions filled in (NaN where
    unknown), a (n_lines,) bool of lines whose expressions could not be known,
    and the warnings list.
    """
    values = prog.word_value.copy()
    poisoned = np.zeros(prog.n_lines, dtype=bool)
    warnings: list[str] = []
    if not prog.line_exprs and not prog.opaque_reason:
        return values, poisoned, warnings
    params = Params()
    events = sorted(set(prog.line_exprs) | set(prog.opaque_reason))
    for i in events:
        if skip is not None and skip[i]:
            continue
        if i in prog.opaque_reason:
            if prog.opaque_reason[i].upper() in FLOW_CONTROL or _is_oword(prog, i):
                params.values.clear()  # flow we do not follow: nothing known stays known
            continue
        pending = []
        for kind, a, b in prog.line_exprs[i]:
            try:
                if kind == "word":
                    w = int(np.searchsorted(prog.word_start, a))
                    values[w] = params.eval(b)
                else:
                    pending.append((params.key(a), params.eval(b)))
            except Unknown:
                poisoned[i] = True
                if kind == "assign":
                    try:
                        params.values.pop(params.key(a), None)
                    except Unknown:
                        params.values.clear()
            except (ZeroDivisionError, ValueError, OverflowError) as exc:
                raise NcoptError(f"cannot evaluate expression: {exc}; fix the expression",
                                 prog.path, i + 1, 1) from None
            except NcoptError as exc:
                raise NcoptError(f"{exc.message}; fix the parameter reference", prog.path,
                                 i + 1, 1) from None
        for key, value in pending:  # assignments take effect after the line is read
            params.values[key] = value
    return values, poisoned, warnings


_OWORD = re.compile(r"\s*/?\s*(?:N[0-9.]+\s*)?O\s*(?:<[^>]*>|[0-9]+|#<[^>]*>|#[0-9]+)\s*"
                    r"([A-Za-z]+)", re.IGNORECASE)


def oword_keyword(text: str) -> str | None:
    """The o-word keyword of a LinuxCNC control line (``sub``, ``call``...), lower case."""
    m = _OWORD.match(text)
    return m.group(1).lower() if m else None


def _is_oword(prog: Program, i: int) -> bool:
    return oword_keyword(prog.line_text(i)) is not None


def executed_lines(prog: Program, lines: LineTable, warnings: list) -> np.ndarray:
    """Lines the control runs in reading order: not subroutine bodies, not after M2/M30."""
    executed = np.ones(prog.n_lines, dtype=bool)
    depth, sub_start = 0, None
    for i in sorted(prog.opaque_reason):
        keyword = oword_keyword(prog.line_text(i))
        if keyword == "endsub":
            depth -= 1
            if depth == 0 and sub_start is not None:
                executed[sub_start:i + 1] = False
        elif keyword == "sub":
            if depth > 0:
                raise NcoptError("nested subroutine definition; end the first 'sub' with "
                                 "'endsub' before starting another", prog.path, i + 1, 1)
            depth, sub_start = depth + 1, i
    ends = np.flatnonzero(lines.has_m({2, 30}) & executed)
    if ends.size:
        executed[ends[0] + 1:] = False
    executed &= prog.line_kind != LineKind.TRAILER
    unread = unread_lines_warning(prog)
    if unread:
        warnings.append(unread)
    return executed


def l_calls(lines: LineTable, modal) -> np.ndarray:
    """(n,) bool: Sinumerik ``L100``, a subprogram call (an L word beside no G10/G76 and
    outside a canned cycle, where it is a count)."""
    return lines.present("L") & ~lines.has_g({100, 760}) & ~np.isin(modal.motion, list(CANNED))


def unread_opaque(reason: str) -> bool:
    """An opaque line (its head ``reason``) that may move the machine or hand control
    elsewhere: not a harmless statement nor an assignment ncopt keeps (``R1=``)."""
    return reason.upper() not in HARMLESS_OPAQUE and not reason.endswith("=")
