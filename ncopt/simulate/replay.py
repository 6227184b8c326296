"""What a real spindle would do with a program: cycle time, real fz and vc.

Replays any program (the original, an ncopt rewrite, or one written by hand)
on a model of the machine, from the program text alone: parse -> interpret ->
contacts.  Nothing the planner computed is reused, so the simulation checks
the planner rather than repeating it (METHOD.md, "Checking the result").

Machine model
-------------
* A block's S and F apply at its start.  F is constant over the block (capped
  at ``Machine.max_feed_mm_min``); rapids run at ``Machine.rapid_mm_min``.
  Within a block time is linear in distance.
* The real spindle speed ramps toward the S in force (capped to the
  machine's range; 0 while the spindle is off) at ``a = Machine.accel_rpm_s``,
  the same for deceleration, continuously across blocks, rapids and air
  moves.  It is piecewise linear in time (ramp, then hold), so it is computed
  exactly at every sample.
* When the spindle starts (M3/M4 after a stop) the control waits for speed:
  the real speed is the commanded one at once.  The wait is not timed.
* Moves the interpreter cannot place (the first move, moves after G28 or a
  subprogram call, G95 feed mode, cutter compensation, a tool axis it cannot
  read) take no time and are not evaluated; a warning counts them.  A G93
  block lasts 1 / F minutes.
* The tool axis comes from the program text (``--kinematics`` for rotary
  angles), so a 5-axis program, or a 3-axis rewrite of one, is judged with
  its real R_eff.

Samples
-------
Every move is sampled at most ``sample_mm`` apart (a move longer than
``ncopt.contacts.locate.MAX_SAMPLES_PER_MOVE`` times that, every length / that many, with
a warning: memory stays bounded by the program), both ends included: the
start of block ``b`` is sampled with block ``b``'s F (and again, at the same
place, as the end of block ``b-1``), so the jump of fz where F changes is
seen exactly.  Within a block F is constant and S monotone, so fz takes its
extremes at the sampled block ends; vc varies with ``R_eff`` and is sampled.
Shares of the cut length weight each sample by the path length it stands for
(trapezoid rule).

Targets default to the program's own S and F at the nominal diameter
(``ncopt.planning.plans.nominal_cutting_data``).  For a rewritten program pass the
original's targets in ``Job.cutting``: a rewrite's S words are planned
speeds, not the nominal one.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from ncopt.reading.read import read_text
from ncopt.model import Job
from ncopt.reading.dialect import detect
from ncopt.reading.stamp import read_stamps, stamped_line
from ncopt.contacts.locate import (MAX_SAMPLES_PER_MOVE, centre_offsets, path_contacts_at_samples,
                       sample_axes, sample_points, samples_per_move)
from ncopt.runtime.errors import NcoptError, UsageError
from ncopt.contacts.geometry import MeshIndex, contacts_from_mesh, load_stl
from ncopt.motion.interp import interpret, tcp_of
from ncopt.planning.intent import nominal_cutting_data
from ncopt.model import MM_PER_INCH
from ncopt.motion.modal import ffill
from ncopt.motion.kinematics import tilt_deg
from ncopt.model import Contacts, Cutter, CuttingData, Machine, Motion, Program, Toolpath
from ncopt.planning.tooltable import BALL, BULL, cutter_for, tool_table

__all__ = ["LagStretch", "SimReport", "SimSeries", "ToolsToSimulate", "simulate_file",
           "simulate_program", "spindle_ramp", "tools_to_simulate"]

# The spindle counts as "not at speed" when it is further than this from its command.
_LAG_RPM = 0.5
# to_dict lists this many lag stretches (in program order) and counts the rest
_LAG_LISTED = 100
_FEED_MOTIONS = (Motion.LINEAR, Motion.ARC_CW, Motion.ARC_CCW)


# ---------------------------------------------------------------- results


@dataclass(frozen=True)
class LagStretch:
    """A stretch of cut where fz leaves its band while the spindle is not at speed.

    The program commands S faster than the spindle can follow (and F with it):
    fz is off until the spindle catches up.

    first_line, last_line : 1-based source lines of the stretch
    length_mm : cut length of the stretch
    worst_fz_pct : fz deviation from its target with the largest magnitude, %
    s_cmd_rpm, s_real_rpm : commanded and real spindle speed at that worst sample
    """

    first_line: int
    last_line: int
    length_mm: float
    worst_fz_pct: float
    s_cmd_rpm: float
    s_real_rpm: float


@dataclass(frozen=True)
class SimReport:
    """What the simulated machine did with a program.

    Times in minutes, lengths in mm, speeds in RPM, ``*_pct`` in percent of the
    target.  ``*_line`` are 1-based source lines (0 when there is no cut).
    Cut statistics cover samples where the cutter touches the part on a feed
    move; NaN when nothing cuts.

    cutting_time_min : feed blocks that cut at some sample
    feed_moves_time_min : every timed feed move (``ncopt.motion.times``): the cutting time that
        inspect, rewrite and batch give for the same program
    feed_time_min : the other feed blocks (approach, retract, air)
    rapid_time_min, total_time_min
    cut_length_mm : length of the feed blocks that cut
    fz_in_band_pct : share of the cut length with ``|fz / fz_target - 1| <= band``
    fz_max_over_pct : largest ``fz / fz_target - 1`` (may be negative)
    fz_min_under_pct : largest ``1 - fz / fz_target`` (may be negative)
    vc_max_over_pct : largest ``vc / vc_target - 1``; negative when vc stays below
    vc_mean_m_min : length-weighted mean vc over the cut
    max_rpm : highest real spindle speed anywhere
    s_words : S words in the program text
    lag : stretches where fz leaves its band because the spindle is not at speed
    """

    path: str
    vc_target_m_min: float
    fz_target_mm: float
    band_pct: float
    sample_mm: float
    samples: int
    cutting_time_min: float
    feed_time_min: float
    rapid_time_min: float
    total_time_min: float
    cut_length_mm: float
    fz_in_band_pct: float
    fz_max_over_pct: float
    fz_max_over_line: int
    fz_min_under_pct: float
    fz_min_under_line: int
    vc_max_over_pct: float
    vc_max_over_line: int
    vc_mean_m_min: float
    max_rpm: float
    max_rpm_line: int
    s_words: int
    lag: tuple = ()
    warnings: tuple = ()
    feed_moves_time_min: float = float("nan")  # every timed feed move (ncopt.motion.times)
    tool: int = -1  # the T number evaluated (-1: the program names none)
    cutter: str = ""  # the cutter evaluated, "D16 ball, 2 teeth"
    cutter_from: str = ""  # where it came from: "the options", "line 5: (...)", a stamp

    @property
    def spindle_lag_breaks_fz(self) -> bool:
        """The program commands S faster than the spindle follows, and fz suffers."""
        return len(self.lag) > 0

    def to_dict(self) -> dict:
        """Plain JSON-ready values; NaN and infinities become None."""
        out = asdict(self)
        out["lag"] = [_clean(asdict(s)) for s in self.lag[:_LAG_LISTED]]
        out["lag_count"] = len(self.lag)
        out["warnings"] = list(self.warnings)
        out["spindle_lag_breaks_fz"] = self.spindle_lag_breaks_fz
        return _clean(out)


def _clean(d: dict) -> dict:
    return {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
            for k, v in d.items()}


@dataclass(frozen=True)
class SimSeries:
    """The simulation along the path, one row per sample, (m,) arrays.

    dist_mm : path length from the program start (moves from unknown
        positions count 0)
    time_s : time from the program start
    line : 1-based source line of the block the sample belongs to
    xyz_mm : (m, 3) programmed point
    s_rpm : real spindle speed; s_cmd_rpm : speed commanded (capped to the machine)
    f_mm_min : feed (the rapid rate on rapids)
    fz_mm : ``F / (z S)`` on feed moves, NaN on rapids (inf with the spindle stopped)
    d_eff_mm : effective cutting diameter ``2 R_eff`` (NaN where not evaluated)
    vc_m_min : ``pi d_eff S / 1000``
    cutting : the cutter touches the part on a feed move
    tool_axis : (m, 3) unit tool axis from the program text (5 axes), None: +Z
    """

    dist_mm: np.ndarray
    time_s: np.ndarray
    line: np.ndarray
    xyz_mm: np.ndarray
    s_rpm: np.ndarray
    s_cmd_rpm: np.ndarray
    f_mm_min: np.ndarray
    fz_mm: np.ndarray
    d_eff_mm: np.ndarray
    vc_m_min: np.ndarray
    cutting: np.ndarray
    tool_axis: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.dist_mm.shape[0])

    def write_csv(self, path: str | Path) -> None:
        """Write the series as CSV with a header row (5 axes: and the tool's tilt from +Z)."""
        cols = np.column_stack((self.dist_mm, self.time_s, self.line, self.xyz_mm, self.s_rpm,
                                self.s_cmd_rpm, self.f_mm_min, self.fz_mm, self.d_eff_mm,
                                self.vc_m_min, self.cutting))
        header = ("dist_mm,time_s,line,x_mm,y_mm,z_mm,s_rpm,s_cmd_rpm,f_mm_min,fz_mm,"
                  "d_eff_mm,vc_m_min,cutting")
        fmt = ["%.4f", "%.5f", "%d", "%.4f", "%.4f", "%.4f", "%.2f", "%.2f", "%.3f", "%.6f",
               "%.4f", "%.3f", "%d"]
        if self.tool_axis is not None:
            cols = np.column_stack((cols, tilt_deg(self.tool_axis)))
            header, fmt = header + ",tilt_deg", fmt + ["%.3f"]
        np.savetxt(path, cols, fmt=fmt, delimiter=",", header=header, comments="")


# ---------------------------------------------------------------- entry points


def simulate_file(path: str | Path, job: Job, mesh_path: str | Path | None, *,
                  sample_mm: float = 0.1, band: float | None = None) -> tuple[SimReport, SimSeries]:
    """Read a program and a part mesh, and simulate (see :func:`simulate_program`)."""
    text = Path(path).read_bytes().decode("latin-1")
    mesh_index = MeshIndex(load_stl(mesh_path)) if mesh_path else None
    return simulate_program(text, job, mesh_index, path=str(path), sample_mm=sample_mm,
                            band=band)


def simulate_program(prog_text: str, job: Job, mesh_index: MeshIndex | None = None, *,
                     path: str = "<input>", sample_mm: float = 0.1,
                     contacts: Contacts | None = None,
                     band: float | None = None,
                     read: tuple[Program, Toolpath] | None = None) -> tuple[SimReport, SimSeries]:
    """Replay a program on the machine model of ``job``.

    Parameters
    ----------
    prog_text : str
        Program text (decoded as latin-1).
    job : Job
        Machine, cutter (None: from the program's tool comments), targets
        (``job.cutting``; None: the program's own S and F at the nominal
        diameter, ``ncopt.planning.plans.nominal_cutting_data``) and ``job.tool``, the one
        tool evaluated when the program cuts with several.
    mesh_index : MeshIndex or None
        The part; needed unless ``contacts`` are given.
    sample_mm : float
        Longest distance between samples along a move, mm.
    contacts : Contacts or None
        Precomputed contacts, one row per point of
        ``ncopt.contacts.locate.sample_points(toolpath, sample_mm)``, e.g.
        ``ncopt.contacts.locate.mesh_contacts_at_samples(...)``: an original and its
        rewrite have the same toolpath and can share them.
    band : float or None
        Relative fz band for ``fz_in_band_pct`` and the lag check (None: the band an
        ncopt stamp records, else 0.02).
    read : (Program, Toolpath) or None
        The program as :func:`tools_to_simulate` read it (``ToolsToSimulate.read``): the
        same text with the same job's control, decimal point and kinematics, not read again.

    Returns
    -------
    (SimReport, SimSeries)

    Raises
    ------
    UsageError
        No mesh and no contacts; contacts of the wrong size; a bad sample_mm;
        several tools and no ``job.tool``; no cutter known.
    """
    if not sample_mm > 0:
        raise UsageError(f"sample spacing must be positive, got {sample_mm}", path)
    if not math.isfinite(sample_mm):
        raise UsageError(f"sample spacing must be a finite length, got {sample_mm}", path)
    if read is None:
        prog = read_text(prog_text, path, job)
        read = prog, interpret(prog, kinematics=job.kinematics,
                               tcp=tcp_of(job, detect(prog_text).name))
    prog, tp = read
    _check_sample_count(tp, sample_mm, path)
    cutter, tool_mask, number, source = _evaluated_tool(prog, tp, job, path)
    job = replace(job, cutter=cutter)
    moves = _move_table(prog, tp, job, tool_mask)
    planned = np.concatenate(([False], moves.candidate & (moves.target_rpm > 0)))
    stamp = _stamp_of(prog, int(np.max(tp.tool[1:][tool_mask], initial=-1)))
    if job.cutting is None and stamp is not None:  # rewritten by ncopt: its nominal data
        cut = stamp.cutting
    else:
        cut = job.cutting or nominal_cutting_data(tp, np.flatnonzero(planned), job.cutter, path)
    if mesh_index is None and contacts is None:  # contacts from the toolpath's own shape
        contacts = path_contacts_at_samples(tp, job.cutter, planned, sample_mm,
                                            _normal_groups(prog, tp))
    runs = _spindle_runs(moves, job.machine.accel_rpm_s)
    series, weight, mv = _sample(tp, moves, runs, job, sample_mm, mesh_index, contacts, path)
    s_words = int(np.count_nonzero(prog.word_letter == ord("S")))
    if band is None:  # the band the rewrite held, as its stamp says; else 2 %
        band = stamp.band_pct / 100.0 if stamp is not None and stamp.band_pct else 0.02
    report = _report(path, moves, series, weight, mv, cut, band, sample_mm, s_words,
                     _warnings(path, tp, moves, job.machine, series)
                     + _coarse_moves(path, tp, moves, sample_mm))
    return replace(report, tool=number, cutter=describe_cutter(cutter),
                   cutter_from=source), series


# The most samples a simulation takes: each costs about 300 bytes of memory at its peak,
# so this is about 3 GB (the 110 m of moves of a 3.4 MB Fusion program take 1.4 million
# at the default 0.1 mm).
MAX_SAMPLES = 10_000_000


def _check_sample_count(tp, sample_mm: float, path: str) -> None:
    """Refuse (UsageError) a sample spacing that would take more than MAX_SAMPLES samples
    along the program's moves, naming the spacing that fits: --sample 1e-9 once grew to
    24 GB before the kernel ended it."""
    n = int(samples_per_move(tp, sample_mm).sum()) if tp.n > 1 else 0
    if n <= MAX_SAMPLES:
        return
    length = float(np.sum(np.linalg.norm(np.diff(tp.xyz_mm, axis=0), axis=1)))
    fits = length / max(MAX_SAMPLES - (tp.n - 1), 1)
    least = float(f"{fits * 1.05:.2g}")
    raise UsageError(f"sample spacing {sample_mm:g} mm would take {n:,} samples along the "
                     f"program's {length / 1000:.3g} m of moves; at most {MAX_SAMPLES:,} fit in "
                     f"memory: give a spacing of {least:g} mm or more (--sample)", path)


# ---------------------------------------------------------------- moves and the spindle


@dataclass(frozen=True)
class _Moves:
    """Per move (toolpath points 1..n-1), (nm,) arrays."""

    line: np.ndarray  # 1-based source line
    length_mm: np.ndarray  # 0 for moves from an unknown position
    dt_s: np.ndarray
    t0_s: np.ndarray  # start time
    d0_mm: np.ndarray  # start distance
    speed_mm_min: np.ndarray  # real F (rapid rate for rapids; NaN when unknown)
    target_rpm: np.ndarray  # speed the spindle heads for (0 when off)
    start: np.ndarray  # the spindle starts at this move: the control waits for speed
    rapid: np.ndarray
    feed: np.ndarray
    known: np.ndarray
    candidate: np.ndarray  # known feed move of the evaluated tool


def _move_table(prog: Program, tp: Toolpath, job: Job, tool_mask: np.ndarray) -> _Moves:
    m = job.machine
    motion, known = tp.motion[1:], tp.known[1:]
    rapid = motion == Motion.RAPID
    feed = np.isin(motion, _FEED_MOTIONS)
    speed = np.where(rapid, m.rapid_mm_min, np.minimum(tp.feed_mm_min[1:], m.max_feed_mm_min))
    speed = np.where(known & (rapid | feed), speed, np.nan)
    length = np.where(known, tp.seg_len_mm[1:], 0.0)
    ok = np.isfinite(speed) & (speed > 0)
    dt = np.where(ok, 60.0 * length / np.where(ok, speed, 1.0), 0.0)
    on = tp.spindle_on[1:] if tp.spindle_on is not None else tp.spindle_rpm[1:] > 0
    s = tp.spindle_rpm[1:]
    target = np.where(on & (s > 0), np.clip(s, m.min_rpm, m.max_rpm), 0.0)
    start = on & _spindle_starts(prog, tp)
    candidate = feed & known & tool_mask
    return _Moves(line=tp.line[1:].astype(np.int64) + 1, length_mm=length, dt_s=dt,
                  t0_s=_starts(dt), d0_mm=_starts(length), speed_mm_min=speed,
                  target_rpm=target, start=start, rapid=rapid, feed=feed, known=known,
                  candidate=candidate)


def _spindle_starts(prog: Program, tp: Toolpath) -> np.ndarray:
    """(nm,) bool: an M3/M4 starts the stopped spindle at or before this move (since the last)."""
    m = prog.word_letter == ord("M")
    line, code = prog.word_line[m], prog.word_value[m]
    state = np.full(prog.n_lines, np.nan)
    state[line[np.isin(code, (2, 5, 30))]] = 0.0
    state[line[np.isin(code, (3, 4))]] = 1.0
    before = np.concatenate(([0.0], ffill(state, 0.0)[:-1]))
    starts = np.zeros(prog.n_lines + 1, dtype=np.int64)
    starts[1:] = np.cumsum((state == 1.0) & (before == 0.0))
    move_line = tp.line.astype(np.int64)  # point 0 has line -1: count from the top
    return starts[move_line[1:] + 1] > starts[move_line[:-1] + 1]


def _starts(x: np.ndarray) -> np.ndarray:
    return np.concatenate(([0.0], np.cumsum(x)[:-1])) if x.size else x.copy()


def _normal_groups(prog: Program, tp: Toolpath) -> np.ndarray:
    """(n,) int per toolpath point: whose moves its normal is estimated from without a
    mesh, as the planner does: each operation of the program on its own, and the
    operations an ncopt stamp says were planned together (one group per tool)."""
    from ncopt.planning.operations import spans  # scipy: only when a simulation needs it

    line_group = np.zeros(prog.n_lines + 1, dtype=np.int64)
    for k, sp in enumerate(spans(prog, tp)):
        line_group[sp.first_line:sp.last_line + 1] = k + 1
    stamps = read_stamps(prog)
    for st in stamps.values():
        if st.lines is None:  # an ncopt 0.1 stamp: every operation of its tool
            line_group[np.flatnonzero(tp.lines.tool == st.tool)] = -1 - st.tool
            continue
        first, last = (stamped_line(stamps, n) for n in st.lines)
        line_group[first:last + 1] = -1 - st.tool
    return line_group[np.clip(tp.line, 0, prog.n_lines)]


def _stamp_of(prog: Program, tool: int):
    """The first ncopt stamp of T``tool`` (None: the program is not an ncopt output)."""
    found = sorted((st for (t, _), st in read_stamps(prog).items() if t == tool),
                   key=lambda st: st.line)
    return found[0] if found else None


def _evaluated_tool(prog: Program, tp: Toolpath, job: Job,
                    path: str) -> tuple[Cutter, np.ndarray, int, str]:
    """The cutter to evaluate, (nm,) bool: the moves made with it, its T number (-1: none)
    and where the cutter came from.

    One tool per simulation: ``job.tool``, else the program's only cutting tool
    (:func:`tools_to_simulate` picks them in a program of several).
    Its cutter is ``job.cutter``, else read from the program's tool comments.
    """
    tool = tp.tool[1:]
    used = _feed_tools(tp)
    if job.tool is not None:
        if job.tool not in used:
            raise UsageError(f"no feed moves with tool T{job.tool}; check --tool", path)
        used = [job.tool]
    if len(used) > 1:
        listed = ", ".join(f"T{t}" for t in used)
        raise UsageError(f"the program cuts with several tools ({listed}); simulate one at a "
                         "time with --tool N", path)
    mask = tool == used[0] if used else np.zeros(tool.shape, dtype=bool)
    number = used[0] if used else -1
    if job.cutter is not None:
        return job.cutter, mask, number, "the options"
    stamp = _stamp_of(prog, number)
    if stamp is not None:  # the cutter ncopt planned with (mm, its teeth), as rewrite reads it
        return stamp.cutter, mask, number, f"the ncopt stamp on line {stamp.line + 1}"
    if number in job.tool_library:
        return job.tool_library[number], mask, number, "the tool profiles"
    info = cutter_for(tool_table(prog), number, len(used))
    if info is None or info.kind not in (BALL, BULL):
        raise UsageError("the program's comments do not describe a ball or bull-nose cutter; "
                         "give --diameter (and --corner-radius for a bull-nose)", path)
    inch = tp.line_inch is not None and bool(np.any(tp.line_inch))
    teeth = f"teeth from line {info.teeth_line}" if info.teeth else f"{job.teeth} teeth assumed"
    return (info.cutter(info.teeth or job.teeth, MM_PER_INCH if inch else 1.0), mask, number,
            f"line {info.line}: ({info.text.strip()}); {teeth}")


def _feed_tools(tp: Toolpath) -> list:
    """The T numbers of the program's known feed moves, in ascending order."""
    feed = np.isin(tp.motion[1:], _FEED_MOTIONS) & tp.known[1:]
    return np.unique(tp.tool[1:][feed]).tolist()


def describe_cutter(cutter: Cutter) -> str:
    """``D16 ball, 2 teeth``, ``D10 bull-nose r2, 4 teeth`` (mm)."""
    kind = "ball" if cutter.is_ball else f"bull-nose r{cutter.corner_radius_mm:g}"
    return f"D{cutter.diameter_mm:g} {kind}, {cutter.teeth} teeth"


# ---------------------------------------------------------------- several tools


@dataclass(frozen=True)
class ToolsToSimulate:
    """Which tools of a program to simulate, one simulation each.

    tools : T numbers for ``Job.tool``, in program order; ``(None,)``: the program's only
        tool (or ``Job.tool``), simulated as :func:`simulate_program` picks it
    left : (T, why) the tools that cut but are not simulated: ncopt would plan none of
        their operations
    operations : ``ncopt.planning.inspection.JudgedOperation`` per operation, as rewrite would split
        and judge them (empty when not judged)
    read : the program and its toolpath, for :func:`simulate_program`
    """

    tools: tuple
    left: tuple = ()
    operations: tuple = ()
    read: tuple | None = None


def tools_to_simulate(prog_text: str, job: Job, path: str = "<input>",
                      judge: bool = False) -> ToolsToSimulate:
    """The tools of a program to simulate: ``job.tool``, the only tool, or, in a program
    that cuts with several, each tool ncopt would plan an operation of (as ``ncopt rewrite``
    and ``ncopt inspect`` judge them), the others listed with why they are left.

    ``judge``: judge the operations of a single-tool program too (for a report).
    Raises UsageError where rewrite would (``--diameter`` on a program of several tools),
    and when a program of several tools has none ncopt plans.
    """
    from ncopt.planning.inspection import judge_operations

    prog = read_text(prog_text, path, job)
    tp = interpret(prog, kinematics=job.kinematics, tcp=tcp_of(job, detect(prog.text).name))
    used = _feed_tools(tp)
    if job.tool is not None or len(used) <= 1:
        ops = ()
        if judge:  # for the report's table only: the simulation does not need it
            try:
                ops = judge_operations(prog, tp, job, job.machine.max_feed_mm_min)
            except NcoptError:
                ops = ()
        return ToolsToSimulate((job.tool,), (), ops, (prog, tp))
    ops = judge_operations(prog, tp, job, job.machine.max_feed_mm_min)
    planned = list(dict.fromkeys(o.tool for o in ops if o.planned))  # program order
    left = []
    for t in used:
        if t in planned:
            continue
        why = list(dict.fromkeys(o.reason for o in ops if o.tool == t and o.reason))
        left.append((t, "; ".join(why) or "no operation ncopt plans"))
    if not planned:
        listed = "; ".join(f"T{t}: {why}" for t, why in left)
        raise UsageError(f"none of the tools the program cuts with is one ncopt plans "
                         f"({listed}); simulate one with --tool N (and --diameter for its "
                         "cutter)", path)
    return ToolsToSimulate(tuple(planned), tuple(left), ops, (prog, tp))


@dataclass(frozen=True)
class _Runs:
    """Stretches of moves with one commanded speed: (nr,) arrays plus the move -> run map."""

    first_move: np.ndarray
    w0_rpm: np.ndarray  # real speed at the start of the run
    of_move: np.ndarray  # (nm,) run of each move


def _spindle_runs(moves: _Moves, a: float) -> _Runs:
    """Real spindle speed at the start of each run of constant command.

    The speed at the end of a run depends on the one at its start: see
    :func:`_run_start_speeds`.
    """
    target = moves.target_rpm
    brk = moves.start.copy()
    if brk.size:
        brk[0] = True
        brk[1:] |= target[1:] != target[:-1]
    first = np.flatnonzero(brk)
    end = moves.t0_s[-1] + moves.dt_s[-1] if first.size else 0.0
    dur = np.append(moves.t0_s[first[1:]], end)[:first.size] - moves.t0_s[first]
    reach = np.where(dur > 0, a * dur, 0.0)
    w0 = _run_start_speeds(target[first], moves.start[first], reach)
    return _Runs(first_move=first, w0_rpm=w0, of_move=np.cumsum(brk) - 1)


# _run_start_speeds: rounds, and runs recomputed per run, before the rest goes run by run
RUN_ROUNDS, RUN_WORK = 200, 3


def _ramped(w: np.ndarray, t: np.ndarray, d: np.ndarray) -> np.ndarray:
    """The speed after ramping from ``w`` toward ``t`` by at most ``d``, stopping at ``t``
    (``w + d`` reaching ``t`` is ``t``; NaN anywhere gives ``t``)."""
    up, down = w + d, w - d
    return np.where(w < t, np.where(up < t, up, t), np.where(down > t, down, t))


def _run_start_speeds(t: np.ndarray, s: np.ndarray, reach: np.ndarray) -> np.ndarray:
    """(nr,) speed at the start of each run: 0 at first, the run's command ``t`` where it
    starts the spindle (``s``), else where the run before left it, ramping toward its
    command by at most its ``reach`` (RPM).

    A recurrence, solved without a loop over the runs: first guess that every run
    reached its command (most do), then recompute the runs after those whose guess was
    wrong, as often as a wrong guess still changes the next one (the longest chain of
    runs that end short of their command: ~70 rounds on the 700k runs of a 1M-block
    rewrite).  Every run before the first one still to be recomputed is then right;
    after ``RUN_ROUNDS`` rounds, or once ``RUN_WORK`` times as many runs as there are
    were recomputed (a spindle that lags behind its S words over thousands of runs),
    the rest is finished run by run.  Each run's value is the same float
    operations on the same values as the run-by-run loop, so the result is that
    loop's, bit for bit."""
    n = t.shape[0]
    w0 = np.empty(n)
    if n == 0:
        return w0
    w0[0] = 0.0
    w0[1:] = t[:-1]
    w0[s] = t[s]
    k = None  # runs whose next one is to be (re)computed; None: all of them
    budget = RUN_WORK * n  # runs recomputed in all rounds: past that a loop is cheaper
    for _ in range(RUN_ROUNDS):
        if k is not None and not k.size:
            return w0
        budget -= n if k is None else k.size
        if budget < 0:
            break
        if k is None:
            j = slice(1, n)
            nxt = np.where(s[j], t[j], _ramped(w0[:-1], t[:-1], reach[:-1]))
        else:
            j = k + 1
            nxt = np.where(s[j], t[j], _ramped(w0[k], t[k], reach[k]))
        old = w0[j]
        changed = (nxt != old) & ~(np.isnan(nxt) & np.isnan(old))
        j = np.flatnonzero(changed) + 1 if k is None else j[changed]
        w0[j] = nxt[changed]
        k = j[j < n - 1]
    if k is None or k.size:
        _runs_one_by_one(w0, t, s, reach, 0 if k is None else int(k[0]))
    return w0


def _runs_one_by_one(w0: np.ndarray, t: np.ndarray, s: np.ndarray, reach: np.ndarray,
                     first: int) -> None:
    """:func:`_run_start_speeds` from run ``first`` on (right up to it), run by run."""
    w = float(w0[first])
    target, starts, ramp = t.tolist(), s.tolist(), reach.tolist()
    out = memoryview(w0)
    for i in range(first, w0.shape[0] - 1):
        if w < target[i]:
            w += ramp[i]
            if not w < target[i]:
                w = target[i]
        else:
            w -= ramp[i]
            if not w > target[i]:
                w = target[i]
        if starts[i + 1]:
            w = target[i + 1]
        out[i + 1] = w


def lagging_blocks(prog: Program, tp: Toolpath, s_rpm: np.ndarray, f_mm_min: np.ndarray,
                   machine: Machine, rev_mm: np.ndarray, band: float) -> np.ndarray:
    """Toolpath points (the moves ending there) where the real spindle, ramping toward the
    commanded S at its acceleration, leaves fz out of its band at the move's start or end
    while it is not at the commanded speed (as :func:`simulate_program` flags a lag).

    ``s_rpm``, ``f_mm_min``: (n,) S and F in force per point; ``rev_mm``: (n,) the target
    feed per revolution fz z of each move to check (NaN: not checked).  The same machine model as
    :func:`simulate_program`, at the ends of the moves only (fz is monotone inside a move:
    F is constant and the spindle ramps one way), so it is cheap enough to run after
    every rewrite.
    """
    job = Job(machine=machine)
    moves = _move_table(prog, replace(tp, spindle_rpm=s_rpm, feed_mm_min=f_mm_min), job,
                        np.ones(tp.n - 1, dtype=bool))
    runs = _spindle_runs(moves, machine.accel_rpm_s)
    run = runs.of_move
    t0 = moves.t0_s - moves.t0_s[runs.first_move[run]]
    a = machine.accel_rpm_s
    start = spindle_ramp(runs.w0_rpm[run], moves.target_rpm, t0, a)
    end = spindle_ramp(runs.w0_rpm[run], moves.target_rpm, t0 + moves.dt_s, a)
    rev = rev_mm[1:]
    check = np.isfinite(rev) & moves.feed & moves.known & (moves.target_rpm > 0)
    speed = moves.speed_mm_min

    def out_of_band(real: np.ndarray) -> np.ndarray:
        with np.errstate(divide="ignore", invalid="ignore"):
            dev = speed / real / rev - 1.0
        return (dev > band * (1 + 1e-6) + 1e-9) | (dev < -band * (1 + 1e-6) - 1e-9)

    # fz is monotone along a move; while the spindle lags it runs from its value at the
    # start to its value where the spindle comes within _LAG_RPM of the command (or, if it
    # never does, to its value at the end)
    target = moves.target_rpm
    lags_start = np.abs(start - target) > _LAG_RPM
    lags_end = np.abs(end - target) > _LAG_RPM
    near = target + np.sign(start - target) * _LAG_RPM
    bad = check & lags_start & (out_of_band(start) | np.where(lags_end, out_of_band(end),
                                                               out_of_band(near)))
    return np.flatnonzero(bad) + 1


def spindle_ramp(w0_rpm: np.ndarray, target_rpm: np.ndarray, tau_s: np.ndarray,
                 a_rpm_s: float) -> np.ndarray:
    """Speed ``tau_s`` after a ramp from ``w0_rpm`` toward ``target_rpm`` began, RPM.

    Linear at ``a_rpm_s`` until the target is reached, then constant.
    """
    step = np.where(tau_s > 0, a_rpm_s * tau_s, 0.0)
    return np.where(w0_rpm < target_rpm, np.minimum(w0_rpm + step, target_rpm),
                    np.maximum(w0_rpm - step, target_rpm))


# ---------------------------------------------------------------- samples


def _sample(tp, moves, runs, job, sample_mm, mesh_index, contacts, path):
    """The series along the path, each sample's share of path length (mm) and its move."""
    xyz_u, point_u = sample_points(tp, sample_mm)
    nm = moves.line.shape[0]
    counts = np.bincount(point_u, minlength=tp.n)[1:]
    first_u = np.cumsum(counts) - counts  # unique sample at the start of each move
    reps = counts + 1
    mv = np.repeat(np.arange(nm), reps)
    k = np.arange(int(reps.sum())) - np.repeat(np.cumsum(reps) - reps, reps)
    frac = k / counts[mv]
    uidx = first_u[mv] + k
    weight = (moves.length_mm / counts)[mv] * np.where((k == 0) | (k == counts[mv]), 0.5, 1.0)
    time_s = moves.t0_s[mv] + frac * moves.dt_s[mv]
    run = runs.of_move[mv]
    s_cmd = moves.target_rpm[mv]
    s_real = spindle_ramp(runs.w0_rpm[run], s_cmd, time_s - moves.t0_s[runs.first_move[run]],
                          job.machine.accel_rpm_s)
    cand = moves.candidate[mv]
    r_eff, touch = _contact_radius(tp, job, xyz_u, uidx, cand, sample_mm, mesh_index,
                                   contacts, path)
    f = moves.speed_mm_min[mv]
    with np.errstate(divide="ignore", invalid="ignore"):
        fz = np.where(moves.feed[mv], f / (job.cutter.teeth * s_real), np.nan)
    d_eff = 2.0 * r_eff
    axis = sample_axes(tp, sample_mm)
    series = SimSeries(dist_mm=moves.d0_mm[mv] + frac * moves.length_mm[mv], time_s=time_s,
                       line=moves.line[mv], xyz_mm=xyz_u[uidx], s_rpm=s_real, s_cmd_rpm=s_cmd,
                       f_mm_min=f, fz_mm=fz, d_eff_mm=d_eff,
                       vc_m_min=np.pi * d_eff * s_real / 1000.0, cutting=cand & touch,
                       tool_axis=None if axis is None else axis[uidx])
    return series, weight, mv


def _contact_radius(tp, job, xyz_u, uidx, cand, sample_mm, mesh_index, contacts, path):
    """R_eff (mm, NaN where not evaluated) and touching flag per series sample."""
    need = np.zeros(xyz_u.shape[0], dtype=bool)
    need[uidx[cand]] = True
    rows = np.flatnonzero(need)
    if contacts is not None:
        if contacts.r_eff_mm.shape[0] != xyz_u.shape[0]:
            raise UsageError(f"the contacts have {contacts.r_eff_mm.shape[0]} rows but the "
                             f"program has {xyz_u.shape[0]} sample points at {sample_mm} mm; "
                             "compute them on ncopt.contacts.locate.sample_points with the same spacing",
                             path)
        r_u, cut_u = contacts.r_eff_mm[rows], contacts.cutting[rows]
    else:  # the tool axis from the program text (5 axes), the centre along it
        axis = sample_axes(tp, sample_mm)
        axis = None if axis is None else axis[rows]
        centers = xyz_u[rows] + centre_offsets(tp, job.cutter, axis)
        got = contacts_from_mesh(centers, mesh_index, job.cutter, tol_mm=job.contact_tol_mm,
                                 axis=axis)
        r_u, cut_u = got.r_eff_mm, got.cutting
    r_all = np.full(xyz_u.shape[0], np.nan)
    touch_all = np.zeros(xyz_u.shape[0], dtype=bool)
    r_all[rows], touch_all[rows] = r_u, cut_u
    return np.where(cand, r_all[uidx], np.nan), touch_all[uidx]


# ---------------------------------------------------------------- report


def _report(path, moves, series, weight, mv, cut: CuttingData, band, sample_mm, s_words,
            warnings) -> SimReport:
    move_cuts = np.zeros(moves.line.shape[0], dtype=bool)
    np.logical_or.at(move_cuts, mv, series.cutting)
    cutting_time = float(moves.dt_s[move_cuts].sum()) / 60.0
    feed_time = float(moves.dt_s[moves.feed & ~move_cuts].sum()) / 60.0
    rapid_time = float(moves.dt_s[moves.rapid].sum()) / 60.0
    c = series.cutting
    fz_dev = series.fz_mm[c] / cut.fz_mm - 1.0
    vc_dev = series.vc_m_min[c] / cut.vc_m_min - 1.0
    w, lines = weight[c], series.line[c]
    cut_w = float(w.sum())
    in_band = np.abs(fz_dev) <= band
    return SimReport(
        path=path, vc_target_m_min=cut.vc_m_min, fz_target_mm=cut.fz_mm, band_pct=100 * band,
        sample_mm=sample_mm, samples=len(series), cutting_time_min=cutting_time,
        feed_moves_time_min=cutting_time + feed_time,
        feed_time_min=feed_time, rapid_time_min=rapid_time,
        total_time_min=float(moves.dt_s.sum()) / 60.0,
        cut_length_mm=float(moves.length_mm[move_cuts].sum()),
        fz_in_band_pct=100.0 * float(w[in_band].sum()) / cut_w if cut_w > 0 else math.nan,
        fz_max_over_pct=_extreme(100 * fz_dev), fz_max_over_line=_where(fz_dev, lines),
        fz_min_under_pct=_extreme(-100 * fz_dev), fz_min_under_line=_where(-fz_dev, lines),
        vc_max_over_pct=_extreme(100 * vc_dev), vc_max_over_line=_where(vc_dev, lines),
        vc_mean_m_min=float(np.sum(w * series.vc_m_min[c])) / cut_w if cut_w > 0 else math.nan,
        max_rpm=float(series.s_rpm.max()) if len(series) else 0.0,
        max_rpm_line=int(series.line[np.argmax(series.s_rpm)]) if len(series) else 0,
        s_words=s_words, lag=_lag_stretches(series, weight, cut, band), warnings=warnings)


def _extreme(x: np.ndarray) -> float:
    """Largest value ignoring NaN (inf counts); NaN for no data."""
    x = x[~np.isnan(x)]
    return float(x.max()) + 0.0 if x.size else math.nan  # + 0.0: no "-0.0" in reports


def _where(x: np.ndarray, lines: np.ndarray) -> int:
    ok = ~np.isnan(x)
    if not ok.any():
        return 0
    return int(lines[ok][np.argmax(x[ok])])


def _lag_stretches(series: SimSeries, weight: np.ndarray, cut: CuttingData,
                   band: float) -> tuple:
    """Consecutive cut samples with fz out of band while the spindle is not at speed, on
    moves whose F means the target fz at the commanded S (a move the program runs at
    another feed per tooth, a ramp or a plunge at its own feed, is off target by design,
    not because the spindle lags)."""
    dev = series.fz_mm / cut.fz_mm - 1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        meant = series.fz_mm * series.s_rpm / series.s_cmd_rpm / cut.fz_mm - 1.0
    at_target = np.abs(meant) <= 2.0 * band
    lagging = np.abs(series.s_rpm - series.s_cmd_rpm) > _LAG_RPM
    idx = np.flatnonzero(series.cutting & ~(np.abs(dev) <= band) & lagging & at_target)
    if idx.size == 0:
        return ()
    new = np.concatenate(([True], np.diff(idx) > 1))
    group = np.cumsum(new) - 1
    first, last = idx[new], idx[np.concatenate((new[1:], [True]))]
    length = np.bincount(group, weights=weight[idx])
    mag = np.nan_to_num(np.abs(dev[idx]), nan=np.inf)
    order = np.lexsort((-mag, group))  # by stretch, worst first
    worst = idx[order[np.concatenate(([True], np.diff(group[order]) > 0))]]
    return tuple(LagStretch(int(series.line[a]), int(series.line[b]), float(n),
                            float(100 * dev[w]), float(series.s_cmd_rpm[w]), float(series.s_rpm[w]))
                 for a, b, n, w in zip(first, last, length, worst))


def _coarse_moves(path: str, tp: Toolpath, moves: _Moves, sample_mm: float) -> tuple:
    """Moves too long to sample every ``sample_mm``: where, and how coarsely."""
    chord = np.linalg.norm(np.diff(tp.xyz_mm, axis=0), axis=1)
    long = np.flatnonzero(chord > MAX_SAMPLES_PER_MOVE * sample_mm)
    if long.size == 0:
        return ()
    i = long[np.argmax(chord[long])]
    return (f"{path}:{moves.line[i]}: a move of {chord[i]:.6g} mm is sampled every "
            f"{chord[i] / MAX_SAMPLES_PER_MOVE:.6g} mm, not {sample_mm:g} "
            f"({long.size} move{'s' if long.size > 1 else ''} longer than "
            f"{MAX_SAMPLES_PER_MOVE * sample_mm:g} mm; at most {MAX_SAMPLES_PER_MOVE} samples "
            "a move)",)


def _warnings(path: str, tp: Toolpath, moves: _Moves, machine: Machine,
              series: SimSeries) -> tuple:
    out = list(tp.warnings)
    stopped = np.flatnonzero(series.cutting & (series.s_rpm <= 0))
    if stopped.size:
        out.append(f"{path}:{series.line[stopped[0]]}: the cutter touches the part with the "
                   "spindle stopped; check M3/M5 and S")
    s = tp.spindle_rpm[1:]
    over = np.flatnonzero((s > machine.max_rpm) & (moves.target_rpm > 0))
    if over.size:
        out.append(f"{path}:{moves.line[over[0]]}: S{s[over[0]]:g} is above the machine's "
                   f"{machine.max_rpm:g} RPM ({over.size} moves); the control clamps it")
    # the first move always starts from an unknown position
    unknown = np.flatnonzero(~moves.known & (moves.rapid | moves.feed))[1:]
    if unknown.size:
        out.append(f"{path}:{moves.line[unknown[0]]}: {unknown.size} moves from an unknown "
                   "position, in G95 or G41/G42 mode or with a tool axis ncopt cannot read are "
                   "not timed nor evaluated")
    return tuple(out)
