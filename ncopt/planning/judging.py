"""Which operations of a program ncopt plans, with which cutter and cutting data, and
why it leaves the others: everything :func:`ncopt.planning.plans.plan_program` decides
before it plans, and all that ``ncopt inspect`` shows of it (:func:`judge`)."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ncopt.model import MM_PER_INCH, Cutter, CuttingData, Motion, Program, Toolpath
from ncopt.planning import operations
from ncopt.planning.intent import implausible, nominal_cutting_data
from ncopt.planning.operations import CANNED, NO_CUT, Operation
from ncopt.planning.tooltable import BALL, BULL, cutter_for, tool_table
from ncopt.reading.stamp import (Stamps, as_stamped, read_stamps, stamp_for, stamped_line,
                                 unstamped_line)
from ncopt.runtime.errors import UsageError


@dataclass(frozen=True)
class ToolChoice:
    """The cutter of one T number, or why ncopt cannot plan it."""

    cutter: Cutter | None
    source: str  # "options", "the tool profiles", "line N: (comment)", a stamp
    why: str = ""  # when cutter is None


@dataclass(frozen=True)
class Judged:
    """A program's operations as judged before any is planned.

    ops : every operation, in program order, with its final planned flag and reason
    tools : T number -> its cutter, or why none;  stamps : the program's ncopt stamps
    point_op : (n,) the planned operation of each toolpath point (-1: none)
    cuts : operation index -> (cutting data, where they come from), for each operation
    that was to be planned (one whose cutting data are implausible is left, its data kept)
    """

    ops: list[Operation]
    tools: dict[int, ToolChoice]
    stamps: Stamps
    point_op: np.ndarray
    cuts: dict[int, tuple[CuttingData, str]]


def judge(prog: Program, tp: Toolpath, job) -> Judged:
    """The operations, their cutters and cutting data, and which of them ncopt plans:
    split and classified (or as the program's ncopt stamp says), then decided (the
    cutter, --tool, --operations, block-delete lines), then each one's cutting data: an
    operation whose data cannot be what the programmer meant, or that no spindle speed of
    the machine can hold, is left alone.  Raises as
    the rewrite does (UsageError for --diameter on a program of several tools, ...)."""
    stamps = read_stamps(prog)
    plannable = plannable_points(tp, job.cutting is not None)
    choices = _choices(prog, tp, job, plannable, stamps)
    diameters = {t: c.cutter.diameter_mm for t, c in choices.items() if c.cutter is not None}
    found = _stamped_ops(prog, tp, stamps) or operations.find(prog, tp, diameters)
    ops = decide(found, choices, job, tp, plannable)
    point_op = _point_ops(tp, ops, plannable)
    cuts = {}
    for k, op in enumerate(ops):
        if op.planned:
            cuts[k] = _cutting(job, tp, point_op, k, op, choices[op.tool], stamps, prog.path)
            odd = (implausible(cuts[k][0], choices[op.tool].cutter)
                   or feed_cap_below_min_rpm(cuts[k][0], choices[op.tool].cutter.teeth,
                                             job.machine, job.options.fz_tolerance))
            if odd:
                ops[k] = replace(op, planned=False, reason=odd)
    return Judged(ops, choices, stamps, _point_ops(tp, ops, plannable), cuts)


def plannable_points(tp: Toolpath, cutting_given: bool = False) -> np.ndarray:
    """(n,) bool: feed moves ncopt can place and that run with the program's own,
    known S and F (G94, position known, spindle on, not a block-delete line).

    Where the program states no S at all (the spindle runs at a speed set at the
    machine), moves are plannable only with cutting data given (``cutting_given``) and
    only if no move it leaves alone runs without S too: ncopt could not put the
    operator's speed back before it."""
    ls = tp.lines
    feed = np.isin(tp.motion, [Motion.LINEAR, Motion.ARC_CW, Motion.ARC_CCW])
    if ls.executed.size == 0:
        return np.zeros(tp.n, dtype=bool)
    line = np.maximum(tp.line, 0)
    ok = feed & tp.known & tp.spindle_on & ls.executed[line] & ls.s_known[line]
    ok &= ls.f_known[line] & ~ls.block_delete[line]
    ok[0] = False
    no_s = ~(tp.spindle_rpm > 0)
    if not cutting_given or (feed & tp.spindle_on & no_s & ~ok)[1:].any():
        ok &= ~no_s
    return ok


def choose_cutter(job, table: dict, tool: int, n_tools: int, inch: bool,
                  stamps: dict) -> ToolChoice:
    """The cutter of T``tool``: the options, the tool profiles, the program's tool
    comment, an ncopt stamp; never a shape the program contradicts."""
    info = cutter_for(table, tool, n_tools)
    named = f"T{tool}" if tool >= 0 else "the tool"
    if job.cutter is not None:
        if info is not None and info.kind not in (BALL, BULL) and not job.shape_named:
            return ToolChoice(None, "", (
                f"the program describes {named} as {info.refusal()} ({info.text.strip()}, "
                f"line {info.line}); --diameter does not say the shape: pass --shape ball "
                "or --corner-radius if that comment is wrong"))
        return ToolChoice(job.cutter, "options")
    if tool in job.tool_library:
        return ToolChoice(job.tool_library[tool], "the tool profiles")
    if info is None:
        stamp = next((st for (t, _), st in sorted(stamps.items(), key=lambda kv: kv[1].line)
                      if t == tool), None)
        if stamp is not None:
            return ToolChoice(stamp.cutter, f"the ncopt stamp on line {stamp.line + 1}")
        return ToolChoice(None, "", "no diameter known from the program's comments: give "
                          "--diameter (and --corner-radius for a bull-nose)")
    if info.kind not in (BALL, BULL):
        return ToolChoice(None, "", f"{info.refusal()} ({info.text.strip()}, line "
                          f"{info.line}); ncopt plans ball and bull-nose cutters only")
    scale = MM_PER_INCH if inch else 1.0
    teeth = info.teeth or job.teeth
    said = (f"teeth from line {info.teeth_line}" if info.teeth is not None
            else f"{teeth} teeth assumed")
    return ToolChoice(info.cutter(teeth, scale),
                      f"line {info.line}: ({info.text.strip()}); {said}")


def _choices(prog, tp, job, plannable, stamps) -> dict:
    tools = np.unique(tp.tool[plannable]).tolist()
    if job.tool is not None and job.tool not in tools:
        raise UsageError(f"no feed moves with tool T{job.tool}; check --tool", prog.path)
    if job.cutter is not None and len(tools) > 1 and job.tool is None:
        listed = ", ".join(f"T{t}" for t in tools)
        raise UsageError(f"the program cuts with several tools ({listed}); say which one "
                         "--diameter describes with --tool N", prog.path)
    table = tool_table(prog)
    inch = tp.line_inch is not None and bool(np.any(tp.line_inch))
    choices = {t: choose_cutter(job, table, t, len(tools), inch, stamps) for t in tools}
    return {t: _no_tilted_bull_nose(c, tp, plannable & (tp.tool == t)) for t, c in choices.items()}


def _no_tilted_bull_nose(choice: ToolChoice, tp: Toolpath, points: np.ndarray) -> ToolChoice:
    """A bull-nose whose tool axis tilts is not planned: its contact search assumes +Z,
    and without a mesh its centre path is no offset surface when the axis turns."""
    c = choice.cutter
    if c is None or c.is_ball or tp.tool_axis is None or not np.any(tp.tool_axis[points, :2]):
        return choice
    return ToolChoice(None, "", "a bull-nose with a tilted tool axis: ncopt plans 5-axis "
                      "moves with ball-end mills only")


def decide(ops: list, choices: dict, job, tp: Toolpath, plannable: np.ndarray) -> list:
    """The final choice per operation: its geometry's, unless its cutter cannot be
    planned, --tool names another, --operations overrides it, block-delete lines make
    its course unknown, or nothing of it can be placed."""
    ls = tp.lines
    wanted = _wanted(job.operations)
    out = []
    for op in ops:
        if op.kind == NO_CUT and not op.planned:  # feed moves it cannot place: say why
            located = unplannable_why(tp, op)
            if located != op.reason:
                op = replace(op, kind=operations.UNPLACED, reason=located)
        planned, why = op.planned, op.reason
        choice = choices.get(op.tool)
        base_name = op.name.split(" (part ")[0]
        if wanted is not None and op.kind != CANNED and _points(tp, op, plannable).size:
            forced = wanted == "all" or base_name.lower() in wanted or op.name.lower() in wanted
            if forced and not planned:
                planned, why = True, f"{why}; planned because --operations names it"
            elif not forced and planned:
                planned, why = False, "not named in --operations"
        if choice is not None and choice.cutter is None and op.kind not in (NO_CUT, CANNED):
            planned, why = False, choice.why
        elif choice is None and op.kind not in (NO_CUT, CANNED):
            planned, why = False, unplannable_why(tp, op)
        if planned and job.tool is not None and op.tool != job.tool:
            planned, why = False, f"another tool than T{job.tool} (--tool)"
        span = slice(op.first_line, op.last_line + 1)
        deleted = np.flatnonzero(ls.block_delete[span] & ls.executed[span])
        if deleted.size and op.kind not in (NO_CUT, CANNED):
            planned = False
            why = (f"block-delete line {op.first_line + int(deleted[0]) + 1} (/): whether it "
                   "runs is the operator's choice, so the S and F in force are not known")
        if planned and not _points(tp, op, plannable).size:
            planned, why = False, unplannable_why(tp, op)
        out.append(replace(op, planned=planned, reason=why))
    return out


def _wanted(operations_opt) -> set | str | None:
    if operations_opt is None:
        return None
    if isinstance(operations_opt, str):
        operations_opt = [operations_opt]
    names = {n.strip().lower() for n in operations_opt if n.strip()}
    return "all" if "all" in names else names


def _points(tp: Toolpath, op, plannable: np.ndarray) -> np.ndarray:
    """Toolpath points of ``op`` that ncopt can plan."""
    a, b = np.searchsorted(tp.line[1:], [op.first_line, op.last_line + 1]) + 1
    pts = np.arange(a, b)
    return pts[plannable[pts]]


def _point_ops(tp: Toolpath, ops: list, plannable: np.ndarray) -> np.ndarray:
    out = np.full(tp.n, -1, dtype=np.int64)
    for k, op in enumerate(ops):
        if op.planned:
            out[_points(tp, op, plannable)] = k
    return out


def _cutting(job, tp, point_op, k, op, choice, stamps, path) -> tuple:
    """The cutting data of operation ``k`` and where they come from."""
    if job.cutting is not None:
        return job.cutting, "options"
    stamp = stamp_for(stamps, op.tool, op_lines(stamps, op))
    if stamp is not None:
        return stamp.cutting, f"the ncopt stamp on line {stamp.line + 1}"
    pts = np.flatnonzero(point_op == k)
    return as_stamped(nominal_cutting_data(tp, pts, choice.cutter, path)), "the program"


def op_lines(stamps: dict, op: Operation) -> tuple[int, int]:
    """The operation's lines as a stamp names them (1-based, without stamp lines)."""
    return (unstamped_line(stamps, op.first_line), unstamped_line(stamps, op.last_line))


def _stamped_ops(prog: Program, tp: Toolpath, stamps: dict) -> list | None:
    """An ncopt output is planned again exactly where its stamp says it was planned (its
    S and F words no longer tell roughing from finishing); None for other programs."""
    ranges = sorted({(st.lines, st.tool, st.line) for st in stamps.values() if st.lines})
    if not ranges:
        return None
    out = []
    own = set(getattr(stamps, "lines", None) or ())  # the stamp's lines: no piece alone
    for span in operations.spans(prog, tp):
        a = span.first_line
        for (first, last), tool, line in ranges:
            lo, hi = stamped_line(stamps, first), stamped_line(stamps, last)
            lo, hi = max(lo, span.first_line), min(hi, span.last_line)
            if lo > hi:
                continue
            if lo > a and own.issuperset(range(a, lo)):
                lo = a  # nothing but the stamp before the planned lines
            if lo > a:
                out.append(_piece(tp, span, a, lo - 1, False, "not planned by the rewrite "
                                  f"that stamped this program (line {line + 1})"))
            out.append(_piece(tp, span, lo, hi, True, f"planned by the rewrite that stamped "
                              f"this program (line {line + 1})"))
            a = hi + 1
        if a <= span.last_line:
            out.append(_piece(tp, span, a, span.last_line, False, "not planned by the rewrite "
                              "that stamped this program"))
    return out


def _piece(tp: Toolpath, span, lo: int, hi: int, planned: bool, why: str) -> Operation:
    a, b = np.searchsorted(tp.line[1:], [lo, hi + 1]) + 1
    pts = np.arange(a, b)
    feed = pts[tp.motion[pts] >= Motion.LINEAR]
    tool = int(tp.tool[feed[0]]) if feed.size else int(tp.lines.tool[hi])
    name = span.name or (f"T{tool}" if tool >= 0 else "the program")
    kind = operations.STAMPED if planned else operations.NO_CUT if not feed.size else \
        operations.LEFT_BEFORE
    return Operation(name=name, tool=tool, first_line=lo, last_line=hi, kind=kind,
                     planned=planned, reason=why, name_line=span.name_line)


def unplannable_why(tp: Toolpath, op) -> str:
    """Why none of an operation's feed moves can be planned."""
    a, b = np.searchsorted(tp.line[1:], [op.first_line, op.last_line + 1]) + 1
    pts = np.arange(a, b)
    feed = pts[np.isin(tp.motion[pts], [Motion.LINEAR, Motion.ARC_CW, Motion.ARC_CCW])]
    if feed.size == 0:
        return op.reason
    ls = tp.lines
    line = tp.line[feed]
    located = _located_reason(tp, op)
    for bad, why in (
            (~tp.known[feed], located or "position not known (after G28/G53/G92, a call, a "
             "cycle), G95 feed or cutter compensation"),
            (~tp.spindle_on[feed], "the spindle is not on (no M3/M4)"),
            (~ls.s_known[line] | ~ls.f_known[line], "the S or F in force is not known (after a "
             "subprogram call, or an expression ncopt cannot evaluate)"),
            (~(tp.spindle_rpm[feed] > 0), "the program states no S (the spindle runs at a speed "
             "set at the machine): give --vc and --fz to plan it")):
        if bad.all():
            return why
    return "no feed move ncopt can place"


def _located_reason(tp: Toolpath, op) -> str:
    """The first located 'not planned' warning of the interpreter inside ``op``'s lines
    (the tool axis, G93 without F...), as ``line A-B: why``; "" when there is none."""
    for w in tp.warnings:
        head, sep, rest = w.partition(": not planned (")
        lines = head.rsplit(":", 1)[-1].split("-")
        if not sep or not all(x.isdigit() for x in lines):
            continue
        if op.first_line + 1 <= int(lines[-1]) and int(lines[0]) <= op.last_line + 1:
            return f"line {head.rsplit(':', 1)[-1]}: {rest.rsplit('); S/F', 1)[0]}"
    return ""


def nothing_why(ops, choices, tp: Toolpath | None = None) -> str:
    """Why nothing is planned, operation by operation (the first few); where no
    operation cuts, the first moves the interpreter left alone and why."""
    by_reason: dict[str, list[str]] = {}  # operations with the same reason: one row
    for o in ops:
        if o.kind not in (NO_CUT,):
            by_reason.setdefault(o.reason, []).append(f"{o.name} ({o.lines})")
    if not by_reason:
        first = next((w for w in (tp.warnings if tp is not None else ())
                      if ": not planned (" in w), None)
        more = f"; the first moves left alone: {first}" if first else ""
        return f"nothing to plan (no feed moves with a running spindle and a known position{more})"
    rows = []
    for reason, names in by_reason.items():
        extra = f" and {len(names) - NAMES_PER_REASON} more" if len(names) > NAMES_PER_REASON \
            else ""
        rows.append(", ".join(names[:NAMES_PER_REASON]) + extra + f": {reason}")
    more = f"; and {len(rows) - 6} more" if len(rows) > 6 else ""
    return "nothing to plan: " + "; ".join(rows[:6]) + more


NAMES_PER_REASON = 3  # operations named before "and N more" in a "nothing to plan" row


def feed_cap_below_min_rpm(cut: CuttingData, teeth: int, machine, band: float = 0.0) -> str:
    """Why no spindle speed holds fz ("" when one does): --max-feed over fz z is a speed
    below the machine's lowest by more than the fz band (a share), so every cut would run
    at --min-rpm and --max-feed, fz under its band."""
    rev_mm = cut.fz_mm * teeth
    s_hi = machine.max_feed_mm_min / rev_mm if rev_mm > 0 else float("inf")
    if not s_hi < machine.min_rpm * (1.0 - band):
        return ""
    return (f"--max-feed {machine.max_feed_mm_min:g} mm/min over fz {cut.fz_mm:g} mm x "
            f"{teeth} teeth is {s_hi:.0f} RPM, below --min-rpm {machine.min_rpm:g}: no "
            f"spindle speed holds fz (at both limits it runs "
            f"{100 * (1 - s_hi / machine.min_rpm):.1f} % under its target); raise --max-feed "
            f"to at least {rev_mm * machine.min_rpm:.0f} mm/min or lower --min-rpm")
