"""The library entry points: what the CLI calls, and what people import.

    >>> from ncopt.api import Job, rewrite_file
    >>> from ncopt.model import Cutter, Machine
    >>> job = Job(cutter=Cutter(16, 2), machine=Machine(accel_rad_s2=227, max_rpm=15000))
    >>> result = rewrite_file("samples/bowl.mpf", job, mesh_path="samples/bowl.stl")
    >>> round(result.summary.time_change_pct)
    -47
"""

from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from . import planner
from .contacts import Method, Sampled, contacts_for
from .controls import control_note
from .dialect import detect, resolve_decimal_point
from .errors import NothingToPlan, PlanningError, UsageError, VerificationError
from .feedmode import inverse_time_words
from .geometry import MeshIndex, load_stl
from .interp import interpret
from .model import Cutter, CuttingData, Machine, Motion, PlanOptions, Program, Toolpath
from .parse import parse_text
from .pathnormals import NO_CROSS, ONE_SIDED
from .stamp import as_stamped, read_stamps, stamp_edit
from .rewrite import F_CODE, S_CODE, Targets, apply_edits, detect_style, masked, plan_edits
from .tooltable import BALL, BULL, cutter_for, tool_table
from .tools import required_rpm

MM_PER_INCH = 25.4


@dataclass(frozen=True)
class Job:
    """Everything a rewrite needs besides the program and the mesh.

    cutter : None reads each tool from the program's tool comments
    cutting : None takes vc and fz from the program's own S and F
    tool : plan only this T number's moves
    teeth : used when the cutter comes from the program (only matters with cutting data given)
    """

    machine: Machine
    cutter: Cutter | None = None
    cutting: CuttingData | None = None
    options: PlanOptions = PlanOptions()
    tool: int | None = None
    control: str | None = None  # None: detected from the program's dialect
    control_from: str = "given"  # where a set control came from (the options, a profile)
    tool_library: dict = field(default_factory=dict)  # T number -> Cutter (profiles)
    teeth: int = 2
    method: Method = Method()  # contact point (default) or remaining material
    decimal_point: str | None = None  # Fanuc input convention: calculator, is-b, is-c
    kinematics: str | None = None  # 5-axis: how rotary angles tilt the tool (ncopt.kinematics)
    contact_tol_mm: float = 0.05
    verify: bool = True
    stamp: bool = True


@dataclass(frozen=True)
class ToolPlan:
    """One tool section's plan."""

    tool: int
    cutter: Cutter
    cutting: CuttingData
    source: str  # where the cutter came from: "options" or the comment's line
    blocks: planner.Blocks
    s_cmd_rpm: np.ndarray
    f_mm_min: np.ndarray
    sampled: Sampled
    close_s_words: int = 0
    over_target: tuple = (0, 0.0)  # (blocks, worst vc excess %) forced by the program's own S


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
    tools: tuple = ()  # (T, description, source) per planned tool
    skipped_tools: tuple = ()  # (T, why) per tool left untouched
    mesh_edge_mm: float | None = None
    warnings: tuple = ()
    normals_from: str = "mesh"
    stepover_mm: float | None = None
    one_sided_points: int = 0
    no_cross_points: int = 0
    close_s_words: int = 0
    control: str = ""
    control_source: str = ""
    control_notes: tuple = ()

    @property
    def time_change_pct(self) -> float:
        if self.cut_time_before_min <= 0:
            return 0.0
        return 100.0 * (self.cut_time_after_min / self.cut_time_before_min - 1.0)


@dataclass(frozen=True)
class Result:
    """The rewritten text and how it came about."""

    text: str
    summary: Summary
    program: Program
    toolpath: Toolpath
    block_index: planner.BlockIndex
    plans: tuple[ToolPlan, ...]
    targets: Targets

    @property
    def plan(self) -> ToolPlan:
        """The plan of a single-tool program."""
        return self.plans[0]


def rewrite_file(path: str | Path, job: Job, mesh_path: str | Path | None = None,
                 data: bytes | None = None) -> Result:
    """Read a program (or use ``data`` as its bytes) and rewrite it."""
    if data is None:
        data = Path(path).read_bytes()
    if mesh_path is None:
        return rewrite_text(data.decode("latin-1"), job, str(path))
    # The mesh loads in a thread while the program is parsed and interpreted (STL
    # reading and libigl's normals run largely outside the GIL, fcpw's BVH build
    # does not: 1M blocks and 1M triangles, 5.0 s one after the other, 4.2 s together).  No reference to the
    # future is kept here: rewrite_text drops the index (~700 MB at 1M triangles) as
    # soon as the contacts are found.
    pool = ThreadPoolExecutor(1, thread_name_prefix="ncopt-mesh")
    try:
        return rewrite_text(data.decode("latin-1"), job, str(path),
                            pool.submit(_mesh_index, mesh_path))
    finally:  # an error in the program is reported without waiting for the mesh
        pool.shutdown(wait=False, cancel_futures=True)


def _mesh_index(mesh_path: str | Path) -> MeshIndex:
    index = MeshIndex(load_stl(mesh_path))
    index.edge_lengths  # for the summary, while the main thread still parses
    return index


def _loaded(mesh_index: MeshIndex | Future | None) -> MeshIndex | None:
    """The mesh, once its loading thread is done (re-raises its MeshError)."""
    return mesh_index.result() if isinstance(mesh_index, Future) else mesh_index


def read_text(text: str, path: str, job: Job, detected: str | None = None) -> Program:
    """Parse a program as the job's control reads it.

    With a dialect named (``job.control``: the options or a machine profile),
    that dialect's grammar, which refuses other dialects' constructs; else the
    generic grammar.  Values are then read in the job's decimal-point
    convention: a Fanuc program (named or detected) with a value whose meaning
    depends on it and no convention given is refused at that word.
    ``detected``: the dialect :func:`ncopt.dialect.detect` finds (detected here if None).
    """
    prog = parse_text(text, path, dialect=job.control)
    control = job.control or detected or detect(text).name
    return resolve_decimal_point(prog, control, job.decimal_point)


def rewrite_text(text: str, job: Job, path: str = "<input>",
                 mesh_index: MeshIndex | Future | None = None) -> Result:
    """Rewrite a program's S and F words; every other byte stays as it is.

    ``mesh_index``: the part's mesh, or a ``concurrent.futures.Future`` of it
    (loading while the program is read); None: normals from the toolpath.
    """
    found = detect(text)
    prog = read_text(text, path, job, found.name)
    tp = interpret(prog, kinematics=job.kinematics)
    mesh_index = _loaded(mesh_index)
    idx = planner.block_index(tp.line)
    s_style = detect_style(prog, S_CODE)
    f_style = detect_style(prog, F_CODE, default_decimals=1)
    inch = tp.line_inch is not None and bool(tp.line_inch.any())
    if inch and f_style.decimals < 2:
        f_style = replace(f_style, decimals=2, trailing_point=False)  # inch/min needs them
    quantum = 10.0 ** -f_style.decimals * (MM_PER_INCH if inch else 1.0)
    quantum = max(quantum, _inverse_time_quantum(tp, idx, f_style))
    job = replace(job, options=replace(job.options, f_quantum_mm_min=quantum))
    stamps = read_stamps(prog)
    plans, skipped = _plan_tools(prog, tp, idx, job, mesh_index, stamps)
    mesh_edge = float(mesh_index.edge_lengths.median_mm) if mesh_index else None
    del mesh_index  # the largest object of a big job; verification needs memory too
    targets = _targets(tp, idx, plans, f_style)
    edits = plan_edits(prog, targets, s_style, f_style)
    stamp = stamp_edit(prog, plans) if job.stamp else None
    out = apply_edits(text, edits + ([stamp] if stamp else ()))
    counts = (len(edits), edits.s_words, edits.f_words)
    del edits  # ~800k strings at 1M blocks: not kept through the verification's peak
    if job.verify:
        verify(prog, tp, out, targets, s_style, f_style, job, found.name)
    summary = _summary(prog, tp, idx, plans, skipped, counts, mesh_edge)
    control = job.control or found.name
    source = job.control_from if job.control else (
        f"detected from {len(found.marks)} mark{'s' if len(found.marks) > 1 else ''}"
        if found.marks else "no marks: generic")
    summary = replace(summary, control=control, control_source=source,
                      control_notes=(control_note(control, summary.s_words),))
    return Result(out, summary, prog, tp, idx, tuple(plans), targets)


def _plan_tools(prog, tp, idx, job, mesh_index, stamps):
    """Plan every ball or bull-nose tool section with its own cutter."""
    feed = np.isin(tp.motion, [Motion.LINEAR, Motion.ARC_CW, Motion.ARC_CCW])
    plannable = feed & tp.known & tp.spindle_on
    tools = np.unique(tp.tool[plannable]).tolist()
    if job.tool is not None:
        if job.tool not in tools:
            raise UsageError(f"no feed moves with tool T{job.tool}; check --tool", prog.path)
        tools = [job.tool]
    if job.cutter is not None and len(tools) > 1:
        listed = ", ".join(f"T{t}" for t in tools)
        raise UsageError(f"the program cuts with several tools ({listed}); say which one "
                         "--diameter describes with --tool N", prog.path)
    table = tool_table(prog) if job.cutter is None else {}
    plans, skipped = [], []
    for tool in tools:
        stamp = stamps.get(tool)
        cutter, source, why = _cutter(job, table, tool, len(tools), tp.line_inch)
        if cutter is None and stamp is not None:
            cutter, source = stamp.cutter, f"the ncopt stamp on line {stamp.line + 1}"
        if cutter is None:
            skipped.append((tool, why))
            continue
        selected = plannable & (tp.tool == tool)
        if not cutter.is_ball and _tilted(tp, selected):
            skipped.append((tool, "a bull-nose with a tilted tool axis: ncopt plans 5-axis "
                            "moves with ball-end mills only"))
            continue
        tool_job = job
        if job.cutting is None and stamp is not None:  # an optimised program: its nominal data
            tool_job = replace(job, cutting=stamp.cutting)
        plans.append(_plan_tool(tp, idx, tool_job, mesh_index, tool, cutter, source, selected,
                                prog.path))
    if not plans:
        why = "; ".join(f"{_tool_name(t)}: {w}" for t, w in skipped) or "no feed moves with a " \
            "running spindle and a known position" + _first_left_alone(tp)
        raise NothingToPlan(f"nothing to plan ({why})", prog.path)
    return plans, skipped


def _tilted(tp: Toolpath, selected: np.ndarray) -> bool:
    """Some selected move's tool axis is not +Z."""
    return tp.tool_axis is not None and bool(np.any(tp.tool_axis[selected, :2]))


def _first_left_alone(tp: Toolpath) -> str:
    """The first located 'not planned' warning, to say why nothing could be planned."""
    first = next((w for w in tp.warnings if ": not planned (" in w), None)
    return f"; the first moves left alone: {first}" if first else ""


def _tool_name(tool: int) -> str:
    return f"T{tool}" if tool >= 0 else "the tool (the program names none)"


def _cutter(job, table, tool, n_tools, line_inch):
    """The cutter of T``tool``: from the options, else the program's tool comment."""
    if job.cutter is not None:
        return job.cutter, "options", ""
    if tool in job.tool_library:
        return job.tool_library[tool], "the tool profiles", ""
    info = cutter_for(table, tool, n_tools)
    if info is None:
        return None, "", "no diameter known from the program's comments: give --diameter " \
            "(and --corner-radius for a bull-nose)"
    if info.kind not in (BALL, BULL):
        kind = "a flat end mill" if info.kind == "flat" else "not a ball or bull-nose"
        return None, "", f"{kind} ({info.text.strip()}); ncopt plans ball and bull-nose " \
            "cutters only"
    inch = line_inch is not None and bool(np.any(line_inch))
    scale = MM_PER_INCH if inch else 1.0
    return info.cutter(job.teeth, scale), f"line {info.line}: ({info.text.strip()})", ""


def _plan_tool(tp, idx, job, mesh_index, tool, cutter, source, selected, path) -> ToolPlan:
    cut = job.cutting or as_stamped(nominal_cutting_data(tp, selected, cutter, path))
    sampled = contacts_for(tp, cutter, selected, mesh_index, job.options.sample_mm,
                           job.contact_tol_mm, job.method)
    c = sampled.contacts
    req = required_rpm(c.r_eff_mm, cut.vc_m_min)
    in_section = (tp.tool == tool)
    blocks = planner.blocks_from_contacts(
        idx, tp.seg_len_mm, tp.motion, tp.feed_mm_min, tp.known,
        tp.spindle_on & in_section, tp.spindle_rpm, req, c.cutting, sampled.point, selected,
        job.machine.rapid_mm_min)
    try:
        emitted, f_mm, _ = planner.plan(blocks, job.machine, cut, cutter.teeth, job.options)
    except PlanningError as exc:
        if exc.path is None:
            raise PlanningError(exc.message, path) from None
        raise
    return ToolPlan(tool, cutter, cut, source, blocks, emitted.s_cmd_rpm, f_mm, sampled,
                    emitted.close_s_words, _over_target(blocks, emitted, job, cut, cutter))


def _over_target(blocks, emitted, job, cut, cutter) -> tuple:
    """Cutting blocks where the real spindle stays above the requirement (after the
    program's own S in a block ncopt could not plan): (count, worst vc excess %)."""
    s_lo, s_hi = planner.speed_limits(job.machine, cut, cutter.teeth)
    req = np.clip(blocks.req_rpm, s_lo, s_hi)
    c = blocks.cutting & blocks.planned
    excess = emitted.s_high_rpm[c] / req[c] - 1.0
    bad = excess > 1e-3
    return (int(bad.sum()), float(100.0 * excess[bad].max()) if bad.any() else 0.0)


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


def _targets(tp, idx, plans, f_style) -> Targets:
    """S and F to be in force per block: planned where a tool was planned, else as programmed.

    A G93 block's F is 1 / minutes: the planned tip feed over its length
    (``ncopt.feedmode``).  A rotary-only block (no length) keeps its F."""
    fp = idx.first_point
    inch = tp.line_inch[idx.line] if tp.line_inch is not None else np.zeros(fp.shape, bool)
    unit = np.where(inch, MM_PER_INCH, 1.0)
    feed_move = tp.motion[fp] != Motion.RAPID
    s_value = tp.spindle_rpm[fp].astype(np.float64)
    f_value = np.where(feed_move, tp.feed_mm_min[fp] / unit, np.nan)
    s_value[~(s_value > 0)] = np.nan  # no S in force: nothing to restore (never write S0)
    scale = 10.0 ** f_style.decimals
    g93, length = _inverse_time_blocks(tp, idx)
    if g93 is not None:
        f_value = np.where(g93, inverse_time_words(tp.feed_mm_min[fp], length), f_value)
    for p in plans:
        s_value = np.where(p.blocks.planned, p.s_cmd_rpm, s_value)
        word = p.f_mm_min / unit
        if g93 is not None:
            word = np.where(g93, inverse_time_words(p.f_mm_min, length), word)
        planned_f = np.floor(word * scale + 1e-9) / scale  # never above fz
        f_value = np.where(p.blocks.cutting & (p.blocks.length_mm > 0), planned_f, f_value)
    f_value[~(f_value > 0)] = np.nan  # never F0 or below (controls reject it)
    return Targets(line=idx.line, s_value=s_value, f_value=f_value)


def _inverse_time_blocks(tp, idx):
    """(nb,) bool: the block is in G93, and (nb,) its length in mm; (None, None) if none is."""
    if tp.inverse_time is None:
        return None, None
    fp = idx.first_point
    return tp.inverse_time[fp], np.add.reduceat(tp.seg_len_mm[1:], fp - 1)


def _inverse_time_quantum(tp, idx, f_style) -> float:
    """The feed resolution (mm/min) of the G93 words: the word's own resolution times the
    longest G93 feed block (0 when there is none)."""
    g93, length = _inverse_time_blocks(tp, idx)
    if g93 is None or not np.any(g93 & tp.known[idx.first_point]):
        return 0.0
    return 10.0 ** -f_style.decimals * float(np.max(length[g93 & tp.known[idx.first_point]]))


def verify(prog: Program, tp: Toolpath, out: str, targets: Targets, s_style, f_style,
           job: Job, detected: str | None = None) -> None:
    """The checks run after every rewrite; raises VerificationError, writes nothing.

    One parse of the output (read as the input was) serves all three: the stamp
    lines are whole comment lines at the top, so masking keeps the line structure
    and every target line moves by the same count.  With S and F masked the output
    equals the input, so every geometry word is the input's own: the toolpath
    cannot have changed.
    """
    out_prog = read_text(out, prog.path, job, detected)
    in_stamps = sorted(st.line for st in read_stamps(prog).values())
    out_stamps = sorted(st.line for st in read_stamps(out_prog).values())
    same = _masked_without(out_prog, out_stamps) == _masked_without(prog, in_stamps)
    if not same:
        raise VerificationError("the rewrite changed more than S and F words; nothing written",
                                prog.path)
    shifted = replace(targets, line=targets.line + (len(out_stamps) - len(in_stamps)))
    again = plan_edits(out_prog, shifted, s_style, f_style)
    if again:
        line = int(np.searchsorted(out_prog.line_start, again[0].start, side="right"))
        raise VerificationError("rewriting the result again would change it; nothing written",
                                prog.path, line)


def _masked_without(prog: Program, drop: list) -> str:
    """The program with S/F words masked, without the given (stamp) lines.

    Masking keeps every line ending, so the program's own line numbers hold;
    the stamp lines are near the top, so only the head is split.
    """
    text = masked(prog)
    if not drop:
        return text
    head = text.split("\n", max(drop) + 1)
    rest = head.pop() if len(head) > max(drop) + 1 else ""
    return "".join(line + "\n" for i, line in enumerate(head) if i not in drop) + rest


def _summary(prog, tp, idx, plans, skipped, counts, mesh_edge) -> Summary:
    """``counts``: (edits, S words, F words) written."""
    fp = idx.first_point
    f_orig = tp.feed_mm_min[fp]
    before = after = 0.0
    cutting_blocks = planned_blocks = 0
    for p in plans:
        c = p.blocks.cutting
        before += float(np.sum(p.blocks.length_mm[c] / f_orig[c]))
        after += float(np.sum(p.blocks.length_mm[c] / np.maximum(p.f_mm_min[c], 1e-9)))
        cutting_blocks += int(c.sum())
        planned_blocks += int(p.blocks.planned.sum())
    n_edits, s_words, f_words = counts
    first = plans[0]
    summary = Summary(
        blocks=prog.n_lines, moving_blocks=int(fp.shape[0]), cutting_blocks=cutting_blocks,
        planned_blocks=planned_blocks, s_words=s_words, f_words=f_words, edits=n_edits,
        cut_time_before_min=before, cut_time_after_min=after, vc_m_min=first.cutting.vc_m_min,
        fz_mm=first.cutting.fz_mm, max_s_rpm=max(float(np.max(p.s_cmd_rpm[p.blocks.planned], initial=0.0)) for p in plans),
        tools=tuple((p.tool, _describe(p.cutter), p.source) for p in plans),
        skipped_tools=tuple(skipped),
        mesh_edge_mm=mesh_edge,
        warnings=tp.warnings + tuple(
            f"{prog.path}: T{p.tool}: vc up to {p.over_target[1]:.1f} % above its target on "
            f"{p.over_target[0]} cutting blocks, where the spindle is still falling from an S "
            "that ncopt could not plan (a block it left as programmed)"
            for p in plans if p.over_target[0]),
        close_s_words=sum(p.close_s_words for p in plans))
    est = first.sampled.estimate
    if est is not None:
        summary = replace(summary, normals_from="toolpath", stepover_mm=est.stepover_mm,
                          one_sided_points=int(np.sum(est.confidence == ONE_SIDED)),
                          no_cross_points=int(np.sum((est.confidence == NO_CROSS)
                                                     & first.sampled.contacts.cutting)))
    return summary


def _describe(cutter: Cutter) -> str:
    kind = "ball" if cutter.is_ball else f"bull-nose r{cutter.corner_radius_mm:g}"
    return f"D{cutter.diameter_mm:g} {kind}, {cutter.teeth} teeth"
