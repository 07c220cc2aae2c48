"""The planning nodes, run through flowmc.run on small graphs."""

from __future__ import annotations

import json
from pathlib import Path as FsPath

import numpy as np
import pytest

import flowmc
from flowmc.errors import GraphError
from flowmc.motion.lookahead import plan_lookahead, plan_stop_and_go
from flowmc.motion.machine import Machine
from flowmc.motion.metrics import trajectory_report
from flowmc.motion.path import Path

REF = FsPath(__file__).resolve().parents[1] / "data" / "reference" / "paths" / "mixed.json"
POINTS = [[float(x), float(y), 0.0] for x, y in json.loads(REF.read_text())["points"]]
BOUND = json.loads(REF.read_text())["time_optimal_bound_s"]


def _graph(rule="blend", profile="trapezoid", stop_profile="trapezoid", points=POINTS):
    g = flowmc.GraphBuilder(title="planning")
    poly = g.add("path.polyline", id="poly", points=points, feed=200.0)
    mach = g.add("machine", id="machine", period=0.004)
    look = g.add("plan.lookahead", id="look", rule=rule, tolerance=0.05, profile=profile)
    stop = g.add("plan.stop_and_go", id="stop", profile=stop_profile)
    metrics = g.add("plan.metrics", id="metrics", bound=BOUND)
    for node in (look, stop):
        g.wire(poly.path, node.path)
        g.wire(mach.machine, node.machine)
    g.wire(look.trajectory, metrics.trajectory)
    g.wire(poly.path, metrics.path)
    g.wire(mach.machine, metrics.machine)
    return g.build()


@pytest.mark.parametrize("rule,profile", [("blend", "trapezoid"), ("arm_weighted", "scurve"),
                                          ("junction_deviation", "trapezoid")])
def test_planner_nodes_give_what_the_planners_give(rule, profile):
    result = flowmc.run(_graph(rule, profile))
    assert result.ok, result.errors
    path, machine = Path.polyline(POINTS, feed=200.0), Machine(period=0.004)
    direct = plan_lookahead(path, machine, rule=rule, tolerance=0.05, profile=profile)
    traj = result.output("look", "trajectory")
    assert np.array_equal(traj.positions, direct.trajectory.positions)
    assert np.array_equal(traj.segment, direct.trajectory.segment)
    assert result.output("look", "cycle_time") == direct.cycle_time
    stop = result.output("stop", "cycle_time")
    assert stop == plan_stop_and_go(path, machine).cycle_time
    assert result.output("look", "cycle_time") < stop


def test_metrics_node_table():
    result = flowmc.run(_graph())
    assert result.ok, result.errors
    table = result.output("metrics", "table")
    rows = {name: value for name, value in zip(table["name"].tolist(), table["value"].tolist())}
    traj = result.output("look", "trajectory")
    rep = trajectory_report(traj, Path.polyline(POINTS, feed=200.0), Machine(period=0.004), BOUND)
    assert rows["cycle_time"] == rep["cycle_time"] == result.output("metrics", "cycle_time")
    assert rows["time_ratio"] == pytest.approx(rep["cycle_time"] / BOUND)
    assert rows["contour_error"] == result.output("metrics", "contour_error") <= 0.05
    assert result.output("metrics", "peak_accel") <= 1.01  # blends: no corner spikes to leave out
    assert set(table["unit"].tolist()) == {"s", "x bound", "x limit", "mm"}


def test_profile_choices_change_the_stop_and_go_time():
    times = {}
    for profile in ("trapezoid", "exponential", "scurve"):
        result = flowmc.run(_graph(stop_profile=profile))
        assert result.ok, result.errors
        times[profile] = result.output("stop", "cycle_time")
    assert times["trapezoid"] < times["scurve"] and times["trapezoid"] < times["exponential"]


def test_planner_node_errors_name_the_node_and_segment():
    zero_length_end = [[0, 0, 0], [10, 0, 0], [10, 0, 0]]  # a zero-length last segment is fine
    ok = flowmc.run(_graph(points=zero_length_end))
    assert ok.ok, ok.errors
    g = flowmc.GraphBuilder(title="bad")
    g.add("plan.lookahead", id="look", rule="fastest")
    with pytest.raises(GraphError) as info:
        flowmc.run(g.build())
    assert any("look" in str(issue) and "rule" in str(issue) for issue in info.value.issues)
    g = flowmc.GraphBuilder(title="xy machine, 3D path")
    poly = g.add("path.polyline", id="poly", points=[[0, 0, 0], [10, 0, 0], [10, 0, 4]])
    mach = g.add("machine", id="machine", axes=[{"name": "X"}, {"name": "Y"}])
    look = g.add("plan.lookahead", id="look")
    g.wire(poly.path, look.path)
    g.wire(mach.machine, look.machine)
    result = flowmc.run(g.build())
    err = result.nodes["look"].error
    assert err.startswith("node 'look': segment 2 (point 2): moves along Z")
