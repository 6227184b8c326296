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
from dataclasses import dataclass, replace

import numpy as np

from ncopt import __version__
from ncopt.model import Cutter, CuttingData, Edit, LineKind, Program
from ncopt.reading.stampline import STAMP_LINE  # noqa: F401 (re-exported)
from ncopt.reading.stampline import INFO_BODY, STAMP_START

# The stamp, in the program's comment syntax, every line at most STAMP_WIDTH characters:
#
#   (ncopt 0.1.0 2026-11-27: S and F for constant vc and fz)
#   (ncopt from bowl.mpf)
#   (ncopt machine paper-direct-15000: 227 rad/s2, 15000 RPM)
#   (ncopt cutting time 59.3 -> 28.7 min, estimated)
#   (ncopt T4 lines=1-21902 vc=70.0198 fz=0.100144 band=2)
#   (ncopt T4 D=16mm r=8mm z=2 S0=1393 F0=279mm/min)
#
# (``S0~1393``: the program's S was not one value over the operation, 1393 its median)
#
# two lines per planned operation (a third, ``(ncopt T2 roughing ap=3mm)``, for a roughing
# operation planned on the remaining material of its step-down) (T? where the program names no tool); its lines are
# numbered as in the program without the stamp lines; lengths are always mm.  A re-run
# that plans the same keeps the stamp as it is (its date and source included).  Stamps
# of ncopt before this form are one line per operation (or per tool, ncopt 0.1) and are
# still read: ``(ncopt 0.2.0 T4 lines=15-3800 vc=70.0198 fz=0.100144 D=16mm r=8mm z=2 ...)``.
STAMP_WIDTH = 72
_OLD = re.compile(STAMP_START + r"(?P<version>\S+) T(?P<tool>-?\d+)"
                  r"(?: lines=(?P<a>\d+)-(?P<b>\d+))? "
                  r"vc=(?P<vc>[\d.]+) fz=(?P<fz>[\d.]+) D=(?P<d>[\d.]+)(?:mm)? "
                  r"r=(?P<r>[\d.]+)(?:mm)? z=(?P<z>\d+)(?P<rest>[^)]*)\)?\s*$")
_BAND = re.compile(r"\bband=(?P<band>[\d.]+)")
_INTENT = re.compile(r"\bS0=(?P<s0>[\d.]+) F0=(?P<f0>[\d.]+)")
_OP_A = re.compile(STAMP_START + r"T(?P<tool>-?\d+|\?) lines=(?P<a>\d+)-(?P<b>\d+) "
                   r"vc=(?P<vc>[\d.]+) fz=(?P<fz>[\d.]+)(?: band=(?P<band>[\d.]+))?\s*\)?\s*$")
_OP_B = re.compile(STAMP_START + r"T(?P<tool>-?\d+|\?) D=(?P<d>[\d.]+)mm "
                   r"r=(?P<r>[\d.]+)mm z=(?P<z>\d+)(?: S0(?P<s0op>[=~])(?P<s0>[\d.]+) "
                   r"F0=(?P<f0>[\d.]+)mm/min)?\s*\)?\s*$")
# a roughing operation planned where the edge meets the remaining material (a third line)
_OP_C = re.compile(STAMP_START + r"T(?P<tool>-?\d+|\?) roughing ap=(?P<ap>[\d.]+)mm\s*\)?\s*$")
_INFO = re.compile(STAMP_START + INFO_BODY)
_FROM = re.compile(STAMP_START + "from ")
_TIMES = re.compile(STAMP_START + r"cutting time (?P<before>[\d.]+) -> ")
_MACHINE = re.compile(STAMP_START + "machine ")
_SPINDLE = re.compile(r"\bncopt machine (?:.*: )?(?P<accel>[\d.]+) rad/s2, (?P<rpm>[\d.]+) RPM")


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
    line: int  # 0-based, its first line
    lines: tuple[int, int] | None = None
    band_pct: float | None = None
    s0_rpm: float = 0.0  # the operation's own S and cutting feed before ncopt (S0=0: the
    f0_mm_min: float = 0.0  # program gave no S); F0 0: not stamped
    ap_mm: float = float("nan")  # roughing: the material height its contacts took, mm
    s0_varies: bool = False  # the program's own S was not one value (S0~: S0 its median)


class Stamps(dict):
    """The stamps of a program by (tool, (first, last) lines or None); ``lines``: every
    0-based line of the stamp block (its header lines too), sorted; ``spindle``: the
    (accel rad/s^2, max RPM) of the machine it was planned for (None: not stamped)."""

    lines: list[int] = []
    spindle: tuple[float, float] | None = None


@dataclass(frozen=True)
class StampInfo:
    """What the stamp's header says besides the plans: the date (ISO), the program it was
    planned from, the machine (a profile's name and its spindle) and the estimated whole
    program cutting time before and after, minutes."""

    date: str
    source: str
    machine: str
    time_before_min: float
    time_after_min: float


def read_stamps(prog: Program) -> Stamps:
    """The stamps in a program, by (tool, (first, last) lines or None)."""
    found = Stamps()
    found.lines = []
    pending = None  # (line, match of _OP_A) waiting for its second line
    last = None  # the key of the stamp just read, for its roughing line
    for line in _comment_lines(prog, limit=400):
        text = prog.line_text(line)
        m = _OLD.match(text)
        if m:
            found.lines.append(line)
            _add(found, line, _tool(m), _op(m), m["vc"], m["fz"], m["d"], m["r"], m["z"],
                 _BAND.search(m["rest"] or ""), _INTENT.search(m["rest"] or ""))
            continue
        a = _OP_A.match(text)
        if a:
            found.lines.append(line)
            pending = (line, a)
            continue
        b = _OP_B.match(text)
        if b and pending is not None and _tool(b) == _tool(pending[1]):
            found.lines.append(line)
            at, a = pending
            _add(found, at, _tool(a), _op(a), a["vc"], a["fz"], b["d"], b["r"], b["z"],
                 a if a["band"] else None, b if b["s0"] else None)
            pending = None
            last = (_tool(a), _op(a))
            continue
        c = _OP_C.match(text)
        if c and last is not None and _tool(c) == last[0]:
            found.lines.append(line)
            found[last] = replace(found[last], ap_mm=float(c["ap"]))
            last = None
            continue
        if _INFO.match(text):
            found.lines.append(line)
            spindle = _SPINDLE.search(text)
            if spindle:
                found.spindle = (float(spindle["accel"]), float(spindle["rpm"]))
    return found


def _tool(m) -> int:
    return -1 if m["tool"] == "?" else int(m["tool"])


def _op(m) -> tuple | None:
    return (int(m["a"]), int(m["b"])) if m["a"] is not None else None


def _add(found, line, tool, op, vc, fz, d, r, z, band, intent) -> None:
    found[(tool, op)] = Stamp(
        tool, CuttingData(float(vc), float(fz)), Cutter(float(d), int(z), float(r)), line, op,
        float(band["band"]) if band else None,
        float(intent["s0"]) if intent else 0.0, float(intent["f0"]) if intent else 0.0,
        s0_varies=bool(intent) and intent.groupdict().get("s0op") == "~")


def stamp_for(stamps: dict[tuple, Stamp], tool: int, lines: tuple) -> Stamp | None:
    """The stamp of the operation on ``lines`` (1-based, without the stamp lines) of
    T``tool``, or the tool's own (ncopt 0.1)."""
    return stamps.get((tool, lines)) or stamps.get((tool, None))


def _stamp_block(stamps) -> list:
    return list(stamps.lines) if isinstance(stamps, Stamps) else [
        st.line for st in stamps.values()]


def unstamped_line(stamps: dict[tuple, Stamp], line: int) -> int:
    """1-based number of 0-based ``line`` in the program without its stamp lines."""
    return line + 1 - sum(1 for at in _stamp_block(stamps) if at < line)


def stamped_line(stamps: dict[tuple, Stamp], number: int) -> int:
    """0-based line of the 1-based ``number`` of the program without its stamp lines."""
    block = _stamp_block(stamps)
    first = min(block, default=None)
    if first is None or number - 1 < first:
        return number - 1
    return number - 1 + len(set(block))


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


def _plan_lines(plans, band_pct: float | None) -> list[str]:
    """Two lines per planned operation (``p.lines``: its (first, last) lines, numbered
    without stamp lines); lengths in mm, whatever the program's units."""
    band = f" band={band_pct:g}" if band_pct is not None else ""
    out = []
    for p in plans:
        t = f"T{p.tool}" if p.tool >= 0 else "T?"
        out.append(f"ncopt {t} lines={p.lines[0]}-{p.lines[1]} "
                   f"vc={vc_text(p.cutting.vc_m_min)} fz={p.cutting.fz_mm:.6f}{band}")
        # the operation's own S and cutting feed (S0=0: the program gives no S, it was
        # planned from --vc and --fz), where its cutting feed is known
        s0, f0 = p.s0_rpm, p.cutting_feed_mm_min
        # (S0~: the program's S varied over the operation, S0 is its median)
        op = "~" if getattr(p, "s_varies", False) else "="
        own = (f" S0{op}{max(s0, 0.0):.10g} F0={f0:.10g}mm/min" if 0 < f0 < 1e12 else "")
        out.append(f"ncopt {t} D={p.cutter.diameter_mm:g}mm r={p.cutter.corner_radius_mm:g}mm "
                   f"z={p.cutter.teeth}{own}")
        ap = getattr(p, "ap_mm", float("nan"))
        if ap == ap:  # a roughing operation: a re-run plans it on the same material again
            out.append(f"ncopt {t} roughing ap={ap:.10g}mm")
    return out


def _info_lines(info: StampInfo | None, source_line: str | None) -> list[str]:
    if info is None:
        return []
    room = STAMP_WIDTH - 2 - len("ncopt from ")
    source = _safe(info.source)
    source = source if len(source) <= room else "..." + source[-(room - 3):]
    return [f"ncopt {__version__} {info.date}: S and F for constant vc and fz",
            source_line or f"ncopt from {source}",
            _fit(f"ncopt machine {_safe(info.machine)}"),
            f"ncopt cutting time {info.time_before_min:.1f} -> {info.time_after_min:.1f} min, "
            "estimated"]


def _safe(text: str) -> str:
    """Text a comment can hold on any control: no parentheses or semicolons, ASCII."""
    text = text.encode("ascii", "replace").decode("ascii")
    return re.sub(r"[()\[\];\r\n]", "_", text)


def _fit(text: str) -> str:
    room = STAMP_WIDTH - 2
    return text if len(text) <= room else text[:room - 3] + "..."


def stamp_lines(plans, semicolon: bool, band_pct: float | None = None,
                info: StampInfo | None = None, source_line: str | None = None) -> list[str]:
    """The stamp's comment lines: the header (``info``; ``source_line``: an earlier stamp's
    "from" line, kept), then two lines per planned operation."""
    body = _info_lines(info, source_line) + _plan_lines(plans, band_pct)
    return [f"; {b}" if semicolon else f"({b})" for b in body]


def stamp_edit(prog: Program, plans, band_pct: float | None = None,
               info: StampInfo | None = None) -> Edit | None:
    """Insert the stamp, or replace an existing one (None when it plans the same: its
    date and source then stay as they are)."""
    semicolon = _uses_semicolons(prog)
    nl = prog.newline
    old = read_stamps(prog).lines
    if old:
        start, end = int(prog.line_start[old[0]]), int(prog.line_start[old[-1] + 1])
        present = prog.text[start:end].splitlines()
        # the plan and the machine it was made for the same: the stamp stays (a re-run's
        # times "before" are the planned program's own, its date and file name today's)
        if info is not None and any(_INFO.match(ln) for ln in present) and (
                _decisive(present) == _decisive(stamp_lines(plans, semicolon, band_pct, info))):
            return None
        source = next((_body(ln) for ln in present if _FROM.match(ln)), None)
        before = next((float(m["before"]) for m in map(_TIMES.match, present) if m), None)
        if info is not None and before is not None:  # "before" is the original's, as stamped
            info = replace(info, time_before_min=before)
        text = nl.join(stamp_lines(plans, semicolon, band_pct, info, source)) + nl
        return None if prog.text[start:end] == text else Edit(start, end, text)
    text = nl.join(stamp_lines(plans, semicolon, band_pct, info)) + nl
    at = int(prog.line_start[_stamp_position(prog)])
    if at == len(prog.text) and prog.text and not prog.text.endswith("\n"):
        text = nl + text
    return Edit(at, at, text)


def _decisive(lines: list[str]) -> list[str]:
    """The stamp lines a re-run must find as it would write them: the plans' data and the
    machine."""
    return [ln for ln in lines if _OP_A.match(ln) or _OP_B.match(ln) or _OP_C.match(ln)
            or _MACHINE.match(ln)]


def _body(line: str) -> str:
    """A comment line's text without its ``( )`` or ``;``."""
    text = line.strip()
    return text[1:-1].strip() if text.startswith("(") else text[1:].strip()


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
