"""Signal nodes (Digital I/O, PWM, Analog/spindle): events at times or at segment starts of a program.

They do not touch a device: they add events, chained from node to node, for Card output to send with
the program (or "I/O now" to set at once; both in ``flowmc.nodes.devices``, which a graph that only
validates or lists them need not import). With an untimed step stream, event times count ticks (the
``Steps`` convention).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field

from flowmc.errors import NodeError
from flowmc.registry import In, NodeType, Out, register

if TYPE_CHECKING:  # numpy and the value types are imported when a node runs
    import numpy as np

    from flowmc.motion.trajectory import Signal

__all__ = ["DigitalIO", "Pwm", "Analog", "DigitalIOParams", "PwmParams", "AnalogParams"]

_SIGNALS_OUT = Out("signals", "Signal", doc="The incoming events plus these")


class _Params(BaseModel):
    model_config = ConfigDict(extra="forbid", defer_build=True)


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
    import numpy as np

    from flowmc.motion.path import describe_segment
    from flowmc.motion.trajectory import Steps, Trajectory

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
    from flowmc.motion.trajectory import Signal

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
        import numpy as np

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
