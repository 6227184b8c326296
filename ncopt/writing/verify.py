"""The checks after every rewrite: the output differs from the input in S and F words
only, every line ncopt leaves alone is the input's, the program's own S and F are in
force at every fixed line, and rewriting the output again changes nothing."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ncopt.model import Program, Toolpath
from ncopt.motion.modal import ffill
from ncopt.planning.regions import Scope
from ncopt.reading.stamp import read_stamps
from ncopt.runtime.errors import VerificationError
from ncopt.writing.edits import F_CODE, S_CODE, Targets, WordStyle, masked, plan_edits
from ncopt.writing.targets import rapid_lines


def check_output(prog: Program, out_prog: Program, tp: Toolpath, targets: Targets,
                 s_style: WordStyle, f_style: WordStyle, scope: Scope | None = None,
                 masked_input: str | None = None) -> None:
    """The checks run after every rewrite on ``out_prog``, the output read as the input
    ``prog`` was; raises VerificationError, writes nothing.

    The stamp lines are whole comment lines at the top, so masking keeps the line
    structure and every target line moves by the same count.  With S and F masked the
    output equals the input, so every geometry word is the input's own: the toolpath
    cannot have changed.  Every line ncopt may not edit is byte for byte the input's,
    and the S and F in force at every fixed line are the program's own.  Rewriting the
    output again to the same ``targets`` changes nothing.
    ``masked_input``: :func:`masked_input_of` ``prog``, if it was made already.
    """
    in_stamps = _stamp_lines(prog)
    out_stamps = _stamp_lines(out_prog)
    if masked_input is None:
        masked_input = masked_input_of(prog)
    same = _masked_without(out_prog, out_stamps) == masked_input
    del masked_input
    if not same:
        raise VerificationError("the rewrite changed more than S and F words; nothing written",
                                prog.path)
    shift = len(out_stamps) - len(in_stamps)
    if scope is not None:
        _check_untouched(prog, out_prog, in_stamps, out_stamps, scope, tp)
    shifted = replace(targets, line=targets.line + shift)
    editable = None
    if scope is not None:
        editable = _shift_lines(scope.editable, out_prog.n_lines, in_stamps, out_stamps)
    f_kept = _shift_lines(rapid_lines(tp, prog.n_lines), out_prog.n_lines, in_stamps,
                          out_stamps)
    again = plan_edits(out_prog, shifted, s_style, f_style, editable, f_kept)
    if again:
        line = int(np.searchsorted(out_prog.line_start, again[0].start, side="right"))
        raise VerificationError("rewriting the result again would change it; nothing written",
                                prog.path, line)


def _stamp_lines(prog: Program) -> list:
    """0-based lines of the program's ncopt stamp, in order (its header lines too)."""
    return sorted(read_stamps(prog).lines)


def masked_input_of(prog: Program) -> str:
    """The input's side of the verification's comparison: S/F words masked, stamps out."""
    return _masked_without(prog, _stamp_lines(prog))


def _kept_lines(prog: Program, drop: list) -> np.ndarray:
    """0-based lines of ``prog`` without the (stamp) lines ``drop``."""
    keep = np.ones(prog.n_lines, dtype=bool)
    keep[drop] = False
    return np.flatnonzero(keep)


def _shift_lines(mask: np.ndarray, n_out: int, in_stamps: list, out_stamps: list) -> np.ndarray:
    """A per-line mask of the input carried to the output's lines (stamps: False)."""
    src = np.ones(mask.shape[0], dtype=bool)
    src[in_stamps] = False
    dst = np.ones(n_out, dtype=bool)
    dst[out_stamps] = False
    out = np.zeros(n_out, dtype=bool)
    out[np.flatnonzero(dst)] = mask[np.flatnonzero(src)]
    return out


def _check_untouched(prog: Program, out_prog: Program, in_stamps: list, out_stamps: list,
                     scope: Scope, tp: Toolpath) -> None:
    """Lines outside the scope are byte-identical; S and F in force at every fixed line
    are the program's own."""
    a, b = _kept_lines(prog, in_stamps), _kept_lines(out_prog, out_stamps)
    if a.size != b.size:
        raise VerificationError("the rewrite changed the program's lines; nothing written",
                                prog.path)
    fixed_only = ~scope.editable[a]
    for i, j in zip(a[fixed_only].tolist(), b[fixed_only].tolist()):
        if prog.text[prog.line_start[i]:prog.line_start[i + 1]] != \
                out_prog.text[out_prog.line_start[j]:out_prog.line_start[j + 1]]:
            raise VerificationError("a line ncopt leaves alone changed; nothing written",
                                    prog.path, i + 1)
    check = scope.fixed[a]
    if not check.any():
        return
    executed = tp.lines.executed
    out_executed = _shift_lines(executed, out_prog.n_lines, in_stamps, out_stamps)
    for code in (S_CODE, F_CODE):
        before = _in_force(prog, code, executed)[a]
        after = _in_force(out_prog, code, out_executed)[b]
        bad = np.flatnonzero(check & ~((before == after) | (np.isnan(before) & np.isnan(after))))
        if bad.size:
            raise VerificationError(
                f"the program's own {chr(code)} is not in force at a line ncopt leaves alone; "
                "nothing written", prog.path, int(a[bad[0]]) + 1)


def _in_force(prog: Program, code: int, executed: np.ndarray) -> np.ndarray:
    """(n_lines,) value of the last ``code`` word at or before each line (executed lines)."""
    sel = np.flatnonzero(prog.word_letter == code)
    sel = sel[executed[prog.word_line[sel]]]
    per_line = np.full(prog.n_lines, np.nan)
    per_line[prog.word_line[sel]] = np.nan_to_num(prog.word_value[sel], nan=-1.0)
    return ffill(per_line)


def _masked_without(prog: Program, drop: list) -> str:
    """The program with S/F words masked, without the given (stamp) lines.

    Masking keeps every line ending, so the program's own line numbers hold;
    the stamp lines are near the top, so only the head is split.
    """
    text = masked(prog)
    if not drop:
        return text
    head = text.split("\n", max(drop) + 1)
    rest = head.pop() if len(head) > max(drop) + 1 else ""
    return "".join(line + "\n" for i, line in enumerate(head) if i not in drop) + rest
