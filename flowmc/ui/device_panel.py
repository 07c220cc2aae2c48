"""The device panel: connect to a motion card, home, jog, e-stop, drive outputs and PWM, watch its state.

Everything goes through the editor's device session (``session.DeviceAccess``: one connection, the one
a job runner uses too) and the card interface it opens, so the simulated card, a GRBL board and
LinuxCNC look the same here. A device error (a limit, a value out of range, a port that went away) is
shown beside the control that caused it, never as a traceback. A background thread refreshes the
position and input status a few times a second.
"""

from __future__ import annotations

import threading
from typing import Any, Callable

import numpy as np
import viser

from flowmc.errors import FlowmcError
from flowmc.motion.machine import Machine
from flowmc.ui.session import DeviceAccess
from flowmc.ui.text import md

__all__ = ["DevicePanel", "N_OUTPUT_TOGGLES"]

N_OUTPUT_TOGGLES = 8
#: Options passed to ``DeviceAccess.connect`` per backend: the panel drives PWM, so the simulated card's
#: shared PWM/DA terminal is set to PWM (its default is DA).
DEFAULT_OPTIONS = {"sim": {"analog": "pwm"}}


def _message(exc: Exception) -> str:
    """What to show for a failed device call: the error's own text, else its type and text."""
    return str(exc) if isinstance(exc, FlowmcError) else f"{type(exc).__name__}: {exc}"


class DevicePanel:
    """Device controls in a folder of ``gui`` (placed in the current container), on ``devices``.

    ``machine_provider``: the Machine to open the device with (a Machine, a function returning the
    editor's current one, or None for the default). ``on_log(log)`` receives the DeviceLog of every
    operation (for the 3D view). Public handles: ``spec``, ``connect_button``, ``home_button``,
    ``step``, ``speed``, ``jog`` (per axis), ``estop_button``, ``reset_button`` (enabled after an
    e-stop: clears the latch, ``MotionCard.reset``), ``outputs``, ``pwm_freq``, ``pwm_duty``,
    ``pwm_button``, ``status`` and the messages ``connection_msg``, ``motion_msg``, ``output_msg``, ``pwm_msg``.
    """

    def __init__(self, gui: Any, devices: DeviceAccess, machine_provider: Machine | Callable[[], Machine | None] | None = None,
                 *, label: str = "Device", refresh_s: float = 0.25, device_options: dict | None = None,
                 on_log: Callable[[Any], Any] | None = None):
        self.gui = gui
        self.devices = devices
        self.machine_provider = machine_provider
        self.device_options = DEFAULT_OPTIONS if device_options is None else device_options
        self.on_log = on_log
        self.jog: dict[str, Any] = {}
        self._lock = threading.RLock()
        self._syncing = False
        self._stop = threading.Event()
        self.folder = gui.add_folder(label)
        with self.folder:
            self._build_connection()
            self._jog_folder = gui.add_folder("Home and jog")
            with self._jog_folder:
                self._build_motion()
            with gui.add_folder("Outputs", expand_by_default=False):
                self._build_outputs()
        self._refresh_s = refresh_s
        self._poller = threading.Thread(target=self._poll, name="flowmc-device-status", daemon=True)
        self._poller.start()

    # ------------------------------------------------------------------ building
    def _build_connection(self) -> None:
        gui = self.gui
        self.spec = gui.add_text("Device", "sim", hint="Known: " + ", ".join(self.devices.known()))
        self.connect_button = gui.add_button("Connect", icon=viser.Icon.PLUG_CONNECTED)
        self.disconnect_button = gui.add_button("Disconnect", icon=viser.Icon.PLUG_CONNECTED_X, disabled=True)
        self.connection_msg = gui.add_markdown("Not connected.")
        self.status = gui.add_markdown("")
        self.connect_button.on_click(lambda _: self.connect())
        self.disconnect_button.on_click(lambda _: self.disconnect())

    def _build_motion(self) -> None:
        gui = self.gui
        self.estop_button = gui.add_button("E-STOP", color="red", icon=viser.Icon.HAND_STOP, disabled=True)
        self.reset_button = gui.add_button("Reset", icon=viser.Icon.REFRESH, disabled=True)
        self.home_button = gui.add_button("Home all", icon=viser.Icon.HOME, disabled=True)
        self.step = gui.add_number("Jog step (mm)", 1.0, min=0.0001, step=0.01)
        self.speed = gui.add_number("Jog speed (mm/s)", 10.0, min=0.001, step=0.1)
        self.motion_msg = gui.add_markdown("")
        self.estop_button.on_click(lambda _: self.estop())
        self.reset_button.on_click(lambda _: self.reset())
        self.home_button.on_click(lambda _: self.home())

    def _build_jog(self, axes: tuple[str, ...]) -> None:
        """One -/+ button group per axis of the connected machine."""
        for group in self.jog.values():
            group.remove()
        self.jog = {}
        with self._jog_folder:
            for axis in axes:
                group = self.gui.add_button_group(f"Jog {axis}", ("-", "+"))
                group.on_click(lambda event, a=axis: self.jog_axis(a, -1 if event.target.value == "-" else +1))
                self.jog[axis] = group

    def _build_outputs(self) -> None:
        gui = self.gui
        self.outputs = [gui.add_checkbox(f"DO{ch}", False, disabled=True) for ch in range(1, N_OUTPUT_TOGGLES + 1)]
        for ch, box in enumerate(self.outputs, start=1):
            box.on_update(lambda _, ch=ch: self._output_toggled(ch))
        self.output_msg = gui.add_markdown("")
        self.pwm_freq = gui.add_number("PWM frequency (Hz)", 1000.0, step=1.0)
        self.pwm_duty = gui.add_number("PWM duty (%)", 50.0, step=0.1)
        self.pwm_button = gui.add_button("Set PWM", disabled=True)
        self.pwm_msg = gui.add_markdown("")
        self.pwm_button.on_click(lambda _: self.set_pwm())

    # ------------------------------------------------------------------ operations
    def _machine(self) -> Machine | None:
        p = self.machine_provider
        return p() if callable(p) else p

    @property
    def card(self) -> Any:
        """The session's open card (None when disconnected)."""
        return self.devices.card

    def _do(self, message: Any, what: str, call: Callable[[Any], Any]) -> Any:
        """Run ``call(card)`` under the lock; a failure goes to ``message`` (and returns None)."""
        with self._lock:
            if self.card is None:
                message.content = "Not connected."
                return None
            try:
                out = call(self.card)
            except Exception as exc:  # noqa: BLE001 - any device failure is shown at the control, not raised
                message.content = md("**{} failed:** {}", what, _message(exc))
                return None
        if hasattr(out, "outcome"):  # a DeviceLog
            events = "; ".join(e.message for e in out.events if e.message)
            message.content = md("{}: {}", what, out.outcome) + (md(" ({})", events) if events else "")
            if self.on_log is not None:
                self.on_log(out)
        self.refresh()
        return out

    def connect(self, spec: str | None = None) -> bool:
        """Open the device named in the Device field (or ``spec``); True when connected."""
        self.disconnect()
        spec = (spec or self.spec.value).strip()
        name = spec.partition(":")[0]
        try:
            with self._lock:
                card = self.devices.connect(spec, self._machine(), **self.device_options.get(name, {}))
        except Exception as exc:  # noqa: BLE001 - shown at the Device field
            self.connection_msg.content = md("**Cannot connect:** {}", _message(exc))
            return False
        self.connection_msg.content = md("Connected to **{}** (axes {}).", spec, ", ".join(card.machine.names))
        self._build_jog(card.machine.names)
        self._set_enabled(True)
        self.refresh()
        return True

    def disconnect(self) -> None:
        with self._lock:
            was_open = self.card is not None
            try:
                self.devices.disconnect()
            except Exception as exc:  # noqa: BLE001
                self.connection_msg.content = md("Closed with an error: {}", _message(exc))
            else:
                if was_open:
                    self.connection_msg.content = "Not connected."
        self._set_enabled(False)
        self.status.content = ""

    def _set_enabled(self, on: bool) -> None:
        n_out = min(self.card.ranges.outputs, N_OUTPUT_TOGGLES) if on and self.card else 0
        self.connect_button.disabled, self.disconnect_button.disabled = on, not on
        self.home_button.disabled = self.estop_button.disabled = self.pwm_button.disabled = not on
        self.reset_button.disabled = True
        self._syncing = True
        for ch, box in enumerate(self.outputs, start=1):
            box.disabled = ch > n_out
            box.value = False
        self._syncing = False

    def home(self) -> Any:
        return self._do(self.motion_msg, "Home all", lambda c: c.home())

    def jog_axis(self, axis: str, direction: int) -> Any:
        """Jog ``axis`` one step in ``direction`` (+1/-1) at the jog speed."""
        step, speed = float(self.step.value), float(self.speed.value)
        if not (np.isfinite(step) and step > 0 and np.isfinite(speed) and speed > 0):
            self.motion_msg.content = "**Jog:** step and speed must be numbers > 0"
            return None
        sign = "+" if direction > 0 else "-"
        return self._do(self.motion_msg, f"Jog {axis}{sign}{step:g} mm",
                        lambda c: c.jog(axis, direction * step, speed))

    def estop(self) -> Any:
        log = self._do(self.motion_msg, "E-stop", lambda c: c.estop())
        if log is not None:
            self.motion_msg.content += " — latched: press Reset once the cause is clear"
            self.reset_button.disabled = False
        return log

    def reset(self) -> Any:
        """Clear a latched e-stop (the button stays enabled while the device refuses, e.g. its input is closed)."""
        log = self._do(self.motion_msg, "Reset", lambda c: c.reset())
        if log is not None:
            self.reset_button.disabled = True
        return log

    def _output_toggled(self, channel: int) -> None:
        if self._syncing:
            return
        box = self.outputs[channel - 1]
        if self._do(self.output_msg, f"DO{channel} {'on' if box.value else 'off'}",
                    lambda c: c.set_output(channel, bool(box.value))) is None:
            self._syncing = True
            box.value = not box.value  # the device did not take it: show its real state
            self._syncing = False

    def set_pwm(self) -> Any:
        freq, duty = float(self.pwm_freq.value), float(self.pwm_duty.value)
        return self._do(self.pwm_msg, f"PWM {freq:g} Hz {duty:g} %", lambda c: c.set_pwm(freq, duty))

    # ------------------------------------------------------------------ status
    def status_text(self) -> str:
        """Position, e-stop and input bits (limit/home switches labelled by axis) as markdown."""
        with self._lock:
            card = self.card
            if card is None:
                return ""
            pos, inputs, status = card.position(), card.read_inputs(), card.status()
            switch = card.input_names()
        names = card.machine.names
        lines = [" · ".join(md("**{}** {:.4f}", a, p) for a, p in zip(names, pos)) + " mm"]
        lines.append(f"E-stop: {'**LATCHED**' if status.get('estop') else 'clear'}"
                     + (md(" · homed: {}", ", ".join(a for a, h in zip(names, status["homed"]) if h) or "none")
                        if "homed" in status else ""))
        closed = [switch.get(ch, f"in {ch}") for ch, on in sorted(inputs.items()) if on]
        lines.append(md("Inputs closed: {}", ", ".join(closed) if closed else "none"))
        if "outputs" in status:
            lines.append("Outputs on: " + (", ".join(f"DO{ch}" for ch in status["outputs"]) or "none"))
        if "pwm_hz_duty" in status:
            hz, duty = status["pwm_hz_duty"]
            lines.append(f"PWM: {hz:.6g} Hz, {duty:.4g} %")
        return "\n\n".join(lines)

    def refresh(self) -> None:
        """Update the status text now."""
        try:
            text = self.status_text()
        except Exception as exc:  # noqa: BLE001 - a port that went away is shown, not raised
            text = md("**Status failed:** {}", _message(exc))
        if text != self.status.content:
            self.status.content = text

    def _poll(self) -> None:
        while not self._stop.wait(self._refresh_s):
            if self.card is not None:
                self.refresh()

    def close(self) -> None:
        """Stop the status thread and close the connection (safe to call twice)."""
        self._stop.set()
        if self._poller.is_alive():
            self._poller.join(timeout=2.0)
        self.disconnect()
