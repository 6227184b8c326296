"""What ncopt understands of a program before it changes anything: how it reads it, and
its operations as ``ncopt rewrite`` would split and judge them (planned, or left and why),
without planning any."""

from __future__ import annotations

import re
from dataclasses import asdict, dataclass

import numpy as np

from ncopt.reading.dialect import (HEIDENHAIN, SINUMERIK, apply_decimal_point,
                      check_convention_applies, decimal_point_issue, detect)
from ncopt.motion.interp import interpret, tcp_for
from ncopt.motion.modal import INCH_HEADER
from ncopt.motion.kinematics import tilt_deg
from ncopt.motion.times import feed_minutes
from ncopt.model import Job, LineKind, Machine, Motion, Program
from ncopt.reading.parse import parse_text
from ncopt.planning.judging import judge
from ncopt.planning.tooltable import ToolInfo, tool_table
from ncopt.runtime.stdio import count, styled


@dataclass(frozen=True)
class JudgedOperation:
    """One operation as ``ncopt rewrite`` would split and judge it.

    lines : ``first-last``, 1-based;  time_min : its feed moves at the programmed feed
    (at most the machine's highest feed), min
    """

    name: str
    tool: int
    lines: str
    kind: str
    planned: bool
    reason: str
    time_min: float


# A tool comment: (T, kind, diameter, corner radius or None, line, teeth or None, teeth
# line or None, unit or None: the program's, source); lengths in the comment's unit
ToolRow = tuple[int, str, float, float | None, int, int | None, int | None, str | None, str]


@dataclass(frozen=True)
class Inspection:
    """A program as ncopt reads it.  Lengths in mm, feeds in mm/min, times in min."""

    path: str
    dialect: str
    dialect_marks: tuple[str, ...]
    units: str
    lines: int
    blocks: int
    moves: int
    feed_moves: int
    rapids: int
    arcs: int
    unknown_moves: int
    tools: tuple[ToolRow, ...]  # from the comments
    tools_used: tuple[int, ...]  # T numbers with feed moves
    opaque: tuple[tuple[int, str], ...]  # (line, construct) left alone
    warnings: tuple[str, ...]
    s_range_rpm: tuple[float, float]
    f_range_mm_min: tuple[float, float]
    cut_length_mm: float
    cut_time_min: float
    kinematics: str | None = None  # what gave the tool axes (5-axis), None: always +Z
    tilt_range_deg: tuple[float, float] = (0.0, 0.0)  # tool axis from +Z, the readable feed moves
    unknown_lines: tuple[tuple[int, int], ...] = ()  # 1-based runs of the lines of unknown_moves
    operations: tuple[JudgedOperation, ...] = ()  # in program order
    operations_not_judged: str = ""  # why there are none where the program has moves

    def to_dict(self) -> dict:
        return asdict(self)


def inspect_text(text: str, path: str = "<input>", *, dialect: str | None = None,
                 decimal_point: str | None = None,
                 kinematics: str | None = None,
                 max_feed_mm_min: float = float("inf"), job=None) -> Inspection:
    """Parse and interpret; raises a located NcoptError when the program is unreadable.

    ``dialect`` selects the grammar (None: the generic one) and, with the
    detected dialect when None, whether values need a decimal point
    convention; ``decimal_point`` is that convention (see
    :data:`ncopt.reading.dialect.DECIMAL_POINT_CONVENTIONS`).  A value that depends on
    an unknown convention is reported among the warnings, and the operations are
    then not judged (rewrite refuses such a program).  ``job``: an
    :class:`ncopt.model.Job` whose cutter, cutting data, ``tool`` and ``operations``
    the judgement follows (None: the cutters of the program's tool comments).
    """
    prog = parse_text(text, path, dialect=dialect)
    found = detect(text)
    check_convention_applies(dialect or found.name, decimal_point, path)
    issue = decimal_point_issue(prog, dialect or found.name, decimal_point)
    if decimal_point is not None:
        prog = apply_decimal_point(prog, decimal_point)
    tcp = None if job is None else tcp_for(job.tcp, dialect or found.name)
    tp = interpret(prog, kinematics=kinematics, tcp=tcp)
    motion = tp.motion[1:]
    feed = np.isin(motion, [Motion.LINEAR, Motion.ARC_CW, Motion.ARC_CCW])
    arcs = np.isin(motion, [Motion.ARC_CW, Motion.ARC_CCW])
    lines_with_arcs = np.unique(tp.line[1:][arcs])
    known = tp.known[1:]
    cut = feed & known & (tp.feed_mm_min[1:] > 0)
    length = tp.seg_len_mm[1:]
    s_on = tp.spindle_rpm[1:][feed & tp.spindle_on[1:]]
    f_vals = tp.feed_mm_min[1:][feed]
    f_vals = f_vals[np.isfinite(f_vals)]
    units = "inch" if tp.line_inch is not None and tp.line_inch.any() else "mm"
    table = tool_table(prog)
    return Inspection(
        path=path, dialect=dialect or found.name, dialect_marks=() if dialect else found.marks, units=units,
        lines=prog.n_lines, blocks=int(np.sum(prog.line_kind == LineKind.WORDS)),
        moves=int(np.unique(tp.line[1:]).size), feed_moves=int(np.unique(tp.line[1:][feed]).size),
        rapids=int(np.unique(tp.line[1:][motion == Motion.RAPID]).size),
        arcs=int(lines_with_arcs.size), unknown_moves=int(np.unique(tp.line[1:][~known]).size),
        tools=tuple(_tool_row(t) for t in table.values()),
        tools_used=tuple(int(t) for t in np.unique(tp.tool[1:][feed])),
        opaque=tuple((i + 1, why) for i, why in sorted(prog.opaque_reason.items())),
        warnings=((f"{path}:{issue.line}:{issue.column}: {issue.message}",) if issue else ())
        + _notes(prog, dialect or found.name, table) + tuple(tp.warnings),
        s_range_rpm=(float(s_on.min()), float(s_on.max())) if s_on.size else (0.0, 0.0),
        f_range_mm_min=(float(f_vals.min()), float(f_vals.max())) if f_vals.size else (0.0, 0.0),
        cut_length_mm=float(length[cut].sum()),
        cut_time_min=float(feed_minutes(tp, None, max_feed_mm_min).sum()),
        kinematics=tp.kinematics, tilt_range_deg=_tilt_range(tp, feed & known),
        unknown_lines=_runs(np.unique(tp.line[1:][~known]) + 1),
        operations=() if issue else judge_operations(prog, tp, job, max_feed_mm_min),
        operations_not_judged=(f"{path}: rewrite refuses the program until --decimal-point "
                               "is given (see the warning)") if issue else "")


def judge_operations(prog: Program, tp, job=None,
                     max_feed_mm_min: float = float("inf")) -> tuple[JudgedOperation, ...]:
    """The operations as ``ncopt rewrite`` splits and judges them, without planning:
    :func:`ncopt.planning.judging.judge`, as :func:`ncopt.planning.plans.plan_program`
    calls it before it plans (tests/test_shopfloor_cli.py checks that both agree on real
    programs).  Raises as the rewrite does (UsageError for --diameter on a program of
    several tools, ...)."""
    if job is None:
        job = Job(machine=Machine(float("nan"), float("nan")))  # judging needs no spindle
    ops = judge(prog, tp, job).ops
    minutes = feed_minutes(tp, None, max_feed_mm_min)
    out = []
    for op in ops:
        a, b = np.searchsorted(tp.line[1:], [op.first_line, op.last_line + 1]) + 1
        out.append(JudgedOperation(op.name, op.tool, f"{op.first_line + 1}-{op.last_line + 1}",
                                   op.kind, op.planned, op.reason, float(minutes[a:b].sum())))
    return tuple(out)


def _runs(lines: np.ndarray) -> tuple[tuple[int, int], ...]:
    """(first, last) of each run of consecutive numbers in sorted ``lines``."""
    if lines.size == 0:
        return ()
    breaks = np.flatnonzero(np.diff(lines) != 1)
    firsts = np.concatenate(([lines[0]], lines[breaks + 1]))
    lasts = np.concatenate((lines[breaks], [lines[-1]]))
    return tuple((int(a), int(b)) for a, b in zip(firsts, lasts))


def _tilt_range(tp, moves: np.ndarray) -> tuple[float, float]:
    """(lowest, highest) angle of the tool axis from +Z at the ends of ``moves``, deg."""
    if tp.tool_axis is None or not moves.any():
        return (0.0, 0.0)
    tilt = tilt_deg(tp.tool_axis[1:][moves])
    return (float(tilt.min()), float(tilt.max()))


def render_inspection(info: Inspection, out) -> None:
    """The inspection as a few readable lines on a rich console."""
    say = lambda text: out.print(styled(text))  # noqa: E731
    why = count(len(info.dialect_marks), "mark")
    say(f"{info.path}: {info.dialect} dialect ({why}), {info.units}, {count(info.lines, 'line')}")
    say(f"  blocks {info.blocks}, moves {info.moves} (feed {info.feed_moves}, rapid "
        f"{info.rapids}, arcs {info.arcs}), not plannable {info.unknown_moves}"
        + (f" ({line_runs(info.unknown_lines)})" if info.unknown_lines else ""))
    for t in info.tools:
        say(f"  tool {_name(t[0])}: {_describe_tool(t, info.units)}")
    say(f"  tools cutting: {', '.join(_name(t) for t in info.tools_used) or 'none'}")
    say(f"  S {info.s_range_rpm[0]:g}..{info.s_range_rpm[1]:g} RPM, "
        f"F {info.f_range_mm_min[0]:g}..{info.f_range_mm_min[1]:g} mm/min")
    say(f"  cutting {info.cut_length_mm:.0f} mm in {info.cut_time_min:.1f} min at the "
        "programmed feed")
    if info.kinematics is not None:
        say(f"  5-axis: tool axes from {_axes_from(info.kinematics)}, tilted "
            f"{info.tilt_range_deg[0]:.1f}..{info.tilt_range_deg[1]:.1f} deg from +Z on the "
            "moves ncopt can plan")
    for line, why in info.opaque[:20]:
        say(f"  line {line}: '{why}' left alone")
    if len(info.opaque) > 20:
        say(f"  ... {count(len(info.opaque) - 20, 'more line')} left alone")
    _render_operations(info, say)
    for w in info.warnings[:20]:
        say(f"  warning: {w}")


def _render_operations(info: Inspection, say) -> None:
    """The operations as rewrite would judge them, in the rewrite summary's words."""
    if info.operations_not_judged:
        say(f"  operations: not judged: {info.operations_not_judged}")
        return
    if not info.operations:
        return
    planned = sum(o.planned for o in info.operations)
    say(f"  operations: {planned} of {count(len(info.operations), 'operation')} would be "
        "planned (times at the programmed feed):")
    for o in info.operations:
        head = f"    {o.name} ({_name(o.tool) if o.tool >= 0 else 'T?'}, lines {o.lines}): "
        say(head + (f"planned, {o.kind.lower()}, {o.time_min:.1f} min" if o.planned else
                    f"left as programmed ({o.time_min:.1f} min): {o.reason}"))


RUNS_SHOWN = 8  # runs of lines named before "and N more"


def line_runs(runs: tuple[tuple[int, int], ...]) -> str:
    """``line 5``, ``lines 5-9, 12``, ``lines 5-9, ... and 3 more runs``."""
    shown = ", ".join(f"{a}" if a == b else f"{a}-{b}" for a, b in runs[:RUNS_SHOWN])
    more = f" and {count(len(runs) - RUNS_SHOWN, 'more run')}" if len(runs) > RUNS_SHOWN else ""
    single = len(runs) == 1 and runs[0][0] == runs[0][1]
    return f"{'line' if single else 'lines'} {shown}{more}"


def _axes_from(kinematics: str) -> str:
    return "the program's tool vectors" if kinematics == "vector" else \
        f"the rotary axes through the {kinematics} kinematics"


def _name(tool: int) -> str:
    return f"T{tool}" if tool >= 0 else "a tool with no T number"


def _tool_row(t: ToolInfo) -> ToolRow:
    corner = None if np.isnan(t.corner_radius) else t.corner_radius
    return (t.number, t.kind, t.diameter, corner, t.line, t.teeth, t.teeth_line, t.unit,
            t.source)


def _describe_tool(row: ToolRow, program_units: str) -> str:
    """``ball D16 r8 mm, 2 teeth (line 4, Fusion 360)``."""
    number, kind, diameter, corner, line, teeth, teeth_line, unit, source = row
    size = f"D{diameter:g}" + ("" if corner is None else f" r{corner:g}")
    where = f"line {line}" + ("" if teeth is None or teeth_line == line
                              else f", teeth line {teeth_line}")
    teeth_said = "teeth not given" if teeth is None else count(teeth, "tooth", "teeth")
    del number
    return f"{kind} {size} {unit or program_units}, {teeth_said} ({where}, {source})"


def _units_note(g: np.ndarray, dialect: str) -> str:
    """What the owner should know about the units the program states (G values ``g``)."""
    if np.isin(g, (20.0, 21.0)).any():
        return ""
    if dialect in (SINUMERIK, HEIDENHAIN):  # G70/G700 inch, G71/G710 metric there
        inch = [c for c in (70.0, 700.0) if np.any(g == c)]
        if inch:
            return (f"G{inch[0]:g} selects inch for the lengths only on this control (F "
                    "stays in the machine's basic unit, which the program does not say): the "
                    "moves under it are left as programmed; G700 selects inch for lengths "
                    "and F alike, and ncopt reads it")
        if np.isin(g, (71.0, 710.0)).any():
            return ""
    return ("no G20/G21 in the program: ncopt reads it in mm, as a control does that starts "
            "in metric; add G21 (or G20) to say which")


_MM_SIZE = re.compile(r"(\d+(?:\.\d*)?)\s*MM\b", re.I)


def _unit_clash(table: dict, inch: bool) -> str:
    """``line: ...`` where a tool comment's own mm size shows its sizes are in the other unit."""
    for t in table.values():
        if t.unit is not None:
            continue
        for m in _MM_SIZE.finditer(t.text):
            mm = float(m.group(1))
            other = t.diameter * 25.4 if not inch else t.diameter / 25.4
            if mm > 0 and abs(other - mm) <= 0.01 * mm and abs(t.diameter - mm) > 0.01 * mm:
                units = ("inch", "mm") if not inch else ("mm", "inch")
                return (f"{t.line}: the tool comment gives D{t.diameter:g} for "
                        f"`{m.group(0)}`: its sizes are in {units[0]}, but the program is "
                        f"read in {units[1]}; check G20/G21")
    return ""


def _notes(prog: Program, dialect: str, table: dict) -> tuple[str, ...]:
    """What the program's owner should know before ncopt changes anything."""
    notes = []
    g = prog.word_value[prog.word_letter == ord("G")]
    first = next((i for i in range(min(prog.n_lines, 5)) if prog.line_text(i).strip()), None)
    if first is not None and INCH_HEADER.match(prog.line_text(first)):
        g = np.append(g, 70.0)  # "%NAME G70 *": a Heidenhain ISO program in inch
    note = _units_note(g, dialect)
    if note and prog.n_words:
        notes.append(f"{prog.path}: {note}")
    if prog.n_words and not np.any(prog.word_letter == ord("S")):
        notes.append(f"{prog.path}: no S word: the program never sets a spindle speed (shown "
                     "as S 0 below)")
    clash = _unit_clash(table, inch=bool(np.any(g == 20.0)))
    if clash:
        notes.append(f"{prog.path}:{clash}")
    return tuple(notes)
