"""Digital I/O, the shared PWM/DA terminal and the spindle on the simulated card."""

from __future__ import annotations

import numpy as np
import pytest

from device_programs import line_trajectory
from flowmc.devices.preflight import preflight
from flowmc.devices.ranges import CARD_6050, da_output, pwm_output
from flowmc.devices.sim import SimCard
from flowmc.errors import DeviceError, LimitError
from flowmc.motion.trajectory import Signal


@pytest.mark.parametrize("freq", [17.9, 10.0, 150_000.5, 200_000.0])
def test_pwm_outside_18_to_150000_hz_is_refused(machine, freq):
    card = SimCard(machine, analog="pwm")
    with pytest.raises(LimitError, match="outside 18-150,000 Hz"):
        card.set_pwm(freq, 50.0)
    assert card.status()["pwm_hz_duty"] == [0.0, 0.0]  # nothing changed
    tr = line_trajectory((0, 0, 0), (5, 0, 0))
    with pytest.raises(LimitError, match="PWM frequency") as err:
        preflight(tr, machine, Signal([0.1], ["pwm_freq"], [1], [freq]), ranges=CARD_6050.with_analog("pwm"))
    assert err.value.where == "segment 1"  # the one segment, counted from 1 (the program names none)


@pytest.mark.parametrize("freq", [18.0, 1000.0, 150_000.0])
def test_pwm_at_the_range_ends_is_produced_by_the_counters(machine, freq):
    card = SimCard(machine, analog="pwm")
    log = card.set_pwm(freq, 37.5)
    f, d = card.status()["pwm_hz_duty"]
    assert f == pytest.approx(freq, rel=1e-4) and d == pytest.approx(37.5, abs=0.1)
    assert [c.kind for c in log.changes] == ["pwm_freq", "pwm_duty"]


def test_pwm_counter_arithmetic():
    # 150 MHz / (prescale * count); the lowest frequency needs the full 1:128 prescaler
    f, d = pwm_output(18.0, 50.0)
    assert 150e6 / (128 * 65536) < f < 18.001 and d == 50.0
    f, d = pwm_output(149_000.0, 33.0)  # 150 MHz / 1007: duty in steps of 1/1007
    assert f == pytest.approx(150e6 / 1007) and d == pytest.approx(100 * 332 / 1007)


def test_da_is_12_bit_over_plus_minus_10_v(machine):
    assert da_output(0.0) == 0.0
    assert da_output(10.0) == pytest.approx(10.0 - 20.0 / 4096)
    assert da_output(-10.0) == -10.0
    levels = {da_output(v) for v in np.linspace(-10, 10, 20001)}
    assert len(levels) == 4096
    card = SimCard(machine)
    card.set_da(3.3)
    assert card.status()["da_v"] == pytest.approx(3.3, abs=20 / 4096 / 2)
    with pytest.raises(LimitError, match="outside -10..10 V"):
        card.set_da(10.5)


def test_shared_terminal_gives_pwm_or_da_not_both(machine):
    with pytest.raises(LimitError, match="set to DA"):
        SimCard(machine, analog="da").set_pwm(1000.0, 10.0)
    with pytest.raises(LimitError, match="set to PWM"):
        SimCard(machine, analog="pwm").set_spindle(1000.0)


def test_spindle_speed_through_the_da_with_run_and_direction_outputs(machine):
    card = SimCard(machine)
    log = card.set_spindle(12_000.0)
    assert card.status()["da_v"] == pytest.approx(5.0, abs=0.005)
    assert card.status()["outputs"] == [1]  # run on, clockwise
    assert {(c.kind, c.channel) for c in log.changes} == {("da", 1), ("dout", 1), ("spindle_rpm", 1)}
    card.set_spindle(-24_000.0)
    assert card.status()["spindle_rpm"] == pytest.approx(-24_000.0, rel=1e-3)
    assert card.status()["outputs"] == [1, 2]  # run and counter-clockwise
    card.set_spindle(0.0)
    assert card.status()["outputs"] == [] and card.status()["da_v"] == 0.0
    with pytest.raises(LimitError, match="beyond 24,000 rpm"):
        card.set_spindle(30_000.0)


def test_digital_outputs_and_program_signals_at_their_times(machine):
    card = SimCard(machine)
    with pytest.raises(LimitError, match="output 9 does not exist"):
        card.set_output(9, True)
    tr = line_trajectory((0, 0, 0), (20, 0, 0))
    pen = Signal([0.0, 0.2504, tr.duration], ["dout", "dout", "dout"], [3, 3, 3], [1, 0, 1])
    log = card.run(tr, pen)
    changes = log.changes_of("dout", 3)
    assert [c.value for c in changes] == [1.0, 0.0, 1.0]
    assert [c.t for c in changes] == pytest.approx([0.0, 0.251, tr.duration])  # the next period boundary


def test_inputs_map_switches_to_9_20_and_plain_inputs(machine):
    card = SimCard(machine)
    levels = card.read_inputs()
    assert sorted(levels) == list(range(1, 21))
    assert levels[10] and levels[13] and levels[16]  # every axis starts on its home cam
    assert not any(levels[ch] for ch in (9, 11, 12, 14, 15, 17))
    card.schedule_input(0.0, 5, True)
    assert card.read_inputs()[5] is True
    with pytest.raises(DeviceError, match="axis X's switch"):
        card.schedule_input(1.0, 9, True)
    card.set_axis_io("X", False)
    card.schedule_input(1.0, 9, True)
    card.jog("Y", 60.0, 50.0)
    assert card.read_inputs()[9] is True and card.read_inputs()[13] is False
    assert 18 in levels and levels[18] is False  # the 4th card axis is unused: plain inputs
