"""The comparison report: flowmc's look-ahead plan beside LinuxCNC's executed motion."""

import json

import numpy as np
import pytest

from flowmc.cli import main as flowmc_main
from flowmc.devices.linuxcnc.compare import compare_trajectories, flowmc_feed_time
from flowmc.motion.lookahead import plan_lookahead
from flowmc.motion.machine import Axis, Machine
from linuxcnc_programs import MEASURED, TOL, machine

pytestmark = pytest.mark.linuxcnc


def test_report_puts_both_sides_measured_the_same_way(runs):
    path, run, _, _ = runs["mixed"]
    ours = plan_lookahead(path, Machine(axes=machine().axes, period=0.004), rule="blend", tolerance=TOL).trajectory
    table = compare_trajectories(ours, run, path)
    rows = {q: (f, lc) for q, f, lc in zip(table["quantity"], table["flowmc"], table["linuxcnc"])}
    assert rows["feed cycle time"][1] == pytest.approx(run.feed_time)
    assert rows["feed cycle time"][1] == pytest.approx(MEASURED["mixed"], rel=0.02)
    assert rows["feed cycle time"][0] == pytest.approx(ours.duration, abs=0.004)  # all of it is feed
    assert rows["period"] == (0.004, 0.001)
    # both keep the corner tolerance (chords of the samples against the programmed path)
    assert 0.01 < rows["deviation from the programmed path"][0] <= TOL * 1.01
    assert 0.01 < rows["deviation from the programmed path"][1] <= TOL * 1.05
    assert max(rows["deviation from the other tool path"]) < 2 * TOL
    for axis in "XY":
        f, lc = rows[f"peak velocity {axis}"]
        assert 150 < f <= 200.0 + 1e-6 and 150 < lc <= 200.0 + 1e-3
        f, lc = rows[f"peak acceleration {axis}"]
        assert 100 < f <= 200 * 1.01 and 100 < lc <= 200 * 1.01 + 2.0
    assert rows["peak velocity Z"] == (0.0, 0.0)


def test_flowmc_feed_time_leaves_out_rapids_and_standstill():
    from flowmc.motion.path import Line, Path
    from flowmc.motion.trajectory import Trajectory

    path = Path([Line([0, 0, 0], [1, 0, 0], feed=10.0, rapid=True), Line([1, 0, 0], [2, 0, 0], feed=10.0)])
    pos = np.array([[0, 0, 0], [0.5, 0, 0], [1, 0, 0], [1.5, 0, 0], [2, 0, 0], [2, 0, 0]], dtype=float)
    traj = Trajectory(pos, 0.1, segment=[0, 0, 0, 1, 1, 1])
    assert flowmc_feed_time(traj, path) == pytest.approx(0.2)


def _square_graph(tmp_path, lookahead: dict | None = None):
    nodes = [
        {"id": "machine", "type": "machine",
         "params": {"axes": [a.model_dump() for a in machine().axes], "period": 0.004}},
        {"id": "path", "type": "path.polyline",
         "params": {"feed": 100.0, "points": [[0, 0, 0], [30, 0, 0], [30, 30, 0], [0, 30, 0], [0, 0, 0]]}},
    ]
    wires = []
    if lookahead is not None:
        nodes.append({"id": "plan", "type": "plan.lookahead", "params": lookahead})
        wires = [{"from": "path.path", "to": "plan.path"}, {"from": "machine.machine", "to": "plan.machine"}]
    file = tmp_path / "square.flowmc.json"
    file.write_text(json.dumps({"schema_version": 1, "title": "compare a square", "nodes": nodes, "wires": wires}))
    return file


def _cells(out: str, quantity: str) -> list[float]:
    """The flowmc and LinuxCNC values of one row of the printed table."""
    line = next(ln for ln in out.splitlines() if ln.startswith(quantity + " "))
    return [float(v.rstrip("!")) for v in line[len(quantity):].split()[1:3]]


def test_flowmc_compare_cli_compares_like_with_like(tmp_path, capsys):
    code = flowmc_main(["compare", str(_square_graph(tmp_path)), "--with", "linuxcnc"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "set up like LinuxCNC" in out and "differences: none" in out
    assert "flowmc:   trapezoid, T = 1 ms, tolerance 0.05 mm" in out
    assert _cells(out, "period") == [0.001, 0.001]
    flowmc_s, linuxcnc_s = _cells(out, "feed cycle time")
    # 30 mm sides with near-stops at the corners never reach 100 mm/s: a triangle of about
    # 2 sqrt(30 / 200) = 0.77 s per side at 200 mm/s^2, a little more with the blends; flowmc's corners, moved
    # out within the tolerance, are passed at about 8 mm/s: 2 (sqrt(8^2 + 200 * 30) - 8) / 200 = 0.70 s a side
    assert 2.8 < flowmc_s < 3.7 and 3.0 < linuxcnc_s < 3.7 and flowmc_s < linuxcnc_s
    for row in ("deviation from the programmed path", "deviation of the programmed path from the tool path"):
        assert all(0.0 < v <= TOL * 1.01 for v in _cells(out, row))
    assert all(v > 0 for v in _cells(out, "peak jerk X"))  # reported for both, held to jmax by neither here
    assert "! flowmc:" not in out  # (LinuxCNC cuts the corner vertices by a hair over G64 P: flagged if so)


def test_compare_lists_what_differs_and_flags_a_broken_limit(tmp_path, capsys):
    # the graph plans S-curves at 4 ms within 0.01 mm: compared as planned, every difference is listed;
    # LinuxCNC's sampled jerk is far over jmax but LinuxCNC does not limit jerk, so it is not flagged
    graph = _square_graph(tmp_path, {"rule": "blend", "profile": "scurve", "tolerance": 0.01})
    code = flowmc_main(["compare", str(graph), "--as-planned"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "profile: flowmc scurve, LinuxCNC trapezoid" in out
    assert "period: flowmc 4 ms, LinuxCNC 1 ms" in out
    assert "tolerance: flowmc 0.01 mm, LinuxCNC G64 P0.05" in out
    assert "jerk: flowmc limits it per axis, LinuxCNC does not" in out
    jerk_flowmc, jerk_linuxcnc = _cells(out, "peak jerk X")
    assert jerk_flowmc <= 500.0 < jerk_linuxcnc


def test_compare_flags_a_side_over_its_limits():
    from flowmc.devices.linuxcnc.compare import compare_trajectories
    from flowmc.motion.path import Line, Path
    from flowmc.motion.trajectory import Trajectory

    path = Path([Line([0, 0, 0], [10, 0, 0], feed=10.0)])
    # jumps straight to 20 mm/s (twice the feed) and runs 0.2 mm off the line
    t = np.arange(0, 0.5 + 1e-9, 0.001)
    pos = np.c_[np.minimum(20.0 * t, 10.0), np.full_like(t, 0.2), np.zeros_like(t)]
    pos[0] = [0, 0, 0]
    fake = Trajectory(pos, 0.001, np.zeros(len(t), dtype=int))

    class Run:  # LinuxCNC's record shape, here a faithful copy of a slow, clean move
        samples = np.c_[np.linspace(0, 10, 1001), np.zeros(1001), np.zeros(1001)]
        motion_type = np.full(1001, 2)
        servo_period = 0.001
        feed_time = duration = 1.0

    table = compare_trajectories(fake, Run(), path, machine(), 0.05)
    over = dict(zip(table["quantity"], table["over"]))
    assert over["peak path speed over the feed"] == "flowmc"
    assert over["deviation from the programmed path"] == "flowmc"
    assert over["peak acceleration Y"] == "flowmc"  # the step onto y = 0.2
    assert over["peak velocity X"] == over["peak jerk Y"] == ""  # 20 mm/s is within vmax; jerk is not limited here

    class FastRun:  # and the other way round: LinuxCNC's record over the feed and 0.2 mm off, flowmc clean
        samples = pos
        motion_type = np.full(len(t), 2)
        servo_period = 0.001
        feed_time = duration = 0.5

    clean = Trajectory(Run.samples, 0.001, np.zeros(1001, dtype=int))
    table = compare_trajectories(clean, FastRun(), path, machine(), 0.05)
    over = dict(zip(table["quantity"], table["over"]))
    assert over["peak path speed over the feed"] == over["deviation from the programmed path"] == "linuxcnc"
    assert over["deviation of the programmed path from the tool path"] == "linuxcnc"


def test_compare_names_a_graph_without_a_path(tmp_path, capsys):
    file = tmp_path / "empty.flowmc.json"
    file.write_text(json.dumps({"schema_version": 1, "title": "no path", "nodes": [
        {"id": "machine", "type": "machine", "params": {}}], "wires": []}))
    assert flowmc_main(["compare", str(file)]) != 0
    assert "produces no Path" in capsys.readouterr().err


def test_axis_limits_come_from_the_graph_machine():
    from flowmc.devices.linuxcnc.backend import StartState, render_ini

    slow = Machine(axes=(Axis(name="X", min=-10, max=20, vmax=50, amax=70), Axis(name="Y"),
                         Axis(name="Z", min=-5, max=5)))
    ini = render_ini(slow, program="/p.ngc", display="/d", dir=__import__("pathlib").Path("/run"),
                     servo_period=0.001, timeout=1.0, start=StartState())
    section = ini[ini.index("[AXIS_X]"):ini.index("[AXIS_Y]")]
    assert "MIN_LIMIT = -10.0" in section and "MAX_LIMIT = 20.0" in section
    assert "MAX_VELOCITY = 50.0" in section and "MAX_ACCELERATION = 70.0" in section
    assert "MAX_LINEAR_VELOCITY = 200.0" in ini  # the fastest axis bounds the vector speed
