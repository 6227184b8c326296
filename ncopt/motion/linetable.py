"""The program's words as per-line arrays: the table every stage of the interpreter reads.

One column per letter (NaN where a line has no such word) and the G and M codes with
their lines, built in one pass over the words (:class:`LineTable`).
"""

from __future__ import annotations

import numpy as np

from ncopt.model import Program
from ncopt.motion.modal import G_READ


class LineTable:
    """Per-line word values, NaN where a line has no such word.

    ``letters[c]``: (values (n_lines,) float64, present (n_lines,) bool) for each letter
    c in the program; ``g_line``/``g_code`` and ``m_line``/``m_code``: the G and M codes
    (G x10, int) with their lines.
    """

    def __init__(self, prog: Program, values: np.ndarray) -> None:
        self.n = prog.n_lines
        self.letters = {}
        # the words grouped by letter, each group in text order (a stable sort): one
        # pass over the words instead of one per letter
        order = np.argsort(prog.word_letter, kind="stable")
        codes, first = np.unique(prog.word_letter[order], return_index=True)
        of = {code: order[a:b] for code, a, b in
              zip(codes.tolist(), first.tolist(), first[1:].tolist() + [order.size])}
        for code, sel in of.items():
            if code in (ord("G"), ord("M"), ord("N"), ord("O")):
                continue
            arr = np.full(self.n, np.nan)
            arr[prog.word_line[sel]] = values[sel]
            present = np.zeros(self.n, dtype=bool)
            present[prog.word_line[sel]] = True
            self.letters[chr(code)] = (arr, present)
        gsel = of.get(ord("G"), np.zeros(0, np.int64))
        self.g_line = prog.word_line[gsel]
        self.g_code = np.round(values[gsel] * 10).astype(np.int64, copy=False) if gsel.size \
            else np.zeros(0, np.int64)
        msel = of.get(ord("M"), np.zeros(0, np.int64))
        self.m_line = prog.word_line[msel]
        self.m_code = np.nan_to_num(values[msel], nan=-1).astype(np.int64)

    def value(self, letter: str) -> np.ndarray:
        return self.letters[letter][0] if letter in self.letters else np.full(self.n, np.nan)

    def present(self, letter: str) -> np.ndarray:
        return self.letters[letter][1] if letter in self.letters else np.zeros(self.n, bool)

    def value_at(self, letter: str, i: int) -> float:
        """The value of ``letter`` on line ``i`` (NaN where it has none): for code that
        walks lines one by one, where :meth:`value` of a letter the program lacks would
        build a whole column each time."""
        column = self.letters.get(letter)
        return column[0][i] if column is not None else np.nan

    def present_at(self, letter: str, i: int) -> bool:
        """Whether line ``i`` holds ``letter`` (see :meth:`value_at`)."""
        column = self.letters.get(letter)
        return bool(column[1][i]) if column is not None else False

    def present_any(self, letters: str) -> np.ndarray:
        """(n,) bool: the line holds a word of any of ``letters``."""
        out = np.zeros(self.n, dtype=bool)
        for c in letters:
            out |= self.present(c)
        return out

    def g_group(self, group: set) -> np.ndarray:
        """(n,) float: the code of this group on each line (NaN if none).

        G80 yields to another motion code on the same line.
        """
        out = np.full(self.n, np.nan)
        sel = np.isin(self.g_code, list(group))
        cancel = sel & (self.g_code == 800)
        out[self.g_line[cancel]] = 800
        out[self.g_line[sel & ~cancel]] = self.g_code[sel & ~cancel]
        return out

    def has_g(self, codes) -> np.ndarray:
        out = np.zeros(self.n, dtype=bool)
        out[self.g_line[np.isin(self.g_code, list(codes))]] = True
        return out

    def unread_g(self) -> np.ndarray:
        """(n,) bool: the line holds a G code outside :data:`G_READ` (computed once)."""
        if getattr(self, "_unread", None) is None:
            self._unread = np.zeros(self.n, dtype=bool)
            self._unread[self.g_line[~np.isin(self.g_code, list(G_READ))]] = True
        return self._unread

    def has_m(self, codes) -> np.ndarray:
        out = np.zeros(self.n, dtype=bool)
        out[self.m_line[np.isin(self.m_code, list(codes))]] = True
        return out
