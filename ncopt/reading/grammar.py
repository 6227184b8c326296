"""The grammars: where they live, their LALR parsers (one per dialect, built once per
process), and what the fast path (:mod:`ncopt.reading.fastpath`) derives from their terminals:
the class of every byte and the patterns of the address words of more than a letter."""

from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path

import numpy as np
from lark import Lark

from ncopt.reading.dialect import DIALECTS, GENERIC
from ncopt.runtime.errors import UsageError

# byte classes of the fast path
SPACE, LETTER, DIGIT, SIGN, POINT, NL, OTHER = range(7)
SEP, SLASH = 7, 8  # a comment's first byte; a block delete mark first on its line


def grammar_path(name: str = "generic.lark") -> Path:
    """Where a grammar lives: inside the installed package, else the source tree."""
    here = Path(__file__).resolve().parent.parent  # the ncopt package
    for folder in (here / "grammars", here.parent / "grammars"):
        if (folder / name).is_file():
            return folder / name
    raise FileNotFoundError(f"grammar {name} not found next to {here}")


def dialect_name(dialect: str | None) -> str:
    """The grammar name of a dialect: ``None`` means the generic grammar."""
    if dialect is None:
        return GENERIC
    if dialect not in DIALECTS:
        raise UsageError(f"unknown dialect {dialect!r}; use one of {', '.join(DIALECTS)}")
    return dialect


@lru_cache(maxsize=None)
def lark_parser(name: str) -> Lark:
    # Lark.open resolves the grammar's relative %import .core next to the file
    return Lark.open(str(grammar_path(f"{name}.lark")), parser="lalr",
                     propagate_positions=True, maybe_placeholders=False)


def parser(dialect: str | None = None) -> Lark:
    """The LALR parser of one source line in a dialect (built once per process)."""
    return lark_parser(dialect_name(dialect))


@lru_cache(maxsize=None)
def fast_tables(name: str) -> tuple[np.ndarray, np.ndarray]:
    """(256,) int8 class and (256,) bool block-end mark of every byte, from the terminals."""
    terms = {t.name: re.compile(t.pattern.to_regexp()) for t in lark_parser(name).terminals}
    letter, number, ws = terms["LETTER"], terms["SNUMBER"], terms["WS"]
    block_end = terms.get("BLOCK_END")
    table = np.full(256, OTHER, dtype=np.int8)
    ends = np.zeros(256, dtype=bool)
    for code in range(256):
        ch = chr(code)
        if ws.fullmatch(ch):
            table[code] = SPACE
        elif letter.fullmatch(ch):
            table[code] = LETTER
        elif number.fullmatch(ch):
            table[code] = DIGIT
        elif number.fullmatch("1" + ch) and number.fullmatch(ch + "1"):
            table[code] = POINT
        elif number.fullmatch(ch + "1"):
            table[code] = SIGN
        ends[code] = block_end is not None and block_end.fullmatch(ch) is not None
    ends &= table == OTHER  # a byte the fast path reads as a word is never a block end
    return table, ends


def byte_classes(dialect: str | None = None) -> np.ndarray:
    """(256,) int8 class of every byte, derived from the grammar's terminals."""
    return fast_tables(dialect_name(dialect))[0]


# Address words whose address is more than a letter, read as words with a letter code of
# their own: the grammar's terminal and the code of each (None: by the letter, see
# VECTOR_WORD_CODES).  CR= is the radius of an arc: R's code (the R-format arc: the same
# radius, and the same sign for the arc of more than 180 degrees).
RADIUS_CODE = ord("R")

_ADDRESS_WORDS = (("VECTOR_ADDRESS", None), ("RADIUS_ADDRESS", RADIUS_CODE))


@lru_cache(maxsize=None)
def address_patterns(name: str) -> tuple:
    """(pattern, code) of the grammar's address word terminals (``A3=``, ``CR=`` before a
    number), of those it has: see :data:`_ADDRESS_WORDS`."""
    terms = {t.name: t for t in lark_parser(name).terminals}
    return tuple((re.compile(terms[t].pattern.to_regexp()), code)
                 for t, code in _ADDRESS_WORDS if t in terms)
