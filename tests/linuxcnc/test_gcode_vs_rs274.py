"""flowmc's G-code reader against LinuxCNC's own interpreter, rs274 (Debian package linuxcnc-uspace).

Every move must match rs274's canonical output: kind (traverse, feed, arc), start and end, arc
centre, plane and signed turn count, source line and feed. rs274 prints 4 decimals in the
program's units, so mm programs are held to 1e-4 mm; programs in inches can only be checked to half
a printed digit, 0.00005 in (0.00127 mm) - the inch programs written here use values exact to
4 decimals, so they are held to 1e-4 mm as well. Dwells, spindle and output changes are compared
with rs274's events.
"""

import math
import random
import shutil

import numpy as np
import pytest

from flowmc.devices.linuxcnc.rs274 import ARC, FEED, TRAVERSE, run_rs274
from flowmc.errors import GcodeError
from flowmc.motion.gcode import parse_gcode
from flowmc.motion.gcode_write import path_to_gcode
from flowmc.motion.path import Arc, Dwell, Path

pytestmark = pytest.mark.linuxcnc

MM_TOL = 1e-4
INCH_PRINT_TOL = 0.5e-4 * 25.4 + 1e-9


def test_rs274_is_installed():
    assert shutil.which("rs274"), "LinuxCNC's rs274 is missing: apt-get install -y linuxcnc-uspace"


def line_of(seg) -> int:
    return int(seg.source.rsplit(":", 1)[1])


def assert_moves_agree(path: Path, ref, tol: float = MM_TOL, lines: bool = True) -> None:
    """Move by move: kind, start, end, centre, plane, turns, line (unless told not to) and feed."""
    ours = [s for s in path if not isinstance(s, Dwell)]
    assert len(ours) == len(ref), f"{len(ours)} moves, rs274 made {len(ref)}"
    for k, seg in enumerate(ours):
        where = f"move {k} ({seg.source})"
        kind = ARC if isinstance(seg, Arc) else TRAVERSE if seg.rapid else FEED
        assert kind == ref.kind[k], f"{where}: kind {kind}, rs274 {ref.kind[k]}"
        assert np.max(np.abs(seg.start - ref.start[k])) <= tol, f"{where}: start {seg.start} vs {ref.start[k]}"
        assert np.max(np.abs(seg.end - ref.end[k])) <= tol, f"{where}: end {seg.end} vs {ref.end[k]}"
        if lines and ref.line[k]:
            assert line_of(seg) == ref.line[k], f"{where}: rs274 says line {ref.line[k]}"
        if kind == ARC:
            assert seg.normal_axis == ref.normal_axis[k], f"{where}: plane"
            turn = (seg.turns + 1) * (1 if seg.ccw else -1)
            assert turn == ref.turn[k], f"{where}: turn {turn}, rs274 {ref.turn[k]}"
            assert np.max(np.abs(seg.center - ref.center[k])) <= tol, f"{where}: centre {seg.center} vs {ref.center[k]}"
        if kind != TRAVERSE:
            assert seg.feed == pytest.approx(ref.feed[k], rel=1e-6, abs=1e-9), f"{where}: feed"


def assert_events_agree(path: Path, ref) -> None:
    """Dwells, spindle and output changes against rs274's canonical events."""
    segs = list(path)
    moves_before = np.cumsum([0] + [not isinstance(s, Dwell) for s in segs])[:-1]
    move_list = [s for s in segs if not isinstance(s, Dwell)]
    events = ref.events

    # Zero-second dwells that rs274 has no DWELL for only carry state changes (outputs, spindle).
    ours_dwell = sorted((line_of(s), round(s.seconds, 4)) for s in segs if isinstance(s, Dwell)
                        and not (s.seconds == 0 and not any(
                            e.name == "DWELL" and e.line == line_of(s) for e in events)))
    theirs_dwell = sorted((e.line, round(e.values[0], 4)) for e in events if e.name == "DWELL")
    assert ours_dwell == theirs_dwell

    def changes(names_on, names_off, names_value):
        out = set()
        for e in events:
            if e.name in names_on or e.name in names_off:
                out.add((e.index, "d", int(e.values[0]), e.name in names_on))
            elif e.name in names_value:
                out.add((e.index, "a", int(e.values[0]), round(e.values[1], 6)))
        return out

    theirs_sync = changes({"SET_MOTION_OUTPUT_BIT"}, {"CLEAR_MOTION_OUTPUT_BIT"}, {"SET_MOTION_OUTPUT_VALUE"})
    theirs_now = changes({"SET_AUX_OUTPUT_BIT"}, {"CLEAR_AUX_OUTPUT_BIT"}, {"SET_AUX_OUTPUT_VALUE"})
    ours_sync, ours_now = set(), set()
    for seg, k in zip(segs, moves_before.tolist()):
        target = ours_now if isinstance(seg, Dwell) else ours_sync
        target.update((k, "d", c, v) for c, v in seg.outputs)
        target.update((k, "a", c, round(v, 6)) for c, v in seg.analog)
    assert ours_sync == theirs_sync
    assert ours_now == theirs_now

    # Spindle: the signed rpm in force at each move, replayed from rs274's calls.
    speed, direction, k = 0.0, 0.0, 0
    expected = []
    ordered = sorted(events, key=lambda e: e.index)
    for idx in range(len(move_list)):
        while k < len(ordered) and ordered[k].index <= idx:
            e = ordered[k]
            if e.name == "SET_SPINDLE_SPEED":
                speed = e.values[1]
            elif e.name == "START_SPINDLE_CLOCKWISE":
                direction = 1.0
            elif e.name == "START_SPINDLE_COUNTERCLOCKWISE":
                direction = -1.0
            elif e.name == "STOP_SPINDLE_TURNING":
                direction = 0.0
            k += 1
        expected.append(speed * direction)
    assert [s.spindle for s in move_list] == pytest.approx(expected)
    for e in ordered[k:]:  # calls after the last move: the program's end state
        if e.name == "SET_SPINDLE_SPEED":
            speed = e.values[1]
        elif e.name in ("START_SPINDLE_CLOCKWISE", "START_SPINDLE_COUNTERCLOCKWISE", "STOP_SPINDLE_TURNING"):
            direction = {"START_SPINDLE_CLOCKWISE": 1.0, "START_SPINDLE_COUNTERCLOCKWISE": -1.0}.get(e.name, 0.0)
    if segs:
        assert segs[-1].spindle == pytest.approx(speed * direction)


def check_program(text: str, name: str, tol: float = MM_TOL, events: bool = True) -> Path:
    path = parse_gcode(text, name)
    ref = run_rs274(text, name=name).in_machine_coordinates()
    assert_moves_agree(path, ref, tol)
    if events:
        assert_events_agree(path, ref)
    return path


# ------------------------------------------------------------------ programs written for this test

PLANES = """\
(every plane, both directions, I/J/K and R forms, full circles, helices and turns)
G21 G90 G17 G94
F900
G0 X5 Y5 Z2
G1 Z-1
G2 X15 Y5 I5 J0
G3 X25 Y5 R5
G2 X35 Y5 R-5.2 Z-2
G3 X35 Y5 I-4 J3 (full circle)
G2 X35 Y5 I0 J-3 Z-4 P3 (helix, three turns)
G2 I0 J3 (full circle, no axis words)
G18 G2 X45 Z-4 I5 K0
G3 X55 Z-6 R6
G2 X55 Z-6 K2 I0
G3 X60 Z-1 K2.5 I2.5 P2
G2 X70 R-5 Y3
G19 G2 Y13 Z-1 J5 K0
G3 Y25 Z-3 R-6.5
G2 Y25 Z-3 J0 K-2 X50
G3 Y35 Z-3 R5 P2 X45
G17 G3 X40 Y20 R10 Z0
G2 X40.5 Y20 R0.25 (semicircle)
M2
"""

MODES = """\
%
; incremental moves, absolute arc centres, inches, dwells, spindle and outputs
G21 G90
G0 X10 Y10
F600 G1 X20 Y15 Z-1
G91 G1 X5 Y-5
G2 X10 Y0 I5 J0
G3 X-5 Y5 R5 Z1
G90 G90.1 G2 X40 Y15 I35 J15
G3 X35 Y20 I35 J15
G18 G2 X45 Z0 I40 K0
G19 G3 Y30 Z0 J25 K0 P2
G17 G91.1 G90
G4 P0.5
S1200 M3
G1 X0 Y0 M62 P1
M63 P1
M64 P2
G4 P1.25
M67 E0 Q3.3
G1 X10
M68 E1 Q-2
M65 P2
G0 X12
M4 S500
G20 F24 G1 X1 Y1
F12
G2 X2 Y1 I0.5 J0
G3 X2.5 Y1.5 R0.5
G91 G1 X0.1 Y0.1 Z0.1
G3 X0.6 Y0.8 I0.3 J0.4 Z-0.05
G90 G2 X3.2 Y1.6 R-0.5
G21 G90 G0 X0 Y0 Z5
G1 X1
G0
G1 F300
M5
G61 G40 G49 G54 G80 G94
G64 P0.05 Q0.01
G4 P0
M30
%
G1 X1000 (after the closing percent: never read)
"""


def test_every_plane_direction_and_arc_form_agrees_with_rs274():
    path = check_program(PLANES, "planes.ngc")
    assert {s.normal_axis for s in path if isinstance(s, Arc)} == {0, 1, 2}
    assert any(isinstance(s, Arc) and s.turns == 2 for s in path)


def test_every_mode_dwell_spindle_and_output_agrees_with_rs274():
    path = check_program(MODES, "modes.ngc")
    feeds = {s.source: s.feed for s in path}
    assert feeds["modes.ngc:26"] == pytest.approx(24 / 60)  # F on the G20 line is read in mm
    assert feeds["modes.ngc:28"] == pytest.approx(12 * 25.4 / 60)
    assert feeds["modes.ngc:34"] == pytest.approx(12 * 25.4 / 60)  # back in G21: same speed
    assert sum(isinstance(s, Dwell) for s in path) >= 4
    assert any(s.spindle < 0 for s in path) and any(s.spindle > 0 for s in path)


def random_program(seed: int, n: int = 400, inches: bool = False) -> str:
    """A random program in the subset: every motion form, plane, distance and arc-centre mode.

    Values are printed to 4 decimals, so rs274's printout is exact for end points and I/J/K
    centres. In inches, arc end points sit exactly on their circles (Pythagorean offsets), and R
    arcs are left out (their centres are not exact in 4 printed decimals).
    """
    rng = random.Random(seed)
    lines = ["G20" if inches else "G21", "G90 G17 G91.1", f"F{rng.choice([300, 600, 1200])}"]
    unit = 1 / 25.4 if inches else 1.0
    pos = [0.0, 0.0, 0.0]
    incremental = False
    absolute_centres = False
    plane = 2
    triples = [(3, 4), (4, 3), (5, 12), (12, 5), (8, 15), (0, 5)]

    def q(v):
        return round(v, 4)

    def axis_words(new, axes):
        words = []
        for k in axes:
            value = q(new[k] - pos[k]) if incremental else q(new[k])
            words.append(f"{'XYZ'[k]}{value:.4f}")
        return words

    for _ in range(n):
        r = rng.random()
        if r < 0.05:
            incremental = not incremental
            lines.append("G91" if incremental else "G90")
            continue
        if r < 0.08:
            absolute_centres = not absolute_centres
            lines.append("G90.1" if absolute_centres else "G91.1")
            continue
        if r < 0.12:
            plane = rng.choice([0, 1, 2])
            lines.append({2: "G17", 1: "G18", 0: "G19"}[plane])
            continue
        if r < 0.14:
            lines.append(f"F{rng.choice([100, 250, 800, 1500])}")
            continue
        if r < 0.16:
            lines.append(f"G4 P{rng.choice([0, 0.1, 0.25])}")
            continue
        iu, iv = {2: (0, 1), 1: (2, 0), 0: (1, 2)}[plane]
        normal = plane
        new = list(pos)
        if r < 0.45:
            code = rng.choice(["G0", "G1", "G1"])
            axes = rng.sample([0, 1, 2], rng.choice([1, 2, 3]))
            for k in axes:
                new[k] = q(rng.uniform(-60, 60) * unit)
            lines.append(" ".join([code] + axis_words(new, sorted(axes))))
            pos = [q(v) for v in new]
            continue
        code = rng.choice(["G2", "G3"])
        helix = rng.random() < 0.3
        if helix:
            new[normal] = q(pos[normal] + rng.uniform(-5, 5) * unit)
        extra = []
        if rng.random() < 0.2:
            extra.append(f"P{rng.choice([2, 3])}")
        use_r = not inches and rng.random() < 0.35
        if inches:
            a, b = rng.choice(triples)
            scale = rng.choice([0.05, 0.1, 0.2])
            su, sv = rng.choice([1, -1]), rng.choice([1, -1])
            cu, cv = q(pos[iu] + su * a * scale), q(pos[iv] + sv * b * scale)
            # another lattice point on the same circle
            pu, pv = rng.choice([(a, b), (b, a), (-a, b), (a, -b), (-b, -a), (b, -a)])
            new[iu], new[iv] = q(cu + pu * scale), q(cv + pv * scale)
        else:
            radius = rng.uniform(1, 30)
            cu, cv = q(pos[iu] + radius * math.cos(t := rng.uniform(0, 2 * math.pi))), q(
                pos[iv] + radius * math.sin(t))
            radius = math.hypot(pos[iu] - cu, pos[iv] - cv)
            if rng.random() < 0.15 and not use_r:
                end_angle = math.atan2(pos[iv] - cv, pos[iu] - cu)  # full circle
                new[iu], new[iv] = pos[iu], pos[iv]
            else:
                end_angle = rng.uniform(0, 2 * math.pi)
                new[iu], new[iv] = q(cu + radius * math.cos(end_angle)), q(cv + radius * math.sin(end_angle))
        words = [code] + axis_words(new, [0, 1, 2])
        if use_r:
            if new[iu] == pos[iu] and new[iv] == pos[iv]:
                continue
            chord = math.hypot(new[iu] - pos[iu], new[iv] - pos[iv])
            radius = max(radius, chord / 2 + 0.01)
            words.append(f"R{'-' if rng.random() < 0.3 else ''}{radius:.4f}")
        else:
            letters = {0: "I", 1: "J", 2: "K"}
            for k, c in ((iu, cu), (iv, cv)):
                value = c if absolute_centres else q(c - pos[k])
                words.append(f"{letters[k]}{value:.4f}")
        lines.append(" ".join(words + extra))
        pos = [q(v) for v in new]
    lines.append("M2")
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_random_mm_programs_agree_with_rs274(seed):
    text = random_program(seed)
    path = check_program(text, f"random{seed}.ngc")
    assert sum(isinstance(s, Arc) for s in path) > 100


@pytest.mark.parametrize("seed", [4, 5])
def test_random_inch_programs_agree_with_rs274_to_a_tenth_of_a_micrometre(seed):
    text = random_program(seed, inches=True)
    path = check_program(text, f"inch{seed}.ngc")
    assert sum(isinstance(s, Arc) for s in path) > 100


def test_what_we_write_is_read_by_rs274_as_the_same_moves():
    path = parse_gcode(PLANES, "planes.ngc")
    text = path_to_gcode(path, blend_tolerance=0.05)
    assert_moves_agree(parse_gcode(text, "out.ngc"), run_rs274(text, name="out.ngc"))
    assert_moves_agree(path, run_rs274(text, name="out.ngc"), lines=False)


@pytest.mark.parametrize("text, line, rs274_says", [
    ("G1 X10 F100\nG2 X20 R4\nM2\n", 2, "too small to reach"),
    ("G1 X10 F100\nG2 X20 I5.1 J0\nM2\n", 2, "differs from radius"),
    ("G1 X10 F100\nG2 X10 R5\nM2\n", 2, "same as end point"),
    ("G1 X10 F100\nG2 X20 I5 K1\nM2\n", 2, "K word given"),
    ("G0 X1\nG1 X2\nM2\n", 2, "zero feed rate"),
    ("G1 X1 F100 X2\nM2\n", 1, "Multiple x words"),
])
def test_programs_rs274_refuses_we_refuse_on_the_same_line(text, line, rs274_says):
    with pytest.raises(GcodeError) as theirs:
        run_rs274(text, name="bad.ngc")
    assert rs274_says.lower() in str(theirs.value).lower()
    assert theirs.value.where == f"bad.ngc:{line}"
    with pytest.raises(GcodeError) as ours:
        parse_gcode(text, "bad.ngc")
    assert ours.value.where == f"bad.ngc:{line}"
