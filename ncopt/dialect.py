"""Which control a program was posted for, from its own marks.

Each dialect has a list of telling marks (regular expressions over the text);
the one with the most distinct marks wins, ties broken by the order below.
The result is reported with the marks that decided it, so a user can see why.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

SINUMERIK, FANUC, LINUXCNC, GRBL, HEIDENHAIN, GENERIC = (
    "sinumerik", "fanuc", "linuxcnc", "grbl", "heidenhain-iso", "generic")
DIALECTS = (SINUMERIK, FANUC, HEIDENHAIN, LINUXCNC, GRBL, GENERIC)

_MARKS = {
    SINUMERIK: [r"^%_N_\w+_(?:MPF|SPF)", r"\bCYCLE8\d\d\s*\(", r"\bG64[12]\b", r"\bT\s*=\s*\"",
                r"^\s*(?:N\d+\s*)?DEF\s+(?:REAL|INT|BOOL)", r"\bTRAORI\b|\bTRAFOOF\b",
                r"\bMSG\s*\(", r"^\s*(?:N\d+\s*)?R\d+\s*=", r"\bS1\s*=",
                r"^\s*(?:N\d+\s+)?T\d+\s+D\d+\s*$"],
    FANUC: [r"^\s*O\d{3,5}\b", r"\bG43\s*H\d+|\bG43\s*Z[-\d.]+\s*H\d+", r"\bG28\s*G91|\bG91\s*G28",
            r"\bG0?5\.1\b", r"^\s*#\d+\s*=", r"\bIF\s*\[.*\]\s*GOTO", r"\bM98\s*P", r"\bG65\s*P"],
    LINUXCNC: [r"^\s*[oO]\s*(?:\d+|<[^>]+>)\s+(?:sub|call|if|while|do|repeat)\b",
               r"#<[^>]+>", r"\bG64\s*P", r"\(\s*(?:MSG|DEBUG|PRINT)\s*,", r"^\s*(?:N\d+\s*)?M2\s*$"],
    GRBL: [r"^\s*\$[A-Z]", r"\bgrbl\b", r"\bM[67]\b.*laser|\blaser\b.*\bM[34]\b", r"\$H\b"],
    HEIDENHAIN: [r"^\s*%\w+\s+G7[01]\s*\*", r"\*\s*$", r"\bN\d+\s+G9[89]\b"],
}
_COMPILED = {k: [re.compile(p, re.I | re.M) for p in v] for k, v in _MARKS.items()}
_SAMPLE_CHARS = 400_000  # headers and the first blocks tell; no need to scan 30 MB


@dataclass(frozen=True)
class Detected:
    """The dialect and the marks that decided it."""

    name: str
    marks: tuple[str, ...]


def detect(text: str) -> Detected:
    """Guess the control dialect of a program."""
    sample = text[:_SAMPLE_CHARS] + "\n" + text[-20_000:]
    best, best_marks = GENERIC, ()
    for name in DIALECTS[:-1]:
        found = tuple(_MARKS[name][i] for i, rx in enumerate(_COMPILED[name]) if rx.search(sample))
        if len(found) > len(best_marks):
            best, best_marks = name, found
    return Detected(best, best_marks)
