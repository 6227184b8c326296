"""The summary of a rewrite, in the numbers a machinist checks, and the stamp's header.

Times are the estimate of :mod:`ncopt.motion.times` for every move before and after the
rewrite (:func:`ncopt.writing.targets.cut_minutes`), the same for the summary and the
stamp."""

from __future__ import annotations

import datetime
import os
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from ncopt.contacts.pathnormals import NO_CROSS, ONE_SIDED
from ncopt.model import Cutter, Job, Program, Toolpath
from ncopt.motion.times import untimed_moves
from ncopt.planning.meshfit import MeshFit
from ncopt.planning.operations import Operation
from ncopt.planning.plans import Work
from ncopt.planning.schedule import BlockIndex
from ncopt.reading.controls import ANYWHERE, control_note
from ncopt.reading.dialect import Detected
from ncopt.reading.stamp import StampInfo
from ncopt.writing.warnings import plan_warnings, unknown_share


@dataclass(frozen=True)
class OpRow:
    """One operation in the summary: what it is, whether ncopt planned it and why,
    and its cutting time before -> after (min) and S range after (RPM)."""

    name: str
    tool: int
    lines: str
    kind: str
    planned: bool
    reason: str
    time_before_min: float
    time_after_min: float
    s_min_rpm: float
    s_max_rpm: float


@dataclass(frozen=True)
class Summary:
    """What a rewrite did, in numbers a machinist checks."""

    blocks: int
    moving_blocks: int
    cutting_blocks: int
    planned_blocks: int
    s_words: int
    f_words: int
    edits: int
    cut_time_before_min: float
    cut_time_after_min: float
    vc_m_min: float
    fz_mm: float
    max_s_rpm: float
    tools: tuple[tuple[int, str, str], ...] = ()  # (T, description, source) per planned tool
    skipped_tools: tuple[tuple[int, str], ...] = ()  # (T, why) per tool left untouched
    mesh_edge_mm: float | None = None
    warnings: tuple[str, ...] = ()
    normals_from: str = "mesh"
    stepover_mm: float | None = None
    one_sided_points: int = 0
    no_cross_points: int = 0
    # the share of the planned cut (by length) whose contact is not known (without a mesh,
    # or where the mesh has no part), planned at the cutter's full radius (ncopt.contacts.locate)
    unknown_contact_pct: float = 0.0
    # 1-based lines of the cutting blocks where the spindle, ramping at its acceleration,
    # cannot follow the S words written (fz leaves its band): the check simulate makes
    lag_lines: tuple[int, ...] = ()
    close_s_words: int = 0
    control: str = ""
    control_source: str = ""
    control_notes: tuple[str, ...] = ()
    operations: tuple[OpRow, ...] = ()  # in program order
    planned_time_before_min: float = 0.0  # the planned operations only
    planned_time_after_min: float = 0.0
    untimed_moves: int = 0  # feed moves the cutting time leaves out
    units: str = "mm"
    mesh_fit: tuple[tuple[int, MeshFit], ...] = ()  # per planned tool, with a mesh
    s_changes: str = ANYWHERE  # where S may change: anywhere, or between passes only
    s_changes_source: str = ""  # "given", or the control whose default it is
    passes: int = 0
    cut_time_other_min: float = float("nan")  # the whole program with the other s_changes

    def to_dict(self) -> dict:
        """The summary as plain JSON values (rewrite --json, batch reports)."""
        out = asdict(self)
        out["time_change_pct"] = self.time_change_pct
        out["mesh_fit"] = [dict(tool=t, **asdict(f)) for t, f in self.mesh_fit]
        out["tools"] = [dict(tool=t, cutter=c, source=src) for t, c, src in self.tools]
        out["skipped_tools"] = [dict(tool=t, why=w) for t, w in self.skipped_tools]
        return _finite(out)

    @property
    def time_change_pct(self) -> float:
        if self.cut_time_before_min <= 0:
            return 0.0
        return 100.0 * (self.cut_time_after_min / self.cut_time_before_min - 1.0)


def summarise(prog: Program, tp: Toolpath, idx: BlockIndex, work: Work,
              counts: tuple[int, int, int], mesh_edge: float | None, job: Job,
              minutes: tuple[np.ndarray, np.ndarray]) -> Summary:
    """What the rewrite did.  ``counts``: (edits, S words, F words) written;
    ``mesh_edge``: the mesh's median edge, mm (None: no mesh); ``minutes``: each move's
    before and after (:func:`ncopt.writing.targets.cut_minutes`)."""
    t_before, t_after = minutes
    rows = tuple(op_row(o, k, tp, work, t_before, t_after) for k, o in enumerate(work.ops))
    plans = work.plans
    n_edits, s_words, f_words = counts
    first = plans[0]
    tools, seen = [], set()
    for p in plans:
        if p.tool not in seen:
            seen.add(p.tool)
            tools.append((p.tool, describe_cutter(p.cutter), work.tools[p.tool].source))
    skipped = tuple((t, c.why) for t, c in work.tools.items() if c.cutter is None)
    planned_pts = work.point_op >= 0
    summary = Summary(
        blocks=prog.n_lines, moving_blocks=int(idx.first_point.shape[0]),
        cutting_blocks=sum(int((p.blocks.cutting & p.blocks.planned).sum()) for p in plans),
        planned_blocks=sum(int(p.blocks.planned.sum()) for p in plans),
        s_words=s_words, f_words=f_words, edits=n_edits,
        cut_time_before_min=float(t_before.sum()), cut_time_after_min=float(t_after.sum()),
        vc_m_min=first.cutting.vc_m_min, fz_mm=first.cutting.fz_mm,
        max_s_rpm=max(float(np.max(p.s_cmd_rpm[p.blocks.planned], initial=0.0)) for p in plans),
        tools=tuple(tools), skipped_tools=skipped, mesh_edge_mm=mesh_edge,
        warnings=tp.warnings + plan_warnings(prog, tp, idx, work, job),
        close_s_words=sum(p.close_s_words for p in plans), operations=rows,
        planned_time_before_min=float(t_before[planned_pts].sum()),
        planned_time_after_min=float(t_after[planned_pts].sum()),
        untimed_moves=untimed_moves(tp),
        units="inch" if tp.line_inch is not None and tp.line_inch.any() else "mm",
        mesh_fit=tuple((t, f) for t, f in (work.fits or {}).items() if f is not None),
        passes=sum(p.passes for p in plans),
        cut_time_other_min=float(t_after.sum()) + sum(
            p.other_time_min - p.cut_time_min for p in plans))
    sampled = next(iter(work.views.values())).sampled
    est = sampled.estimate
    if est is not None:
        summary = replace(summary, normals_from="toolpath", stepover_mm=est.stepover_mm,
                          one_sided_points=int(np.sum(est.confidence == ONE_SIDED)),
                          no_cross_points=int(np.sum((est.confidence == NO_CROSS)
                                                     & sampled.contacts.cutting)),
                          unknown_contact_pct=unknown_share(tp, work, planned_pts)[0])
    return summary


def op_row(op: Operation, k: int, tp: Toolpath, work: Work, t_before: np.ndarray,
           t_after: np.ndarray) -> OpRow:
    """Operation ``k``'s row: its times before and after (``t_before``, ``t_after``: min
    per move) and the S range of its plan."""
    a, b = np.searchsorted(tp.line[1:], [op.first_line, op.last_line + 1]) + 1
    s_lo = s_hi = float("nan")
    for p in work.plans:
        if p.op == k:
            s = p.s_cmd_rpm[p.blocks.planned]
            if s.size:
                s_lo, s_hi = float(s.min()), float(s.max())
    return OpRow(op.name, op.tool, f"{op.first_line + 1}-{op.last_line + 1}", op.kind,
                 op.planned, op.reason, float(t_before[a:b].sum()), float(t_after[a:b].sum()),
                 s_lo, s_hi)


def with_control(summary: Summary, job: Job, found: Detected, mode_given: bool) -> Summary:
    """The summary with the control it was written for and where S may change: ``job``'s
    control, or the one ``found`` in the program (the marks that say so); ``job``'s
    s_changes, given (``mode_given``) or that control's default."""
    control = job.control or found.name
    mode = job.options.s_changes
    source = job.control_from if job.control else (
        f"detected from {len(found.marks)} mark{'s' if len(found.marks) > 1 else ''}"
        if found.marks else "no marks: generic")
    return replace(summary, control=control, control_source=source,
                   control_notes=(control_note(control, summary.s_words, mode),),
                   s_changes=mode,
                   s_changes_source="given" if mode_given else f"the default for {control}")


def stamp_info(path: str, job: Job, minutes: tuple[np.ndarray, np.ndarray]) -> StampInfo:
    """The stamp's header: today (or SOURCE_DATE_EPOCH's day, for reproducible outputs),
    the program's file name, the machine, and the whole program's estimated cutting time
    before and after (``minutes``: :func:`ncopt.writing.targets.cut_minutes`, as the summary
    gives it)."""
    epoch = os.environ.get("SOURCE_DATE_EPOCH", "")
    day = (datetime.datetime.fromtimestamp(int(epoch), datetime.timezone.utc).date()
           if epoch.isdigit() else datetime.date.today())
    m = job.machine
    spindle = f"{m.accel_rad_s2:g} rad/s2, {m.max_rpm:g} RPM"
    machine = f"{job.machine_name}: {spindle}" if job.machine_name else spindle
    before, after = (float(t.sum()) for t in minutes)
    source = "stdin" if path in ("-", "<stdin>", "<input>") else Path(path).name
    return StampInfo(day.isoformat(), source, machine, before, after)


def describe_cutter(cutter: Cutter) -> str:
    """``D16 ball, 2 teeth``, ``D6 bull-nose r1, 4 teeth``: a planned tool in the summary."""
    kind = "ball" if cutter.is_ball else f"bull-nose r{cutter.corner_radius_mm:g}"
    return f"D{cutter.diameter_mm:g} {kind}, {cutter.teeth} teeth"


def _finite(value):
    """NaN and infinities as None: JSON has neither."""
    if isinstance(value, float):
        return value if np.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    return value
