"""Making jobs (what a device node does when its graph runs) and starting them (what Start does).

Preparing checks everything that can be checked without a connection: the pre-flight against the
machine and the card's ranges, and what the card refuses of a program's signals (the card is made,
not connected: nothing is opened, nothing moves). Starting hands the job to a ``JobRunner`` with the
Start's options (pace, speed, start from a segment, single block, initial overrides), tells the Start's
hook about the runner (the editor's controls, the CLI's progress bar), runs it, and turns a stop or a
fault into a ``DeviceError`` that says where it stopped.
"""

from __future__ import annotations

import math
from typing import Any

from flowmc.devices.backends import DeviceOptions, check_spec, unconnected
from flowmc.devices.card import HOME_METHODS
from flowmc.devices.jobs.job import Job, SafeOutputs
from flowmc.devices.jobs.runner import JobRunner
from flowmc.devices.log import DeviceLog
from flowmc.errors import DeviceError
from flowmc.motion.machine import Machine
from flowmc.motion.trajectory import Signal, Steps, Trajectory

__all__ = ["program_job", "home_job", "jog_job", "io_job", "wait_job", "start_job", "START_OPTIONS"]

#: What ``Start.options`` may hold for jobs: pace ("instant", "realtime", "virtual"), speed (factor of
#: real time for the simulated card), start_at ({node id: segment number from 1}), single_block,
#: start_line ({node id: G-code line}), optional_stop (M1 stops the job),
#: feed / rapid / spindle (initial overrides, %), tick_hz (position events per second), record.
START_OPTIONS = ("pace", "speed", "start_at", "start_line", "single_block", "optional_stop", "feed", "rapid", "spindle",
                 "tick_hz", "record")


def program_job(device: str, machine: Machine, motion: Trajectory | Steps, signals: Signal | None = None,
                options: DeviceOptions | None = None, *, safe: SafeOutputs | None = None, name: str = "") -> Job:
    """A program checked against the machine and the card (``LimitError``/``DeviceError`` naming where)."""
    options = options or DeviceOptions()
    card = unconnected(device, machine, options)
    report = card.check_program(motion, signals)
    return Job(device.strip(), machine, "program", motion, signals if signals is not None else Signal(),
               options=options, safe=safe or SafeOutputs(), report=report, name=name)


def home_job(device: str, machine: Machine, axes: tuple[str, ...] | None, method: str,
             options: DeviceOptions | None = None, *, name: str = "") -> Job:
    check_spec(device)
    if method not in HOME_METHODS:
        raise DeviceError(f"unknown homing method {method!r}; known: {', '.join(HOME_METHODS)}", where=name or device)
    unknown = [a for a in axes or () if a not in machine.names]
    if unknown:
        raise DeviceError(f"no axis {', '.join(unknown)}; axes: {', '.join(machine.names)}", where=name or device)
    return Job(device.strip(), machine, "home", args=(axes, method), options=options or DeviceOptions(), name=name)


def jog_job(device: str, machine: Machine, axis: str, distance: float, speed: float,
            options: DeviceOptions | None = None, *, name: str = "") -> Job:
    check_spec(device)
    if axis not in machine.names:
        raise DeviceError(f"no axis {axis!r}; axes: {', '.join(machine.names)}", where=name or device)
    if not (math.isfinite(distance) and speed > 0):
        raise DeviceError(f"a jog needs a finite distance and a speed > 0, got {distance}, {speed}", where=name or device)
    return Job(device.strip(), machine, "jog", args=(axis, float(distance), float(speed)),
               options=options or DeviceOptions(), name=name)


def io_job(device: str, machine: Machine, signals: Signal, options: DeviceOptions | None = None, *,
           name: str = "") -> Job:
    """Outputs to set at once, in time order (times ignored): a PWM duty needs a frequency before it."""
    check_spec(device)
    kinds = signals.kind.tolist()
    if "tool" in kinds:
        raise DeviceError("a tool (pen) event goes with a program: send it with Card output", where=name or device)
    settings, freq = [], None
    for kind, ch, value in zip(kinds, signals.channel.tolist(), signals.value.tolist()):
        if kind == "pwm_freq":
            freq = float(value)
            continue
        if kind == "pwm_duty" and freq is None:
            raise DeviceError("a PWM duty needs a PWM frequency before it (use the PWM node)", where=name or device)
        settings.append((kind, int(ch), float(value), freq))
    return Job(device.strip(), machine, "io", args=tuple(settings), options=options or DeviceOptions(), name=name)


def wait_job(device: str, machine: Machine, channel: int, closed: bool, timeout: float, label: str = "",
             options: DeviceOptions | None = None, *, required: bool = True, name: str = "") -> Job:
    """Wait at Start until digital input ``channel`` is ``closed`` (or open), at most ``timeout`` s; a
    timeout faults the job when ``required``, else the job ends done and says the input did not come."""
    if not (math.isfinite(timeout) and timeout >= 0):
        raise DeviceError(f"a wait needs a finite timeout >= 0 s, got {timeout}", where=name or device)
    unconnected(device, machine, options)  # the simulated world's inputs are checked as the card is made
    return Job(device.strip(), machine, "wait", args=(int(channel), bool(closed), float(timeout), label.strip(), bool(required)),
               options=options or DeviceOptions(), name=name)


def start_job(job: Job, after: DeviceLog | None, start: Any, node_id: str) -> JobRunner:
    """Run ``job`` under an explicit Start (``flowmc.runtime.Start``, or None: instant, no hook); the
    runner when it ended as it should. A stop or a fault raises DeviceError naming where; its ``.log``
    is what the device did."""
    options = dict(getattr(start, "options", None) or {})
    unknown = sorted(set(options) - set(START_OPTIONS))
    if unknown:
        raise DeviceError(f"unknown start option(s) {unknown}; known: {', '.join(START_OPTIONS)}", where=node_id)
    segment = (options.get("start_at") or {}).get(node_id)
    line = (options.get("start_line") or {}).get(node_id)
    runner = JobRunner(job, after=after, pace=options.get("pace", "instant"), speed=float(options.get("speed", 1.0)),
                       start_at=None if segment is None else int(segment) - 1,
                       single_block=bool(options.get("single_block", False)),
                       optional_stop=bool(options.get("optional_stop", False)),
                       start_line=None if line is None else int(line),
                       tick_hz=float(options.get("tick_hz", 50.0)), record=bool(options.get("record", False)))
    overrides = {k: float(options[k]) for k in ("feed", "rapid", "spindle") if options.get(k) is not None}
    if overrides:
        runner.set_overrides(**overrides)
    hook = getattr(start, "on_job", None)
    if hook is not None:
        hook(node_id, runner)
    log = runner.run()
    if runner.state == "aborted":
        err = DeviceError(runner.message, where=node_id)
        err.log = log
        raise err
    return runner
