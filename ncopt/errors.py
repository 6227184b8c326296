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

    operations: tuple = ()


class UsageError(NcoptError):
    """Options that contradict each other or are missing."""


class VerificationError(NcoptError):
    """A rewrite failed its own safety checks: nothing is written."""


class FileError(NcoptError):
    """A file (or stdin, stdout, a folder) cannot be read or written; names the path."""
