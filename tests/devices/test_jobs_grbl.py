"""Jobs on GRBL through its real-time bytes, against the protocol simulator with its motion model
(``GrblSimulator(motion=True)``: moves take time, hold decelerates at 200 mm/s^2, overrides change the
speed). What is checked comes from the simulator's own record of the bytes it received and from the
status reports the job logged."""

import threading
import time

import numpy as np
import pytest

import flowmc
from flowmc.devices.jobs import Job, JobRunner
from flowmc.devices.jobs.grbl_driver import override_bytes
from flowmc.errors import DeviceError
from flowmc.motion.machine import Machine
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


def _start(grbl_sim):
    sim = grbl_sim(motion=True, accel=ACCEL)
    machine = Machine(period=0.001)
    runner = JobRunner(Job(f"grbl:{sim.port}", machine, "program", _program(), name="plotter"))
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


def test_a_start_mid_program_is_refused_before_anything_moves(grbl_sim):
    """GRBL does not rebuild the state mid-program yet: streaming the whole program instead would be
    motion nobody asked for, so the job faults at Start, naming the segment, and the board sees no line."""
    sim = grbl_sim(motion=True, accel=ACCEL)
    runner = JobRunner(Job(f"grbl:{sim.port}", Machine(period=0.001), "program", _program(), name="plotter"),
                       start_at=1)
    with pytest.raises(DeviceError, match=r"starting at segment 2.*nothing was moved") as err:
        runner.run()
    assert err.value.where == "plotter" and runner.state == "faulted"
    assert sim.model.position == [0.0, 0.0, 0.0]
    assert not any(b == ord("G") for _, b in sim.bytes_seen)  # no G-code line reached the board
