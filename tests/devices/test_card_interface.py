"""open_device, the backend table, the DeviceLog value, and the simulator as a command."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from device_programs import line_trajectory
from flowmc.devices import backends
from flowmc.devices.backends import DeviceOptions, SimOptions, known_devices, open_device, register_backend
from flowmc.devices.card import MotionCard
from flowmc.devices.log import Change, DeviceLog, Event
from flowmc.devices.ranges import CARD_6050
from flowmc.devices.sim import SimCard
from flowmc.errors import DeviceError


def test_sim_is_the_default_and_unknown_specs_list_the_known_ones(machine):
    card = open_device()
    assert isinstance(card, SimCard) and isinstance(card, MotionCard)
    with pytest.raises(DeviceError, match=r"unknown device 'plc:3'; known: grbl:<serial port>, grbl-sim, linuxcnc, sim"):
        open_device("plc:3", machine)
    with pytest.raises(DeviceError, match="say which serial port"):
        open_device("grbl", machine)
    with pytest.raises(DeviceError, match="'grbl-sim' takes no argument"):
        open_device("grbl-sim:/dev/ttyUSB0", machine)


def test_grbl_sim_streams_through_the_real_serial_code_and_stops_its_simulator(machine):
    with open_device("grbl-sim", machine) as card:
        simulator = card.simulator
        log = card.run("G21 G90\nG1 X10 Y5 F600\nG0 X0 Y5\n")
        assert log.device == "grbl-sim" and log.outcome == "done"
        assert simulator.received == ["G21 G90", "G1 X10 Y5 F600", "G0 X0 Y5"]
        assert simulator.mpos[:2] == [0.0, 5.0]
    assert simulator._thread is not None and not simulator._thread.is_alive()


def test_backends_are_imported_only_when_opened(machine, monkeypatch):
    code = ("import sys, flowmc.devices.backends as b; b.check_spec('linuxcnc'); b.known_devices(); "
            "print(sorted(m for m in sys.modules if m.startswith(('flowmc.devices.linuxcnc', 'flowmc.devices.grbl', "
            "'flowmc.devices.sim', 'serial'))))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0 and proc.stdout.strip() == "[]", proc.stderr
    assert "linuxcnc" in known_devices()
    monkeypatch.setitem(sys.modules, "flowmc.devices.linuxcnc.card", None)
    with pytest.raises(DeviceError, match=r"the linuxcnc backend is not installed \(flowmc.devices.linuxcnc.card"):
        open_device("linuxcnc", machine)


def test_a_registered_backend_gets_its_argument_and_options(machine, monkeypatch):
    monkeypatch.setattr(backends, "_BACKENDS", dict(backends._BACKENDS))
    monkeypatch.setattr(backends, "_SPEC_HELP", dict(backends._SPEC_HELP))
    seen = {}

    def factory(argument, m, options, **kwargs):
        seen.update(argument=argument, machine=m, options=options, kwargs=kwargs)
        return SimCard(m)

    register_backend("bench", factory, "bench:<slot>")
    wanted = DeviceOptions(sim=SimOptions(closed_loop=True))
    card = open_device("bench:2", machine, wanted, speed=3)
    assert isinstance(card, SimCard)
    assert seen == {"argument": "2", "machine": machine, "options": wanted, "kwargs": {"speed": 3}}
    assert "bench:<slot>" in known_devices()


def test_typed_options_reach_the_card_they_belong_to(machine):
    log = SimCard(machine).home()
    options = DeviceOptions(sim=SimOptions(closed_loop=True, estop_input=3, analog="pwm", pen_output=4),
                            resume=log.state)
    with open_device("sim", machine, options) as card:
        assert card.loop is not None and card.estop_input == 3 and card.ranges == CARD_6050.with_analog("pwm")
        assert all(log.state["homed"]) and card.state()["homed"] == log.state["homed"]
    with open_device("sim", machine, DeviceOptions(resume={**log.state, "device": "grbl-sim"})) as card:
        assert not any(card.state()["homed"])  # a state from another kind of card is not taken
    assert DeviceOptions(resume={"device": "grbl-sim"}).resume_for("sim") is None


def test_device_log_digest_and_summary(machine):
    log = SimCard(machine).run(line_trajectory((0, 0, 0), (5, 2, 0)))
    again = SimCard(machine).run(line_trajectory((0, 0, 0), (5, 2, 0)))
    other = SimCard(machine).run(line_trajectory((0, 0, 0), (5, 2.0025, 0)))
    assert log.digest() == again.digest() != other.digest()
    summary = log.summary()
    assert json.loads(json.dumps(summary)) == summary
    assert summary["steps_per_axis"] == [2000, 800, 0] and summary["outcome"] == "done"
    assert log.position.flags.writeable is False
    assert log.steps[0].tolist() == [0, 0, 0] and np.abs(log.steps).sum() == 2800


def test_device_log_refuses_unknown_kinds():
    with pytest.raises(ValueError, match="unknown outcome"):
        DeviceLog("sim", ("X",), 0.001, [0.0], [[0]], [[0.0]], outcome="fine")
    with pytest.raises(ValueError, match="unknown change kind"):
        DeviceLog("sim", ("X",), 0.001, [0.0], [[0]], [[0.0]], changes=[Change(0.0, "relay", 1, 1.0)])
    log = DeviceLog("sim", ("X",), 0.001, [0.0], [[0]], [[0.0]], events=[Event("note", 0.0, "", "hello")])
    assert log.events_of("note")[0].message == "hello"


def test_the_grbl_simulator_runs_as_a_command_and_stops_by_itself():
    proc = subprocess.Popen([sys.executable, "-m", "flowmc.devices.grbl_sim", "--idle-timeout", "1.5"],
                            stdout=subprocess.PIPE, text=True)
    try:
        port = proc.stdout.readline().strip()
        assert port.startswith("/dev/pts/")
        fd = os.open(port, os.O_RDWR | os.O_NOCTTY)
        try:
            assert b"Grbl 1.1h" in os.read(fd, 100)
        finally:
            os.close(fd)
        assert proc.wait(timeout=20) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
