"""Kept lines as generated Python functions: what a loop, a subroutine or a line template runs again.

A line that runs many times (a subroutine's, a loop's, a template shared by the lines of one shape)
is compiled once into one Python function that evaluates its values, makes its parameter settings
and, for the common G0/G1 line and XY arc, makes the move: one call a line instead of a tree of closures
called node by node. The function's text is written here from the parsed Block only: float
operators and functions from fixed tables, word letters, and bound names (``n0``, ``n1``...) for
every number and parameter name, which are passed in as values, never written into the text. No
program text is evaluated.

Same results and errors as ``expr.evaluate`` over the nodes, in the same order: words, then G and M
values, then the settings' values, then the settings made one by one.
"""

from __future__ import annotations

import math
from types import CodeType

import flowmc.motion.gcode.expr as X
from flowmc.motion.gcode.arcs import SPIRAL_WARN_MM, centre_ijk
from flowmc.motion.gcode.codes import InterpError

__all__ = ["compile_block", "value_function", "value_list"]

_ARITH = {X.ADD: "+", X.SUB: "-", X.MUL: "*"}
_COMPARE = {X.GT: ">", X.GE: ">=", X.LT: "<", X.LE: "<="}
_INLINE_FUNCTIONS = {"SIN": "sin(radians({}))", "COS": "cos(radians({}))", "ABS": "abs({})"}
_STRAIGHT_WORDS = frozenset("XYZF")
_ARC_XY_WORDS = frozenset("XYZIJF")
_AXES = frozenset("XYZ")
# Compiled texts by text. Every number and name is bound, not written, so lines of one structure
# (``#101 = [#102 * 0.5]`` and ``#110 = [#103 * 0.7]``) share one text and compile once.
_CODE: dict[str, CodeType] = {}
_MAX_CODES = 4096


_FIXED = {"binary": X.binary, "function": X.function, "atan2_degrees": X.atan2_degrees, "param_index": X.param_index,
          "sin": math.sin, "cos": math.cos, "radians": math.radians, "InterpError": InterpError,
          "centre_ijk": centre_ijk, "SPIRAL_WARN_MM": SPIRAL_WARN_MM}


class _Writer:
    """Python text for expression nodes, with the values the text refers to."""

    def __init__(self, params, computed, slots):
        self.computed = computed
        self.slots = slots
        self.env = {**_FIXED, "num": params.num, "number": params.number, "named": params.named,
                    "exists": params.exists, "P": params, "GL": params.globals, "S": slots}
        self.count = 0

    def bind(self, value) -> str:
        name = f"n{self.count}"
        self.count += 1
        self.env[name] = value
        return name

    def temp(self) -> str:
        self.count += 1
        return f"t{self.count}"

    def const(self, value: float) -> str:
        return self.bind(value)

    def expr(self, node) -> str:
        if type(node) is float:
            return self.const(node)
        kind = node[0]
        if kind == X.PARAM:
            index = node[1]
            if type(index) is int:
                return f"number({self.bind(index)})" if index in self.computed else f"num[{self.bind(index)}]"
            return f"number(param_index({self.expr(index)}))"
        if kind == X.NAMED:
            name = node[1]
            if self.slots is not None and name[:1] == "$":
                return f"S[{int(name[1:]):d}]"
            n, t = self.bind(name), self.temp()
            table = "GL" if name[:1] == "_" else "P.locals"  # P.locals is a new dict in each call
            return f"({t} if ({t} := {table}.get({n})) is not None else named({n}))"
        if kind == X.NEG:
            return f"(-{self.expr(node[1])})"
        if kind == X.BIN:
            op = node[1]
            a, b = self.expr(node[2]), self.expr(node[3])
            if op in _ARITH:
                return f"({a} {_ARITH[op]} {b})"
            if op in _COMPARE:
                return f"(1.0 if {a} {_COMPARE[op]} {b} else 0.0)"
            return f"binary({int(op):d}, {a}, {b})"
        if kind == X.FUNC:
            arg = self.expr(node[2])
            inline = _INLINE_FUNCTIONS.get(node[1])
            if inline is not None:
                return inline.format(arg)
            return f"function({self.bind(node[1])}, {arg})"
        if kind == X.ATAN2:
            return f"atan2_degrees({self.expr(node[1])}, {self.expr(node[2])})"
        if kind == X.EXISTS:
            return f"(1.0 if exists({self.bind(node[1])}) else 0.0)"
        raise X.EvalError(f"bad expression node {kind}")

    def build(self, lines: list[str], name: str, args: str):
        text = f"def {name}({args}):\n" + "".join(f"    {line}\n" for line in lines)
        code = _CODE.get(text)
        if code is None:
            if len(_CODE) >= _MAX_CODES:
                _CODE.clear()
            code = _CODE[text] = compile(text, f"<flowmc gcode {name}>", "exec")
        namespace: dict = {}
        exec(code, self.env, namespace)  # noqa: S102 - text built from parsed nodes above, values bound
        return namespace[name]


def value_function(node, params, computed=frozenset(), slots=None):
    """A node as a function of no arguments (a float stays a float): an O-word's label, condition or
    argument that runs again."""
    if type(node) is float:
        return node
    writer = _Writer(params, computed, slots)
    return writer.build([f"return {writer.expr(node)}"], "value", "")


def value_list(nodes: list, params, computed=frozenset(), slots=None):
    """Nodes as one function of no arguments giving their values in a list, left to right: a
    call's arguments."""
    writer = _Writer(params, computed, slots)
    return writer.build(["return [" + ", ".join(writer.expr(node) for node in nodes) + "]"], "values", "")


def compile_block(block, params, computed=frozenset(), slots=None):
    """``run(I, src, i, fast)`` for a block without an O-word: its values evaluated and its settings
    made; returns (words, G values, M values), or None when ``fast`` and the line was a G0/G1 move
    made here (the interpreter ``I``'s fast lines, as ``Interpreter._fast_move``)."""
    w = _Writer(params, computed, slots)
    lines: list[str] = []
    words = []
    for k, (letter, value) in enumerate(block.words.items()):
        if type(value) is float:
            words.append((letter, w.const(value)))
        else:
            lines.append(f"w{k} = {w.expr(value)}")
            words.append((letter, f"w{k}"))
    constant_codes = all(type(v) is float for v in block.g) and all(type(v) is float for v in block.m)
    if constant_codes:
        g_text, m_text = w.bind(block.g), w.bind(block.m)  # handed out as they are: only read
    else:
        g_text = "[" + ", ".join(w.expr(v) for v in block.g) + "]"
        m_text = "[" + ", ".join(w.expr(v) for v in block.m) + "]"
        lines.append(f"gv = {g_text}")
        lines.append(f"mv = {m_text}")
        g_text, m_text = "gv", "mv"
    targets = []
    for k, (target, value) in enumerate(block.assign):
        if type(target) is tuple:  # #[expr] = ...: the parameter number first, as the interpreter reads it
            lines.append(f"i{k} = param_index({w.expr(target[1])})")
            targets.append(("number", f"i{k}"))
        elif type(target) is int:
            targets.append(("number" if target in computed else "num", w.bind(target)))
        else:
            targets.append(("named", w.bind(target)))
        lines.append(f"a{k} = {w.expr(value)}")
    for k, (how, target) in enumerate(targets):
        lines.append(f"if a{k} - a{k} != 0.0: raise InterpError('number too large (a parameter cannot hold it)')")
        if how == "num":
            lines.append(f"num[{target}] = a{k}")
        elif how == "number":
            lines.append(f"P.set_number({target}, a{k})")
        else:
            lines.append(f"P.set_named({target}, a{k})")
    if constant_codes and block.comment is None and not block.m and len(block.g) <= 1 and \
            (block.words or block.g) and set(block.words) <= _STRAIGHT_WORDS and \
            (not block.g or block.g[0] in (0.0, 1.0)):
        lines += _straight(dict(words), block.g[0] if block.g else None)
    elif constant_codes and block.comment is None and not block.m and len(block.g) <= 1 and \
            set(block.words) <= _ARC_XY_WORDS and ("I" in block.words or "J" in block.words) and \
            (block.g or set(block.words) & _AXES) and (not block.g or block.g[0] in (2.0, 3.0)):
        lines += _arc_xy(dict(words), block.g[0] if block.g else None)
    elif not block.words and not block.g and not block.m and block.comment is None:
        lines.append("if fast: return None")  # settings only: nothing more to do
    lines.append("return {" + ", ".join(f"{letter!r}: {text}" for letter, text in words) + f"}}, {g_text}, {m_text}")
    return w.build(lines, "run", "I, src, i, fast")


def _straight(words: dict, g: float | None) -> list[str]:
    """The text of ``Interpreter._fast_move`` for a line with these words (letter -> value text)."""
    out = ["if fast and I.comp_mode == 400 and I.feed_mode == 940 and not I.diameter_mode:"]
    if g is None:
        out += ["    motion = I.motion", "    if motion == 0 or motion == 10:"]
    else:
        out += [f"    motion = {10 if g == 1.0 else 0}", "    if True:"]
    body = []
    if words:
        checks = " or ".join(f"{v} - {v} != 0.0" for v in words.values())
        body.append(f"if {checks}: raise InterpError('number too large')")
    if "F" in words:
        f = words["F"]
        body += [f"if {f} < 0: raise InterpError('negative F word (feed)')",
                 f"I.feed_word = {f}", f"I.feed = {f} * I.scale / 60.0"]
    axes = [a for a in "XYZ" if a in words]
    if g is None and not axes:
        body.append("return None")
    else:
        body.append("x, y, z = I.x, I.y, I.z")
        if axes:
            body += ["scale = I.scale", "if I.incremental:"]
            body += [f"    {a.lower()} += {words[a]} * scale" for a in axes]
            body.append("else:")
            body += [f"    {a.lower()} = {words[a]} * scale" for a in axes]
        if g != 0.0:
            body.append("if motion == 10 and not I.feed > 0: "
                        "raise InterpError('G1 with no feed rate: program an F word first')")
        body += ["I.arc_not_allowed = False", "I.cycle_il = None"]
        body += _to_machine("m", "x", "y", "z")
        body += ["I.canon.line_to(mx, my, mz, motion == 0, I.feed, I.speed * I.spindle_dir + 0.0, src.index, i + 1)",
                 "I.x, I.y, I.z = x, y, z", "I.mx, I.my, I.mz = mx, my, mz", "I.motion = motion", "return None"]
    return out + [f"        {line}" for line in body]


def _to_machine(out: str, x: str, y: str, z: str) -> list[str]:
    """``Interpreter.to_machine`` (``_straight``'s inline form when no XY rotation is in force)."""
    return ["if I._sin == 0.0 and I._cos == 1.0:",
            "    g92, g5x, tlo = I.g92, I.g5x, I.tlo",
            f"    {out}x, {out}y, {out}z = ({x} + g92[0] + g5x[0] + tlo[0], {y} + g92[1] + g5x[1] + tlo[1], "
            f"{z} + g92[2] + g5x[2] + tlo[2])",
            "else:",
            f"    {out}x, {out}y, {out}z = I.to_machine({x}, {y}, {z})"]


def _arc_xy(words: dict, g: float | None) -> list[str]:
    """The text of ``Interpreter._fast_arc`` for an I/J arc in the XY plane (incremental centre, no
    XY rotation, no cutter compensation) with these words (letter -> value text)."""
    out = ["if fast and I.comp_mode == 400 and I.feed_mode == 940 and not I.diameter_mode and I.plane == 2 and "
           "I.arc_incremental and not I.arc_not_allowed and I._sin == 0.0 and I._cos == 1.0:"]
    if g is None:
        out += ["    motion = I.motion", "    if motion == 20 or motion == 30:"]
    else:
        out += [f"    motion = {30 if g == 3.0 else 20}", "    if True:"]
    checks = " or ".join(f"{v} - {v} != 0.0" for v in words.values())
    body = [f"if {checks}: raise InterpError('number too large')"]
    if "F" in words:
        f = words["F"]
        body += [f"if {f} < 0: raise InterpError('negative F word (feed)')",
                 f"I.feed_word = {f}", f"I.feed = {f} * I.scale / 60.0"]
    body += ["I.cycle_il = None",
             "name = 'G3' if motion == 30 else 'G2'",
             "if not I.feed > 0: raise InterpError(name + ' with no feed rate: program an F word first')",
             "su, sv, z0 = I.x, I.y, I.z", "x, y, z = su, sv, z0", "s = I.scale"]
    axes = [a for a in "XYZ" if a in words]
    if axes:
        body.append("if I.incremental:")
        body += [f"    {a.lower()} = {a.lower()} + {words[a]} * s" for a in axes]
        body.append("else:")
        body += [f"    {a.lower()} = {words[a]} * s" for a in axes]
    body += [f"cu = su + {words.get('I', '0.0')} * s", f"cv = sv + {words.get('J', '0.0')} * s",
             "diff = centre_ijk(su, sv, x, y, cu, cv, s)",
             "if diff > SPIRAL_WARN_MM: I.warn_spiral(name, diff, src, i)",
             "g92, g5x, tlo = I.g92, I.g5x, I.tlo",
             "mx, my, mz = (x + g92[0] + g5x[0] + tlo[0], y + g92[1] + g5x[1] + tlo[1], "
             "z + g92[2] + g5x[2] + tlo[2])",
             "cx, cy, cz = (cu + g92[0] + g5x[0] + tlo[0], cv + g92[1] + g5x[1] + tlo[1], "
             "z0 + g92[2] + g5x[2] + tlo[2])",
             "I.canon.arc_to(mx, my, mz, (cx, cy, cz), 2, motion == 30, 0, I.feed, I.speed * I.spindle_dir + 0.0, "
             "src.index, i + 1)",
             "I.x, I.y, I.z = x, y, z", "I.mx, I.my, I.mz = mx, my, mz", "I.motion = motion", "return None"]
    return out + [f"        {line}" for line in body]
