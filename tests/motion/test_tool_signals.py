"""The tool (pen) state as "tool" signal events: one rule (flowmc.motion.signals) for planners and step streams.

A plotter path from image contours lifts the pen on each rapid (tool_down=False) and lowers it on
each stroke; the events must land on those segments' starts in every program made from the path.
"""

from __future__ import annotations

import numpy as np
import pytest

import flowmc
from flowmc.motion.contour import Contour, contours_to_path
from flowmc.motion.lookahead import plan_lookahead, plan_stop_and_go
from flowmc.motion.machine import Axis, Machine
from flowmc.motion.path import Dwell, Line, Path
from flowmc.motion.path_steps import path_to_steps
from flowmc.motion.signals import path_signals, step_start_times
from flowmc.motion.trajectory import Signal
from flowmc.plugins import default_registry
from flowmc.registry import NodeType, Out

MACHINE = Machine(axes=(Axis(name="X", step_mm=0.01, vmax=50.0, amax=500.0, max_step_rate=20000.0),
                        Axis(name="Y", step_mm=0.01, vmax=50.0, amax=500.0, max_step_rate=20000.0),
                        Axis(name="Z", min=-50.0, max=50.0)), period=0.002)


def plotter_path() -> Path:
    """Two outlines as the contour tracer gives them: rapid (pen up) to each start, strokes (pen down)."""
    square = Contour(np.array([[10, 10], [30, 10], [30, 30], [10, 30], [10, 10]], dtype=float), True)
    triangle = Contour(np.array([[50, 10], [70, 10], [60, 25], [50, 10]], dtype=float), True)
    return contours_to_path([square, triangle], feed=20.0)


def tool_events(sig: Signal) -> list[tuple[float, float]]:
    sel = sig.kind == "tool"
    return list(zip(sig.t[sel].tolist(), sig.value[sel].tolist()))


def changes(path: Path) -> list[tuple[int, float]]:
    """(segment, 1/0) where the pen must go down/up: every change of tool_down, the tool starting up."""
    down = np.array([s.tool_down for s in path.segments])
    prev = np.concatenate([[False], down[:-1]])
    return [(int(i), float(down[i])) for i in np.flatnonzero(down != prev)]


def tool_state_at(sig: Signal, times: np.ndarray) -> np.ndarray:
    """The tool level after every event at or before each time (up before the first)."""
    sel = sig.kind == "tool"
    k = np.searchsorted(sig.t[sel], times, side="right") - 1
    return np.where(k >= 0, sig.value[sel][np.maximum(k, 0)], 0.0)


def test_the_contour_path_lifts_the_pen_on_rapids_and_lowers_it_on_strokes():
    path = plotter_path()
    assert changes(path) == [(1, 1.0), (5, 0.0), (6, 1.0)]  # the first rapid keeps the pen up
    starts = np.arange(len(path)) * 10.0
    sig = path_signals(path, starts)
    assert tool_events(sig) == [(10.0, 1.0), (50.0, 0.0), (60.0, 1.0)]
    assert set(sig.channel[sig.kind == "tool"].tolist()) == {0}


def test_the_tool_starts_up_and_dwells_do_not_change_it():
    path = Path([
        Line((0, 0, 0), (10, 0, 0)),                      # tool down (the default): an event at its start
        Dwell((10, 0, 0), 0.5, tool_down=False),          # a dwell's own flag is ignored
        Line((10, 0, 0), (10, 10, 0)),                    # still down: no event
        Line((10, 10, 0), (0, 10, 0), rapid=True, tool_down=False),
        Dwell((0, 10, 0), 0.2),                           # tool_down=True on a dwell: still up
        Line((0, 10, 0), (0, 0, 0), rapid=True, tool_down=False),
    ])
    sig = path_signals(path, [0.0, 1.0, 2.0, 3.0, 4.0, 5.0])
    assert tool_events(sig) == [(0.0, 1.0), (3.0, 0.0)]


def test_events_at_one_start_come_outputs_analog_spindle_then_tool():
    path = Path([Line((0, 0, 0), (5, 0, 0), rapid=True, tool_down=False),
                 Line((5, 0, 0), (9, 0, 0), spindle=900.0, outputs=((2, True),), analog=((1, 3.0),))])
    sig = path_signals(path, [0.0, 2.0])
    assert list(zip(sig.t.tolist(), sig.kind.tolist())) == [(2.0, "dout"), (2.0, "da"), (2.0, "spindle_rpm"),
                                                            (2.0, "tool")]


@pytest.mark.parametrize("planner", ["lookahead", "stop_and_go"])
def test_lookahead_trajectories_switch_the_pen_at_each_segment_start_and_at_rest(planner):
    path = plotter_path()
    plan = plan_lookahead(path, MACHINE) if planner == "lookahead" else plan_stop_and_go(path, MACHINE)
    traj = plan.trajectory
    first_row = {i: int(np.flatnonzero(traj.segment == i)[0]) for i in range(len(path))}
    expected = [(first_row[i] * MACHINE.period, v) for i, v in changes(path)]
    got = tool_events(traj.signals)
    assert [v for _, v in got] == [v for _, v in expected]
    np.testing.assert_allclose([t for t, _ in got], [t for t, _ in expected], rtol=0, atol=1e-12)
    # at every setpoint the pen is down exactly when the setpoint belongs to a stroke
    down = tool_state_at(traj.signals, traj.times + 1e-12)
    strokes = np.array([path.segments[i].tool_down for i in traj.segment], dtype=float)
    assert np.array_equal(down, strokes)
    # the pen moves where the table stops: the planner comes to rest at a tool change, and the first
    # setpoint of the segment is less than one period after that rest (speeds within amax * 2T around it)
    for t, _ in got:
        k = int(round(t / MACHINE.period))
        near = traj.speed()[max(k - 1, 0):k + 1]
        assert near.max() <= 500.0 * 2 * MACHINE.period + 1e-9


@pytest.mark.parametrize("method", ["pbp", "dda"])
@pytest.mark.parametrize("tick", [1e-4, 0.0])
def test_step_streams_carry_the_pen_at_the_first_step_of_each_segment(method, tick):
    path = plotter_path()
    steps = path_to_steps(path, 0.01, method, tick=tick)
    rows = np.searchsorted(steps.segment, np.arange(len(path)))
    unit = tick if tick > 0 else 1.0  # untimed: signal times count ticks
    assert tool_events(steps.signals) == [(rows[i] * unit, v) for i, v in changes(path)]
    pos = steps.positions()
    for t, _ in tool_events(steps.signals):
        i = int(round(t / unit))
        seg = path.segments[int(steps.segment[i])]
        # row i of positions() is where the table stands before step i: the segment's start, on the grid
        np.testing.assert_allclose(pos[i], np.rint(seg.start[:2] / 0.01) * 0.01, atol=1e-9)
        assert steps.segment[i - 1] == int(steps.segment[i]) - 1  # the previous step ended the segment before
    assert steps.summary()["signal_events"] == 3


def test_step_start_times_put_stepless_segments_where_the_next_starts():
    segment = np.array([0, 0, 0, 2, 2])  # segment 1 (a dwell) has no steps, segment 3 neither
    np.testing.assert_array_equal(step_start_times(segment, 0.5, 4), [0.0, 1.5, 1.5, 2.5])
    np.testing.assert_array_equal(step_start_times(segment, 0.0, 4), [0, 3, 3, 5])


def test_a_trailing_stepless_segment_signals_after_the_last_step():
    path = Path([Line((0, 0, 0), (0.05, 0, 0)), Line((0.05, 0, 0), (0.05, 0, 0), rapid=True, tool_down=False)])
    steps = path_to_steps(path, 0.01, tick=0.0)
    assert len(steps) == 5
    assert tool_events(steps.signals) == [(0.0, 1.0), (5.0, 0.0)]


def test_interpolator_nodes_and_the_time_division_node_give_the_same_tool_sequence():
    path = plotter_path()
    registry = default_registry().copy()

    @registry.add
    class PlotterPath(NodeType):
        type_id = "test.plotter_path"
        title = "Plotter path"
        category = "Test"
        description = "Two contours, pen up between them."
        outputs = (Out("path", "Path", doc="The path"),)

        def run(self, ctx, params):
            return {"path": path}

    g = flowmc.GraphBuilder(title="pen everywhere")
    src = g.add("test.plotter_path", id="src")
    for node_id, type_id in (("pbp", "interp.point_by_point"), ("dda", "interp.dda"),
                             ("td", "interp.time_division"), ("la", "plan.lookahead")):
        node = g.add(type_id, id=node_id)
        g.wire(src.path, node.path)
    result = flowmc.run(g.build(), registry=registry)
    assert result.ok, result.errors
    expected = [v for _, v in changes(path)]
    for node_id, port in (("pbp", "steps"), ("dda", "steps"), ("td", "trajectory"), ("la", "trajectory")):
        sig = result.output(node_id, port).signals
        assert [v for _, v in tool_events(sig)] == expected, node_id


def test_signal_rows_are_the_first_row_at_or_after_each_event():
    """The rounding the LinuxCNC and GRBL programs put an event on a setpoint row with (Signal.rows): one landing on a
    row by arithmetic (0.1 + 0.2 s, a hair past 0.3 s) is on that row, not the next; others round up; all are kept
    to the rows given."""
    period = 0.1
    sig = Signal([0.0, 0.1 + 0.2, 0.31, 0.75, 9.0], ["dout"] * 5, [1] * 5, [1.0] * 5)
    assert (0.1 + 0.2) / period > 3.0  # the float sum lies just past row 3
    assert sig.rows(period, 0, 6).tolist() == [0, 3, 4, 6, 6]
    assert sig.rows(period, 1, 20).tolist() == [1, 3, 4, 8, 20]
