"""stdin, stdout, stderr and signals at the edge of the command line.

A write to stdout that fails (a closed pipe: ``ncopt rewrite x | head -1``; a full disk;
stdout closed with ``>&-``) becomes a FileError naming ``<stdout>``, and stdout is then
pointed at the null device so that the interpreter's last flush cannot print a
traceback.  stderr is rich's console, made on first use: importing rich costs startup
time that ``ncopt --help`` should not pay.  On an interactive stderr, long commands show
the stage they are in (:func:`stages`).

A listing (``ncopt inspect``, ``ncopt profiles``) whose reader stops early (``| head -1``)
ends quietly with exit 0 (:func:`listing`): the reader has seen what it wanted.  A program
written to a pipe that closes is incomplete: that stays a FileError (exit 7).

Colours follow ``--color``: ``auto`` (rich decides: a terminal, and no ``NO_COLOR`` in
the environment), ``always`` or ``never``.  ``warning:`` prefixes are yellow and an
error's first line red (:func:`styled`).
"""

from __future__ import annotations

import errno
import os
import signal
import sys
import threading
from contextlib import contextmanager
from typing import Callable, Iterator

import typer

from ncopt.runtime.errors import FileError, NcoptError, UsageError, out_of_memory


_stderr_console = None
COLOR_MODES = ("auto", "always", "never")
_color = "auto"


def set_color(mode: str) -> None:
    """``--color``: how the consoles made from now on colour (see the module's doc)."""
    global _color, _stderr_console
    if mode not in COLOR_MODES:
        raise UsageError(f"--color must be one of {', '.join(COLOR_MODES)}, not {mode!r}")
    _color = mode
    _stderr_console = None  # the next use makes it with this mode


def color_options() -> dict:
    """rich Console arguments for the ``--color`` mode (none for auto: rich's own rules,
    NO_COLOR included).  ``always`` wins over NO_COLOR, as an explicit option should."""
    if _color == "always":
        return {"color_system": "standard", "no_color": False}
    if _color == "never":
        return {"color_system": None}
    return {}


def stderr_console():
    """rich's console on stderr, made on first use (the same one every time).

    rich's own objects (a Progress, a Live display) take this one: they use the console
    as a context manager and set its live display, which a proxy cannot stand in for."""
    global _stderr_console
    if _stderr_console is None:
        from rich.console import Console
        _stderr_console = Console(stderr=True, highlight=False, soft_wrap=True,
                                  **color_options())
    return _stderr_console


class _LazyConsole:
    """The stderr console for printing, made on first use (see :func:`stderr_console`)."""

    def __getattr__(self, name):
        return getattr(stderr_console(), name)


err = _LazyConsole()


@contextmanager
def stages(quiet: bool = False) -> Iterator[Callable[[str], None]]:
    """A one-line display on an interactive stderr of what a long command is doing: a
    spinner, the stage (``show("planning")``) and the time spent, gone when it ends.
    Elsewhere (a pipe, a file, ``-q``) ``show`` does nothing, so logs stay clean."""
    console = stderr_console()
    if quiet or not console.is_terminal:
        yield lambda stage: None
        return
    from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

    with Progress(SpinnerColumn(), TextColumn("{task.description}"), TimeElapsedColumn(),
                  console=console, transient=True) as progress:
        task = progress.add_task("ncopt: starting", total=None)
        yield lambda stage: progress.update(task, description=f"ncopt: {stage}")


def stdout_console(**kwargs):
    """A rich console (on stdout unless ``file`` says otherwise) whose closed pipe raises
    BrokenPipeError, to be reported like any other write to stdout, instead of rich's
    quiet exit 1."""
    from rich.console import Console

    class _Console(Console):
        def on_broken_pipe(self) -> None:
            self.quiet = True
            raise BrokenPipeError(errno.EPIPE, os.strerror(errno.EPIPE))

    return _Console(**{**color_options(), **kwargs})


def count(n: int, noun: str, plural: str | None = None) -> str:
    """``1 block``, ``2 blocks``; ``plural`` where an added s is wrong (tooth, teeth)."""
    return f"{n} {noun if n == 1 else plural or noun + 's'}"


PREFIX_STYLES = {"warning:": "bold yellow", "error:": "bold red"}


def styled(text: str, error: bool = False):
    """``text`` as rich Text: a ``warning:`` or ``error:`` prefix (after any indent)
    coloured; with ``error``, its whole first line in red."""
    from rich.text import Text

    out = Text(text)
    if error:
        out.stylize("bold red", 0, len(text.split("\n", 1)[0]))
        return out
    body = text.lstrip(" ")
    for prefix, style in PREFIX_STYLES.items():
        if body.startswith(prefix):
            start = len(text) - len(body)
            out.stylize(style, start, start + len(prefix))
    return out


def say(text: str, error: bool = False) -> None:
    """One line on stderr, a ``warning:`` prefix coloured (``error``: an error's lines);
    a closed or broken stderr loses it rather than raising."""
    try:
        err.print(styled(text, error))
    except OSError:
        pass


def require_stdout(instead: str = "") -> None:
    """Raise FileError (exit 7) when stdout is closed (``>&-``): Python then drops what
    print() writes without a word, and the command would end with exit 0 and no output.
    ``instead``: what the user can do (``use -q``)."""
    if sys.stdout is None:
        raise FileError("standard output is closed; nothing could be shown"
                        + (f"; {instead}" if instead else ""), "<stdout>")


@contextmanager
def listing() -> Iterator[None]:
    """Run a listing's output: a reader that closes the pipe early ends it quietly (the
    caller then exits 0).  Any other write fault (a full disk) is reported as usual, and
    so is a closed stdout (:func:`require_stdout`)."""
    require_stdout()
    try:
        yield
        if sys.stdout is not None:
            sys.stdout.flush()
    except BrokenPipeError:
        silence_stdout()


def read_programs(names: list[str]) -> list[bytes]:
    """The programs' bytes; ``-`` is stdin, for one of them at most."""
    from ncopt.runtime.fileio import read_input

    if names.count("-") > 1:
        raise UsageError("only one program can come from stdin (-)")
    return [read_input(name) for name in names]


def write_stdout(data: bytes) -> None:
    """A program's bytes on stdout, as they are."""
    if sys.stdout is None:
        raise FileError("standard output is closed; give -o FILE", "<stdout>")
    try:
        sys.stdout.flush()
        out, rest = sys.stdout.buffer, memoryview(data)
        while rest:  # a write cut short by the reader's going away says so only once
            written = out.write(rest)
            if not written:
                raise OSError(errno.EIO, "nothing could be written")
            rest = rest[written:]
        out.flush()
    except OSError as exc:
        raise stdout_fault(exc) from None


def flush_stdout() -> None:
    """Flush what print() left in stdout's buffer; a failure is a FileError."""
    if sys.stdout is None:
        return
    try:
        sys.stdout.flush()
    except OSError as exc:
        raise stdout_fault(exc) from None


def stdout_fault(exc: OSError) -> FileError:
    """A write to stdout failed: the error to report; nothing more goes there."""
    from ncopt.runtime.fileio import hint

    silence_stdout()
    return FileError(f"cannot write the output: {exc.strerror}; {hint(exc)}", "<stdout>")


def silence_stdout() -> None:
    """Point stdout at the null device, so the interpreter's last flush cannot fail."""
    try:
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, sys.stdout.fileno())
        os.close(null)
    except (OSError, ValueError, AttributeError):
        pass


@contextmanager
def command_faults(code_of: Callable[[NcoptError], int], interrupted: int) -> Iterator[None]:
    """Run a command: an ncopt error, an interrupt (Ctrl-C or SIGTERM) or a failed write to
    stdout becomes one line on stderr and the exit code ``code_of(error)`` or
    ``interrupted``."""
    previous = on_sigterm(interrupt)
    try:
        try:
            yield
        except typer.Exit:  # an exit code of the command's own (diff, batch)
            flush_stdout()
            raise
        flush_stdout()  # what print() left in the buffer fails here, not at interpreter exit
    except NcoptError as exc:
        _fail(exc, code_of)
    except MemoryError:  # a program larger than the memory this machine gives the run
        _fail(out_of_memory(), code_of)
    except KeyboardInterrupt:
        say("ncopt: interrupted")
        raise typer.Exit(interrupted) from None
    except OSError as exc:  # not wrapped on its way: a write to stdout
        _fail(stdout_fault(exc) if exc.filename is None else
              FileError(f"{exc.strerror}; check the path", str(exc.filename)), code_of)
    finally:
        on_sigterm(previous)


def _fail(exc: NcoptError, code_of: Callable[[NcoptError], int]) -> None:
    say(str(exc), error=True)
    raise typer.Exit(int(code_of(exc)))


def interrupt(signum, frame):
    """A signal handler: SIGTERM ends a command as Ctrl-C does."""
    raise KeyboardInterrupt


def on_sigterm(handler):
    """Install a SIGTERM handler (main thread only); the handler it replaced."""
    if handler is None or threading.current_thread() is not threading.main_thread():
        return None
    return signal.signal(signal.SIGTERM, handler)
