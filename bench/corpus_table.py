"""One markdown table row per program of the shared corpus: what ncopt reads, what a
mesh-free rewrite plans, what it leaves alone, or where it refuses the program.

    python bench/corpus_table.py                 # the table and its totals
    python bench/corpus_table.py --judge         # and a column by LinuxCNC's rs274
    python bench/corpus_table.py --corpus DIR    # another folder

Every ``*.nc *.ngc *.tap *.gcode`` under the corpus (recursively, with
``linuxcnc/interp-tests``) gets a row:

* dialect: ``ncopt.reading.dialect.detect``
* blocks: lines of kind WORDS; moves: lines that move (``ncopt.planning.inspection.inspect_text``)
* cutting: cutting blocks planned by ``rewrite_text`` without a mesh, as a user runs it:
  ``Machine(227, 15000)``, the tools and cutting data the program gives; where it names
  no diameter for a tool, ``Cutter(3, 2)`` for that tool (``--diameter 3 --tool N``, what
  the CLI asks for) and the counts are added up; 0 when nothing is planned.
* operations: a second table lists every operation of every program ncopt reads (name,
  tool, lines, kind, planned or left and why), and checks that every line outside the
  planned operations came out byte-identical.
* left alone: the opaque constructs (``prog.opaque_reason``: o-words counted together,
  other keywords by name) and the stretches of feed moves ncopt does not plan (its
  "not planned" warnings)
* error: the located message (``file:line:col: message``, shortened) where ncopt
  refuses the program, or the message of a rewrite it refuses.

``--judge`` adds what ``rs274`` (through tests/judge.py, which strips D words, Fanuc
program numbers and tape control codes first) says of the original and, where ncopt
rewrote the program, whether rs274 accepts the rewrite with the same motion.  rs274 runs
here without the ini files and subroutine paths some interp tests are run with.

The totals end the output; a crash (anything but a located NcoptError) makes the exit
status 1.  Runtime: about 15 s, with ``--judge`` about 25 s.
"""

from __future__ import annotations

import argparse
import collections
import re
import sys
import time
import traceback
import warnings
from dataclasses import dataclass, replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from ncopt.api import rewrite_text  # noqa: E402
from ncopt.model import Job
from ncopt.reading.dialect import detect  # noqa: E402
from ncopt.runtime.errors import NcoptError, NothingToPlan, UsageError  # noqa: E402
from ncopt.planning.inspection import inspect_text  # noqa: E402
from ncopt.model import Cutter, CuttingData, Machine  # noqa: E402
from ncopt.reading.stampline import STAMP_LINE as STAMP  # noqa: E402  (a line of a stamp, any version)

CORPUS = (ROOT / "../shared/corpus").resolve()
SUFFIXES = (".nc", ".ngc", ".tap", ".gcode", ".mpf", ".h")
JOB = Job(machine=Machine(227, 15000))  # as a user runs it: tools and data from the program
FALLBACK = Cutter(3, 2)  # for a tool the program names no diameter of
OWORD = re.compile(r"\s*/?\s*(?:N\s*[\d.]+\s*)?O\s*[\d<#\[]", re.IGNORECASE)
MORE_STRETCHES = re.compile(r"(\d+) more stretches not planned")
MESSAGE_CHARS = 80  # of the message, after file:line:col


@dataclass
class Row:
    file: str
    dialect: str = ""
    blocks: int | None = None
    moves: int | None = None
    cutting: str = ""
    left_alone: str = ""
    error: str = ""
    status: str = "planned"  # planned, nothing, refused, rewrite-refused, crashed
    located: bool = True
    numpy_warnings: tuple = ()
    rs274: str = ""
    rs274_accepts: bool | None = None
    rewrites: tuple = ()  # rewritten texts (one per tool), for the judge
    operations: tuple = ()  # (operation, planned, why) of the rewrite(s)
    untouched: bool = True  # every line outside the planned operations is the input's

    def cells(self, judge: bool) -> list[str]:
        num = lambda v: "-" if v is None else str(v)  # noqa: E731
        cells = [self.file, self.dialect, num(self.blocks), num(self.moves), self.cutting,
                 self.left_alone, self.error]
        return cells + [self.rs274] if judge else cells


def programs(corpus: Path) -> list[Path]:
    return sorted((p for p in corpus.rglob("*") if p.is_file() and p.suffix in SUFFIXES),
                  key=lambda p: str(p.relative_to(corpus)))


def shorten(text: str, n: int = MESSAGE_CHARS) -> str:
    line = " ".join(text.split())
    return line if len(line) <= n else line[: n - 1] + "…"


def located_message(exc: NcoptError, n: int = MESSAGE_CHARS) -> str:
    """``file:line:col: message`` with the message (not the place) shortened."""
    return f"{exc.location}: {shorten(exc.message, n)}"


def left_alone(text: str, info) -> str:
    """'3 o-word, 2 CYCLE832; 4 not planned' from the opaque lines and the warnings."""
    lines = text.split("\n")
    kinds = collections.Counter(
        "o-word" if OWORD.match(lines[line - 1] if line <= len(lines) else "") else why
        for line, why in info.opaque)
    parts = [f"{n} {kind}" for kind, n in kinds.most_common(4)]
    if len(kinds) > 4:
        parts.append(f"{sum(kinds.values()) - sum(n for _, n in kinds.most_common(4))} other")
    stretches = 0
    for w in info.warnings:
        more = MORE_STRETCHES.search(w)
        stretches += int(more.group(1)) if more else ("not planned" in w)
    out = ", ".join(parts)
    if stretches:
        out += ("; " if out else "") + f"{stretches} not planned"
    return out


def rewrite(text: str, rel: str, info, row: Row) -> tuple[str, tuple]:
    """Cutting blocks of the mesh-free rewrite (a second rewrite per tool with no known
    diameter), and the texts; the operations and the untouched check go into ``row``."""
    try:
        results = [rewrite_text(text, JOB, rel)]
    except NothingToPlan as exc:
        results, row.operations = [], exc.operations
        if "no diameter known" not in exc.message:
            return "0", ()
        for tool in info.tools_used:
            try:
                results.append(rewrite_text(text, replace(JOB, cutter=FALLBACK, tool=tool), rel))
            except NothingToPlan as exc_tool:  # why it is left with a diameter given
                row.operations = exc_tool.operations or row.operations
            except UsageError as exc_tool:
                if "no feed moves with tool" not in exc_tool.message:
                    raise
    if not results:
        return "0", ()
    row.operations = tuple(o for r in results for o in r.operations)
    row.untouched = all(untouched(text, r) for r in results)
    total = sum(r.summary.cutting_blocks for r in results)
    suffix = f" ({len(results)} rewrites, --diameter 3 per tool)" if len(results) > 1 else ""
    return f"{total}{suffix}", tuple(r.text for r in results)


def untouched(text: str, result) -> bool:
    """Every line outside the rewrite's planned operations is byte for byte the input's."""
    a = text.splitlines(keepends=True)
    b = [line for line in result.text.splitlines(keepends=True)
         if not STAMP.match(line)]
    if len(a) != len(b):
        return False
    editable = result.scope.editable
    return all(a[i] == b[i] for i in range(len(a)) if not editable[i])


def examine(path: Path, rel: str) -> Row:
    row = Row(rel)
    text = path.read_bytes().decode("latin-1")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            row.dialect = detect(text).name
            try:
                info = inspect_text(text, rel)
            except NcoptError as exc:
                row.status, row.error = "refused", located_message(exc)
                row.located = str(exc).startswith(f"{rel}:") and exc.line is not None
                return row
            row.blocks, row.moves = info.blocks, info.moves
            row.left_alone = left_alone(text, info)
            try:
                row.cutting, row.rewrites = rewrite(text, rel, info, row)
                if row.cutting == "0":
                    row.status = "nothing"
            except NcoptError as exc:
                row.status, row.error = "rewrite-refused", located_message(exc)
                row.located = str(exc).startswith(f"{rel}:")
        except Exception as exc:  # noqa: BLE001 - reported, and counted as a crash
            row.status = "crashed"
            frame = traceback.extract_tb(exc.__traceback__)[-1]
            row.error = shorten(f"CRASH {type(exc).__name__}: {exc} "
                                f"({Path(frame.filename).name}:{frame.lineno})")
        finally:
            row.numpy_warnings = tuple(sorted({
                f"{w.category.__name__}: {w.message} ({Path(w.filename).name}:{w.lineno})"
                for w in caught}))
    if row.numpy_warnings:
        row.left_alone += ("; " if row.left_alone else "") + "WARNING " + \
            "; ".join(row.numpy_warnings)
    return row


def judge_row(row: Row, path: Path) -> None:
    """What rs274 says of the original and of ncopt's rewrites."""
    import tempfile

    from judge import canon  # tests/judge.py, on the path since main()

    text = path.read_bytes().decode("latin-1")
    with tempfile.TemporaryDirectory(prefix="corpus_judge") as tmp:
        def run(t: str, name: str):
            (Path(tmp) / name).mkdir()
            return canon(t, Path(tmp) / name)
        try:
            original = run(text, "original")
        except RuntimeError as exc:
            row.rs274_accepts = False
            row.rs274 = "rejects: " + rs274_message(exc)
            return
        row.rs274_accepts = True
        notes = []
        for k, out in enumerate(row.rewrites):
            try:
                again = run(out, f"rewrite{k}")
            except RuntimeError as exc:
                notes.append("REWRITE REJECTED: " + rs274_message(exc))
                continue
            if again.motion != original.motion:
                notes.append("REWRITE MOVES DIFFERENTLY")
        row.rs274 = "accepts" + ("; " + "; ".join(notes) if notes else
                                 ", rewrite same motion" if row.rewrites else "")


def rs274_message(exc: Exception, n: int = 70) -> str:
    """rs274's complaint without judge.py's prefix, rs274's 'executing' and temp paths."""
    text = str(exc).split("rejected the program:", 1)[-1].strip()
    text = re.sub(r"^executing\s*", "", text)
    return shorten(re.sub(r"/\S*/prog\.ngc", "prog.ngc", text), n)


def markdown(cells: list[str]) -> str:
    return "| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--corpus", type=Path, default=CORPUS)
    ap.add_argument("--judge", action="store_true", help="add rs274's verdicts (LinuxCNC)")
    args = ap.parse_args(argv)
    if args.judge:
        sys.path.insert(0, str(ROOT / "tests"))
        from judge import RS274
        if RS274 is None:
            ap.error("--judge needs rs274 (Debian package linuxcnc-uspace)")
    t0 = time.perf_counter()
    files = programs(args.corpus)
    head = ["file", "dialect", "blocks", "moves", "cutting blocks planned", "left alone",
            "error"] + (["rs274"] if args.judge else [])
    print(markdown(head))
    print("|" + "---|" * len(head))
    rows = []
    for path in files:
        row = examine(path, str(path.relative_to(args.corpus)))
        if args.judge:
            judge_row(row, path)
        rows.append(row)
        print(markdown(row.cells(args.judge)), flush=True)

    count = collections.Counter(r.status for r in rows)
    refused = [r for r in rows if r.status == "refused"]
    crashed = [r for r in rows if r.status == "crashed" or not r.located]
    bad = [r for r in rows if "/bad/" in f"/{r.file}"]
    print()
    print(f"programs read: {len(rows)}; planned: {count['planned']}; nothing to plan: "
          f"{count['nothing']}; refused with a located message: "
          f"{sum(r.located for r in refused)} (of {len(refused)} refused); rewrite refused "
          f"(planning/usage): {count['rewrite-refused']}; crashed: {len(crashed)}")
    print(f"LinuxCNC interp-tests bad/ (must be rejected): {len(bad)}, refused by ncopt: "
          f"{sum(r.status == 'refused' for r in bad)}")
    flagged = [r for r in rows if r.numpy_warnings]
    if flagged:
        print(f"numpy warnings during the rewrite: {', '.join(r.file for r in flagged)}")
    if args.judge:
        accepted = [r for r in rows if r.rs274_accepts]
        print(f"rs274 accepts {len(accepted)} of {len(rows)} originals; of those ncopt refuses "
              f"to read {sum(r.status == 'refused' for r in accepted)}: "
              + (", ".join(r.file for r in accepted if r.status == "refused") or "none")
              + f"; refuses to rewrite {sum(r.status == 'rewrite-refused' for r in accepted)}: "
              + (", ".join(r.file for r in accepted if r.status == "rewrite-refused") or "none"))
        broken = [r for r in rows if "REWRITE" in r.rs274]
        print(f"rewrites rs274 rejects or moves differently: {len(broken)}"
              + (": " + ", ".join(r.file for r in broken) if broken else ""))
    print_operations(rows)
    print(f"({time.perf_counter() - t0:.0f} s)", file=sys.stderr)
    touched = [r for r in rows if not r.untouched]
    return 1 if crashed or touched else 0


def print_operations(rows: list[Row]) -> None:
    """Every operation ncopt found, planned or left and why; the untouched-lines check."""
    print()
    print(markdown(["file", "operation", "tool", "lines", "kind", "planned", "why"]))
    print("|" + "---|" * 7)
    kinds: collections.Counter = collections.Counter()
    for r in rows:
        for o in r.operations:
            if o.kind == "no cut":
                continue
            tool = f"T{o.tool}" if o.tool >= 0 else "-"
            print(markdown([r.file, o.name, tool, f"{o.first_line + 1}-{o.last_line + 1}",
                            o.kind, "planned" if o.planned else "left", shorten(o.reason, 110)]))
            kinds[("planned" if o.planned else "left", o.kind)] += 1
    print()
    planned = sum(n for (p, _), n in kinds.items() if p == "planned")
    left = sum(n for (p, _), n in kinds.items() if p == "left")
    print(f"operations: {planned} planned, {left} left; by kind: "
          + "; ".join(f"{k} {p} {n}" for (p, k), n in sorted(kinds.items())))
    touched = [r.file for r in rows if not r.untouched]
    print("lines outside the planned operations byte-identical in every rewrite: "
          + ("yes" if not touched else "NO: " + ", ".join(touched)))


if __name__ == "__main__":
    sys.exit(main())
