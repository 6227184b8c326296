"""Evaluate RS-274NGC expressions and parameter assignments parsed by the grammar.

Only what can be known by reading the program in order is evaluated:
numbered and named parameters assigned earlier from known values.  Anything
else (system parameters such as ``#<_x>``, ``#5221``, values set by a
subroutine) is unknown, and the words that use it are not planned.
"""

from __future__ import annotations

import math

from lark import Token, Tree

from .errors import NcoptError

MAX_PARAM = 5602  # RS-274NGC numbered parameters run 1..5602


class Unknown(Exception):
    """The value cannot be known without running the control."""


_FUNCS = {
    "ABS": abs, "ACOS": lambda v: math.degrees(math.acos(v)),
    "ASIN": lambda v: math.degrees(math.asin(v)), "COS": lambda v: math.cos(math.radians(v)),
    "EXP": math.exp, "FIX": math.floor, "FUP": math.ceil, "LN": math.log,
    "ROUND": lambda v: float(math.floor(v + 0.5)), "SIN": lambda v: math.sin(math.radians(v)),
    "SQRT": math.sqrt, "TAN": lambda v: math.tan(math.radians(v)),
}

_BINOPS = {
    "**": lambda a, b: a ** b, "*": lambda a, b: a * b, "/": lambda a, b: a / b,
    "MOD": lambda a, b: math.fmod(a, b) if a * b >= 0 else math.fmod(a, b) + b,
    "+": lambda a, b: a + b, "-": lambda a, b: a - b,
    "EQ": lambda a, b: float(a == b), "NE": lambda a, b: float(a != b),
    "GT": lambda a, b: float(a > b), "GE": lambda a, b: float(a >= b),
    "LT": lambda a, b: float(a < b), "LE": lambda a, b: float(a <= b),
    "AND": lambda a, b: float(bool(a) and bool(b)), "OR": lambda a, b: float(bool(a) or bool(b)),
    "XOR": lambda a, b: float(bool(a) != bool(b)),
}


class Params:
    """Parameters known at a point of the program (numbered and named)."""

    def __init__(self) -> None:
        self.values: dict = {}

    def key(self, node: Tree) -> object:
        """Parameter key (int or lower-case name) addressed by a param node."""
        if node.data == "named_param":
            return str(node.children[0])[1:-1].strip().lower().replace(" ", "")
        if node.data == "num_param":
            number = float(node.children[0])
        else:
            number = self.eval(node.children[0])
        index = int(round(number))
        if not 1 <= index <= MAX_PARAM:
            raise NcoptError(f"parameter number {index} out of range 1..{MAX_PARAM}")
        return index

    def get(self, node: Tree) -> float:
        key = self.key(node)
        if key not in self.values:
            raise Unknown(key)
        return self.values[key]

    def eval(self, node) -> float:
        """Value of an expression tree; raises :class:`Unknown`."""
        if isinstance(node, Token):
            return float(node)
        kind = node.data
        if kind in ("number",):
            return float(node.children[0])
        if kind in ("num_param", "named_param", "ind_param"):
            return self.get(node)
        if kind == "unop":
            value = self.eval(node.children[1])
            return -value if str(node.children[0]) == "-" else value
        if kind == "binop":
            left, op, right = node.children
            return _BINOPS[str(op).upper()](self.eval(left), self.eval(right))
        if kind == "call":
            return _FUNCS[str(node.children[0]).upper()](self.eval(node.children[1]))
        if kind == "atan2":
            return math.degrees(math.atan2(self.eval(node.children[1]), self.eval(node.children[3])))
        if kind == "exists":
            target = node.children[1]
            if target.data == "named_param":
                return float(self.key(target) in self.values)
            number = float(target.children[0]) if target.data == "num_param" \
                else self.eval(target.children[0])
            index = int(round(number))  # EXISTS[#99999] is false, not an error
            return float(1 <= index <= MAX_PARAM and index in self.values)
        if len(node.children) == 1:
            return self.eval(node.children[0])
        raise Unknown(kind)
