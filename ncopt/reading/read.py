"""A program read as the job's control reads it: the grammar of the dialect the job names
(or the generic one), then the values in the job's decimal-point convention."""

from __future__ import annotations

from ncopt.model import Job, Program
from ncopt.reading.dialect import detect, resolve_decimal_point
from ncopt.reading.parse import parse_text


def read_text(text: str, path: str, job: Job, detected: str | None = None) -> Program:
    """Parse a program as the job's control reads it.

    With a dialect named (``job.control``: the options or a machine profile),
    that dialect's grammar, which refuses other dialects' constructs; else the
    generic grammar.  Values are then read in the job's decimal-point
    convention: a Fanuc program (named or detected) with a value whose meaning
    depends on it and no convention given is refused at that word.
    ``detected``: the dialect :func:`ncopt.reading.dialect.detect` finds (detected here if None).
    """
    prog = parse_text(text, path, dialect=job.control)
    control = job.control or detected or detect(text).name
    return resolve_decimal_point(prog, control, job.decimal_point)
