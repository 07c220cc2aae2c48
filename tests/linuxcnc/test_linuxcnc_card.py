"""The LinuxCNC machine behind the motion-card interface: open_device("linuxcnc"), state carried across operations."""

import numpy as np
import pytest

from flowmc.devices.backends import open_device
from flowmc.devices.linuxcnc.card import trajectory_gcode
from flowmc.errors import DeviceError
from flowmc.motion.path import Line, Path
from flowmc.motion.trajectory import Signal, Trajectory
from linuxcnc_programs import live_linuxcnc_processes, machine

pytestmark = pytest.mark.linuxcnc


def test_setpoints_become_a_g1_polyline_with_chord_feeds_dwells_and_synced_outputs():
    pos = np.array([[0, 0, 0], [1, 0, 0], [1, 0, 0], [1, 0, 0], [1, 2, 0]], dtype=float)
    sig = Signal([0.01, 0.02], ["dout", "spindle_rpm"], [3, 1], [1.0, -500.0])
    text = trajectory_gcode(pos, ("X", "Y", "Z"), 0.01, sig, tolerance=0.002)
    assert text.splitlines() == [
        "%", "G21 G90 G17 G94", "G64 P0.002", "G0 X0 Y0 Z0",
        "M62 P2", "G1 X1 Y0 Z0 F6000",    # 1 mm in 10 ms = 100 mm/s
        "S500 M4", "G4 P0.02", "G1 X1 Y2 Z0 F12000", "%",
    ]
    with pytest.raises(DeviceError, match="no pwm_duty output"):
        trajectory_gcode(pos, ("X", "Y", "Z"), 0.01, Signal([0.0], ["pwm_duty"], [1], [50.0]))
    with pytest.raises(DeviceError, match="digital output 5"):
        trajectory_gcode(pos, ("X", "Y", "Z"), 0.01, Signal([0.0], ["dout"], [5], [1.0]))


def test_the_card_runs_programs_and_keeps_position_outputs_and_spindle_between_operations():
    with open_device("linuxcnc", machine()) as card:
        assert card.spec == "linuxcnc" and card.position().tolist() == [0.0, 0.0, 0.0]
        log = card.set_output(2, True)
        assert [(c.kind, c.channel, c.value) for c in log.changes] == [("dout", 2, 1.0)]
        card.set_spindle(-1200.0)
        log = card.jog("X", 10.0, 50.0)
        np.testing.assert_allclose(log.end_position, [10, 0, 0])
        assert log.changes == ()  # output 2 and the spindle stay as they were
        assert log.period == 0.001 and abs(log.steps.sum(axis=0)[0] - round(10 / machine().axes[0].step_mm)) <= 1
        # a trajectory from here: 20 mm along Y in 1 s at T = 4 ms, output 1 on half way
        s = np.linspace(0.0, 1.0, 251)[:, None]
        traj = Trajectory(np.array([10.0, 0, 0]) + s * [0, 20.0, 0], 0.004,
                          signals=Signal([0.5], ["dout"], [1], [1.0]))
        log = card.run(traj, check=False)
        np.testing.assert_allclose(log.end_position, [10, 20, 0])
        on = [c for c in log.changes if c.kind == "dout"]
        assert [(c.channel, c.value) for c in on] == [(1, 1.0)]
        y_at = log.position[int(round(on[0].t / log.period)), 1]
        assert 9.0 < y_at < 11.0  # switched with the motion, about half way
        assert card.status()["outputs"] == [1, 2] and card.status()["spindle_rpm"] == -1200.0
        log = card.run_path(Path([Line([10, 20, 0], [0, 0, 0], feed=100.0)]), tolerance=0.05)
        np.testing.assert_allclose(card.position(), [0, 0, 0])
        assert log.state["spindle_rpm"] == -1200.0
        with pytest.raises(DeviceError, match="no PWM"):
            card.set_pwm(1000.0, 50.0)
        assert card.estop().outcome == "estop" and card.status()["outputs"] == []
    assert live_linuxcnc_processes() == []


def test_a_machine_axis_linuxcnc_does_not_have_is_refused():
    from flowmc.motion.machine import Axis, Machine

    with pytest.raises(DeviceError, match="not A"):
        open_device("linuxcnc", Machine(axes=(Axis(name="X"), Axis(name="A"))))
    with pytest.raises(DeviceError, match="takes no argument"):
        open_device("linuxcnc:fast", machine())


def test_a_path_with_pauses_tool_changes_and_indexing_runs_straight_through_on_the_card():
    from flowmc.devices.linuxcnc.card import LinuxCNCCard
    from flowmc.motion.path import Dwell, PathEvent

    events = [PathEvent("pause", "check"), PathEvent("tool_change", "T2", 2), PathEvent("index", axes=(("B", 45.0),))]
    segs = []
    for k, event in enumerate(events):
        segs += [Line([k, 0, 0], [k + 1, 0, 0], feed=50.0), Dwell([k + 1, 0, 0], 0.0, event)]
    card = LinuxCNCCard(machine(), timeout=60.0)  # an M0 would wait here for a resume until the timeout
    log = card.run_path(Path(segs))
    np.testing.assert_allclose(log.end_position, [3, 0, 0], atol=1e-6)
    assert live_linuxcnc_processes() == []
