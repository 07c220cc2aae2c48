"""A job: one prepared, pre-flighted operation for one device, and what a running job reports.

A device node does not move anything when a graph runs: it prepares a ``Job`` (the program, its
signals, the device and its options, pre-flighted against the machine) and only an explicit Start
hands that job to a ``JobRunner``. A job is a value: the same inputs give the same ``digest()``,
so the editor can tell a prepared job from a stale one.
"""

from __future__ import annotations

import hashlib
import json
import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from flowmc.devices.backends import DeviceOptions
from flowmc.devices.preflight import PreflightReport
from flowmc.errors import DeviceError
from flowmc.motion.machine import Machine
from flowmc.motion.path import describe_segment
from flowmc.motion.trajectory import Signal, Steps, Trajectory

__all__ = ["Job", "SafeOutputs", "wait_name", "JobStatus", "JobEvent", "STATES", "ACTIVE", "FINAL", "OPERATIONS",
           "gcode_line"]

#: queued: made, not started; running; holding: decelerating to a feed hold; held: at rest on the path;
#: stopping: decelerating to a controlled stop; aborted: stopped (stop or e-stop), the rest cleared;
#: done: ran to the end; faulted: the device stopped it (a limit, an alarm, a lost port, an error).
STATES = ("queued", "running", "holding", "held", "stopping", "aborted", "done", "faulted")
ACTIVE = ("running", "holding", "held", "stopping")
FINAL = ("aborted", "done", "faulted")
OPERATIONS = ("program", "home", "jog", "io", "wait")

_LINE = re.compile(r":(\d+)$")


def gcode_line(name: str) -> int | None:
    """The G-code line a segment came from (``"part.ngc:12"`` -> 12), or None."""
    m = _LINE.search(name or "")
    return int(m.group(1)) if m else None


def wait_name(args: tuple) -> str:
    """How a wait job names what it waits for: ``input 3 (clamp) on``."""
    channel, closed, _timeout, label, _required = args
    return f"input {channel}{f' ({label})' if label else ''} {'on' if closed else 'off'}"


@dataclass(frozen=True)
class SafeOutputs:
    """What an abort, e-stop or fault leaves the outputs at: spindle off, PWM duty 0, DA 0 V, the tool
    (pen) up and every digital output off except ``keep_on`` (outputs the machine needs on when stopped,
    e.g. a brake release or a clamp)."""

    keep_on: tuple[int, ...] = ()

    def describe(self) -> str:
        kept = f"; outputs {', '.join(map(str, self.keep_on))} stay on" if self.keep_on else ""
        return "spindle off, PWM 0 %, DA 0 V, pen up, digital outputs off" + kept


@dataclass(frozen=True, eq=False)
class Job:
    """A prepared operation for ``device`` (a spec string) on ``machine``.

    ``operation``: ``program`` (``motion`` with ``signals``), ``home`` (``args`` = axes, method),
    ``jog`` (axis, distance, speed), ``io`` (a tuple of (kind, channel, value) to set at once) or ``wait``
    (input channel, closed, timeout s, what the input is, whether a timeout is a fault: wait until the
    input is at that level).
    ``options``: the device's options (closed loop, pen output, ...; ``resume`` is filled at Start from the
    log of the operation before). ``report``: the pre-flight.
    ``name``: what the user calls it (the graph node that prepared it).
    """

    device: str
    machine: Machine
    operation: str = "program"
    motion: Trajectory | Steps | None = None
    signals: Signal = field(default_factory=Signal)
    args: tuple = ()
    options: DeviceOptions = field(default_factory=DeviceOptions)
    safe: SafeOutputs = field(default_factory=SafeOutputs)
    report: PreflightReport | None = None
    name: str = ""

    def __post_init__(self):
        if self.operation not in OPERATIONS:
            raise ValueError(f"unknown job operation {self.operation!r}; known: {', '.join(OPERATIONS)}")
        if (self.operation == "program") != (self.motion is not None):
            raise ValueError("a program job needs motion, other jobs none")

    @property
    def segment_names(self) -> tuple[str, ...]:
        return self.motion.segment_names if self.motion is not None else ()

    @property
    def duration(self) -> float:
        """Planned seconds (a program's own timing; 0 when the device paces it or for other operations)."""
        if isinstance(self.motion, Trajectory):
            return self.motion.duration
        if isinstance(self.motion, Steps):
            return len(self.motion) * self.motion.tick
        return 0.0

    def where(self, segment: int | None) -> str:
        """How the user names a place in the job: ``segment 5 (part.ngc:12)``, or the operation."""
        if segment is None or segment < 0 or self.motion is None:
            return self.operation if self.operation != "program" else "approach"
        return describe_segment(int(segment), self.segment_names)

    def segment_at_line(self, line: int) -> tuple[int, str]:
        """The segment (0-based) a start at G-code line ``line`` starts from, and what that assumes: the
        line's first segment, or, for a line without motion of its own (a comment, an M-code), the first
        segment of a later line. DeviceError when no segment comes from that line or after it."""
        lines = [gcode_line(name) for name in self.segment_names]
        later = [(ln, i) for i, ln in enumerate(lines) if ln is not None and ln >= line]
        if not later:
            known = [ln for ln in lines if ln is not None]
            raise DeviceError(f"no motion at G-code line {line} or after it" + (
                f" (the program's segments come from lines {min(known)}-{max(known)})" if known else
                " (the program's segments carry no G-code lines)"), where=self.name or "job")
        first, seg = min(later)
        at = describe_segment(seg, self.segment_names)
        if first != line:
            return seg, f"G-code line {line} has no motion of its own: started at line {first}, {at}"
        return seg, f"G-code line {line} is {at}"

    def describe(self) -> str:
        what = {"program": f"a {type(self.motion).__name__} program of {self.duration:.2f} s"
                           + (f" ({len(self.segment_names)} segments)" if self.segment_names else ""),
                "home": "homing", "jog": "a jog", "io": "setting outputs",
                "wait": f"waiting for {wait_name(self.args)}" if self.operation == "wait" else ""}[self.operation]
        return f"{what} on {self.device}" + (f" from node {self.name!r}" if self.name else "")

    def digest(self) -> str:
        h = hashlib.blake2b(digest_size=16)
        for part in (self.device, self.machine.model_dump_json(), self.operation,
                     self.motion.digest() if self.motion is not None else "", self.signals.digest(),
                     json.dumps(self.args, default=str), repr(self.options), repr(self.safe)):
            h.update(part.encode())
            h.update(b"\0")
        return h.hexdigest()

    def summary(self) -> dict:
        return {"type": "Job", "device": self.device, "operation": self.operation, "duration_s": round(self.duration, 6),
                "segments": len(self.segment_names), "name": self.name}


@dataclass(frozen=True)
class JobStatus:
    """A running job at one moment: what the DRO, the progress bar and the log show.

    ``commanded``/``actual`` are mm per machine axis (``actual`` None where the device has no feedback
    of its own); ``segment`` is 0-based (None before the program, e.g. on the approach); ``where`` names
    it as the user counts; ``progress`` 0..1; ``time_left`` in s at the current overrides (None when
    unknown); overrides in %; ``outputs``: spindle rpm, digital outputs on, tool down, PWM, DA.
    """

    state: str = "queued"
    t: float = 0.0
    axes: tuple[str, ...] = ()
    commanded: tuple[float, ...] = ()
    actual: tuple[float, ...] | None = None
    segment: int | None = None
    where: str = ""
    line: int | None = None
    progress: float = 0.0
    time_left: float | None = None
    feed: float = 100.0
    rapid: float = 100.0
    spindle: float = 100.0
    single_block: bool = False
    optional_stop: bool = False
    outputs: dict = field(default_factory=dict)
    message: str = ""

    @property
    def following_error(self) -> tuple[float, ...] | None:
        if self.actual is None:
            return None
        return tuple(float(c - a) for c, a in zip(self.commanded, self.actual))

    def as_dict(self) -> dict:
        out = {k: getattr(self, k) for k in self.__dataclass_fields__}
        out["following_error"] = self.following_error
        return out


@dataclass(frozen=True)
class JobEvent:
    """What a job tells its listeners: ``state`` (a new state), ``tick`` (position and progress, at
    20 Hz or more while it runs), ``io`` (an output or input changed: ``change``), ``fault``, ``log``."""

    kind: str
    status: JobStatus
    message: str = ""
    change: Any = None


def positions_of(values) -> tuple[float, ...]:
    return tuple(float(v) for v in np.asarray(values, dtype=float).reshape(-1))
