"""Evaluate RS-274NGC expressions and parameter assignments parsed by the grammar.

Only what can be known by reading the program in order is evaluated:
numbered and named parameters assigned earlier from known values.  Anything
else (system parameters such as ``#<_x>``, ``#5221``, values set by a
subroutine) is unknown, and the words that use it are not planned.
"""

from __future__ import annotations

import math

from lark import Token, Tree

from ncopt.runtime.errors import NcoptError

# The numbered variables the controls have, and what ncopt reads: their union.  LinuxCNC:
# #1-#5601 (rs274 refuses #0 and #5602: "Parameter number out of range").  Fanuc custom
# macro B: #0 the null variable (always vacant, read only), #1-#33 local, #100-#999 common
# (#100-#199 and #500-#999; #200-#499 with more common variables), #1000 and up system
# variables (offsets, positions, #3000 alarms: #1000-#9999, and #10000-#89999 on the
# Series 30i, tool offsets #10001-#19999 among them); the 30i adds the common variables
# #98000-#98499 and the variables of six digits #100000-#199999 and #900000-#999999.
# Which of these a control has depends on its model and options, which ncopt does not
# know: a number in one of the ranges is read, its value unknown until the program assigns
# it (the words that use it are not planned); a number in none of them is refused.
VARIABLE_RANGES = ((0, 89_999), (98_000, 98_499), (100_000, 199_999), (900_000, 999_999))
NULL_VARIABLE = 0  # Fanuc's #0: vacant whatever is assigned to it


def is_variable(index: int) -> bool:
    """Whether some control has the numbered variable ``#index`` (:data:`VARIABLE_RANGES`)."""
    return any(lo <= index <= hi for lo, hi in VARIABLE_RANGES)


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
            return _name(node)
        if node.data == "num_param":
            return _index(float(node.children[0]))
        return _index(self.eval(node.children[0]))

    def get(self, node: Tree) -> float:
        return self._value_of(self.key(node))

    def _value_of(self, key) -> float:
        if key == NULL_VARIABLE or key not in self.values:
            raise Unknown(key)  # a vacant (null) variable is no number either
        return self.values[key]

    def eval(self, node) -> float:
        """Value of an expression tree; raises :class:`Unknown`, and OverflowError where
        the value is no finite number (``[10**400]``, ``[1e308*10]``: no control holds it).

        The tree is walked with a stack of its own, not by recursion: a program's
        ``#1=[1+1+...]`` of 50,000 terms is a tree 50,000 deep."""
        value = _walk(self, node)
        if not math.isfinite(value):
            raise OverflowError(f"the value is {value}, not a finite number")
        return value


def _name(node: Tree) -> str:
    return str(node.children[0])[1:-1].strip().lower().replace(" ", "")


def _index(number: float) -> int:
    index = int(round(number))
    if not is_variable(index):
        raise NcoptError(f"variable number {index} is out of the range of every control "
                         "(LinuxCNC #1-#5601: \"Parameter number out of range\"; Fanuc #0-"
                         "#89999, #98000-#98499, #100000-#199999, #900000-#999999)")
    return index


def _operands(node) -> list:
    """The subtrees whose values ``node``'s value is computed from, in order."""
    if isinstance(node, Token):
        return []
    kind, children = node.data, node.children
    if kind in ("number", "num_param", "named_param"):
        return []
    if kind == "ind_param":
        return [children[0]]
    if kind in ("unop", "call"):
        return [children[1]]
    if kind == "binop":
        return [children[0], children[2]]
    if kind == "atan2":
        return [children[1], children[3]]
    if kind == "exists":
        target = children[1]
        return [target.children[0]] if target.data == "ind_param" else []
    if len(children) == 1:
        return [children[0]]
    raise Unknown(kind)


def _apply(params: Params, node, args: list) -> float:
    """``node``'s value from its operands' values ``args``."""
    if isinstance(node, Token):
        return float(node)
    kind, children = node.data, node.children
    if kind == "number":
        return float(children[0])
    if kind in ("num_param", "named_param"):
        return params.get(node)
    if kind == "ind_param":
        return params._value_of(_index(args[0]))
    if kind == "unop":
        return -args[0] if str(children[0]) == "-" else args[0]
    if kind == "binop":
        return _BINOPS[str(children[1]).upper()](args[0], args[1])
    if kind == "call":
        return _FUNCS[str(children[0]).upper()](args[0])
    if kind == "atan2":
        return math.degrees(math.atan2(args[0], args[1]))
    if kind == "exists":
        target = children[1]
        if target.data == "named_param":
            return float(_name(target) in params.values)
        number = float(target.children[0]) if target.data == "num_param" else args[0]
        index = int(round(number))  # EXISTS[#99999] is false, not an error
        return float(index != NULL_VARIABLE and is_variable(index) and index in params.values)
    return args[0]  # a node of one child stands for it


def _walk(params: Params, root) -> float:
    """The value of ``root``, its tree walked in post-order with an explicit stack."""
    stack: list = [(root, None)]
    values: list[float] = []
    while stack:
        node, operands = stack.pop()
        if operands is None:
            operands = _operands(node)
            stack.append((node, operands))
            stack.extend((child, None) for child in reversed(operands))
            continue
        args = values[len(values) - len(operands):]
        del values[len(values) - len(operands):]
        values.append(_apply(params, node, args))
    return values[0]
