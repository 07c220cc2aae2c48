"""A program job on the LinuxCNC simulator: hold, resume, stop and e-stop through LinuxCNC's own task.

The program runs inside LinuxCNC's display program (display.py), so the runner's commands go to it
through the run's command file, every 20 ms: feed hold is the task's AUTO_PAUSE (the trajectory
planner decelerates along the path within the acceleration limits and keeps its position), resume
AUTO_RESUME, stop the task's abort (a stop along the path, the rest cleared) and e-stop the machine's
e-stop state; after either the spindle and the digital outputs (but the kept ones) are switched off
and DA set to 0 V. LinuxCNC's state comes back as events: ``held`` once paused at rest, a position
every 40 ms (each a job tick), the program line. Feed, rapid and spindle overrides are LinuxCNC's own
(``feedrate``, ``rapidrate``, ``spindleoverride``: the planner re-times the rest within its limits).
Program stops and single block are not passed on yet: a job with them is refused at Start (drivers.py).
A start at segment N runs the approach and the program from there (``linuxcnc_restart``); LinuxCNC's
program lines are named back as the user's segment, G-code line and progress in every tick.
"""

from __future__ import annotations

from flowmc.devices.jobs.job import positions_of
from flowmc.devices.jobs.linuxcnc_restart import ProgramRows, start_motion
from flowmc.devices.log import DeviceLog, Event

__all__ = ["LinuxCNCDriver"]

_SENT = {"hold": ("pause", ("running",), "holding", "feed hold"),
         "resume": ("resume", ("holding", "held"), "running", "resumed"),
         "stop": ("abort", ("running", "holding", "held"), "stopping", "stopping"),
         "estop": ("estop", ("running", "holding", "held", "stopping"), "stopping", "e-stop")}


class LinuxCNCDriver:
    def __init__(self, runner, card):
        self.runner, self.card, self.job = runner, card, runner.job
        self.line = 0
        self.position: tuple[float, ...] = positions_of(card.position())
        self.notes: list[Event] = []

    def _cols(self, xyz) -> tuple[float, ...]:
        return positions_of([xyz["XYZ".index(a.upper())] for a in self.job.machine.names])

    def commands(self) -> list[str]:
        out = []
        for name, value in self.runner.take_commands():
            if name in ("feed", "rapid", "spindle"):  # checked by the runner: feed 10-200, rapid 25/50/100 %
                out.append(f"{name} {float(value):g}")
                self.runner.emit("log", f"{name} override {value:g} %", **{name: float(value)})
                continue
            if name not in _SENT:
                self.runner.emit("log", f"{name} is not passed to LinuxCNC yet: ignored")
                continue
            sent, when, state, said = _SENT[name]
            if self.runner.state in when:
                out.append(sent)
                self.runner.set_state(state, f"{said} at line {self.line}")
                self.notes.append(Event("job", 0.0, "", f"{name} at line {self.line}"))
        return out

    def on_event(self, event: dict) -> None:
        runner, kind = self.runner, event.get("kind")
        if kind in ("position", "progress", "state") and "line" in event:
            self.line = int(event["line"])
        if "position" in event:
            self.position = self._cols(event["position"])
        if kind == "position":
            runner.emit("tick", commanded=self.position, actual=None, where=f"line {self.line}",
                        **self.rows.at(self.line))
        elif kind == "state" and event.get("state") == "held" and runner.state == "holding":
            runner.set_state("held", f"held at line {self.line}")
        elif kind == "state" and event.get("state") == "safe":
            runner.emit("log", f"outputs left safe: {self.job.safe.describe()}")

    def run(self) -> DeviceLog:
        runner, job = self.runner, self.job
        motion, signals, original = job.motion, job.signals, None
        if runner.start_at is not None:  # the approach and the program from the segment on (linuxcnc_restart)
            motion, original, assumptions = start_motion(job, self.card, runner.start_at)
            signals = None
            runner.assumptions = ([runner.line_note] if runner.line_note else []) + assumptions
            for text in runner.assumptions:
                runner.emit("log", text)
                self.notes.append(Event("restart", 0.0, "", text))
        self.rows = ProgramRows(self.card, motion, signals, original, job.motion, job.segment_names)
        runner.emit("tick", commanded=self.position, actual=None)
        log = self.card.run(motion, signals, check=False, commands=self.commands,
                            on_event=self.on_event, keep_on=tuple(self.job.safe.keep_on))
        for change in log.changes:
            runner.emit("io", change=change)
        end = positions_of(log.position[-1]) if len(log.position) else self.position
        if log.outcome == "done":
            runner.emit("tick", commanded=end, actual=None, progress=1.0, time_left=0.0, t=float(log.duration))
            return log.amended(events=self.notes)
        said = "e-stop" if log.outcome == "estop" else "stopped by the operator"
        message = f"{said} at line {self.line}; outputs left safe: {self.job.safe.describe()}"
        runner.emit("tick", commanded=end, actual=None, t=float(log.duration))
        runner.message = message
        runner.set_state("aborted", message)
        return log.amended(events=[*self.notes, Event("stop", float(log.duration), "", message)])
