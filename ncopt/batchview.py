"""The batch's progress bars and final table (rich, at the edge)."""

from __future__ import annotations

from pathlib import Path

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table


class BatchView:
    """Two bars, files and blocks; blocks are counted from the files' line counts."""

    def __init__(self, console: Console, files: list[Path]) -> None:
        self.console = console
        self.lines = {str(f): _count_lines(f) for f in files}
        self.progress = Progress(TextColumn("{task.description}"), BarColumn(),
                                 MofNCompleteColumn(), TimeElapsedColumn(), console=console,
                                 transient=False, disable=not console.is_terminal)
        self.files_task = self.progress.add_task("files ", total=len(files))
        self.blocks_task = self.progress.add_task("blocks", total=sum(self.lines.values()))

    def __enter__(self):
        self.progress.start()
        return self

    def __exit__(self, *exc) -> None:
        self.progress.stop()

    def done(self, report) -> None:
        self.progress.advance(self.files_task)
        self.progress.advance(self.blocks_task, self.lines.get(report.source, 0))

    def table(self, reports, base: Path | None = None) -> None:
        t = Table(title="ncopt batch", show_lines=False)
        for col, just in (("file", "left"), ("status", "left"), ("blocks", "right"),
                          ("S words", "right"), ("time before -> after (min)", "right"),
                          ("warnings", "right")):
            t.add_column(col, justify=just, overflow="fold")
        for r in reports:
            time = f"{r.time_before_min:.1f} -> {r.time_after_min:.1f}" if r.status == "ok" else ""
            status = r.status if r.status == "ok" else f"{r.status}: {r.error}"
            name = _relative(r.source, base)
            t.add_row(name, status, str(r.blocks), str(r.s_words), time, str(r.warnings))
        self.console.print(t)
        counts = {k: sum(r.status == k for r in reports) for k in ("ok", "unchanged", "failed")}
        self.console.print(f"ncopt: {counts['ok']} rewritten, {counts['unchanged']} unchanged "
                           f"(nothing to plan), {counts['failed']} failed, of {len(reports)} "
                           "files", markup=False)


def _count_lines(path: Path) -> int:
    try:
        with open(path, "rb") as handle:
            return sum(chunk.count(b"\n") for chunk in iter(lambda: handle.read(1 << 20), b""))
    except OSError:
        return 0


def _relative(path: str, base: Path | None) -> str:
    try:
        return str(Path(path).resolve().relative_to(base.resolve())) if base else path
    except ValueError:
        return path
