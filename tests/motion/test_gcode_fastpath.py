"""Plain runs read all at once (fastpath) give exactly what the line-by-line interpreter gives."""

import random

import numpy as np
import pytest

from flowmc.errors import GcodeError
from flowmc.motion.gcode import interp as interp_module
from flowmc.motion.gcode import interpret, lexer
from flowmc.motion.gcode.expr import EvalError
from flowmc.motion.path import Arc, Dwell


def plain_program(seed: int, n: int = 600) -> str:
    """Everything fastpath reads (comments, N words, units, planes, modes, arcs of both forms with turns,
    spindle, outputs, dwells), broken now and then by lines it leaves to the interpreter."""
    rng = random.Random(seed)
    out = ["(plain program)", "G21 G90 G17", "F900", "S1000 M3"]
    pos = [0.0, 0.0, 0.0]
    plane, inc = 2, False
    while len(out) < n:
        r = rng.random()
        prefix = f"N{len(out)} " if rng.random() < 0.2 else ""
        note = " (cut)" if rng.random() < 0.05 else ""
        if r < 0.02:
            plane = rng.choice([0, 1, 2])
            out.append(prefix + {2: "G17", 1: "G18", 0: "G19"}[plane])
        elif r < 0.04:
            inc = not inc
            out.append("G91" if inc else "G90")
        elif r < 0.05:
            out.append(f"F{rng.choice([300, 600, 1200])}{note}")
        elif r < 0.055:
            out.append(f"G4 P{rng.choice([0, 0.2])}")
        elif r < 0.065:
            out.append(rng.choice(["M62 P1", "M63 P1", "M64 P2", "M65 P2", "M67 E0 Q2.5", "M68 E1 Q1", "S500 M4",
                                   "M5", "S2000 M3"]))
        elif r < 0.07:
            out.append(rng.choice(["#1 = 5", "(MSG, hello)", "M8", "M9"]))  # lines for the interpreter
        elif r < 0.072:
            out += ["G20 F20", "G90 G1 X1 Y1", "G21 F900"]  # a stretch in inches
            pos[0] = pos[1] = 25.4
            inc = False
        elif r < 0.55:
            code = rng.choice(["G0", "G1", "G1"])
            new = [round(rng.uniform(-50, 50), 3) for _ in range(3)]
            words = " ".join(f"{'XYZ'[k]}{(new[k] - pos[k]) if inc else new[k]:.3f}" for k in range(3))
            out.append(f"{prefix}{code} {words}{note}")
            pos = new
        else:
            iu, iv = {2: (0, 1), 1: (2, 0), 0: (1, 2)}[plane]
            radius = rng.uniform(2, 20)
            a = rng.uniform(0, 6.28)
            cu, cv = round(pos[iu] + radius * np.cos(a), 3), round(pos[iv] + radius * np.sin(a), 3)
            radius = float(np.hypot(pos[iu] - cu, pos[iv] - cv))
            b = rng.uniform(0, 6.28)
            new = list(pos)
            new[iu], new[iv] = round(cu + radius * np.cos(b), 3), round(cv + radius * np.sin(b), 3)
            words = " ".join(f"{'XYZ'[k]}{(new[k] - pos[k]) if inc else new[k]:.3f}" for k in range(3))
            code = rng.choice(["G2", "G3"])
            turns = f" P{rng.choice([2, 3])}" if rng.random() < 0.05 else ""
            if rng.random() < 0.3 and (new[iu], new[iv]) != (pos[iu], pos[iv]):
                chord = float(np.hypot(new[iu] - pos[iu], new[iv] - pos[iv]))
                out.append(f"{prefix}{code} {words} R{max(radius, chord / 2 + 0.01):.3f}{turns}")
            else:
                letters = {0: "I", 1: "J", 2: "K"}
                out.append(f"{prefix}{code} {words} {letters[iu]}{cu - pos[iu]:.3f} {letters[iv]}{cv - pos[iv]:.3f}"
                           f"{turns}{note}")
            pos = new
    out.append("M2")
    return "\n".join(out) + "\n"


def both(text: str, monkeypatch):
    fast = interpret(text, "p.ngc")
    with monkeypatch.context() as m:
        m.setattr(interp_module, "_FAST_MIN_LINES", 10 ** 9)
        slow = interpret(text, "p.ngc")
    return fast, slow


def assert_same(fast, slow):
    assert len(fast.path) == len(slow.path)
    for a, b in zip(fast.path, slow.path):
        assert type(a) is type(b) and a.source == b.source
        np.testing.assert_array_equal(a.start, b.start)
        np.testing.assert_array_equal(a.end, b.end)
        assert (a.feed, a.rapid, a.tool_down, a.spindle, a.outputs, a.analog) == \
               (b.feed, b.rapid, b.tool_down, b.spindle, b.outputs, b.analog), a.source
        if isinstance(a, Arc):
            np.testing.assert_array_equal(a.center, b.center)
            assert (a.normal_axis, a.ccw, a.turns) == (b.normal_axis, b.ccw, b.turns)
        if isinstance(a, Dwell):
            assert a.seconds == b.seconds
    assert fast.path.digest() == slow.path.digest()
    assert fast.warnings == slow.warnings


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_plain_runs_read_at_once_give_what_line_by_line_gives(seed, monkeypatch):
    text = plain_program(seed)
    fast, slow = both(text, monkeypatch)
    assert_same(fast, slow)
    assert sum(isinstance(s, Arc) for s in fast.path) > 100


@pytest.mark.parametrize("block", [37, 100])
def test_long_runs_read_in_blocks_give_what_line_by_line_gives(block, monkeypatch):
    """Runs longer than _FAST_MAX_RUN lines are read a block at a time (bounded working memory):
    G91 sums, feeds and modes carry over each block boundary as from line to line."""
    text = plain_program(5)
    with monkeypatch.context() as m:
        m.setattr(interp_module, "_FAST_MAX_RUN", block)
        fast = interpret(text, "p.ngc")
    _, slow = both(text, monkeypatch)
    assert_same(fast, slow)


def test_the_fast_path_hands_back_each_line_it_cannot_read_with_the_same_error(monkeypatch):
    base = plain_program(5).splitlines()
    for bad, message in [("G1 X1 Y2 Y3", "two Y words"), ("G17 G90 G2 X1 Y1 I0.1 J0", "differs from radius"),
                         ("G17 G90 G2 X1 R0.1", "too small to reach"), ("G0 X", "X word has no number"),
                         ("G7.5 X1", "G7.5 is not a G-code")]:
        lines = list(base)
        lines[300] = bad
        text = "\n".join(lines) + "\n"
        errors = []
        for fast in (True, False):
            with monkeypatch.context() as m:
                if not fast:
                    m.setattr(interp_module, "_FAST_MIN_LINES", 10 ** 9)
                with pytest.raises(GcodeError) as err:
                    interpret(text, "p.ngc")
            errors.append(str(err.value))
        assert errors[0] == errors[1] and "p.ngc:301" in errors[0] and message in errors[0]


def test_spiral_warnings_are_the_same_both_ways(monkeypatch):
    lines = ["G21 G90 G17 F600"] + [f"G1 X{k % 7} Y{k % 5}" for k in range(150)]
    lines += ["G1 X10 Y0", "G2 X20 Y0 I5.0129 J0"]  # 0.0129 mm off the circle: accepted with a warning
    lines += [f"G1 X{k % 7} Y{k % 5}" for k in range(100)] + ["M2"]
    fast, slow = both("\n".join(lines) + "\n", monkeypatch)
    assert_same(fast, slow)
    assert fast.warnings == (("p.ngc:153", "G2 end point is 0.025800 mm off the circle through its start; accepted "
                                           "as LinuxCNC accepts it (the arc blends its radius: a spiral)"),)


def test_the_token_parser_and_the_character_parser_read_lines_alike():
    rng = random.Random(5)
    atoms = ["1", "2.5", ".5", "#1", "#<a>", "#<_b>", "##2", "-3", "+4", "SIN[30]", "ATAN[1]/[2]", "EXISTS[#<a>]",
             "ABS[-2]", "[1+2]"]
    ops = ["+", "-", "*", "/", "**", "MOD", "EQ", "NE", "GT", "GE", "LT", "LE", "AND", "OR", "XOR"]

    def expr(depth=0):
        if depth > 2 or rng.random() < 0.4:
            return rng.choice(atoms)
        return "[" + expr(depth + 1) + "".join(rng.choice(ops) + expr(depth + 1)
                                               for _ in range(rng.randint(1, 3))) + "]"

    def outcome(parse, code):
        block = lexer.Block()
        try:
            parse(code, 0, block)
        except (lexer.LexError, EvalError) as exc:
            return ("error", str(exc))
        except (lexer._Fallback, IndexError, KeyError, ValueError):
            return ("fallback",)
        return ("ok", repr(block.words), repr(block.g), repr(block.m), repr(block.assign), block.const)

    compared = 0
    for _ in range(4000):
        parts = []
        for _ in range(rng.randint(1, 4)):
            r = rng.random()
            parts.append(f"#{rng.randint(1, 40)}={expr()}" if r < 0.2 else f"#<v>={expr()}" if r < 0.3
                         else rng.choice("GXYZFIJKRSPQM") + expr())
        code = "".join(parts)
        if rng.random() < 0.2:
            k = rng.randrange(len(code))
            code = code[:k] + rng.choice("[]#+-*X1.$") + code[k + 1:]
        code = lexer.split_comments(code)[0]
        fast = outcome(lexer._parse_tokens, code)
        if fast[0] == "fallback":
            continue
        compared += 1
        assert fast == outcome(lexer._parse_chars, code), code
    assert compared > 2000
