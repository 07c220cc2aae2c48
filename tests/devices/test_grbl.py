"""Streaming to GRBL over serial, against the GRBL protocol simulator on a pseudo-terminal.

The simulator models the protocol (128-byte buffer, ok/error/ALARM, status, hold/resume/reset) but
not motion timing; see flowmc/devices/grbl_sim.py.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from device_programs import thesis_trajectory
from flowmc.devices.backends import open_device
from flowmc.devices.grbl import GrblStreamer, parse_status
from flowmc.devices.grbl_program import ProgramLine, decimate, motion_gcode, text_gcode
from flowmc.errors import DeviceError
from flowmc.motion.trajectory import Signal


def _card(sim, machine):
    return open_device(f"grbl:{sim.port}", machine, timeout=5.0)


def test_the_thesis_pattern_streams_with_character_counting(grbl_sim, machine):
    sim = grbl_sim(line_time=0.002)
    tr = thesis_trajectory()
    program = motion_gcode(tr, machine)
    with _card(sim, machine) as card:
        log = card.run(tr)
        assert log.outcome == "done"
        assert log.state["acknowledged"] == len(program)
        assert sim.received == [line.text for line in program]
        assert not sim.overflowed
        assert 100 < sim.max_rx_fill <= 128  # the buffer was kept full, never overrun
        assert card.position() == pytest.approx([0.0, 0.0, 0.0], abs=1e-3)  # the pattern ends at its start


def test_an_error_at_line_n_stops_there_and_says_so(grbl_sim, machine):
    n = 23
    sim = grbl_sim(error_at={n: 33}, line_time=0.002)
    tr = thesis_trajectory()
    program = motion_gcode(tr, machine)
    with _card(sim, machine) as card:
        with pytest.raises(DeviceError) as err:
            card.run(tr)
        e = err.value
        assert e.line == n
        assert e.where == f"line {n} ({program[n - 1].source})"
        row = int(program[n - 1].source.split()[1])  # "setpoint <row> of segment <k> (row <k>)"
        k = int(tr.segment[row]) + 1
        assert program[n - 1].source == f"setpoint {row} of segment {k} (row {k})"  # as users count segments
        assert "GRBL error:33 (invalid motion target)" in e.message and repr(program[n - 1].text) in e.message
        assert f"{n - 1} lines before it acknowledged" in e.message
        assert e.log.outcome == "error" and e.log.state["acknowledged"] == n - 1
        seen = len(sim.received)
        time.sleep(0.2)
        assert len(sim.received) == seen  # nothing more was sent after the error
        assert seen < n + 12  # at most what was already in the 128-byte buffer
        assert sim.resets == 2  # the connection's reset and the stop
        assert sim.received[n - 1] == program[n - 1].text


def test_an_alarm_stops_the_stream(grbl_sim, machine):
    sim = grbl_sim(travel=((-50.0, 50.0), (-50.0, 50.0), (-10.0, 10.0)))
    big = thesis_trajectory()  # X reaches -75: GRBL's own soft limit raises ALARM:2
    with _card(sim, machine) as card:
        with pytest.raises(DeviceError, match=r"ALARM:2 \(soft limit") as err:
            card.run(big)
        assert err.value.log.outcome == "alarm"
        assert card.status()["state"] == "Alarm"  # a soft-limit alarm survives the reset
        assert card.streamer.command("$X") == "ok"
        assert card.status()["state"] == "Idle"


def test_a_vanished_port_names_the_last_acknowledged_line(grbl_sim, machine):
    sim = grbl_sim(vanish_after=30, line_time=0.002)
    tr = thesis_trajectory()
    program = motion_gcode(tr, machine)
    with _card(sim, machine) as card:
        with pytest.raises(DeviceError, match="serial port vanished") as err:
            card.run(tr)
    assert err.value.where == sim.port
    assert f"last acknowledged: line 30 ({program[29].source}: {program[29].text!r})" in err.value.message


def test_feed_hold_resume_and_status(grbl_sim):
    sim = grbl_sim(line_time=0.05)
    streamer = GrblStreamer(sim.port, timeout=5.0)
    streamer.connect()
    try:
        streamer._write(b"G1 X1 F600\nG1 X2\nG1 X3\nG1 X4\n")
        streamer.feed_hold()
        time.sleep(0.3)
        held = streamer.status()
        assert held["state"] == "Hold:0" and held["MPos"][0] < 4.0
        streamer.resume()
        time.sleep(0.4)
        done = streamer.status()
        assert done["state"] == "Idle" and done["MPos"] == [4.0, 0.0, 0.0]
    finally:
        streamer.close()


def test_gcode_text_is_sent_as_written_and_a_bad_line_is_named(grbl_sim, machine):
    sim = grbl_sim()
    text = "; a test\nG21 G90\n(move)\nG1 X5 Y5 F600\n\nG1 X10 Q3\nG1 X0\n"
    with _card(sim, machine) as card:
        with pytest.raises(DeviceError, match="error:20") as err:
            card.run(text)
    assert err.value.where == "line 3 (program:6)"
    assert [line.source for line in text_gcode(text)] == ["program:2", "program:4", "program:6", "program:7"]


def test_gcode_from_a_trajectory_keeps_its_shape_speed_and_signals(machine):
    tr = thesis_trajectory(feed=20.0)
    sig = Signal([0.0, 3.0], ["spindle_rpm", "dout"], [0, 1], [12000.0, 1.0])
    program = motion_gcode(tr, machine, sig, tolerance=0.01)
    texts = [line.text for line in program]
    assert texts[:4] == ["G21", "G90", "G94", "G0 X0 Y0 Z0"]
    assert texts[4] == "M3 S12000"
    assert "M8" in texts and texts.index("M8") > 5
    moves = [t for t in texts if t.startswith("G1")]
    assert len(moves) < len(tr) / 10  # thinned
    feeds = [float(t.rsplit("F", 1)[1]) for t in moves]
    assert max(feeds) == pytest.approx(20.0 * 60, rel=0.01)  # the cruise speed survives
    kept = decimate(tr.positions, 0.01)
    # every dropped setpoint lies within the tolerance of the polyline through the kept ones
    for i, j in zip(kept[:-1], kept[1:]):
        a, b = tr.positions[i], tr.positions[j]
        inner = tr.positions[i + 1:j]
        if len(inner):
            u = np.clip((inner - a) @ (b - a) / max((b - a) @ (b - a), 1e-12), 0, 1)
            assert np.linalg.norm(inner - (a + np.outer(u, b - a)), axis=1).max() <= 0.01
    with pytest.raises(DeviceError, match="GRBL cannot drive pwm_duty"):
        motion_gcode(tr, machine, Signal([1.0], ["pwm_duty"], [1], [50.0]))


def test_status_report_parsing():
    status = parse_status("<Hold:0|MPos:1.000,-2.500,0.000|Bf:15,120|FS:600,12000|Pn:XZ>")
    assert status == {"state": "Hold:0", "MPos": [1.0, -2.5, 0.0], "Bf": [15.0, 120.0], "FS": [600.0, 12000.0],
                      "Pn": "XZ"}


def test_a_port_that_is_not_there_is_a_clear_error(machine):
    with pytest.raises(DeviceError, match="cannot open serial port") as err:
        open_device("grbl:/dev/does-not-exist", machine)
    assert err.value.where == "/dev/does-not-exist"


def test_a_line_longer_than_the_buffer_is_refused_before_sending(grbl_sim):
    sim = grbl_sim()
    streamer = GrblStreamer(sim.port, timeout=5.0)
    streamer.connect()
    try:
        with pytest.raises(DeviceError, match="128-byte buffer") as err:
            streamer.stream([ProgramLine("G1 X1 F600", "a"), ProgramLine("G1 X" + "1" * 130, "b")])
        assert err.value.where == "line 2 (b)"
        assert sim.received == []
    finally:
        streamer.close()
