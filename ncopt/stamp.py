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

# ``(ncopt 0.2.0 T4 lines=15-3800 vc=70.0198 fz=0.100144 D=16mm r=8mm z=2 band=2 ...)``:
# the lines of the planned operation are numbered as in the program without the stamp
# lines; lengths are always mm (the unit is written out, whatever the program's units).
# lines= and the units are absent from stamps of ncopt 0.1, which hold one tool each.
_STAMP = re.compile(r"^\s*(?:\(|;)\s*ncopt (?P<version>\S+) T(?P<tool>-?\d+)"
                    r"(?: lines=(?P<a>\d+)-(?P<b>\d+))? "
                    r"vc=(?P<vc>[\d.]+) fz=(?P<fz>[\d.]+) D=(?P<d>[\d.]+)(?:mm)? "
                    r"r=(?P<r>[\d.]+)(?:mm)? z=(?P<z>\d+)(?P<rest>[^)]*)\)?\s*$")
_BAND = re.compile(r"\bband=(?P<band>[\d.]+)")
_INTENT = re.compile(r"\bS0=(?P<s0>[\d.]+) F0=(?P<f0>[\d.]+)")


@dataclass(frozen=True)
class Stamp:
    """Nominal data of one planned operation (or, from ncopt 0.1, one tool) as stamped.

    lines : (first, last) 1-based lines of the planned operation, numbered without the
        stamp lines (None: every operation of the tool, an ncopt 0.1 stamp)
    band_pct : the fz band the rewrite held (None: not stamped)
    """

    tool: int
    cutting: CuttingData
    cutter: Cutter
    line: int  # 0-based
    lines: tuple | None = None
    band_pct: float | None = None
    s0_rpm: float = 0.0  # the operation's own S and cutting feed before ncopt (0: not stamped)
    f0_mm_min: float = 0.0


def read_stamps(prog: Program) -> dict[tuple, Stamp]:
    """The stamps in a program, by (tool, (first, last) lines or None)."""
    found: dict[tuple, Stamp] = {}
    for line in _comment_lines(prog, limit=400):
        m = _STAMP.match(prog.line_text(line))
        if m:
            tool = int(m.group("tool"))
            op = (int(m.group("a")), int(m.group("b"))) if m.group("a") is not None else None
            band = _BAND.search(m.group("rest") or "")
            intent = _INTENT.search(m.group("rest") or "")
            found[(tool, op)] = Stamp(
                tool, CuttingData(float(m.group("vc")), float(m.group("fz"))),
                Cutter(float(m.group("d")), int(m.group("z")), float(m.group("r"))), line, op,
                float(band.group("band")) if band else None,
                float(intent.group("s0")) if intent else 0.0,
                float(intent.group("f0")) if intent else 0.0)
    return found


def stamp_for(stamps: dict[tuple, Stamp], tool: int, lines: tuple) -> Stamp | None:
    """The stamp of the operation on ``lines`` (1-based, without the stamp lines) of
    T``tool``, or the tool's own (ncopt 0.1)."""
    return stamps.get((tool, lines)) or stamps.get((tool, None))


def unstamped_line(stamps: dict[tuple, Stamp], line: int) -> int:
    """1-based number of 0-based ``line`` in the program without its stamp lines."""
    return line + 1 - sum(1 for st in stamps.values() if st.line < line)


def stamped_line(stamps: dict[tuple, Stamp], number: int) -> int:
    """0-based line of the 1-based ``number`` of the program without its stamp lines."""
    first = min((st.line for st in stamps.values()), default=None)
    if first is None or number - 1 < first:
        return number - 1
    return number - 1 + len({st.line for st in stamps.values()})


def as_stamped(cut: CuttingData) -> CuttingData:
    """The cutting data exactly as the stamp will hold it, so a later run that reads
    the stamp plans with the very same numbers (and changes nothing)."""
    return CuttingData(float(vc_text(cut.vc_m_min)), float(f"{cut.fz_mm:.6f}"))


def vc_text(vc_m_min: float) -> str:
    """vc as the stamp writes it: 4 decimals where they hold it exactly (``90.0000``),
    else 10 significant digits.  The program's own vc (pi D S0) rounded to 4 decimals
    put the full diameter's S a rounding error under S0 (S3999 for S4000 at D6)."""
    short = f"{vc_m_min:.4f}"
    return short if float(short) == vc_m_min else f"{vc_m_min:.10g}"


def stamp_lines(plans, semicolon: bool, band_pct: float | None = None) -> list[str]:
    """One stamp comment per planned operation (lengths in mm, whatever the program's
    units); ``p.lines``: its (first, last) lines, numbered without stamp lines."""
    out = []
    band = f" band={band_pct:g}" if band_pct is not None else ""
    for p in plans:
        body = (f"ncopt {__version__} T{p.tool} lines={p.lines[0]}-{p.lines[1]} "
                f"vc={vc_text(p.cutting.vc_m_min)} "
                f"fz={p.cutting.fz_mm:.6f} D={p.cutter.diameter_mm:g}mm "
                f"r={p.cutter.corner_radius_mm:g}mm z={p.cutter.teeth}{band} "
                f"S0={p.s0_rpm:.10g} F0={p.cutting_feed_mm_min:.10g}mm/min "
                "- S and F for constant vc and fz")
        out.append(f"; {body}" if semicolon else f"({body})")
    return out


def stamp_edit(prog: Program, plans, band_pct: float | None = None) -> Edit | None:
    """Insert the stamp, or replace an existing one (None when it is already right)."""
    semicolon = _uses_semicolons(prog)
    nl = prog.newline
    text = nl.join(stamp_lines(plans, semicolon, band_pct)) + nl
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
    """After a leading %, %_N_..._MPF, O number or ':' line (and after the header of blank
    and comment lines a program may have before its opening %: a stamp above that % is
    outside the program, where LinuxCNC refuses it); else the first line."""
    i = 0
    while i < prog.n_lines and prog.line_kind[i] == LineKind.BLANK:
        i += 1
    if i >= prog.n_lines or prog.line_kind[i] != LineKind.PERCENT:
        i = 0  # no opening % after them: the program starts at its first line
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
