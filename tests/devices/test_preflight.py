"""Pre-flight: nothing is sent when a program would break a limit, and the error says where."""

from __future__ import annotations

import numpy as np
import pytest

from device_programs import line_trajectory, thesis_trajectory
from flowmc.devices.preflight import preflight
from flowmc.devices.ranges import CARD_6050
from flowmc.devices.sim import SimCard
from flowmc.errors import DeviceError, LimitError
from flowmc.motion.machine import Axis, Machine
from flowmc.motion.trajectory import Signal, Steps, Trajectory


def _pattern_over_soft_limit():
    """The thesis pattern on a machine whose X travel stops at -60 mm: the cw arc (row 4) runs to X = -75."""
    machine = Machine(axes=(Axis(name="X", min=-60.0, max=60.0), Axis(name="Y"), Axis(name="Z", min=-50, max=50)),
                      period=0.001)
    return thesis_trajectory(), machine


def test_a_program_crossing_a_soft_limit_is_refused_naming_segment_time_axis_value():
    tr, machine = _pattern_over_soft_limit()
    with pytest.raises(LimitError) as err:
        preflight(tr, machine)
    e = err.value
    rows = np.flatnonzero(tr.positions[:, 0] < -60.0)
    first = rows[0]
    assert tr.segment[first] == 3  # index 3: the fourth segment, the table's row 4
    assert e.where == "segment 4 (row 4)"
    assert e.details["segment"] == 4 and e.details["source"] == "row 4"
    assert e.details["t"] == pytest.approx(first * tr.period)
    assert e.details["axis"] == "X" and e.details["value"] == pytest.approx(tr.positions[first, 0])
    assert str(e).startswith("segment 4 (row 4): X = -60.00")
    assert "beyond soft limit min -60 mm at t=" in str(e)


def test_nothing_is_sent_when_preflight_refuses():
    tr, machine = _pattern_over_soft_limit()
    card = SimCard(machine)
    before = card.snapshot()
    with pytest.raises(LimitError):
        card.run(tr)
    after = card.snapshot()
    assert after.digest() == before.digest()  # no motion, no clock, no output change
    assert card.clock == 0.0


def test_velocity_acceleration_and_step_rate_are_checked():
    m = Machine(axes=(Axis(name="X", vmax=100.0, amax=500.0, max_step_rate=30_000.0),), period=0.001)
    t = np.arange(200) * 0.001
    fast = Trajectory(np.column_stack([150.0 * t]), 0.001, segment=np.repeat([0, 1], 100), axes=("X",))
    with pytest.raises(LimitError, match=r"X velocity 150 mm/s over the limit 100 mm/s") as err:
        preflight(fast, m)
    assert err.value.where == "segment 1" and err.value.details["segment"] == 1  # no names: the number alone
    assert err.value.details["source"] == ""
    m2 = Machine(axes=(Axis(name="X", vmax=300.0, amax=500.0, max_step_rate=30_000.0),), period=0.001)
    with pytest.raises(LimitError, match=r"X step rate 60,000 Hz over the limit 30,000 Hz"):
        preflight(fast, m2)
    jerk = Trajectory(np.column_stack([np.where(t > 0.1, 20.0 * (t - 0.1), 0.0)]), 0.001,
                      segment=np.repeat([0, 1], 100), axes=("X",))
    with pytest.raises(LimitError, match=r"X acceleration .* over the limit 500 mm/s\^2") as err:
        preflight(jerk, m2)
    assert err.value.where == "segment 2" and err.value.details["t"] == pytest.approx(0.101, abs=0.0015)


def test_acceleration_gets_one_percent_slack():
    m = Machine(axes=(Axis(name="X", amax=100.0),), period=0.001)
    t = np.arange(100) * 0.001
    ok = Trajectory(np.column_stack([0.5 * 100.9 * t ** 2]), 0.001, axes=("X",))
    assert preflight(ok, m).peak_accel[0] == pytest.approx(100.9)
    over = Trajectory(np.column_stack([0.5 * 101.2 * t ** 2]), 0.001, axes=("X",))
    with pytest.raises(LimitError, match="acceleration"):
        preflight(over, m)


def test_the_earliest_violation_wins():
    m = Machine(axes=(Axis(name="X", min=-5, max=5), Axis(name="Y", vmax=10.0)), period=0.001)
    t = np.arange(1000) * 0.001
    pos = np.column_stack([10 * t, 20 * t])  # Y too fast from the start, X over its limit at t > 0.5
    with pytest.raises(LimitError, match="Y velocity"):
        preflight(Trajectory(pos, 0.001, axes=("X", "Y")), m)


def test_signal_ranges_and_channels(machine):
    tr = line_trajectory((0, 0, 0), (10, 0, 0))
    cases = [
        (Signal([0.05], ["dout"], [9], [1]), "digital output 9 does not exist"),
        (Signal([0.05], ["da"], [1], [12.0]), "DA 12 V outside -10..10 V"),
        (Signal([0.05], ["spindle_rpm"], [0], [-25_000]), "spindle -25,000 rpm beyond 24,000 rpm"),
        (Signal([0.05], ["pwm_duty"], [1], [50]), "set to DA; set it to PWM"),
    ]
    for sig, text in cases:
        with pytest.raises(LimitError, match=text):
            preflight(tr, machine, sig)
    with pytest.raises(LimitError, match="PWM duty 120 % outside 0-100 %"):
        preflight(tr, machine, Signal([0.05], ["pwm_duty"], [1], [120]), ranges=CARD_6050.with_analog("pwm"))
    report = preflight(tr, machine, Signal([0.05], ["spindle_rpm"], [0], [12_000]))
    assert report.signal_events == 1


def test_steps_are_checked_for_travel_and_pulse_rate():
    m = Machine(axes=(Axis(name="X", min=-1, max=1, max_step_rate=20_000.0), Axis(name="Y")), period=0.001)
    far = Steps(np.ones((500, 2), dtype=np.int8), 0.0025, tick=0.0001, segment=np.repeat([0, 1], 250),
                axes=("X", "Y"))
    slow = Machine(axes=(Axis(name="X", max_step_rate=5_000.0), Axis(name="Y")), period=0.001)
    with pytest.raises(LimitError, match="X step rate 10,000 Hz over the limit 5,000 Hz"):
        preflight(far, slow)
    with pytest.raises(LimitError, match=r"X = 1.0025 mm beyond soft limit max 1 mm") as err:
        preflight(far, m)
    assert err.value.where == "segment 2"
    with pytest.raises(DeviceError, match="pulse equivalent"):
        preflight(Steps(np.ones((5, 2), dtype=np.int8), 0.01, tick=0.001, axes=("X", "Y")), m)


def test_unknown_axis_is_a_device_error(machine):
    tr = Trajectory(np.zeros((3, 1)), 0.001, axes=("B",))
    with pytest.raises(DeviceError, match="axis B is not on the machine"):
        preflight(tr, machine)
