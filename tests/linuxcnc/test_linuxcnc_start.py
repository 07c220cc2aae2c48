"""Starting a job at a G-code line on the real LinuxCNC simulator: the state the program built before it
(spindle, output 1) is restored before the tool goes down, Z comes from above, and from the line on
LinuxCNC runs the program's path. Checked from HAL's sampler record of every servo period (the
device log) and from the job's ticks."""

import threading
import time

import numpy as np
import pytest

from flowmc.devices import backends
from flowmc.devices.jobs import Job, JobRunner
from flowmc.devices.jobs.runner import claim
from flowmc.devices.linuxcnc.card import LinuxCNCCard
from flowmc.errors import DeviceError
from flowmc.motion.gcode import parse_gcode
from flowmc.motion.lookahead import plan_stop_and_go
from job_waits import quiet as _quiet
from job_waits import wait_until
from linuxcnc_programs import distance_to, live_linuxcnc_processes, machine

pytestmark = pytest.mark.linuxcnc

MILL = """G21 G90 G17
G0 X0 Y0 Z5
M3 S1000
M8
G1 Z-1 F1200
G1 X20 F2400
G1 Y20
G0 Z5
G0 X30 Y0
G1 Z-1 F1200
G1 X40 Y10 F2400
M9
M5
G0 Z5
M2
"""
ELSEWHERE = [35.0, 25.0, 3.0]  # where the machine stands at Start
BLEND = 0.001 + 1e-6  # mm: LinuxCNC rounds corners within the card's G64 P0.001 (samples have 6 decimals)


@pytest.fixture
def mill(monkeypatch):
    """(motion, runner factory): the card starts at ELSEWHERE with its outputs and spindle off."""
    monkeypatch.setitem(backends._BACKENDS, "linuxcnc", lambda argument, m, options, **kw: LinuxCNCCard(
        m, state={"position_xyz": ELSEWHERE}, **kw))
    motion = plan_stop_and_go(parse_gcode(MILL, "part.ngc"), machine()).trajectory

    def runner(**options):
        """A runner whose device is free: another test process may hold LinuxCNC (its lock) for a while."""
        end = time.monotonic() + 300.0
        while True:
            run = JobRunner(Job("linuxcnc", machine(), "program", motion, name="mill"), **options)
            ticks = []
            run.subscribe(lambda e: ticks.append(e.status) if e.kind == "tick" else None)
            try:
                with claim("linuxcnc", "the test, waiting for the device"):
                    return run, ticks
            except DeviceError:
                if time.monotonic() > end:
                    raise
                time.sleep(1.0)

    return motion, runner


def test_a_start_at_a_gcode_line_restores_the_state_approaches_from_above_and_runs_the_rest(mill):
    motion, make = mill
    runner, ticks = make(start_line=7)  # G1 Y20: cutting at Z -1, spindle and coolant (output 1) on
    log = runner.run()
    assert runner.state == "done"
    seg = runner.start_at
    row0 = int(np.flatnonzero(motion.segment == seg)[0])
    first = motion.positions[row0]
    pos = log.position
    at_start = int(np.flatnonzero(np.linalg.norm(pos - first, axis=1) < BLEND)[0])
    approach = pos[:at_start + 1]
    z_safe = max(ELSEWHERE[2], first[2])
    across = np.hypot(approach[:, 0] - first[0], approach[:, 1] - first[1]) > BLEND
    assert across.any() and approach[across, 2].min() >= z_safe - BLEND  # across only at the safe height
    assert approach[:, 2].min() >= first[2] - BLEND  # and never below the cut on the way
    down = log.t[int(np.flatnonzero(pos[:, 2] < z_safe - BLEND)[0])]
    on = {c.kind: c.t for c in log.changes if c.value > 0}
    assert set(on) == {"spindle_rpm", "dout"} and max(on.values()) < down  # restored before the tool goes down
    assert down - on["spindle_rpm"] >= 1.0 - 2 * log.period  # with the spin-up dwell
    # from the line on, LinuxCNC runs the program's path (within its G64 P0.001 blending), both ways
    rest, plan = pos[at_start:], motion.positions[row0:]
    assert distance_to(plan, rest).max() < 0.005 and distance_to(rest, plan).max() < 0.005
    np.testing.assert_allclose(log.end_position, motion.positions[-1], atol=1e-6)
    # what was assumed is in the job log and the device log
    text = " | ".join(runner.assumptions)
    assert "G-code line 7 is segment 5 (part.ngc:7)" in text and "output 1 on, spindle 1,000 rpm cw" in text
    assert "approach: Z up to 3.000 mm" in text and "pen" not in text  # the tool drives nothing on LinuxCNC
    assert [e.message for e in log.events if e.kind == "restart"] == runner.assumptions
    # ticks name the user's program: nothing on the approach, then line 7 and on, progress from there
    program = [s for s in ticks if s.segment is not None]
    assert program[0].segment == seg and program[0].line == 7 and min(s.line for s in program) == 7
    on_approach = [s for s in ticks[1:] if s.segment is None and s.where.startswith("approach to segment")]
    assert on_approach and all(s.progress == pytest.approx(row0 / (len(motion.positions) - 1)) for s in on_approach)
    progress = [s.progress for s in ticks[1:]]
    assert np.all(np.diff(progress) >= -1e-12) and progress[-1] == 1.0
    assert not live_linuxcnc_processes()


def test_a_stop_in_the_spin_up_leaves_the_tool_up_and_the_outputs_off(mill):
    motion, make = mill
    runner, ticks = make(start_line=11)  # G1 X40 Y10 from X30 Y0 Z-1
    over = motion.positions[np.flatnonzero(motion.segment == runner.start_at)[0]][:2]
    threading.Thread(target=lambda: _quiet(runner.run), daemon=True).start()
    wait_until(lambda: ticks and np.hypot(*(np.array(ticks[-1].commanded[:2]) - over)) < BLEND, 300.0,
               "across, over the start")
    time.sleep(0.3)  # into the 1 s spin-up dwell
    runner.stop()
    assert runner.wait(60.0)
    log = runner.log
    assert runner.state == "aborted" and log.outcome == "aborted"
    assert [c.value for c in log.changes if c.kind == "spindle_rpm"] == [1000.0, 0.0]  # restored, then off
    assert log.state["spindle_rpm"] == 0.0 and not any(log.state["dout"])
    assert log.position[:, 2].min() >= ELSEWHERE[2] - BLEND  # the tool never went down
    assert not live_linuxcnc_processes()
