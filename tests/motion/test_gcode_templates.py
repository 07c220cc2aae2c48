"""Line templates (flowmc/motion/gcode/templates.py): lines that differ only in their numbers share one
parse. Reading with templates must give exactly what the ordinary parse gives: the same Path, the
same parameters, the same errors naming the same line."""

from __future__ import annotations

import math
import random

import numpy as np
import pytest

import flowmc.motion.gcode.templates as templates
from flowmc.errors import GcodeError
from flowmc.motion.gcode import interpret


@pytest.fixture
def without_templates(monkeypatch):
    """Read with every line through the ordinary parse."""
    def read(text: str):
        with monkeypatch.context() as m:
            m.setattr(templates.Templates, "block", lambda self, src, i: None)
            return interpret(text, "t.ngc")
    return read


def _program(seed: int, n: int = 400) -> str:
    rng = random.Random(seed)
    out = ["G21 G90 G17 F600", "#<_safe> = 5", "#100 = 1", "#101 = 0",
           "o<slot> sub", "  G0 X#1 Y#2", "  G1 Z#3 F[#<_safe> * 100]", "  G1 X[#1 + 10] Y#2",
           "  o<slot> return [#1 * 2]", "o<slot> endsub"]
    for _ in range(n):
        r = rng.random()
        a, b = rng.uniform(-50, 50), rng.uniform(-50, 50)
        if r < 0.2:
            out.append(f"#{rng.randint(102, 110)} = [#{rng.randint(100, 110)} * {rng.uniform(0.2, 0.9):.3f} - {b:.2f}]")
        elif r < 0.3:
            out.append(f"N{rng.randint(1, 999)} #100 = [#100 + {abs(a):.1f}] #101 = [#101 MOD 360 + {rng.randint(1, 40)}]")
        elif r < 0.4:
            out.append(f"o<slot> call [{a:.3f}] [#{rng.randint(100, 110)}] [-{rng.choice([1, 2])}]")
            out.append("#<len> = [#<_value> + 1]")
        elif r < 0.5:
            out.append(f"G91 G1 X{a / 10:.4f} Y-{abs(b) / 10:.4f}")
            out.append("G90")
        elif r < 0.6:
            out.append(f"G0 X{a:.3f} Y{b:.3f}")
            out.append(f"G2 X{-a:.3f} Y{-b:.3f} R{math.hypot(a, b) + 1:.3f}")
        elif r < 0.8:
            out.append(f"G1 X[#100 * COS[#101] + {a:.3f}] Y[#100 * SIN[#101]] Z[-.5 - #{rng.randint(100, 110)} / 100]")
        else:
            out.append(f"G0 X{a:.3f} Y{b:.3f} Z#<_safe>")
    out.append("M2")
    return "\n".join(out) + "\n"


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_templates_read_exactly_as_the_ordinary_parse(seed, without_templates):
    text = _program(seed)
    fast, slow = interpret(text, "t.ngc"), without_templates(text)
    a, b = fast.path.columns, slow.path.columns
    assert len(a.kind) == len(b.kind) > 300
    for name in ("kind", "start", "end", "feed", "rapid", "center", "normal_axis", "ccw", "turns", "line"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert fast.parameters == slow.parameters


def test_a_repeated_shape_is_parsed_once(monkeypatch):
    compiled = []
    original = templates.Templates._compile

    def counting(self, texts):
        compiled.append("$".join(texts))
        return original(self, texts)

    monkeypatch.setattr(templates.Templates, "_compile", counting)
    lines = ["G1 F100"] + [f"G1 X[{k}.5 * 2] Y{'-' if k % 2 else ''}{k}" for k in range(300)]
    path = interpret("\n".join(lines) + "\n", "t.ngc").path
    assert path.columns.end[-1].tolist() == [599.0, -299.0, 0.0]
    assert path.columns.end[-2].tolist() == [597.0, 298.0, 0.0]
    assert compiled.count("G1X[$*$]Y$") == 1  # a sign joins its number: Y-3 and Y4 share the shape
    assert not any("-" in shape for shape in compiled)


@pytest.mark.parametrize("expression", ["[7 - 3]", "[#100-3]", "[#100 - -3]", "[#100 * -3]", "[#100 + -3 ** 2]",
                                        "[-3 ** 2]", "[2 ** -3]", "[[#100] - 3]", "[#100 MOD -3]", "[#100 GT -3]",
                                        "[#100 / -3 - 2]", "-[#100 - 3]"])
def test_a_minus_reads_as_in_the_ordinary_parse(expression, without_templates):
    lines = ["G1 F100", "#100 = 5"]
    for k in range(1, 6):
        lines += [f"G1 X{expression.replace('3', str(k))} Y-{k}", f"#101 = {expression.replace('3', str(k + 1))}",
                  "G1 Z#101"]
    text = "\n".join(lines) + "\n"
    fast, slow = interpret(text, "t.ngc"), without_templates(text)
    np.testing.assert_array_equal(fast.path.columns.end, slow.path.columns.end)
    assert len(fast.path.columns.end) == 11


@pytest.mark.parametrize("line", ["G1 X--3", "G1 X+-3", "G1 X[#100 * - -3]", "G1 X[+-3]"])
def test_a_doubled_sign_reads_as_in_the_ordinary_parse(line, without_templates):
    text = f"G1 F100\n#100 = 2\n{line}\n{line.replace('3', '4')}\n"
    try:
        fast = interpret(text, "t.ngc").path.columns.end.tolist()
    except GcodeError as exc:
        fast = (exc.where, exc.message)
    try:
        slow = without_templates(text).path.columns.end.tolist()
    except GcodeError as exc:
        slow = (exc.where, exc.message)
    assert fast == slow


@pytest.mark.parametrize("line, message", [
    ("G1 X1..5", "malformed number"),
    ("G1 X1.2.3", "malformed number"),
    ("1=2", "has no letter before it"),
    ("G1 X[1/0]", "division by zero"),
    ("G1 X[SQRT[-4]]", "square root of a negative number"),
    ("#-2 = 1", "out of range"),
    ("G1 N5 X1", "must come first"),
])
def test_a_line_that_does_not_read_gets_the_ordinary_error(line, message, without_templates):
    text = f"G1 F100\nG1 X1\n{line}\n"
    with pytest.raises(GcodeError) as fast:
        interpret(text, "t.ngc")
    with pytest.raises(GcodeError) as slow:
        without_templates(text)
    assert message in fast.value.message
    assert fast.value.where == slow.value.where == "t.ngc:3"
    assert fast.value.message == slow.value.message


def test_digits_in_a_parameter_name_stay_part_of_the_name():
    text = "#<a1> = 7\n#<b22> = [#<a1> * 2]\nG1 F100 X#<a1> Y#<b22>\nG1 X[#<a1> + 1]\n"
    ends = interpret(text, "t.ngc").path.columns.end
    assert ends.tolist() == [[7.0, 14.0, 0.0], [8.0, 14.0, 0.0]]
