"""Jobs stop for the program's operator events (M0, M1 with the optional stop on, M6) on the simulated
card, through the job API: the job comes to rest where the G-code reader put the event, holds, and
Resume carries on along the uninterrupted path. Checked from the raw commanded setpoints and the
card's output changes."""

import threading

import numpy as np
import pytest

from flowmc.devices.jobs import Job, JobRunner
from flowmc.motion.gcode import parse_gcode
from flowmc.motion.lookahead import plan_lookahead, plan_stop_and_go
from flowmc.motion.machine import Machine
from tests.devices.job_helpers import distance_to_polyline, limits_ratio

PROGRAM = """G21 G90 G17
G0 X0 Y0 Z5
M3 S1000
G1 Z0 F600
G1 X20 F1200
(MSG, check the part)
M0
G1 Y20
M1
G1 X0
M5
T2 M6
M3 S2000
G1 Y0
M5
M2
"""
M0_AT, M1_AT, M6_AT = (20.0, 0.0, 0.0), (20.0, 20.0, 0.0), (0.0, 20.0, 0.0)


def _job(planner=plan_lookahead) -> Job:
    machine = Machine()
    motion = planner(parse_gcode(PROGRAM, "part.ngc"), machine).trajectory
    return Job("sim", machine, "program", motion, name="card")


def _run(job, resume_after: float = 0.5, **options):
    """Run on the virtual pace; Resume ``resume_after`` s after every hold. (runner, held events, log)."""
    runner = JobRunner(job, pace="virtual", record=True, **options)
    held = []

    def on_event(event):
        if event.kind == "state" and event.status.state == "held":
            held.append(event)
            runner.at(event.status.t + resume_after, "resume")

    runner.subscribe(on_event)
    log = runner.run()
    return runner, held, log


def test_the_planned_program_carries_the_readers_events_with_their_lines():
    motion = _job().motion
    assert [(e.code, motion.segment_names[e.segment]) for e in motion.events] == [
        ("M0", "part.ngc:7"), ("M1", "part.ngc:9"), ("M6", "part.ngc:12")]
    assert motion.events[0].message == "check the part" and motion.events[2].tool == 2


@pytest.mark.parametrize("planner", [plan_lookahead, plan_stop_and_go])
def test_m0_and_m6_hold_the_job_at_rest_where_they_are_and_resume_carries_on(planner):
    job = _job(planner)
    runner, held, log = _run(job)
    assert runner.state == "done"
    assert [e.message.split(";")[0] for e in held] == [
        "program pause (M0) at segment 4 (part.ngc:7): check the part",
        "tool change (M6) at segment 8 (part.ngc:12): change to tool T2"]
    assert [e.status.line for e in held] == [7, 12]  # the DRO and the source view show the M0 and M6 lines
    for event, point in zip(held, (M0_AT, M6_AT)):
        np.testing.assert_allclose(event.status.commanded, point, atol=1e-3)
    sp = runner.setpoints()
    T = job.machine.period
    for event, point in zip(held, (M0_AT, M6_AT)):  # stays there, not moving, until Resume
        k = int(round(event.status.t / T))
        np.testing.assert_allclose(sp[k - 1:k + int(0.4 / T)], np.broadcast_to(point, (int(0.4 / T) + 1, 3)), atol=1e-3)
    motion = job.motion
    assert distance_to_polyline(sp, np.asarray(motion.positions)).max() < 1e-3  # the uninterrupted path
    np.testing.assert_allclose(sp[-1], motion.positions[-1], atol=1e-9)
    v, a = limits_ratio(np.vstack([motion.positions[:1], sp]), job.machine, T)
    assert v <= 1.0 + 1e-6 and a <= 1.0 + 1e-6
    assert runner.setpoints().shape[0] * T == pytest.approx(motion.duration + 2 * 0.5, abs=0.2)  # two holds of 0.5 s
    assert [e.kind for e in log.events].count("pause") == 2


def test_the_spindle_is_off_through_a_tool_change_and_starts_after_resume():
    runner, held, log = _run(_job(), resume_after=1.0)
    t_m6 = held[1].status.t
    spindle = [(c.t, c.value) for c in log.changes if c.kind == "spindle_rpm"]
    off = [t for t, v in spindle if v == 0 and t <= t_m6 + 1e-9]
    on_after = [(t, v) for t, v in spindle if t > t_m6]
    assert off and held[1].status.outputs["spindle_rpm"] == 0  # M5 before M6: off while held
    assert on_after[0][0] == pytest.approx(t_m6 + 1.0, abs=0.02) and on_after[0][1] > 1900  # M3 S2000 after Resume


def test_m1_stops_only_with_the_optional_stop_on():
    _runner, held, _log = _run(_job())
    assert not any("M1" in e.message for e in held)
    _runner, held, _log = _run(_job(), optional_stop=True)
    assert [e.message.split(" at ")[0] for e in held] == ["program pause (M0)", "optional stop (M1)", "tool change (M6)"]
    np.testing.assert_allclose(held[1].status.commanded, M1_AT, atol=1e-3)


def test_the_optional_stop_switched_on_while_the_job_runs_stops_at_the_next_m1():
    job = _job()
    runner = JobRunner(job, pace="virtual", record=True)
    held = []

    def on_event(event):
        if event.kind == "state" and event.status.state == "held":
            held.append(event)
            if len(held) == 1:
                runner.set_optional_stop(True)  # while held at M0: it must not move the job
            runner.at(event.status.t + 0.5, "resume")

    runner.subscribe(on_event)
    runner.run()
    assert [e.message.split(" at ")[0] for e in held] == ["program pause (M0)", "optional stop (M1)", "tool change (M6)"]
    assert runner.status.optional_stop


def test_a_start_after_a_tool_change_does_not_stop_for_it_and_says_which_tool_it_assumes():
    job = _job()
    after_m6 = job.motion.events[2].segment + 1
    runner, held, _log = _run(job, start_at=after_m6)
    assert runner.state == "done" and held == []
    assert any("tool T2 is loaded" in a and "part.ngc:12" in a for a in runner.assumptions)


def test_a_stop_command_while_paused_aborts_with_outputs_safe():
    job = _job()
    runner = JobRunner(job, pace="virtual")
    runner.subscribe(lambda e: runner.stop() if e.kind == "state" and e.status.state == "held" else None)
    runner.run()
    assert runner.state == "aborted"
    assert runner.status.outputs["spindle_rpm"] == 0 and not runner.status.outputs["dout"]


# ---------------------------------------------------------------- GRBL (protocol simulator, motion model)

def _grbl_run(grbl_sim, **options):
    """The program on the GRBL simulator; every hold is resumed after 0.3 s. (sim, runner, held, where held)."""
    sim = grbl_sim(motion=True, accel=200.0)
    machine = Machine()
    motion = plan_lookahead(parse_gcode(PROGRAM.replace("M3 S2000", "M3 S2000 F1200"), "part.ngc"), machine).trajectory
    runner = JobRunner(Job(f"grbl:{sim.port}", machine, "program", motion, name="mill"), **options)
    held, at = [], []

    def on_event(event):
        if event.kind == "state" and event.status.state == "held":
            held.append(event)
            at.append((list(sim.model.position), sim.spindle_dir, sim.model.state()))
            threading.Timer(0.3, runner.resume).start()

    runner.subscribe(on_event)
    runner.run()
    return sim, runner, held, at


def test_grbl_pauses_on_m0_and_m6_as_m0_and_cycle_start_resumes(grbl_sim):
    sim, runner, held, at = _grbl_run(grbl_sim)
    assert runner.state == "done"
    assert [e.message.split(";")[0] for e in held] == [
        "program pause (M0): check the part at part.ngc:7", "tool change (M6): change to tool T2 at part.ngc:12"]
    assert [e.status.line for e in held] == [7, 12]
    for (position, _spindle, state), point in zip(at, (M0_AT, M6_AT)):
        assert state == "Hold:0"  # GRBL itself is paused, at rest
        np.testing.assert_allclose(position, point, atol=0.02)
    assert at[1][1] == 5  # M5 went before the M6: the spindle is off through the tool change
    sent = [line for line in sim.received if line.strip()]
    i_m6 = [i for i, line in enumerate(sent) if line == "M0"][1]
    i_m3 = next(i for i, line in enumerate(sent) if line.startswith("M3 S2000"))
    assert sent[i_m6 - 1] == "M5" and i_m6 < i_m3 < i_m6 + 3  # M3 after the stop (the dwell's last row between)
    assert sum(1 for _t, b in sim.bytes_seen if b == ord("~")) == 2
    np.testing.assert_allclose(sim.model.position, runner.job.motion.positions[-1], atol=0.02)


def test_grbl_sends_m1_as_a_stop_only_with_the_optional_stop_on(grbl_sim):
    _sim, _runner, held, _at = _grbl_run(grbl_sim)
    assert len(held) == 2
    _sim, runner, held, at = _grbl_run(grbl_sim, optional_stop=True)
    assert runner.state == "done" and len(held) == 3
    assert held[1].message.startswith("optional stop (M1) at part.ngc:9")
    np.testing.assert_allclose(at[1][0], M1_AT, atol=0.02)


# ---------------------------------------------------------------- start at a G-code line

def test_start_at_a_gcode_line_starts_at_its_segment_and_says_what_it_assumed():
    job = _job()
    runner, held, _log = _run(job, start_line=13)  # "M3 S2000": no motion of its own, after the M6
    assert runner.state == "done" and held == []  # the tool change before it is behind the start
    text = " | ".join(runner.assumptions)
    assert "G-code line 13 has no motion of its own: started at line 14" in text
    assert "spindle 2,000 rpm" in text and "tool T2 is loaded" in text
    sp = runner.setpoints()
    y_line = job.motion.positions[np.flatnonzero(job.motion.segment == runner.start_at)]
    assert np.min(np.linalg.norm(sp - y_line[0], axis=1)) < 1e-6  # it reached the start of line 14's move ...
    np.testing.assert_allclose(sp[-1], job.motion.positions[-1], atol=1e-9)  # ... and ran to the end
    assert np.all(sp[:, 0] <= 1e-6)  # never drew the X moves before it (the job started at X 0 Y 20)


def test_start_at_a_line_after_the_program_is_refused_naming_its_lines():
    from flowmc.errors import DeviceError

    said = r"no motion at G-code line 99 or after it \(the program's segments come from lines 2-16\)"
    with pytest.raises(DeviceError, match=said):
        JobRunner(_job(), pace="virtual", start_line=99)


def test_start_line_as_a_start_option_reaches_the_runner():
    from flowmc.devices.jobs.prepare import start_job

    class Start:
        options = {"pace": "virtual", "start_line": {"card": 14}}  # after the M6: no stop waits for Resume
        on_job = None

    runner = start_job(_job(), None, Start(), "card")
    assert runner.state == "done" and runner.assumptions[0] == "G-code line 14 is segment 9 (part.ngc:14)"
