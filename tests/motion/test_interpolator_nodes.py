"""The step interpolator nodes run through flowmc.run on small graphs, against the motion functions."""

import numpy as np
import pytest

import flowmc
from flowmc.motion.linkage import path_linkage_table
from flowmc.motion.machine import Axis, Machine, default_machine
from flowmc.motion.path_steps import path_to_steps
from flowmc.motion.segment_table import path_from_rows

ROWS = [
    {"type": "line", "end": (12.0, 7.0, 0.0)},
    {"type": "arc", "direction": "ccw", "radius": 5.0, "start_angle": -90.0, "end_angle": 180.0},
    {"type": "ellipse", "direction": "cw", "a": 6.0, "b": 3.0, "start_angle": 90.0, "end_angle": -90.0},
    {"type": "line", "end": (0.0, 0.0, 0.0), "feed": 80.0},
]


def table_path():
    return path_from_rows(ROWS, start=(0, 0, 0), feed=40.0)


def graph(node_type, machine_input=False, **params):
    g = flowmc.GraphBuilder()
    src = g.add("path.segment_table", id="src", rows=ROWS, feed=40.0)
    node = g.add(node_type, id="interp", **params)
    g.wire(src.path, node.path)
    if machine_input:
        g.input("machine", "Machine", node.machine)
    return g, node


def machine(step_x, step_y, rate=100_000.0):
    return Machine(axes=(Axis(name="X", step_mm=step_x, max_step_rate=rate),
                         Axis(name="Y", step_mm=step_y, max_step_rate=rate), Axis(name="Z")))


def test_point_by_point_node_is_path_to_steps_on_the_default_machine():
    g, node = graph("interp.point_by_point")
    g.output("steps", "Steps", node.steps)
    result = flowmc.run(g.build())
    assert result.ok, result.errors
    steps = result.outputs["steps"]
    d = default_machine()
    expected = path_to_steps(table_path(), (d.axes[0].step_mm, d.axes[1].step_mm), "pbp")
    assert steps.digest() == expected.digest()
    assert np.all(np.abs(steps.steps).sum(axis=1) == 1)
    pulses = np.count_nonzero(steps.steps, axis=0)
    assert result.nodes["interp"].logs == [f"{len(steps)} ticks, {pulses[0]} X and {pulses[1]} Y pulses"]


def test_dda_node_takes_the_machine_and_register_settings():
    g, node = graph("interp.dda", machine_input=True, bits=14, preset="zero", tick_s=1e-5)
    g.output("steps", "Steps", node.steps)
    m = machine(0.005, 0.01)
    result = flowmc.run(g.build(), inputs={"machine": m})
    assert result.ok, result.errors
    steps = result.outputs["steps"]
    expected = path_to_steps(table_path(), (0.005, 0.01), "dda", bits=14, preset="zero", tick=1e-5)
    assert steps.digest() == expected.digest()
    assert steps.tick == 1e-5 and steps.step_mm.tolist() == [0.005, 0.01]
    assert np.allclose(steps.positions()[-1], [0.0, 0.0])
    # the first line is one 14-bit DDA block of 2**14 ticks
    assert np.count_nonzero(steps.segment == 0) == 2**14


def test_dda_register_size_can_come_down_a_wire():
    g, node = graph("interp.dda")
    bits = g.add("basic.number", id="bits", value=13.0)
    g.wire(bits.value, node.bits)
    g.output("steps", "Steps", node.steps)
    result = flowmc.run(g.build())
    assert result.ok, result.errors
    d = default_machine()
    expected = path_to_steps(table_path(), (d.axes[0].step_mm, d.axes[1].step_mm), "dda", bits=13)
    assert result.outputs["steps"].digest() == expected.digest()


def test_linkage_table_node_uses_step_sizes_and_step_rates():
    g, node = graph("interp.linkage_table", machine_input=True, chord_tol=0.002)
    g.output("table", "Table", node.table)
    g.output("duration", "Number", node.duration)
    m = machine(0.01, 0.02, rate=3000.0)
    result = flowmc.run(g.build(), inputs={"machine": m})
    assert result.ok, result.errors
    table = result.outputs["table"]
    expected = path_linkage_table(table_path(), (0.01, 0.02), (3000.0, 3000.0), 0.002)
    assert table.digest() == expected.digest()
    assert result.outputs["duration"] == pytest.approx(float(table["duration_s"].sum()))
    # 40 mm/s on 0.01 mm steps needs up to 4000 Hz: some moves are slowed, and the log says how many
    limited = int(table["rate_limited"].sum())
    assert limited > 0 and max(table["x_freq_hz"].max(), table["y_freq_hz"].max()) <= 3000.0 * (1 + 1e-12)
    assert result.nodes["interp"].logs == [f"{len(table)} rows, {limited} slowed to the max step rate"]


def test_a_register_too_small_fails_the_node_naming_the_segment():
    g, node = graph("interp.dda", bits=10)
    g.output("steps", "Steps", node.steps)
    result = flowmc.run(g.build())
    assert not result.ok
    assert result.errors == ["node 'interp': segment 1 (row 1): DDA register too small for this line: 10 bits hold "
                             "integrands below 1024, but it needs 4800 (at least 13 bits)"]


def test_a_machine_without_a_y_axis_is_refused():
    g, node = graph("interp.point_by_point", machine_input=True)
    g.output("steps", "Steps", node.steps)
    m = Machine(axes=(Axis(name="X"), Axis(name="Z")))
    result = flowmc.run(g.build(), inputs={"machine": m})
    assert not result.ok
    assert result.errors == ["node 'interp': the machine needs axes named X and Y, it has X, Z"]
