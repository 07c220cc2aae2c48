"""Expressions: LinuxCNC's operators and functions over parameter values, evaluated from data.

An expression node is a float (a constant) or a tuple whose first item says what it is:
``(PARAM, index)`` ``#n`` (index an int, or a node for ``##n`` / ``#[..]``), ``(NAMED, name)``,
``(FUNC, name, arg)``, ``(ATAN2, y, x)``, ``(EXISTS, name)``, ``(BIN, op, a, b)``, ``(NEG, a)``,
``(INDEX, node)`` (a computed parameter number on the left of '='). The lexer folds constant
parts as it reads, so most values arrive as floats.

LinuxCNC's rules (measured with rs274 2.9): precedence ``**`` > ``* / MOD`` > ``+ -`` > comparisons >
``AND OR XOR``, left to right within a group; ``EQ``/``NE`` treat numbers closer than 0.0001 as
equal, the other comparisons are exact; ``MOD`` gives a result >= 0 for a positive divisor;
angles are degrees; ``FIX`` floors, ``FUP`` ceils, ``ROUND`` rounds halves away from zero; a unary
minus belongs to the value right after it (``-2 ** 2`` is 4).
"""

from __future__ import annotations

import math

__all__ = ["EvalError", "evaluate", "fold_binary", "fold_function", "fold_atan", "param_index", "label_number",
           "integer", "NUM_PARAMS"]

PARAM, NAMED, FUNC, ATAN2, EXISTS, BIN, NEG, INDEX = range(8)
POW, MUL, DIV, MOD, ADD, SUB, EQ, NE, GT, GE, LT, LE, AND, OR, XOR = range(15)
OP_NAMES = ("**", "*", "/", "MOD", "+", "-", "EQ", "NE", "GT", "GE", "LT", "LE", "AND", "OR", "XOR")

#: Numbered parameters run from 1 to this (LinuxCNC's RS274NGC_MAX_PARAMETERS - 1).
NUM_PARAMS = 5602
TOLERANCE_EQUAL = 0.0001
_CLOSE_TO_INT = 0.0001


class EvalError(Exception):
    """An expression that cannot be evaluated (the interpreter adds file and line)."""


def _finite(value: float) -> float:
    if value != value or value in (math.inf, -math.inf):
        raise EvalError("number too large (the result is not a finite number)")
    return value


def integer(value: float, what: str) -> int:
    """``value`` as an int when within 0.0001 of one (LinuxCNC's rule), else an error naming ``what``."""
    if not math.isfinite(value):
        raise EvalError(f"{what} is not a finite number")
    k = round(value)
    if abs(value - k) > _CLOSE_TO_INT:
        raise EvalError(f"{what} must be a whole number, got {value:g}")
    return int(k)


def param_index(value: float) -> int:
    k = integer(value, "parameter number")
    if not 1 <= k <= NUM_PARAMS:
        raise EvalError(f"parameter number #{k} is out of range (1 to {NUM_PARAMS})")
    return k


def label_number(value: float) -> int:
    k = integer(value, "O-word number")
    if k < 0:
        raise EvalError(f"O-word number must be >= 0, got {k}")
    return k


def binary(op: int, a: float, b: float) -> float:
    if op == ADD:
        return _finite(a + b)
    if op == SUB:
        return _finite(a - b)
    if op == MUL:
        return _finite(a * b)
    if op == DIV:
        if b == 0.0:
            raise EvalError("division by zero")
        return _finite(a / b)
    if op == POW:
        if a < 0.0 and b != math.floor(b):
            raise EvalError(f"a negative number cannot be raised to a non-integer power ({a:g} ** {b:g})")
        if a == 0.0 and b < 0.0:
            raise EvalError("zero cannot be raised to a negative power")
        try:
            return _finite(math.pow(a, b))
        except OverflowError:
            raise EvalError("number too large (the result is not a finite number)") from None
    if op == MOD:
        if b == 0.0:
            raise EvalError("MOD by zero")
        r = math.fmod(a, b)
        if r < 0.0:
            r += abs(b)
        return r
    if op == EQ:
        return 1.0 if abs(a - b) < TOLERANCE_EQUAL else 0.0
    if op == NE:
        return 0.0 if abs(a - b) < TOLERANCE_EQUAL else 1.0
    if op == GT:
        return 1.0 if a > b else 0.0
    if op == GE:
        return 1.0 if a >= b else 0.0
    if op == LT:
        return 1.0 if a < b else 0.0
    if op == LE:
        return 1.0 if a <= b else 0.0
    if op == AND:
        return 1.0 if (a != 0.0 and b != 0.0) else 0.0
    if op == OR:
        return 1.0 if (a != 0.0 or b != 0.0) else 0.0
    if op == XOR:
        return 1.0 if ((a != 0.0) != (b != 0.0)) else 0.0
    raise EvalError(f"unknown operator {op}")


def function(name: str, a: float) -> float:
    if name == "SIN":
        return math.sin(math.radians(a))
    if name == "COS":
        return math.cos(math.radians(a))
    if name == "TAN":
        c = math.cos(math.radians(a))
        if c == 0.0:
            raise EvalError(f"TAN of {a:g} degrees is infinite")
        return _finite(math.sin(math.radians(a)) / c)
    if name == "ABS":
        return abs(a)
    if name == "SQRT":
        if a < 0.0:
            raise EvalError(f"square root of a negative number ({a:g})")
        return math.sqrt(a)
    if name == "FIX":
        return float(math.floor(a))
    if name == "FUP":
        return float(math.ceil(a))
    if name == "ROUND":
        return float(math.floor(abs(a) + 0.5)) * (1.0 if a >= 0 else -1.0)
    if name == "ACOS":
        if not -1.0 <= a <= 1.0:
            raise EvalError(f"ACOS argument {a:g} is outside -1 to 1")
        return math.degrees(math.acos(a))
    if name == "ASIN":
        if not -1.0 <= a <= 1.0:
            raise EvalError(f"ASIN argument {a:g} is outside -1 to 1")
        return math.degrees(math.asin(a))
    if name == "EXP":
        try:
            return _finite(math.exp(a))
        except OverflowError:
            raise EvalError("number too large (EXP overflows)") from None
    if name == "LN":
        if a <= 0.0:
            raise EvalError(f"LN of a number <= 0 ({a:g})")
        return math.log(a)
    raise EvalError(f"unknown function {name}")


def atan2_degrees(y: float, x: float) -> float:
    return math.degrees(math.atan2(y, x))


# Folding while parsing: constants become floats, the rest stays a node --------------------------

def fold_binary(op: int, a, b):
    if type(a) is float and type(b) is float:
        return binary(op, a, b)
    return (BIN, op, a, b)


def fold_function(name: str, a):
    if type(a) is float:
        return function(name, a)
    return (FUNC, name, a)


def fold_atan(y, x):
    if type(y) is float and type(x) is float:
        return atan2_degrees(y, x)
    return (ATAN2, y, x)


def evaluate(node, params) -> float:
    """The value of a node; ``params`` gives ``number(i)``, ``named(name)`` and ``exists(name)``.
    A compiled node (``codegen.value_function``) is called instead."""
    if type(node) is float:
        return node
    if type(node) is not tuple:
        return node()
    kind = node[0]
    if kind == BIN:
        return binary(node[1], evaluate(node[2], params), evaluate(node[3], params))
    if kind == PARAM:
        index = node[1]
        if type(index) is not int:
            index = param_index(evaluate(index, params))
        return params.number(index)
    if kind == NAMED:
        return params.named(node[1])
    if kind == NEG:
        return -evaluate(node[1], params)
    if kind == FUNC:
        return function(node[1], evaluate(node[2], params))
    if kind == ATAN2:
        return atan2_degrees(evaluate(node[1], params), evaluate(node[2], params))
    if kind == EXISTS:
        return 1.0 if params.exists(node[1]) else 0.0
    if kind == INDEX:
        return float(param_index(evaluate(node[1], params)))
    raise EvalError(f"bad expression node {kind}")
