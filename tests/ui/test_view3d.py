"""The 3D toolpath view driven through its viser handles (no browser): scene, playback, colours, plots."""

from __future__ import annotations

import socket
import time

import numpy as np
import pytest

import flowmc
from flowmc.devices.sim import SimCard
from flowmc.motion.machine import Axis, Machine
from flowmc.motion.trajectory import Signal, Steps, Trajectory
from flowmc.ui import view3d_data as data
from flowmc.ui.text import unescape_md
from flowmc.ui.view3d import ToolpathView, embed_html

ROWS = [
    {"type": "line", "end": [30.0, 0.0, 0.0]},
    {"type": "arc", "direction": "ccw", "radius": 10.0, "start_angle": -90.0, "end_angle": 90.0},
    {"type": "line", "end": [0.0, 20.0, 5.0]},
]


def planning_graph(dx: float = 0.0) -> flowmc.Graph:
    g = flowmc.GraphBuilder(title="view test")
    table = g.add("path.segment_table", id="table", rows=ROWS, feed=40.0)
    shift = g.add("path.translate", id="shift", dx=dx)
    plan = g.add("interp.time_division", id="plan", profile="trapezoid")
    g.wire(table.path, shift.path)
    g.wire(shift.path, plan.path)
    return g.build()


@pytest.fixture(scope="module")
def planned():
    """A real planned trajectory: segment table (line, arc, helix-free line with Z) -> time-division planner."""
    graph = planning_graph()
    result = flowmc.Runtime().run(graph)
    assert result.ok, result.errors
    return graph, result, result.output("shift", "path"), result.output("plan", "trajectory")


@pytest.fixture
def view():
    v = ToolpathView()
    yield v
    v.close()


def test_scene_has_path_trajectory_travel_box_and_marker(view, planned):
    _, _, path, traj = planned
    view.show([path], [traj], Machine())
    assert set(view.nodes) == {"/machine/travel", "/path/0", "/trajectory/0"}
    segs = view.nodes["/trajectory/0"].points
    assert segs.shape == (len(traj) - 1, 2, 3)
    np.testing.assert_allclose(segs[:, 0], traj.positions[:-1], atol=1e-4)
    np.testing.assert_allclose(segs[:, 1], traj.positions[1:], atol=1e-4)
    path_pts = view.nodes["/path/0"].points.reshape(-1, 3)
    np.testing.assert_allclose(path_pts[0], path.start, atol=1e-5)
    np.testing.assert_allclose(path_pts[-1], path.end, atol=1e-5)
    # the arc is sampled, not drawn as a chord: its points keep the 10 mm radius about (30, 10)
    on_arc = path_pts[(path_pts[:, 0] > 30.0 + 1e-6)]
    assert len(on_arc) > 8
    np.testing.assert_allclose(np.hypot(on_arc[:, 0] - 30.0, on_arc[:, 1] - 10.0), 10.0, atol=1e-4)
    assert view.marker.visible and not view.time_slider.disabled
    assert view.time_slider.max == pytest.approx(traj.duration)


def test_slider_moves_marker_to_the_sample_at_that_time(view, planned):
    _, _, path, traj = planned
    view.show([path], [traj], None)
    for t in (0.0, 0.371, traj.duration / 2 + 0.001, traj.duration):
        view.time_slider.value = t
        k = round(t / traj.period)
        np.testing.assert_allclose(view.marker.position, traj.positions[k], atol=1e-9)
        assert f"t = {k * traj.period:.4f}" in unescape_md(view.readout.content)
        # the segment as users count it, with the table row it came from
        i = int(traj.segment[k])
        assert unescape_md(view.readout.content).endswith(f" · segment {i + 1} (row {i + 1})")
    view.set_time(1e9)  # clamped to the end
    np.testing.assert_allclose(view.marker.position, traj.positions[-1])


def test_trajectory_colours_follow_speed(view, planned):
    _, _, path, traj = planned
    view.show([path], [traj], None)
    colors = view.nodes["/trajectory/0"].colors
    speed = traj.speed()
    np.testing.assert_array_equal(colors[:, 0], data.linear_rgb(data.speed_colors(speed, speed.max())))
    np.testing.assert_array_equal(colors[:, 0], colors[:, 1])
    assert tuple(colors[np.argmax(speed), 0]) == tuple(data.linear_rgb(data.SPEED_STOPS[-1][1]))  # fastest: red
    slow = colors[np.argmin(speed), 0].astype(int)
    assert slow[2] > slow[0]  # slowest: blue end of the scale
    assert "40 mm/s" in unescape_md(view.info.content)


def test_speed_colour_scale_stops():
    out = data.speed_colors(np.array([0.0, 25.0, 50.0, 100.0, 150.0]), 100.0)
    assert [tuple(c) for c in out] == [data.SPEED_STOPS[0][1], data.SPEED_STOPS[1][1], data.SPEED_STOPS[2][1],
                                       data.SPEED_STOPS[4][1], data.SPEED_STOPS[4][1]]


def test_plots_get_velocity_acceleration_and_jerk(view, planned):
    _, _, path, traj = planned
    view.show([path], [traj], None)
    v, a, j = traj.derivatives()
    t = traj.times
    vel = view.plots["Velocity (mm/s)"].data
    np.testing.assert_allclose(vel[0], t[:-1] + traj.period / 2)
    np.testing.assert_allclose(vel[1], np.linalg.norm(v, axis=1), rtol=1e-9, atol=1e-9)
    for i in range(3):
        np.testing.assert_allclose(vel[2 + i], v[:, i], rtol=1e-9, atol=1e-9)
    acc = view.plots["Acceleration (mm/s²)"].data
    np.testing.assert_allclose(acc[0], t[1:-1])
    np.testing.assert_allclose(np.column_stack(acc[1:]), a, rtol=1e-6, atol=1e-6)
    jerk = view.plots["Jerk (mm/s³)"].data
    np.testing.assert_allclose(jerk[0], t[1:-2] + traj.period / 2)
    np.testing.assert_allclose(np.column_stack(jerk[1:]), j, rtol=1e-6, atol=1e-3)
    assert [s["label"] for s in view.plots["Velocity (mm/s)"].series] == ["t (s)", "|v|", "X", "Y", "Z"]


def test_travel_box_matches_machine_limits(view, planned):
    _, _, path, traj = planned
    machine = Machine(axes=(Axis(name="X", min=-10, max=120), Axis(name="Y", min=-5, max=80),
                            Axis(name="Z", min=-30, max=12)))
    view.show([path], [traj], machine)
    box = view.nodes["/machine/travel"].points
    assert box.shape == (12, 2, 3)
    np.testing.assert_allclose(box.reshape(-1, 3).min(axis=0), [-10, -5, -30])
    np.testing.assert_allclose(box.reshape(-1, 3).max(axis=0), [120, 80, 12])
    lengths = sorted(np.round(np.linalg.norm(box[:, 1] - box[:, 0], axis=1), 6))
    assert lengths == [42.0] * 4 + [85.0] * 4 + [130.0] * 4  # every edge is axis-parallel


def test_output_and_pwm_timeline_from_program_signals(view):
    sig = Signal(t=[0.1, 0.3, 0.2], kind=["dout", "dout", "pwm_duty"], channel=[1, 1, 1], value=[1, 0, 50])
    line = np.column_stack([np.linspace(0, 10, 101), np.zeros(101), np.zeros(101)])
    view.show([], [Trajectory(line, 0.005, signals=sig)], None)
    x, do1 = view.plots["Digital outputs"].data
    inside = (x > 0.1) & (x < 0.3)
    assert np.all(do1[inside] == 0.8) and np.all(do1[(x < 0.1) | (x > 0.3)] == 0.0)
    x, duty = view.plots["PWM duty (%)"].data
    assert np.all(duty[x < 0.2] == 0.0) and np.all(duty[x > 0.2] == 50.0)
    assert x[-1] == pytest.approx(0.5)
    assert view.plots["Digital outputs"].series[1]["label"] == "DO1 (program)"


def test_device_log_is_drawn_and_its_outputs_join_the_timeline(view, planned):
    _, _, path, traj = planned
    sig = Signal(t=[0.2], kind=["dout"], channel=[4], value=[1])
    program = Trajectory(traj.positions, traj.period, traj.segment, signals=sig)
    log = SimCard(Machine()).run(program)
    assert log.outcome == "done"
    view.show([path], [program], Machine(), logs=[log])
    assert "/device/0" in view.nodes
    np.testing.assert_allclose(view.nodes["/device/0"].points[-1, 1], log.end_position, atol=1e-4)
    labels = [s["label"] for s in view.plots["Digital outputs"].series]
    assert labels == ["t (s)", "DO4 (program)", "DO4 (device 1)"]
    assert view.follow.options == ("motion 1", "device log 1") and view.follow.value == "motion 1"
    view.follow.value = "device log 1"  # follow what the card did instead
    view.time_slider.value = view.time_slider.max
    np.testing.assert_allclose(view.marker.position, log.end_position, atol=1e-9)


def test_show_result_picks_the_most_downstream_values(view):
    graph = planning_graph(dx=100.0)
    result = flowmc.Runtime().run(graph)
    shown = view.show_result(result, graph)
    assert shown.paths == [result.output("shift", "path")]  # not the untranslated table path
    assert shown.trajectories == [result.output("plan", "trajectory")]
    assert view.follow.value == "plan.trajectory"
    np.testing.assert_allclose(view.nodes["/path/0"].points[0, 0], [100.0, 0.0, 0.0])
    last_only = data.collect(result)  # without the graph: the last of each kind in run order
    assert last_only.paths == [result.output("shift", "path")]


def test_steps_are_played_untimed_with_the_index_as_time(view):
    steps = Steps([[1, 0], [1, 0], [0, -1], [1, 0]], step_mm=0.5, origin=[10.0, 0.0], axes=("X", "Y"))
    view.show([], [steps], None)
    assert view.time_slider.max == 4
    view.time_slider.value = 3
    np.testing.assert_allclose(view.marker.position, [11.0, -0.5, 0.0])
    assert "Velocity (mm/tick)" in view.plots


def test_pen_timeline_of_an_untimed_step_stream_is_in_ticks(view):
    from flowmc.motion.contour import Contour, contours_to_path
    from flowmc.motion.path_steps import path_to_steps

    square = Contour(np.array([[1, 1], [3, 1], [3, 3], [1, 1]], dtype=float), True)
    steps = path_to_steps(contours_to_path([square], feed=10.0), 0.5)  # untimed: times are tick indices
    view.show([], [steps], None)
    down = int(np.searchsorted(steps.segment, 1))  # the first stroke's first step
    x, pen = view.plots["Tool/pen (1 = down)"].data
    assert np.all(pen[x < down] == 0.0) and np.all(pen[x > down] == 1.0) and x[-1] == len(steps)


def test_nothing_to_show_hides_marker_and_playback(view, planned):
    _, _, path, traj = planned
    view.show([path], [traj], None)
    view.show()
    assert view.nodes == {} and view.plots == {}
    assert not view.marker.visible and view.time_slider.disabled
    assert "Nothing to show" in unescape_md(view.info.content)


def test_play_advances_the_slider_and_pause_stops_it(view, planned):
    _, _, path, traj = planned
    view.show([path], [traj], None)
    view.play_button.value = True
    assert view.play_button.label == "Pause"
    deadline = time.monotonic() + 10.0
    while view.time_slider.value < 0.2 and time.monotonic() < deadline:
        time.sleep(0.02)
    assert view.time_slider.value >= 0.2
    view.play_button.value = True
    held = view.time_slider.value
    time.sleep(0.3)
    assert view.time_slider.value == held and view.play_button.label == "Play"
    k = round(held / traj.period)
    np.testing.assert_allclose(view.marker.position, traj.positions[k])


def test_envelope_keeps_peaks_when_decimating():
    x = np.arange(100_000) * 0.001
    y = np.sin(x)
    y[54_321] = 7.0
    xo, (yo,) = data.envelope(x, [y], 4000)
    assert len(xo) <= 4000 and yo.max() == 7.0 and np.all(np.diff(xo) >= 0)


def test_embed_html_and_close_frees_the_port():
    view = ToolpathView()
    port = view.server.get_port()
    assert view.url == f"http://127.0.0.1:{port}/?token={view.guard.token}"
    assert embed_html(view).startswith(f'<iframe data-flowmc-port="{port}" data-flowmc-token="{view.guard.token}"')
    assert f'href="http://127.0.0.1:{port}/?token={view.guard.token}"' in embed_html(view)
    view.close()
    view.close()
    with pytest.raises(OSError):
        socket.create_connection(("127.0.0.1", port), timeout=1.0).close()


def test_a_view_on_all_interfaces_is_addressed_by_the_machine_name():
    import socket

    view = ToolpathView(host="0.0.0.0", port=0)
    try:
        assert view.url == f"http://{socket.gethostname()}:{view.server.get_port()}/?token={view.guard.token}"
    finally:
        view.close()
