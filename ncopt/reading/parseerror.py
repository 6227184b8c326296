"""Why a line does not parse: the located description of a Lark error, and for a
construct of another dialect (``R1=5`` under ``fanuc``) its name and the dialects that
read it."""

from __future__ import annotations

import re

from lark import Token, Tree
from lark.exceptions import UnexpectedInput

from ncopt.reading.dialect import DIALECTS, FANUC, GENERIC, GRBL
from ncopt.reading.grammar import lark_parser
from ncopt.reading.refuse import klartext_what, looks_like_klartext


def describe(exc: UnexpectedInput, src: str, name: str) -> str:
    col = (getattr(exc, "column", 1) or 1) - 1
    ch = src[col] if 0 <= col < len(src) else ""
    if looks_like_klartext(src):
        return f"the line is a block of {klartext_what()}"
    if "(" in src and src.count("(") != src.count(")"):
        return "unbalanced comment parentheses; close every '(' with ')' on the same line"
    inner = src.find("(", col + 1)
    if ch == "(" and 0 <= inner < src.find(")", col + 1):
        return ("a comment inside a comment: controls do not nest parentheses (LinuxCNC: "
                "\"Nested comment found\"); remove the inner ( )")
    if ch == "\r":
        return ("a carriage return (CR) inside the line: the file mixes line ends (CR alone, "
                "or CR CR LF); save it with LF or CR LF line ends")
    if src.startswith("\xef\xbb\xbf", col):
        return ("a UTF-8 byte order mark inside the file (files joined together?); delete "
                "the three bytes EF BB BF")
    if ch:
        after = " or after ;" if any(t.name == "EOL_COMMENT" for t in lark_parser(name).terminals) \
            else ""
        what = repr(ch) if " " <= ch <= "~" else f"byte 0x{ord(ch):02X}"
        return (f"unexpected {what}; expected a word such as X1.5, a comment in ( ){after}, "
                "or fix the line")
    return "line ends in the middle of a word or expression; complete or remove it"


# ------------------------------------------------ constructs of other dialects ----
# What a construct of the generic grammar is, by the name of its tree node or of
# the head token of an opaque node.
_CONSTRUCTS = {
    "KEYWORD": "a keyword (macro statement, cycle call or label)",
    "ADDRESS_ASSIGN": "an address assignment",
    "O_WORD": "a LinuxCNC o-word",
    "DOLLAR": "a '$' system command or variable",
    "COLON": "a ':' program or main block number",
    "assign": "a parameter assignment",
    "expr_word": "a word with a computed value",
    "vector_word": "a Sinumerik tool vector word",
    "radius_word": "a Sinumerik arc radius (CR=)",
    "named_param": "a LinuxCNC named parameter",
    "eol_comment": "a ';' comment",
    "block_end": "a Heidenhain ISO block end",
    "tape_mark": "a '%' tape mark",
}

_R_PARAMETER = re.compile(r"R[0-9]+[ \t]*=", re.I)

_SNIPPET_CHARS = 24


def other_dialect(src: str, col: int, name: str) -> str | None:
    """Why ``src`` is refused under dialect ``name`` although another dialect reads it."""
    if name == GENERIC:
        return None
    try:
        tree = lark_parser(GENERIC).parse(src)
    except UnexpectedInput:
        return None  # malformed in every dialect
    found = _construct_at(tree.children[0], col - 1)
    if found is None:
        return None
    kind, start, end = found
    snippet = src[start:end].strip()
    if len(snippet) > _SNIPPET_CHARS:
        snippet = snippet[:_SNIPPET_CHARS - 3] + "..."
    what = _CONSTRUCTS[kind]
    if kind == "ADDRESS_ASSIGN" and _R_PARAMETER.match(snippet):
        what = "a Sinumerik R-parameter assignment"
    readers = [d for d in DIALECTS if d not in (name, GENERIC) and _reads(d, src, col - 1, found)]
    todo = (f"pass --dialect {readers[0]} or --dialect {GENERIC}" if len(readers) == 1 else
            f"pass --dialect {', '.join(readers)} or {GENERIC}" if readers else
            f"pass --dialect {GENERIC}")
    if kind == "eol_comment" and name == FANUC:
        return (f"`{snippet}` is {what}, which Fanuc does not have: its manuals print the "
                "end-of-block code as ';', so the text after it would be read as a block; "
                f"write the comment in ( ) or {todo}")
    if kind == "tape_mark" and name == GRBL:
        return (f"`{snippet}` is {what}, which grbl does not read (it reports the line as an "
                f"error); remove the line or {todo}")
    return f"`{snippet}` is {what}, not read under the {name} dialect; {todo}"


def _construct_at(line: Tree, index: int) -> tuple[str, int, int] | None:
    """(kind, start, end) of the innermost construct of :data:`_CONSTRUCTS` at ``index``."""
    items = [c for c in line.children if _span(c) is not None]
    at = [c for c in items if _span(c)[0] <= index < _span(c)[1]]
    after = [c for c in items if _span(c)[0] >= index]
    node = (at or after or items[-1:] or [None])[0]
    found = None
    while node is not None:
        kind = _kind(node)
        if kind is not None:
            found = (kind, *_span(node))
        inner = [c for c in getattr(node, "children", ()) if _span(c) is not None
                 and _span(c)[0] <= index < _span(c)[1]]
        node = inner[0] if inner else None
    return found


def _span(node) -> tuple[int, int] | None:
    if isinstance(node, Token):
        return (node.start_pos, node.end_pos) if node.start_pos is not None else None
    if node.meta.empty:
        return None
    return node.meta.start_pos, node.meta.end_pos


_SAME_KIND = {"MACRO_STATEMENT": "KEYWORD", "O_WORD_COMPUTED": "O_WORD"}


def _kind(node) -> str | None:
    if isinstance(node, Token):
        return None
    if node.data == "opaque":
        head = node.children[0].type
        return _SAME_KIND.get(head, head)
    return node.data if node.data in _CONSTRUCTS else None


def _reads(dialect: str, src: str, index: int, construct: tuple[str, int, int]) -> bool:
    """Whether ``dialect`` reads ``src`` with ``construct`` (kind, start, end) at ``index``.

    Also when it reads the construct as part of a larger one of its own
    (LinuxCNC's ``o[#1] call`` holds the keyword ``call``).
    """
    try:
        tree = lark_parser(dialect).parse(src)
    except UnexpectedInput:
        return False
    found = _construct_at(tree.children[0], index)
    if found is None:
        return False
    kind, start, end = construct
    return found[0] == kind or (found[1] <= start and found[2] >= end)
