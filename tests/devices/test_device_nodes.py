"""Device nodes through flowmc.run on small graphs."""

from __future__ import annotations

import json

import numpy as np
import pytest

import flowmc
from device_programs import PATTERN
from flowmc.devices.log import DeviceLog
from flowmc.motion.table import Table

ROWS = json.loads(PATTERN.read_text())["segments"]


def _pattern_graph(device_params: dict | None = None, machine_params: dict | None = None):
    g = flowmc.GraphBuilder(title="thesis pattern on the card")
    m = g.add("machine", id="m", period=0.001, **(machine_params or {}))
    p = g.add("path.segment_table", id="p", rows=ROWS, feed=20.0)
    i = g.add("interp.time_division", id="i", profile="trapezoid")
    g.wire(p.path, i.path)
    g.wire(m.machine, i.machine)
    pen = g.add("device.digital_io", id="pen", channel=3, at="segment",
                changes=[{"at": 1, "on": True}, {"at": 6, "on": False}])  # segments count from 1
    g.wire(i.trajectory, pen.motion)
    spindle = g.add("device.analog", id="spindle", mode="rpm", changes=[{"at": 0.0, "value": 12000.0}])
    g.wire(pen.signals, spindle.signals)
    card = g.add("device.card_output", id="card", **(device_params or {}))
    g.wire(i.trajectory, card.motion)
    g.wire(m.machine, card.machine)
    g.wire(spindle.signals, card.signals)
    g.output("log", "Log", card.log)
    return g


def test_card_output_runs_the_pattern_and_the_same_graph_twice_gives_the_identical_log():
    graph = _pattern_graph().build()
    first = flowmc.run(graph, start=True)
    second = flowmc.run(graph, start=True)
    assert first.ok and second.ok, first.errors + second.errors
    a, b = first.outputs["log"], second.outputs["log"]
    assert isinstance(a, DeviceLog) and a.outcome == "done"
    assert first.nodes["card"].status == second.nodes["card"].status == "done"  # never cached
    assert a.digest() == b.digest()
    assert a.summary() == b.summary()
    assert np.array_equal(a.position, b.position) and a.changes == b.changes
    assert a.end_position == pytest.approx([0, 0, 0])
    pen = a.changes_of("dout", 3)
    assert [c.value for c in pen] == [1.0, 0.0]
    assert pen[1].t > 0.5 * a.duration  # at the start of the last segment
    assert a.changes_of("spindle_rpm")[0].value == pytest.approx(12000.0, rel=1e-3)
    json.dumps(a.summary())


def test_closed_loop_card_output_reports_following_error():
    result = flowmc.run(_pattern_graph({"closed_loop": True}).build(), start=True)
    assert result.ok, result.errors
    log = result.outputs["log"]
    assert 0 < max(log.summary()["max_following_error_mm"]) < 0.05


def test_preflight_failure_in_card_output_names_the_segment_and_sends_nothing():
    axes = [{"name": "X", "min": -60, "max": 60}, {"name": "Y"}, {"name": "Z", "min": -50, "max": 50}]
    result = flowmc.run(_pattern_graph(machine_params={"axes": axes}).build(), start=True)
    assert not result.ok
    assert result.nodes["card"].status == "failed"
    assert "node 'card': segment 4 (row 4): X = -60.00" in result.nodes["card"].error
    assert "beyond soft limit min -60 mm" in result.nodes["card"].error


def test_preflight_names_the_table_row_behind_a_spin_up_dwell():
    """The thesis pattern behind lib.spindle_on's spin-up dwell on a machine whose X travel is -60..60:
    the first setpoint past X = -60 is on the cw arc, the table's row 4, which is the program's 5th segment."""
    g = flowmc.GraphBuilder(title="thesis pattern, spindle on, short X travel")
    axes = [{"name": "X", "min": -60, "max": 60}, {"name": "Y"}, {"name": "Z", "min": -50, "max": 50}]
    m = g.add("machine", id="m", period=0.001, axes=axes)
    p = g.add("path.segment_table", id="p", rows=ROWS, feed=20.0)
    spindle = g.add("lib.spindle_on", id="spindle")
    plan = g.add("plan.lookahead", id="plan")
    check = g.add("device.preflight", id="check")
    g.wire(p.path, spindle.path)
    g.wire(spindle.path, plan.path)
    g.wire(m.machine, plan.machine)
    g.wire(plan.trajectory, check.motion)
    g.wire(m.machine, check.machine)
    result = flowmc.run(g.build(), start=True)
    path = result.nodes["spindle"].outputs["path"]
    assert path.segments[0].kind == "dwell" and path.segments[0].source == "node spindle: spin-up"
    arc = path.segments[4]
    assert ROWS[3]["type"] == "arc" and ROWS[3]["direction"] == "cw"
    assert arc.kind == "arc" and not arc.ccw and arc.source == "row 4"
    traj = result.nodes["plan"].outputs["trajectory"]
    assert traj.segment_names == path.segment_names()
    first = int(np.flatnonzero(traj.positions[:, 0] < -60.0)[0])
    assert traj.segment[first] == 4  # 0-based index 4: segment 5 as users count
    assert result.nodes["check"].status == "failed"
    error = result.nodes["check"].error
    assert error.startswith("node 'check': segment 5 (row 4): X = -60.0")
    assert f"beyond soft limit min -60 mm at t={first * traj.period:.3f} s" in error


def test_changes_at_segments_count_from_one_and_a_missing_segment_is_named():
    def run_pen(at: list[float]):
        g = flowmc.GraphBuilder()
        m = g.add("machine", id="m", period=0.001)
        p = g.add("path.segment_table", id="p", rows=ROWS, feed=20.0)
        i = g.add("interp.time_division", id="i", profile="trapezoid")
        g.wire(p.path, i.path)
        g.wire(m.machine, i.machine)
        pen = g.add("device.digital_io", id="pen", channel=3, at="segment",
                    changes=[{"at": k, "on": True} for k in at])
        g.wire(i.trajectory, pen.motion)
        g.output("signals", "Signal", pen.signals)
        return flowmc.run(g.build(), start=True)

    result = run_pen([1, 2, 6])
    assert result.ok, result.errors
    traj = result.nodes["i"].outputs["trajectory"]
    starts = [int(np.flatnonzero(traj.segment == k)[0]) * traj.period for k in (0, 1, 5)]
    assert result.outputs["signals"].t.tolist() == pytest.approx(starts)
    assert starts[0] == 0.0 < starts[1]  # segment 1 is the first row's segment, at the program's start
    for at in (0, 7, 2.5):
        error = run_pen([at]).nodes["pen"].error
        assert error == f"node 'pen': segment {at:g}: no such segment in the program; its segments are numbered 1 to 6"


def test_preflight_node_reports_per_axis_figures():
    g = _pattern_graph()
    check = g.add("device.preflight", id="check")
    g.wire("i.trajectory", check.motion)
    g.wire("m.machine", check.machine)
    g.output("report", "Table", check.report)
    result = flowmc.run(g.build(), start=True)
    assert result.ok, result.errors
    table = result.outputs["report"]
    assert isinstance(table, Table) and list(table["axis"]) == ["X", "Y", "Z"]
    assert table["min_mm"][0] == pytest.approx(-75.0, abs=0.01)
    assert np.all(table["peak_v_mm_s"] <= 20.0 + 1e-6)


def test_home_then_card_output_carries_the_sim_state_on():
    g = flowmc.GraphBuilder()
    m = g.add("machine", id="m", period=0.001)
    home = g.add("device.home", id="home", axes="X", method="midpoint")
    g.wire(m.machine, home.machine)
    line = g.add("path.polyline", id="line", points=[(0, 0, 0), (10, 0, 0)], feed=20.0)
    i = g.add("interp.time_division", id="i", profile="trapezoid")
    g.wire(line.path, i.path)
    g.wire(m.machine, i.machine)
    card = g.add("device.card_output", id="card")
    g.wire(i.trajectory, card.motion)
    g.wire(m.machine, card.machine)
    g.wire(home.log, card.after)
    g.output("homed", "Log", home.log)
    g.output("log", "Log", card.log)
    result = flowmc.run(g.build(), start=True)
    assert result.ok, result.errors
    homed, log = result.outputs["homed"], result.outputs["log"]
    assert homed.events_of("home")[0].axis == "X"
    assert log.t[0] == pytest.approx(homed.t[-1])  # the card's clock carried on
    assert log.end_position == pytest.approx([10, 0, 0])


def test_pwm_and_io_now_nodes():
    g = flowmc.GraphBuilder()
    pwm = g.add("device.pwm", id="pwm", frequency=20_000.0, changes=[{"at": 0.0, "duty": 40.0}])
    dio = g.add("device.digital_io", id="dio", channel=5, changes=[{"at": 0.0, "on": True}])
    g.wire(pwm.signals, dio.signals)
    now = g.add("device.io_now", id="now", analog="pwm")
    g.wire(dio.signals, now.signals)
    g.output("log", "Log", now.log)
    g.output("inputs", "Number", now.inputs)
    result = flowmc.run(g.build(), start=True)
    assert result.ok, result.errors
    log = result.outputs["log"]
    assert log.changes_of("pwm_freq")[0].value == pytest.approx(20_000.0)
    assert log.changes_of("pwm_duty")[0].value == pytest.approx(40.0)
    assert log.state["outputs"][4] is True
    mask = int(result.outputs["inputs"])
    assert mask == (1 << 9) | (1 << 12) | (1 << 15)  # inputs 10, 13, 16: each axis on its home cam


def test_pwm_outside_the_card_range_is_refused_when_the_graph_is_checked():
    g = flowmc.GraphBuilder()
    g.add("device.pwm", id="pwm", frequency=10.0)
    issues = flowmc.validate(g.build())
    assert issues and any("pwm" in str(issue) for issue in issues)


def test_an_unknown_device_is_refused_listing_the_known_ones():
    g = flowmc.GraphBuilder()
    g.add("device.home", id="home", device="plotter")
    issues = flowmc.validate(g.build())
    text = " ".join(str(issue) for issue in issues)
    assert "unknown device 'plotter'" in text and "grbl:<serial port>" in text and "linuxcnc" in text
