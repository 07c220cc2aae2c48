"""Lines that differ only in their numbers share one parse.

A generated program repeats a few line shapes with new numbers (``G1 X[#100 * COS[#101] + 3.026]``,
then ``... + 0.541]``). A line's template is its code with each number written as a slot ``#<$k>``;
the template is parsed once by the lexer and compiled into closures that read the slots, so each
later line of that shape only splits out its numbers. Parameter numbers (``#12``), O-word numbers
and a leading N word stay part of the shape.

Only shapes that cannot read differently with a slot than with a number are taken: every number
follows a letter, ``[``, an operator or ``=``, none runs into a ``.``, none sits inside a
``#<name>``. Anything else (and a template that does not parse) is left to the ordinary parse, which
explains what is wrong with a line.
"""

from __future__ import annotations

import re

from flowmc.motion.gcode.expr import compile_value
from flowmc.motion.gcode.lexer import Block, parse_line, split_comments

__all__ = ["Templates"]

_LITERAL = re.compile(r"(?<![#O\d.])(\d+\.?\d*|\.\d+)")
_LEAD_N = re.compile(r"/?N\d+(?:\.\d*)?")
_SLOT_IN_NAME = re.compile(r"<[^>]*#<\$")
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
        code, _ = split_comments(raw)
        if not code:
            return None
        if code[0] == "N" or code[0] == "/":
            m = _LEAD_N.match(code)
            if m is not None:
                code = ("/" if code[0] == "/" else "") + code[m.end():]
        parts = _LITERAL.split(code)
        key = "$".join(parts[0::2])
        shape = self.shapes.get(key, False)
        if shape is False:
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
        if len(texts) == 1:
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


def evaluator(block: Block):
    """A compiled block's values in one call: (words, G values, M values, parameter settings), what
    ``Interpreter.values`` otherwise works out item by item. Computed targets (``#[..] =``) are left
    to it (None)."""
    if any(type(t) is tuple for t, _ in block.assign):
        return None
    keys = tuple(block.words)
    fw = tuple(_call(v) for v in block.words.values())
    fg = tuple(_call(v) for v in block.g)
    fm = tuple(_call(v) for v in block.m)
    targets = tuple(t for t, _ in block.assign)
    fa = tuple(_call(v) for _, v in block.assign)
    if not fg and not fm and not fa:
        def run():
            return dict(zip(keys, [f() for f in fw])), [], [], ()
    else:
        def run():
            return (dict(zip(keys, [f() for f in fw])), [f() for f in fg], [f() for f in fm],
                    list(zip(targets, [f() for f in fa])))
    return run
