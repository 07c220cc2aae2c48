"""Every example graph runs headless and checks the numbers its paper is about."""

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import flowmc
from flowmc.devices.grbl_sim import GrblSimulator

REPO = Path(__file__).resolve().parents[2]
GRAPHS = REPO / "graphs"
REFERENCE = REPO / "tests" / "data" / "reference"
EXAMPLES = sorted(GRAPHS.glob("*.flowmc.json"))


def run(name: str, **inputs):
    result = flowmc.run(flowmc.load(GRAPHS / f"{name}.flowmc.json"), inputs=inputs, start=True)
    assert result.ok, result.errors
    return result


@pytest.mark.parametrize("path", EXAMPLES + sorted((REPO / "flowmc" / "lib").glob("*.flowmc.json")), ids=lambda p: p.name)
def test_every_graph_has_a_title_and_a_description_and_saves_byte_identical(path):
    graph = flowmc.load(path)
    assert graph.title.strip() and len(graph.description.split()) >= 12
    assert flowmc.dumps(graph) == path.read_text()


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_flowmc_run_succeeds_headless(path, tmp_path):
    out = tmp_path / "results.json"
    proc = subprocess.run([sys.executable, "-m", "flowmc", "run", str(path), "--out", str(out)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr
    assert json.loads(out.read_text())["outputs"]


def test_readme_lists_every_example_graph():
    readme = (REPO / "README.md").read_text()
    for path in EXAMPLES:
        assert f"graphs/{path.name}" in readme


def test_thesis_pattern_lengths_spindle_and_homing():
    result = run("thesis_3axis")
    rows = result.outputs["segment_lengths"].to_rows()
    np.testing.assert_allclose([r["xy_chord_mm"] for r in rows], [32.01562, 28.28427, 15, 28.28427, 25, 75], atol=1e-5)
    assert [r["diff_mm"] for r in rows][2] == pytest.approx(5.0)  # the thesis's misprint, reported
    log = result.outputs["log"]
    assert log.outcome == "done"
    np.testing.assert_allclose(log.position[-1], [0, 0, 0], atol=0.0025)
    rpm = [c.value for c in log.changes if c.kind == "spindle_rpm"]
    assert rpm and rpm[0] == pytest.approx(10000, rel=1e-3)  # through the 12-bit DA
    assert any(c.kind == "da" and c.value == pytest.approx(10000 / 24000 * 10, abs=0.005) for c in log.changes)
    homing = result.nodes["home"].outputs["log"]
    assert homing.outcome == "done" and {e.axis for e in homing.events if e.kind == "home"} == {"X", "Y", "Z"}


def test_thesis_nurbs_feed_is_steady_and_chords_are_within_eps():
    result = run("thesis_nurbs")
    assert result.outputs["fluctuation_pct"] < 1e-4
    assert result.outputs["chord_error_mm"] <= 1.05 * 0.001
    curve = json.loads((REFERENCE / "nurbs_test_curve.json").read_text())
    np.testing.assert_allclose(result.outputs["log"].position[-1][:2], curve["control_points"][-1], atol=0.0025)


def test_laser_duty_follows_the_cuts_and_ends_off():
    result = run("thesis_laser_pwm")
    log = result.outputs["log"]
    duty = [(c.t, c.value) for c in log.changes if c.kind == "pwm_duty"]
    assert [d for _, d in duty] == [60.0, 0.0, 60.0]
    assert all(c.value == 20000 for c in log.changes if c.kind == "pwm_freq")
    off = result.nodes["laser_off_now"].outputs["log"]
    assert [c.value for c in off.changes if c.kind == "pwm_duty"] == [0.0]
    traj = result.nodes["plan"].outputs["trajectory"]
    # The laser is on exactly while the frame and the circle are traced: segments 1-4 and 6 as the PWM
    # node's "at" counts them (indices 0-3 and 5 of traj.segment); segment 5 is the rapid between them.
    assert traj.segment_names[4] == "join"
    first = [np.flatnonzero(traj.segment == k)[0] * traj.period for k in (0, 4, 5)]
    assert [t for t, _ in duty] == pytest.approx(first)


def test_dsp_improved_arc_keeps_the_radius_and_pid_follows():
    result = run("dsp_controller")
    original, improved = result.outputs["radial_error_original_mm"], result.outputs["radial_error_improved_mm"]
    assert improved < 1e-9 < 1e-5 < original
    assert 0 < result.outputs["following_error_mm"] < 0.05
    slower = run("dsp_controller", arc_feed=25.0)
    assert slower.outputs["radial_error_original_mm"] < original / 4  # smaller steps, less drift


def test_teaching_machine_pulse_table_and_grbl_stream():
    result = run("teaching_machine")
    table = result.outputs["pulse_table"]
    x, y = table["x_pulses"] * table["x_dir"], table["y_pulses"] * table["y_dir"]
    assert x.sum() == 0 and y.sum() == 0  # the program returns to X0 Y0
    assert np.all(table["rate_limited"] == 0)
    durations = table["duration_s"]
    for axis in ("x", "y"):  # every axis of a row finishes at the row's end: pulses / frequency = duration
        pulses, freq = table[f"{axis}_pulses"], table[f"{axis}_freq_hz"]
        moving = pulses > 0
        np.testing.assert_allclose(pulses[moving] / freq[moving], durations[moving], rtol=1e-9)
    log = result.outputs["log"]
    assert log.device == "grbl-sim" and log.outcome == "done"


def test_teaching_machine_on_a_grbl_board_stops_at_a_failing_line():
    with GrblSimulator(error_at={12: 20}) as sim:
        graph = flowmc.load(GRAPHS / "teaching_machine.flowmc.json")
        result = flowmc.run(graph, inputs={"device": f"grbl:{sim.port}"}, start=True)
    assert not result.ok
    assert "line 12" in result.nodes["grbl"].error and "error:20" in result.nodes["grbl"].error


def test_arm_lookahead_is_at_least_a_third_faster_than_stop_and_go():
    result = run("arm_lookahead")
    assert result.outputs["ratio"] <= 0.68
    assert result.outputs["ratio"] == pytest.approx(result.outputs["lookahead_s"] / result.outputs["stop_and_go_s"])
    metrics = {r["name"]: r["value"] for r in result.outputs["metrics"].to_rows()}
    assert metrics["contour_error"] <= 0.05 and metrics["peak_accel"] <= 1.01


def test_xy_plotter_draws_in_all_quadrants_and_lifts_the_pen():
    result = run("xy_plotter")
    steps = result.outputs["steps"]
    pos = steps.positions()
    assert (pos[:, 0] > 0).any() and (pos[:, 0] < 0).any() and (pos[:, 1] > 0).any() and (pos[:, 1] < 0).any()
    assert np.abs(steps.steps).sum(axis=1).max() == 1  # point-by-point: one axis steps per tick
    log = result.outputs["log"]
    assert log.outcome == "done"
    np.testing.assert_allclose(log.position[-1], pos[-1], atol=1e-9)
    homing, jog = result.nodes["home"].outputs["log"], result.nodes["jog"].outputs["log"]
    assert homing.outcome == "done" and jog.outcome == "done"
    np.testing.assert_allclose(jog.position[-1], [20.0, 0.0], atol=0.01)
    np.testing.assert_allclose(pos[0], jog.position[-1], atol=0.01)  # the drawing starts where the jog left the pen
    # The pen (output 1) goes down for every stroke and up for every move between them.
    tool = [c.value for c in log.changes if c.kind == "tool"]
    pen = [c.value for c in log.changes if c.kind == "dout" and c.channel == 1]
    assert pen == tool and len(pen) >= 6 and pen[-1] == 1.0
    assert all(a != b for a, b in zip(pen, pen[1:]))
    table = flowmc.load(GRAPHS / "xy_plotter.flowmc.json")
    limits = next(n for n in table.nodes if n.id == "table").params["axes"]
    for axis, col in zip(limits, pos.T):
        assert axis["min"] <= col.min() and col.max() <= axis["max"]


def test_xy_plotter_refuses_a_drawing_past_the_table_edge_before_motion():
    result = flowmc.run(flowmc.load(GRAPHS / "xy_plotter.flowmc.json"), inputs={"picture_width_mm": 400.0}, start=True)
    assert not result.ok
    error = result.nodes["card"].error
    assert "segment" in error and "soft limit" in error and "X" in error
    # 1-based, with the contour the segment came from
    assert re.match(r"node 'card': segment [1-9]\d* \(house\.png contour [1-9]\d*\): X = [\d.]+ mm beyond soft limit max",
                    error), error
    assert "log" not in result.nodes["card"].outputs  # nothing was sent


def test_svg_plotter_draws_the_svg_with_two_pens_within_the_table():
    result = run("svg_plotter")
    steps = result.outputs["steps"]
    pos = steps.positions()
    assert np.abs(steps.steps).sum(axis=1).max() == 1  # point-by-point
    log = result.outputs["log"]
    assert log.outcome == "done"
    np.testing.assert_allclose(log.position[-1], pos[-1], atol=1e-9)
    # the 80 x 50 mm drawing centred on the table (frame corners at +-38, +-23), to a step
    np.testing.assert_allclose(pos.min(axis=0), [-38, -23], atol=0.011)
    np.testing.assert_allclose(pos.max(axis=0), [38, 23], atol=0.011)
    path = result.nodes["drawing"].outputs["path"]
    events = path.events()
    assert [(e.kind, e.tool) for _, e in events] == [("tool_change", 2)]  # black pen, then the red one
    assert {s.kind for s in path} <= {"line", "arc", "dwell"}  # Béziers and ellipses as arcs
    pen = [c.value for c in log.changes if c.kind == "dout" and c.channel == 1]
    assert len(pen) >= 2 * 9 - 1 and all(a != b for a, b in zip(pen, pen[1:]))  # down and up for the 9 strokes
