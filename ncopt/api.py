"""The library entry points: what the CLI calls, and what people import.

    >>> from ncopt.api import Job, rewrite_file
    >>> job = Job(cutter=Cutter(16, 2), machine=Machine(accel_rad_s2=227, max_rpm=15000))
    >>> result = rewrite_file("bowl.mpf", job, mesh_path="bowl.stl")
    >>> result.text, result.summary.cut_time_after_min
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from . import planner
from .errors import PlanningError, UsageError, VerificationError
from .geometry import MeshIndex, contacts_from_mesh, load_stl, mesh_resolution_mm
from .interp import interpret
from .model import Contacts, Cutter, CuttingData, Machine, Motion, PlanOptions, Program, Toolpath
from .parse import parse_text
from .pathnormals import NO_CROSS, ONE_SIDED, contacts_from_path
from .rewrite import F_CODE, S_CODE, Targets, apply_edits, detect_style, masked, plan_edits
from .tools import center_offset_mm, required_rpm

MM_PER_INCH = 25.4


@dataclass(frozen=True)
class Job:
    """Everything a rewrite needs besides the program and the mesh."""

    cutter: Cutter
    machine: Machine
    cutting: CuttingData | None = None  # None: from the program's own S and F
    options: PlanOptions = PlanOptions()
    tool: int | None = None  # plan only this T number's moves
    contact_tol_mm: float = 0.05
    verify: bool = True


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
    mesh_edge_mm: float | None = None
    warnings: tuple = ()
    normals_from: str = "mesh"
    stepover_mm: float | None = None
    one_sided_points: int = 0
    no_cross_points: int = 0

    @property
    def time_change_pct(self) -> float:
        if self.cut_time_before_min <= 0:
            return 0.0
        return 100.0 * (self.cut_time_after_min / self.cut_time_before_min - 1.0)


@dataclass(frozen=True)
class Result:
    """The rewritten text and how it came about (arrays per moving block)."""

    text: str
    summary: Summary
    program: Program
    toolpath: Toolpath
    blocks: planner.Blocks
    block_line: np.ndarray
    s_cmd_rpm: np.ndarray
    f_mm_min: np.ndarray
    extras: dict = field(default_factory=dict)


def rewrite_file(path: str | Path, job: Job, mesh_path: str | Path | None = None,
                 data: bytes | None = None) -> Result:
    """Read a program (or use ``data`` as its bytes) and rewrite it."""
    if data is None:
        data = Path(path).read_bytes()
    mesh_index = MeshIndex(load_stl(mesh_path)) if mesh_path else None
    return rewrite_text(data.decode("latin-1"), job, str(path), mesh_index)


def rewrite_text(text: str, job: Job, path: str = "<input>",
                 mesh_index: MeshIndex | None = None) -> Result:
    """Rewrite a program's S and F words; every other byte stays as it is."""
    prog = parse_text(text, path)
    tp = interpret(prog)
    selected = _selected_moves(tp, job, path)
    cut = job.cutting or nominal_cutting_data(tp, selected, job.cutter, path)
    if mesh_index is not None:
        contacts, sample_point = _contacts(tp, job, mesh_index)
        estimate = None
    else:
        contacts, sample_point, estimate = _contacts_without_mesh(tp, job, selected)
    blocks, block_line, first_point = build_blocks(tp, contacts, sample_point, selected, cut,
                                                   job)
    s_cmd, f_mm = plan_blocks(blocks, job, cut)
    s_style = detect_style(prog, S_CODE)
    f_style = detect_style(prog, F_CODE, default_decimals=1)
    if tp.line_inch is not None and tp.line_inch.any() and f_style.decimals < 2:
        f_style = replace(f_style, decimals=2, trailing_point=False)  # inch/min needs them
    targets = _targets(prog, tp, blocks, block_line, first_point, s_cmd, f_mm, f_style)
    edits = plan_edits(prog, targets, s_style, f_style)
    out = apply_edits(text, edits)
    if job.verify:
        verify(prog, tp, out, targets, s_style, f_style)
    summary = _summary(prog, tp, blocks, block_line, first_point, s_cmd, f_mm, cut, edits,
                       mesh_index, targets)
    if estimate is not None:
        summary = replace(summary, normals_from="toolpath", stepover_mm=estimate.stepover_mm,
                          one_sided_points=int(np.sum(estimate.confidence == ONE_SIDED)),
                          no_cross_points=int(np.sum((estimate.confidence == NO_CROSS)
                                                     & contacts.cutting)))
    return Result(out, summary, prog, tp, blocks, block_line, s_cmd, f_mm,
                  {"contacts": contacts, "sample_point": sample_point, "cutting": cut})


def _selected_moves(tp: Toolpath, job: Job, path: str) -> np.ndarray:
    """(n,) bool: feed moves ncopt may plan (known position, chosen tool, spindle on)."""
    feed = np.isin(tp.motion, [Motion.LINEAR, Motion.ARC_CW, Motion.ARC_CCW])
    ok = feed & tp.known & tp.spindle_on
    tools = np.unique(tp.tool[ok])
    if job.tool is None and tools.size > 1:
        listed = ", ".join(f"T{t}" for t in tools.tolist())
        raise UsageError(f"the program cuts with several tools ({listed}); choose the ball or "
                         "bull-nose to plan with --tool N", path)
    if job.tool is not None:
        ok &= tp.tool == job.tool
        if not ok.any():
            raise UsageError(f"no feed moves with tool T{job.tool}; check --tool", path)
    return ok


def nominal_cutting_data(tp: Toolpath, selected: np.ndarray, cutter: Cutter,
                         path: str) -> CuttingData:
    """vc and fz the program itself runs at its nominal diameter (what the CAM intended).

    S and F are the length-weighted medians over the feed moves ncopt plans, so a
    plunge or lead-in feed does not set the target of the whole finish.
    """
    idx = np.flatnonzero(selected & (tp.spindle_rpm > 0) & (tp.feed_mm_min > 0))
    if idx.size == 0:
        raise PlanningError("the program gives no spindle speed or feed for its cuts; "
                            "give --vc and --fz", path)
    weight = tp.seg_len_mm[idx]
    s = _weighted_median(tp.spindle_rpm[idx], weight)
    f = _weighted_median(tp.feed_mm_min[idx], weight)
    vc = np.pi * cutter.diameter_mm * s / 1000.0
    return CuttingData(vc_m_min=vc, fz_mm=f / (cutter.teeth * s))


def _weighted_median(values: np.ndarray, weight: np.ndarray) -> float:
    order = np.argsort(values, kind="stable")
    cum = np.cumsum(weight[order])
    if cum[-1] <= 0:
        return float(values[order][len(values) // 2])
    return float(values[order][np.searchsorted(cum, 0.5 * cum[-1])])


def sample_points(tp: Toolpath, sample_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """Points along every move, at most ``sample_mm`` apart, ending on each CL point.

    Returns xyz (m, 3) in mm and, per sample, the index of the toolpath point
    whose move it lies on (point 0 for the start point).
    """
    seg = np.linalg.norm(np.diff(tp.xyz_mm, axis=0), axis=1)
    n_per = np.maximum(np.ceil(seg / sample_mm).astype(np.int64), 1)
    point = np.concatenate(([0], np.repeat(np.arange(1, tp.n), n_per)))
    offsets = np.concatenate(([0], np.cumsum(n_per)))
    k = np.arange(1, offsets[-1] + 1) - np.repeat(offsets[:-1], n_per)
    frac = k / np.repeat(n_per, n_per)
    a = tp.xyz_mm[point[1:] - 1]
    b = tp.xyz_mm[point[1:]]
    xyz = np.vstack((tp.xyz_mm[:1], a + (b - a) * frac[:, None]))
    return xyz, point


def _contacts(tp: Toolpath, job: Job, mesh_index: MeshIndex) -> tuple[Contacts, np.ndarray]:
    xyz, point = sample_points(tp, job.options.sample_mm)
    centers = xyz + np.array([0.0, 0.0, center_offset_mm(job.cutter)])
    return contacts_from_mesh(centers, mesh_index, job.cutter, tol_mm=job.contact_tol_mm), point


def air_moves(tp: Toolpath) -> np.ndarray:
    """(n,) bool: feed moves that cannot be cutting without a mesh to say otherwise:
    plunges and retracts (nearly vertical), and moves at or above the lowest rapid
    height that follows a retract (the clearance plane)."""
    d = np.diff(tp.xyz_mm, axis=0)
    length = np.linalg.norm(d, axis=1)
    steep = np.concatenate(([False], np.abs(d[:, 2]) > 0.98 * np.maximum(length, 1e-12)))
    rapid_z = tp.xyz_mm[tp.motion == Motion.RAPID, 2]
    clear = np.zeros(tp.n, dtype=bool)
    if rapid_z.size:
        clear = tp.xyz_mm[:, 2] >= np.min(rapid_z) - 1e-6
    start_z = np.concatenate(([np.inf], tp.xyz_mm[:-1, 2]))
    return steep | (clear & (start_z >= np.min(rapid_z) - 1e-6 if rapid_z.size else clear))


def _contacts_without_mesh(tp: Toolpath, job: Job, selected: np.ndarray):
    """Contacts at the CL points from the toolpath's own shape (no interior samples:
    normals between two points are their interpolation)."""
    centers = tp.xyz_mm + np.array([0.0, 0.0, center_offset_mm(job.cutter)])
    path = np.cumsum(tp.seg_len_mm)
    cutting = selected & ~air_moves(tp)
    contacts, estimate = contacts_from_path(centers, path, cutting, job.cutter)
    return contacts, np.arange(tp.n), estimate


def build_blocks(tp: Toolpath, contacts: Contacts, sample_point: np.ndarray,
                 selected: np.ndarray, cut: CuttingData, job: Job):
    """Per moving block: length, lowest required S, cutting, duration."""
    req = np.where(contacts.cutting, required_rpm(contacts.r_eff_mm, cut.vc_m_min), np.inf)
    n = tp.n
    seg_min = np.full(n, np.inf)
    np.minimum.at(seg_min, sample_point, req)
    cut_pt = np.zeros(n, dtype=bool)
    np.logical_or.at(cut_pt, sample_point, contacts.cutting)
    end_req = np.full(n, np.inf)
    last_sample = np.concatenate((np.flatnonzero(np.diff(sample_point)), [sample_point.size - 1]))
    end_req[sample_point[last_sample]] = req[last_sample]
    point_req = np.minimum(seg_min, np.concatenate(([np.inf], end_req[:-1])))
    starts = np.flatnonzero(np.diff(tp.line[1:]) != 0) + 2 if n > 1 else np.zeros(0, int)
    first_point = np.concatenate(([1], starts)) if n > 1 else np.zeros(0, int)
    block_line = tp.line[first_point]
    length = np.add.reduceat(tp.seg_len_mm[1:], first_point - 1) if n > 1 else np.zeros(0)
    block_req = np.minimum.reduceat(point_req[1:], first_point - 1) if n > 1 else np.zeros(0)
    block_cut = np.logical_or.reduceat(cut_pt[1:], first_point - 1) if n > 1 else np.zeros(0, bool)
    planned = selected[first_point]
    cutting = block_cut & planned  # an infinite requirement (tip contact) is capped at S_max
    motion = tp.motion[first_point]
    speed = np.where(motion == Motion.RAPID, job.machine.rapid_mm_min,
                     np.nan_to_num(tp.feed_mm_min[first_point], nan=job.machine.rapid_mm_min))
    time_s = 60.0 * length / np.maximum(speed, 1e-9)
    # rapids and air moves are free for the spindle to ramp; a rapid needs no known start
    rapid = motion == Motion.RAPID
    free = ~selected[first_point] & tp.spindle_on[first_point] & (rapid | tp.known[first_point])
    planned = planned | free
    fixed = tp.spindle_rpm[first_point]
    blocks = planner.Blocks(length_mm=length, req_rpm=block_req, cutting=cutting,
                            planned=planned, time_s=time_s, fixed_rpm=fixed)
    return blocks, block_line, first_point


def plan_blocks(blocks: planner.Blocks, job: Job, cut: CuttingData):
    """Profile -> integer S commands -> F (mm/min) per block."""
    teeth = job.cutter.teeth
    plan = planner.lookahead if job.options.planner == "lookahead" else planner.forward
    if job.options.planner not in ("lookahead", "forward"):
        raise UsageError(f"unknown planner {job.options.planner!r}; use lookahead or forward")
    profile = plan(blocks, job.machine, cut, teeth, job.options)
    incs = planner.increments(blocks, job.machine, profile.k_rpm2_per_mm)
    s_lo, _ = planner.speed_limits(job.machine, cut, teeth)
    s_cmd, s_low = planner.emit_rpm(profile, blocks, incs, job.options, s_lo)
    f_mm = planner.feeds(s_low, blocks, cut, teeth, job.machine.max_feed_mm_min)
    return s_cmd, f_mm


def _targets(prog, tp, blocks, block_line, first_point, s_cmd, f_mm, f_style) -> Targets:
    inch = tp.line_inch[block_line] if tp.line_inch is not None else np.zeros(len(block_line), bool)
    unit = np.where(inch, MM_PER_INCH, 1.0)
    s_value = np.where(blocks.planned, s_cmd, tp.spindle_rpm[first_point])
    feed_move = tp.motion[first_point] != Motion.RAPID
    original_f = tp.feed_mm_min[first_point] / unit
    scale = 10.0 ** f_style.decimals
    planned_f = np.floor(f_mm / unit * scale + 1e-9) / scale  # never above the fz target
    f_value = np.where(blocks.cutting, planned_f, np.where(feed_move, original_f, np.nan))
    return Targets(line=block_line, s_value=s_value, f_value=f_value)


def verify(prog: Program, tp: Toolpath, out: str, targets: Targets, s_style, f_style) -> None:
    """The checks run after every rewrite; raises VerificationError, writes nothing."""
    out_prog = parse_text(out, prog.path)
    if masked(out_prog) != masked(prog):
        raise VerificationError("the rewrite changed more than S and F words; nothing written",
                                prog.path)
    out_tp = interpret(out_prog)
    if out_tp.n != tp.n or not np.array_equal(out_tp.xyz_mm, tp.xyz_mm):
        raise VerificationError("the rewrite changed the toolpath; nothing written", prog.path)
    again = plan_edits(out_prog, targets, s_style, f_style)
    if again:
        line = int(np.searchsorted(out_prog.line_start, again[0].start, side="right"))
        raise VerificationError("rewriting the result again would change it; nothing written",
                                prog.path, line)


def _summary(prog, tp, blocks, block_line, first_point, s_cmd, f_mm, cut, edits, mesh_index,
             targets) -> Summary:
    cutting = blocks.cutting
    f_orig = tp.feed_mm_min[first_point]
    before = float(np.sum(blocks.length_mm[cutting] / f_orig[cutting]))
    after = float(np.sum(blocks.length_mm[cutting] / f_mm[cutting]))
    edge = float(mesh_resolution_mm(mesh_index.mesh).median_mm) if mesh_index is not None else None
    s_words = sum(1 for e in edits if prog.text[e.start - 1:e.start] in "Ss" and e.start != e.end
                  or "S" in e.text.upper() and e.start == e.end)
    f_words = sum(1 for e in edits if prog.text[e.start - 1:e.start] in "Ff" and e.start != e.end
                  or "F" in e.text.upper() and e.start == e.end)
    return Summary(blocks=prog.n_lines, moving_blocks=int(blocks.length_mm.shape[0]),
                   cutting_blocks=int(cutting.sum()), planned_blocks=int(blocks.planned.sum()),
                   s_words=s_words, f_words=f_words, edits=len(edits),
                   cut_time_before_min=before, cut_time_after_min=after,
                   vc_m_min=cut.vc_m_min, fz_mm=cut.fz_mm,
                   max_s_rpm=float(np.max(s_cmd)) if s_cmd.size else 0.0,
                   mesh_edge_mm=edge, warnings=tp.warnings)
