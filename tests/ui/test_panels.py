"""Front panel and device panel, driven through their viser handles (no browser)."""

from __future__ import annotations

import time
from typing import Literal

import numpy as np
import pytest
import viser
from pydantic import BaseModel, ConfigDict, Field

import flowmc
from flowmc.devices.grbl_sim import GrblSimulator
from flowmc.devices.session import DeviceSession
from flowmc.errors import PlanningError
from flowmc.motion.machine import Machine
from flowmc.plugins import default_registry
from flowmc.registry import In, NodeType, Out
from flowmc.ui.device_panel import DevicePanel
from flowmc.ui.front_panel import FrontPanel, control_specs
from flowmc.ui.session import EditorSession
from flowmc.ui.text import unescape_md
from flowmc.ui.view3d import ToolpathView


@pytest.fixture
def server():
    srv = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    yield srv
    srv.stop()


# ---------------------------------------------------------------- front panel
class KnobParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    gain: float = Field(1.0, ge=0, le=10, description="Gain")
    count: int = Field(2, ge=1, le=5, description="How many")
    rate: float = Field(3.0, gt=0, description="Rate")
    mode: Literal["fast", "fine", "off"] = "fine"
    on: bool = True
    label: str = "a"
    limit: float | None = Field(None, gt=0, description="Optional limit (empty: none)")


class Knobs(NodeType):
    type_id = "test.knobs"
    title = "Knobs"
    category = "Test"
    description = "Params of every kind, for the front panel."
    Params = KnobParams
    inputs = (In("path", "Path", default=None, doc="Unused path"),)
    outputs = (Out("value", "Number", doc="gain * count"),)

    def run(self, ctx, params, path=None):
        return {"value": params.gain * params.count}


@pytest.fixture
def registry():
    reg = default_registry().copy()
    reg.add(Knobs)
    return reg


@pytest.fixture
def knob_graph():
    g = flowmc.GraphBuilder(title="knobs")
    k = g.add("test.knobs", id="k", gain=2.0)
    for name, kind in (("gain", "Number"), ("count", "Number"), ("rate", "Number"), ("mode", "Text"),
                       ("on", "Bool"), ("label", "Text"), ("limit", "Number"), ("path", "Path")):
        g.input(name, kind, k[name])
    g.output("value", "Number", k.value)
    return g.build()


def test_controls_follow_the_param_schema(server, knob_graph, registry):
    specs = {s.name: s for s in control_specs(knob_graph, registry)}
    assert {n: s.kind for n, s in specs.items()} == {"gain": "slider", "count": "slider", "rate": "number",
                                                     "mode": "dropdown", "on": "checkbox", "label": "text",
                                                     "limit": "number", "path": "note"}
    panel = FrontPanel(server.gui, knob_graph, lambda values: None, registry)
    gain, count = panel.controls["gain"], panel.controls["count"]
    assert (gain.min, gain.max, gain.value) == (0.0, 10.0, 2.0)  # the node's stored value, not the default
    assert (count.min, count.max, count.step, count.value) == (1, 5, 1, 2)
    assert panel.controls["mode"].options == ("fast", "fine", "off")
    assert panel.values() == {"gain": 2.0, "count": 2, "rate": 3.0, "mode": "fine", "on": True, "label": "a"}
    assert "limit" not in panel.values()  # left empty in the graph: not sent until set
    panel.controls["limit"].value = 4.0
    assert panel.values()["limit"] == 4.0


def test_a_change_calls_back_with_every_value(server, knob_graph, registry):
    seen = []
    panel = FrontPanel(server.gui, knob_graph, seen.append, registry)
    panel.controls["gain"].value = 7.5
    panel.controls["mode"].value = "fast"
    panel.controls["on"].value = False
    assert seen[-1] == {"gain": 7.5, "count": 2, "rate": 3.0, "mode": "fast", "on": False, "label": "a"}
    assert len(seen) == 3
    result = flowmc.Runtime(registry).run(knob_graph, inputs=seen[-1])
    assert result.outputs["value"] == 15.0


def test_a_value_out_of_range_is_shown_at_its_field_and_not_run(server, knob_graph, registry):
    seen = []
    panel = FrontPanel(server.gui, knob_graph, seen.append, registry)
    panel.controls["rate"].value = 0.0
    assert seen == []
    assert panel.messages["rate"].visible and "must be > 0" in unescape_md(panel.messages["rate"].content)
    panel.controls["rate"].value = 0.5
    assert not panel.messages["rate"].visible and seen[-1]["rate"] == 0.5


def test_a_failed_run_is_shown_in_the_panel(server, knob_graph, registry):
    def fail(values):
        raise PlanningError("feed too high for this arc", where="plan")

    panel = FrontPanel(server.gui, knob_graph, fail, registry)
    panel.controls["gain"].value = 3.0
    assert unescape_md(panel.status.content) == "**Run failed:** plan: feed too high for this arc"


def planning_graph() -> flowmc.Graph:
    g = flowmc.GraphBuilder(title="front panel")
    pts = g.add("path.polyline", id="pts", points=[(0, 0, 0), (40, 0, 0), (40, 30, 0)], feed=40.0)
    shift = g.add("path.translate", id="shift")
    plan = g.add("interp.time_division", id="plan", profile="trapezoid")
    g.wire(pts.path, shift.path)
    g.wire(shift.path, plan.path)
    g.input("offset", "Number", shift.dx, default=0.0)
    g.input("profile", "Text", plan.profile)
    g.output("trajectory", "Trajectory", plan.trajectory)
    return g.build()


def test_a_change_reruns_only_the_affected_nodes_through_the_session_and_refreshes_the_view(server):
    session, view = EditorSession(planning_graph()), ToolpathView()
    results = []
    session.on_result(lambda request: (results.append(request.result), view.show_result(request.result, request.plan.graph)))
    try:
        panel = FrontPanel(server.gui, session.state.graph, lambda values: session.run(values, source="front panel"),
                          session.runtime.registry)
        session.inputs_provider = panel.values
        session.run()
        assert session.wait().executed == ["pts", "shift", "plan"]

        panel.controls["profile"].value = "scurve"
        assert session.wait().executed == ["plan"] and results[-1].cached == ["pts", "shift"]
        panel.controls["offset"].value = 12.5
        assert session.wait().executed == ["shift", "plan"] and results[-1].cached == ["pts"]

        traj = results[-1].output("plan", "trajectory")
        np.testing.assert_allclose(view.nodes["/path/0"].points[0, 0], [12.5, 0.0, 0.0])
        np.testing.assert_allclose(view.nodes["/trajectory/0"].points[:, 0], traj.positions[:-1], atol=1e-4)
        assert view.time_slider.max == pytest.approx(traj.duration)
    finally:
        view.close()
        session.close()


def test_changes_during_a_run_wait_and_only_the_latest_runs(server):
    """One run at a time: requests made while one runs wait, and a newer one replaces a waiting one."""
    session = EditorSession(planning_graph())
    try:
        first = session.run({"offset": 1.0})
        assert first.started.wait(10)
        waiting = [session.run({"offset": float(k)}, source="front panel") for k in range(2, 6)]
        session.wait()
        assert first.result is not None
        assert [r.superseded for r in waiting[:-1]] == [True] * 3 and waiting[-1].result is not None
        np.testing.assert_allclose(waiting[-1].result.output("shift", "path").start, [5.0, 0.0, 0.0])
    finally:
        session.close()


# ---------------------------------------------------------------- device panel
@pytest.fixture
def device(server):
    logs = []
    panel = DevicePanel(server.gui, DeviceSession(), Machine, refresh_s=0.05, on_log=logs.append)
    panel.connect_button.value = True
    assert panel.card is not None, unescape_md(panel.connection_msg.content)
    panel.logs = logs
    yield panel
    panel.close()


def test_connect_to_the_simulated_card(device):
    assert "Connected to **sim**" in unescape_md(device.connection_msg.content)
    assert set(device.jog) == {"X", "Y", "Z"}
    assert "**X** 0.0000" in unescape_md(device.status.content)
    assert device.disconnect_button.disabled is False and device.connect_button.disabled is True


def test_jog_moves_the_simulated_card_by_the_step(device):
    device.step.value = 2.5
    device.jog["X"].value = "+"
    device.jog["Y"].value = "-"
    device.jog["Y"].value = "-"
    np.testing.assert_allclose(device.card.position(), [2.5, -5.0, 0.0])
    assert "**X** 2.5000 · **Y** -5.0000" in unescape_md(device.status.content)
    assert unescape_md(device.motion_msg.content).startswith("Jog Y-2.5 mm: done")
    assert len(device.logs) == 3 and device.logs[0].end_position[0] == pytest.approx(2.5)


def test_estop_latches_and_refuses_further_jogs(device):
    device.estop_button.value = True
    assert "LATCHED" in unescape_md(device.status.content)
    device.jog["X"].value = "+"
    assert "failed" in unescape_md(device.motion_msg.content) and "e-stop" in unescape_md(device.motion_msg.content)
    np.testing.assert_allclose(device.card.position(), [0.0, 0.0, 0.0])
    device.disconnect_button.value = True
    device.connect_button.value = True  # a fresh connection clears it
    assert "clear" in unescape_md(device.status.content)


def test_reset_clears_the_estop_without_reconnecting(device):
    assert device.reset_button.disabled  # nothing to reset yet
    device.step.value = 2.0
    device.jog["X"].value = "+"
    device.estop_button.value = True
    assert "press Reset" in unescape_md(device.motion_msg.content) and not device.reset_button.disabled
    card = device.card
    device.reset_button.value = True
    assert unescape_md(device.motion_msg.content).startswith("Reset: done (e-stop cleared)")
    assert "E-stop: clear" in unescape_md(device.status.content) and device.reset_button.disabled
    assert device.card is card  # the same connection: the card kept its position
    device.jog["X"].value = "+"
    assert unescape_md(device.motion_msg.content).startswith("Jog X+2 mm: done")
    np.testing.assert_allclose(device.card.position(), [4.0, 0.0, 0.0])


def test_reset_that_the_device_refuses_is_shown_and_stays_offered(server):
    panel = DevicePanel(server.gui, DeviceSession(), Machine, refresh_s=0.05, device_options={"sim": {"estop_input": 2}})
    try:
        panel.connect_button.value = True
        with panel._lock:  # the panel's status poller uses the card too
            panel.card.schedule_input(0.0, 2, True)  # the e-stop button on input 2 is pressed
        panel.estop_button.value = True
        panel.reset_button.value = True
        assert "**Reset failed:** sim card: e-stop input 2 is still closed" in unescape_md(panel.motion_msg.content)
        assert not panel.reset_button.disabled and "LATCHED" in unescape_md(panel.status.content)
        with panel._lock:
            panel.card.schedule_input(panel.card.clock, 2, False)  # released
        panel.reset_button.value = True
        assert unescape_md(panel.motion_msg.content).startswith("Reset: done") and panel.reset_button.disabled
    finally:
        panel.close()


def test_output_toggle_shows_in_the_status(device):
    device.outputs[2].value = True
    assert device.card.status()["outputs"] == [3]
    assert "Outputs on: DO3" in unescape_md(device.status.content)
    device.outputs[2].value = False
    assert "Outputs on: none" in unescape_md(device.status.content)


def test_pwm_out_of_range_gives_a_message_at_the_field(device):
    device.pwm_freq.value = 5.0
    device.pwm_button.value = True
    assert unescape_md(device.pwm_msg.content) == "**PWM 5 Hz 50 % failed:** sim card: PWM frequency 5 Hz outside 18-150,000 Hz"
    device.pwm_freq.value, device.pwm_duty.value = 2000.0, 120.0
    device.pwm_button.value = True
    assert "PWM duty 120 % outside 0-100 %" in unescape_md(device.pwm_msg.content)
    device.pwm_duty.value = 25.0
    device.pwm_button.value = True
    assert unescape_md(device.pwm_msg.content).startswith("PWM 2000 Hz 25 %: done")
    assert "PWM: 2000 Hz, 25 %" in unescape_md(device.status.content)


def test_home_all_zeroes_every_axis(device):
    device.step.value = 3.0
    device.jog["Z"].value = "+"
    device.home_button.value = True
    assert unescape_md(device.motion_msg.content).startswith("Home all: done")
    np.testing.assert_allclose(device.card.position(), [0.0, 0.0, 0.0])
    assert "homed: X, Y, Z" in unescape_md(device.status.content)


def test_status_refreshes_by_itself(device):
    device.card.jog("X", 1.0, 10.0)  # moved behind the panel's back
    deadline = time.monotonic() + 5.0
    while "**X** 1.0000" not in unescape_md(device.status.content) and time.monotonic() < deadline:
        time.sleep(0.02)
    assert "**X** 1.0000" in unescape_md(device.status.content)


def test_unknown_device_is_reported_at_the_device_field(server):
    panel = DevicePanel(server.gui, DeviceSession())
    try:
        panel.spec.value = "plotter9000"
        panel.connect_button.value = True
        assert panel.card is None
        assert "unknown device 'plotter9000'" in unescape_md(panel.connection_msg.content)
        assert panel.home_button.disabled
    finally:
        panel.close()


def test_grbl_through_the_pty_simulator(server):
    sim = GrblSimulator(idle_timeout=20.0, lifetime=60.0)
    port = sim.start()
    panel = DevicePanel(server.gui, DeviceSession(), Machine(), refresh_s=0.2)
    try:
        panel.spec.value = f"grbl:{port}"
        panel.connect_button.value = True
        assert panel.card is not None, unescape_md(panel.connection_msg.content)
        panel.step.value = 1.5
        panel.jog["Y"].value = "+"
        assert unescape_md(panel.motion_msg.content).startswith("Jog Y+1.5 mm: done"), unescape_md(panel.motion_msg.content)
        with panel._lock:  # the panel's status poller reads the same serial port: take turns with it
            np.testing.assert_allclose(panel.card.position(), [0.0, 1.5, 0.0])
        assert [box.disabled for box in panel.outputs] == [False] + [True] * 7  # GRBL drives one output
        panel.outputs[0].value = True
        assert unescape_md(panel.output_msg.content).startswith("DO1 on: done")
        panel.pwm_button.value = True
        assert "GRBL's PWM is its spindle output" in unescape_md(panel.pwm_msg.content)
    finally:
        panel.close()
        sim.stop()
