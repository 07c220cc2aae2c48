"""Feed hold, resume and abort of a job on the real LinuxCNC simulator (through its task, from the job API).

The job is a 30 mm X line at 10 mm/s with the spindle on at 1000 rpm (3 s of motion). What is checked
comes from the job's position ticks (LinuxCNC's commanded position, 25 Hz) and from HAL's sampler
record of every servo period (the device log).
"""

import threading
import time

import numpy as np
import pytest

from flowmc.devices.jobs import Job, JobRunner
from flowmc.motion.trajectory import ProgramEvent, Signal, Trajectory
from job_waits import quiet as _quiet
from job_waits import wait_until
from linuxcnc_programs import live_linuxcnc_processes, machine


def _wait(check, timeout=300.0, what="condition"):  # long: another session may hold the machine
    wait_until(check, timeout, what)


pytestmark = pytest.mark.linuxcnc

SPEED, LENGTH, PERIOD = 10.0, 30.0, 0.01
AMAX = machine().axes[0].amax  # mm/s^2


def _within_limits(log):
    """Forwards along X only, never faster than programmed, never harder than AMAX (from every servo period)."""
    v = np.diff(log.position, axis=0) / log.period
    a = np.diff(v[:, 0]) / log.period
    assert v[:, 0].min() > -1e-6 and v[:, 0].max() < SPEED * 1.001
    assert np.abs(v[:, 1:]).max() == 0.0
    assert np.abs(a).max() <= AMAX * 1.01


_STARTED: list[JobRunner] = []


@pytest.fixture(autouse=True)
def _stop_what_a_test_left():
    """A failed check while a job is held would leave LinuxCNC held for ever (held time has no timeout):
    stop every job a test started and did not see end."""
    yield
    while _STARTED:
        runner = _STARTED.pop()
        if not runner.wait(0.0):
            runner.stop()
            runner.wait(60.0)


def _start():
    rows = int(LENGTH / SPEED / PERIOD) + 1
    pos = np.zeros((rows, 3))
    pos[:, 0] = np.linspace(0.0, LENGTH, rows)
    motion = Trajectory(pos, PERIOD, np.zeros(rows, dtype=int))
    spindle = Signal([0.0], ["spindle_rpm"], [1], [1000.0])
    runner = JobRunner(Job("linuxcnc", machine(), "program", motion, spindle, name="slow line"))
    ticks = []
    runner.subscribe(lambda e: ticks.append((time.monotonic(), e.status)) if e.kind == "tick" else None)
    _STARTED.append(runner)
    threading.Thread(target=lambda: _quiet(runner.run), daemon=True).start()
    return runner, ticks


def _x(ticks):
    return ticks[-1][1].commanded[0] if ticks else 0.0


def _hold_at(runner, ticks, x):
    _wait(lambda: _x(ticks) > x, what=f"X past {x} mm")
    runner.hold()
    _wait(lambda: runner.state == "held", timeout=10.0, what="held")
    held_at = len(ticks)
    time.sleep(1.0)
    return [t[1].commanded[0] for t in ticks[held_at:]]


def test_hold_stops_the_motion_on_the_path_and_resume_ends_at_the_programmed_end():
    runner, ticks = _start()
    held = _hold_at(runner, ticks, 8.0)
    assert len(held) >= 15  # 25 Hz for a second
    assert max(held) - min(held) == 0.0  # held: LinuxCNC's commanded position does not change
    assert 8.0 < held[0] < 8.0 + 3.0  # a deceleration along the path, not a jump
    runner.resume()
    assert runner.wait(60.0)
    assert runner.state == "done"
    log = runner.log
    np.testing.assert_allclose(log.end_position, [LENGTH, 0.0, 0.0], atol=1e-9)
    _within_limits(log)
    x = log.position[:, 0]
    still = np.flatnonzero((x > held[0] - 1e-9) & (x < held[0] + 1e-9))
    assert len(still) * log.period >= 1.0  # the sampler saw it stand still at the hold for the second
    assert not live_linuxcnc_processes()


@pytest.mark.parametrize("command, outcome, said", [("stop", "aborted", "stopped by the operator"),
                                                     ("estop", "estop", "e-stop")])
def test_stop_and_estop_end_the_job_aborted_with_the_spindle_off(command, outcome, said):
    runner, ticks = _start()
    _wait(lambda: _x(ticks) > 8.0, what="X past 8 mm")
    x_stop = _x(ticks)
    getattr(runner, command)()
    assert runner.wait(60.0)
    assert runner.state == "aborted" and said in runner.message
    log = runner.log
    assert log.outcome == outcome
    # stopped soon after the command (the 20 ms command poll, the display program's 10 ms loop and
    # LinuxCNC's task cycle; about 80 ms measured, 0.5 s allowed on a loaded machine), well short of
    # the end: the rest of the job is cleared
    assert x_stop < log.end_position[0] < x_stop + SPEED * 0.5 + SPEED**2 / (2 * AMAX)
    if command == "stop":
        _within_limits(log)  # a controlled stop along the path, within the acceleration limit
    else:
        v = np.diff(log.position[:, 0]) / log.period
        assert v.min() > -1e-6
        assert np.abs(np.diff(v)).max() / log.period > 10 * AMAX  # no deceleration ramp: LinuxCNC's e-stop
    assert [c.value for c in log.changes if c.kind == "spindle_rpm"] == [1000.0, 0.0]  # on, then off
    assert log.state["spindle_rpm"] == 0.0 and not any(log.state["dout"])
    assert not live_linuxcnc_processes()


def test_feed_override_halves_the_speed_for_the_rest_of_the_job():
    runner, ticks = _start()
    _wait(lambda: _x(ticks) > 5.0, what="X past 5 mm")
    runner.set_overrides(feed=50.0)
    assert runner.wait(60.0)
    assert runner.state == "done" and runner.status.feed == 50.0
    log = runner.log
    np.testing.assert_allclose(log.end_position, [LENGTH, 0.0, 0.0], atol=1e-9)
    _within_limits(log)
    v = np.diff(log.position[:, 0]) / log.period
    moving = v > 1e-9
    assert v[np.flatnonzero(log.position[1:, 0] < 5.0)].max() == pytest.approx(SPEED, rel=1e-3)
    late = (log.position[1:, 0] > 15.0) & (log.position[1:, 0] < LENGTH - 1.0) & moving
    np.testing.assert_allclose(v[late], SPEED / 2, rtol=1e-3)  # the rest at 5 mm/s
    # time left: the plan's time still to run, doubled once the override is 50 %
    slow = [s for _t, s in ticks if s.feed == 50.0 and 0.0 < s.progress < 1.0]
    assert slow and all(s.time_left == pytest.approx(2 * LENGTH / SPEED * (1 - s.progress), abs=0.02) for s in slow)
    assert not live_linuxcnc_processes()


def test_a_hold_longer_than_the_cards_timeout_is_not_a_fault(monkeypatch):
    """The timeout guards a LinuxCNC that hangs, not an operator who holds: held time does not count."""
    from flowmc.devices import backends
    from flowmc.devices.linuxcnc.card import LinuxCNCCard

    timeout = 5.0  # the 3 s program and its start-up fit; the 3 s program plus a 4 s hold does not
    monkeypatch.setitem(backends._BACKENDS, "linuxcnc",
                        lambda argument, machine, options, **kw: LinuxCNCCard(machine, timeout=timeout, **kw))
    runner, ticks = _start()
    _hold_at(runner, ticks, 8.0)
    time.sleep(timeout - 1.0)  # held for the 1 s of _hold_at plus this: 5 s in all
    runner.resume()
    assert runner.wait(60.0)
    assert runner.state == "done", runner.message
    np.testing.assert_allclose(runner.log.end_position, [LENGTH, 0.0, 0.0], atol=1e-9)
    assert not live_linuxcnc_processes()


def test_an_m1_with_the_optional_stop_off_runs_on_linuxcnc():
    rows = int(1.0 / SPEED / PERIOD) + 1
    pos = np.zeros((rows, 3))
    pos[:, 0] = np.linspace(0.0, 1.0, rows)
    motion = Trajectory(pos, PERIOD, np.zeros(rows, dtype=int), events=(ProgramEvent(0, "optional_pause"),))
    runner = JobRunner(Job("linuxcnc", machine(), "program", motion, name="m1 off"))
    runner.run()
    assert runner.state == "done"
    np.testing.assert_allclose(runner.log.end_position, [1.0, 0.0, 0.0], atol=1e-9)
