"""The tool (pen) signal on devices: the simulated card's pen output, pre-flight, and GRBL's pen commands.

Programs come from a contour-like plotter path (rapids pen up, strokes pen down) through the real
planner and step interpolator, so the events are where flowmc.motion.signals puts them.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from flowmc.devices.grbl_program import PEN_COMMANDS, motion_gcode
from flowmc.devices.preflight import preflight
from flowmc.devices.sim import SimCard
from flowmc.errors import DeviceError, LimitError
from flowmc.motion.contour import Contour, contours_to_path
from flowmc.motion.lookahead import plan_lookahead
from flowmc.motion.machine import Axis, Machine
from flowmc.motion.path import Line, Path
from flowmc.motion.path_steps import path_to_steps
from flowmc.motion.trajectory import Signal, Steps

STEP = 0.01
TOLERANCE = 0.05  # plan_lookahead's blend tolerance, mm
PLOTTER = Machine(axes=(Axis(name="X", step_mm=STEP, vmax=50.0, amax=500.0, max_step_rate=20000.0),
                        Axis(name="Y", step_mm=STEP, vmax=50.0, amax=500.0, max_step_rate=20000.0)), period=0.001)


def plotter_path() -> Path:
    square = Contour(np.array([[10, 10], [30, 10], [30, 30], [10, 30], [10, 10]], dtype=float), True)
    triangle = Contour(np.array([[50, 10], [70, 10], [60, 25], [50, 10]], dtype=float), True)
    return contours_to_path([square, triangle], feed=20.0)


def pen_changes(path: Path) -> list[tuple[int, float]]:
    down = np.array([s.tool_down for s in path.segments])
    prev = np.concatenate([[False], down[:-1]])
    return [(int(i), float(down[i])) for i in np.flatnonzero(down != prev)]


def first_rows(segment: np.ndarray, path: Path) -> np.ndarray:
    return np.searchsorted(segment, np.arange(len(path)))


def timeline(changes) -> list[tuple[float, float]]:
    return [(round(c.t, 9), c.value) for c in changes]


# ---------------------------------------------------------------- the simulated card

def test_timed_steps_switch_the_pen_output_at_exactly_the_event_ticks():
    path = plotter_path()
    steps = path_to_steps(path, STEP, "pbp", tick=PLOTTER.period)  # one tick per card period
    log = SimCard(PLOTTER, pen_output=1).run(steps)
    assert log.outcome == "done" and not log.events_of("approach")
    rows = first_rows(steps.segment, path)
    expected = [(round(rows[i] * PLOTTER.period, 9), v) for i, v in pen_changes(path)]
    assert timeline(log.changes_of("dout", 1)) == expected  # the plotter's pen on output 1
    assert timeline(log.changes_of("tool")) == expected  # and the log names it as the tool
    for i, _down in pen_changes(path):
        row = int(rows[i])  # log row k is card period k: the table stands on the segment's start
        np.testing.assert_allclose(log.position[row], path.segments[i].start[:2], atol=1e-9)
    assert log.state["tool_down"] is True and log.state["outputs"][0] is True  # ends on a stroke


def test_untimed_steps_count_signal_times_in_ticks_and_the_card_paces_them():
    path = plotter_path()
    steps = path_to_steps(path, STEP, "pbp", tick=0.0)
    card = SimCard(PLOTTER, pen_output=1)
    log = card.run(steps)
    # the card paces an untimed stream at the fastest rate both axes allow: 1/20 kHz vs 0.01 mm at 50 mm/s
    tick = max(1 / 20000.0, STEP / 50.0)
    rows = first_rows(steps.segment, path)
    expected = [(round(math.ceil(rows[i] * tick / PLOTTER.period - 1e-9) * PLOTTER.period, 9), v)
                for i, v in pen_changes(path)]
    assert timeline(log.changes_of("dout", 1)) == expected
    assert log.duration == pytest.approx(math.ceil(len(steps) * tick / PLOTTER.period) * PLOTTER.period)


def test_a_planned_trajectory_switches_the_pen_at_its_segment_starts():
    path = plotter_path()
    traj = plan_lookahead(path, PLOTTER).trajectory
    log = SimCard(PLOTTER, pen_output=1).run(traj)
    rows = first_rows(traj.segment, path)
    assert timeline(log.changes_of("dout", 1)) == [(round(rows[i] * PLOTTER.period, 9), v)
                                                   for i, v in pen_changes(path)]


def test_the_pen_output_is_a_card_setting_and_0_leaves_it_unwired():
    path = plotter_path()
    steps = path_to_steps(path, STEP, "pbp", tick=PLOTTER.period)
    on4 = SimCard(PLOTTER, pen_output=4).run(steps)
    assert [c.value for c in on4.changes_of("dout", 4)] == [1.0, 0.0, 1.0]
    assert not on4.changes_of("dout", 1)
    unwired = SimCard(PLOTTER, pen_output=0)
    log = unwired.run(steps)
    assert not log.changes_of("dout") and [c.value for c in log.changes_of("tool")] == [1.0, 0.0, 1.0]
    assert unwired.status()["tool_down"] is True and unwired.status()["outputs"] == []
    with pytest.raises(DeviceError, match="pen output 9 does not exist"):
        SimCard(PLOTTER, pen_output=9)


def test_a_program_starts_with_the_pen_up_even_when_the_card_left_it_down():
    path = plotter_path()
    steps = path_to_steps(path, STEP, "pbp", tick=PLOTTER.period)
    first = SimCard(PLOTTER, pen_output=1).run(steps)
    assert first.state["tool_down"] is True  # the drawing ended on a stroke
    again = SimCard(PLOTTER, pen_output=1, state=first.state).run(steps)
    # the card is at the triangle's end, the program starts at (0, 0): the pen lifts before the approach
    (approach,) = again.events_of("approach")
    assert timeline(again.changes_of("tool"))[0] == (round(again.t[0], 9), 0.0)
    assert again.changes_of("dout", 1)[0].t == again.t[0] == approach.t
    assert [c.value for c in again.changes_of("tool")] == [0.0, 1.0, 0.0, 1.0]
    # a program without tool events leaves the pen as it is
    still = SimCard(PLOTTER, pen_output=1, state=first.state).run(Steps(np.ones((3, 2), np.int8), STEP, origin=(50, 10),
                                                          tick=0.001, axes=("X", "Y")))
    assert not still.changes_of("tool") and still.state["tool_down"] is True


def test_lifting_the_pen_on_the_spindle_run_output_while_the_spindle_runs_is_refused():
    line = Path([Line((0, 0, 0), (5, 0, 0), spindle=6000.0),
                 Line((5, 0, 0), (5, 5, 0), rapid=True, tool_down=False, spindle=6000.0)])
    traj = plan_lookahead(line, PLOTTER).trajectory
    card = SimCard(PLOTTER, pen_output=1)
    with pytest.raises(LimitError, match=r"tool up would switch output 1 off, the spindle's run output, while the "
                                         r"spindle runs at 6,000 rpm; give the pen its own output"):
        card.run(traj)
    assert card.clock == 0.0 and card.status()["outputs"] == []  # nothing moved, nothing switched
    log = SimCard(PLOTTER, pen_output=3).run(traj)  # a pen of its own: both work
    assert [c.value for c in log.changes_of("dout", 3)] == [1.0, 0.0]
    assert [c.value for c in log.changes_of("dout", 1)] == [1.0]  # the spindle keeps running


def test_preflight_checks_tool_events_and_names_segments_of_untimed_streams_by_tick():
    path = plotter_path()
    steps = path_to_steps(path, STEP, tick=0.0)
    assert preflight(steps, PLOTTER).signal_events == 3
    bad = Signal([0.0], ["tool"], [0], [0.5])
    with pytest.raises(LimitError, match=r"tool set to 0.5, not 1 \(down\) or 0 \(up\)"):
        preflight(steps, PLOTTER, bad)
    with pytest.raises(LimitError, match="tool channel 2"):
        preflight(steps, PLOTTER, Signal([0.0], ["tool"], [2], [1.0]))
    rows = first_rows(steps.segment, path)
    late = Signal([rows[6] + 3], ["dout"], [12], [1.0])  # 3 ticks into segment index 6, in tick units
    with pytest.raises(LimitError, match=rf"digital output 12 does not exist .* at tick {rows[6] + 3}") as err:
        preflight(steps, PLOTTER, late)
    assert path.segments[6].source == "image contour 2"
    assert err.value.where == "segment 7 (image contour 2)"  # 1-based, with where the segment came from
    assert err.value.details["segment"] == 7 and err.value.details["source"] == "image contour 2"
    far = Steps(np.ones((30, 2), dtype=np.int8), STEP, origin=(199.9, 0.0), axes=("X", "Y"))
    with pytest.raises(LimitError, match=r"X = 200.01 mm beyond soft limit max 200 mm at tick 11"):
        preflight(far, PLOTTER)


def test_io_now_refuses_a_tool_event():
    import flowmc

    g = flowmc.GraphBuilder(title="io now")
    now = g.add("device.io_now", id="now")
    g.input("signals", "Signal", now.signals)
    result = flowmc.run(g.build(), inputs={"signals": Signal([0.0], ["tool"], [0], [1.0])}, start=True)
    assert not result.ok and "a tool (pen) event goes with a program" in result.nodes["now"].error


# ---------------------------------------------------------------- GRBL

_WORD = re.compile(r"([XYZF])(-?\d+(?:\.\d+)?)")


def positions_at_lines(texts: list[str]) -> list[np.ndarray]:
    """Where the machine stands when each line is reached (after every G0/G1 before it)."""
    here = np.zeros(2)
    out = []
    for text in texts:
        out.append(here.copy())
        if text.startswith(("G0", "G1")):
            for letter, value in _WORD.findall(text):
                if letter in "XY":
                    here["XY".index(letter)] = float(value)
    return out


@pytest.mark.parametrize("program", ["trajectory", "untimed steps"])
def test_grbl_program_puts_the_pen_commands_where_the_strokes_start(program):
    path = plotter_path()
    motion = plan_lookahead(path, PLOTTER, tolerance=TOLERANCE).trajectory if program == "trajectory" else \
        path_to_steps(path, STEP, tick=0.0)
    texts = [line.text for line in motion_gcode(motion, PLOTTER, pen=PEN_COMMANDS)]
    pen = [(k, t) for k, t in enumerate(texts) if t in PEN_COMMANDS]
    # M3 S1000 / M5 by default: up before the move to the start (the tool starts up), then down, up, down
    assert [t for _, t in pen] == ["M5", "M3 S1000", "M5", "M3 S1000"]
    assert texts[:5] == ["G21", "G90", "G94", "M5", "G0 X0 Y0"]
    pen = pen[1:]
    where = positions_at_lines(texts)
    for (k, _), (i, _) in zip(pen, pen_changes(path)):
        np.testing.assert_allclose(where[k], path.segments[i].start[:2], atol=0.011)  # 4 decimals, or a step
        assert texts[k + 1].startswith("G1")  # the stroke or rapid follows
    # between pen down and pen up the moves trace the square; after the last pen down, the triangle
    square_end = pen[1][0]
    drawn = np.array(where[pen[0][0]:square_end + 1])
    # a planned trajectory may pass a corner outside the programmed one, within the plan's 0.05 mm tolerance
    near = TOLERANCE + 0.001 if program == "trajectory" else 0.011
    assert drawn[:, 0].min() == pytest.approx(10, abs=near) and drawn[:, 0].max() == pytest.approx(30, abs=near)


def test_grbl_pen_commands_are_configurable_and_conflict_with_a_spindle_program():
    path = plotter_path()
    traj = plan_lookahead(path, PLOTTER).trajectory
    texts = [line.text for line in motion_gcode(traj, PLOTTER, pen=("M8", "M9"))]
    assert [t for t in texts if t in ("M8", "M9")] == ["M9", "M8", "M9", "M8"]
    none = [line.text for line in motion_gcode(traj, PLOTTER, pen=None)]
    assert not [t for t in none if t.startswith("M")]
    spindle = Signal([0.0], ["spindle_rpm"], [0], [8000.0])
    with pytest.raises(DeviceError, match=r"drive the spindle too; give the pen commands that do not"):
        motion_gcode(traj, PLOTTER, spindle, pen=PEN_COMMANDS)
    both = [line.text for line in motion_gcode(traj, PLOTTER, spindle, pen=("M8", "M9"))]
    assert both[3:6] == ["M9", "G0 X0 Y0", "M3 S8000"] and both.count("M8") == 2
    with pytest.raises(DeviceError, match="pen up command must be one line"):
        motion_gcode(traj, PLOTTER, pen=("M3 S1000", "M5\nG0 X0"))


def test_grbl_board_receives_the_pen_commands(grbl_sim):  # noqa: F811
    from flowmc.devices.backends import open_device

    sim = grbl_sim(line_time=0.0005)
    path = plotter_path()
    traj = plan_lookahead(path, PLOTTER).trajectory
    machine = Machine(axes=PLOTTER.axes + (Axis(name="Z", min=-50, max=50),), period=PLOTTER.period)
    with open_device(f"grbl:{sim.port}", machine, timeout=5.0, pen=("M3 S255", "M5")) as card:
        log = card.run(traj)
    assert log.outcome == "done"
    assert [t for t in sim.received if t.startswith("M")] == ["M5", "M3 S255", "M5", "M3 S255"]
    assert sim.received == [line.text for line in motion_gcode(traj, machine, pen=("M3 S255", "M5"))]


def test_by_default_no_pen_is_driven_so_a_milling_program_with_rapids_and_a_spindle_runs():
    from flowmc.devices.linuxcnc.card import trajectory_gcode
    from flowmc.motion.gcode import parse_gcode

    path = parse_gcode("G21 G90\nM3 S8000\nG0 X10 Y5\nG1 X30 F600\nG0 Z5\nG0 X0 Y0\nM5\nM2\n")
    machine = Machine(axes=(Axis(name="X"), Axis(name="Y"), Axis(name="Z", min=-50, max=50)))
    traj = plan_lookahead(path, machine).trajectory
    assert "tool" in set(traj.signals.kind.tolist())  # the path says when the tool is "up" ...
    log = SimCard(machine).run(traj)  # ... but the spindle's run output is not taken over by a pen
    assert log.outcome == "done"
    assert [c.value for c in log.changes if c.kind == "dout" and c.channel == 1] == [1.0, 0.0]  # spindle run
    grbl = [line.text for line in motion_gcode(traj, machine)]
    assert [t for t in grbl if t.startswith("M")] == ["M3 S8000", "M5"]
    assert "M62" not in trajectory_gcode(traj.positions, traj.axes, traj.period, traj.signals)
