"""MotionCard.reset() on the simulated card and GRBL, and the Jog node chained after Home."""

from __future__ import annotations

import numpy as np
import pytest

import flowmc
from device_programs import line_trajectory
from flowmc.devices.backends import open_device
from flowmc.devices.sim import SimCard
from flowmc.errors import DeviceError

# ---------------------------------------------------------------- reset

def test_reset_clears_a_latched_software_estop_on_the_sim_card(machine):
    card = SimCard(machine)
    card.jog("X", 2.0, 10.0)
    card.estop()
    assert card.status()["estop"] is True
    with pytest.raises(DeviceError, match="the card is in e-stop; release the e-stop and call reset"):
        card.jog("X", 1.0, 10.0)
    log = card.reset()
    assert log.outcome == "done" and [e.message for e in log.events_of("reset")] == ["e-stop cleared"]
    assert card.status()["estop"] is False and log.state["estop"] is False
    assert card.jog("X", 1.0, 10.0).end_position[0] == pytest.approx(3.0)


def test_reset_refuses_while_the_estop_input_is_closed_and_clears_once_it_opens(machine):
    card = SimCard(machine, estop_input=3)
    card.schedule_input(0.05, 3, True)
    log = card.run(line_trajectory((0, 0, 0), (20, 0, 0)))
    assert log.outcome == "estop"
    with pytest.raises(DeviceError, match="e-stop input 3 is still closed"):
        card.reset()
    assert card.status()["estop"] is True  # still latched
    card.schedule_input(card.clock, 3, False)
    assert card.reset().events_of("reset")
    assert card.run(line_trajectory(card.position(), (20, 0, 0))).outcome == "done"


def test_grbl_reset_soft_resets_and_unlocks_an_alarm(grbl_sim, machine):  # noqa: F811
    sim = grbl_sim()
    with open_device(f"grbl:{sim.port}", machine, timeout=5.0) as card:
        with pytest.raises(DeviceError, match="ALARM:2"):
            card.run("G1 X500 F600\n")  # beyond the simulator's 200 mm travel
        with pytest.raises(DeviceError, match="error:9"):
            card.run("G1 X1 F600\n")  # locked: GRBL refuses G-code until unlocked
        resets = sim.resets
        log = card.reset()
        assert sim.resets == resets + 1 and sim.received[-1] == "$X"
        assert log.outcome == "done" and log.events_of("reset")
        assert card.run("G1 X1 F600\n").outcome == "done"
        assert card.position() == pytest.approx([1.0, 0.0, 0.0])


# ---------------------------------------------------------------- the Jog node

def _home_jog_graph(distance: float = 12.5, axis: str = "X", **jog_params):
    g = flowmc.GraphBuilder(title="home, jog, draw")
    m = g.add("machine", id="m", period=0.001)
    home = g.add("device.home", id="home", method="switch")
    g.wire(m.machine, home.machine)
    jog = g.add("device.jog", id="jog", axis=axis, distance=distance, speed=20.0, **jog_params)
    g.wire(m.machine, jog.machine)
    g.wire(home.log, jog.after)
    g.output("home_log", "Log", home.log)
    g.output("jog_log", "Log", jog.log)
    return g, m, jog


def test_jog_node_moves_the_axis_by_the_distance_after_home():
    g, _, _ = _home_jog_graph()
    result = flowmc.run(g.build(), start=True)
    assert result.ok, result.errors
    home, jog = result.outputs["home_log"], result.outputs["jog_log"]
    assert home.end_position == pytest.approx([0, 0, 0])
    assert jog.t[0] == pytest.approx(home.t[-1])  # it carried on from the homed card, on the same clock
    np.testing.assert_allclose(jog.position[0], [0, 0, 0])
    np.testing.assert_allclose(jog.end_position, [12.5, 0, 0])
    assert jog.state["homed"] == [True, True, True]
    speed = np.abs(np.diff(jog.position[:, 0])) / jog.period
    assert speed.max() == pytest.approx(20.0, rel=0.02)  # at the jog speed, not the axis's vmax
    assert result.nodes["jog"].status == "done"
    again = flowmc.run(g.build(), start=True)
    assert again.nodes["jog"].status == "done"  # a device node: run again, never cached
    assert again.outputs["jog_log"].digest() == jog.digest()


def test_a_program_after_the_jog_starts_where_the_jog_left_the_table():
    g, m, jog = _home_jog_graph(distance=-7.0, axis="y")
    card = g.add("device.card_output", id="card")
    g.input("program", "Trajectory", card.motion)
    g.wire(m.machine, card.machine)
    g.wire(jog.log, card.after)
    g.output("log", "Log", card.log)
    program = line_trajectory((0, -7, 0), (10, -7, 0))
    result = flowmc.run(g.build(), inputs={"program": program}, start=True)
    assert result.ok, result.errors
    log = result.outputs["log"]
    assert not log.events_of("approach")  # the table was already at the program's start
    np.testing.assert_allclose(log.end_position, [10, -7, 0], atol=1e-9)


def test_jog_node_failures_name_the_axis_or_the_limit():
    g, _, _ = _home_jog_graph(axis="Q")
    result = flowmc.run(g.build(), start=True)
    assert result.nodes["jog"].status == "failed" and "no axis 'Q'" in result.nodes["jog"].error
    g, _, _ = _home_jog_graph(distance=500.0)
    result = flowmc.run(g.build(), start=True)
    assert result.nodes["jog"].status == "failed"
    assert "the jog of X ended with soft_limit" in result.nodes["jog"].error


# ---------------------------------------------------------------- the card node's pen output

def test_card_output_node_drives_the_pen_output_it_is_given():
    from flowmc.motion.contour import Contour, contours_to_path

    square = Contour(np.array([[5, 5], [15, 5], [15, 15], [5, 5]], dtype=float), True)
    path = contours_to_path([square, Contour(square.points + 20.0, True)], feed=10.0)
    g = flowmc.GraphBuilder(title="pen on DO6")
    m = g.add("machine", id="m", period=0.001)
    pbp = g.add("interp.point_by_point", id="pbp", tick_s=0.001)
    g.input("path", "Path", pbp.path)
    g.wire(m.machine, pbp.machine)
    card = g.add("device.card_output", id="card", pen_output=6)
    g.wire(pbp.steps, card.motion)
    g.wire(m.machine, card.machine)
    g.output("log", "Log", card.log)
    g.output("steps", "Steps", pbp.steps)
    result = flowmc.run(g.build(), inputs={"path": path}, start=True)
    assert result.ok, result.errors
    steps, log = result.outputs["steps"], result.outputs["log"]
    rows = np.searchsorted(steps.segment, [1, 4, 5])  # first stroke, the rapid between, second stroke
    assert [(round(c.t, 9), c.value) for c in log.changes_of("dout", 6)] == \
        [(round(r * 0.001, 9), v) for r, v in zip(rows, (1.0, 0.0, 1.0))]
    assert not log.changes_of("dout", 1)
