"""Original vs rewritten program: side by side on a terminal, unified diff otherwise.

Streams: rows are rendered as they are found, unchanged runs are folded into
one line with their count, so a 1M-line program never has its rendering
built in memory.  On a terminal the view goes through a pager as git's does:
``$NCOPT_PAGER``, else ``$PAGER``, else ``less`` (with ``LESS=FRX`` unless LESS is
set: colours pass, a short diff stays on the screen); an empty pager or ``cat``
means none.  A reader that quits early (``q`` in less, ``| head``) ends the view
quietly.
"""

from __future__ import annotations

import difflib
import io
import os
import re
import sys
from contextlib import contextmanager
from itertools import zip_longest
from typing import TYPE_CHECKING, Iterator, NamedTuple, TextIO

from ncopt.reading.stampline import STAMP_LINE

if TYPE_CHECKING:  # rich is imported where a view is drawn: a unified diff needs none of it
    from rich.console import Console

_TOKEN = re.compile(r"\s+|\([^)]*\)|;.*|[A-Za-z]\s*[-+]?[\d.]+|.")
CONTEXT = 1


class DiffTotals(NamedTuple):
    """What changed between two programs with the same lines (a NamedTuple: dataclasses
    imports inspect, more than a quick diff costs)."""

    lines: int
    changed: int
    s_changed: int
    f_changed: int


def changed_words(a: str, b: str) -> tuple[list[tuple[str, bool]], list[tuple[str, bool]]]:
    """Tokens of two lines, each flagged when it differs from the other line."""
    ta, tb = _TOKEN.findall(a), _TOKEN.findall(b)
    sm = difflib.SequenceMatcher(a=ta, b=tb, autojunk=False)
    fa = [(t, True) for t in ta]
    fb = [(t, True) for t in tb]
    for block in sm.get_matching_blocks():
        for k in range(block.size):
            fa[block.a + k] = (ta[block.a + k], False)
            fb[block.b + k] = (tb[block.b + k], False)
    return fa, fb


def totals(a_lines: list[str], b_lines: list[str]) -> DiffTotals:
    """Changed lines counted on the same pairing the view shows (a stamp line is one line);
    a changed line counts for S (F) where its S (F) words differ."""
    changed = s = f = 0
    for row in _rows(a_lines, b_lines):
        if row[0] != "change":
            continue
        changed += 1
        sa, fa = _sf_words(row[2])
        sb, fb = _sf_words(row[4])
        s += sa != sb
        f += fa != fb
    return DiffTotals(max(len(a_lines), len(b_lines)), changed, s, f)


def _sf_words(line: str) -> tuple[list[str], list[str]]:
    """The S words and the F words of a line, as written (comments aside)."""
    words = [t.replace(" ", "").replace("\t", "").upper() for t in _TOKEN.findall(line)
             if len(t) > 1 and t[0] in "SsFf"]
    return [w for w in words if w[0] == "S"], [w for w in words if w[0] == "F"]


_STAMP = STAMP_LINE  # every line of a stamp, of any ncopt version


def _rows(a_lines: list[str], b_lines: list[str]) -> Iterator[tuple]:
    """(kind, number_a, text_a, number_b, text_b) rows; kind 'fold' carries a count.

    A rewrite keeps every line and adds its stamp comment at the top: the stamp
    lines are shown first and the rest is paired line by line (fast on 1M lines);
    other pairs of programs go through difflib.
    """
    a_stamps = [i for i, t in enumerate(a_lines[:50]) if _STAMP.match(t)]
    b_stamps = [i for i, t in enumerate(b_lines[:50]) if _STAMP.match(t)]
    if len(a_lines) - len(a_stamps) == len(b_lines) - len(b_stamps) and (a_stamps or b_stamps):
        for i in b_stamps:
            if b_lines[i] not in [a_lines[j] for j in a_stamps]:
                yield ("change", None, "", i + 1, b_lines[i])
        a_rest = [t for i, t in enumerate(a_lines) if i not in set(a_stamps)]
        b_rest = [t for i, t in enumerate(b_lines) if i not in set(b_stamps)]
        for row in _rows(a_rest, b_rest):
            if row[0] == "fold":
                yield row
            else:  # back to the files' own line numbers
                yield (row[0], _renumber(row[1], a_stamps), row[2],
                       _renumber(row[3], b_stamps), row[4])
        return
    if len(a_lines) != len(b_lines):
        yield from _rows_difflib(a_lines, b_lines)
        return
    n = len(a_lines)
    diff = [i for i in range(n) if a_lines[i] != b_lines[i]]
    shown = 0
    for k, i in enumerate(diff):
        lo = max(i - CONTEXT, shown)
        if lo > shown:
            yield ("fold", lo - shown)
        for j in range(lo, i):
            yield ("same", j + 1, a_lines[j], j + 1, b_lines[j])
        yield ("change", i + 1, a_lines[i], i + 1, b_lines[i])
        nxt = diff[k + 1] if k + 1 < len(diff) else n
        hi = min(i + 1 + CONTEXT, nxt)
        for j in range(i + 1, hi):
            yield ("same", j + 1, a_lines[j], j + 1, b_lines[j])
        shown = hi
    if shown < n:
        yield ("fold", n - shown)


def _renumber(number: int | None, skipped: list[int]) -> int | None:
    """A 1-based line number counted without the skipped lines, in the file's numbering."""
    if number is None:
        return None
    n = number
    for s in sorted(skipped):
        if s < n:
            n += 1
    return n


def _rows_difflib(a_lines, b_lines) -> Iterator[tuple]:
    sm = difflib.SequenceMatcher(a=a_lines, b=b_lines, autojunk=False)
    for tag, i1, i2, j1, j2 in sm.get_opcodes():
        if tag == "equal":
            yield ("fold", i2 - i1)
            continue
        for a, b in zip_longest(range(i1, i2), range(j1, j2)):
            yield ("change", None if a is None else a + 1, "" if a is None else a_lines[a],
                   None if b is None else b + 1, "" if b is None else b_lines[b])


def render_side_by_side(a_name: str, b_name: str, a_lines, b_lines, console: "Console",
                        header: str = "") -> DiffTotals:
    """Two columns with line numbers; changed words highlighted; unchanged runs folded."""
    from rich.text import Text

    t = totals(a_lines, b_lines)
    console.print(Text(f"{a_name} -> {b_name}: {t.changed} of {t.lines} "
                       f"{'line' if t.lines == 1 else 'lines'} changed "
                       f"(S in {t.s_changed}, F in {t.f_changed}){header}", style="bold"))
    width = max((console.width - 14) // 2, 20)
    for row in _rows(a_lines, b_lines):
        if row[0] == "fold":
            lines = "line" if row[1] == 1 else "lines"
            console.print(Text(f"  ··· {row[1]} unchanged {lines} ···", style="dim"))
            continue
        kind, na, ta, nb, tb = row
        left, right = Text(no_wrap=True, overflow="ellipsis"), Text(no_wrap=True, overflow="ellipsis")
        if kind == "change":
            fa, fb = changed_words(ta, tb)
            for tok, diff in fa:
                left.append(tok, style="bold red" if diff else None)
            for tok, diff in fb:
                right.append(tok, style="bold green" if diff else None)
        else:
            left.append(ta, style="dim")
            right.append(tb, style="dim")
        left.truncate(width, pad=True)
        right.truncate(width, pad=True)
        row_text = Text()  # no base style: the line number's colour must not run on
        row_text.append(f"{na or '':>6} ", style="cyan")
        row_text.append_text(left)
        row_text.append(" │ " if kind == "same" else " ┃ ", style="yellow" if kind == "change" else "dim")
        row_text.append_text(right)
        console.print(row_text, no_wrap=True, overflow="ellipsis")
    return t


def write_unified(a_name: str, b_name: str, a_lines, b_lines, out: TextIO,
                  same_lines_note: bool = False) -> None:
    """A plain unified diff (what patch and review tools read).  A rewrite and its original
    (the same lines but the stamp's) are paired line by line, as the side-by-side view
    pairs them: no difflib over the whole program (150k lines: 7 s against 0.2 s).
    ``same_lines_note``: the files are known to differ; where their lines do not (line
    ends, the last newline), one line says so."""
    opcodes = _aligned_opcodes(a_lines, b_lines)
    if opcodes is None:
        lines = difflib.unified_diff(a_lines, b_lines, a_name, b_name, lineterm="", n=CONTEXT)
    else:
        lines = _unified(a_name, b_name, a_lines, b_lines, opcodes, CONTEXT)
    text = "".join(line + "\n" for line in lines)
    if not text and same_lines_note:
        text = f"Files {a_name} and {b_name} differ only in their line ends\n"
    out.write(text)


def _kind(path: str) -> str:
    """What a path is, in diff's words: ``regular file``, ``directory``, ``fifo``, ..."""
    import stat

    try:
        mode = os.stat(path).st_mode
    except OSError:  # a link to nothing
        return "link to nothing"
    for test, name in ((stat.S_ISREG, "regular file"), (stat.S_ISDIR, "directory"),
                       (stat.S_ISFIFO, "fifo"), (stat.S_ISSOCK, "socket"),
                       (stat.S_ISCHR, "character special file"),
                       (stat.S_ISBLK, "block special file")):
        if test(mode):
            return name
    return "special file"


def folder_pairs(a_dir: str, b_dir: str) -> Iterator[tuple[str, str | None, str | None]]:
    """The entries of two folders paired by their path below each, as ``diff -r`` pairs
    them, sorted: (that path, the entry in ``a_dir`` or None, the one in ``b_dir`` or
    None).  Folders linked in are followed, but for a link to a folder it lies in (a loop);
    a folder of one side alone is one entry, not its files."""
    def entries(root: str) -> dict[str, str]:
        found = {}
        for folder, subfolders, names in os.walk(root, followlinks=True):
            here = os.path.realpath(folder)
            keep = []
            for name in sorted(subfolders):
                path = os.path.join(folder, name)
                found[os.path.relpath(path, root)] = path
                real = os.path.realpath(path)
                if not (here == real or here.startswith(real.rstrip(os.sep) + os.sep)):
                    keep.append(name)
            subfolders[:] = keep
            for name in names:
                path = os.path.join(folder, name)
                found[os.path.relpath(path, root)] = path
        return found

    a, b = entries(a_dir), entries(b_dir)
    alone: list[str] = []  # folders of one side only: what lies below them is not listed
    for rel in sorted(a.keys() | b.keys()):
        if any(rel.startswith(f + os.sep) for f in alone):
            continue
        pa, pb = a.get(rel), b.get(rel)
        if (pa is None or pb is None) and os.path.isdir(pa or pb):
            alone.append(rel)
        yield rel, pa, pb


def write_folders(a_dir: str, b_dir: str, out: TextIO, quiet: bool = False,
                  read=None) -> bool:
    """``diff -ru`` of two folders (a batch's input and its output): a unified diff of
    each pair of programs that differ, ``Only in FOLDER: NAME`` for an entry of one side
    alone, and as diff says them, binary files that differ and entries of other kinds
    (a file against a folder, fifos: never opened).  True when anything differs;
    ``quiet``: print nothing; ``read``: a file's bytes (the command line's reader, which
    names a file it cannot read), else a plain open."""
    read = read or _read_bytes
    differ = False
    say = (lambda line: None) if quiet else (lambda line: out.write(line + "\n"))  # noqa: E731
    for _, a_path, b_path in folder_pairs(a_dir, b_dir):
        if a_path is None or b_path is None:
            differ = True
            alone = a_path or b_path
            say(f"Only in {os.path.dirname(alone)}: {os.path.basename(alone)}")
            continue
        kinds = _kind(a_path), _kind(b_path)
        if kinds == ("directory", "directory"):
            continue
        if kinds != ("regular file", "regular file"):
            differ = True
            say(f"File {a_path} is a {kinds[0]} while file {b_path} is a {kinds[1]}")
            continue
        a, b = read(a_path), read(b_path)
        if a == b:
            continue
        differ = True
        if b"\0" in a or b"\0" in b:
            say(f"Binary files {a_path} and {b_path} differ")
        elif not quiet:
            write_unified(a_path, b_path, a.decode("latin-1").splitlines(),
                          b.decode("latin-1").splitlines(), out, same_lines_note=True)
    return differ


def _read_bytes(path: str) -> bytes:
    with open(path, "rb") as f:
        return f.read()


def _aligned_opcodes(a_lines: list[str], b_lines: list[str]) -> list | None:
    """difflib's opcodes for a rewrite and its original, or another rewrite of it: the
    lines outside the stamps paired one for one; None for any other pair of programs."""
    a_stamps = {i for i, t in enumerate(a_lines[:50]) if _STAMP.match(t)}
    b_stamps = {i for i, t in enumerate(b_lines[:50]) if _STAMP.match(t)}
    if len(a_lines) - len(a_stamps) != len(b_lines) - len(b_stamps):
        return None
    ops: list[list] = []

    def add(tag: str, i: int, j: int, di: int, dj: int) -> None:
        if ops and ops[-1][0] == tag and ops[-1][2] == i and ops[-1][4] == j:
            ops[-1][2] += di
            ops[-1][4] += dj
        else:
            ops.append([tag, i, i + di, j, j + dj])

    i = j = 0
    na, nb = len(a_lines), len(b_lines)
    # the stamps are near the top: line by line up to the last of them, then the rest of
    # both programs is aligned at a fixed offset, and only its differing lines are visited
    top = max(max(a_stamps, default=-1), max(b_stamps, default=-1)) + 1
    while (i < na or j < nb) and (i < top or j < top):
        if i in a_stamps and j in b_stamps and a_lines[i] == b_lines[j]:
            add("equal", i, j, 1, 1)
        elif i in a_stamps:
            add("delete", i, j, 1, 0)
            j -= 1
        elif j in b_stamps:
            add("insert", i, j, 0, 1)
            i -= 1
        else:
            add("equal" if a_lines[i] == b_lines[j] else "replace", i, j, 1, 1)
        i += 1
        j += 1
    rest = na - i
    differ = [k for k, (x, y) in enumerate(zip(a_lines[i:], b_lines[j:])) if x != y]
    done = 0
    for first, last in _runs(differ):
        if first > done:
            add("equal", i + done, j + done, first - done, first - done)
        add("replace", i + first, j + first, last - first, last - first)
        done = last
    if rest > done:
        add("equal", i + done, j + done, rest - done, rest - done)
    return [tuple(op) for op in _merged(ops)]


def _runs(sorted_ints: list[int]):
    """(first, last + 1) of each run of consecutive numbers."""
    if not sorted_ints:
        return
    first = prev = sorted_ints[0]
    for k in sorted_ints[1:]:
        if k != prev + 1:
            yield first, prev + 1
            first = k
        prev = k
    yield first, prev + 1


def _merged(ops: list[list]) -> list[list]:
    """Adjacent delete, insert and replace runs as difflib would give them: one replace."""
    out: list[list] = []
    for op in ops:
        if out and op[0] != "equal" and out[-1][0] != "equal":
            last = out[-1]
            out[-1] = ["replace", last[1], op[2], last[3], op[4]]
        else:
            out.append(op)
    return out


def _unified(a_name, b_name, a_lines, b_lines, opcodes, n: int):
    """difflib.unified_diff's lines, from given opcodes."""
    matcher = difflib.SequenceMatcher(None, "", "")
    matcher.opcodes = list(opcodes)  # get_grouped_opcodes reads them from here
    started = False
    for group in matcher.get_grouped_opcodes(n):
        if not started:
            started = True
            yield f"--- {a_name}"
            yield f"+++ {b_name}"
        first, last = group[0], group[-1]
        yield (f"@@ -{difflib._format_range_unified(first[1], last[2])} "
               f"+{difflib._format_range_unified(first[3], last[4])} @@")
        for tag, i1, i2, j1, j2 in group:
            if tag == "equal":
                if i2 > i1:
                    yield " " + "\n ".join(a_lines[i1:i2])
                continue
            if tag in ("replace", "delete") and i2 > i1:
                yield "-" + "\n-".join(a_lines[i1:i2])
            if tag in ("replace", "insert") and j2 > j1:
                yield "+" + "\n+".join(b_lines[j1:j2])


def show_diff(a_name: str, b_name: str, a_lines, b_lines, plain: bool = False,
              pager: bool = True) -> None:
    """The diff on stdout: side by side (through the pager) on a terminal, else unified."""
    from ncopt.runtime.stdio import silence_stdout, stdout_console

    try:
        if plain or not _maybe_terminal():
            write_unified(a_name, b_name, a_lines, b_lines, sys.stdout, same_lines_note=True)
            sys.stdout.flush()
            return
        out = stdout_console(highlight=False)
        if not out.is_terminal:
            write_unified(a_name, b_name, a_lines, b_lines, sys.stdout, same_lines_note=True)
            sys.stdout.flush()
            return
        with paged(out, enabled=pager) as console:
            render_side_by_side(a_name, b_name, a_lines, b_lines, console)
    except BrokenPipeError:  # the reader has seen enough
        silence_stdout()


def _maybe_terminal() -> bool:
    """Could rich take stdout for a terminal (a tty, or forced by its variables)?  Where
    it could not, the unified diff is written without importing rich at all."""
    try:
        tty = sys.stdout is not None and sys.stdout.isatty()
    except (ValueError, OSError):
        tty = False
    return tty or any(v in os.environ for v in ("FORCE_COLOR", "TTY_COMPATIBLE"))


def pager_command() -> str | None:
    """The pager to use, or None: $NCOPT_PAGER, $PAGER, else less where it exists."""
    for var in ("NCOPT_PAGER", "PAGER"):
        if var in os.environ:
            command = os.environ[var].strip()
            return None if command in ("", "cat") else command
    import shutil  # here: a diff into a pipe never pages (startup time, see ncopt.cli.entry)

    return "less" if shutil.which("less") else None


@contextmanager
def paged(out: "Console", enabled: bool = True) -> Iterator["Console"]:
    """A console that writes into the pager (with out's width and colours), or out itself."""
    command = pager_command() if enabled else None
    if command is None:
        yield out
        return
    import subprocess  # here: a diff into a pipe never pages (startup time)

    env = {**os.environ, "LESS": os.environ.get("LESS", "FRX"), "LV": os.environ.get("LV", "-c")}
    try:
        proc = subprocess.Popen(command, shell=True, stdin=subprocess.PIPE, env=env)
    except OSError:
        yield out
        return
    stream = io.TextIOWrapper(proc.stdin, encoding=out.encoding or "utf-8", errors="replace")
    from ncopt.runtime.stdio import stdout_console

    console = stdout_console(file=stream, force_terminal=True, width=out.width,
                             highlight=False, color_system=out.color_system,
                             no_color=out.no_color)
    try:
        yield console
    except BrokenPipeError:
        pass
    finally:
        try:
            stream.close()
        except BrokenPipeError:
            pass
        proc.wait()
