"""A job on any motion card, through the ``MotionCard`` interface: the whole operation at once.

This is how a card without a streaming driver of its own runs a job (a backend someone registered),
and how the simulated card runs on the instant pace. There is nothing to hold or override while the
card works: commands given meanwhile have nothing to act on. An operation that ends other than
done (a limit, an e-stop, an alarm) leaves the outputs safe and faults the job.
"""

from __future__ import annotations

from flowmc.devices.jobs.job import positions_of
from flowmc.devices.log import Change, DeviceLog, Event
from flowmc.errors import DeviceError, LimitError

__all__ = ["InstantDriver", "stop_message"]


def stop_message(job, log: DeviceLog) -> str:
    """``the jog of X ended with soft_limit: X stopped at its soft limit max 200 mm``."""
    what = [e.message for e in log.events if e.kind in ("limit", "soft_limit", "estop", "home_failed", "error")]
    name = {"home": "homing", "jog": f"the jog of {job.args[0]}" if job.args else "the jog",
            "io": "setting outputs", "program": "the program"}[job.operation]
    return f"{name} ended with {log.outcome}" + (": " + "; ".join(what) if what else "")


class InstantDriver:
    def __init__(self, runner, card):
        self.runner, self.card, self.job = runner, card, runner.job

    def outputs(self) -> dict:
        """What the DRO's I/O lamps show (the card's status as it reports it)."""
        status = self.card.status()
        return {k: status[k] for k in ("outputs", "spindle_rpm", "tool_down") if k in status}

    def make_safe(self) -> list[Change]:
        """Spindle off, DA 0 V, every digital output off but the kept ones (what the card lets us set)."""
        card, changes = self.card, []
        steps = [lambda: card.set_spindle(0.0), lambda: card.set_da(0.0)]
        steps += [lambda ch=ch: card.set_output(ch, False) for ch in range(1, card.ranges.outputs + 1)
                  if ch not in self.job.safe.keep_on]
        for step in steps:
            try:
                changes += list(step().changes)
            except (LimitError, DeviceError):
                continue  # an output this card does not have is not on
        return changes

    def run(self) -> DeviceLog:
        runner, card, job = self.runner, self.card, self.job
        here = positions_of(card.position())
        runner.emit("tick", commanded=here, actual=here, outputs=self.outputs())
        if job.operation == "program":
            log = card.run(job.motion, job.signals, check=False)  # pre-flighted when the job was prepared
        elif job.operation == "home":
            log = card.home(*job.args)
        elif job.operation == "jog":
            log = card.jog(*job.args)
        else:
            log = self._io()
        for change in log.changes:
            runner.emit("io", change=change)
        if log.outcome != "done":
            safe = self.make_safe()
            log = log.amended(safe, [Event("safe", log.t[-1] if len(log.t) else 0.0, "",
                                           f"outputs left safe: {job.safe.describe()}")], state=card.state()
                              if hasattr(card, "state") else None)
        end = positions_of(log.position[-1]) if len(log.position) else here
        runner.emit("tick", commanded=end, actual=end, progress=1.0, time_left=0.0, t=float(log.duration),
                    outputs=self.outputs())
        if log.outcome != "done":
            err = DeviceError(stop_message(job, log), where=job.device)
            err.log = log
            raise err
        return log

    def _io(self) -> DeviceLog:
        card = self.card
        changes, events = [], []
        for kind, ch, value, freq in self.job.args:
            if kind == "dout":
                done = card.set_output(int(ch), bool(value))
            elif kind == "pwm_duty":
                done = card.set_pwm(freq, value)
            elif kind == "da":
                done = card.set_da(value)
            else:
                done = card.set_spindle(value)
            changes += done.changes
            events += done.events
        self.runner.extra["inputs"] = sum(1 << (ch - 1) for ch, on in card.read_inputs().items() if on)
        now = card.snapshot()
        return DeviceLog(now.device, now.axes, now.period, now.t, now.steps, now.position, now.following_error,
                         changes, events, now.outcome, now.state)
