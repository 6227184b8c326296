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
from typing import Callable

import numpy as np

from ncopt.contacts import kdtree
from ncopt.planning import schedule
from ncopt.planning import plans as _plans
from ncopt.contacts.locate import below_top_mm
from ncopt.model import Job, Method
from ncopt.reading.read import read_text
from ncopt.reading.controls import ANYWHERE, control_note, default_s_changes
from ncopt.reading.dialect import detect, resolve_decimal_point
from ncopt.runtime.errors import VerificationError
from ncopt.motion.feedmode import inverse_time_words
from ncopt.contacts.geometry import MeshIndex, load_stl
from ncopt.motion.interp import interpret, tcp_for, tcp_of
from ncopt.motion.modal import ffill
from ncopt.runtime.memory import release_freed_memory, small_pages, working_memory
from ncopt.model import MM_PER_INCH, Cutter, CuttingData, Machine, Motion, PlanOptions, Program, Toolpath
from ncopt.reading.parse import parse_text
from ncopt.contacts.pathnormals import NO_CROSS, ONE_SIDED
from ncopt.planning.plans import OpPlan, Work, plan_program
from ncopt.planning.regions import Scope
from ncopt.writing.edits import F_CODE, S_CODE, Targets, apply_edits, detect_style, masked, plan_edits
from ncopt.reading.stamp import StampInfo, read_stamps, stamp_edit
from ncopt.motion.times import feed_minutes, untimed_moves



ToolPlan = OpPlan  # the plan of one operation (one tool in ncopt 0.1)


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
    tools: tuple = ()  # (T, description, source) per planned tool
    skipped_tools: tuple = ()  # (T, why) per tool left untouched
    mesh_edge_mm: float | None = None
    warnings: tuple = ()
    normals_from: str = "mesh"
    stepover_mm: float | None = None
    one_sided_points: int = 0
    no_cross_points: int = 0
    # the share of the planned cut (by length) whose contact is not known (without a mesh,
    # or where the mesh has no part), planned at the cutter's full radius (ncopt.contacts.locate)
    unknown_contact_pct: float = 0.0
    # 1-based lines of the cutting blocks where the spindle, ramping at its acceleration,
    # cannot follow the S words written (fz leaves its band): the check simulate makes
    lag_lines: tuple = ()
    close_s_words: int = 0
    control: str = ""
    control_source: str = ""
    control_notes: tuple = ()
    operations: tuple = ()  # OpRow per operation, in program order
    planned_time_before_min: float = 0.0  # the planned operations only
    planned_time_after_min: float = 0.0
    untimed_moves: int = 0  # feed moves the cutting time leaves out
    units: str = "mm"
    mesh_fit: tuple = ()  # (T, MeshFit) per planned tool, with a mesh
    s_changes: str = ANYWHERE  # where S may change: anywhere, or between passes only
    s_changes_source: str = ""  # "given", or the control whose default it is
    passes: int = 0
    cut_time_other_min: float = float("nan")  # the whole program with the other s_changes

    def to_dict(self) -> dict:
        """The summary as plain JSON values (rewrite --json, batch reports)."""
        from dataclasses import asdict

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


@dataclass(frozen=True)
class Result:
    """The rewritten text and how it came about."""

    text: str
    summary: Summary
    program: Program
    toolpath: Toolpath
    block_index: schedule.BlockIndex
    plans: tuple[OpPlan, ...]
    targets: Targets
    operations: tuple = ()
    scope: Scope | None = None

    @property
    def plan(self) -> ToolPlan:
        """The plan of a single-tool program."""
        return self.plans[0]


def rewrite_file(path: str | Path, job: Job, mesh_path: str | Path | None = None,
                 data: bytes | None = None,
                 progress: Callable[[str], None] | None = None) -> Result:
    """Read a program (or use ``data`` as its bytes) and rewrite it.

    ``progress``: called with the name of each stage as it starts (``"planning"``)."""
    text = (Path(path).read_bytes() if data is None else data).decode("latin-1")
    del data  # the file's bytes are not kept through the rewrite (the text is)
    if mesh_path is None:
        return rewrite_text(text, job, str(path), progress=progress)
    # The mesh loads in a thread while the program is parsed and interpreted (STL
    # reading and libigl's normals run largely outside the GIL, fcpw's BVH build
    # does not: 1M blocks and 1M triangles, 5.0 s one after the other, 4.2 s together).
    # No reference to the future is kept here: rewrite_text drops the index (~700 MB at
    # 1M triangles) as soon as the contacts are found.
    pool = ThreadPoolExecutor(1, thread_name_prefix="ncopt-mesh")
    try:
        with small_pages():  # from the mesh's first array on (ncopt.runtime.memory)
            return rewrite_text(text, job, str(path), pool.submit(_mesh_index, mesh_path),
                                progress=progress)
    finally:  # an error in the program is reported without waiting for the mesh
        pool.shutdown(wait=False, cancel_futures=True)


def _mesh_index(mesh_path: str | Path) -> MeshIndex:
    index = MeshIndex(load_stl(mesh_path))
    index.edge_lengths  # for the summary, while the main thread still parses
    # scipy.spatial (the operations' k-d trees) here or in the main thread once it waits
    # for the mesh (rewrite_text), whichever comes first; not in a third thread beside the
    # parse and the mesh: an import holds the GIL, and with three busy threads on two
    # cores the one that holds it is often the one waiting for a core
    kdtree.load()
    return index


def _loaded(mesh_index: MeshIndex | Future | None) -> MeshIndex | None:
    """The mesh, once its loading thread is done (re-raises its MeshError)."""
    return mesh_index.result() if isinstance(mesh_index, Future) else mesh_index


def rewrite_text(text: str, job: Job, path: str = "<input>",
                 mesh_index: MeshIndex | Future | None = None,
                 progress: Callable[[str], None] | None = None) -> Result:
    """Rewrite a program's S and F words; every other byte stays as it is.

    ``mesh_index``: the part's mesh, or a ``concurrent.futures.Future`` of it
    (loading while the program is read); None: normals from the toolpath.
    ``progress``: called with the name of each stage as it starts.
    Raises NothingToPlan (exit 5) when no operation of the program can be planned.
    """
    # numpy's arrays on small pages throughout (ncopt.runtime.memory.small_pages).
    with small_pages():
        # Up to the verification, freed memory stays for the next stage (ncopt.runtime.memory); the
        # verification, the peak of a rewrite, hands its temporaries back between its steps.
        # The stages are inside the block, not in a call: a caller's frame would keep the
        # mesh's future, and so the mesh, alive.
        with working_memory():
            if not isinstance(mesh_index, Future):  # else the mesh's thread imports it
                kdtree.prefetch()  # scipy.spatial loads while the program is parsed
            show = progress or (lambda stage: None)
            show(f"reading {path}")
            found = detect(text)
            prog = read_text(text, path, job, found.name)
            show("following the toolpath")
            tp = interpret(prog, kinematics=job.kinematics, tcp=tcp_of(job, found.name))
            if isinstance(mesh_index, Future) and not mesh_index.done():
                show("reading the mesh")
                kdtree.load()  # while the mesh's thread finishes (a short program)
            mesh_index = _loaded(mesh_index)
            idx = schedule.block_index(tp.line)
            s_style = detect_style(prog, S_CODE)
            f_style = detect_style(prog, F_CODE, default_decimals=1)
            inch = tp.line_inch is not None and bool(tp.line_inch.any())
            if inch and f_style.decimals < 2:
                f_style = replace(f_style, decimals=2, trailing_point=False)  # inch/min needs them
            quantum = 10.0 ** -f_style.decimals * (MM_PER_INCH if inch else 1.0)
            quantum = max(quantum, _inverse_time_quantum(tp, idx, f_style))
            mode_given = job.options.s_changes is not None
            control = job.control or found.name
            mode = job.options.s_changes or default_s_changes(control)
            job = replace(job, options=replace(job.options, f_quantum_mm_min=quantum,
                                               s_changes=mode))
            show("finding the contacts and planning S and F")
            work = plan_program(prog, tp, idx, job, mesh_index)
            mesh_edge = float(mesh_index.edge_lengths.median_mm) if mesh_index else None
            del mesh_index  # the largest object of a big job; verification needs memory too
            if mesh_edge is not None:  # it was built in its own thread's arena: hand that back
                release_freed_memory(force=True)
            show("writing the new S and F words")
            targets = _targets(prog, tp, idx, work, f_style)
            consumers = _with_fixed_lines(tp, idx, work.scope, targets)
            with ThreadPoolExecutor(1, thread_name_prefix="ncopt-checks") as pool:
                # numpy work that needs no edit, beside the edits and the splice (Python loops):
                # the lag check, and the input's side of the verification's comparison
                lag = pool.submit(_lag_warnings, prog, tp, idx, work, targets, job)
                masked_input = pool.submit(_masked_input, prog) if job.verify else None
                edits = plan_edits(prog, consumers, s_style, f_style, work.scope.editable,
                                   rapid_lines(tp, prog.n_lines))
                minutes = _cut_minutes(tp, idx, targets, job.machine)
                stamp = (stamp_edit(prog, work.plans, 100.0 * job.options.fz_tolerance,
                                    _stamp_info(path, job, minutes))
                         if job.stamp else None)
                out = apply_edits(text, edits + ([stamp] if stamp else ()))
                counts = (len(edits), edits.s_words, edits.f_words)
                del edits  # ~800k strings at 1M blocks: not kept through the verification's peak
                lag_warnings, lag_lines = lag.result()
                masked_input = masked_input.result() if masked_input is not None else None
        if job.verify:
            show("checking the output")
            verify(prog, tp, out, consumers, s_style, f_style, job, found.name, work.scope,
                   masked_input)
        del masked_input
        summary = _summary(prog, tp, idx, work, counts, mesh_edge, job, minutes)
        summary = replace(summary, warnings=summary.warnings + lag_warnings,
                          lag_lines=lag_lines)
        source = job.control_from if job.control else (
            f"detected from {len(found.marks)} mark{'s' if len(found.marks) > 1 else ''}"
            if found.marks else "no marks: generic")
        summary = replace(summary, control=control, control_source=source,
                          control_notes=(control_note(control, summary.s_words, mode),),
                          s_changes=mode,
                          s_changes_source="given" if mode_given else f"the default for {control}")
        return Result(out, summary, prog, tp, idx, tuple(work.plans), targets, work.ops, work.scope)


def _targets(prog: Program, tp: Toolpath, idx: schedule.BlockIndex, work: "Work",
             f_style) -> Targets:
    """S and F to be in force per block: planned where an operation's plan owns the
    block, else the program's own; and the program's own at every fixed line that does
    not move (a canned cycle, a call), so that it is in force there too.

    A G93 block's F is 1 / minutes: the planned tip feed over its length
    (``ncopt.motion.feedmode``).  A rotary-only block (no length) keeps its F."""
    fp = idx.first_point
    ls = tp.lines
    inch = tp.line_inch[idx.line] if tp.line_inch is not None else np.zeros(fp.shape, bool)
    unit = np.where(inch, MM_PER_INCH, 1.0)
    feed_move = tp.motion[fp] != Motion.RAPID
    s_value = tp.spindle_rpm[fp].astype(np.float64)
    f_value = np.where(feed_move, tp.feed_mm_min[fp] / unit, np.nan)
    s_value[~(s_value > 0) | ~ls.s_known[idx.line]] = np.nan  # never write S0
    f_value[~ls.f_known[idx.line]] = np.nan
    scale = 10.0 ** f_style.decimals
    g93, length = _inverse_time_blocks(tp, idx)
    if g93 is not None:
        f_value = np.where(g93 & ls.f_known[idx.line],
                           inverse_time_words(tp.feed_mm_min[fp], length), f_value)
    for p in work.plans:
        lo, hi = p.window
        planned = p.blocks.planned
        s_value[lo:hi] = np.where(planned, p.s_cmd_rpm, s_value[lo:hi])
        word = p.f_mm_min / unit[lo:hi]
        if g93 is not None:
            word = np.where(g93[lo:hi], inverse_time_words(p.f_mm_min, length[lo:hi]), word)
        # never above fz; a value a rounding error short of a written one is that one
        planned_f = np.floor(word * scale + 1e-6) / scale
        # the program's own F, kept by the plan, stays as it is written (F333.33 with F
        # words of the post's usual F1000. style)
        own = f_value[lo:hi]
        planned_f = np.where(np.abs(word - own) <= 1e-9 * np.abs(own), own, planned_f)
        moves = p.blocks.length_mm > 0  # a rotary-only block keeps its F
        f_value[lo:hi] = np.where(np.isfinite(p.f_mm_min) & moves, planned_f, f_value[lo:hi])
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


def _with_fixed_lines(tp: Toolpath, idx: schedule.BlockIndex, scope: Scope,
                      targets: Targets) -> Targets:
    """The block targets and the fixed lines that do not move (canned cycles, calls):
    consumers of the program's own S and F, which must be in force there too."""
    ls = tp.lines
    extra = np.flatnonzero(scope.fixed)
    extra = extra[~np.isin(extra, idx.line)]
    if extra.size == 0:
        return targets
    # a call uses what is in force when it starts: known unless lost before its line
    prev = np.maximum(extra - 1, 0)
    s_known = np.where(ls.call[extra], ls.s_known[prev] | (extra == 0), ls.s_known[extra])
    f_known = np.where(ls.call[extra], ls.f_known[prev] | (extra == 0), ls.f_known[extra])
    s_x = np.where(s_known & (ls.s_rpm[extra] > 0), ls.s_rpm[extra], np.nan)
    f_x = np.where(f_known & (ls.f_prog[extra] > 0), ls.f_prog[extra], np.nan)
    line = np.concatenate((targets.line, extra))
    order = np.argsort(line, kind="stable")
    return Targets(line[order], np.concatenate((targets.s_value, s_x))[order],
                   np.concatenate((targets.f_value, f_x))[order])


def verify(prog: Program, tp: Toolpath, out: str, targets: Targets, s_style, f_style,
           job: Job, detected: str | None = None, scope: Scope | None = None,
           masked_input: str | None = None) -> None:
    """The checks run after every rewrite; raises VerificationError, writes nothing.

    One parse of the output (read as the input was) serves them all: the stamp
    lines are whole comment lines at the top, so masking keeps the line structure
    and every target line moves by the same count.  With S and F masked the output
    equals the input, so every geometry word is the input's own: the toolpath
    cannot have changed.  Every line ncopt may not edit is byte for byte the input's,
    and the S and F in force at every fixed line are the program's own.
    ``masked_input``: :func:`_masked_input` of ``prog``, if it was made already.
    """
    out_prog = read_text(out, prog.path, job, detected)
    in_stamps = _stamp_lines(prog)
    out_stamps = _stamp_lines(out_prog)
    if masked_input is None:
        masked_input = _masked_input(prog)
    same = _masked_without(out_prog, out_stamps) == masked_input
    del masked_input
    if not same:
        raise VerificationError("the rewrite changed more than S and F words; nothing written",
                                prog.path)
    shift = len(out_stamps) - len(in_stamps)
    if scope is not None:
        _check_untouched(prog, out_prog, in_stamps, out_stamps, scope, tp)
    shifted = replace(targets, line=targets.line + shift)
    editable = None
    if scope is not None:
        editable = _shift_lines(scope.editable, out_prog.n_lines, in_stamps, out_stamps)
    f_kept = _shift_lines(rapid_lines(tp, prog.n_lines), out_prog.n_lines, in_stamps,
                          out_stamps)
    again = plan_edits(out_prog, shifted, s_style, f_style, editable, f_kept)
    if again:
        line = int(np.searchsorted(out_prog.line_start, again[0].start, side="right"))
        raise VerificationError("rewriting the result again would change it; nothing written",
                                prog.path, line)


def _stamp_info(path: str, job: Job, minutes: tuple) -> StampInfo:
    """The stamp's header: today (or SOURCE_DATE_EPOCH's day, for reproducible outputs),
    the program's file name, the machine, and the whole program's estimated cutting time
    before and after (``minutes``: :func:`_cut_minutes`, as the summary gives it)."""
    import datetime
    import os

    epoch = os.environ.get("SOURCE_DATE_EPOCH", "")
    day = (datetime.datetime.fromtimestamp(int(epoch), datetime.timezone.utc).date()
           if epoch.isdigit() else datetime.date.today())
    m = job.machine
    spindle = f"{m.accel_rad_s2:g} rad/s2, {m.max_rpm:g} RPM"
    machine = f"{job.machine_name}: {spindle}" if job.machine_name else spindle
    before, after = (float(t.sum()) for t in minutes)
    source = "stdin" if path in ("-", "<stdin>", "<input>") else Path(path).name
    return StampInfo(day.isoformat(), source, machine, before, after)


def rapid_lines(tp: Toolpath, n_lines: int) -> np.ndarray:
    """(n_lines,) bool: the lines that move at the rapid rate (G0): their F words are the
    program's, never rewritten."""
    out = np.zeros(n_lines, dtype=bool)
    rapid = tp.line[(tp.motion == Motion.RAPID) & (tp.line >= 0)]
    out[rapid] = True
    return out


def _stamp_lines(prog: Program) -> list:
    """0-based lines of the program's ncopt stamp, in order (its header lines too)."""
    return sorted(read_stamps(prog).lines)


def _masked_input(prog: Program) -> str:
    """The input's side of the verification's comparison: S/F words masked, stamps out."""
    return _masked_without(prog, _stamp_lines(prog))


def _kept_lines(prog: Program, drop: list) -> np.ndarray:
    """0-based lines of ``prog`` without the (stamp) lines ``drop``."""
    keep = np.ones(prog.n_lines, dtype=bool)
    keep[drop] = False
    return np.flatnonzero(keep)


def _shift_lines(mask: np.ndarray, n_out: int, in_stamps: list, out_stamps: list) -> np.ndarray:
    """A per-line mask of the input carried to the output's lines (stamps: False)."""
    src = np.ones(mask.shape[0], dtype=bool)
    src[in_stamps] = False
    dst = np.ones(n_out, dtype=bool)
    dst[out_stamps] = False
    out = np.zeros(n_out, dtype=bool)
    out[np.flatnonzero(dst)] = mask[np.flatnonzero(src)]
    return out


def _check_untouched(prog, out_prog, in_stamps, out_stamps, scope, tp) -> None:
    """Lines outside the scope are byte-identical; S and F in force at every fixed line
    are the program's own."""
    a, b = _kept_lines(prog, in_stamps), _kept_lines(out_prog, out_stamps)
    if a.size != b.size:
        raise VerificationError("the rewrite changed the program's lines; nothing written",
                                prog.path)
    fixed_only = ~scope.editable[a]
    for i, j in zip(a[fixed_only].tolist(), b[fixed_only].tolist()):
        if prog.text[prog.line_start[i]:prog.line_start[i + 1]] != \
                out_prog.text[out_prog.line_start[j]:out_prog.line_start[j + 1]]:
            raise VerificationError("a line ncopt leaves alone changed; nothing written",
                                    prog.path, i + 1)
    check = scope.fixed[a]
    if not check.any():
        return
    executed = tp.lines.executed
    out_executed = _shift_lines(executed, out_prog.n_lines, in_stamps, out_stamps)
    for code in (S_CODE, F_CODE):
        before = _in_force(prog, code, executed)[a]
        after = _in_force(out_prog, code, out_executed)[b]
        bad = np.flatnonzero(check & ~((before == after) | (np.isnan(before) & np.isnan(after))))
        if bad.size:
            raise VerificationError(
                f"the program's own {chr(code)} is not in force at a line ncopt leaves alone; "
                "nothing written", prog.path, int(a[bad[0]]) + 1)


def _in_force(prog: Program, code: int, executed: np.ndarray) -> np.ndarray:
    """(n_lines,) value of the last ``code`` word at or before each line (executed lines)."""
    sel = np.flatnonzero(prog.word_letter == code)
    sel = sel[executed[prog.word_line[sel]]]
    per_line = np.full(prog.n_lines, np.nan)
    per_line[prog.word_line[sel]] = np.nan_to_num(prog.word_value[sel], nan=-1.0)
    return ffill(per_line)


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


def _cut_minutes(tp: Toolpath, idx: schedule.BlockIndex, targets: Targets,
                 machine: Machine) -> tuple[np.ndarray, np.ndarray]:
    """Minutes of every move before and after the rewrite (:mod:`ncopt.motion.times`), for the
    stamp and the summary alike."""
    cap = machine.max_feed_mm_min
    return feed_minutes(tp, None, cap), feed_minutes(tp, _feed_after(tp, idx, targets), cap)


def _summary(prog, tp, idx, work: Work, counts, mesh_edge, job, minutes) -> Summary:
    """``counts``: (edits, S words, F words) written; ``minutes``: :func:`_cut_minutes`."""
    t_before, t_after = minutes
    rows = tuple(_op_row(o, k, tp, work, t_before, t_after) for k, o in enumerate(work.ops))
    plans = work.plans
    n_edits, s_words, f_words = counts
    first = plans[0]
    tools, seen = [], set()
    for p in plans:
        if p.tool not in seen:
            seen.add(p.tool)
            tools.append((p.tool, _describe(p.cutter), work.tools[p.tool].source))
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
        warnings=tp.warnings + _plan_warnings(prog, tp, idx, work, job),
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
                          unknown_contact_pct=_unknown_share(tp, work, planned_pts)[0])
    return summary


def _unknown_share(tp: Toolpath, work: Work, points: np.ndarray) -> tuple:
    """Without a mesh, over the cut of ``points`` (mask): (percent of its length planned
    at the cutter's full radius for want of a known contact, (n,) mask of those points)."""
    unknown = np.zeros(tp.n, dtype=bool)
    cut_mm = np.zeros(tp.n)  # each move's length that can touch the part
    for view in work.views.values():
        sampled = view.sampled
        if sampled.unknown is None:
            continue
        mine = points & (tp.tool == view.tool)
        # per toolpath point (the move ending there): a mesh's samples come several a move
        new_pt = np.zeros(tp.n, dtype=bool)
        np.logical_or.at(new_pt, sampled.point, sampled.unknown)
        cut_pt = np.zeros(tp.n, dtype=bool)
        np.logical_or.at(cut_pt, sampled.point, sampled.contacts.cutting)
        known = np.flatnonzero(cut_pt & ~new_pt & mine)
        cut_mm[known] = tp.seg_len_mm[known]
        new = np.flatnonzero(new_pt & mine)
        cut_mm[new] = below_top_mm(tp, new, sampled.top_mm, sampled.up)
        unknown[new] = True
    total = float(cut_mm.sum())
    pct = 100.0 * float(cut_mm[unknown].sum()) / total if total > 0 else 0.0
    return pct, unknown


def _line_ranges(lines: np.ndarray, shown: int = 3) -> str:
    """``19-21, 88, 102-140 and 12 more`` from sorted 0-based line numbers."""
    if lines.size == 0:
        return ""
    breaks = np.flatnonzero(np.diff(lines) > 1)
    starts = np.concatenate(([lines[0]], lines[breaks + 1]))
    ends = np.concatenate((lines[breaks], [lines[-1]]))
    parts = [f"{a + 1}" if a == b else f"{a + 1}-{b + 1}"
             for a, b in zip(starts[:shown].tolist(), ends[:shown].tolist())]
    more = f" and {starts.size - shown} more" if starts.size > shown else ""
    return ", ".join(parts) + more


def _lag_warnings(prog, tp, idx, work: Work, targets: Targets, job: Job) -> tuple:
    """The simulator's check on the rewrite: the moves where the real spindle, ramping at
    its acceleration toward the S words written, leaves fz out of its band.

    Checked, as simulate checks them: every move of a planned block whose F, at the S
    commanded for it, means the operation's target fz (within twice the band: a plunge
    at its own feed per tooth is off target by design, not because the spindle lags).
    Returns (warnings, 1-based lines)."""
    from ncopt.simulate.spindle import lagging_blocks

    n = tp.n
    counts = np.diff(np.concatenate((idx.first_point, [n])))
    start = int(idx.first_point[0]) if idx.first_point.size else n
    s_pt = tp.spindle_rpm.copy()
    s_block = np.where(np.isfinite(targets.s_value), targets.s_value,
                       tp.spindle_rpm[idx.first_point])
    s_pt[start:] = np.repeat(s_block, counts)
    rev_block = np.full(idx.first_point.shape[0], np.nan)
    for p in work.plans:
        lo, hi = p.window
        rev_block[lo:hi][p.blocks.planned] = p.cutting.fz_mm * p.cutter.teeth
    rev = np.full(n, np.nan)
    rev[start:] = np.repeat(rev_block, counts)
    f_pt = _feed_after(tp, idx, targets)
    band = job.options.fz_tolerance
    with np.errstate(divide="ignore", invalid="ignore"):
        meant = np.abs(np.minimum(f_pt, job.machine.max_feed_mm_min) / (s_pt * rev) - 1.0)
    rev = np.where(meant <= 2.0 * band, rev, np.nan)
    bad = lagging_blocks(prog, tp, s_pt, f_pt, job.machine, rev, band)
    if bad.size == 0:
        return (), ()
    lines = np.unique(tp.line[bad])
    return ((f"{prog.path}:{int(lines[0]) + 1}: the spindle cannot follow the S words at "
             f"{lines.size} cutting block{'s' if lines.size > 1 else ''} (lines "
             f"{_line_ranges(lines)}; simulated at its acceleration): fz leaves its "
             f"+-{100 * band:g} % band while it catches up",),
            tuple(int(x) + 1 for x in lines))


def _feed_after(tp: Toolpath, idx: schedule.BlockIndex, targets: Targets) -> np.ndarray:
    """(n,) F in force per point after the rewrite, mm/min (from the targets)."""
    on_block = np.isin(targets.line, idx.line)
    f_block = targets.f_value[on_block]  # program units, the blocks' order
    unit = np.where(tp.line_inch[idx.line], MM_PER_INCH, 1.0) if tp.line_inch is not None else 1.0
    g93, length = _inverse_time_blocks(tp, idx)
    if g93 is not None:  # a G93 word is 1 / minutes: the tip feed is the word x the length
        unit = np.where(g93, length, unit)
    f_block = f_block * unit
    out = tp.feed_mm_min.copy()
    counts = np.diff(np.concatenate((idx.first_point, [tp.n])))
    per_point = np.repeat(f_block, counts)
    ok = np.isfinite(per_point)
    sl = slice(int(idx.first_point[0]), tp.n) if idx.first_point.size else slice(0, 0)
    out[sl] = np.where(ok, per_point, out[sl])
    return out


def _op_row(op, k, tp, work, t_before, t_after) -> OpRow:
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


def _plan_warnings(prog, tp, idx, work, job) -> tuple:
    out = []
    stamps = read_stamps(prog)
    if len(stamps) and stamps.spindle is None:
        out.append(f"{prog.path}:{stamps.lines[0] + 1}: the stamp of an earlier ncopt does not "
                   "say which spindle its S and F were planned for: planned again as if for "
                   "this one; for another machine, rewrite the original program")
    inch = tp.line_inch is not None and bool(tp.line_inch.any())
    if inch and job.cutter is not None and job.diameter_bare and job.cutter.diameter_mm < 2.0:
        d = job.cutter.diameter_mm
        out.append(f"{prog.path}: --diameter {d:g} is read as mm (a {d:g} mm cutter) but the "
                   f"program is in inches: for a {d:g} inch cutter pass --diameter {d:g}in")
    for p in work.plans:
        s0 = p.s0_rpm
        if s0 > job.machine.max_rpm:
            op = work.ops[p.op]
            reached = p.cutting.vc_m_min * job.machine.max_rpm / s0
            out.append(f"{prog.path}: {op.name}: the program's S{s0:.0f} is above the machine's "
                       f"{job.machine.max_rpm:.0f} RPM: it was written for a faster spindle; "
                       f"at {job.machine.max_rpm:.0f} RPM vc reaches {reached:.1f} of its "
                       f"{p.cutting.vc_m_min:.1f} m/min where the cutter cuts at its full diameter")
    for p in work.plans:
        out.extend(_below_min_rpm(prog, idx, work, p, job.machine))
        if p.over_target[0]:
            op = work.ops[p.op]
            out.append(f"{prog.path}: {op.name} (T{p.tool}): vc up to {p.over_target[1]:.1f} % "
                       f"above its target on {p.over_target[0]} cutting blocks, where the "
                       "spindle is still falling from an S that ncopt could not plan")
        if p.coarse_lines is not None and p.coarse_lines.size:
            op = work.ops[p.op]
            first = int(p.coarse_lines[0]) + 1
            out.append(f"{prog.path}:{first}: {op.name}: {p.coarse_lines.size} cutting blocks keep "
                       "their S and F: their feed is too low for the resolution of the "
                       "program's F words to hold fz within its band (write F with more "
                       "decimals to plan them)")
        out.extend(_unknown_warning(prog, tp, work, p))
        if p.reduced.any():
            op = work.ops[p.op]
            out.append(f"{prog.path}: {op.name}: {int(p.reduced.sum())} blocks off the cutting "
                       f"feed {p.cutting_feed_mm_min:g} mm/min or in the air (plunges, ramps, "
                       "lead-ins, links) keep the program's feed per tooth: F scaled with S")
    return tuple(out)


def _below_min_rpm(prog, idx: schedule.BlockIndex, work: Work, p, machine: Machine) -> list:
    """Cutting blocks that need a lower S than the machine's lowest (--min-rpm): vc runs
    above its target there, and the rewrite says where and by how much."""
    c = p.blocks.cutting & p.blocks.planned
    need = p.blocks.req_rpm
    low = np.flatnonzero(c & (need < machine.min_rpm))
    if low.size == 0 or not machine.min_rpm > 0:
        return []
    worst = 100.0 * (machine.min_rpm / float(np.min(need[low])) - 1.0)
    lines = np.unique(idx.line[p.window[0] + low])
    return [f"{prog.path}:{int(lines[0]) + 1}: {work.ops[p.op].name} (T{p.tool}): "
            f"{low.size} cutting block{'s' if low.size > 1 else ''} (lines "
            f"{_line_ranges(lines)}) need less than the machine's lowest speed "
            f"{machine.min_rpm:g} RPM: vc up to {worst:+.1f} % above its target there (lower "
            "--min-rpm if the spindle can turn slower)"]


def _unknown_warning(prog, tp: Toolpath, work: Work, p) -> list:
    """Where a plan without a mesh could not see the contact: one located warning."""
    pct, unknown = _unknown_share(tp, work, work.point_op == p.op)
    if not unknown.any():
        return []
    lines = np.unique(tp.line[unknown])
    op = work.ops[p.op]
    where = f"{prog.path}:{int(lines[0]) + 1}: {op.name} (T{p.tool}): {pct:.1f} % of the cut " \
        f"({lines.size} blocks: lines {_line_ranges(lines)})"
    if (work.fits or {}).get(p.tool) is not None:  # a mesh, which has no part there
        return [f"{where} runs below the top of the cut where the mesh has no part: planned "
                "as if the cutter cut at its full diameter, so vc stays at or below its target "
                "there; check that the mesh is the whole part (a floor, a side missing)"]
    return [f"{where} runs where the toolpath cannot show the contact (down or up a wall, a "
            "plunge below the top of the cut, a pass with no neighbour): planned as if the "
            "cutter cut at its full diameter, so vc stays at or below its target there; give "
            "--mesh to plan it exactly"]


def _finite(value):
    """NaN and infinities as None: JSON has neither."""
    if isinstance(value, float):
        return value if np.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    return value


def _describe(cutter: Cutter) -> str:
    kind = "ball" if cutter.is_ball else f"bull-nose r{cutter.corner_radius_mm:g}"
    return f"D{cutter.diameter_mm:g} {kind}, {cutter.teeth} teeth"
