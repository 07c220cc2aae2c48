"""Subroutine bodies as one generated function: a called subroutine runs as a unit, not line by line.

A subroutine is called again and again; its body (the lines between ``sub`` and ``endsub``) is
compiled once, at its first call, into one Python function: its lines' compiled functions called
in order, ``while`` loops as Python loops, ``if``/``elseif``/``else`` as Python branches,
``break``/``continue`` and ``return`` as theirs. The main loop's work for each line (the line
budget, the line number, the segment budget, the end of the program) is written out inline, so the
result, the budgets and every error (naming the file and line, and the calls it came through) are
the interpreter's own.

Only plain structures are compiled: constant labels, each ``while`` and ``if`` closed in the body,
no label reused inside its own construct, ``break``/``continue`` of the innermost loop, ``return``
and ``endsub`` of this subroutine. A body with anything else (``do``, ``repeat``, calls, nested
``sub``, block-delete lines, a line that does not parse) runs line by line as before. The text is
written from parsed lines only (see ``codegen``): no program text is evaluated.
"""

from __future__ import annotations

from flowmc.errors import GcodeError
from flowmc.motion.gcode.arcs import ArcError
from flowmc.motion.gcode.codegen import _Writer
from flowmc.motion.gcode.expr import EvalError

__all__ = ["compile_body"]

_WHILE_END = ("endwhile",)
_IF_MARKS = ("elseif", "else", "endif")


class _NotPlain(Exception):
    """The body has a structure left to the line-by-line interpreter."""


class _Body:
    def __init__(self, interp, src, sub_line: int, label, computed):
        self.interp, self.src, self.label = interp, src, label
        self.w = _Writer(interp.params, computed, None)
        self.w.env.update(EvalError=EvalError, ArcError=ArcError)
        self.out: list[str] = []
        self.k = sub_line + 1

    # Reading the lines ---------------------------------------------------------------------------
    def read(self, k: int):
        """Line k: ('oword', label, keyword, args) or ('block', Block) or None (blank)."""
        src = self.src
        raw = src.parse(k)  # errors: GcodeError, caught by compile_body
        if raw is None:
            return None
        if raw.delete:
            raise _NotPlain
        if raw.oword is not None:
            label, keyword, args = raw.oword
            if type(label) is not str and type(label) is not int:
                raise _NotPlain
            return ("oword", label, keyword, args)
        return ("block", self.interp.cached_block(src, k))

    # Writing ----------------------------------------------------------------------------------
    def line(self, depth: int, text: str) -> None:
        self.out.append("    " * depth + text)

    def count(self, depth: int, k: int) -> None:
        """What the main loop does for every line it reads: the line budget and the line number."""
        self.line(depth, f"k = {k:d}")
        self.line(depth, "n = I.blocks_run + 1")
        self.line(depth, "I.blocks_run = n")
        self.line(depth, f"if n > M: raise I.over_lines(src, {k:d})")
        self.line(depth, f"I.line_no = {k + 1:d}")

    def cond(self, args) -> str:
        return f"({self.w.expr(args[0])}) != 0.0"

    def statements(self, depth: int, loops: list, opened: list, stop: tuple) -> tuple[int, str]:
        """Lines from self.k until an O-word of ``opened[-1]`` with a keyword in ``stop``: (its line,
        its keyword). ``loops``: labels of the enclosing while loops, innermost last."""
        src, w = self.src, self.w
        while True:
            k = self.k
            if k >= src.end:
                raise _NotPlain
            self.k = k + 1
            item = self.read(k)
            if item is None:
                continue
            if item[0] == "block":
                block = item[1]
                self.count(depth, k)
                if block.run is not None:
                    run, b = w.bind(block.run), w.bind(block)
                    self.line(depth, f"rest = {run}(I, src, {k:d}, True)")
                    self.line(depth, f"if rest is not None: I._run_values({b}, *rest, src, {k:d})")
                else:
                    self.line(depth, f"I._block({w.bind(block)}, src, {k:d})")
                if block.m or block.comment is not None or block.run is None:
                    self.line(depth, "if I.ended: return")
                if block.words or block.g or block.m or block.run is None:
                    self.line(depth, f"if canon.sealed + len(canon.kind) > S: raise I.over_segments(src, {k:d})")
                continue
            _, label, keyword, args = item
            if opened and label == opened[-1] and keyword in stop:
                return k, keyword
            if keyword in ("break", "continue"):
                if not loops or loops[-1] != label:
                    raise _NotPlain
                self.count(depth, k)
                self.line(depth, keyword)
            elif label in opened:
                raise _NotPlain
            elif keyword == "while":
                self.count_loop(depth, k, label, args, loops, opened)
            elif keyword == "if":
                self.branches(depth, k, label, args, loops, opened)
            elif keyword in ("return", "endsub"):
                if label != self.label:
                    raise _NotPlain
                self.count(depth, k)
                self.line(depth, f"I._return({self.w.expr(args[0]) if args else 'None'})")
                self.line(depth, "return")
                if keyword == "endsub":
                    if opened:
                        raise _NotPlain
                    return k, keyword
            else:
                raise _NotPlain

    def count_loop(self, depth: int, k: int, label, args, loops: list, opened: list) -> None:
        self.line(depth, "while True:")
        self.count(depth + 1, k)
        self.line(depth + 1, f"if not {self.cond(args)}: break")
        end, _ = self.statements(depth + 1, loops + [label], opened + [label], _WHILE_END)
        self.count(depth + 1, end)

    def branches(self, depth: int, k: int, label, args, loops: list, opened: list) -> None:
        self.count(depth, k)
        inner = opened + [label]
        self.line(depth, f"if {self.cond(args)}:")
        at, mark = self.statements(depth + 1, loops, inner, _IF_MARKS)
        self.count(depth + 1, at)  # the next mark is read: past endif
        while mark != "endif":
            self.line(depth, "else:")
            depth += 1
            if mark == "elseif":
                cond = self.oword_args(at)
                self.line(depth, f"k = {at:d}")
                self.line(depth, f"I.line_no = {at + 1:d}")
                self.line(depth, f"if {self.cond(cond)}:")
                at, mark = self.statements(depth + 1, loops, inner, _IF_MARKS)
                self.count(depth + 1, at)
            else:
                self.line(depth, "pass")
                at, mark = self.statements(depth, loops, inner, ("endif",))
                self.count(depth, at)

    def oword_args(self, k: int):
        return self.src.parse(k).oword[2]

    def build(self):
        src = self.src
        w = self.w
        self.statements(1, [], [], ())
        head = ["canon, M, S = I.canon, I.max_blocks, I.max_segments", f"I.file_index = {src.index:d}", "k = 0",
                "try:"]
        tail = ["except (InterpError, EvalError, ArcError) as exc:", "    raise I._error(src, k, str(exc)) from None"]
        return w.build(head + self.out + tail, "body", "I, src")


def compile_body(interp, src, sub_line: int, label, computed):
    """The body of the subroutine whose ``sub`` is on line ``sub_line`` of ``src``, as
    ``body(interp, src)`` (run it right after the call: it ends with the return), or None when it is
    left to the line-by-line interpreter."""
    try:
        return _Body(interp, src, sub_line, label, computed).build()
    except (_NotPlain, GcodeError, EvalError):
        return None
