"""What a real spindle would do with a program: cycle time, real fz and vc.

Replays any program (the original, an ncopt rewrite, or one written by hand)
on a model of the machine, from the program text alone: parse -> interpret ->
contacts.  Nothing the planner computed is reused, so the simulation checks
the planner rather than repeating it (docs/method.md, "Checking the result").

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
(``ncopt.planning.intent.nominal_cutting_data``).  For a rewritten program pass the
original's targets in ``Job.cutting``: a rewrite's S words are planned
speeds, not the nominal one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ncopt.contacts.geometry import MeshIndex, load_stl
from ncopt.contacts.locate import path_contacts_at_samples
from ncopt.model import Contacts, Job, Program, Toolpath
from ncopt.motion.interp import interpret, tcp_of
from ncopt.planning.inspection import JudgedOperation, judge_operations
from ncopt.planning.intent import nominal_cutting_data
from ncopt.reading.dialect import detect
from ncopt.reading.read import read_text
from ncopt.runtime.errors import NcoptError, UsageError
from ncopt.simulate.movetable import feed_tools, move_table
from ncopt.simulate.results import SimReport, SimSeries
from ncopt.simulate.samples import check_sample_count, normal_groups, sample_series
from ncopt.simulate.spindle import spindle_runs
from ncopt.simulate.summary import coarse_moves, replay_warnings, summarize
from ncopt.simulate.toolchoice import describe_cutter, evaluated_tool, stamp_of

__all__ = ["ToolsToSimulate", "simulate_file", "simulate_program", "tools_to_simulate"]


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
        diameter, ``ncopt.planning.intent.nominal_cutting_data``) and ``job.tool``, the one
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
    check_sample_count(tp, sample_mm, path)
    cutter, tool_mask, number, source = evaluated_tool(prog, tp, job, path)
    job = replace(job, cutter=cutter)
    moves = move_table(prog, tp, job, tool_mask)
    planned = np.concatenate(([False], moves.candidate & (moves.target_rpm > 0)))
    stamp = stamp_of(prog, int(np.max(tp.tool[1:][tool_mask], initial=-1)))
    if job.cutting is None and stamp is not None:  # rewritten by ncopt: its nominal data
        cut = stamp.cutting
    else:
        cut = job.cutting or nominal_cutting_data(tp, np.flatnonzero(planned), job.cutter, path)
    if mesh_index is None and contacts is None:  # contacts from the toolpath's own shape
        contacts = path_contacts_at_samples(tp, job.cutter, planned, sample_mm,
                                            normal_groups(prog, tp))
    runs = spindle_runs(moves, job.machine.accel_rpm_s)
    series, weight, mv = sample_series(tp, moves, runs, job, sample_mm, mesh_index, contacts,
                                       path)
    s_words = int(np.count_nonzero(prog.word_letter == ord("S")))
    if band is None:  # the band the rewrite held, as its stamp says; else 2 %
        band = stamp.band_pct / 100.0 if stamp is not None and stamp.band_pct else 0.02
    report = summarize(path, moves, series, weight, mv, cut, band, sample_mm, s_words,
                       replay_warnings(path, tp, moves, job.machine, series)
                       + coarse_moves(path, tp, moves, sample_mm))
    return replace(report, tool=number, cutter=describe_cutter(cutter),
                   cutter_from=source), series


@dataclass(frozen=True)
class ToolsToSimulate:
    """Which tools of a program to simulate, one simulation each.

    tools : T numbers for ``Job.tool``, in program order; ``(None,)``: the program's only
        tool (or ``Job.tool``), simulated as :func:`simulate_program` picks it
    left : (T, why) the tools that cut but are not simulated: ncopt would plan none of
        their operations
    operations : ``ncopt.planning.inspection.JudgedOperation`` per operation, as rewrite
        would split and judge them (empty when not judged)
    read : the program and its toolpath, for :func:`simulate_program`
    """

    tools: tuple[int | None, ...]
    left: tuple[tuple[int, str], ...] = ()
    operations: tuple[JudgedOperation, ...] = ()
    read: tuple[Program, Toolpath] | None = None


def tools_to_simulate(prog_text: str, job: Job, path: str = "<input>",
                      judge: bool = False) -> ToolsToSimulate:
    """The tools of a program to simulate: ``job.tool``, the only tool, or, in a program
    that cuts with several, each tool ncopt would plan an operation of (as ``ncopt rewrite``
    and ``ncopt inspect`` judge them), the others listed with why they are left.

    ``judge``: judge the operations of a single-tool program too (for a report).
    Raises UsageError where rewrite would (``--diameter`` on a program of several tools),
    and when a program of several tools has none ncopt plans.
    """
    prog = read_text(prog_text, path, job)
    tp = interpret(prog, kinematics=job.kinematics, tcp=tcp_of(job, detect(prog.text).name))
    used = feed_tools(tp)
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
