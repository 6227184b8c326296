"""What every command of the ``ncopt`` command line shares: its exit codes, the typer
app that runs each command inside :func:`ncopt.runtime.stdio.command_faults`, the help
that groups a command's options into panels, and the root's own flags.

Startup stays light: ``ncopt --help``, ``ncopt COMMAND -h`` and ``ncopt version`` import
neither numpy nor lark nor the api, nor pydantic (which typer loads to convert any option
value that is not a flag); each command imports what it needs in its body.  An ncopt
error, an interrupt (Ctrl-C or SIGTERM) or a failed write to stdout ends a command with
one line on stderr and an exit code of :class:`Exit`, never a traceback.
"""

# No `from __future__ import annotations` here: typer evaluates every string annotation when
# it builds the commands, a third of the time `ncopt --help` took.
import functools
import os
from enum import IntEnum
from typing import Annotated

import typer
from typer.core import TyperCommand, TyperGroup

from ncopt import __version__
from ncopt.runtime.errors import (FileError, MeshError, OutOfMemory, NcoptError, NcParseError,
                                  PlanningError, UsageError, VerificationError)
from ncopt.runtime.stdio import command_faults, say, set_color, write_stdout


class Exit(IntEnum):
    """Exit codes scripts can rely on."""

    OK = 0
    INTERNAL = 1
    USAGE = 2
    PROGRAM = 3  # the NC program is malformed or cannot be interpreted
    MESH = 4
    PLANNING = 5
    VERIFICATION = 6  # the rewrite failed its own checks; nothing written
    IO = 7
    SOME_FAILED = 8  # batch: some files failed, the others were written
    NOTHING_DONE = 9  # batch: no program found, or every file failed
    MEMORY = 10  # not enough memory to finish; nothing written
    INTERRUPTED = 130


DIFFERENT = 1  # ncopt diff: the files differ (as diff(1) says it)
WOULD_CHANGE = 1  # ncopt rewrite --check: the rewrite would change the program (as black)

#: the panels of a command's help, in this order (a command's own panels come first,
#: the help flag's "Options" last)
PANELS = ("Cutter", "Targets", "Machine", "Control", "Part", "Planning", "Output")
OPTIONS = "Options"


def exit_code(exc: NcoptError) -> Exit:
    """The exit code of an ncopt error."""
    for kind, code in ((OutOfMemory, Exit.MEMORY), (FileError, Exit.IO), (UsageError, Exit.USAGE), (MeshError, Exit.MESH),
                       (PlanningError, Exit.PLANNING), (VerificationError, Exit.VERIFICATION),
                       (NcParseError, Exit.PROGRAM)):
        if isinstance(exc, kind):
            return code
    return Exit.PROGRAM


def guarded(fn):
    """``fn`` run inside :func:`ncopt.runtime.stdio.command_faults`, its ``--color`` set."""
    @functools.wraps(fn)
    def run(*args, **kwargs):
        with command_faults(exit_code, Exit.INTERRUPTED):
            set_color(kwargs.get("color", "auto"))  # every run: in-process runs share it
            return fn(*args, **kwargs)
    return run


class PanelCommand(TyperCommand):
    """A command whose help lists its options by panel (each option's
    ``rich_help_panel``), in plain text: ncopt's help does not load rich."""

    def format_options(self, ctx, formatter) -> None:
        arguments, panels = [], {}
        for param in self.get_params(ctx):
            record = param.get_help_record(ctx)
            if record is None:
                continue
            if param.param_type_name == "argument":
                arguments.append(record)
            else:
                panel = getattr(param, "rich_help_panel", None) or OPTIONS
                panels.setdefault(panel, []).append(record)
        width = min(COLUMN_MAX, max((len(first) for rows in (arguments, *panels.values())
                                     for first, _ in rows), default=0))
        if arguments:
            with formatter.section("Arguments"):
                formatter.write_dl(_aligned(arguments, width), col_max=COLUMN_MAX)
        for panel in sorted(panels, key=_panel_rank):
            with formatter.section(panel):
                formatter.write_dl(_aligned(panels[panel], width), col_max=COLUMN_MAX)


COLUMN_MAX = 30  # click's widest first column; a longer entry puts its help below it


def _aligned(rows: list, width: int) -> list:
    """``rows`` whose first column is at least ``width`` wide: every panel's help text
    starts in the same column (rows without a help text are left alone: no trailing
    blanks)."""
    return [(first.ljust(width) if second else first, second) for first, second in rows]


def _panel_rank(panel: str) -> int:
    """A command's own panels first (as they come), then :data:`PANELS`, "Options" last."""
    if panel == OPTIONS:
        return len(PANELS)
    return PANELS.index(panel) if panel in PANELS else -1


class Group(TyperGroup):
    """typer's group, with shell completion served although ncopt declares the completion
    options itself (see InstallCompletion): typer registers its shells only where it adds
    them."""

    def _main_shell_completion(self, ctx_args, prog_name, complete_var=None):
        var = complete_var or f"_{prog_name}_COMPLETE".replace("-", "_").upper()
        if os.environ.get(var):
            from typer.completion import completion_init

            completion_init()
        return super()._main_shell_completion(ctx_args, prog_name, complete_var)


class App(typer.Typer):
    """typer.Typer whose commands all run inside :func:`ncopt.runtime.stdio.command_faults`
    and list their options by panel."""

    def command(self, *args, **kwargs):
        kwargs.setdefault("cls", PanelCommand)
        register = super().command(*args, **kwargs)

        def decorator(fn):
            register(guarded(fn))
            return fn
        return decorator


def print_version(value: bool) -> None:
    """``--version``: print it and end."""
    if value:
        raise typer.Exit(say_version())


def say_version() -> int:
    """Print the version; the exit code (a closed stdout is exit 7 here too)."""
    try:
        write_stdout(f"{__version__}\n".encode())
    except FileError as exc:
        say(str(exc))
        return int(Exit.IO)
    return int(Exit.OK)


def _show_help(ctx: typer.Context, value: bool) -> None:
    if value and not ctx.resilient_parsing:
        typer.echo(ctx.get_help(), color=ctx.color)
        raise typer.Exit()


# The help flag of a group, declared rather than left to click: click's own reaches typer's
# value conversion as None, not a bool, and so imports pydantic before every `COMMAND -h`.
HelpFlag = Annotated[bool, typer.Option(
    "-h", "--help", is_eager=True, expose_value=False, callback=_show_help,
    help="Show this message and exit.")]


def _completion(action: str):
    """typer's --install-completion / --show-completion callback, for a flag of our own."""
    def run(ctx: typer.Context, param: typer.CallbackParam, value: bool) -> None:
        if value and not ctx.resilient_parsing:
            from typer import completion

            completion.completion_init()
            done = completion.install_callback if action == "install" else completion.show_callback
            done(ctx, param, value)
    return run


# typer's own completion options (add_completion) default to None, not False: like click's
# help flag above, they would load pydantic before every command ran or showed its help
InstallCompletion = Annotated[bool, typer.Option(
    "--install-completion", expose_value=False, callback=_completion("install"),
    help="Install completion for the current shell.")]
ShowCompletion = Annotated[bool, typer.Option(
    "--show-completion", expose_value=False, callback=_completion("show"),
    help="Show completion for the current shell, to copy it or customize the installation.")]
VersionFlag = Annotated[bool, typer.Option(
    "--version", is_eager=True, callback=print_version, help="Print the version and exit.")]
