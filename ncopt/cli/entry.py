"""The ``ncopt`` console entry point.

``ncopt diff ORIGINAL REWRITTEN`` (two programs, or two folders as ``diff -ru`` takes them)
into a pipe or a file (the unified diff review tools read) answers here, before the command line (typer, and pydantic through it: about 0.1 s)
is imported: a diff of two programs should cost about what ``diff -u`` does.  Everything
else, and every case of ``diff`` this does not take (options, stdin, a terminal, a file it
cannot read), goes to :func:`ncopt.cli.app.main`, which reports as every command does.
"""

from __future__ import annotations

import os
import sys

DIFFERENT = 1  # the exit code of diff(1) for files that differ (ncopt.cli.core.DIFFERENT)


def main() -> None:
    code = _quick_diff(sys.argv[1:])
    if code is not None:
        sys.exit(code)
    from ncopt.cli.app import main as command_line

    command_line()


def _quick_diff(argv: list[str]) -> int | None:
    """The exit code of ``diff A B`` written as a unified diff, or None where the command
    line is to take it."""
    if len(argv) != 3 or argv[0] != "diff" or any(a.startswith("-") for a in argv[1:]):
        return None
    from ncopt.report.diffview import _maybe_terminal, write_unified

    names = argv[1:]
    if sys.stdout is None or _maybe_terminal():
        return None
    folders = all(os.path.isdir(n) for n in names)
    if not folders and not all(os.path.isfile(n) for n in names):
        return None
    try:
        a, b = (b"", b"") if folders else (_read(n) for n in names)
    except OSError:
        return None  # the command line names the file and what to do
    if a == b and not folders:
        return 0
    try:
        try:
            if folders:
                from ncopt.report.diffview import folder_pairs, write_folders

                if not all(os.access(p, os.R_OK) for pair in folder_pairs(*names)
                           for p in pair[1:] if p is not None):
                    return None  # a file it cannot read: the command line names it
                same = not write_folders(names[0], names[1], sys.stdout)
                sys.stdout.flush()
                return 0 if same else DIFFERENT
            write_unified(names[0], names[1], a.decode("latin-1").splitlines(),
                          b.decode("latin-1").splitlines(), sys.stdout, same_lines_note=True)
            sys.stdout.flush()
        except BrokenPipeError:  # the reader has seen enough, as for the command line
            from ncopt.runtime.stdio import silence_stdout

            silence_stdout()
        except OSError as exc:  # a full disk under stdout: reported as the command line does
            from ncopt.cli.core import exit_code
            from ncopt.runtime.stdio import say, stdout_fault

            fault = stdout_fault(exc)
            say(str(fault), error=True)
            return int(exit_code(fault))
    except KeyboardInterrupt:
        print("ncopt: interrupted", file=sys.stderr)
        return 130
    return DIFFERENT


def _read(name: str) -> bytes:
    """The bytes of a file (plain open: pathlib costs more to import than the diff takes)."""
    with open(name, "rb") as f:
        return f.read()
