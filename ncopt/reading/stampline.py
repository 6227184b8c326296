"""What a line of an ncopt stamp looks like (:mod:`ncopt.reading.stamp`), for the readers that only
need to recognise one: the tool-comment reader and the diff view (this module imports no
numpy, so ``ncopt diff`` starts fast)."""

from __future__ import annotations

import re

# the text of any stamp line, either form, after its "(" or ";": ncopt's own data, never a
# tool description or a line of the program
STAMP_BODY = (r"ncopt (?:\S+ T-?\d+ (?:lines=\d+-\d+ )?vc=|T(?:-?\d+|\?) |"
              r"\d\S* \d{4}-\d\d-\d\d: |from |machine |cutting time )")
STAMP_LINE = re.compile(r"^\s*(?:\(|;)\s*" + STAMP_BODY)
