"""The comment a rewrite leaves in the program: the ncopt version and the
nominal cutting data it planned with.

Running ncopt again on a stamped program re-plans from the stamped vc and fz
instead of misreading the optimised S and F words as nominal, and the
simulator judges it against the same targets.  The stamp uses the program's
own comment syntax (``( ... )`` or ``; ...``) and sits after the leading tape
mark and program-number lines, where controls accept a comment.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from . import __version__
from .model import Cutter, CuttingData, Edit, LineKind, Program

_STAMP = re.compile(r"^\s*(?:\(|;)\s*ncopt (?P<version>\S+) T(?P<tool>-?\d+) vc=(?P<vc>[\d.]+) "
                    r"fz=(?P<fz>[\d.]+) D=(?P<d>[\d.]+) r=(?P<r>[\d.]+) z=(?P<z>\d+)"
                    r"(?P<rest>[^)]*)\)?\s*$")


@dataclass(frozen=True)
class Stamp:
    """Nominal data of one planned tool as stamped in the program."""

    tool: int
    cutting: CuttingData
    cutter: Cutter
    line: int  # 0-based


def read_stamps(prog: Program) -> dict[int, Stamp]:
    """The stamps in a program, by tool number."""
    found: dict[int, Stamp] = {}
    for line in _comment_lines(prog, limit=200):
        m = _STAMP.match(prog.line_text(line))
        if m:
            tool = int(m.group("tool"))
            found[tool] = Stamp(tool, CuttingData(float(m.group("vc")), float(m.group("fz"))),
                                Cutter(float(m.group("d")), int(m.group("z")), float(m.group("r"))),
                                line)
    return found


def as_stamped(cut: CuttingData) -> CuttingData:
    """The cutting data exactly as the stamp will hold it, so a later run that reads
    the stamp plans with the very same numbers (and changes nothing)."""
    return CuttingData(float(f"{cut.vc_m_min:.4f}"), float(f"{cut.fz_mm:.6f}"))


def stamp_lines(plans, semicolon: bool) -> list[str]:
    """One stamp comment per planned tool."""
    out = []
    for p in plans:
        body = (f"ncopt {__version__} T{p.tool} vc={p.cutting.vc_m_min:.4f} "
                f"fz={p.cutting.fz_mm:.6f} D={p.cutter.diameter_mm:g} "
                f"r={p.cutter.corner_radius_mm:g} z={p.cutter.teeth} "
                "- S and F rewritten for constant vc and fz")
        out.append(f"; {body}" if semicolon else f"({body})")
    return out


def stamp_edit(prog: Program, plans) -> Edit | None:
    """Insert the stamp, or replace an existing one (None when it is already right)."""
    semicolon = _uses_semicolons(prog)
    nl = prog.newline
    text = nl.join(stamp_lines(plans, semicolon)) + nl
    old = sorted(s.line for s in read_stamps(prog).values())
    if old:
        start, end = int(prog.line_start[old[0]]), int(prog.line_start[old[-1] + 1])
        if prog.text[start:end] == text:
            return None
        return Edit(start, end, text)
    at = int(prog.line_start[_stamp_position(prog)])
    if at == len(prog.text) and prog.text and not prog.text.endswith("\n"):
        text = nl + text
    return Edit(at, at, text)


def _comment_lines(prog: Program, limit: int) -> list[int]:
    """Early lines that may hold a stamp (it is always near the top)."""
    n = min(prog.n_lines, limit)
    return [i for i in range(n) if prog.line_kind[i] in (LineKind.BLANK, LineKind.WORDS)
            and ("ncopt" in prog.line_text(i))]


def _stamp_position(prog: Program) -> int:
    """After a leading %, %_N_..._MPF, O number or ':' line; else the first line."""
    i = 0
    while i < prog.n_lines:
        text = prog.line_text(i).strip()
        words = prog.word_letter[prog.word_line == i]
        header = prog.line_kind[i] == LineKind.PERCENT or text.startswith(":") or (
            words.size > 0 and np.all(words == ord("O")))
        if not header:
            break
        i += 1
    return i


def _uses_semicolons(prog: Program) -> bool:
    sample = prog.text[:200_000]
    return sample.count(";") > sample.count("(")
