"""What a line of an ncopt stamp looks like (:mod:`ncopt.reading.stamp`), for the readers that only
need to recognise one: the tool-comment reader and the diff view (this module imports no
numpy, so ``ncopt diff`` starts fast).  The one definition of how a stamp line starts:
the stamp's own patterns in :mod:`ncopt.reading.stamp` are built on :data:`STAMP_START`."""

from __future__ import annotations

import re

COMMENT_START = r"^\s*(?:\(|;)\s*"  # a comment line's opening "(" or ";"
STAMP_START = COMMENT_START + "ncopt "  # how every stamp line starts
# what a header line holds after "ncopt ": the version and date, the source program, the
# machine, the cutting times
_INFO_KINDS = r"\d\S* \d{4}-\d\d-\d\d: |from |machine |cutting time "
INFO_BODY = f"(?:{_INFO_KINDS})"
# the text of any stamp line, either form, after its "(" or ";": ncopt's own data, never a
# tool description or a line of the program
STAMP_BODY = r"ncopt (?:\S+ T-?\d+ (?:lines=\d+-\d+ )?vc=|T(?:-?\d+|\?) |" + _INFO_KINDS + ")"
STAMP_LINE = re.compile(COMMENT_START + STAMP_BODY)
