"""One exception tree for everything ncopt reports to a user.

Messages read ``file:line:col: what is wrong; what to do``.
"""

from __future__ import annotations


class NcoptError(Exception):
    """Root of every error ncopt raises on purpose."""

    def __init__(self, message: str, path: str | None = None, line: int | None = None,
                 column: int | None = None, context: str = "") -> None:
        super().__init__(message)
        self.message = message
        self.path = path
        self.line = line  # 1-based
        self.column = column  # 1-based
        self.context = context

    @property
    def location(self) -> str:
        parts = [self.path or "<input>"]
        if self.line is not None:
            parts.append(str(self.line))
            if self.column is not None:
                parts.append(str(self.column))
        return ":".join(parts)

    def __str__(self) -> str:
        if self.path is None and self.line is None:  # about options, not a file
            return self.message
        return f"{self.location}: {self.message}"


class NcParseError(NcoptError):
    """A line of the program is malformed; carries a caret context."""

    def __str__(self) -> str:
        head = super().__str__()
        return f"{head}\n{self.context}" if self.context else head


class MeshError(NcoptError):
    """The part mesh cannot be read or used."""


class PlanningError(NcoptError):
    """The cutting data or the machine limits make planning impossible."""


class NothingToPlan(PlanningError):
    """No move of the program is one ncopt can plan (no ball/bull-nose cut, no known position).

    ``operations``: the program's operations, each with why it is left (empty where the
    program was not read that far)."""

    operations: tuple[object, ...] = ()  # the planning stage's operation records


class UsageError(NcoptError):
    """Options that contradict each other or are missing."""


class ValueRangeError(UsageError, ValueError):
    """A value outside the range it may take (a machine's, a cutter's, the cutting data's,
    an option's); names the value and the range.  A ValueError too, as Python's own checks
    of a value are, for code that builds ncopt's objects itself."""


def from_program(exc: ValueRangeError, path: str | None) -> "PlanningError":
    """A value out of range met while a program is planned (the options were checked
    before): it comes from the program, its S and F words (``F0.0001`` gives fz 0) or its
    ncopt stamp.  The error to report instead, located at the program (exit 5)."""
    return PlanningError(f"{exc.message}, from the program's own S and F words or its ncopt "
                         "stamp: check them, or give --vc and --fz", path)


class VerificationError(NcoptError):
    """A rewrite failed its own safety checks: nothing is written."""


class FileError(NcoptError):
    """A file (or stdin, stdout, a folder) cannot be read or written; names the path."""


class OutOfMemory(NcoptError):
    """The machine gave the run less memory than the program needs: nothing is written."""


def out_of_memory(what: str | None = None) -> OutOfMemory:
    """The error a run ends with when an allocation fails (``what``: the file, if known)."""
    return OutOfMemory("not enough memory to finish (the operating system refused an "
                       "allocation); nothing was written: close other programs, raise the "
                       "memory limit, or split the program into smaller files", path=what)
