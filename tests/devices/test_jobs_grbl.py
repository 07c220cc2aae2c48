"""Jobs on GRBL through its real-time bytes, against the protocol simulator with its motion model
(``GrblSimulator(motion=True)``: moves take time, hold decelerates at 200 mm/s^2, overrides change the
speed). What is checked comes from the simulator's own record of the bytes it received and from the
status reports the job logged."""

import functools
import threading
import time

import numpy as np
import pytest

import flowmc
from flowmc.devices.grbl_sim import GrblSimulator
from flowmc.devices.jobs import Job, JobRunner
from flowmc.devices.jobs.grbl_driver import override_bytes
from flowmc.errors import DeviceError
from flowmc.motion.gcode import parse_gcode
from flowmc.motion.lookahead import plan_stop_and_go
from flowmc.motion.machine import Machine
from job_helpers import distance_to_polyline
from job_waits import quiet as _quiet
from job_waits import wait_until as _wait

ACCEL = 200.0  # mm/s^2, the simulator's


def _program():
    """Three 60 mm lines at 20 mm/s (a square's sides), planned at 1 ms."""
    g = flowmc.GraphBuilder(title="grbl job")
    square = g.add("path.polyline", id="square", points=[(0, 0, 0), (60, 0, 0), (60, 60, 0), (0, 60, 0)], feed=20.0)
    plan = g.add("interp.time_division", id="plan", profile="trapezoid")
    g.wire(square.path, plan.path)
    result = flowmc.Runtime().run(g.build())
    assert result.ok, result.errors
    return result.output("plan", "trajectory")


def _start(grbl_sim, motion=None, **options):
    sim = grbl_sim(motion=True, accel=ACCEL)
    machine = Machine(period=0.001)
    runner = JobRunner(Job(f"grbl:{sim.port}", machine, "program", _program() if motion is None else motion,
                           name="plotter"), **options)
    ticks = []
    runner.subscribe(lambda e: ticks.append((time.monotonic(), e.status)) if e.kind == "tick" else None)
    thread = threading.Thread(target=lambda: _quiet(runner.run), daemon=True)
    thread.start()
    return sim, runner, ticks


def test_override_bytes_step_from_100_percent():
    assert override_bytes("feed", 100, 50) == b"\x90" + b"\x92" * 5
    assert override_bytes("feed", 100, 137) == b"\x90" + b"\x91" * 3 + b"\x93" * 7
    assert override_bytes("rapid", 100, 25) == b"\x97"
    assert override_bytes("spindle", 100, 80) == b"\x99" + b"\x9b" * 2


def test_hold_sends_bang_decelerates_within_accel_and_resume_ends_at_the_end(grbl_sim):
    sim, runner, ticks = _start(grbl_sim)
    _wait(lambda: sim.model.position[0] > 30.0, what="the first line under way")
    runner.hold()
    _wait(lambda: runner.state == "held", 10, "held")
    bang = next(t for t, b in sim.bytes_seen if b == ord("!"))
    held_at = list(sim.model.position)
    time.sleep(1.0)
    assert sim.model.position == held_at and runner.state == "held"  # stays stopped, no position lost
    # it was at 20 mm/s: stopping takes v^2 / 2a = 1 mm along the line, not more
    assert 30.0 < held_at[0] < 60.0 and held_at[1] == 0.0
    runner.resume()
    _wait(lambda: runner.finished, 60, "the end")
    assert runner.state == "done"
    np.testing.assert_allclose(sim.model.position, [0.0, 60.0, 0.0], atol=1e-3)
    # status polled at 5 Hz or more while the job ran
    polls = [t for t, b in sim.bytes_seen if b == ord("?")]
    assert len(polls) / (polls[-1] - polls[0]) >= 5.0
    moves = [s for t, s in ticks if t < bang]
    assert moves and moves[-1].commanded[0] > 25.0  # the readout followed the motion


def test_feed_override_50_sends_its_bytes_and_halves_the_speed(grbl_sim):
    sim, runner, ticks = _start(grbl_sim)
    _wait(lambda: sim.model.position[1] > 10.0, what="the second line under way")
    runner.set_overrides(feed=50.0)
    _wait(lambda: sim.model.overrides["feed"] == 50, 5, "feed 50 %")
    time.sleep(0.5)  # 20 mm/s down to 10 takes 50 ms at 200 mm/s^2
    programmed = sim.model.block.speed  # the line's F (the plan's chord speed, about 20 mm/s)
    assert 15.0 < programmed <= 20.0 + 1e-9
    assert sim.model.speed == pytest.approx(0.5 * programmed, abs=1e-6)  # the block runs at 50 %
    y0, t0 = sim.model.position[1], time.monotonic()
    time.sleep(1.0)
    assert 5.0 < (sim.model.position[1] - y0) / (time.monotonic() - t0) < 12.0  # about 10 mm/s by the clock too
    received = bytes(b for _t, b in sim.bytes_seen if b >= 0x90)
    assert received == override_bytes("feed", 100, 50)
    runner.stop()
    _wait(lambda: runner.finished, 20, "the stop")


def test_stop_holds_then_resets_and_leaves_spindle_and_coolant_off(grbl_sim):
    sim, runner, ticks = _start(grbl_sim)
    _wait(lambda: sim.model.position[1] > 10.0, what="the second line under way")
    runner.stop()
    _wait(lambda: runner.finished, 20, "the stop")
    assert runner.state == "aborted" and "stopped by the operator at line" in runner.message
    kinds = [b for _t, b in sim.bytes_seen if b in (ord("!"), 0x18)]
    assert kinds[-2:] == [ord("!"), 0x18]  # a feed hold, then (at rest) the soft reset
    assert sim.alarm == 0  # reset at rest: GRBL keeps its position, no alarm
    assert sim.spindle_dir == 5 and sim.coolant == 9
    assert not sim.model.busy and runner.log.outcome == "aborted"
    assert any(e.kind == "safe" for e in runner.log.events)


def test_estop_resets_at_once_and_grbl_reports_the_lost_position(grbl_sim):
    sim, runner, ticks = _start(grbl_sim)
    _wait(lambda: sim.model.position[0] > 10.0, what="moving")
    runner.estop()
    _wait(lambda: runner.finished, 20, "the e-stop")
    assert runner.state == "aborted" and runner.log.outcome == "estop"
    assert sim.alarm == 3  # reset while moving: GRBL's alarm 3, locked until $X or homing
    assert not sim.model.busy and sim.spindle_dir == 5


# ---------------------------------------------------------------- start at segment or G-code line N

MILL = """G21 G90 G17
G0 X0 Y0 Z5
M3 S1000
M8
G1 Z-1 F600
G1 X20 F2400
G1 Y20
G0 Z5
G0 X30 Y0
G1 Z-1 F600
G1 X40 Y10 F2400
G1 X30 Y20
G0 Z5
M9
M5
M2
"""
ELSEWHERE = [35.0, 25.0, 3.0]  # where the machine stands before a mid-program start
PATH_TOL = 0.025  # mm: each stream is the plan thinned to within the card's 0.01 mm, the two thinned apart


def _mill():
    machine = Machine()
    return plan_stop_and_go(parse_gcode(MILL, "part.ngc"), machine).trajectory, machine


@functools.lru_cache(maxsize=1)
def _uninterrupted():
    """The raw trace (time, xyz, spindle M-code, S, coolant M-code) of the whole program on its own simulator."""
    motion, machine = _mill()
    sim = GrblSimulator(motion=True, accel=ACCEL, idle_timeout=20.0, lifetime=120.0)
    sim.start()
    try:
        runner = JobRunner(Job(f"grbl:{sim.port}", machine, "program", motion, name="mill"))
        runner.run()
        assert runner.state == "done"
        return tuple(sim.trace)
    finally:
        sim.stop()


def _from(trace, point):
    """The positions of ``trace`` from the first time it stands at ``point`` on."""
    xyz = np.array([p for _t, p, *_s in trace])
    k = int(np.flatnonzero(np.linalg.norm(xyz - point, axis=1) < 1e-3)[0])
    return xyz[k:]


def _start_mid(grbl_sim, **options):
    """A mill job started mid-program on a simulator whose machine stands at ELSEWHERE; (sim, runner, ticks, logged)."""
    sim = grbl_sim(motion=True, accel=ACCEL)
    sim.model.position = list(ELSEWHERE)
    _wait(lambda: sim.mpos == ELSEWHERE, 5, "the simulator standing elsewhere")
    sim.trace.clear()  # what it recorded at the origin before
    motion, machine = _mill()
    runner = JobRunner(Job(f"grbl:{sim.port}", machine, "program", motion, name="mill"), **options)
    ticks, logged = [], []
    runner.subscribe(lambda e: ticks.append(e.status) if e.kind == "tick" else
                     logged.append(e.message) if e.kind == "log" else None)
    return sim, runner, ticks, logged


def test_a_start_at_a_segment_restores_spindle_and_coolant_approaches_from_above_and_runs_the_rest(grbl_sim):
    motion, _machine = _mill()
    seg = motion.segment_names.index("part.ngc:7")  # G1 Y20, cutting at Z -1 with spindle and coolant on
    first = motion.positions[np.flatnonzero(motion.segment == seg)[0]]
    sim, runner, ticks, logged = _start_mid(grbl_sim, start_at=seg)
    runner.run()
    assert runner.state == "done"
    trace = sim.trace
    xyz = np.array([p for _t, p, *_s in trace])
    at_start = int(np.flatnonzero(np.linalg.norm(xyz - first, axis=1) < 1e-3)[0])
    approach = trace[:at_start + 1]
    # Z goes up first (to the higher of where it was and where it goes), then across, then down on the spot
    z_safe = max(ELSEWHERE[2], first[2])
    across = [p for _t, p, *_s in approach if np.hypot(p[0] - first[0], p[1] - first[1]) > 1e-3]
    assert across and min(p[2] for p in across) >= z_safe - 1e-6
    down = [(t, p, spindle, rpm, coolant) for t, p, spindle, rpm, coolant in approach if p[2] < z_safe - 1e-6]
    assert down and all(spindle == 3 and rpm == 1000 and coolant == 8 for _t, _p, spindle, rpm, coolant in down)
    spindle_on = next(t for t, _p, spindle, *_r in trace if spindle == 3)
    assert down[0][0] - spindle_on >= 1.0  # the spin-up dwell before the tool goes down
    assert min(p[2] for _t, p, *_s in approach) >= first[2] - 1e-6  # never below the cut's depth on the way
    # from the start on, the executed path is the uninterrupted run's, both ways
    ours, theirs = _from(trace, first), _from(_uninterrupted(), first)
    assert distance_to_polyline(ours, theirs).max() <= PATH_TOL
    assert distance_to_polyline(theirs, ours).max() <= PATH_TOL
    np.testing.assert_allclose(ours[-1], motion.positions[-1], atol=PATH_TOL)
    # the assumptions went to the job log, and into the device log's events
    text = " | ".join(runner.assumptions)
    assert "started at segment 5 (part.ngc:7) at X 20.000, Y 0.000, Z -1.000 mm" in text
    assert "output 1 on, spindle 1,000 rpm cw" in text and "approach: Z up to 3.000 mm" in text
    assert all(a in logged for a in runner.assumptions)
    assert [e.message for e in runner.log.events if e.kind == "restart"] == runner.assumptions
    # ticks name the user's program: no segment on the approach, then segment 5 = line 7 and on
    program = [s for s in ticks if s.segment is not None]
    assert ticks[0].segment is None and program[0].segment == seg and program[0].line == 7
    assert min(s.line for s in program) == 7  # nothing before the start line
    progress = [s.progress for s in ticks]
    row0 = np.flatnonzero(motion.segment == seg)[0]
    assert progress[0] == pytest.approx(row0 / (len(motion.positions) - 1))  # where line 7 is in the program
    assert np.all(np.diff(progress) >= 0) and progress[-1] == 1.0


def test_a_start_at_a_gcode_line_can_be_held_on_the_approach_and_resumed(grbl_sim):
    motion, _machine = _mill()
    first = motion.positions[np.flatnonzero(motion.segment == motion.segment_names.index("part.ngc:11"))[0]]
    sim, runner, ticks, logged = _start_mid(grbl_sim, start_line=11)
    thread = threading.Thread(target=lambda: _quiet(runner.run), daemon=True)
    thread.start()
    _wait(lambda: abs(sim.model.position[0] - ELSEWHERE[0]) > 1.0, what="going across")
    runner.hold()
    _wait(lambda: runner.state == "held", 10, "held on the approach")
    held_at = list(sim.model.position)
    time.sleep(0.5)
    assert sim.model.position == held_at and held_at[2] == pytest.approx(ELSEWHERE[2])  # still, still up
    assert ticks[-1].segment is None  # on the approach, not yet in the program
    runner.resume()
    _wait(lambda: runner.finished, 30, "the end")
    assert runner.state == "done"
    assert runner.assumptions[0] == "G-code line 11 is segment 9 (part.ngc:11)"
    ours, theirs = _from(sim.trace, first), _from(_uninterrupted(), first)
    assert distance_to_polyline(ours, theirs).max() <= PATH_TOL
    assert distance_to_polyline(theirs, ours).max() <= PATH_TOL
    assert min(s.line for s in ticks if s.line is not None) == 11


def test_a_stop_in_the_spin_up_before_the_tool_goes_down_leaves_it_up_and_outputs_off(grbl_sim):
    sim, runner, _ticks, _logged = _start_mid(grbl_sim, start_line=11)
    thread = threading.Thread(target=lambda: _quiet(runner.run), daemon=True)
    thread.start()
    _wait(lambda: sim.spindle_dir == 3, 20, "the spindle restored")
    runner.stop()
    _wait(lambda: runner.finished, 20, "the stop")
    assert runner.state == "aborted" and runner.log.outcome == "aborted"
    assert sim.spindle_dir == 5 and sim.coolant == 9 and sim.alarm == 0
    assert min(p[2] for _t, p, *_s in sim.trace) == pytest.approx(ELSEWHERE[2])  # the tool never went down


def test_a_start_at_a_segment_the_job_does_not_have_is_refused_before_anything_moves(grbl_sim):
    sim = grbl_sim(motion=True, accel=ACCEL)
    runner = JobRunner(Job(f"grbl:{sim.port}", Machine(period=0.001), "program", _program(), name="plotter"),
                       start_at=98)
    with pytest.raises(DeviceError, match=r"segment 99 has no setpoints") as err:
        runner.run()
    assert err.value.where == "plotter" and runner.state == "faulted"
    assert not any(line.startswith("G") for line in sim.received)  # no G-code line reached the board


# ---------------------------------------------------------------- single block (streamed a block at a time)

def _states(runner):
    """The (state, message) changes of ``runner`` from now on, as a list that fills."""
    seen = []
    runner.subscribe(lambda e: seen.append((e.status.state, e.message)) if e.kind == "state" else None)
    return seen


def _held_at_rest(sim, point):
    """The simulator's trace ends standing at ``point`` and stays there (nothing moves while held)."""
    n = len(sim.trace)
    np.testing.assert_allclose(sim.trace[-1][1], point, atol=1e-3)
    assert not sim.model.busy
    time.sleep(0.5)
    assert len(sim.trace) == n and list(sim.model.position) == list(sim.trace[-1][1])


def test_single_block_from_start_holds_at_rest_at_each_block_end_and_resume_runs_the_next(grbl_sim):
    sim, runner, _ticks = _start(grbl_sim, single_block=True)
    for k, corner in enumerate([(60.0, 0.0, 0.0), (60.0, 60.0, 0.0)]):
        _wait(lambda: runner.state == "held", 20, f"held after block {k + 1}")
        assert runner.status.message == f"single block: held at the end of segment {k + 1} (point {k + 1})"
        _held_at_rest(sim, corner)
        # the next side never started: the trace has nothing past this corner
        assert max(p[1] for _t, p, *_s in sim.trace) <= corner[1] + 1e-9
        runner.resume()
        _wait(lambda: runner.state != "held", 5, "resumed")
    _wait(lambda: runner.finished, 20, "the end")
    assert runner.state == "done"
    np.testing.assert_allclose(sim.model.position, [0.0, 60.0, 0.0], atol=1e-3)
    assert [e.message for e in runner.log.events if e.kind == "pause"] == [
        "single block: held at the end of segment 1 (point 1)", "single block: held at the end of segment 2 (point 2)"]


def test_single_block_switched_off_while_held_runs_the_rest_to_the_end(grbl_sim):
    sim, runner, _ticks = _start(grbl_sim, single_block=True)
    _wait(lambda: runner.state == "held", 20, "held after the first block")
    _held_at_rest(sim, (60.0, 0.0, 0.0))
    states = _states(runner)
    runner.set_single_block(False)
    time.sleep(0.3)
    assert runner.state == "held" and len(sim.trace) and sim.model.position == [60.0, 0.0, 0.0]  # Resume goes on
    runner.resume()
    _wait(lambda: runner.finished, 20, "the end")
    assert runner.state == "done" and [s for s, _m in states] == ["running", "done"]  # no hold on the way
    np.testing.assert_allclose(sim.model.position, [0.0, 60.0, 0.0], atol=1e-3)
    np.testing.assert_allclose(sim.trace[-1][1], [0.0, 60.0, 0.0], atol=1e-3)


def _vertex(i):
    return (4.0 * i, 4.0 * (i % 2), 0.0)


def _zigzag():
    """40 sides (zigzag, 4 mm steps within the simulator's travel) at 40 mm/s: more G-code lines than
    GRBL's buffers hold, so some wait to be sent."""
    pts = [_vertex(i) for i in range(41)]
    g = flowmc.GraphBuilder(title="zigzag")
    path = g.add("path.polyline", id="zigzag", points=pts, feed=40.0)
    plan = g.add("interp.time_division", id="plan", profile="trapezoid")
    g.wire(path.path, plan.path)
    result = flowmc.Runtime().run(g.build())
    assert result.ok, result.errors
    return result.output("plan", "trajectory")


def test_single_block_switched_on_mid_job_holds_at_a_block_end_and_stop_from_there_resets(grbl_sim):
    motion = _zigzag()
    sim, runner, _ticks = _start(grbl_sim, motion=motion)
    _wait(lambda: sim.model.position[0] > 10.0, 20, "the third side under way")
    runner.set_single_block(True)
    _wait(lambda: runner.state == "held", 30, "held at a block end")
    # held at a vertex: the end of the segment the message names, at rest, not at the path's end
    k = int(runner.status.message.rsplit("segment ", 1)[1].split(" ")[0])
    assert runner.status.message == f"single block: held at the end of segment {k} (point {k})"
    assert 3 < k < 40
    end = motion.positions[np.flatnonzero(motion.segment == k - 1)[-1]]
    np.testing.assert_allclose(end, _vertex(k), atol=1e-9)
    _held_at_rest(sim, end)
    runner.resume()  # the next block, then held at its end
    _wait(lambda: runner.state == "held" and sim.model.position[0] > end[0] + 2.0, 20, "held after the next block")
    assert runner.status.message == f"single block: held at the end of segment {k + 1} (point {k + 1})"
    _held_at_rest(sim, _vertex(k + 1))
    runner.stop()  # from a single-block hold: GRBL is Idle, the soft reset at once
    _wait(lambda: runner.finished, 20, "the stop")
    assert runner.state == "aborted" and "stopped by the operator" in runner.message
    assert sim.alarm == 0 and sim.spindle_dir == 5 and sim.coolant == 9
    assert [b for _t, b in sim.bytes_seen if b in (ord("!"), 0x18)][-1:] == [0x18]
    assert any(e.kind == "safe" for e in runner.log.events)


def test_single_block_with_a_start_at_a_gcode_line_and_a_program_stop(grbl_sim):
    """Started at line 11 with single block on, on a program with an M0 at line 12."""
    text = MILL.replace("G1 X30 Y20\n", "M0 (check the cut)\nG1 X30 Y20\n")
    machine = Machine()
    motion = plan_stop_and_go(parse_gcode(text, "part.ngc"), machine).trajectory
    sim = grbl_sim(motion=True, accel=ACCEL)
    runner = JobRunner(Job(f"grbl:{sim.port}", machine, "program", motion, name="mill"), start_line=11,
                       single_block=True)
    thread = threading.Thread(target=lambda: _quiet(runner.run), daemon=True)
    thread.start()
    holds = []
    while True:
        _wait(lambda: runner.state == "held" or runner.finished, 30, "held or the end")
        if runner.finished:
            break
        time.sleep(0.3)
        holds.append((runner.status.message, tuple(sim.model.position), sim.model.busy))
        runner.resume()
        _wait(lambda: runner.state != "held", 5, "resumed")
    assert runner.state == "done", runner.status.message
    np.testing.assert_allclose(sim.model.position, motion.positions[-1], atol=1e-3)
    # a hold at the end of each block from the start line on, the program's M0 as its own stop between
    assert [m for m, _p, _busy in holds] == [
        "single block: held at the end of segment 9 (part.ngc:11)",
        "program pause (M0) at part.ngc:12; Resume carries on",
        "single block: held at the end of segment 11 (part.ngc:13)",
        "single block: held at the end of segment 12 (part.ngc:14)"]
    for (_m, at, busy), end in zip(holds, [(40, 10, -1), (40, 10, -1), (30, 20, -1), (30, 20, 5)]):
        assert not busy and np.linalg.norm(np.subtract(at, end)) <= PATH_TOL  # at rest at the block's end
    assert runner.assumptions[0] == "G-code line 11 is segment 9 (part.ngc:11)"


def test_single_block_a_feed_hold_inside_a_block_resumes_to_its_end_and_estop_from_there_resets(grbl_sim):
    sim, runner, _ticks = _start(grbl_sim, single_block=True)
    _wait(lambda: sim.model.position[0] > 20.0, 10, "the first side under way")
    runner.hold()
    _wait(lambda: runner.state == "held", 10, "the feed hold")
    assert runner.status.message.startswith("held at line") and 20.0 < sim.model.position[0] < 60.0
    runner.resume()  # the rest of the block, then the single-block hold at its end
    _wait(lambda: runner.status.message.startswith("single block"), 20, "held at the block's end")
    assert runner.status.message == "single block: held at the end of segment 1 (point 1)"
    _held_at_rest(sim, (60.0, 0.0, 0.0))
    runner.estop()
    _wait(lambda: runner.finished, 20, "the e-stop")
    assert runner.state == "aborted" and runner.log.outcome == "estop"
    assert sim.alarm == 0 and sim.spindle_dir == 5  # the reset came at rest: GRBL kept its position
    np.testing.assert_allclose(sim.model.position, [60.0, 0.0, 0.0], atol=1e-3)
