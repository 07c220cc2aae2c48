"""The NURBS and time-division interpolator nodes, run through flowmc.run on small graphs."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

import flowmc
from flowmc.motion import nurbs, timediv
from flowmc.motion.path import Dwell, EllipseArc, Line, NurbsCurve
from flowmc.motion.path import Path as PathValue
from flowmc.plugins import default_registry
from flowmc.registry import NodeType, Out

REF = Path(__file__).resolve().parents[1] / "data" / "reference" / "nurbs_test_curve.json"


#: The real Machine node's axes for these tests: amax 1000 mm/s^2, jmax 20000 mm/s^3 on X, Y, Z.
AXES = [{"name": n, "amax": 1000.0, "jmax": 20000.0} for n in "XYZ"]


class MixedPathSource(NodeType):
    """A path no table row makes: I/O and spindle changes, a dwell, an ellipse arc and a NURBS."""

    type_id = "test.mixed_path"
    title = "Mixed path"
    category = "Test"
    description = "Line with I/O, dwell, ellipse arc, NURBS."
    outputs = (Out("path", "Path", doc="path"),)

    def run(self, ctx, params):
        ell = EllipseArc.from_axes((0, 0, 0), 20.0, 10.0, 0.0, 0.0, math.pi / 2, feed=80.0)
        line = Line((0, -30, 0), ell.start, feed=80.0, outputs=((3, True),), spindle=1200.0)
        dwell = Dwell(ell.start, 0.1, spindle=1200.0)
        ell = ell.with_state(analog=((0, 2.5),), spindle=1200.0)
        curve = NurbsCurve([ell.end, (-10, 20, 0), (-20, 0, 0), (-30, 10, 0)], feed=60.0, spindle=0.0)
        return {"path": PathValue([line, dwell, ell, curve])}


@pytest.fixture(scope="module")
def registry():
    reg = default_registry().copy()
    reg.add(MixedPathSource)
    return reg


@pytest.fixture(scope="module")
def spec():
    return json.loads(REF.read_text())


def _nurbs_graph(spec, feed, period, corrector=1):
    g = flowmc.GraphBuilder(title="nurbs")
    ctrl = [[x, y, 0.0] for x, y in spec["control_points"]]
    src = g.add("path.nurbs", id="curve", control_points=ctrl, weights=spec["weights"], degree=3, feed=feed)
    mach = g.add("machine", id="machine", period=period, axes=AXES)
    interp = g.add("interp.nurbs", id="interp", eps=0.001, corrector=corrector)
    g.wire(src.path, interp.path)
    g.wire(mach.machine, interp.machine)
    return g.build()


@pytest.mark.parametrize("feed, period", [(200.0, 0.004), (100.0, 0.001)])
def test_nurbs_interpolator_node(spec, feed, period):
    result = flowmc.run(_nurbs_graph(spec, feed, period))
    assert result.ok, result.errors
    traj = result.output("interp", "trajectory")
    assert traj.period == period and traj.positions.shape[1] == 3
    assert np.allclose(traj.positions[0], [0, 0, 0]) and np.allclose(traj.positions[-1], [10, -60, 0])
    assert result.output("interp", "fluctuation_pct") < 1e-4
    assert result.output("interp", "chord_error") <= 1.05e-3
    v, a, _ = traj.derivatives()
    assert np.linalg.norm(v, axis=1).max() <= feed * (1 + 1e-6)
    assert np.linalg.norm(a, axis=1).max() <= 1000.0 * 1.01  # normal + tangential within amax
    # the same setpoints as calling the algorithm directly with the node's settings
    ctrl = np.column_stack([np.array(spec["control_points"], float), np.zeros(9)])
    curve = nurbs.Nurbs(ctrl, spec["weights"], nurbs.clamped_uniform_knots(9, 3), 3)
    direct = nurbs.interpolate(curve, feed, period, eps=0.001, amax=1000.0 / math.sqrt(2))
    assert np.array_equal(direct, traj.positions)


def test_nurbs_node_without_corrector_fluctuates_more(spec):
    on = flowmc.run(_nurbs_graph(spec, 200.0, 0.004, 1)).output("interp", "fluctuation_pct")
    off = flowmc.run(_nurbs_graph(spec, 200.0, 0.004, 0)).output("interp", "fluctuation_pct")
    assert off > 1000 * on and off > 1e-3


def test_nurbs_node_from_params_and_its_errors():
    g = flowmc.GraphBuilder(title="params")
    g.add("interp.nurbs", id="bad", control_points=[[0, 0, 0], [1, 1, 0], [2, 0, 0], [3, 1, 0]],
          knots=[0, 0, 0, 0, 1, 1, 1])
    g.add("interp.nurbs", id="good", control_points=[[0, 0, 0], [10, 10, 0], [20, 0, 0], [30, 10, 0]], feed=20.0)
    result = flowmc.run(g.build())
    assert result.nodes["good"].status == "done"
    assert np.allclose(result.output("good", "trajectory").positions[-1], [30, 10, 0])
    err = result.nodes["bad"].error
    assert err.startswith("node 'bad'") and "knots" in err and "4 + 3 + 1 = 8" in err and "got 7" in err


def test_nurbs_node_refuses_lines():
    g = flowmc.GraphBuilder(title="lines")
    poly = g.add("path.polyline", id="poly", points=[[0, 0, 0], [10, 0, 0]])
    interp = g.add("interp.nurbs", id="interp")
    g.wire(poly.path, interp.path)
    result = flowmc.run(g.build())
    assert not result.ok
    assert result.nodes["interp"].error.startswith("node 'interp': segment 1 (point 1): is a line, not a NURBS")
    assert "time-division" in result.nodes["interp"].error


def _table_graph(profile, method, period=0.004):
    g = flowmc.GraphBuilder(title="table")
    rows = [
        {"type": "line", "end": [40, 0, 0]},
        {"type": "arc", "direction": "ccw", "radius": 20, "start_angle": -90, "end_angle": 630},  # two turns
        {"type": "line", "end": [0, 0, 0]},
    ]
    table = g.add("path.segment_table", id="table", rows=rows, feed=150.0)
    mach = g.add("machine", id="machine", period=period, axes=AXES)
    interp = g.add("interp.time_division", id="interp", profile=profile, arc_method=method, eps=0.001)
    g.wire(table.path, interp.path)
    g.wire(mach.machine, interp.machine)
    return g.build()


@pytest.mark.parametrize("profile", ["trapezoid", "exponential", "scurve"])
def test_time_division_node_stop_and_go(profile):
    result = flowmc.run(_table_graph(profile, "exact"))
    assert result.ok, result.errors
    traj = result.output("interp", "trajectory")
    path = result.output("table", "path")
    assert list(np.unique(traj.segment)) == [0, 1, 2]
    assert np.allclose(traj.positions[0], path.start) and np.array_equal(traj.positions[-1], path.end)
    speed = traj.speed()
    for i, seg in enumerate(path.segments):  # stops at every segment end, exactly on it
        last = np.flatnonzero(traj.segment == i)[-1]
        assert np.allclose(traj.positions[last], seg.end, atol=1e-9)
        assert speed[last - 1] < 0.1 * 150 and (last == len(speed) or speed[last] < 0.1 * 150)
    # arc feed clamped to the chord bound: (2/T) sqrt(2 R eps - eps^2) = 100 mm/s at R 20, T 4 ms
    arc_speed = speed[traj.segment[1:] == 1]
    assert arc_speed.max() <= timediv.arc_feed_limit(20.0, 0.004, 0.001) * (1 + 1e-9)
    assert result.output("interp", "chord_error") <= 0.001 * (1 + 1e-6)
    assert result.output("interp", "radial_error") < 1e-9
    a = np.linalg.norm(traj.derivatives()[1], axis=1)
    assert a.max() <= 1000.0 * 1.01


def test_time_division_second_order_arcs_drift():
    exact = flowmc.run(_table_graph("trapezoid", "exact"))
    approx = flowmc.run(_table_graph("trapezoid", "second_order"))
    assert approx.ok
    drift = approx.output("interp", "radial_error")
    assert exact.output("interp", "radial_error") < 1e-9 < drift
    # two turns at ~100 mm/s, d = V T / R = 0.02 rad: about n d^4 / 8 R with n ~ 2 turns / d ~ 630 steps
    assert 0.2 * 630 * 0.02**4 / 8 * 20 < drift < 2 * 630 * 0.02**4 / 8 * 20


def test_time_division_default_machine_and_wired_param():
    g = flowmc.GraphBuilder(title="defaults")
    poly = g.add("path.polyline", id="poly", points=[[0, 0, 0], [30, 40, 0]], feed=100.0)
    kind = g.add("basic.text", id="kind", value="trapezoid")
    interp = g.add("interp.time_division", id="interp")
    g.wire(poly.path, interp.path)
    g.wire(kind.value, interp.profile)
    result = flowmc.run(g.build())
    assert result.ok, result.errors
    traj = result.output("interp", "trajectory")
    assert traj.period == 0.004  # default machine
    # trapezoid from rest at amax 200: 0.5 s to 100 mm/s covering 25 mm each way; 50 mm in total -> no cruise
    assert traj.duration == pytest.approx(2 * math.sqrt(50.0 / 200.0), abs=0.004)


def test_time_division_dwell_curves_and_signals(registry):
    g = flowmc.GraphBuilder(title="mixed")
    src = g.add("test.mixed_path", id="src")
    interp = g.add("interp.time_division", id="interp", eps=0.001)
    g.wire(src.path, interp.path)
    result = flowmc.run(g.build(), registry=registry)
    assert result.ok, result.errors
    traj = result.output("interp", "trajectory")
    path = result.output("src", "path")
    seg = traj.segment
    # the dwell holds the point for 0.1 s = 25 periods
    held = traj.positions[seg == 1]
    assert len(held) == 25 and np.all(held == path.segments[1].start)
    # ellipse and NURBS setpoints lie on their curves, and the run ends on the NURBS's end
    ell = traj.positions[seg == 2]
    assert np.allclose((ell[:, 0] / 20.0) ** 2 + (ell[:, 1] / 10.0) ** 2, 1.0, atol=1e-6)
    assert np.allclose(traj.positions[-1], path.end)
    # speed on the ellipse respects its chord clamp at the tightest radius b^2/a = 5 mm
    speed = traj.speed()
    assert speed[seg[1:] == 2].max() <= timediv.arc_feed_limit(5.0, 0.004, 0.001) * (1 + 1e-9)
    # signals at each segment's start time: dout, spindle and tool down (the tool starts up) on the line,
    # DA on the ellipse, spindle off on the NURBS
    sig = traj.signals
    t_ell = (np.flatnonzero(seg == 2)[0] - 1) * traj.period
    t_nurbs = (np.flatnonzero(seg == 3)[0] - 1) * traj.period
    events = sorted(zip(sig.t.round(9), sig.kind, sig.channel, sig.value))
    assert events == sorted([(0.0, "dout", 3, 1.0), (0.0, "spindle_rpm", 0, 1200.0), (0.0, "tool", 0, 1.0),
                             (round(t_ell, 9), "da", 0, 2.5), (round(t_nurbs, 9), "spindle_rpm", 0, 0.0)])
