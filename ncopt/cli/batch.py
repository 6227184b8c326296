"""Rewrite a folder of programs in parallel processes, safely.

* one bad file never stops the others; each file's outcome is reported truthfully;
* outputs are written atomically (:mod:`ncopt.runtime.fileio`), so an interrupted or killed
  batch leaves no partial output file (at most a temporary, which the next run in the
  folder removes), and workers whose parent is gone stop quietly;
* originals are never overwritten unless ``in_place``, which keeps every version it
  replaces as a backup (NAME.bak, NAME.1.bak, ...); an output folder that is, lies in
  or links to the input folder is refused;
* subfolders are mirrored under the output folder, never written outside it.
"""

from __future__ import annotations

import glob
import multiprocessing as mp
import os
import signal
import tempfile
import threading
from dataclasses import asdict, dataclass, replace
from pathlib import Path

from ncopt.runtime.errors import (FileError, NcoptError, NothingToPlan, UsageError, ValueRangeError,
                     from_program)
from ncopt.runtime.fileio import (TMP_SUFFIX, clean_stale_temporaries, discard, hint, replace_in_place,
                     write_output)

PROGRAM_SUFFIXES = {".nc", ".ngc", ".tap", ".gcode", ".mpf", ".spf", ".cnc", ".iso", ".h",
                    ".eia", ".ptp", ".min"}
__all__ = ["TMP_SUFFIX", "FileReport", "Task", "find_programs", "plan_targets", "run_batch"]


@dataclass(frozen=True)
class Task:
    """One file of a batch: where it is read, where it goes, and how it is planned."""

    source: str
    target: str
    job: object  # ncopt.model.Job
    mesh: str | None = None
    in_place: bool = False
    page: str | None = None  # batch --report index.html: this file's HTML page
    lite: bool = False  # --report-lite: that page with static images, no plotly.js


@dataclass(frozen=True)
class FileReport:
    """How one file went."""

    source: str
    target: str
    status: str  # "ok", "unchanged" (nothing to plan: copied as is), "failed"
    blocks: int = 0
    s_words: int = 0
    f_words: int = 0
    time_before_min: float = 0.0
    time_after_min: float = 0.0
    warnings: int = 0
    error: str = ""
    backup: str = ""  # in place: the backup made of the version replaced
    report: str = ""  # the file's HTML page (batch --report index.html)
    report_error: str = ""  # why it has none
    summary: dict | None = None  # the rewrite's summary (ncopt.api.Summary.to_dict)
    operations: tuple[tuple[str, bool, str], ...] = ()  # (name, planned, why) of each

    def to_dict(self) -> dict:
        return asdict(self)


def find_programs(spec: str) -> tuple[Path, list[Path]]:
    """The base folder and the programs named by a folder or a glob pattern."""
    path = Path(spec)
    if path.is_dir():
        files = sorted(p for p in path.rglob("*") if p.is_file()
                       and p.suffix.lower() in PROGRAM_SUFFIXES and not p.name.startswith("."))
        return path, files
    files = sorted(Path(p) for p in glob.glob(spec, recursive=True) if Path(p).is_file())
    base = Path(os.path.commonpath([str(p.parent) for p in files])) if files else Path(".")
    return base, files


def plan_targets(files: list[Path], base: Path, out_dir: Path | None, in_place: bool,
                 folder_given: bool) -> list[Path]:
    """Where each program's rewrite goes: mirrored under out_dir, or over itself.

    Refused (UsageError): no -o and no --in-place, both, an output folder that is the
    input folder, lies inside it or links to it (folder_given: the input was a folder),
    and any output that would land on an input.
    """
    if in_place and out_dir is not None:
        raise UsageError("give either -o OUTDIR or --in-place, not both")
    if in_place:
        return list(files)
    if out_dir is None:
        raise UsageError("give an output folder with -o, or --in-place to replace the originals")
    real_out, real_base = Path(os.path.realpath(out_dir)), Path(os.path.realpath(base))
    if folder_given and real_out.is_relative_to(real_base):
        where = "the input folder" if real_out == real_base else "inside the input folder"
        raise UsageError(f"the output folder is {where} {base}: the originals would be "
                         "overwritten or read again; write to another folder, or use "
                         "--in-place (which keeps backups)", str(out_dir))
    targets = [_mirrored(f, base, out_dir) for f in files]
    inputs = {_identity(f) for f in files} - {None}
    for t in targets:
        if _identity(t) in inputs:
            raise UsageError("this output would overwrite an input program; write to another "
                             "folder, or use --in-place (which keeps backups)", str(t))
    return targets


def _identity(path: Path) -> tuple[int, int] | None:
    """The file a path names (device, inode), through links; None when there is none."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_dev, st.st_ino


def _mirrored(src: Path, base: Path, out_dir: Path) -> Path:
    # the path as found in the folder (a symlink to elsewhere keeps its place in it)
    rel = Path(os.path.abspath(src)).relative_to(os.path.abspath(base))
    target = Path(os.path.abspath(out_dir / rel))
    if not target.is_relative_to(os.path.abspath(out_dir)) or ".." in rel.parts:
        raise UsageError(f"refusing to write outside {out_dir}", str(target))
    return target


def prepare_output_folder(out_dir: Path) -> None:
    """Create the output folder and make sure files can be written into it; a FileError
    that names the output folder, not an input, otherwise."""
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".ncopt-probe.", suffix=TMP_SUFFIX, dir=out_dir)
        os.close(fd)
        discard(Path(probe))
    except OSError as exc:
        raise FileError(f"cannot write into the output folder: {exc.strerror}; {hint(exc)}",
                        str(out_dir)) from None


def process_one(task: Task) -> FileReport:
    """Rewrite one file (runs in a worker process); every failure becomes a report."""
    from ncopt.api import rewrite_file

    src, target = task.source, task.target
    try:
        data = Path(src).read_bytes()
    except OSError as exc:
        return _failed(task, f"cannot read the file: {exc.strerror}; {hint(exc)}")
    try:
        result = rewrite_file(src, task.job, mesh_path=task.mesh, data=data)
        text = result.text.encode("latin-1")
        backup = None
        if task.in_place:
            backup = replace_in_place(Path(src), data, text)
        else:
            write_output(Path(target), text, make_parents=True)
        s = result.summary
        done = FileReport(src, target, "ok", s.blocks, s.s_words, s.f_words,
                          s.cut_time_before_min, s.cut_time_after_min, len(s.warnings),
                          backup=str(backup or ""), summary=s.to_dict(),
                          operations=tuple((o.name, o.planned, o.reason)
                                           for o in s.operations))
        if task.page:
            from ncopt.report.html import write_file_page
            written, why = write_file_page(task.page, result, data, src, target, task.job,
                                           task.mesh, lite=task.lite)
            done = replace(done, report=written, report_error=why)
        return done
    except NothingToPlan as exc:
        try:
            if not task.in_place:
                write_output(Path(target), data, make_parents=True)
        except FileError as write_exc:
            return _failed(task, str(write_exc))
        return FileReport(src, target, "unchanged", error=exc.message,
                          operations=tuple((o.name, o.planned, o.reason)
                                           for o in getattr(exc, "operations", ())))
    except FileError as exc:  # names the output, or the file replaced in place
        same = exc.path is not None and Path(exc.path) == Path(task.source)
        return _failed(task, exc.message if same else str(exc))
    except ValueRangeError as exc:  # the job was checked: the program gave the value
        return _failed(task, _short(from_program(exc, src)))
    except NcoptError as exc:
        return _failed(task, _short(exc))
    except Exception as exc:  # noqa: BLE001 - a bug on one file must not stop the batch
        return _failed(task, f"internal error, please report it: {type(exc).__name__}: {exc}")


def _failed(task: Task, error: str) -> FileReport:
    return FileReport(task.source, task.target, "failed", error=error)


def _short(exc: NcoptError) -> str:
    """The message without the file name (the table shows it): 'line 12:3: ...'."""
    where = f"line {exc.line}" + (f":{exc.column}" if exc.column else "") + ": " if exc.line else ""
    return where + exc.message


def _worker_init() -> None:
    # The parent handles Ctrl-C and SIGTERM: it stops the pool with SIGTERM, whose default
    # ends a worker at once whichever of its threads the signal reaches (a Python handler
    # would run only in the main thread, which may wait on a lock no signal interrupts).
    # What a worker stopped mid-write leaves is a temporary with its pid in the name; the
    # parent removes those once the pool is gone, and so does any later run in the folder.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if hasattr(signal, "SIGPIPE"):
        # a worker's pipes lead to its parent: a killed parent leaves them without a
        # reader, and the result being sent then ends the worker (its default), where
        # Python's BrokenPipeError would print multiprocessing's traceback
        signal.signal(signal.SIGPIPE, signal.SIG_DFL)
    parent = mp.parent_process()
    if parent is not None:  # a killed parent: end the same way, with no traceback
        threading.Thread(target=_stop_with, args=(parent,), daemon=True).start()


def _stop_with(parent) -> None:
    parent.join()
    os.kill(os.getpid(), signal.SIGTERM)


def run_batch(tasks: list[Task], jobs: int, on_done=None) -> list[FileReport]:
    """Run tasks in ``jobs`` processes; ``on_done(report)`` after each file.

    On SIGINT/SIGTERM the workers are stopped, temporary files removed, and
    KeyboardInterrupt propagates (finished files stay: each was renamed whole).
    """
    reports: list[FileReport] = []
    previous = signal.signal(signal.SIGTERM, _raise_interrupt)
    ctx = mp.get_context("fork") if hasattr(os, "fork") else mp.get_context("spawn")
    pool = ctx.Pool(max(1, min(jobs, len(tasks))), initializer=_worker_init)
    try:
        for report in pool.imap_unordered(process_one, tasks):
            reports.append(report)
            if on_done:
                on_done(report)
        pool.close()
    except BaseException:
        pool.terminate()
        raise
    finally:
        pool.join()
        signal.signal(signal.SIGTERM, previous)
        for folder in {Path(t.target).parent for t in tasks}:
            clean_stale_temporaries(folder)  # the workers are gone: theirs are stale
    order = {t.source: i for i, t in enumerate(tasks)}
    return sorted(reports, key=lambda r: order.get(r.source, 0))


def _raise_interrupt(signum, frame):
    raise KeyboardInterrupt
