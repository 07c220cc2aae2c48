"""The whole language against LinuxCNC's rs274: parameters, expressions, O-words, offsets, tools, canned
cycles, cutter compensation, splines and spindle-synchronised moves, move by move, in machine
coordinates (rs274's printed program coordinates with its own offset calls applied, as its canon
layer applies them). rs274 reads tool tables and parameter files in inches; so does the reader here
(``machine_units_mm``). Seeded random programs mix all of it.
"""

import math
import random
import re
from pathlib import Path as FsPath

import numpy as np
import pytest

from flowmc.devices.linuxcnc.rs274 import MACHINE_UNITS_MM, run_rs274
from flowmc.errors import GcodeError
from flowmc.motion.gcode import GcodeOptions, ToolTable, interpret, read_var_file
from flowmc.motion.path import Dwell
from gcode_compare import assert_same_moves

pytestmark = pytest.mark.linuxcnc

DATA = FsPath(__file__).parents[1] / "data" / "gcode"
TOOLS = DATA / "tools.tbl"
VAR = DATA / "offsets.var"
SUBS = DATA / "subs"
MM_TOL = 1e-4
INCH_TOL = 0.5e-4 * 25.4 + 1e-9
# rs274 prints program coordinates and the offsets it applies each to 4 decimals; where a program
# moves its offsets, machine coordinates made from both carry both roundings.
OFFSET_TOL = 2 * MM_TOL


def options(var: bool = False, **extra) -> GcodeOptions:
    return GcodeOptions(tool_table=ToolTable.load(TOOLS, units_mm=MACHINE_UNITS_MM), machine_units_mm=MACHINE_UNITS_MM,
                        parameters=read_var_file(VAR) if var else None, subroutine_dirs=(SUBS,), **extra)


def check(text: str, name: str = "t.ngc", *, var: bool = False, tol: float = MM_TOL, lines: bool = True):
    ref = run_rs274(text, name=name, tool_table=TOOLS, parameters=VAR if var else None, subroutine_dir=SUBS)
    result = interpret(text, name, options(var))
    assert_same_moves(result.path, ref.in_machine_coordinates(), tol, lines)
    return result, ref


PARAMETERS = """\
G21 G90 G17 F600
#1 = 2 #2 = [#1 * 3] (#2 reads the old #1: settings take effect after the line's reads)
#<width> = [ATAN[1]/[1] / 4.5]
#<_depth> = -1.5
G1 X[#1 + #2] Y[#<width> ** 2] Z#<_depth>
G1 X[SQRT[#2] * COS[30]] Y[ABS[-3] + FIX[2.7] + FUP[-2.2] + ROUND[2.5] + EXP[0] + LN[1]]
G1 X[7 MOD 3] Y[-7 MOD 3] Z[-2 ** 2 - 5]
G1 X[1 EQ 1.00005] Y[[2 GT 1] AND [3 LE 3] OR [0 XOR 1]] Z[ASIN[1] / 90 + ACOS[1] + TAN[45]]
##1 = 11 (#2 = 11, through #1)
G1 X#2 Y[#5420 + 1] Z#<_z>
G1 X-#1 Y-[#1 + 1]
#3 = [EXISTS[#<width>] + EXISTS[#<nothing>] * 10]
G1 X#3 Y#<_x> Z[#<_metric> * 3]
M2
"""

OWORDS = """\
G21 G90 F900
#10 = 0
o4 do
  #10 = [#10 + 1]
  G1 Z#10
o4 while [#10 LT 3]
o<zig> sub
  #<n> = 0
  o1 while [#<n> LT #1]
    G1 X[#<n> * 2] Y[[#<n> MOD 2] * #2]
    #<n> = [#<n> + 1]
    o2 if [#<n> EQ 3]
      o1 continue
    o2 elseif [#<n> GT 5]
      o1 break
    o2 else
      G1 Z[-#<n> / 10]
    o2 endif
  o1 endwhile
  o<zig> return [#<n> * 10]
o<zig> endsub
o<zig> call [4] [3]
G1 X#<_value> Y#<_value_returned>
o<zig> call [9] [1.5]
G1 X#<_value>
o3 repeat [3]
  G91 G1 X1 Y-0.5
o3 endrepeat
G90
o<frame> call [5] [2] [1200] (a subroutine file)
G1 X[#<_value>]
o<later> call [2]
M2
o<later> sub
  G1 X#1 Y#1
o<later> endsub
"""

OFFSETS = """\
G20 G90 F20
G0 X0 Y0 Z0
G55 G0 X1 Y1
G10 L2 P3 X1 Y2 Z0.5 R30
G56 G1 X1 Y0
G2 X0 Y1 I-1 J0
G10 L20 P3 X0 Y0
G1 X0.5 Y0.5
G54 G0 X0 Y0
G92 X5 Y5
G0 X6 Y6
G92.2
G0 X1 Y1
G92.3
G0 X6 Y5
G92.1
G52 X0.25
G0 X1 Y1
G52 X0
G28 Z0.1
G28.1
G0 X2 Y2
G28
G30 X1
G30.1
G53 G0 X-1 Y-1 Z-1
G0 X0 Y0 Z0
G21 G0 X10
M2
"""

TOOLING = """\
G21 G90 F600
T1 M6
G43
G0 X10 Y10 Z5
T3 M6
G0 X20
G43 H3
G0 Y20
G43.1 Z2.5
G0 X30
G43.2 H2
G0 Y30
G49
G0 Z10
M61 Q4
G43
G0 X0
G10 L1 P2 Z-2
G43 H2
G0 Y0
G10 L10 P1 Z0
G43 H1
G0 X5
S3000 M3 M8
G1 Z-1
M7
M9
M5
M0
M1
M60
M2
"""

CYCLES = """\
G21 G90 G17 F300 S1000 M3
G0 X0 Y0 Z10
G81 X5 Y5 Z-2 R2
X10
G98 G82 X15 Z-3 R1 P0.5
G99 G83 X20 Y10 Z-6 R1 Q1.5
G73 X25 Z-4 R1 Q1
G85 X30 Z-2 R1
G86 X35 Z-2 R1 P0.2
G89 X40 Z-2 R1 P0.3
G84 X45 Z-2 R1
M4
G74 X47 Z-2 R1
M3
G87 X50 Y10 Z-4 R1 I1 J0 K-2
G88 X55 Z-2 R1 P0.1
G80
G0 Z10
G91 G81 X5 Y-2 Z-3 R-8 L3
G90 G0 X10 Y0 Z5
G91 G81 @10 ^45 Z-2 R-3 L2
G90 G80
G18
G0 X0 Y0 Z0
G81 Z5 X-3 Y-2 R1
G19 G81 Y5 Z5 X-3 R1
G17 G80
G0 X0 Y0 Z20
M2
"""

COMP = """\
G20 G90 G17 F20
T1 M6
G0 X-1 Y-1 Z0
G41 G1 X0 Y0
G1 X2
G3 X3 Y1 R1
G1 Y3
G2 X2 Y4 I-1 J0
G1 X1
G1 X1 Y3.5 (a concave corner)
G1 X0 Y4
G1 Z-0.1
G1 Y0.5
G3 X0.5 Y0 R0.5
G40 G1 X-1 Y-1
G42.1 D0.1 G0 X-2 Y0
G1 X4
G1 X4 Y2
G2 X3 Y3 R1
G1 X-2
G40 G0 X-3 Y-3
G18 G41 D2 G1 Z0.5 X-1
G1 Z2
G2 Z3 X0 R1
G40 G1 Z5 X-2
G17
M2
"""

MOTIONS = """\
G21 G90 F600 S1200 M3
G0 X0 Y0 Z0
G5.1 X10 Y5 I5 J5
G5 X20 Y0 I2 J2 P-2 Q-2
G5 X30 Y0 P-2 Q2
G1 X35 Y5
G33 Z-10 K1.5
G0 Z0
G33.1 Z-5 K1
G0 X40 B0 (a rotary word that leaves its axis where it is)
G0 B45 (an indexing move of a rotary axis)
G0 X45
M2
"""

LATHE = """\
G18 G21 G90 F200 S800 M3
O100 SUB
  G0 X2 Z1
  G1 Z0 C0.5
  X6 A1
  #<k> = 0
  O101 WHILE [#<k> LT 2]
    G1 X[8 + #<k> * 2] Z[-5 - #<k> * 4]
    #<k> = [#<k> + 1]
  O101 ENDWHILE
  G2 X14 Z-18 R6
  G1 Z-24
  G3 X18 Z-28 I0 K-4
  G1 X22
O100 ENDSUB
O200 SUB
  G0 X22 Z-30
  G1 X16 Z-30
  G1 X16 Z-20 A1.5
  U-8 Z-12
  W8 C1
  X2 Z0
O200 ENDSUB
G0 X30 Z5
G71 Q100 X24 Z3 D0.4 I1.5 R0.5
G71.1 Q100 X24 Z3 D0.2 I1 R0.3
G71.2 Q100 X24 Z3 D0.2 I1 R0.3
G70 Q100 X24 Z3 D0.4 E0.1 P3
G0 X30 Z5
G72 Q200 X24 Z3 D0.3 I1.2 R0.4
G72.1 Q200 X24 Z3 D0.3 I1.2
G72.2 Q200 X24 Z3 D0.3 I1.2
G71 Q100 X24 Z3 D0.1 I2
G70 Q200 X24 Z3 P1
X30 Z6
G90.1
O300 SUB
  G1 X4 Z0
  G3 X8 Z-4 I4 K-4
  G1 Z-10
  X20
O300 ENDSUB
G71 Q300 X22 Z2 D0.2 I1
O400 SUB (a pocket: G71 cuts it, G71.1 leaves it, G71.2 cuts only it)
  G1 X2 Z0
  X6 Z-4
  X3 Z-8
  X9 Z-10
O400 ENDSUB
G0 X12 Z2
G71 Q400 X10 Z2 D0.2 I1
G71.1 Q400 X10 Z2 D0.2 I1
G71.2 Q400 X10 Z2 D0.2 I1
G0 X30 Z10
M2
"""

# G76 threading: outside and bored threads, degression, compound angle, spring passes, tapers at
# either end or both, a drive line running +Z, diameter mode, Y off the axis, and a tool offset.
THREADING = """\
G18 G21 G90 S500 M3 F100
G0 X12 Z2
G76 P1.5 Z-20 I-1 J0.1 K0.9 R1.5 Q29.5 H2
G0 X12 Z2
G76 P1.25 Z-10 X14 I-0.5 J0.2 K0.8 E2 L1
G0 X12 Z2
G76 P1.25 Z-10 I-0.5 J0.2 K0.8 E2 L2 R2
G0 X12 Z2
G76 P1.25 Z-10 I-0.5 J0.3 K0.8 E1.5 L3 H1
G0 X5 Z-30 Y1
G76 P2 Z-5 I1 J0.25 K1.2 Q30 (a bore, cut towards +Z)
G7 G0 X20 Z2
G76 P1 Z-8 I-1 J0.2 K1.3 (I, J and K as diameters)
G8 G43.1 Z0.5
G0 X10 Z3
G76 P1 Z-8 I-0.6 J0.1 K0.6 R3
M2
"""


@pytest.mark.parametrize("name, text, var, tol, lines", [
    ("parameters.ngc", PARAMETERS, False, MM_TOL, True),
    ("owords.ngc", OWORDS, False, MM_TOL, True),
    ("offsets.ngc", OFFSETS, True, INCH_TOL, True),
    ("tooling.ngc", TOOLING, False, MM_TOL, True),
    ("cycles.ngc", CYCLES, False, MM_TOL, True),
    ("comp.ngc", COMP, False, INCH_TOL, False),  # rs274 names a held move by the line that released it
    ("motions.ngc", MOTIONS, False, MM_TOL, True),
    # rs274 names a lathe cycle's moves by the profile's last line, flowmc by the cycle's line.
    ("lathe.ngc", LATHE, False, MM_TOL, False),
    ("lathe_inch.ngc", LATHE.replace("G21", "G20"), False, INCH_TOL, False),
    ("threading.ngc", THREADING, False, MM_TOL, True),
    ("threading_inch.ngc", THREADING.replace("G21", "G20"), False, INCH_TOL, True),
], ids=lambda v: v if isinstance(v, str) and v.endswith(".ngc") else "")
def test_feature_program_agrees_with_rs274(name, text, var, tol, lines):
    result, ref = check(text, name, var=var, tol=tol, lines=lines)
    assert len(ref) >= 7


def test_pauses_tool_changes_and_coolant_are_events_and_outputs():
    result = interpret(TOOLING, "tooling.ngc", options())
    events = [(seg.source, seg.event.kind, seg.event.tool) for seg in result.path
              if isinstance(seg, Dwell) and seg.event is not None]
    assert events == [("tooling.ngc:2", "tool_change", 1), ("tooling.ngc:5", "tool_change", 3),
                      ("tooling.ngc:29", "pause", None), ("tooling.ngc:30", "optional_pause", None),
                      ("tooling.ngc:31", "pallet_change", None)]
    changes = [(seg.source, seg.outputs) for seg in result.path if seg.outputs]
    # Coolant switches when reached: M8 rides on the move after it; M7 then M9 with no motion between
    # leave mist off and flood off on the next stop (the pause), the last change to a channel winning.
    assert changes == [("tooling.ngc:24", ((1, True),)), ("tooling.ngc:29", ((2, False), (1, False)))]
    assert result.path[-1].spindle == 0.0


def test_the_parameter_file_comes_back_with_what_the_program_changed():
    result = interpret("G20\nG10 L2 P2 X3 Y4\nG0 X1\nG28.1\nM2\n", "p.ngc", options(var=True))
    assert result.parameters[5241] == pytest.approx(3.0) and result.parameters[5242] == pytest.approx(4.0)
    assert result.parameters[5161] == pytest.approx(0.5 + 1.0)  # G28.1 stores the machine position
    assert set(result.parameters) >= set(range(5161, 5391))


# ------------------------------------------------------------------ refused as rs274 refuses them

PROFILE = "G18 G21 F100\nO1 SUB\nG1 X2 Z0\nX6 Z-4\nZ-8\nX4 Z-12\nO1 ENDSUB\n"


@pytest.mark.parametrize("text, line, rs274_says, ours", [
    ("G20 F10 T1 M6\nG41 G1 X0.1\nM2\n", 2, "entry move is not greater", "entry move"),
    ("G20 F10 T1 M6\nG0 X-1\nG41 G1 X0 Y0\nG1 X2\nG1 Y0.1\nG1 X0\nG40 G1 X-1\nM2\n", 6, "cannot be reached",
     "cannot be reached by the tool without gouging"),
    ("G20 F10 T1 M6\nG0 X-1\nG41 G1 X0 Y0\nG3 X0.1 Y0.1 R0.1\nM2\n", 4, "Tool radius not less than arc radius",
     "is not less than the arc radius"),
    ("G20 F10 T1 M6\nG0 X-1\nG41 G1 X0\nG40\nG2 X1 R1\nM2\n", 5, "must be straight", "must be straight"),
    ("G21 F10\nG81 X1 Y1 Z-1\nM2\n", 2, "R clearance plane unspecified", "needs an R word"),
    ("G21 F10\nG81 X1 Y1 Z3 R1\nM2\n", 2, "R less than Z", "below the bottom of the hole"),
    ("G21 F10\nG83 X1 Y1 Z-3 R1\nM2\n", 2, "Q word missing", "needs a Q word"),
    ("G21 F10\nG86 X1 Z-3 R1 P1\nM2\n", 2, "Spindle not turning", "spindle is not turning"),
    ("G21 F10 S100 M3\nG74 X1 Z-3 R1\nM2\n", 2, "Spindle turning clockwise in G74", "left-hand tapping needs M4"),
    ("G21 F10\no1 call\nM2\n", 2, "", "subroutine o1 is not defined"),
    ("G21\n#1 = [1 / 0]\nM2\n", 2, "divide by zero", "division by zero"),
    ("G21\nG1 X#<nope>\nM2\n", 2, "not defined", "#<nope> is not defined"),
    ("G21\nG38.2 Z-1 F10\nM2\n", 2, "", "probing (G38.x) is not supported"),
    (PROFILE + "G71 X10 Z2 D0.2 I1\nM2\n", 8, "requires a Q word", "G71 needs a Q word"),
    (PROFILE.replace("G18", "G17") + "G72 Q1 X10 Z2 D0.2 I1\nM2\n", 8, "only be used in XZ plane",
     "G72 can only be used in the XZ plane (G18)"),
    (PROFILE + "G41.1 D1\nG71.1 Q1 X10 Z2 D0.2 I1\nM2\n", 9, "cannot be used with cutter compensation",
     "G71.1 cannot be used with cutter compensation on"),
    ("G18 G21 S100 M3\nG76 Z-1 I-1 J0.1 K0.5\nM2\n", 2, "P word missing with G76", "G76 needs a P word"),
    ("G18 G21 S100 M3\nG76 P1 Z-1 I-1 K0.5\nM2\n", 2, "I J or K words missing with G76", "needs I, J and K"),
    ("G18 G21 S100 M3\nG76 P1 Z-1 I0 J0.1 K0.5\nM2\n", 2, "I must not be 0", "I must not be 0"),
    ("G18 G21 S100 M3\nG76 P1 Z-1 I-1 J0 K0.5\nM2\n", 2, "J must be greater than 0", "J must be greater than 0"),
    ("G18 G21 S100 M3\nG76 P1 Z-1 I-1 J0.5 K0.5\nM2\n", 2, "K must be greater than J", "K must be greater than J"),
    ("G18 G21 S100\nG76 P1 Z-1 I-1 J0.1 K0.5\nM2\n", 2, "not turning in G76", "spindle turning"),
    ("G18 G21 S100 M3\nG76 P1 Z-1 I-1 J0.1 K0.5 R1000000\nM2\n", 2, "", "passes"),
])
def test_programs_rs274_refuses_we_refuse_on_the_same_line(text, line, rs274_says, ours):
    if rs274_says:
        with pytest.raises(GcodeError) as theirs:
            run_rs274(text, name="bad.ngc", tool_table=TOOLS)
        assert rs274_says.lower() in str(theirs.value).lower()
        assert theirs.value.where == f"bad.ngc:{line}"
    with pytest.raises(GcodeError) as err:
        interpret(text, "bad.ngc", options())
    assert err.value.where == f"bad.ngc:{line}" and ours in err.value.message


def test_a_profile_lathe_cycles_cannot_cut_is_refused_on_the_cycles_line():
    text = PROFILE.replace("X4 Z-12", "X8 Z-2") + "G0 X10 Z2\nG71 Q1 X10 Z2 D0.2 I1\nM2\n"
    with pytest.raises(GcodeError, match="Not monotonic"):
        run_rs274(text, name="bad.ngc")
    with pytest.raises(GcodeError) as err:
        interpret(text, "bad.ngc", options())
    assert err.value.where == "bad.ngc:9" and "G71 cannot cut this profile: Not monotonic" in err.value.message


def test_a_lathe_cycle_that_linuxcnc_would_never_finish_stops_with_an_error():
    # An arc whose end is off its circle (G7x does not check it): rs274 loops here, emitting moves forever.
    text = ("G18 G21 F100 G90.1\nO3 SUB\nG1 X4 Z0\nG3 X12 Z-4 I4 K-4\nG1 Z-10\nX20\nO3 ENDSUB\n"
            "G0 X22 Z2\nG71 Q3 X22 Z2 D0.2 I1\nM2\n")
    with pytest.raises(GcodeError) as err:
        interpret(text, "loop.ngc", options())
    assert err.value.where == "loop.ngc:9" and "does not finish" in err.value.message


@pytest.mark.parametrize("offset, accepted", [(0.0129, True), (0.014, True), (0.0145, False)])
def test_ijk_arcs_off_their_circle_are_accepted_as_linuxcnc_accepts_them_with_a_warning(offset, accepted):
    text = f"G21 G1 X10 F100\nG2 X20 I{5 + offset}\nM2\n"
    if not accepted:
        with pytest.raises(GcodeError, match="differs"):
            run_rs274(text)
        with pytest.raises(GcodeError, match="differs from radius"):
            interpret(text)
        return
    result, _ = check(text, "spiral.ngc")
    arc = result.path[1]
    assert arc.end_radius - arc.radius == pytest.approx(-2 * offset, abs=1e-9)
    np.testing.assert_allclose(arc.point_at(arc.length), arc.end, atol=1e-12)
    assert result.warnings == (("spiral.ngc:2", f"G2 end point is {2 * offset:.6f} mm off the circle through its "
                                                "start; accepted as LinuxCNC accepts it (the arc blends its radius: "
                                                "a spiral)"),)


# ------------------------------------------------------------------ seeded random programs

def random_program(seed: int, n: int = 150) -> str:
    """Parameters and expressions, subroutines with arguments and return values, loops and conditions,
    work offsets (G54-G59.3, G10 L2 with rotation, G92), tool length offsets and canned cycles."""
    rng = random.Random(seed)
    out = ["G21 G90 G17 G94 F600 S2000 M3", "T1 M6", "G43",
           "o<bump> sub", "  G1 X[#1 + #3] Y[#2]", "  G1 Y[#2 + #3 * SIN[#4]]", "  o<bump> return [#1 * 2]",
           "o<bump> endsub"]
    for k in range(n):
        r = rng.random()
        x, y = round(rng.uniform(-40, 40), 3), round(rng.uniform(-40, 40), 3)
        if r < 0.12:
            out.append(f"#{rng.randint(100, 105)} = [{x} * {rng.choice(['SIN', 'COS'])}[{rng.randint(0, 359)}] "
                       f"+ #{rng.randint(100, 105)} / 2]")
        elif r < 0.22:
            out.append(f"G1 X[#{rng.randint(100, 105)} + {x}] Y[{y} - #{rng.randint(100, 105)} MOD 7] "
                       f"Z[-{rng.randint(0, 3)}]")
        elif r < 0.3:
            out.append(f"o<bump> call [{x}] [{y}] [{round(rng.uniform(1, 5), 2)}] [{rng.randint(0, 90)}]")
            out.append("G1 X[#<_value> / 4] Y#<_value_returned>")
        elif r < 0.36:
            label = 200 + k
            out.append(f"o{label} repeat [{rng.randint(1, 3)}]")
            out.append(f"  G91 G1 X{round(rng.uniform(-5, 5), 2)} Y{round(rng.uniform(-5, 5), 2)}")
            out.append(f"o{label} endrepeat")
            out.append("G90")
        elif r < 0.42:
            label = 200 + k
            out.append(f"o{label} if [#{rng.randint(100, 105)} GT 0]")
            out.append(f"  G0 X{x}")
            out.append(f"o{label} else")
            out.append(f"  G0 Y{y}")
            out.append(f"o{label} endif")
        elif r < 0.5:
            code = rng.choice(["G54", "G55", "G56", "G57", "G58", "G59", "G59.1", "G59.2", "G59.3"])
            out.append(f"G10 L2 P{rng.randint(1, 9)} X{x / 4} Y{y / 4} Z{round(rng.uniform(-2, 2), 2)} "
                       f"R{rng.choice([0, 0, 15, 30])}")
            out.append(f"{code} G0 X{x} Y{y}")
        elif r < 0.55:
            out.append(f"G92 X{x} Y{y}" if rng.random() < 0.6 else "G92.1")
        elif r < 0.6:
            out.append(rng.choice([f"G43 H{rng.randint(1, 4)}", "G49", f"G43.1 Z{round(rng.uniform(-3, 3), 2)}"]))
        elif r < 0.7:
            cycle = rng.choice(["G81", "G82 P0.1", "G83 Q1.2", "G73 Q0.8", "G85", "G89 P0.1"])
            out.append(f"{rng.choice(['G98', 'G99'])} {cycle} X{x} Y{y} Z{round(rng.uniform(-6, -1), 2)} "
                       f"R{round(rng.uniform(1, 3), 2)}")
            out.append(f"X{round(x + 3, 3)}")
            out.append("G80")
        elif r < 0.8:
            radius = round(rng.uniform(2, 10), 3)
            out.append(f"G1 X{x} Y{y}")
            out.append(f"G{rng.choice([2, 3])} X{round(x + 2 * radius, 3)} Y{y} I{radius} J0")
        else:
            out.append(f"G0 X{x} Y{y} Z{round(rng.uniform(0, 5), 2)}")
    out.append("M2")
    return "\n".join(out) + "\n"


@pytest.mark.parametrize("seed", [1, 2, 3, 4, 5, 6])
def test_random_programs_with_parameters_owords_offsets_and_cycles_agree_with_rs274(seed):
    text = random_program(seed)
    result, ref = check(text, f"random{seed}.ngc", tol=OFFSET_TOL)
    assert len(ref) > 150
    assert re.search(r"G10 L2", text) and re.search(r"o<bump> call", text)


def test_random_programs_use_rotations_and_every_coordinate_system():
    text = "".join(random_program(seed) for seed in range(1, 7))
    assert all(code in text for code in ("G59.3", "R30", "G92", "G83", "repeat", "else"))
    assert math.isfinite(len(text))
