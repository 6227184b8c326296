"""The commands that change nothing: ``ncopt inspect`` (what ncopt reads of a program),
``ncopt diff`` (which blocks a rewrite changed), ``ncopt profiles`` (the machines, tools
and cutting data found; ``profiles init`` writes one) and ``ncopt version``."""

# No `from __future__ import annotations`: typer reads these annotations as objects.
import os
import sys
from typing import Annotated, Optional

import typer

from ncopt import __version__
from ncopt.cli.core import DIFFERENT
from ncopt.cli.options import COLOR, FOR_INSPECTION, OUTPUT, TOOLS_FILE, Given, takes
from ncopt.runtime.errors import FileError, UsageError, ValueRangeError, from_program
from ncopt.runtime.fileio import read_input
from ncopt.runtime.stdio import listing, read_programs, require_stdout, say, write_stdout


@takes(*FOR_INSPECTION, COLOR)
def inspect(
    program: Annotated[str, typer.Argument(help="NC program, or - for stdin.")],
    as_json: Annotated[bool, typer.Option("--json", rich_help_panel=OUTPUT,
                                          help="One JSON object on stdout.")] = False,
    given: Given = None,
) -> None:
    """Show what ncopt understands of a program before it changes anything, and its
    operations as rewrite would split and judge them (the same cutter, cutting-data and
    machine options; nothing is planned, so no spindle is needed)."""
    from ncopt.planning.inspection import inspect_text, render_inspection
    from ncopt.runtime.stdio import listing, stdout_console

    job = given.job(spindle_needed=False)
    [data] = read_programs([program])
    try:
        info = inspect_text(data.decode("latin-1"), program, dialect=job.control,
                            decimal_point=job.decimal_point, kinematics=job.kinematics,
                            max_feed_mm_min=job.machine.max_feed_mm_min, job=job)
    except ValueRangeError as exc:  # the options were checked: the program gave the value
        raise from_program(exc, program) from None
    with listing():  # `| head` ends it quietly
        if as_json:
            import json
            print(json.dumps(info.to_dict(), indent=2))
        else:
            render_inspection(info, stdout_console(highlight=False, soft_wrap=True))


@takes(COLOR)
def diff(
    original: Annotated[str, typer.Argument(help="The original program, or - for stdin.")],
    rewritten: Annotated[str, typer.Argument(
        help="The rewritten program, or - for stdin (two folders: every pair of files, as "
             "diff -ru).")],
    plain: Annotated[bool, typer.Option("--plain", rich_help_panel=OUTPUT,
                                        help="Unified diff even on a terminal.")] = False,
    no_pager: Annotated[bool, typer.Option(
        "--no-pager", rich_help_panel=OUTPUT,
        help="Print on the terminal, not through $PAGER (less -R).")] = False,
    quiet: Annotated[bool, typer.Option(
        "--quiet", "-q", rich_help_panel=OUTPUT,
        help="Print nothing; the exit code says whether the files differ.")] = False,
    given: Given = None,
) -> None:
    """Show which blocks changed: side by side on a terminal (paged), a unified diff otherwise.

    Two folders (a batch's input and its output): a unified diff of each pair of files
    that differ, and the files of one alone, as diff -ru.  Exit code 0 when the files are
    the same, 1 when they differ (as diff does).
    """
    from ncopt.report.diffview import show_diff, write_folders

    if os.path.isdir(original) and os.path.isdir(rewritten):  # as diff -ru: unified
        if quiet:
            differ = write_folders(original, rewritten, sys.stdout, True, read=read_input)
        else:
            differ = True  # a reader that stops early (| head) saw a difference
            with listing():
                differ = write_folders(original, rewritten, sys.stdout, read=read_input)
        if differ:
            raise typer.Exit(DIFFERENT)
        return
    a, b = read_programs([original, rewritten])
    if a == b:
        return
    if not quiet:
        require_stdout("use -q to learn from the exit code alone whether they differ")
        show_diff(original, rewritten, a.decode("latin-1").splitlines(),
                  b.decode("latin-1").splitlines(), plain=plain, pager=not no_pager)
    raise typer.Exit(DIFFERENT)


@takes(TOOLS_FILE, COLOR)
def profiles(ctx: typer.Context, given: Given = None) -> None:
    """List the machine, tool and cutting-data profiles found, and where from
    (profiles init: write a commented profile for a machine)."""
    if ctx.invoked_subcommand is not None:
        return
    from ncopt.planning.profiles import load, render_profiles
    from ncopt.runtime.stdio import listing, stdout_console

    found = load(tools_file=given.tools_file)
    with listing():  # `| head` ends it quietly
        render_profiles(found, stdout_console(highlight=False))


@takes(TOOLS_FILE)
def profiles_init(
    name: Annotated[str, typer.Argument(help="The machine's name; a profile of that name "
                                        "(ncopt profiles) gives its values.")] = "my-machine",
    output: Annotated[Optional[str], typer.Option(
        "-o", "--output", rich_help_panel=OUTPUT, help="The file to write (never one that "
        "exists, e.g. ncopt.toml in the project's folder); - or omitted: stdout.")] = None,
    given: Given = None,
) -> None:
    """Write a commented TOML profile for a machine: every key, what it means, its unit."""
    from ncopt.planning.profiles import load, machine_template

    if not name.strip() or any(ord(c) < 32 for c in name):
        raise UsageError(f"a machine's name is a word such as my-mill, not {name!r}")
    base = load(tools_file=given.tools_file).machines.get(name)
    text = machine_template(name, base).encode("utf-8")
    if output in (None, "-"):
        write_stdout(text)
        return
    try:
        with open(output, "xb") as handle:
            handle.write(text)
    except FileExistsError:
        raise FileError("exists; profiles init never replaces a file: name another, or add "
                        "the machine to it by hand", output) from None
    except OSError as exc:
        raise FileError(f"cannot write the profile: {exc.strerror}; check the path",
                        output) from None
    todo = "" if base is not None else "; give accel_rad_s2 and max_rpm in it"
    say(f"ncopt: machine profile {name} written to {output}{todo}")


def version() -> None:
    """Print the ncopt version."""
    print(__version__)
