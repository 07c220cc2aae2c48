"""What a device did, period by period: the value on ``Log`` wires that tests, the CLI and the 3D view read.

A log is plain data (arrays, tuples, a JSON string of the device's end state), so two runs of the
simulated card with the same inputs give logs with the same ``digest()``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from flowmc.motion.values import array_digest, frozen_array

__all__ = ["Change", "Event", "DeviceLog", "CHANGE_KINDS", "OUTCOMES"]

#: Kinds of I/O change: digital input/output bit, PWM frequency (Hz) and duty (%), DA volts, spindle rpm,
#: and the tool (pen) state, 1 down / 0 up (besides the output that carries it, as the spindle's are).
CHANGE_KINDS = ("din", "dout", "pwm_freq", "pwm_duty", "da", "spindle_rpm", "tool")

#: How an operation ended. ``done``: as commanded; the rest name what stopped it (``aborted``: a job's
#: controlled stop, asked for by the operator).
OUTCOMES = ("done", "limit", "soft_limit", "estop", "error", "alarm", "home_failed", "aborted")


class Change(NamedTuple):
    """An input or output took ``value`` at time ``t`` (s). Channels count from 1, as on the card."""

    t: float
    kind: str
    channel: int
    value: float


class Event(NamedTuple):
    """Something worth telling: ``kind`` in limit, soft_limit, estop, reset, home, approach, error, alarm, hold, ..."""

    kind: str
    t: float
    axis: str  # "" when the event concerns no single axis
    message: str


@dataclass(frozen=True, eq=False)
class DeviceLog:
    """Per-period record of one device operation (a program run, a homing, a jog).

    Row k is the state at ``t[k]``; row 0 is the state before the first period.

    - ``steps[k]``: pulses issued per axis during the period ending at ``t[k]`` (signed).
    - ``position[k]``: axis position in mm (the step counter in open loop, the motor in closed loop).
    - ``following_error[k]``: commanded minus actual position (closed loop only, else ``None``).
    - ``changes``: I/O, PWM, DA and spindle changes in time order; ``events``: what happened.
    - ``state``: the device's end state as a dict (positions, outputs, clock); a later operation
      can start from it.
    """

    device: str
    axes: tuple[str, ...]
    period: float
    t: np.ndarray
    steps: np.ndarray
    position: np.ndarray
    following_error: np.ndarray | None
    changes: tuple[Change, ...]
    events: tuple[Event, ...]
    outcome: str
    state_json: str

    def __init__(self, device: str, axes, period: float, t, steps, position, following_error=None,
                 changes=(), events=(), outcome: str = "done", state: dict | None = None):
        axes = tuple(axes)
        t = frozen_array(t)
        n = len(t)
        steps = frozen_array(np.asarray(steps).reshape(n, len(axes)), dtype=np.int32)
        position = frozen_array(np.asarray(position, dtype=float).reshape(n, len(axes)))
        if following_error is not None:
            following_error = frozen_array(np.asarray(following_error, dtype=float).reshape(n, len(axes)))
        if outcome not in OUTCOMES:
            raise ValueError(f"unknown outcome {outcome!r}; known: {OUTCOMES}")
        for c in changes:
            if c.kind not in CHANGE_KINDS:
                raise ValueError(f"unknown change kind {c.kind!r}; known: {CHANGE_KINDS}")
        object.__setattr__(self, "device", str(device))
        object.__setattr__(self, "axes", axes)
        object.__setattr__(self, "period", float(period))
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "steps", steps)
        object.__setattr__(self, "position", position)
        object.__setattr__(self, "following_error", following_error)
        object.__setattr__(self, "changes", tuple(Change(float(c.t), str(c.kind), int(c.channel), float(c.value))
                                                  for c in sorted(changes, key=lambda c: c.t)))
        object.__setattr__(self, "events", tuple(Event(str(e.kind), float(e.t), str(e.axis), str(e.message))
                                                 for e in events))
        object.__setattr__(self, "outcome", outcome)
        object.__setattr__(self, "state_json", json.dumps(state or {}, sort_keys=True))

    def __len__(self) -> int:
        return len(self.t)

    @property
    def state(self) -> dict:
        return json.loads(self.state_json)

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0]) if len(self.t) else 0.0

    @property
    def end_position(self) -> np.ndarray:
        return self.position[-1] if len(self.position) else np.zeros(len(self.axes))

    def axis(self, name: str) -> int:
        """Column of the named axis."""
        try:
            return self.axes.index(name)
        except ValueError:
            raise KeyError(f"no axis {name!r} in this log; axes: {self.axes}") from None

    def amended(self, changes=(), events=(), outcome: str | None = None, state: dict | None = None) -> "DeviceLog":
        """This log with more changes and events (a job leaving the outputs safe after it), another outcome
        or end state."""
        return DeviceLog(self.device, self.axes, self.period, self.t, self.steps, self.position, self.following_error,
                         self.changes + tuple(changes), sorted(self.events + tuple(events), key=lambda e: e.t),
                         outcome or self.outcome, self.state if state is None else state)

    def events_of(self, kind: str) -> tuple[Event, ...]:
        return tuple(e for e in self.events if e.kind == kind)

    def changes_of(self, kind: str, channel: int | None = None) -> tuple[Change, ...]:
        return tuple(c for c in self.changes if c.kind == kind and (channel is None or c.channel == channel))

    def digest(self) -> str:
        fe = self.following_error if self.following_error is not None else np.zeros(0)
        return array_digest("DeviceLog", self.device, self.axes, self.period, self.t, self.steps, self.position,
                            fe, repr(self.changes), repr(self.events), self.outcome, self.state_json)

    def summary(self) -> dict:
        out = {
            "type": "Log",
            "device": self.device,
            "outcome": self.outcome,
            "periods": max(len(self) - 1, 0),
            "period_s": self.period,
            "duration_s": round(self.duration, 6),
            "axes": list(self.axes),
            "end_position": self.end_position.round(6).tolist(),
            "steps_per_axis": np.abs(self.steps).sum(axis=0, dtype=np.int64).tolist(),
            "changes": len(self.changes),
            "events": [f"{e.kind} t={e.t:.4f}{' ' + e.axis if e.axis else ''}: {e.message}" for e in self.events[:8]],
        }
        if self.following_error is not None and len(self):
            out["max_following_error_mm"] = np.abs(self.following_error).max(axis=0).round(6).tolist()
        return out
