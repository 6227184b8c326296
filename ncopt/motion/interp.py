"""Modal interpreter: :class:`Program` -> :class:`Toolpath` (numpy arrays).

The modal tables of RS-274 are constant data below; the interpreter is a
function of the program and a start state.  Plain blocks are interpreted with
vectorised forward fills (a 1M-block program in about a second); arcs and
expressions take a per-line path.

Nothing is guessed: where the position cannot be known (a subprogram call, a
macro, a return to home, a parameter the program does not set, an opaque
line that may move the machine) the axes become unknown until the program
states them again absolutely, and moves in between are not planned.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, replace

import numpy as np

from ncopt.runtime.errors import NcoptError
from ncopt.reading.expr import Params, Unknown
from ncopt.motion.feedmode import G93, G95, tip_feed_mm_min
from ncopt.model import Job, LineKind, LineState, Program, Toolpath
from ncopt.motion.orientation import Orientation, lean_toward_travel, read_orientation, with_tool_axis
from ncopt.reading.tapemarks import unread_lines_warning
from ncopt.motion.planes import after_keyword
from ncopt.motion.modal import (
    CANNED, FLOW_CONTROL, G_ARC_DISTANCE, G_COMP, G_DISTANCE, G_FEED_MODE, G_MODES_NOT_READ, G_MOTION, G_NON_MODAL_MOVE, G_NOT_A_TARGET, G_OTHER_MOVES, G_PLANE, G_POLE, G_READ, G_SCALE_OFF, G_SCALE_ON, G_SPLINE, G_UNITS, G_WORK_OFFSETS, HARMLESS_OPAQUE, INCH_HEADER, KW_FRAME_RESET, KW_SCALE, SCALED_WHY, ffill, row_norms,
)
from ncopt.model import MM_PER_INCH
from ncopt.reading.refuse import MIN_ARC_RADIUS_MM, check_arc_centres, check_signs, check_words

@dataclass(frozen=True)
class StartState:
    """Modal state before the first line (a control's usual power-on state)."""

    inch: bool = False
    absolute: bool = True
    arc_absolute: bool = False
    plane: int = 170
    chord_tol_mm: float = 0.005


def tcp_for(tcp: str | None, dialect: str) -> str | None:
    """A machine's ``tcp`` setting for a program of ``dialect``: grbl has no
    tool-centre-point control, whatever a profile says."""
    return None if dialect == "grbl" else tcp


def tcp_of(job: Job, detected: str) -> str | None:
    """The job's ``tcp`` for a program of the ``detected`` dialect (:func:`tcp_for`)."""
    return tcp_for(job.tcp, job.control or detected)


def interpret(prog: Program, start: StartState = StartState(),
              kinematics: str | None = None, tcp: str | None = None) -> Toolpath:
    """Interpret a program into cutter locations.

    ``kinematics``: the machine's kinematics (``ncopt.motion.kinematics``) for
    programs that tilt the tool with rotary axes; None: such moves are not
    planned.  ``tcp``: ``"always"`` where the machine's control runs tool-tip
    kinematics for every program (its profile says so); None: only where the
    program switches tool-centre-point control on (``ncopt.motion.orientation``).

    Returns
    -------
    Toolpath
        One row per CL point; arcs split within ``start.chord_tol_mm``.
    """
    skip = None
    if prog.line_exprs:  # subroutine bodies and lines after M2/M30 are not evaluated
        skip = ~_executed_lines(prog, _LineTable(prog, prog.word_value), [])
    values, poisoned, warnings = _evaluate(prog, skip)
    lines = _LineTable(prog, values)
    executed = _executed_lines(prog, lines, warnings)
    _check_semantics(prog, lines, executed)
    modal = _modal_state(lines, start, executed)
    orient = read_orientation(prog, lines, modal, executed, kinematics, tcp)
    pos_mm, known, last_event = _positions(prog, lines, modal, executed, poisoned, warnings)
    orient = lean_toward_travel(orient, prog, lines, modal, executed, pos_mm)  # G43.5 Q
    _check_comp_corners(prog, lines, modal, pos_mm, known, executed)
    tp = _build_points(prog, lines, modal, pos_mm, known, executed, start, warnings, orient,
                       last_event)
    tp = replace(tp, lines=_line_state(prog, lines, modal, executed))
    return tp if orient is None else with_tool_axis(tp, orient)


class _LineTable:
    """Per-line word values, NaN where a line has no such word.

    ``axis[c]`` (n_lines,) float64 for each letter c present in the program;
    ``g``/``m`` list the G and M codes (x10, int) with their lines.
    """

    def __init__(self, prog: Program, values: np.ndarray) -> None:
        self.n = prog.n_lines
        self.letters = {}
        # the words grouped by letter, each group in text order (a stable sort): one
        # pass over the words instead of one per letter
        order = np.argsort(prog.word_letter, kind="stable")
        codes, first = np.unique(prog.word_letter[order], return_index=True)
        of = {code: order[a:b] for code, a, b in
              zip(codes.tolist(), first.tolist(), first[1:].tolist() + [order.size])}
        for code, sel in of.items():
            if code in (ord("G"), ord("M"), ord("N"), ord("O")):
                continue
            arr = np.full(self.n, np.nan)
            arr[prog.word_line[sel]] = values[sel]
            present = np.zeros(self.n, dtype=bool)
            present[prog.word_line[sel]] = True
            self.letters[chr(code)] = (arr, present)
        gsel = of.get(ord("G"), np.zeros(0, np.int64))
        self.g_line = prog.word_line[gsel]
        self.g_code = np.round(values[gsel] * 10).astype(np.int64, copy=False) if gsel.size \
            else np.zeros(0, np.int64)
        msel = of.get(ord("M"), np.zeros(0, np.int64))
        self.m_line = prog.word_line[msel]
        self.m_code = np.nan_to_num(values[msel], nan=-1).astype(np.int64)

    def value(self, letter: str) -> np.ndarray:
        return self.letters[letter][0] if letter in self.letters else np.full(self.n, np.nan)

    def present(self, letter: str) -> np.ndarray:
        return self.letters[letter][1] if letter in self.letters else np.zeros(self.n, bool)

    def g_group(self, group: set) -> np.ndarray:
        """(n,) float: the code of this group on each line (NaN if none).

        G80 yields to another motion code on the same line.
        """
        out = np.full(self.n, np.nan)
        sel = np.isin(self.g_code, list(group))
        cancel = sel & (self.g_code == 800)
        out[self.g_line[cancel]] = 800
        out[self.g_line[sel & ~cancel]] = self.g_code[sel & ~cancel]
        return out

    def has_g(self, codes) -> np.ndarray:
        out = np.zeros(self.n, dtype=bool)
        out[self.g_line[np.isin(self.g_code, list(codes))]] = True
        return out

    def unread_g(self) -> np.ndarray:
        """(n,) bool: the line holds a G code outside :data:`G_READ` (computed once)."""
        if getattr(self, "_unread", None) is None:
            self._unread = np.zeros(self.n, dtype=bool)
            self._unread[self.g_line[~np.isin(self.g_code, list(G_READ))]] = True
        return self._unread

    def has_m(self, codes) -> np.ndarray:
        out = np.zeros(self.n, dtype=bool)
        out[self.m_line[np.isin(self.m_code, list(codes))]] = True
        return out


def _evaluate(prog: Program, skip: np.ndarray | None = None):
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


def _executed_lines(prog: Program, lines: _LineTable, warnings: list) -> np.ndarray:
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


def _check_semantics(prog: Program, lines: _LineTable, executed: np.ndarray) -> None:
    """Errors a control would raise (the LinuxCNC interpreter's own checks)."""
    check_words(prog, lines.has_g({650, 660}))
    check_signs(prog, lines, executed)
    # G80 beside a motion code is accepted by Mach3/Fanuc posts (N100G00G21G17G90G40G49G80)
    groups = [G_MOTION - {800}, G_NON_MODAL_MOVE | {40}, G_PLANE, G_DISTANCE, G_UNITS,
              G_FEED_MODE, G_COMP]
    for group in groups:
        line = lines.g_line[np.isin(lines.g_code, list(group))]  # in text order
        twice = line[1:][line[1:] == line[:-1]]  # the lines holding two of the group
        bad = twice[executed[twice]]
        if bad.size:
            _fail(prog, bad[0], "two G codes from the same modal group on one line; "
                  "put them on separate lines")
    motion = ffill(lines.g_group(G_MOTION))
    rotary = lines.present("A") | lines.present("B") | lines.present("C")
    bad = np.flatnonzero(np.isin(motion, list(CANNED)) & rotary & executed)
    if bad.size:
        _fail(prog, bad[0], "a rotary axis word (A/B/C) in a canned cycle; remove it")
    probe = lines.has_g({382, 383, 384, 385})
    axes = lines.present("X") | lines.present("Y") | lines.present("Z")
    bad = np.flatnonzero(probe & ~axes & executed)
    if bad.size:
        _fail(prog, bad[0], "all axes missing with a probe move (G38.x); give a target")
    r_used = np.isin(motion, [20, 30] + list(CANNED))
    r_used |= lines.has_g({640, 100, 760, 700, 710, 711, 712, 720, 721, 722, 51})  # G05.1 R: level
    r_used |= lines.has_m({19}) | lines.unread_g()  # an unknown code may take R
    bad = np.flatnonzero(lines.present("R") & ~r_used & executed)
    if bad.size:
        _fail(prog, bad[0], "R word with no G code that uses it; remove the R word")
    arc = np.isin(motion, [20, 30]) & executed & (axes | lines.has_g({20, 30}))
    no_centre = ~(lines.present("I") | lines.present("J") | lines.present("K") | lines.present("R"))
    # an arc whose line holds what ncopt does not read (Sinumerik CR=R1*2, AR=90, I=AC(5))
    # may give its centre there: it is no move ncopt reads, and the position is lost after it
    no_centre &= prog.line_kind != LineKind.OPAQUE
    if (arc & no_centre).any():
        _fail(prog, np.flatnonzero(arc & no_centre)[0],
              "arc with none of I, J, K or R; give the centre or the radius")
    check_arc_centres(prog, lines, arc, plane=ffill(lines.g_group(G_PLANE), 170.0),
                      incremental=ffill(lines.g_group(G_ARC_DISTANCE), 911.0) == 911.0,
                      inch=ffill(lines.g_group(G_UNITS), 210.0) == 200.0)
    _check_comp_exit(prog, lines, motion, executed)
    both = lines.present("R") & lines.has_g({640}) & lines.has_m({19})
    if both.any():
        _fail(prog, np.flatnonzero(both)[0], "R word is ambiguous with both G64 and M19; "
              "use separate lines")


def _check_comp_exit(prog, lines, motion, executed) -> None:
    """The move after leaving cutter compensation (G40) must be straight."""
    comp = lines.g_group(G_COMP)
    words = [lines.present(k) for k in "XYZIJKR"]
    moves = np.flatnonzero(executed & np.isin(motion, [0, 10, 20, 30]) & np.logical_or.reduce(words))
    for i in np.flatnonzero(comp == 400).tolist():
        before = comp[:i][~np.isnan(comp[:i])]
        if before.size == 0 or before[-1] == 400:
            continue
        nxt = moves[moves >= i]
        if nxt.size and motion[nxt[0]] in (20, 30):
            _fail(prog, nxt[0], "the move just after leaving cutter compensation (G40) "
                  "must be straight, not an arc")


def _check_comp_corners(prog, lines, modal, pos_mm, known, executed) -> None:
    """Cutter compensation with a stated diameter (G41.1/G42.1 D..): in a concave
    corner between two straight XY moves, the offset lines must meet inside both
    offset moves, or the tool cannot reach the corner without gouging (the
    LinuxCNC interpreter's check)."""
    dynamic = np.isin(modal.comp, [411, 421]) & executed
    if not dynamic.any():
        return
    diameter = ffill(np.where(lines.has_g({411, 421}), lines.value("D"), np.nan))
    feed = dynamic & np.isin(modal.motion, [10]) & (lines.present("X") | lines.present("Y"))
    # moves under compensation are "unknown" for planning; their programmed path is
    # trusted here when the position was known where compensation began
    begins = np.flatnonzero(dynamic & ~np.concatenate(([False], dynamic[:-1])))
    trusted = np.zeros(lines.n, dtype=bool)
    for c in begins.tolist():
        if c > 0 and known[c - 1, :2].all():
            end = c + int(np.argmin(dynamic[c:])) if not dynamic[c:].all() else lines.n
            trusted[c:end] = True
    moves = np.flatnonzero(feed & trusted)
    for a, b in zip(moves[:-1].tolist(), moves[1:].tolist()):
        prev = pos_mm[a - 1] if a > 0 else None
        if prev is None or modal.comp[a] != modal.comp[b]:
            continue
        r = 0.5 * diameter[b] * (MM_PER_INCH if modal.inch[b] else 1.0)
        side = 1.0 if modal.comp[b] == 411 else -1.0  # tool left (G41) or right of the path
        if _gouges(prev[:2], pos_mm[a, :2], pos_mm[b, :2], r, side):
            _fail(prog, b, "straight feed in a concave corner cannot be reached by the tool "
                  "without gouging; lengthen the move or use a smaller tool")


def _gouges(p0, p1, p2, r, side) -> bool:
    d1, d2 = p1 - p0, p2 - p1
    l1, l2 = math.hypot(*d1), math.hypot(*d2)
    if l1 < 1e-12 or l2 < 1e-12 or not r > 0:
        return False
    d1, d2 = d1 / l1, d2 / l2
    turn = d1[0] * d2[1] - d1[1] * d2[0]
    if turn * side <= 1e-12:  # convex corner (or straight on): the tool goes round it
        return False
    n1 = side * np.array([-d1[1], d1[0]])  # offset directions toward the tool
    n2 = side * np.array([-d2[1], d2[0]])
    # X = p1 + r n1 + t1 d1 = p1 + r n2 + t2 d2
    m = np.column_stack((d1, -d2))
    t1, t2 = np.linalg.solve(m, r * (n2 - n1))
    return t1 < -l1 - 1e-9 or t2 > l2 + 1e-9


def _fail(prog: Program, line: int, message: str) -> None:
    raise NcoptError(message, prog.path, int(line) + 1, 1)


@dataclass(frozen=True)
class _Modal:
    """Modal state in force at each line, (n_lines,) arrays."""

    motion: np.ndarray  # G code x10, NaN if never set
    inch: np.ndarray  # bool
    absolute: np.ndarray  # bool
    arc_absolute: np.ndarray
    plane: np.ndarray  # 170 / 180 / 190
    feed_mode: np.ndarray  # 930 / 940 / 950
    comp: np.ndarray  # 400 / 410 / 420
    feed: np.ndarray  # programmed F in program units (NaN before any)
    spindle_rpm: np.ndarray
    spindle_on: np.ndarray
    tool: np.ndarray


def _modal_state(lines: _LineTable, start: StartState, executed: np.ndarray) -> _Modal:
    def group(codes, initial):
        arr = lines.g_group(codes)
        arr[~executed] = np.nan
        return ffill(arr, initial)

    units = group(G_UNITS, 200.0 if start.inch else 210.0)
    spindle_on = np.full(lines.n, np.nan)
    for codes, state in (({3, 4}, 1.0), ({5}, 0.0), ({2, 30}, 0.0)):
        spindle_on[lines.has_m(codes) & executed] = state
    limit = lines.has_g({250, 260})  # Sinumerik G26 S8000: a spindle limit, not a speed
    s_words = np.where(executed & ~limit, lines.value("S"), np.nan)
    speed = ffill(s_words, 0.0)
    running = ffill(spindle_on, 0.0) > 0
    t_words = np.where(executed, lines.value("T"), np.nan)
    t_ffill = ffill(t_words, -1.0)
    changes = lines.has_m({6}) & executed
    tool = ffill(np.where(changes, t_ffill, np.nan), -1.0) if changes.any() else t_ffill
    feed = ffill(np.where(executed, lines.value("F"), np.nan))
    return _Modal(
        motion=group(G_MOTION, np.nan), inch=units == 200.0,
        absolute=group(G_DISTANCE, 900.0 if start.absolute else 910.0) == 900.0,
        arc_absolute=group(G_ARC_DISTANCE, 901.0 if start.arc_absolute else 911.0) == 901.0,
        plane=group(G_PLANE, float(start.plane)), feed_mode=group(G_FEED_MODE, 940.0),
        comp=group(G_COMP, 400.0), feed=feed, spindle_rpm=speed, spindle_on=running, tool=tool)


def _unknown_events(prog, lines, modal, executed, poisoned, warnings) -> np.ndarray:
    """(n,) bool: lines after which no axis position can be trusted."""
    event = np.zeros(lines.n, dtype=bool)
    # G10: data setting (offsets); Heidenhain ISO's polar rapid: either way a lost position
    event |= lines.has_g({280, 300, 530, 920, 921, 922, 923, 520, 281, 301, 100}
                         | G_OTHER_MOVES | G_POLE)
    event |= lines.has_m({6, 98, 99}) | lines.has_g({650, 660} | G_SCALE_ON | G_SCALE_OFF
                                                    | {160, 150, 121, 131, 71})
    event |= np.isin(modal.motion, list(CANNED)) | np.isin(modal.motion, [330, 382, 383, 384, 385])
    event |= np.isin(modal.comp, [410, 420, 411, 421])
    event |= _offset_changes(lines, executed)
    unread = lines.unread_g() & executed
    for i in np.flatnonzero(unread)[:20].tolist():
        codes = lines.g_code[(lines.g_line == i) & ~np.isin(lines.g_code, list(G_READ))]
        warnings.append(f"{prog.path}:{i + 1}: G{codes[0] / 10:g} is a G code ncopt does not "
                        "read; the moves after it keep their S/F until the position is known "
                        "again")
    event |= unread
    spline = lines.has_g(G_SPLINE) & executed
    spline &= lines.present("X") | lines.present("Y") | lines.present("Z")
    for i in np.flatnonzero(spline)[:20].tolist():
        warnings.append(f"{prog.path}:{i + 1}: a spline, NURBS or smoothing block (G5, G5.1, "
                        "G5.2, G6.2) with axis words is not followed by ncopt; the moves after "
                        "it keep their S/F until the position is known again")
    event |= spline
    for i, reason in prog.opaque_reason.items():
        if reason.upper() in KW_SCALE:
            event[i] = True  # the moves under it get their own reason (SCALED_WHY)
        elif reason.upper() in ("F", "S"):
            # G1 X15 F=R1: the line is no move ncopt reads, so the position is lost too;
            # the moves under it get their own reason, not this warning
            event[i] = True
        elif reason.upper() not in HARMLESS_OPAQUE and not reason.endswith("="):
            event[i] = True
            warnings.append(f"{prog.path}:{i + 1}: '{reason}' is not interpreted by ncopt; "
                            "the moves after it keep their S/F until the position is "
                            "known again")
        elif reason.upper().startswith(("$", ":")):
            event[i] = True
    lines_l = lines.present("L") & ~lines.has_g({100, 760}) & ~np.isin(modal.motion, list(CANNED))
    event |= lines_l  # Sinumerik L100: subprogram call
    event |= poisoned & (lines.present("X") | lines.present("Y") | lines.present("Z"))
    return event & executed


def _offset_changes(lines, executed) -> np.ndarray:
    """(n,) bool: lines that select a work offset other than the one in force (G54 ->
    G55): the moves after them are in another frame.  Re-stating the same one (posts write
    G54 at every operation) changes nothing."""
    code = lines.g_group(G_WORK_OFFSETS)
    code[~executed] = np.nan
    extended = code == 541  # G54.1 P1..P300: the P word says which
    code[extended] += np.nan_to_num(lines.value("P")[extended], nan=-1.0) / 1000.0
    given = np.flatnonzero(~np.isnan(code))
    out = np.zeros(lines.n, dtype=bool)
    if given.size > 1:
        change = code[given[1:]] != code[given[:-1]]
        out[given[1:][change]] = True
    return out


def _positions(prog, lines, modal, executed, poisoned, warnings):
    """Absolute positions in mm per line (n,3), whether each axis is known, and (n,) the
    last line at or before each after which no position can be trusted (-1: none)."""
    events = _unknown_events(prog, lines, modal, executed, poisoned, warnings)
    special = lines.has_g(G_NOT_A_TARGET) | lines.unread_g() | np.isin(modal.motion, list(CANNED))
    scale = np.where(modal.inch, MM_PER_INCH, 1.0)
    pos = np.zeros((lines.n, 3))
    known = np.zeros((lines.n, 3), dtype=bool)
    idx = np.arange(lines.n)
    last_evt = np.maximum.accumulate(np.where(events, idx, -1))
    for k, axis in enumerate("XYZ"):
        value = lines.value(axis) * scale
        present = lines.present(axis) & executed & ~special & ~np.isnan(value)
        absolute = present & modal.absolute
        increment = np.where(present & ~modal.absolute, value, 0.0)
        cum = np.cumsum(increment)
        base = np.where(absolute, value - cum, np.nan)
        pos[:, k] = ffill(base, 0.0) + cum
        last_abs = np.maximum.accumulate(np.where(absolute, idx, -1))
        known[:, k] = last_abs > last_evt
        # an event on the same line as an absolute word: the word is a target
        # of that special move (G28 X0...), the axis stays unknown
    return pos, known, last_evt


def _build_points(prog, lines, modal, pos_mm, known, executed, start, warnings,
                  orient: Orientation | None = None,
                  last_event: np.ndarray | None = None) -> Toolpath:
    motion = modal.motion
    axes_present = lines.present("X") | lines.present("Y") | lines.present("Z")
    if orient is not None:  # a rotary-only move turns the tool: a move of its own
        axes_present = axes_present | orient.rotary_move
    arc_words = lines.present("I") | lines.present("J") | lines.present("K") | lines.present("R")
    special = lines.has_g(G_NOT_A_TARGET) | lines.unread_g()
    is_lin = np.isin(motion, [0, 10]) & axes_present
    is_arc = np.isin(motion, [20, 30]) & (axes_present | arc_words)
    move = (is_lin | is_arc) & executed & ~special & (prog.line_kind == LineKind.WORDS)
    move_lines = np.flatnonzero(move)
    end = np.take(pos_mm, move_lines, axis=0)  # take: rows 4x faster than pos_mm[...]
    all_known = known.all(axis=1)
    end_known = all_known[move_lines]
    scale = np.where(modal.inch, MM_PER_INCH, 1.0)
    feed_mm = modal.feed * scale
    comp = modal.comp != 400
    arcs = np.flatnonzero(is_arc[move_lines])
    pieces = [None] * move_lines.shape[0]
    counts = np.ones(move_lines.shape[0], dtype=np.int64)
    seg_len = np.zeros(move_lines.shape[0])
    prev_pt = np.vstack((np.zeros((1, 3)), end[:-1]))
    prev_known = np.concatenate(([False], end_known[:-1]))
    if last_event is not None and move_lines.size:
        # after a tool change, G28, a canned cycle, compensation... between two moves the
        # next one starts where ncopt does not know, even where it gives every axis again
        prev_line = np.concatenate(([-1], move_lines[:-1]))
        prev_known &= ~(last_event[move_lines] > prev_line)
    seg_len[:] = row_norms(end - prev_pt)
    for j in arcs.tolist():
        i = move_lines[j]
        if not (prev_known[j] and end_known[j]):
            continue
        pts, lengths = _arc_points(prog, lines, modal, i, prev_pt[j], end[j], start.chord_tol_mm)
        pieces[j] = (pts, lengths)
        counts[j] = pts.shape[0]
    computed_f = _computed(prog, lines, executed, "F")
    computed_s = _computed(prog, lines, executed, "S")
    _check_feed(prog, modal,
                move_lines[~computed_f[move_lines]] if computed_f.any() else move_lines)
    n_pts = int(counts.sum()) + 1
    one_each = n_pts == move_lines.shape[0] + 1  # no arc cut into pieces: nothing to repeat
    xyz = np.zeros((n_pts, 3))
    rows = np.concatenate(([0], np.cumsum(counts)))  # first row of each move, minus 1
    last_rows = slice(1, None) if one_each else rows[1:]  # each move's last point
    xyz[last_rows] = end
    lengths = np.zeros(n_pts)
    lengths[last_rows] = seg_len
    for j in arcs.tolist():  # only arcs have pieces (a loop over 1M moves otherwise)
        piece = pieces[j]
        if piece is not None:
            xyz[rows[j] + 1:rows[j + 1] + 1] = piece[0]
            lengths[rows[j] + 1:rows[j + 1] + 1] = piece[1]
    xyz[0] = end[0] if end.shape[0] else 0.0

    def rep(a, first):
        return np.concatenate(([first], a if one_each else np.repeat(a, counts)))
    line = rep(move_lines, -1).astype(np.int32)
    mcode = rep(np.nan_to_num(motion[move_lines], nan=-10) // 10, -1).astype(np.int8)
    feed_mm, g93 = feed_mm[move_lines], modal.feed_mode[move_lines] == G93
    g93_ok = np.ones(move_lines.shape[0], dtype=bool)
    if g93.any():  # the tip feed each F (1 / minutes) stands for, over the whole block
        block_len = np.add.reduceat(lengths[1:], rows[:-1])
        feed_mm, g93_ok = tip_feed_mm_min(modal.feed_mode[move_lines],
                                          lines.value("F")[move_lines], feed_mm, block_len)
    seg_known = end_known & prev_known & g93_ok
    seg_known &= (modal.feed_mode[move_lines] != G95) & ~comp[move_lines]
    scaled = _scaled(prog, lines, executed)
    mode = _modes_not_read(prog, lines, executed)
    not_read = scaled | computed_f | computed_s | (mode > 0)  # per line: one gather below
    if not_read.any():
        seg_known &= ~not_read[move_lines]
    if orient is not None:
        seg_known &= orient.blocked[move_lines] == 0
    known_pts = rep(seg_known, False)
    feed_moves = np.isin(motion[move_lines], [10, 20, 30])
    no_f = np.zeros(lines.n, dtype=bool)
    no_f[move_lines[~g93_ok]] = True
    _warn_unplanned(prog, move_lines[feed_moves], seg_known[feed_moves], modal, warnings, orient,
                    no_f, scaled, computed_f, computed_s, mode)
    return Toolpath(
        xyz_mm=xyz, line=line, motion=mcode,
        feed_mm_min=rep(np.where(mcode_is_feed(motion[move_lines]), feed_mm, np.nan), np.nan),
        spindle_rpm=rep(modal.spindle_rpm[move_lines], 0.0),
        seg_len_mm=lengths, known=known_pts, tool=rep(modal.tool[move_lines], -1).astype(np.int32),
        line_inch=modal.inch, spindle_on=rep(modal.spindle_on[move_lines], False),
        warnings=tuple(warnings), inverse_time=rep(g93, False) if g93.any() else None)


def mcode_is_feed(motion_x10: np.ndarray) -> np.ndarray:
    return np.isin(motion_x10, [10, 20, 30])


def _check_feed(prog, modal, move_lines) -> None:
    feed_moves = move_lines[np.isin(modal.motion[move_lines], [10, 20, 30])]
    bad = feed_moves[(np.nan_to_num(modal.feed[feed_moves], nan=0.0) <= 0)
                     & (modal.feed_mode[feed_moves] == 940)]
    if bad.size:
        _fail(prog, bad[0], "feed move with zero feed rate; add an F word before it")
    # inverse time: F is 1/minutes, F0 a move that never ends (LinuxCNC refuses it too)
    zero = feed_moves[(modal.feed[feed_moves] <= 0) & (modal.feed_mode[feed_moves] == 930)]
    if zero.size:
        _fail(prog, zero[0], "inverse-time (G93) move with F0 (F is 1/minutes there): give "
              "the move's F")


def _switched(on: np.ndarray, off: np.ndarray, executed: np.ndarray) -> np.ndarray:
    """(n,) bool: a mode switched on on the lines ``on`` and off on ``off`` (``on`` wins on
    a line with both) is in force; lines not executed switch nothing."""
    on, off = on & executed, off & executed
    if not on.any():  # the usual program: no ffill over its lines
        return np.zeros(on.shape[0], dtype=bool)
    state = np.full(on.shape[0], np.nan)
    state[off] = 0.0
    state[on] = 1.0
    return ffill(state, 0.0) > 0


def _modes_not_read(prog, lines, executed) -> np.ndarray:
    """(n,) int: 1 + the index in :data:`G_MODES_NOT_READ` of a mode in force on the line
    (the first listed wins), 0 where none is; M2/M30 end them all."""
    out = np.zeros(lines.n, dtype=np.int64)
    first = next((i for i in range(min(prog.n_lines, 5)) if prog.line_text(i).strip()), None)
    ends = lines.has_m({2, 30})
    for k, (codes_on, codes_off, _) in reversed(list(enumerate(G_MODES_NOT_READ))):
        on, off = lines.has_g(codes_on), lines.has_g(codes_off) | ends
        if 700 in codes_on and first is not None and INCH_HEADER.match(prog.line_text(first)):
            on[first] = True
        if 71 in codes_on:  # G07.1 C0 (a zero radius) switches cylindrical interpolation off
            zero = on & (np.nan_to_num(lines.value("C"), nan=1.0) == 0.0)
            on, off = on & ~zero, off | zero
        out[_switched(on & ~ends, off, executed)] = k + 1
    return out


def _scaled(prog, lines, executed) -> np.ndarray:
    """(n,) bool: a scaling or mirror image is in force on the line (Fanuc G51/G51.1 until
    G50/G50.1, Sinumerik SCALE/ASCALE/MIRROR/AMIRROR until the frame is reset; M2/M30 end
    both).  The moves under it are not where the program says, nor the surface as long."""
    on, off = lines.has_g(G_SCALE_ON), lines.has_g(G_SCALE_OFF)
    for i, head in prog.opaque_reason.items():
        up = head.upper()
        if up in KW_SCALE or up in KW_FRAME_RESET:
            args = bool(after_keyword(prog.line_text(i), up))
            on[i] |= up in KW_SCALE and args
            off[i] |= up in KW_FRAME_RESET and not args
    ends = lines.has_m({2, 30})
    return _switched(on & ~ends, off | ends, executed)


def _computed(prog, lines, executed, letter: str) -> np.ndarray:
    """(n,) bool: the feed (``letter`` F) or spindle speed (S) in force is a Sinumerik
    assignment ncopt does not evaluate (``F=R1``, ``S=R2*2``), from that line to the next
    such word with a number."""
    on = np.zeros(lines.n, dtype=bool)
    on[[i for i, head in prog.opaque_reason.items() if head.upper() == letter]] = True
    return _switched(on, lines.present(letter), executed)


def _warn_unplanned(prog, move_lines, seg_known, modal, warnings, orient=None,
                    no_f=None, scaled=None, computed_f=None, computed_s=None,
                    mode=None) -> None:
    unknown = move_lines[~seg_known]
    if unknown.size == 0:
        return
    breaks = np.flatnonzero(np.diff(unknown) > 1)
    starts = np.concatenate(([unknown[0]], unknown[breaks + 1]))
    stops = np.concatenate((unknown[breaks], [unknown[-1]]))
    for a, b in list(zip(starts.tolist(), stops.tolist()))[:20]:
        why = "position not known"
        if mode is not None and mode[a]:
            why = G_MODES_NOT_READ[mode[a] - 1][2]
        elif scaled is not None and scaled[a]:
            why = SCALED_WHY
        elif computed_s is not None and computed_s[a]:
            why = "the spindle speed is an assignment (S=...) ncopt does not evaluate"
        elif computed_f is not None and computed_f[a]:
            why = "the feed is an assignment (F=...) ncopt does not evaluate"
        elif orient is not None and orient.blocked[a]:
            why = orient.reasons[orient.blocked[a]]
        elif modal.feed_mode[a] == G95:
            why = "per-revolution feed (G95)"
        elif no_f is not None and no_f[a]:
            why = "an inverse-time (G93) block without its own F word"
        elif modal.comp[a] != 400:
            why = "cutter radius compensation (G41/G42) active"
        warnings.append(f"{prog.path}:{a + 1}-{b + 1}: not planned ({why}); S/F left as programmed")
    if len(starts) > 20:
        warnings.append(f"{prog.path}: {len(starts) - 20} more stretches not planned")


_PLANE_AXES = {170: (0, 1, 2), 180: (2, 0, 1), 190: (1, 2, 0)}


def _arc_points(prog, lines, modal, i, p0, p1, tol_mm):
    """Points and exact lengths of the arc on line i from p0 to p1 (mm)."""
    a, b, c = _PLANE_AXES.get(int(modal.plane[i]), (0, 1, 2))
    scale = MM_PER_INCH if modal.inch[i] else 1.0
    offs = {k: lines.value(k)[i] * scale for k in "IJK"}
    off = np.nan_to_num(np.array([offs["I"], offs["J"], offs["K"]]))
    has_ijk = any(lines.present(k)[i] for k in "IJK")
    cw = modal.motion[i] == 20
    if lines.present("R")[i] and not has_ijk:
        center = _center_from_r(prog, i, modal, p0, p1, lines.value("R")[i] * scale, cw, a, b)
    elif has_ijk:
        center = off.copy() if modal.arc_absolute[i] else p0 + off
    else:
        _fail(prog, i, "arc with none of I, J, K or R; give the centre or the radius")
    u0, v0 = p0[a] - center[a], p0[b] - center[b]
    u1, v1 = p1[a] - center[a], p1[b] - center[b]
    r0, r1 = math.hypot(u0, v0), math.hypot(u1, v1)
    if min(r0, r1) < MIN_ARC_RADIUS_MM * (1.0 - 1e-9):
        where = "start" if r0 < r1 else "end"
        _fail(prog, i, f"zero-radius arc: the centre is on the {where} point (radius "
              f"{min(r0, r1):.4f} mm); correct I, J, K (LinuxCNC refuses it: \"Zero-radius arc\")")
    # LinuxCNC's tolerance: 2*0.01 mm*sqrt2 (2*0.001 inch*sqrt2) and 0.1 % relative
    t_abs = 2 * math.sqrt(2) * (0.001 * MM_PER_INCH if modal.inch[i] else 0.01)
    err = abs(r0 - r1)
    if err > 100 * t_abs or (err > t_abs and err / max(r0, r1) > 0.001):
        _fail(prog, i, f"radius to end of arc differs from radius to start "
              f"({r0:.4f} vs {r1:.4f} mm); correct the arc centre or end point")
    t0, t1 = math.atan2(v0, u0), math.atan2(v1, u1)
    sweep = (t0 - t1) if cw else (t1 - t0)
    sweep %= 2 * math.pi
    if sweep < 1e-12:
        sweep = 2 * math.pi
    turns = lines.value("P")[i]
    if not np.isnan(turns) and turns > 1:
        sweep += 2 * math.pi * (int(turns) - 1)
    r = max(r0, 1e-9)
    step = 2 * math.acos(max(1 - tol_mm / r, -1.0)) if tol_mm < r else math.pi / 2
    n = max(int(math.ceil(sweep / max(step, 1e-6))), 1)
    n = min(n, 100000)
    t = t0 + (-1 if cw else 1) * sweep * np.arange(1, n + 1) / n
    pts = np.empty((n, 3))
    pts[:, a] = center[a] + r * np.cos(t)
    pts[:, b] = center[b] + r * np.sin(t)
    pts[:, c] = p0[c] + (p1[c] - p0[c]) * np.arange(1, n + 1) / n
    pts[-1] = p1
    length = math.hypot(r * sweep, p1[c] - p0[c]) / n
    return pts, np.full(n, length)


def _center_from_r(prog, i, modal, p0, p1, radius, cw, a, b):
    du, dv = p1[a] - p0[a], p1[b] - p0[b]
    chord = math.hypot(du, dv)
    if chord < 1e-12:
        _fail(prog, i, "R-format arc with identical start and end point; use I/J/K")
    r = abs(radius)
    # a half circle whose printed end point is a hair too far: the LinuxCNC interpreter
    # allows the half chord to exceed R by 0.0001 inch (its TOLERANCE_EQUAL)
    if chord / 2 > r + 0.0001 * MM_PER_INCH:
        _fail(prog, i, f"arc radius {r:.4f} mm is too small for the chord {chord:.4f} mm; "
              "correct R or the end point")
    r = max(r, chord / 2)
    h = math.sqrt(max(r * r - chord * chord / 4, 0.0))
    # the centre lies left of the chord for CCW short arcs; R < 0 asks for the long arc
    sign = (1 if not cw else -1) * (1 if radius > 0 else -1)
    center = np.array(p0, dtype=float)
    center[a] = p0[a] + du / 2 - sign * h * dv / chord
    center[b] = p0[b] + dv / 2 + sign * h * du / chord
    return center


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


def _calls(prog: Program, lines: _LineTable, modal: _Modal) -> np.ndarray:
    """(n_lines,) bool: lines that hand control to code ncopt does not read (a
    subprogram or macro call, a return, flow control, a line it does not interpret)."""
    call = lines.has_m({98, 99}) | lines.has_g({650, 660})
    call |= lines.present("L") & ~lines.has_g({100, 760}) & ~np.isin(modal.motion, list(CANNED))
    for i, reason in prog.opaque_reason.items():
        if reason.upper() not in HARMLESS_OPAQUE and not reason.endswith("="):
            call[i] = True
    return call


def _known_after(n: int, word: np.ndarray, value: np.ndarray, lost: np.ndarray) -> np.ndarray:
    """(n,) bool: the value in force is a word the program states (1), or was lost (0) at
    a ``lost`` line or a word whose value is unknown, until the next known word."""
    code = np.full(n, np.nan)
    code[word] = np.where(np.isnan(value[word]), 0.0, 1.0)
    code[lost] = 0.0
    return ffill(code, 1.0) == 1.0


def _line_state(prog: Program, lines: _LineTable, modal: _Modal, executed: np.ndarray) -> LineState:
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
