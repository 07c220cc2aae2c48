"""Lines that differ only in their numbers share one parse.

A generated program repeats a few line shapes with new numbers (``G1 X[#100 * COS[#101] + 3.026]``,
then ``... + 0.541]``). A line's template is its code with each number written as a slot ``#<$k>``;
the template is parsed once by the lexer and compiled into a function that reads the slots, so each
later line of that shape only splits out its numbers. Parameter numbers (``#12``), G, M and O-word
numbers stay part of the shape; a leading N word is dropped from it.

Only shapes that cannot read differently with a slot than with a number are taken: every number
follows a letter, ``[``, an operator or ``=``, none runs into a ``.``, none sits inside a
``#<name>``. Anything else (and a template that does not parse) is left to the ordinary parse, which
explains what is wrong with a line.
"""

from __future__ import annotations

import re

import numpy as np

from flowmc.motion.gcode.codegen import compile_block, value_function, value_list
from flowmc.motion.gcode.lexer import Block, parse_line

__all__ = ["Templates"]

_LITERAL = re.compile(r"(?<![#OGM\d.])(\d+\.?\d*|\.\d+)")
_SLOT_IN_NAME = re.compile(r"<[^>]*#<\$")
_NEW = (None, None)  # a shape not seen yet
_MAX_SHAPES = 20_000  # a program of ever new shapes gains nothing here: past this, new shapes parse as usual
_BEFORE = frozenset("ABCDEFGHIJKLMNOPQRSTUVWXYZ[+-*/=")
_NOT_TEMPLATED = re.compile(r"[();$%]")  # comments, and what a slot or '%' could be confused with
_LEAD_N_LINES = re.compile(r"^(/?)N\d+(?:\.\d*)?", re.MULTILINE)
_CHUNK = 4096  # lines split at a time: a whole-text pass, bounded in memory
_NUMERIC = np.zeros(256, dtype=bool)
_NUMERIC[list(b"0123456789.")] = True
_AFTER_CODE = np.zeros(256, dtype=bool)  # a number after these is part of the shape
_AFTER_CODE[list(b"#OGM")] = True
_SIGN_AFTER = np.zeros(256, dtype=bool)  # a '-' after these is a sign
_SIGN_AFTER[list(b"[XYZIJKR")] = True
_OPERATOR = np.zeros(256, dtype=bool)
_OPERATOR[list(b"+*/")] = True
_OPERAND_END = np.zeros(256, dtype=bool)
_OPERAND_END[list(b"0123456789]")] = True


class Templates:
    """Compiled templates by shape, for one interpreter's parameters."""

    def __init__(self, params, computed):
        self.params = params
        self.computed = computed
        self.shapes: dict[str, tuple | None] = {}
        self.chunk: tuple | None = None  # the lines last split (``_split``)

    def split(self, src, i: int) -> tuple:
        """The split chunk holding line ``i`` of ``src`` (see ``_split``)."""
        chunk = self.chunk
        if chunk is None or chunk[0] is not src or not 0 <= i - chunk[1] < _CHUNK:
            chunk = self.chunk = _split(src, i - i % _CHUNK)
        return chunk

    def shape(self, key: str):
        """The (block, slots) of a shape key, compiled at its first line; None when it is not taken."""
        shape = self.shapes.get(key, _NEW)
        if shape is _NEW:
            if len(self.shapes) >= _MAX_SHAPES:
                return None
            shape = self.shapes[key] = self._compile(key.split("$"))
        return shape

    def block(self, src, i: int) -> Block | None:
        """The Block of line ``i`` of ``src`` through its template, its slots filled; None when the line
        is not one to take this way (the caller parses it as usual)."""
        chunk = self.chunk
        if chunk is None or chunk[0] is not src or not 0 <= i - chunk[1] < _CHUNK:
            chunk = self.chunk = _split(src, i - i % _CHUNK)
        k = i - chunk[1]
        key = chunk[2][k]
        if key is None:
            return None
        shape = self.shapes.get(key, _NEW)
        if shape is _NEW:
            if len(self.shapes) >= _MAX_SHAPES:
                return None
            shape = self.shapes[key] = self._compile(key.split("$"))
        if shape is None:
            return None
        block, slots = shape
        if slots is not None:
            ends = chunk[4]
            slots[:] = chunk[3][ends[k] - len(slots):ends[k]]
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
        if block.oword is not None:
            label, keyword, args = block.oword
            if type(label) is not str and type(label) is not int:
                label = value_function(label, params, computed, slots)
            if keyword == "call":  # its arguments are read by ``run`` only, in one function
                block.oword = (label, keyword, args)
                block.run = value_list(args, params, computed, slots)
            else:
                block.oword = (label, keyword, [value_function(a, params, computed, slots) for a in args])
        else:
            block.run = compile_block(block, params, computed, slots)
        return block, slots


def _split(src, first: int) -> tuple:
    """Lines ``first`` to ``first + _CHUNK`` of ``src`` split into shapes and numbers over their joined
    text with numpy (what ``_LITERAL`` does line by line, at a fraction of the cost): (src, first,
    each line's shape key or None, all their numbers, where each line's numbers end).

    A number is a run of digits with at most one '.' (not '.' alone) that does not follow '#', 'O',
    'G' or 'M'; it becomes '$' in the key. A line with a run of two or more '.' gets no key (the
    ordinary parse explains it), nor does one with a comment, '$', '%' or a non-ASCII character."""
    lines = src.lines[first:min(first + _CHUNK, src.end)]
    code = "\n".join(lines)
    if _NOT_TEMPLATED.search(code) or not code.isascii():
        code = "\n".join("" if _NOT_TEMPLATED.search(raw) or not raw.isascii() else raw for raw in lines)
    code = code.replace(" ", "")
    if "\t" in code:
        code = code.replace("\t", "")
    code = code.upper()
    if code[:1] == "N" or code[:2] == "/N" or "\nN" in code or "\n/N" in code:
        code = _LEAD_N_LINES.sub(r"\1", code)
    if not code.strip("\n"):
        return src, first, [None] * _CHUNK, [], [0] * _CHUNK
    chars = np.frombuffer(code.encode("ascii"), dtype=np.uint8)
    n = chars.size
    numeric = _NUMERIC[chars]
    before = np.empty(n, dtype=np.uint8)
    before[0] = 10
    before[1:] = chars[:-1]
    starts = np.flatnonzero(numeric & ~_NUMERIC[before])
    ends = np.flatnonzero(numeric & ~np.append(numeric[1:], False)) + 1
    dots = np.cumsum(chars == 46)
    run_dots = dots[ends - 1] - np.where(starts > 0, dots[starts - 1], 0)
    literal = ~_AFTER_CODE[before[starts]] & ~((ends - starts == 1) & (chars[starts] == 46)) & (run_dots <= 1)
    newlines = np.flatnonzero(chars == 10)
    bad_lines = np.searchsorted(newlines, starts[run_dots > 1])
    starts, ends = starts[literal], ends[literal]
    # A minus that can only be a sign joins its number ("X-5" and "X5", "[a + -5]" and "[a + 5]" share a
    # shape): right after a word letter or '[', or after '+', '*' or '/' that follow a number or ']'.
    pad = np.concatenate((np.full(3, 10, dtype=np.uint8), chars))  # pad[s + 3 - j] is chars[s - j]
    prev = pad[starts + 1]
    starts = starts - ((pad[starts + 2] == 45) & (_SIGN_AFTER[prev] | (_OPERATOR[prev] & _OPERAND_END[pad[starts]])))
    inside = np.bincount(starts + 1, minlength=n + 1) - np.bincount(ends, minlength=n + 1)
    keep = np.cumsum(inside[:n]) == 0
    marked = chars.copy()
    marked[starts] = 36  # '$'
    keys: list = marked[keep].tobytes().decode("ascii").split("\n")
    spaced = np.full(n, 32, dtype=np.uint8)
    in_number = ~keep
    in_number[starts] = True
    spaced[in_number] = chars[in_number]
    numbers = list(map(float, spaced.tobytes().split()))
    counts = np.bincount(np.searchsorted(newlines, starts), minlength=len(keys))
    for k in bad_lines.tolist():
        keys[k] = ""
    keys = [key or None for key in keys]
    keys += [None] * (_CHUNK - len(keys))
    return src, first, keys, numbers, np.cumsum(counts).tolist()
