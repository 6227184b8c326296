"""The batch's progress bars and final table (rich, at the edge).

The table fits an 80-column terminal: one row per file with a short status
(failures first, then rewrites, then files with nothing to plan), long file names
shortened from the left, the reasons listed below the table, and a total row
with the cutting time saved.
"""

from __future__ import annotations

import os
from collections import Counter
from pathlib import Path

from rich import box
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

ORDER = {"failed": 0, "ok": 1, "unchanged": 2}
STATUS = {"failed": "FAILED", "ok": "ok", "unchanged": "same"}
SHOWN_PER_REASON = 3  # files named for each reason a file had nothing to plan


class BatchView:
    """Two bars, files and blocks; blocks are counted from the files' line counts."""

    def __init__(self, console: Console, files: list[Path], quiet: bool = False) -> None:
        self.console = console
        self.quiet = quiet
        self.lines = {str(f): _count_lines(f) for f in files}
        self.progress = Progress(TextColumn("{task.description}"), BarColumn(),
                                 MofNCompleteColumn(), TimeElapsedColumn(), console=console,
                                 transient=False, disable=quiet or not console.is_terminal)
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
        """The table, the reasons and the totals; with quiet, only the failures."""
        say = lambda text: self.console.print(text, markup=False)  # noqa: E731
        rows = sorted(reports, key=lambda r: ORDER.get(r.status, 0))
        if self.quiet:
            for r in rows:
                if r.status == "failed":
                    say(f"{r.source}: {r.error}")
            return
        self.console.print(_table(rows, base, self.console.width))
        failed = [r for r in rows if r.status == "failed"]
        if failed:
            say("failed:")
            for r in failed:
                say(f"  {_relative(r.source, base)}: {r.error}")
        same = Counter(r.error for r in rows if r.status == "unchanged")
        if same:
            say("same (nothing to plan, copied unchanged):")
            for reason, count in same.most_common():
                names = [_relative(r.source, base) for r in rows
                         if r.status == "unchanged" and r.error == reason]
                more = f" and {count - SHOWN_PER_REASON} more" if count > SHOWN_PER_REASON else ""
                say(f"  {reason}: {', '.join(names[:SHOWN_PER_REASON])}{more}")
        for line in summary_lines(reports):
            say(line)


def _table(rows, base: Path | None, width: int) -> Table:
    """One line per file; the file column takes what the others leave of ``width``."""
    ok = [r for r in rows if r.status == "ok"]
    cells = [[STATUS.get(r.status, r.status)] + ([str(r.blocks), str(r.s_words),
              _minutes(r.time_before_min, r.time_after_min), str(r.warnings)]
             if r.status == "ok" else ["", "", "", ""]) for r in rows]
    footer = ["", str(sum(r.blocks for r in ok)), str(sum(r.s_words for r in ok)),
              _minutes(sum(r.time_before_min for r in ok), sum(r.time_after_min for r in ok))
              if ok else "", str(sum(r.warnings for r in ok))]
    heads = ("status", "blocks", "S words", "minutes", "warn")
    widths = [max(len(h), len(f), *(len(c[i]) for c in cells))
              for i, (h, f) in enumerate(zip(heads, footer))]
    names = [_relative(r.source, base) for r in rows]
    file_width = max(width - sum(widths) - 2 * len(widths), 12)
    file_width = min(file_width, max(len(n) for n in [*names, "file"]))
    t = Table(box=box.SIMPLE_HEAD, padding=(0, 1), pad_edge=False, show_footer=True,
              show_edge=False, collapse_padding=True)  # two spaces between columns
    t.add_column("file", footer=_count(len(rows), "file"), width=file_width, no_wrap=True)
    for head, foot, w in zip(heads, footer, widths):
        t.add_column(head, footer=foot, width=w, no_wrap=True,
                     justify="left" if head == "status" else "right")
    for name, row in zip(names, cells):
        t.add_row(_shorten(name, file_width), *row)
    return t


def summary_lines(reports) -> list[str]:
    """The closing lines: the time saved over the rewritten files, then the counts."""
    counts = {k: sum(r.status == k for r in reports) for k in ("ok", "unchanged", "failed")}
    lines = []
    ok = [r for r in reports if r.status == "ok"]
    if ok:
        before = sum(r.time_before_min for r in ok)
        after = sum(r.time_after_min for r in ok)
        pct = f" ({(after - before) / before * 100:+.1f} %)" if before > 0 else ""
        lines.append(f"ncopt: estimated cutting time of the {len(ok)} rewritten "
                     f"{'file' if len(ok) == 1 else 'files'} {before:.1f} -> {after:.1f} min: "
                     f"{before - after:.1f} min saved{pct}")
    lines.append(f"ncopt: {counts['ok']} rewritten, {counts['unchanged']} unchanged (nothing to "
                 f"plan), {counts['failed']} failed, of {_count(len(reports), 'file')}")
    return lines


def _count(n: int, noun: str) -> str:
    """``1 file``, ``3 files``."""
    return f"{n} {noun}" + ("" if n == 1 else "s")


def _minutes(before: float, after: float) -> str:
    return f"{before:.1f} -> {after:.1f}"


def _shorten(name: str, width: int) -> str:
    """A path that fits ``width`` characters: its first folder and its file name kept, the
    middle elided (``sub/…/part_07.nc``: the folder tells the files of one part from
    another's); where even that is too long, the file name's end."""
    if len(name) <= width:
        return name
    head, sep, _ = name.partition("/")
    tail = name.rsplit("/", 1)[-1]
    if sep and len(head) + len(tail) + 3 <= width:
        room = width - len(tail) - 2  # "…/" before the file name
        return name[:room] + "…/" + tail if room > len(head) else head + "/…/" + tail
    return "…" + name[len(name) - width + 1:]


def _count_lines(path: Path) -> int:
    try:
        with open(path, "rb") as handle:
            return sum(chunk.count(b"\n") for chunk in iter(lambda: handle.read(1 << 20), b""))
    except OSError:
        return 0


def _relative(path: str, base: Path | None) -> str:
    """The path under the batch's folder, as found there (links not followed)."""
    try:
        return str(Path(os.path.abspath(path)).relative_to(os.path.abspath(base))) if base else path
    except ValueError:
        return path
