"""The simulated card's outputs: 8 digital outputs, the shared PWM/DA terminal and the spindle.

What is set is what the card really produces: PWM frequency and duty through the 6050's counters,
DA volts at 12 bits, spindle speed through the DA (0-10 V for 0-24,000 rpm) with run and direction
on two digital outputs (the thesis's FWD/REV inverter terminals), and the tool (pen) state on the
pen output. Every change is returned as a ``Change`` so the log can record it.

The pen output (default 1) may be one of the spindle's outputs: a plotter's pen relay and a mill's
spindle run take the same terminal, as GRBL's M3/M5 drive both. A program that runs the spindle and
would switch that output against it with the tool (lift the pen while the spindle runs) is refused.
"""

from __future__ import annotations

import math

from flowmc.devices.log import Change
from flowmc.devices.ranges import CardRanges, da_output, pwm_output, spindle_volts
from flowmc.errors import DeviceError, LimitError

__all__ = ["Outputs"]


def _fmt(x: float) -> str:
    return f"{x:,.6g}" if abs(x) >= 1e3 else f"{x:.6g}"


class Outputs:
    """Output state plus ``apply(kind, channel, value, t)`` that checks, quantises and reports changes."""

    def __init__(self, ranges: CardRanges, spindle_outputs: tuple[int, int] = (1, 2), state: dict | None = None,
                 pen_output: int | None = 1):
        self.ranges = ranges
        self.spindle_outputs = tuple(spindle_outputs)
        for ch in self.spindle_outputs:
            if not 1 <= ch <= ranges.outputs:
                raise DeviceError(f"spindle output {ch} does not exist (outputs 1-{ranges.outputs})", where="sim card")
        if pen_output is not None and not 0 <= pen_output <= ranges.outputs:
            raise DeviceError(f"pen output {pen_output} does not exist (outputs 1-{ranges.outputs}, 0: none)",
                              where="sim card")
        self.pen_output = pen_output or None
        state = state or {}
        self.bits = list(state.get("outputs", [False] * ranges.outputs))
        self.pwm_request = tuple(state.get("pwm_request", (1000.0, 0.0)))
        self.pwm = tuple(state.get("pwm", (0.0, 0.0)))  # (0, 0): PWM never started
        self.da = float(state.get("da", 0.0))
        self.spindle_rpm = float(state.get("spindle_rpm", 0.0))
        self.tool_down = bool(state.get("tool_down", False))

    def state(self) -> dict:
        return {"outputs": list(self.bits), "pwm_request": list(self.pwm_request), "pwm": list(self.pwm),
                "da": self.da, "spindle_rpm": self.spindle_rpm, "tool_down": self.tool_down}

    def apply(self, kind: str, channel: int, value: float, t: float, where: str = "sim card") -> list[Change]:
        r = self.ranges
        if not math.isfinite(value):
            raise LimitError(f"{kind} value {value} is not a number", where=where)
        if kind == "dout":
            if not 1 <= channel <= r.outputs:
                raise LimitError(f"digital output {channel} does not exist (outputs 1-{r.outputs})", where=where)
            return self._bit(channel, bool(value), t)
        if channel not in (0, 1):
            raise LimitError(f"{kind} channel {channel}: the card has one (channel 1)", where=where)
        if kind in ("pwm_freq", "pwm_duty"):
            if r.analog == "da":
                raise LimitError("the shared PWM/DA terminal is set to DA; set it to PWM", where=where)
            freq, duty = self.pwm_request
            if kind == "pwm_freq":
                lo, hi = r.pwm_hz
                if not lo <= value <= hi:
                    raise LimitError(f"PWM frequency {_fmt(value)} Hz outside {_fmt(lo)}-{_fmt(hi)} Hz", where=where)
                freq = value
            else:
                lo, hi = r.duty_pct
                if not lo <= value <= hi:
                    raise LimitError(f"PWM duty {_fmt(value)} % outside {_fmt(lo)}-{_fmt(hi)} %", where=where)
                duty = value
            self.pwm_request = (freq, duty)
            new = pwm_output(freq, duty)
            changes = [Change(t, k, 1, v) for k, old, v in (("pwm_freq", self.pwm[0], new[0]),
                                                             ("pwm_duty", self.pwm[1], new[1])) if old != v]
            self.pwm = new
            return changes
        if kind == "tool":
            return self._tool(value, t, where)
        if r.analog == "pwm":
            raise LimitError("the shared PWM/DA terminal is set to PWM; set it to DA", where=where)
        if kind == "da":
            lo, hi = r.da_volts
            if not lo <= value <= hi:
                raise LimitError(f"DA {_fmt(value)} V outside {_fmt(lo)}..{_fmt(hi)} V", where=where)
            return self._da(da_output(value, lo, hi), t)
        if kind == "spindle_rpm":
            if abs(value) > r.spindle_rpm_max:
                raise LimitError(f"spindle {_fmt(value)} rpm beyond {_fmt(r.spindle_rpm_max)} rpm", where=where)
            volts = da_output(spindle_volts(value, r), *r.da_volts)
            rpm = math.copysign(volts / r.spindle_volts_max * r.spindle_rpm_max, value) if volts else 0.0
            run, ccw = self.spindle_outputs
            changes = self._da(volts, t) + self._bit(run, rpm != 0.0, t) + self._bit(ccw, rpm < 0.0, t)
            if rpm != self.spindle_rpm:
                changes.append(Change(t, "spindle_rpm", 1, rpm))
                self.spindle_rpm = rpm
            return changes
        raise LimitError(f"unknown output kind {kind!r}", where=where)

    def _tool(self, value: float, t: float, where: str) -> list[Change]:
        """Tool down (1) or up (0): the tool state, and the pen output when there is one."""
        if value not in (0.0, 1.0):
            raise LimitError(f"tool set to {_fmt(value)}, not 1 (down) or 0 (up)", where=where)
        down = bool(value)
        pen = self.pen_output
        if pen in self.spindle_outputs and self.spindle_rpm != 0.0:
            needs = True if pen == self.spindle_outputs[0] else self.spindle_rpm < 0.0  # run, or ccw
            if down != needs:
                role = "run" if pen == self.spindle_outputs[0] else "counter-clockwise"
                raise LimitError(f"tool {'down' if down else 'up'} would switch output {pen} {'on' if down else 'off'}"
                                 f", the spindle's {role} output, while the spindle runs at "
                                 f"{_fmt(self.spindle_rpm)} rpm; give the pen its own output (pen_output) or 0 "
                                 "for none", where=where)
        changes = [Change(t, "tool", 1, float(down))] if down != self.tool_down else []
        self.tool_down = down
        return changes + (self._bit(pen, down, t) if pen else [])

    def _bit(self, channel: int, on: bool, t: float) -> list[Change]:
        if self.bits[channel - 1] == on:
            return []
        self.bits[channel - 1] = on
        return [Change(t, "dout", channel, float(on))]

    def _da(self, volts: float, t: float) -> list[Change]:
        if volts == self.da:
            return []
        self.da = volts
        return [Change(t, "da", 1, volts)]
