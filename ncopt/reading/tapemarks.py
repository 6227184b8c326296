"""The program's extent on the tape: it runs from its opening ``%`` (after a header of
blank and comment lines, if any) to its closing one; the lines after that are read by no
control and by no grammar here (``LineKind.TRAILER``), with a warning
(:func:`unread_lines_warning`)."""

from __future__ import annotations

import re

import numpy as np

from ncopt.model import LineKind, Program
from ncopt.reading.dialect import LINUXCNC
from ncopt.reading.refuse import refuse_at

_TAPE_MARK = re.compile(r"(?m)^[ \t]*(?:[Nn][0-9.]*[ \t]*)?%")
# what may stand before the opening '%': a header of blank lines, tape leader (NULs,
# DELs) and comment lines, ( ) or ';' (a CAM system's "(PROGRAM FROM FUSION)")
_BLANKS = r"[ \t\f\v\r\x00-\x08\x0e-\x1f\x7f]*"
_HEADER = re.compile(rf"(?:{_BLANKS}(?:\([^()\r\n]*\){_BLANKS})*(?:;[^\r\n]*)?\n)*{_BLANKS}")
_LEADER = re.compile(r"[\s\x00-\x08\x0e-\x1f\x7f]*")


def trailer_start(text: str, line_start: np.ndarray, name: str, path: str) -> int:
    """First line after the closing ``%`` (controls read nothing after it).

    The first ``%`` opens the program when only a header stands before it (see
    :data:`_HEADER`), else it closes it.  Under the LinuxCNC dialect a header with a
    comment before the opening ``%`` is refused, as rs274 refuses it.
    """
    marks = []
    pos = text.find("%")
    while pos >= 0 and len(marks) < 2:  # '%' is rare: look only where it stands
        bol = text.rfind("\n", 0, pos) + 1
        m = _TAPE_MARK.match(text, bol)
        if m and m.end() == pos + 1:
            marks.append(bol)
        pos = text.find("%", pos + 1)
    if not marks:
        return line_start.shape[0] - 1
    opening = _HEADER.fullmatch(text, 0, marks[0]) is not None
    if opening and name == LINUXCNC and _LEADER.fullmatch(text, 0, marks[0]) is None:
        line = int(np.searchsorted(line_start, marks[0], side="right"))
        raise refuse_at(path, text, marks[0], line, text.index("%", marks[0]) - marks[0] + 1,
                        "`%` after comment lines: LinuxCNC reads a '%' only as the first line "
                        "that is not blank (rs274: \"Bad character '%' used\"); move the "
                        "comments below the '%'")
    closing = marks[1] if opening and len(marks) == 2 else (None if opening else marks[0])
    if closing is None:
        return line_start.shape[0] - 1
    return int(np.searchsorted(line_start, closing, side="right"))


def unread_lines_warning(prog: Program) -> str | None:
    """``path:first-last: ...`` for the lines after the closing ``%`` that hold more than
    blanks: no control reads them, nor does ncopt (it keeps them byte for byte)."""
    trailer = np.flatnonzero(prog.line_kind == LineKind.TRAILER)
    if trailer.size == 0 or _LEADER.fullmatch(prog.text, int(prog.line_start[trailer[0]])):
        return None  # blank lines, a tape trailer of NULs or a DOS end of file (Ctrl-Z)
    filled = [i for i in trailer.tolist() if not _LEADER.fullmatch(prog.line_text(i))]
    return (f"{prog.path}:{filled[0] + 1}-{filled[-1] + 1}: after the closing '%' (line "
            f"{int(trailer[0])}): no control reads these lines, and ncopt does not either; "
            "they are kept as they are")
