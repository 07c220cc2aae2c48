"""Device nodes: the machine's limits, pre-flight, card output, homing, and I/O, PWM and analog signals.

Signal nodes (Digital I/O, PWM, Analog/spindle) do not touch a device: they add events at times or
at segment starts of a program, chained from node to node, for Card output to send with the program
(or "I/O now" to set at once). With an untimed step stream, event times count ticks (the ``Steps``
convention). Device nodes are not pure (never cached). Their optional ``after`` input takes the log
of an earlier device node: it orders them (Home, Jog, then Card output), and the simulated card
carries on from the state that log ends in (where homing left the axes, which outputs are on).
"""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator

from flowmc.devices.backends import DeviceOptions, GrblOptions, SimOptions, check_spec, open_device
from flowmc.devices.log import DeviceLog
from flowmc.devices.preflight import preflight
from flowmc.devices.ranges import CARD_6050
from flowmc.errors import DeviceError, NodeError
from flowmc.motion.machine import Axis, Machine, default_machine
from flowmc.motion.path import describe_segment
from flowmc.motion.trajectory import Signal, Steps, Trajectory
from flowmc.registry import In, NodeType, Out, register

_MOTION_IN = In("motion", ("Trajectory", "Steps"), doc="The program: setpoints or a step stream")
_MACHINE_IN = In("machine", "Machine", doc="Axis limits and period (default: the default machine)", default=None)
_SIGNALS_IN = In("signals", "Signal", doc="I/O events to send with the program", default=None)
_AFTER_IN = In("after", "Log", doc="Run after this device log (the sim carries on from its end state)",
               default=None)
_LOG_OUT = Out("log", "Log", doc="What the device did, per period")
_SIGNALS_OUT = Out("signals", "Signal", doc="The incoming events plus these")


class _Params(BaseModel):
    model_config = ConfigDict(extra="forbid")


class _DeviceParams(_Params):
    device: Annotated[str, Field(description="sim, grbl:<serial port> or linuxcnc")] = "sim"
    closed_loop: Annotated[bool, Field(description="Simulated card: PID position loop on a first-order motor")] = False
    estop_input: Annotated[int, Field(ge=0, le=8, description="Simulated card: e-stop input 1-8 (0: none)")] = 0
    analog: Annotated[Literal["da", "pwm"], Field(description="Simulated card: what the shared PWM/DA "
                                                                 "terminal gives")] = "da"

    @field_validator("device")
    @classmethod
    def _known(cls, spec: str) -> str:
        try:
            check_spec(spec)
        except DeviceError as err:
            raise ValueError(err.message) from None
        return spec.strip()


def _machine_for(machine: Machine | None, motion=None) -> Machine:
    if machine is not None:
        return machine
    if isinstance(motion, Trajectory):
        return default_machine(period=motion.period)
    return default_machine()


def _open(params: _DeviceParams, machine: Machine, after: DeviceLog | None):
    """Open the device; a card carries on from ``after``'s end state when that came from one of its kind."""
    card = params if isinstance(params, CardOutputParams) else None  # only Card output drives a pen
    options = DeviceOptions(
        sim=SimOptions(closed_loop=params.closed_loop, estop_input=params.estop_input or None, analog=params.analog,
                       pen_output=(card.pen_output or None) if card else None),
        grbl=GrblOptions(card.grbl_pen_down, card.grbl_pen_up) if card else GrblOptions(),
        resume=after.state if after is not None else None)
    return open_device(params.device, machine, options)


def _report(ctx, log: DeviceLog) -> None:
    for event in log.events:
        ctx.log(f"{event.kind} at t={event.t:.3f} s{' ' + event.axis if event.axis else ''}: {event.message}")
    if log.outcome != "done":
        ctx.log(f"stopped: {log.outcome}")


# ---------------------------------------------------------------- machine

class MachineParams(_Params):
    axes: Annotated[list[Axis], Field(min_length=1, max_length=4,
                                      description="One row per axis: name, soft limits, vmax, amax, jmax, "
                                                  "pulse equivalent, max step rate")] = \
        [Axis(name="X"), Axis(name="Y"), Axis(name="Z", min=-50.0, max=50.0)]
    period: Annotated[float, Field(gt=0, le=0.1, description="Interpolation period T",
                                   json_schema_extra={"unit": "s"})] = 0.004

    @field_validator("axes")
    @classmethod
    def _unique_names(cls, axes: list[Axis]) -> list[Axis]:  # checked when the graph is validated, not at run time
        names = [a.name for a in axes]
        if len(set(names)) != len(names):
            raise ValueError(f"axis names must be unique, got {names}")
        return axes


@register
class MachineNode(NodeType):
    type_id = "machine"
    title = "Machine limits"
    category = "Devices"
    description = "The machine's axes (soft limits, velocity, acceleration, jerk, pulse equivalent, step rate) and T."
    Params = MachineParams
    outputs = (Out("machine", "Machine", doc="Axis limits and period"),)

    def run(self, ctx, params: MachineParams):
        return {"machine": Machine(axes=tuple(params.axes), period=params.period)}


# ---------------------------------------------------------------- pre-flight

class PreflightParams(_Params):
    analog: Annotated[Literal["da", "pwm", "both"], Field(description="What the PWM/DA terminal gives")] = "da"


@register
class PreflightNode(NodeType):
    type_id = "device.preflight"
    title = "Pre-flight"
    category = "Devices"
    description = "Check a program against soft limits, velocity, acceleration, step rate and output ranges."
    pure = False  # a check: always run, so its verdict is never a stale cache entry
    Params = PreflightParams
    inputs = (_MOTION_IN, _SIGNALS_IN, _MACHINE_IN)
    outputs = (Out("report", "Table", doc="Per axis: travel, peak velocity, acceleration, step rate, limits"),)

    def run(self, ctx, params: PreflightParams, motion, signals=None, machine=None):
        machine = _machine_for(machine, motion)
        report = preflight(motion, machine, signals, ranges=CARD_6050.with_analog(params.analog))
        return {"report": report.table(machine)}


# ---------------------------------------------------------------- card output, homing and jogging

class CardOutputParams(_DeviceParams):
    pen_output: Annotated[int, Field(ge=0, le=8, description="Simulated card: digital output the program's "
                                                             "tool (pen) state drives, on = down (0: none, as on a mill)")] = 0
    grbl_pen_down: Annotated[str, Field(description="GRBL: command for tool (pen) down (the pen on the "
                                                    "spindle output, e.g. M3 S1000; empty: no pen)")] = ""
    grbl_pen_up: Annotated[str, Field(description="GRBL: command for tool (pen) up, e.g. M5")] = ""


@register
class CardOutput(NodeType):
    type_id = "device.card_output"
    title = "Card output"
    category = "Devices"
    description = "Check a program (pre-flight), send it to a motion card, and return what the card did."
    pure = False
    Params = CardOutputParams
    inputs = (_MOTION_IN, _SIGNALS_IN, _MACHINE_IN, _AFTER_IN)
    outputs = (_LOG_OUT,)

    def run(self, ctx, params: CardOutputParams, motion, signals=None, machine=None, after=None):
        machine = _machine_for(machine, motion)
        with _open(params, machine, after) as card:
            card.check(motion, signals)
            log = card.run(motion, signals, check=False)
        _report(ctx, log)
        return {"log": log}


class HomeParams(_DeviceParams):
    axes: Annotated[str, Field(description="Axes to home in order, e.g. 'ZXY' (empty: all)")] = ""
    method: Annotated[Literal["switch", "midpoint"],
                      Field(description="switch: the thesis's V1/V2 procedure; midpoint: between the limits")
                      ] = "switch"


@register
class Home(NodeType):
    type_id = "device.home"
    title = "Home"
    category = "Devices"
    description = "Home axes on a device (home switch, or midway between the limit switches) and zero them."
    pure = False
    Params = HomeParams
    inputs = (_MACHINE_IN, _AFTER_IN)
    outputs = (_LOG_OUT,)

    def run(self, ctx, params: HomeParams, machine=None, after=None):
        machine = _machine_for(machine)
        axes = tuple(params.axes.replace(",", "").replace(" ", "").upper()) or None
        with _open(params, machine, after) as card:
            log = card.home(axes, params.method)
        _report(ctx, log)
        if log.outcome != "done":
            raise NodeError(f"homing ended with {log.outcome}: "
                            + "; ".join(e.message for e in log.events if e.kind != "home"))
        return {"log": log}


class JogParams(_DeviceParams):
    axis: Annotated[str, Field(min_length=1, description="The axis to jog, e.g. X")] = "X"
    distance: Annotated[float, Field(description="How far, signed", json_schema_extra={"unit": "mm"})] = 10.0
    speed: Annotated[float, Field(gt=0, description="Top speed (the move ramps at the axis's amax)",
                                  json_schema_extra={"unit": "mm/s"})] = 10.0


@register
class Jog(NodeType):
    type_id = "device.jog"
    title = "Jog"
    category = "Devices"
    description = "Move one axis of a device by a distance at a speed (e.g. to set the table before drawing)."
    pure = False
    Params = JogParams
    inputs = (_MACHINE_IN, _AFTER_IN)
    outputs = (_LOG_OUT,)

    def run(self, ctx, params: JogParams, machine=None, after=None):
        machine = _machine_for(machine)
        axis = params.axis.strip().upper()
        with _open(params, machine, after) as card:
            log = card.jog(axis, params.distance, params.speed)
        _report(ctx, log)
        if log.outcome != "done":
            raise NodeError(f"the jog of {axis} ended with {log.outcome}: "
                            + "; ".join(e.message for e in log.events))
        return {"log": log}


# ---------------------------------------------------------------- signals along a program

class _At(_Params):
    at: Annotated[float, Field(ge=0, description="Time (s), or segment number (1 is the program's first segment), "
                                                  "as the node's 'at' says")]


class BitChange(_At):
    on: Annotated[bool, Field(description="Output on (closed) or off")]


class DutyChange(_At):
    duty: Annotated[float, Field(ge=0, le=100, description="PWM duty", json_schema_extra={"unit": "%"})]


class ValueChange(_At):
    value: Annotated[float, Field(description="Volts or rpm (signed: + cw, - ccw), as the node's mode says")]


class _SignalParams(_Params):
    at: Annotated[Literal["time", "segment"],
                  Field(description="Changes happen at a time (s; ticks with an untimed step stream) or at "
                                    "the start of a program segment (numbered from 1, as Measure path and "
                                    "error messages count them)")] = "time"


def _times(at: str, given: list[float], motion) -> np.ndarray:
    """Times of the change points: as given, or the first setpoint of each segment (numbered from 1)."""
    points = np.asarray(given, dtype=float)
    if at == "time":
        return points
    if not isinstance(motion, (Trajectory, Steps)):
        raise NodeError("changes at segments need the program: wire it to 'motion'")
    seg = np.asarray(motion.segment)
    dt = motion.period if isinstance(motion, Trajectory) else motion.tick or 1.0  # untimed steps: ticks
    names = motion.segment_names
    count = len(names) or (int(seg.max()) + 1 if len(seg) else 0)
    times = []
    for k in points:
        if int(k) != k or not 1 <= k <= count:
            raise NodeError(f"no such segment in the program; its segments are numbered 1 to {count}",
                            where=f"segment {k:g}")
        rows = np.flatnonzero(seg == int(k) - 1)
        if not len(rows):
            raise NodeError("this segment has no setpoints or steps in the program (it does not move)",
                            where=describe_segment(int(k) - 1, names))
        times.append(rows[0] * dt)
    return np.array(times)


def _chain(signals: Signal | None, t, kind, channel, value) -> Signal:
    new = Signal(t, kind, channel, value)
    return new if signals is None else signals.merged(new)


class DigitalIOParams(_SignalParams):
    channel: Annotated[int, Field(ge=1, le=8, description="Digital output 1-8")] = 1
    changes: Annotated[list[BitChange], Field(description="When the output goes on or off (pen down/up, "
                                                          "spindle run)")] = []


@register
class DigitalIO(NodeType):
    type_id = "device.digital_io"
    version = 2  # 2: segment numbers in "at" count from 1
    title = "Digital I/O"
    category = "Devices"
    description = "Switch a digital output at times or segment starts along a program (pen up/down, relays)."
    Params = DigitalIOParams
    inputs = (In("motion", ("Trajectory", "Steps"), doc="The program (for changes at segments)", default=None),
              In("signals", "Signal", doc="Events to add these to", default=None))
    outputs = (_SIGNALS_OUT,)

    def run(self, ctx, params: DigitalIOParams, motion=None, signals=None):
        t = _times(params.at, [c.at for c in params.changes], motion)
        n = len(t)
        return {"signals": _chain(signals, t, ["dout"] * n, [params.channel] * n,
                                  [float(c.on) for c in params.changes])}


class PwmParams(_SignalParams):
    frequency: Annotated[float, Field(ge=18, le=150_000, description="PWM frequency (the card: 18-150,000 Hz)",
                                      json_schema_extra={"unit": "Hz"})] = 1000.0
    changes: Annotated[list[DutyChange], Field(description="Duty changes (laser power)")] = []


@register
class Pwm(NodeType):
    type_id = "device.pwm"
    version = 2  # 2: segment numbers in "at" count from 1
    title = "PWM"
    category = "Devices"
    description = "Set the PWM frequency at the start and its duty (laser power) at times or segment starts."
    Params = PwmParams
    inputs = DigitalIO.inputs
    outputs = (_SIGNALS_OUT,)

    def run(self, ctx, params: PwmParams, motion=None, signals=None):
        t = _times(params.at, [c.at for c in params.changes], motion)
        n = len(t)
        return {"signals": _chain(signals, np.concatenate([[0.0], t]), ["pwm_freq"] + ["pwm_duty"] * n,
                                  [1] * (n + 1), [params.frequency] + [c.duty for c in params.changes])}


class AnalogParams(_SignalParams):
    mode: Annotated[Literal["volts", "rpm"], Field(description="DA volts (-10..10 V) or spindle speed "
                                                               "(0-24,000 rpm on 0-10 V)")] = "rpm"
    changes: Annotated[list[ValueChange], Field(description="Value changes (spindle on: rpm > 0, off: 0)")] = []


@register
class Analog(NodeType):
    type_id = "device.analog"
    version = 2  # 2: segment numbers in "at" count from 1
    title = "Analog/spindle"
    category = "Devices"
    description = "Set the DA voltage or the spindle speed (with its run and direction outputs) along a program."
    Params = AnalogParams
    inputs = DigitalIO.inputs
    outputs = (_SIGNALS_OUT,)

    def run(self, ctx, params: AnalogParams, motion=None, signals=None):
        t = _times(params.at, [c.at for c in params.changes], motion)
        kind = "da" if params.mode == "volts" else "spindle_rpm"
        n = len(t)
        return {"signals": _chain(signals, t, [kind] * n, [1] * n, [c.value for c in params.changes])}


# ---------------------------------------------------------------- I/O now

@register
class IONow(NodeType):
    type_id = "device.io_now"
    title = "I/O now"
    category = "Devices"
    description = "Set outputs on a device at once (events in time order, times ignored) and read its inputs."
    pure = False
    Params = _DeviceParams
    inputs = (In("signals", "Signal", doc="Outputs to set", default=None), _MACHINE_IN, _AFTER_IN)
    outputs = (_LOG_OUT, Out("inputs", "Number", doc="Input levels as a bit mask: bit n-1 is input n"))

    def run(self, ctx, params: _DeviceParams, signals=None, machine=None, after=None):
        machine = _machine_for(machine)
        sig = signals if signals is not None else Signal()
        kinds = sig.kind.tolist()
        if "tool" in kinds:
            raise NodeError("a tool (pen) event goes with a program: send it with Card output")
        if "pwm_duty" in kinds and "pwm_freq" not in kinds[:kinds.index("pwm_duty")]:
            raise NodeError("a PWM duty needs a PWM frequency before it (use the PWM node)")
        changes, events = [], []
        with _open(params, machine, after) as card:
            freq = None
            for kind, ch, value in zip(sig.kind, sig.channel, sig.value):
                if kind == "pwm_freq":
                    freq = float(value)
                    continue
                if kind == "dout":
                    done = card.set_output(int(ch), bool(value))
                elif kind == "pwm_duty":
                    done = card.set_pwm(freq, float(value))
                elif kind == "da":
                    done = card.set_da(float(value))
                else:
                    done = card.set_spindle(float(value))
                changes += done.changes
                events += done.events
            mask = sum(1 << (ch - 1) for ch, on in card.read_inputs().items() if on)
            now = card.snapshot()
        log = DeviceLog(now.device, now.axes, now.period, now.t, now.steps, now.position, now.following_error,
                        changes, events, now.outcome, now.state)
        return {"log": log, "inputs": float(mask)}
