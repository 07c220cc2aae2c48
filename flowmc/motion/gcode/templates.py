"""Lines that differ only in their numbers share one parse.

A generated program repeats a few line shapes with new numbers (``G1 X[#100 * COS[#101] + 3.026]``,
then ``... + 0.541]``). A line's template is its code with each number written as a slot ``#<$k>``;
the template is parsed once by the lexer and compiled into closures that read the slots, so each
later line of that shape only splits out its numbers. Parameter numbers (``#12``), G, M and O-word
numbers stay part of the shape; a leading N word is dropped from it.

Only shapes that cannot read differently with a slot than with a number are taken: every number
follows a letter, ``[``, an operator or ``=``, none runs into a ``.``, none sits inside a
``#<name>``. Anything else (and a template that does not parse) is left to the ordinary parse, which
explains what is wrong with a line.
"""

from __future__ import annotations

import re

from flowmc.motion.gcode.expr import compile_value
from flowmc.motion.gcode.lexer import Block, parse_line, squeeze

__all__ = ["Templates"]

_LITERAL = re.compile(r"(?<![#OGM\d.])(\d+\.?\d*|\.\d+)")
_LEAD_N = re.compile(r"/?N\d+(?:\.\d*)?")
_SLOT_IN_NAME = re.compile(r"<[^>]*#<\$")
_NEW = (None, None)  # a shape not seen yet
_MAX_SHAPES = 20_000  # a program of ever new shapes gains nothing here: past this, new shapes parse as usual
_BEFORE = frozenset("ABCDEFGHIJKLMNOPQRSTUVWXYZ[+-*/=")


class Templates:
    """Compiled templates by shape, for one interpreter's parameters."""

    def __init__(self, params, computed):
        self.params = params
        self.computed = computed
        self.shapes: dict[str, tuple | None] = {}

    def block(self, raw: str) -> Block | None:
        """The Block of a line through its template, its slots filled; None when the line is not
        one to take this way (the caller parses it as usual)."""
        if "(" in raw or ";" in raw or ")" in raw or "$" in raw or "%" in raw:
            return None
        code = squeeze(raw)
        if not code:
            return None
        if code[0] == "N" or code[0] == "/":
            m = _LEAD_N.match(code)
            if m is not None:
                code = ("/" if code[0] == "/" else "") + code[m.end():]
        parts = _LITERAL.split(code)
        key = "$".join(parts[0::2])
        shape = self.shapes.get(key, _NEW)
        if shape is _NEW:
            if len(self.shapes) >= _MAX_SHAPES:
                return None
            shape = self.shapes[key] = self._compile(parts[0::2])
        if shape is None:
            return None
        block, slots = shape
        if slots is not None:
            slots[:] = map(float, parts[1::2])
        return block

    def _compile(self, texts: list[str]):
        for k in range(1, len(texts)):
            before, after = texts[k - 1][-1:], texts[k]
            if before not in _BEFORE or (k < len(texts) - 1 and not after) or after[:1] == ".":
                return None
        template = "".join(text + (f"#<${k}>" if k < len(texts) - 1 else "") for k, text in enumerate(texts))
        if _SLOT_IN_NAME.search(template):
            return None
        try:
            block = parse_line(template)
        except Exception:  # noqa: BLE001 - whatever the template trips on, the ordinary parse explains
            return None
        if len(texts) == 1 and block.const:
            return block, None
        block.const = False
        slots: list[float] = [0.0] * (len(texts) - 1)
        params, computed = self.params, self.computed

        def c(value):
            return compile_value(value, params, computed, slots)

        block.words = {k: c(v) for k, v in block.words.items()}
        block.g = [c(v) for v in block.g]
        block.m = [c(v) for v in block.m]
        block.assign = [(t if type(t) is not tuple else c(t), c(v)) for t, v in block.assign]
        if block.oword is not None:
            label, keyword, args = block.oword
            if type(label) is not str and type(label) is not int:
                label = c(label)
            block.oword = (label, keyword, [c(a) for a in args])
        block.run = evaluator(block)
        return block, slots


def _call(value):
    return value if callable(value) else (lambda: value)


def _words(keys: tuple, fs: tuple):
    """A function building the words dict from its value functions (spelt out for up to 6 words)."""
    n = len(keys)
    if n == 0:
        return dict
    if n > 6:
        return lambda: dict(zip(keys, [f() for f in fs]))
    k1, k2, k3, k4, k5, k6 = keys + ("",) * (6 - n)
    f1, f2, f3, f4, f5, f6 = fs + (None,) * (6 - n)
    return (None,
            lambda: {k1: f1()},
            lambda: {k1: f1(), k2: f2()},
            lambda: {k1: f1(), k2: f2(), k3: f3()},
            lambda: {k1: f1(), k2: f2(), k3: f3(), k4: f4()},
            lambda: {k1: f1(), k2: f2(), k3: f3(), k4: f4(), k5: f5()},
            lambda: {k1: f1(), k2: f2(), k3: f3(), k4: f4(), k5: f5(), k6: f6()})[n]


def evaluator(block: Block):
    """A compiled block's values in one call: (words, G values, M values, parameter settings), what
    ``Interpreter.values`` otherwise works out item by item. Computed targets (``#[..] =``) are left
    to it (None). Constant G and M lists are handed out as they are (the interpreter only reads them)."""
    if any(type(t) is tuple for t, _ in block.assign):
        return None
    words = _words(tuple(block.words), tuple(_call(v) for v in block.words.values()))
    g, m = block.g, block.m
    constant = all(type(v) is float for v in g) and all(type(v) is float for v in m)
    if constant and not block.assign:
        def constant_codes():
            return words(), g, m, ()
        return constant_codes
    fg = tuple(_call(v) for v in g)
    fm = tuple(_call(v) for v in m)
    targets = tuple(t for t, _ in block.assign)
    fa = tuple(_call(v) for _, v in block.assign)

    def run():
        return words(), [f() for f in fg], [f() for f in fm], list(zip(targets, [f() for f in fa]))
    return run
