"""The simulated card: homing, limit switches, soft limits and the e-stop, in open and closed loop."""

from __future__ import annotations

import numpy as np
import pytest

from device_programs import line_trajectory, thesis_trajectory
from flowmc.devices.sim import AxisSwitches, HomingSettings, SimCard
from flowmc.devices.sim.world import switch_inputs
from flowmc.errors import DeviceError

STEP = 0.0025


@pytest.mark.parametrize("closed_loop", [False, True])
def test_homing_ends_at_zero_with_the_switch_released(machine, closed_loop):
    card = SimCard(machine, closed_loop=closed_loop)
    card.jog("X", 37.3, 40.0)
    card.jog("Y", -12.0, 40.0)  # Y starts on the home cam (closed below world 0)
    assert card.read_inputs()[10] is False and card.read_inputs()[13] is True
    log = card.home(("X", "Y"))
    assert log.outcome == "done"
    assert np.abs(card.position()[:2]).max() < 0.01 * STEP
    assert card.status()["counts"][:2] == [0, 0]
    inputs = card.read_inputs()
    home_x, home_y = switch_inputs(0)[1], switch_inputs(1)[1]
    assert inputs[home_x] is False and inputs[home_y] is False  # released
    # zero sits the back-off distance past the cam's edge (world 0), on its open side
    for axis in (0, 1):
        assert card.world_position(axis) == pytest.approx(1.0, abs=2 * STEP)
    # the log shows the procedure in the new frame: X went below the edge, came back, ends at 0
    x = log.position[:, 0]
    assert x[-1] == pytest.approx(0.0, abs=0.01 * STEP)
    assert x.min() < -1.0 + 2 * STEP
    assert [e.axis for e in log.events_of("home")] == ["X", "Y"]
    # the home switch closed then opened during X's homing
    home_changes = [c.value for c in log.changes_of("din", home_x)]
    assert home_changes[:2] == [1.0, 0.0]


def test_homing_speeds_v1_then_v2(machine):
    card = SimCard(machine, homing=HomingSettings(v1=8.0, v2=1.0, backoff=0.5))
    card.jog("X", 10.0, 40.0)
    log = card.home(("X",))
    v = np.diff(log.position[:, 0]) / machine.period  # whole steps per period: average over each phase
    toward, away = v[:np.flatnonzero(v > 0)[0]], v[np.flatnonzero(v > 0)[0]:]
    assert toward[toward < 0].mean() == pytest.approx(-8.0, rel=0.01)  # toward home at V1
    assert away.mean() == pytest.approx(1.0, rel=0.01)  # off it at V2
    assert (away >= 0).all()
    assert card.world_position(0) == pytest.approx(0.5, abs=2 * STEP)


@pytest.mark.parametrize("closed_loop", [False, True])
def test_midpoint_homing_zeroes_halfway_between_the_limits(closed_loop):
    from flowmc.motion.machine import Axis, Machine

    m = Machine(axes=(Axis(name="X", min=-40, max=40), Axis(name="Y", min=-40, max=40)), period=0.001)
    switches = {"X": AxisSwitches(-30.0, 50.0, 0.0)}  # midpoint at world 10
    card = SimCard(m, closed_loop=closed_loop, switches=switches, homing=HomingSettings(v1=20.0))
    log = card.home(("X",), method="midpoint")
    assert log.outcome == "done"
    assert card.world_position(0) == pytest.approx(10.0, abs=0.01)
    assert abs(card.position()[0]) < 0.01 * STEP
    assert {c.channel for c in log.changes_of("din")} >= {9, 11}  # both limits were touched


def test_homing_refuses_an_axis_whose_switches_are_plain_inputs(machine):
    card = SimCard(machine)
    card.set_axis_io("X", False)
    with pytest.raises(DeviceError, match="plain inputs"):
        card.home(("X",))


@pytest.mark.parametrize("closed_loop", [False, True])
def test_a_limit_hit_mid_move_stops_that_axis_at_the_switch(machine, closed_loop):
    card = SimCard(machine, closed_loop=closed_loop, switches={"X": AxisSwitches(-205.0, 30.0, 0.0)})
    tr = line_trajectory((0, 0, 0), (50, 40, 0))
    log = card.run(tr)
    assert log.outcome == "limit"
    (event,) = log.events_of("limit")
    assert event.axis == "X" and "+limit switch (input 9)" in event.message
    x, y = log.position[:, 0], log.position[:, 1]
    if closed_loop:  # the motor coasts through the loop: a following error past the switch
        assert 30.0 <= x[-1] < 30.0 + 0.1
    else:  # the step that closed the switch is the last one
        assert x.max() == pytest.approx(30.0, abs=1e-9)
        assert x[-1] == pytest.approx(30.0, abs=1e-9)
    stop_row = int(round(event.t / machine.period))
    assert np.all(np.abs(np.diff(x[stop_row + 1:])) < 0.05)  # no further motion of X
    assert y[-1] == pytest.approx(40.0, abs=0.01)  # the other axis carried on
    assert log.changes_of("din", 9)[0].value == 1.0


def test_limit_switches_are_directional_so_an_axis_can_back_off(machine):
    card = SimCard(machine, switches={"X": AxisSwitches(-205.0, 30.0, 0.0)})
    card.run(line_trajectory((0, 0, 0), (40, 0, 0)))
    assert card.position()[0] == pytest.approx(30.0)
    log = card.jog("X", -10.0, 20.0)
    assert log.outcome == "done" and card.position()[0] == pytest.approx(20.0)


def test_axis_io_off_disables_the_limit_stop(machine):
    card = SimCard(machine, switches={"X": AxisSwitches(-205.0, 30.0, 0.0)})
    card.set_axis_io("X", False)
    log = card.run(line_trajectory((0, 0, 0), (40, 0, 0)))
    assert log.outcome == "done" and card.position()[0] == pytest.approx(40.0)


def test_soft_limits_stop_an_unchecked_program(machine):
    card = SimCard(machine)
    log = card.run(line_trajectory((0, 0, 0), (0, 0, 60)), check=False)  # Z soft max is 50
    assert log.outcome == "soft_limit"
    assert log.position[:, 2].max() == pytest.approx(50.0)
    assert "soft limit max 50 mm" in log.events_of("soft_limit")[0].message
    assert log.events_of("soft_limit")[0].message.endswith("(segment 1)")  # the program names no segments


def test_a_soft_limit_event_names_the_segment_as_the_user_knows_it():
    from flowmc.motion.machine import Axis, Machine

    short_x = Machine(axes=(Axis(name="X", min=-60.0, max=60.0), Axis(name="Y"), Axis(name="Z", min=-50, max=50)),
                      period=0.001)
    log = SimCard(short_x).run(thesis_trajectory(), check=False)  # the cw arc, row 4, runs to X = -75
    assert log.outcome == "soft_limit"
    assert log.events_of("soft_limit")[0].message.endswith("(segment 4 (row 4))")


@pytest.mark.parametrize("closed_loop", [False, True])
def test_estop_mid_move_stops_every_axis_within_one_period(machine, closed_loop):
    card = SimCard(machine, closed_loop=closed_loop, estop_input=2)
    tr = line_trajectory((0, 0, 0), (60, -45, 10), feed=80.0)
    t_press = 0.6537
    card.schedule_input(t_press, 2, True)
    log = card.run(tr)
    assert log.outcome == "estop"
    (event,) = log.events_of("estop")
    assert t_press <= event.t < t_press + machine.period
    steps_after = log.steps[log.t > event.t]
    assert not steps_after.any()  # no pulse after the period in which it was seen
    if closed_loop:  # the motors coast to rest through the loop, within their following error
        stopped = log.position[log.t <= event.t][-1]
        assert np.abs(log.position[-1] - stopped).max() < 0.1
    else:
        assert log.t[-1] == pytest.approx(event.t)
    assert np.abs(log.position[-1] - tr.positions[-1]).max() > 10  # it did not finish
    # latched: the card refuses to move until the input opens and it is reset
    with pytest.raises(DeviceError, match="e-stop"):
        card.jog("X", 1.0, 10.0)
    with pytest.raises(DeviceError, match="still closed"):
        card.reset()
    card.schedule_input(card.clock, 2, False)
    card.reset()
    assert card.jog("X", 1.0, 10.0).outcome == "done"


def test_software_estop_latches(machine):
    card = SimCard(machine)
    assert card.estop().outcome == "estop"
    with pytest.raises(DeviceError, match="e-stop"):
        card.run(line_trajectory((0, 0, 0), (1, 0, 0)))
    card.reset()
    assert card.run(line_trajectory((0, 0, 0), (1, 0, 0))).outcome == "done"


def test_a_program_starting_elsewhere_is_approached_first(machine):
    card = SimCard(machine)
    log = card.run(line_trajectory((10, 5, 0), (20, 5, 0)))
    assert log.outcome == "done"
    (approach,) = log.events_of("approach")
    assert "program's start" in approach.message
    assert log.position[0].tolist() == [0.0, 0.0, 0.0] and log.position[-1] == pytest.approx([20, 5, 0])
    v = np.diff(log.position, axis=0) / machine.period
    assert np.abs(v).max() <= machine.axes[0].vmax * 1.001


def test_steps_run_at_their_tick_and_untimed_at_the_fastest_allowed(machine):
    from flowmc.motion.trajectory import Steps

    table = np.array([[1, 0]] * 400 + [[0, 1]] * 400 + [[1, -1]] * 400)
    timed = SimCard(machine).run(Steps(table, STEP, tick=0.0002, axes=("X", "Y")))
    assert timed.duration == pytest.approx(1200 * 0.0002)
    assert timed.end_position[:2] == pytest.approx([2.0, 0.0])
    untimed = SimCard(machine).run(Steps(table, STEP, tick=0.0, axes=("X", "Y")))
    assert untimed.duration == pytest.approx(1200 * STEP / 200.0, abs=machine.period)  # vmax-bound
    assert untimed.end_position[:2] == pytest.approx([2.0, 0.0])


def test_log_state_lets_a_new_card_carry_on(machine):
    first = SimCard(machine)
    first.jog("X", 12.5, 30.0)
    log = first.home(("X",))
    first.jog("Y", 3.0, 30.0)
    then = SimCard(machine, state=first.snapshot().state)
    assert then.position() == pytest.approx(first.position())
    assert then.clock == first.clock and then.world_position(0) == first.world_position(0)
    assert log.state["homed"][0] is True
