"""Rewrite a folder of programs in parallel processes, safely.

* one bad file never stops the others; each file's outcome is reported truthfully;
* outputs are written atomically (a temporary file in the target folder, then a
  rename), so an interrupted batch leaves no partial output file;
* originals are never overwritten unless ``in_place``, which keeps a backup;
* subfolders are mirrored under the output folder, never written outside it.
"""

from __future__ import annotations

import glob
import shutil
import multiprocessing as mp
import os
import signal
import tempfile
from dataclasses import asdict, dataclass, replace
from pathlib import Path

from .api import rewrite_file
from .errors import NcoptError, NothingToPlan, UsageError

PROGRAM_SUFFIXES = {".nc", ".ngc", ".tap", ".gcode", ".mpf", ".spf", ".cnc", ".iso", ".h",
                    ".eia", ".ptp", ".min"}
TMP_SUFFIX = ".ncopt-tmp"


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
    report: str = ""  # the file's HTML page (batch --report index.html)
    report_error: str = ""  # why it has none

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


def target_for(src: Path, base: Path, out_dir: Path | None, in_place: bool) -> Path:
    """Where a program's rewrite goes: mirrored under out_dir, or over itself."""
    if in_place:
        return src
    if out_dir is None:
        raise UsageError("give an output folder with -o, or --in-place to replace the originals")
    # the path as found in the folder (a symlink to elsewhere keeps its place in it)
    rel = Path(os.path.abspath(src)).relative_to(os.path.abspath(base))
    target = Path(os.path.abspath(out_dir / rel))
    if not target.is_relative_to(os.path.abspath(out_dir)) or ".." in rel.parts:
        raise UsageError(f"refusing to write outside {out_dir}", str(target))
    return target


def write_atomic(target: Path, data: bytes, backup_suffix: str | None = None,
                 make_parents: bool = True) -> None:
    """Write via a temporary file in the same folder and a rename (never half-written)."""
    if make_parents:
        target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=TMP_SUFFIX, dir=target.parent)
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        if backup_suffix and target.exists():
            if target.read_bytes() == data:  # already so: nothing to replace, nothing to back up
                Path(tmp).unlink()
                return
            _backup(target, target.with_name(target.name + backup_suffix))
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _backup(target: Path, backup: Path) -> None:
    """The version this run replaces becomes NAME.bak (the file itself, hard-linked, so
    nothing is copied; a copy where links are not possible), replacing an older backup."""
    tmp = backup.with_name(f".{backup.name}.link{TMP_SUFFIX}")
    tmp.unlink(missing_ok=True)
    try:
        os.link(target, tmp)
    except OSError:
        shutil.copy2(target, tmp)
    os.replace(tmp, backup)


def process_one(args: tuple) -> FileReport:
    """Rewrite one file (runs in a worker process)."""
    src, target, job, mesh, backup_suffix, *page = args
    try:
        data = Path(src).read_bytes()
        result = rewrite_file(src, job, mesh_path=mesh, data=data)
        write_atomic(Path(target), result.text.encode("latin-1"), backup_suffix)
        s = result.summary
        done = FileReport(str(src), str(target), "ok", s.blocks, s.s_words, s.f_words,
                          s.cut_time_before_min, s.cut_time_after_min, len(s.warnings))
        if page and page[0]:
            from .report import write_file_page
            written, why = write_file_page(page[0], result, data, src, target, job, mesh)
            done = replace(done, report=written, report_error=why)
        return done
    except NothingToPlan as exc:
        if Path(target).resolve() != Path(src).resolve():
            write_atomic(Path(target), Path(src).read_bytes())
        return FileReport(str(src), str(target), "unchanged", error=exc.message)
    except NcoptError as exc:
        return FileReport(str(src), str(target), "failed", error=_short(exc))
    except OSError as exc:
        return FileReport(str(src), str(target), "failed",
                          error=f"{src}: {exc.strerror or exc}")
    except Exception as exc:  # noqa: BLE001 - a bug on one file must not stop the batch
        return FileReport(str(src), str(target), "failed",
                          error=f"{src}: internal error, please report it: "
                                f"{type(exc).__name__}: {exc}")


def _short(exc: NcoptError) -> str:
    """The message without the file name (the table shows it): 'line 12:3: ...'."""
    where = f"line {exc.line}" + (f":{exc.column}" if exc.column else "") + ": " if exc.line else ""
    return where + exc.message


def _worker_init() -> None:
    # the parent handles Ctrl-C and SIGTERM: it stops the pool and cleans up
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def run_batch(tasks: list[tuple], jobs: int, on_done=None) -> list[FileReport]:
    """Run tasks in ``jobs`` processes; ``on_done(report)`` after each file.

    On SIGINT/SIGTERM the workers are stopped, temporary files removed, and
    KeyboardInterrupt propagates (finished files stay: each was renamed whole).
    """
    reports: list[FileReport] = []
    previous = signal.signal(signal.SIGTERM, _raise_interrupt)
    ctx = mp.get_context("fork") if hasattr(os, "fork") else mp.get_context("spawn")
    pool = ctx.Pool(max(1, jobs), initializer=_worker_init)
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
        for _, target, *_ in tasks:
            for tmp in Path(target).parent.glob(f".{Path(target).name}.*{TMP_SUFFIX}"):
                tmp.unlink(missing_ok=True)
    order = {str(t[0]): i for i, t in enumerate(tasks)}
    return sorted(reports, key=lambda r: order.get(r.source, 0))


def _raise_interrupt(signum, frame):
    raise KeyboardInterrupt
