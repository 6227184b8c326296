"""The library entry points: what the CLI calls, and what people import.

    >>> from ncopt.api import Job, rewrite_file
    >>> from ncopt.model import Cutter, Machine
    >>> job = Job(cutter=Cutter(16, 2), machine=Machine(accel_rad_s2=227, max_rpm=15000))
    >>> result = rewrite_file("samples/bowl.mpf", job, mesh_path="samples/bowl.stl")
    >>> round(result.summary.time_change_pct)
    -47

A rewrite composes the stages: read (:mod:`ncopt.reading`) -> interpret
(:mod:`ncopt.motion`) -> plan (:mod:`ncopt.planning`, with the contacts of
:mod:`ncopt.contacts`) -> write (:mod:`ncopt.writing`) -> verify -> summarise; the
spindle check on the rewrite is the simulator's (:mod:`ncopt.simulate`).
"""

from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable

from ncopt.contacts import kdtree
from ncopt.contacts.geometry import MeshIndex, load_stl
from ncopt.model import Job, Program, Toolpath
from ncopt.motion.interp import interpret, tcp_of
from ncopt.planning import schedule
from ncopt.planning.operations import Operation
from ncopt.planning.opplan import OpPlan
from ncopt.planning.plans import Work, plan_program
from ncopt.planning.regions import Scope
from ncopt.reading.controls import default_s_changes
from ncopt.reading.dialect import detect
from ncopt.reading.read import read_text
from ncopt.reading.stamp import stamp_edit
from ncopt.runtime.memory import release_freed_memory, small_pages, working_memory
from ncopt.simulate.spindle import lagging_blocks
from ncopt.writing.edits import Targets, WordStyle, apply_edits, plan_edits
from ncopt.writing.summary import OpRow, Summary, stamp_info, summarise, with_control
from ncopt.writing.targets import (block_targets, cut_minutes, rapid_lines, with_fixed_lines,
                                   word_styles)
from ncopt.writing.verify import check_output, masked_input_of
from ncopt.writing.warnings import lag_warning, spindle_check_inputs

__all__ = ["Job", "OpRow", "Result", "Summary", "rewrite_file", "rewrite_text", "verify"]


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
    operations: tuple[Operation, ...] = ()
    scope: Scope | None = None

    @property
    def plan(self) -> OpPlan:
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
            s_style, f_style, quantum = word_styles(prog, tp, idx)
            mode_given = job.options.s_changes is not None
            job = _planning_job(job, found.name, quantum)
            show("finding the contacts and planning S and F")
            work = plan_program(prog, tp, idx, job, mesh_index)
            mesh_edge = float(mesh_index.edge_lengths.median_mm) if mesh_index else None
            del mesh_index  # the largest object of a big job; verification needs memory too
            if mesh_edge is not None:  # it was built in its own thread's arena: hand that back
                release_freed_memory(force=True)
            show("writing the new S and F words")
            targets = block_targets(tp, idx, work, f_style)
            consumers = with_fixed_lines(tp, idx, work.scope, targets)
            with ThreadPoolExecutor(1, thread_name_prefix="ncopt-checks") as pool:
                # numpy work that needs no edit, beside the edits and the splice (Python loops):
                # the lag check, and the input's side of the verification's comparison
                lag = pool.submit(_lag_warnings, prog, tp, idx, work, targets, job)
                masked_input = pool.submit(masked_input_of, prog) if job.verify else None
                edits = plan_edits(prog, consumers, s_style, f_style, work.scope.editable,
                                   rapid_lines(tp, prog.n_lines))
                minutes = cut_minutes(tp, idx, targets, job.machine)
                stamp = (stamp_edit(prog, work.plans, 100.0 * job.options.fz_tolerance,
                                    stamp_info(path, job, minutes))
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
        summary = summarise(prog, tp, idx, work, counts, mesh_edge, job, minutes)
        summary = replace(summary, warnings=summary.warnings + lag_warnings,
                          lag_lines=lag_lines)
        summary = with_control(summary, job, found, mode_given)
        return Result(out, summary, prog, tp, idx, tuple(work.plans), targets, work.ops, work.scope)


def _planning_job(job: Job, detected: str, quantum_mm_min: float) -> Job:
    """The job as the planner takes it: the F words' resolution (mm/min), and where S may
    change (given, or the default of the control: the job's, else the one detected)."""
    mode = job.options.s_changes or default_s_changes(job.control or detected)
    return replace(job, options=replace(job.options, f_quantum_mm_min=quantum_mm_min,
                                        s_changes=mode))


def verify(prog: Program, tp: Toolpath, out: str, targets: Targets, s_style: WordStyle,
           f_style: WordStyle, job: Job, detected: str | None = None,
           scope: Scope | None = None, masked_input: str | None = None) -> None:
    """The checks run after every rewrite (:func:`ncopt.writing.verify.check_output`), on
    one parse of the output read as the input was; raises VerificationError, writes
    nothing.  ``masked_input``: :func:`ncopt.writing.verify.masked_input_of` ``prog``, if
    it was made already."""
    check_output(prog, read_text(out, prog.path, job, detected), tp, targets, s_style, f_style,
                 scope, masked_input)


def _lag_warnings(prog: Program, tp: Toolpath, idx: schedule.BlockIndex, work: Work,
                  targets: Targets, job: Job) -> tuple:
    """The simulator's check on the rewrite: the moves where the real spindle, ramping at
    its acceleration toward the S words written, leaves fz out of its band.

    Checked, as simulate checks them: every move of a planned block whose F, at the S
    commanded for it, means the operation's target fz
    (:func:`ncopt.writing.warnings.spindle_check_inputs`).  Returns (warnings, 1-based
    lines)."""
    band = job.options.fz_tolerance
    s_pt, f_pt, rev = spindle_check_inputs(tp, idx, work, targets, job)
    bad = lagging_blocks(prog, tp, s_pt, f_pt, job.machine, rev, band)
    return lag_warning(prog, tp, bad, band)
