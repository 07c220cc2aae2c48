"""Subroutine bodies run as one compiled function (flowmc/motion/gcode/bodies.py) must read exactly as
line by line: the same Path, parameters and warnings, the same errors naming the same line and
calls, the same line budget."""

from __future__ import annotations

import random

import numpy as np
import pytest

import flowmc.motion.gcode.interp as interp_module
from flowmc.errors import GcodeError
from flowmc.motion.gcode import GcodeOptions, interpret
from flowmc.motion.gcode.interp import Interpreter

_SUBS = """G21 G90 G17 F600
#<_step> = 0.5
o<bore> sub
  #<z> = 0
  G0 X[#1 + #4] Y#2 (to the start)
  G1 Z0 F300
  o1 while [#<z> GT #3]
    #<z> = [#<z> - #<_step>]
    o2 if [#<z> LT -1.2]
      o1 break
    o2 elseif [#<z> LT -0.7]
      G2 X[#1 + #4] Y#2 I[-#4] J0 Z#<z> F900
      o1 continue
    o2 else
      G3 X[#1 + #4] Y#2 I[-#4] J0 Z#<z>
    o2 endif
    #100 = [#100 + 1]
  o1 endwhile
  o3 if [#4 GT 2]
    o<bore> return [#4 * 2]
  o3 endif
  M8
  G0 Z5
o<bore> endsub [#<z>]
o<slot> sub
  G0 X#1 Y#2
  G1 X#3 Y#4 Z-1 F[#<_step> * 1000]
  M9
o<slot> endsub
#100 = 0
"""


def _program(seed: int, n: int = 120) -> str:
    rng = random.Random(seed)
    out = [_SUBS]
    for _ in range(n):
        r = rng.random()
        if r < 0.4:
            out.append(f"o<bore> call [{rng.uniform(-50, 50):.3f}] [{rng.uniform(-50, 50):.3f}] "
                       f"[-{rng.choice([0.4, 1, 1.5, 2])}] [{rng.uniform(1, 4):.2f}]")
            out.append("#101 = [#101 + #<_value>]")
        elif r < 0.6:
            out.append(f"o<slot> call [{rng.uniform(-50, 50):.3f}] [#100] [{rng.uniform(-50, 50):.3f}] [#101]")
        elif r < 0.8:
            out.append(f"G1 X[#100 * COS[#101]] Y[{rng.uniform(-9, 9):.3f}] F1200")
        else:
            out.append(f"G91 G0 X{rng.uniform(-5, 5):.3f}\nG90")
    out.append("M2")
    return "\n".join(out) + "\n"


@pytest.fixture
def line_by_line(monkeypatch):
    """Read with every subroutine body run line by line."""
    def read(text: str):
        with monkeypatch.context() as m:
            m.setattr(interp_module, "compile_body", lambda *args: None)
            return interpret(text, "t.ngc")
    return read


def _same(a, b) -> None:
    ca, cb = a.path.columns, b.path.columns
    for name in ("kind", "start", "end", "feed", "rapid", "center", "normal_axis", "ccw", "turns", "seconds", "file",
                 "line", "spindle"):
        assert np.array_equal(getattr(ca, name), getattr(cb, name)), name
    assert ca.outputs == cb.outputs
    assert a.parameters == b.parameters
    assert a.warnings == b.warnings and a.messages == b.messages


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_compiled_bodies_read_exactly_as_line_by_line(seed, line_by_line):
    text = _program(seed)
    interp = Interpreter(GcodeOptions())
    interp.run(text, "t.ngc")
    assert sorted(at for (_, at), body in interp.bodies.items() if body is not None) == [2, 24]
    _same(interpret(text, "t.ngc"), line_by_line(text))


@pytest.mark.parametrize("body, message", [
    ("  o1 while [#1 LT 5]\n    #1 = [#1 + 1]\n    #2 = [1 / [#1 - 3]]\n  o1 endwhile\n", "division by zero"),
    ("  o1 if [#1 GT 0]\n    G1 X1 F0\n  o1 endif\n", "G1 with no feed rate"),
    ("  o1 if [#1 GT 9]\n  o1 elseif [SQRT[-#1] GT 0]\n  o1 endif\n", "square root"),
])
def test_an_error_in_a_compiled_body_names_the_same_line_and_call(body, message, line_by_line):
    text = f"G21 G90\no<s> sub\n{body}o<s> endsub\nG0 X0\no<s> call [1]\nM2\n"
    with pytest.raises(GcodeError) as compiled:
        interpret(text, "t.ngc")
    with pytest.raises(GcodeError) as slow:
        line_by_line(text)
    assert message in str(compiled.value)
    assert "called from t.ngc:" in str(compiled.value)
    assert str(compiled.value) == str(slow.value)


def test_an_endless_loop_in_a_compiled_body_stops_at_the_same_line(monkeypatch):
    text = ("G21 G90 F100\no<s> sub\n  o1 while [1]\n    G1 X[#1] Y0\n    #1 = [#1 + 1]\n  o1 endwhile\n"
            "o<s> endsub\no<s> call\nM2\n")
    options = GcodeOptions(max_blocks=500)
    errors = []
    for disabled in (False, True):
        with monkeypatch.context() as m:
            if disabled:
                m.setattr(interp_module, "compile_body", lambda *args: None)
            with pytest.raises(GcodeError) as err:
                interpret(text, "t.ngc", options)
            errors.append(str(err.value))
    assert "more than 500 lines" in errors[0]
    assert errors[0] == errors[1]
