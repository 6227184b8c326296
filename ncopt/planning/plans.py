"""Operations -> plans: the cutter and cutting data of each planned operation, and the
S and F ncopt sets on the blocks it owns.

Operations are planned one after the other, in program order.  Each plan covers a
window of blocks: the operation's own (its cuts and the link moves of its run, see
:mod:`ncopt.planning.regions`), one block before it at the speed then commanded (so the spindle
starts from where it really is), and the first fixed block after it where the program's
own S must be back in force.  Blocks that a later operation owns are left to that one.

Feeds keep the CAM's intent (docs/method.md plans one cutting feed): only the blocks at the
operation's cutting feed follow the fz target; a plunge (at any feed), or a ramp,
lead-in or link at another feed, is scaled with the spindle (``F = F_prog * S_low / S_prog``:
its feed per tooth stays the programmed one and never rises).

The steps: :mod:`ncopt.planning.judging` decides which operations are planned, with
which cutter and cutting data; per tool, the contacts (:mod:`ncopt.contacts.locate`)
and the fit of the mesh (:mod:`ncopt.planning.meshfit`); per operation, its plan
(:mod:`ncopt.planning.opplan`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ncopt.model import Cutter, Method, Program, Toolpath
from ncopt.planning import regions, schedule
from ncopt.planning.intent import Intent
from ncopt.planning.judging import Judged, ToolChoice, judge, nothing_why, op_lines
from ncopt.planning.meshfit import MeshFit, check_fit, mesh_fit
from ncopt.planning.operations import CLEARING, ROUGH_LEVELS, STAMPED, Operation
from ncopt.planning.opplan import OpPlan, ToolView, plan_operation, tool_view
from ncopt.planning.regions import Scope
from ncopt.reading.stamp import Stamps, stamp_for
from ncopt.runtime.errors import NothingToPlan


@dataclass(frozen=True)
class Work:
    """Everything planned in one program.

    ops : every operation, in program order, with its final planned flag and reason
    plans : the planned operations' plans, in program order
    tools : T number -> its cutter, or why none;  views : (T number, contact method) ->
    what its contacts give the blocks (the planned tools)
    point_op : (n,) the planned operation of each toolpath point (-1: none)
    fits : T number -> how the mesh fits its cut (None without a mesh)
    """

    ops: tuple[Operation, ...]
    scope: Scope
    plans: list[OpPlan]
    tools: dict[int, ToolChoice]
    views: dict[tuple[int, Method], ToolView]
    point_op: np.ndarray
    fits: dict[int, MeshFit | None] | None = None


#: why an operation is left whose every cut keeps its S and F (opplan: F words too coarse)
KEPT_WHOLE = ("every cut's feed is too low for the resolution of the program's F words to "
              "hold fz within its band (write F with more decimals, or widen --fz-band)")


def plan_program(prog: Program, tp: Toolpath, idx: schedule.BlockIndex, job,
                 mesh_index) -> Work:
    """Operations, their scope and their plans; NothingToPlan where none is planned."""
    judged = judge(prog, tp, job)
    ops, choices, point_op = judged.ops, judged.tools, judged.point_op
    op_tool = np.array([o.tool for o in ops] or [-1], dtype=np.int64)
    scope = regions.scope(prog, tp, idx, point_op, ops)
    views, plans, fits = {}, [], {}
    cmd = tp.spindle_rpm[idx.first_point].astype(np.float64)
    for k, op in enumerate(ops):
        if not op.planned or not (scope.owner == k).any():
            continue
        method = _method(op, job, stamp_for(judged.stamps, op.tool, op_lines(judged.stamps, op)))
        key = (op.tool, method)
        if key not in views:
            sel = (point_op >= 0) & (op_tool[np.maximum(point_op, 0)] == op.tool)
            views[key] = tool_view(tp, idx, op.tool, choices[op.tool].cutter, sel, mesh_index,
                                   job.options, job.contact_tol_mm, method,
                                   job.machine.rapid_mm_min, job.stock_mm,
                                   _r_floor_mm(job, judged, op.tool, choices[op.tool].cutter))
            fits[op.tool] = mesh_fit(views[key].sampled, tp, sel, job.contact_tol_mm)
            check_fit(fits[op.tool], op.tool, job.contact_tol_mm, prog.path)
        cut, source = judged.cuts[k]
        lines = op_lines(judged.stamps, op)
        before = cmd.copy()
        plan = plan_operation(k, op, views[key], cut, source, tp, idx, point_op, scope, cmd,
                              job.machine, job.options, prog.path,
                              _intent(judged.stamps, op.tool, lines))
        kept = plan.coarse_lines is not None and plan.coarse_lines.size > 0
        if kept and not (plan.blocks.cutting & plan.blocks.planned).any():  # every cut kept
            cmd[:] = before
            ops[k] = replace(op, planned=False, reason=KEPT_WHOLE)
            continue
        plans.append(replace(plan, lines=lines, ap_mm=method.ap_mm
                             if method.name == "material" else float("nan")))
    if not plans:
        exc = NothingToPlan(nothing_why(ops, choices, tp), prog.path)
        exc.operations = tuple(ops)  # for reports: every operation and why it is left
        raise exc
    return Work(tuple(ops), scope, plans, choices, views, point_op, fits)


def _intent(stamps: Stamps, tool: int, lines: tuple[int, int]) -> Intent | None:
    """The :class:`~ncopt.planning.intent.Intent` of an operation an ncopt stamp records
    (the program is an ncopt output); None: read from the program."""
    stamp = stamp_for(stamps, tool, lines)
    return (Intent(stamp.s0_rpm, stamp.f0_mm_min, getattr(stamps, "spindle", None),
                   stamp.s0_varies) if stamp and stamp.f0_mm_min else None)


def _r_floor_mm(job, judged: Judged, tool: int, cutter: Cutter) -> float:
    """The smallest R_eff at which an operation of ``tool`` asks for less than S_max."""
    floors = [1000.0 * cut.vc_m_min
              / (2.0 * np.pi * schedule.speed_limits(job.machine, cut, cutter.teeth)[1])
              for k, (cut, _) in judged.cuts.items() if judged.ops[k].tool == tool]
    return min(floors, default=0.0)


def _method(op: Operation, job, stamp=None) -> Method:
    """The contact method of the job; a roughing operation a user includes is planned
    where the edge meets the remaining material, ap = its step-down along the axis (in
    an ncopt output, as its stamp says: its S and F words no longer show it roughing)."""
    if op.kind in (CLEARING, ROUGH_LEVELS) and np.isfinite(op.step_mm):
        return Method("material", float(op.step_mm), "axis")
    if op.kind == STAMPED and stamp is not None and np.isfinite(stamp.ap_mm):
        return Method("material", float(stamp.ap_mm), "axis")
    return job.method
