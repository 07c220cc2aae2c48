"""Jobs on the simulated card through the job API: hold, resume, stop, e-stop, overrides, single block,
start from a segment, one job per device. Programs are the thesis example graph's plan; every limit
and time is checked from the raw commanded setpoints the runner records."""

import threading

import numpy as np
import pytest

from flowmc.devices.backends import DeviceOptions, SimOptions
from flowmc.devices.jobs import Job, JobRunner
from flowmc.errors import DeviceError
from flowmc.motion.trajectory import Trajectory
from tests.devices.job_helpers import distance_to_polyline, example_program, limits_ratio, moving_rows, thesis_job

TOL = 1e-3  # mm: how far from the planned path a re-timed setpoint may be


def _run(job, *commands, **options):
    runner = JobRunner(job, pace="virtual", record=True, **options)
    for t, name, *value in commands:
        runner.at(t, name, *value)
    log = runner.run()
    motion = job.motion
    return runner, log, np.vstack([motion.positions[:1], runner.setpoints()])


def _event_row(log, kind: str, text: str, period: float) -> int:
    event = next(e for e in log.events if e.kind == kind and text in e.message)
    return int(round(event.t / period))


def test_streamed_job_without_commands_is_the_instant_run():
    job = thesis_job()
    instant = JobRunner(job).run()
    streamed = JobRunner(job, pace="virtual").run()
    assert streamed.digest() == instant.digest()


def test_streamed_closed_loop_matches_the_instant_closed_loop():
    motion, machine = example_program()
    job = Job("sim", machine, "program", motion, options=DeviceOptions(sim=SimOptions(closed_loop=True)))
    instant = JobRunner(job).run()
    runner = JobRunner(job, pace="virtual")
    seen = []
    runner.subscribe(lambda e: seen.append(e.status) if e.kind == "tick" else None)
    streamed = runner.run()
    assert len(streamed) == len(instant)
    np.testing.assert_allclose(streamed.position, instant.position, atol=1e-9)
    assert max(abs(e) for s in seen for e in s.following_error) > 0.001  # the DRO shows a real following error


def test_hold_at_30_percent_stops_within_v_over_amax_on_the_path_and_stays_stopped():
    motion, machine = example_program()
    T = machine.period
    t_hold = 0.3 * motion.duration
    runner, log, sp = _run(thesis_job(), (t_hold, "hold"), (t_hold + 2.0, "resume"))
    k = _event_row(log, "job", "feed hold", T)
    v = float(np.linalg.norm(sp[k] - sp[k - 1]) / T)
    assert v > 5.0  # it was moving
    moves = moving_rows(sp)
    stop = int(moves[moves >= k][np.argmax(np.diff(moves[moves >= k], append=10**9) > 1)]) + 1
    assert (stop - k) * T <= v / machine.column("amax").min() + T
    resumed = _event_row(log, "job", "resume", T)
    assert resumed - stop > 400  # held for ~2 s ...
    assert np.all(sp[stop:resumed + 1] == sp[stop])  # ... without moving
    assert distance_to_polyline(sp[k:stop + 1], motion.positions).max() <= TOL
    vr, ar = limits_ratio(sp, machine, T)
    assert vr <= 1.0 + 1e-9 and ar <= 1.0


def test_resume_ends_at_the_programmed_end_on_the_uninterrupted_path():
    motion, machine = example_program()
    t_hold = 0.3 * motion.duration
    runner, log, sp = _run(thesis_job(), (t_hold, "hold"), (t_hold + 1.0, "resume"))
    assert runner.state == "done" and log.outcome == "done"
    np.testing.assert_allclose(sp[-1], motion.positions[-1], atol=1e-12)
    assert distance_to_polyline(sp, motion.positions).max() <= TOL  # nothing off the path ...
    assert distance_to_polyline(motion.positions, sp).max() <= TOL  # ... and none of it skipped
    assert len(sp) > len(motion.positions) + 0.9 / machine.period  # the hold took its time


def test_stop_decelerates_along_the_path_then_leaves_every_output_safe():
    motion, machine = example_program()
    T = machine.period
    runner, log, sp = _run(thesis_job(), (0.3 * motion.duration, "stop"))
    assert runner.state == "aborted" and log.outcome == "aborted"
    k = _event_row(log, "job", "stop", T)
    v = float(np.linalg.norm(sp[k] - sp[k - 1]) / T)
    assert (len(sp) - 1 - k) * T <= v / machine.column("amax").min() + T
    assert distance_to_polyline(sp[k:], motion.positions).max() <= TOL
    state = log.state
    assert state["spindle_rpm"] == 0 and not state["tool_down"] and state["da"] == 0 and not any(state["outputs"])
    assert any(c.kind == "spindle_rpm" and c.value == 0 for c in log.changes)
    assert "stopped by the operator at segment" in runner.message


def test_estop_stops_every_axis_at_once_latches_and_leaves_outputs_safe():
    motion, machine = example_program()
    T = machine.period
    runner, log, sp = _run(thesis_job(), (0.5 * motion.duration, "estop"))
    assert runner.state == "aborted" and log.outcome == "estop"
    k = _event_row(log, "estop", "software e-stop", T)
    assert len(sp) - 1 == k  # nothing moved after the period it came in
    assert log.state["estop"] and log.state["spindle_rpm"] == 0 and not any(log.state["outputs"])


def test_feed_override_50_roughly_doubles_the_remaining_time_within_limits():
    motion, machine = example_program()
    T = machine.period
    t = 0.3 * motion.duration
    runner, log, sp = _run(thesis_job(), (t, "feed", 50.0))
    k = _event_row(log, "job", "feed override", T)
    planned_left = (len(motion.positions) - 1 - k) * T
    ran_left = (len(sp) - 1 - k) * T
    assert 1.9 <= ran_left / planned_left <= 2.05
    vr, ar = limits_ratio(sp, machine, T)
    assert vr <= 1.0 + 1e-9 and ar <= 1.0


def test_time_left_follows_the_feed_override():
    job = thesis_job()
    runner = JobRunner(job, pace="virtual")
    seen = []
    runner.subscribe(lambda e: seen.append((e.status.t, e.status.time_left, e.status.feed)) if e.kind == "tick" else None)
    runner.at(4.0, "feed", 50.0)
    runner.run()
    before = [left + t for t, left, feed in seen if t < 4.0 and feed == 100.0]
    after = [left for t, left, feed in seen if t >= 4.1 and feed == 50.0]
    at_4 = next(left for t, left, feed in seen if t >= 4.0 and feed == 100.0)
    assert abs(before[-1] - job.duration) < 0.05  # time left + elapsed = the plan
    assert after[0] == pytest.approx(2 * at_4, rel=0.05)


@pytest.mark.parametrize("feed", [200.0, 150.0])
def test_feed_override_above_100_stays_within_every_axis_limit(feed):
    motion, machine = example_program()
    runner, log, sp = _run(thesis_job(), (0.1 * motion.duration, "feed", feed))
    vr, ar = limits_ratio(sp, machine, machine.period)
    assert vr <= 1.0 + 1e-9 and ar <= 1.0
    assert len(sp) < len(motion.positions)  # and it is faster
    assert distance_to_polyline(sp, motion.positions).max() <= TOL


def test_rapid_override_applies_to_rapid_segments_only():
    from flowmc.motion.lookahead import plan_lookahead
    from flowmc.motion.path import Line, Path

    motion, machine = example_program()
    path = Path([Line((0, 0, 0), (40, 0, 0), feed=40.0, rapid=True), Line((40, 0, 0), (40, 30, 0), feed=10.0)])
    traj = plan_lookahead(path, machine).trajectory
    assert traj.segment_rapid == (True, False)
    job = Job("sim", machine, "program", traj)
    _r, _l, full = _run(job)
    _r, _l, slow = _run(job, (0.0, "rapid", 25.0))
    rapid_rows = np.flatnonzero(traj.rapid_rows())
    assert len(slow) - len(full) > 2.5 * len(rapid_rows)  # the rapid took ~4x as long
    feed_only = distance_to_polyline(slow, traj.positions).max()
    assert feed_only <= TOL


def test_single_block_stops_at_each_segment_end_and_resume_runs_the_next():
    motion, machine = example_program()
    runner = JobRunner(thesis_job(), pace="virtual", record=True, single_block=True)
    held = []

    def on_event(event):
        if event.kind == "state" and event.status.state == "held":
            held.append((event.message, np.array(event.status.commanded)))
            runner.resume()

    runner.subscribe(on_event)
    runner.run()
    assert runner.state == "done"
    ends = int(motion.segment.max())
    assert [m for m, _ in held] == [f"single block: held at the end of segment {s} ({motion.segment_names[s - 1]})"
                                    for s in range(1, ends + 1)]
    for s, (_m, where) in enumerate(held, start=1):  # at rest exactly where the next segment starts
        np.testing.assert_allclose(where, motion.positions[np.flatnonzero(motion.segment == s)[0]], atol=0.0025)


def test_start_from_a_segment_rebuilds_the_state_and_approaches_safely():
    motion, machine = example_program()
    runner = JobRunner(thesis_job(), pace="virtual", record=True, start_at=3)
    log = runner.run()
    sp = runner.setpoints()
    first = motion.positions[np.flatnonzero(motion.segment == 3)[0]]
    assert runner.state == "done"
    text = " | ".join(runner.assumptions)
    assert "started at segment 4" in text and "spindle" in text and "approach: Z up" in text
    z = machine.names.index("Z")
    reach = int(np.argmin(np.linalg.norm(sp - first, axis=1)))
    across = int(np.flatnonzero(np.linalg.norm(sp[:, :z] - sp[0, :z], axis=1) > 1e-9)[0])
    assert np.all(np.diff(sp[:across + 1, z]) >= -1e-9)  # Z goes up first, X and Y wait ...
    assert sp[across, z] == pytest.approx(max(sp[0, z], first[z]), abs=1e-6)  # ... to the higher of the two
    spindle_on = next(c.t for c in log.changes if c.kind == "spindle_rpm" and c.value > 0)
    assert spindle_on <= reach * machine.period  # the spindle runs before the tool reaches the work
    np.testing.assert_allclose(sp[-1], motion.positions[-1], atol=1e-12)


def test_a_start_segment_the_job_does_not_have_is_refused():
    with pytest.raises(DeviceError, match="segment 99 has no setpoints"):
        JobRunner(thesis_job(), pace="virtual", start_at=98).run()


def test_two_jobs_never_drive_one_device_at_once():
    first = JobRunner(thesis_job(), pace="realtime", speed=1.0)
    first.start()
    try:
        deadline = threading.Event()
        while first.state == "queued" and not deadline.wait(0.01):
            pass
        with pytest.raises(DeviceError, match="busy"):
            JobRunner(thesis_job(), pace="instant").run()
    finally:
        first.estop()
        first.wait(10)
    assert first.state == "aborted"
    JobRunner(thesis_job(), pace="instant").run()  # free again


def test_a_limit_mid_job_faults_stops_every_axis_and_leaves_outputs_safe():
    motion, machine = example_program()
    beyond = motion.positions * np.array([1.0, 1.0, 0.0]) + np.array([0.0, 0.0, 1.0]) * np.linspace(0, 80, len(motion))[:, None]
    traj = Trajectory(beyond, motion.period, motion.segment, signals=motion.signals, segment_names=motion.segment_names)
    job = Job("sim", machine, "program", traj, name="card")  # not pre-flighted on purpose
    runner = JobRunner(job, pace="virtual", record=True)
    with pytest.raises(DeviceError, match="soft limit") as err:
        runner.run()
    log = err.value.log
    assert runner.state == "faulted" and log.outcome == "soft_limit"
    assert not any(log.state["outputs"]) and log.state["spindle_rpm"] == 0
    assert "segment" in str(err.value)


def test_realtime_pace_follows_the_wall_clock_times_the_speed_factor():
    import time

    job = thesis_job()
    runner = JobRunner(job, pace="realtime", speed=8.0)
    ticks = []
    runner.subscribe(lambda e: ticks.append(time.perf_counter()) if e.kind == "tick" else None)
    t0 = time.perf_counter()
    runner.run()
    wall = time.perf_counter() - t0
    assert wall >= job.duration / 8.0 * 0.95
    assert len(ticks) >= 10
