"""What a planner or interpolator hands to a device: setpoints in time, step streams, and I/O signals."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from flowmc.motion.values import array_digest, frozen_array

__all__ = ["Signal", "Trajectory", "Steps", "SIGNAL_KINDS", "ProgramEvent"]

#: Kinds of signal event: digital output bit, PWM frequency (Hz) and duty (%), DA volts, spindle rpm, and
#: the tool (pen) state: value 1 = tool down, 0 = up, channel 0 (there is one). A device decides what the
#: tool drives (the simulated card: a digital output; GRBL: a pair of commands).
SIGNAL_KINDS = ("dout", "pwm_freq", "pwm_duty", "da", "spindle_rpm", "tool")


class ProgramEvent(NamedTuple):
    """A path event (``flowmc.motion.path.PathEvent``: M0/M1/M60, M6, an indexing stop) where a planned
    program carries it: on path segment ``segment`` (a zero-length dwell, so motion is at rest there),
    after the first ``signals_before`` of the program's own signals (those of the segments up to it:
    an M5 before an M6 happens before the stop, an M3 after it once the job resumes)."""

    segment: int
    kind: str
    message: str = ""
    tool: int | None = None
    signals_before: int = 0

    @property
    def code(self) -> str:
        return {"pause": "M0", "optional_pause": "M1", "pallet_change": "M60", "tool_change": "M6"}.get(self.kind,
                                                                                                     "index")

    @property
    def what(self) -> str:
        """How a job names it: ``tool change (M6)``."""
        return {"pause": "program pause", "optional_pause": "optional stop", "pallet_change": "pallet change",
                "tool_change": "tool change"}.get(self.kind, "indexing stop") + (
                    f" ({self.code})" if self.code != "index" else "")

    @property
    def said(self) -> str:
        """What to tell the operator: the program's message, or the tool to load."""
        return self.message or (f"change to tool T{self.tool}" if self.kind == "tool_change" and self.tool is not None
                                else "")


def _events(events) -> tuple[ProgramEvent, ...]:
    return tuple(ProgramEvent(*e) for e in events)


@dataclass(frozen=True, eq=False)
class Signal:
    """Digital, PWM and analog events over time, sorted by time: at ``t[i]`` set ``kind[i]``/``channel[i]`` to ``value[i]``.

    ``t`` is in seconds, except for the signals of an untimed step stream (``Steps.tick == 0``),
    where it counts ticks: ``t = i`` is just before the stream's row ``i`` (see ``Steps``).
    """

    t: np.ndarray
    kind: np.ndarray
    channel: np.ndarray
    value: np.ndarray

    def __init__(self, t=(), kind=(), channel=(), value=()):
        t = np.asarray(t, dtype=float).reshape(-1)
        order = np.argsort(t, kind="stable")
        kinds = np.asarray(kind, dtype="U12").reshape(-1)
        unknown = sorted(set(kinds.tolist()) - set(SIGNAL_KINDS))
        if unknown:
            raise ValueError(f"unknown signal kind(s) {unknown}; known: {SIGNAL_KINDS}")
        object.__setattr__(self, "t", frozen_array(t[order]))
        object.__setattr__(self, "kind", frozen_array(kinds[order], dtype="U12"))
        object.__setattr__(self, "channel", frozen_array(np.asarray(channel, dtype=int).reshape(-1)[order], dtype=int))
        object.__setattr__(self, "value", frozen_array(np.asarray(value, dtype=float).reshape(-1)[order]))
        if not (len(self.t) == len(self.kind) == len(self.channel) == len(self.value)):
            raise ValueError("signal columns must have equal length")

    def __len__(self) -> int:
        return len(self.t)

    def merged(self, other: "Signal") -> "Signal":
        return Signal(
            np.concatenate([self.t, other.t]),
            np.concatenate([self.kind, other.kind]),
            np.concatenate([self.channel, other.channel]),
            np.concatenate([self.value, other.value]),
        )

    def rows(self, period: float, first: int, last: int) -> np.ndarray:
        """The setpoint row each event takes effect at, rows ``period`` apart: the first row at or after its
        time (an event a rounding error past a row is on it), kept to rows ``first``..``last``."""
        return np.clip(np.ceil(self.t / period - 1e-9).astype(int), first, last)

    def shifted(self, dt: float) -> "Signal":
        return Signal(self.t + dt, self.kind, self.channel, self.value)

    def digest(self) -> str:
        return array_digest("Signal", self.t, self.kind, self.channel, self.value)

    def summary(self) -> dict:
        return {"type": "Signal", "events": len(self), "kinds": sorted(set(self.kind.tolist()))}


def _names(names, segment: np.ndarray) -> tuple[str, ...]:
    """Segment names checked: strings, one for every segment index the rows use (or none at all)."""
    if isinstance(names, str):
        raise ValueError("segment_names is one name per path segment, not a single string")
    out = tuple(names)
    if not all(isinstance(name, str) for name in out):
        raise ValueError("segment names must be strings")
    if out and len(segment) and (segment.min() < 0 or segment.max() >= len(out)):
        raise ValueError(f"segment indices {int(segment.min())}..{int(segment.max())} do not fit the "
                         f"{len(out)} segment names")
    return out


def _rapid(flags, segment: np.ndarray) -> tuple[bool, ...]:
    """Rapid flags checked: one bool for every segment index the rows use (or none at all)."""
    out = tuple(bool(f) for f in flags)
    if out and len(segment) and (segment.min() < 0 or segment.max() >= len(out)):
        raise ValueError(f"segment indices {int(segment.min())}..{int(segment.max())} do not fit the "
                         f"{len(out)} rapid flags")
    return out


def _rapid_rows(flags: tuple[bool, ...], segment: np.ndarray) -> np.ndarray:
    if not any(flags):
        return np.zeros(len(segment), dtype=bool)
    return np.asarray(flags, dtype=bool)[segment]


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Setpoints at period T: row k is the commanded position at t = k*T (row 0 is the start).

    ``segment[k]`` is the (0-based) index of the path segment that row k belongs to, and
    ``segment_names[i]`` where segment i came from (its ``source``; "" for none; empty when not
    known), so a device or a pre-flight check can name the segment of any sample as the user knows
    it: ``describe_segment(segment[k], segment_names)`` -> ``"segment 5 (row 4)"``.
    ``segment_rapid[i]``: segment i is a rapid (a job's rapid override applies to it); empty when not
    known (every segment is a feed move).
    """

    positions: np.ndarray
    period: float
    segment: np.ndarray
    axes: tuple[str, ...] = ("X", "Y", "Z")
    signals: Signal = field(default_factory=Signal)
    segment_names: tuple[str, ...] = ()
    segment_rapid: tuple[bool, ...] = ()
    events: tuple[ProgramEvent, ...] = ()

    def __init__(self, positions, period: float, segment=None, axes=("X", "Y", "Z"), signals: Signal | None = None,
                 segment_names=(), segment_rapid=(), events=()):
        pos = frozen_array(positions, ndim=2)
        if pos.shape[1] != len(axes):
            raise ValueError(f"positions have {pos.shape[1]} columns but {len(axes)} axes {tuple(axes)}")
        if not period > 0:
            raise ValueError("period must be > 0")
        seg = np.zeros(len(pos), dtype=int) if segment is None else np.asarray(segment, dtype=int)
        if seg.shape != (len(pos),):
            raise ValueError("segment must have one entry per setpoint")
        object.__setattr__(self, "positions", pos)
        object.__setattr__(self, "period", float(period))
        object.__setattr__(self, "segment", frozen_array(seg, dtype=int))
        object.__setattr__(self, "axes", tuple(axes))
        object.__setattr__(self, "signals", signals if signals is not None else Signal())
        object.__setattr__(self, "segment_names", _names(segment_names, self.segment))
        object.__setattr__(self, "segment_rapid", _rapid(segment_rapid, self.segment))
        object.__setattr__(self, "events", _events(events))

    def __len__(self) -> int:
        return len(self.positions)

    def rapid_rows(self) -> np.ndarray:
        """Per row: does it belong to a rapid segment (all False when that is not known)."""
        return _rapid_rows(self.segment_rapid, self.segment)

    @property
    def duration(self) -> float:
        """Cycle time: N*T to the last setpoint (the reference README's definition)."""
        return (len(self.positions) - 1) * self.period

    @property
    def times(self) -> np.ndarray:
        return np.arange(len(self.positions)) * self.period

    def derivatives(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Sampled velocity, acceleration and jerk per axis by finite differences (reference README)."""
        v = np.diff(self.positions, axis=0) / self.period
        a = np.diff(v, axis=0) / self.period
        j = np.diff(a, axis=0) / self.period
        return v, a, j

    def speed(self) -> np.ndarray:
        """Path speed |v| per interval (N-1 values)."""
        return np.linalg.norm(np.diff(self.positions, axis=0), axis=1) / self.period

    def digest(self) -> str:
        return array_digest("Trajectory", self.positions, self.period, self.segment, self.axes, self.signals.digest(),
                            self.segment_names, *((self.segment_rapid,) if any(self.segment_rapid) else ()),
                            *((self.events,) if self.events else ()))

    def summary(self) -> dict:
        v = self.speed() if len(self) > 1 else np.zeros(1)
        return {
            "type": "Trajectory",
            "samples": len(self),
            "period_s": self.period,
            "duration_s": round(self.duration, 6),
            "start": self.positions[0].round(6).tolist() if len(self) else [],
            "end": self.positions[-1].round(6).tolist() if len(self) else [],
            "peak_speed_mm_s": round(float(v.max()), 6),
            "signal_events": len(self.signals),
        }


@dataclass(frozen=True, eq=False)
class Steps:
    """Per-axis step streams: row k holds each axis's step (-1, 0, +1) at tick k.

    ``origin`` is the position (mm) before the first step and ``step_mm`` each axis's pulse
    equivalent, so position after tick k is ``origin + cumsum(steps)[k] * step_mm``. ``tick`` is
    the time per row in seconds, or 0 when the stream is untimed (a device paces it).

    ``signals`` happen between steps: an event at ``t = i * tick`` comes just before row ``i`` (after
    ``i`` steps; ``i == len(steps)`` is after the last). An untimed stream has no seconds, so its
    signal times are tick indices: ``t = i``. Extra signals sent with an untimed stream (a device's
    ``run(steps, signals)``) are read the same way.

    ``segment``, ``segment_names`` and ``segment_rapid`` are as on a ``Trajectory``: the path segment
    index of each row, where each segment came from and which are rapids.
    """

    steps: np.ndarray
    step_mm: np.ndarray
    origin: np.ndarray
    tick: float = 0.0
    segment: np.ndarray | None = None
    axes: tuple[str, ...] = ("X", "Y")
    signals: Signal = field(default_factory=Signal)
    segment_names: tuple[str, ...] = ()
    segment_rapid: tuple[bool, ...] = ()
    events: tuple[ProgramEvent, ...] = ()

    def __init__(self, steps, step_mm, origin=None, tick: float = 0.0, segment=None, axes=("X", "Y"), signals=None,
                 segment_names=(), segment_rapid=(), events=()):
        st = np.asarray(steps, dtype=np.int8)
        if st.ndim != 2 or st.shape[1] != len(axes):
            raise ValueError(f"steps must have shape (N, {len(axes)}) for axes {tuple(axes)}, got {st.shape}")
        if st.size and np.abs(st).max() > 1:
            raise ValueError("a step stream holds only -1, 0 and +1")
        n_axes = len(axes)
        seg = np.zeros(len(st), dtype=int) if segment is None else np.asarray(segment, dtype=int)
        object.__setattr__(self, "steps", frozen_array(st, dtype=np.int8))
        object.__setattr__(self, "step_mm", frozen_array(np.broadcast_to(np.asarray(step_mm, float), (n_axes,))))
        object.__setattr__(self, "origin", frozen_array(np.zeros(n_axes) if origin is None else origin))
        object.__setattr__(self, "tick", float(tick))
        object.__setattr__(self, "segment", frozen_array(seg, dtype=int))
        object.__setattr__(self, "axes", tuple(axes))
        object.__setattr__(self, "signals", signals if signals is not None else Signal())
        object.__setattr__(self, "segment_names", _names(segment_names, self.segment))
        object.__setattr__(self, "segment_rapid", _rapid(segment_rapid, self.segment))
        object.__setattr__(self, "events", _events(events))

    def __len__(self) -> int:
        return len(self.steps)

    def rapid_rows(self) -> np.ndarray:
        """Per row: does it belong to a rapid segment (all False when that is not known)."""
        return _rapid_rows(self.segment_rapid, self.segment)

    def counts(self) -> np.ndarray:
        """Position in steps after each tick, relative to the origin, shape (N, n_axes)."""
        return np.cumsum(self.steps, axis=0, dtype=np.int64)

    def positions(self) -> np.ndarray:
        """Position in mm after each tick, with the origin prepended as row 0."""
        pos = self.counts() * self.step_mm + self.origin
        return np.vstack([self.origin[None, :], pos])

    def digest(self) -> str:
        return array_digest("Steps", self.steps, self.step_mm, self.origin, self.tick, self.segment, self.axes,
                            self.signals.digest(), self.segment_names,
                            *((self.segment_rapid,) if any(self.segment_rapid) else ()),
                            *((self.events,) if self.events else ()))

    def summary(self) -> dict:
        end = self.positions()[-1]
        return {
            "type": "Steps",
            "ticks": len(self),
            "steps_per_axis": np.abs(self.steps).sum(axis=0, dtype=np.int64).tolist(),
            "origin": self.origin.round(6).tolist(),
            "end": end.round(6).tolist(),
            "tick_s": self.tick,
            "signal_events": len(self.signals),
        }
