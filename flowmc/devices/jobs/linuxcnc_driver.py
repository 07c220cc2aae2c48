"""A program job on the LinuxCNC simulator: hold, resume, stop, e-stop, program stops and single block
through LinuxCNC's own task.

The program runs inside LinuxCNC's display program (display.py), so the runner's commands go to it
through the run's command file, every 20 ms: feed hold is the task's AUTO_PAUSE (the trajectory
planner decelerates along the path within the acceleration limits and keeps its position), resume
AUTO_RESUME, stop the task's abort (a stop along the path, the rest cleared) and e-stop the machine's
e-stop state; after either the spindle and the digital outputs (but the kept ones) are switched off
and DA set to 0 V. LinuxCNC's state comes back as events: ``held`` once paused at rest, a position
every 40 ms (each a job tick), the program line. Feed, rapid and spindle overrides are LinuxCNC's own
(``feedrate``, ``rapidrate``, ``spindleoverride``: the planner re-times the rest within its limits).

The program's operator stops (``pauses``) go into LinuxCNC's program after the move to their setpoint
row: M1 as M1, which LinuxCNC stops on only while its optional stop is on (set at Start and by the
job's optional-stop switch, as LinuxCNC checks it on reaching each M1); M0, M60 and M6 as M0 (this
machine's tool changer answers at once, so LinuxCNC's own M6 would not stop: the M0 is what waits for
the operator, and the job's message names the tool to load). Single block puts an M0 at every block
end (the first setpoint of each new segment), so LinuxCNC's queue runs empty and the machine rests
exactly there; those marks are in the program only when the job starts with single block on (each
brings the motion to rest, so a job without single block has none). Switched off mid-job, the job
resumes on its own at the marks still ahead; switched on in a job started without it, the job feeds
hold as it enters the next segment and says so (LinuxCNC cannot stop where its program has no stop).
A tick's place is the setpoint row the machine is at (``_reach``): the segment and G-code line of the
user's program, progress along the rows, and time left from the plan's times at the feed override.

A start at segment N hands LinuxCNC ``restart.plan_start``'s setpoints instead (``linuxcnc_restart``:
the approach, the restored outputs and spindle, then the program from N on, with its stops); a tick
on the approach names no segment, and from N on its row is read back as the user's program's row.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flowmc.devices.jobs.job import gcode_line, positions_of
from flowmc.devices.jobs.linuxcnc_restart import start_motion
from flowmc.devices.jobs.pauses import Pause, program_pauses
from flowmc.devices.log import DeviceLog, Event
from flowmc.motion.trajectory import Signal

__all__ = ["LinuxCNCDriver"]

_SENT = {"hold": ("pause", ("running",), "holding", "feed hold"),
         "resume": ("resume", ("holding", "held"), "running", "resumed"),
         "stop": ("abort", ("running", "holding", "held"), "stopping", "stopping"),
         "estop": ("estop", ("running", "holding", "held", "stopping"), "stopping", "e-stop")}


@dataclass(frozen=True)
class _Stop:
    """One stop line of LinuxCNC's program: its line number, and the program stop or block end it is."""

    line: int
    pause: Pause | None = None  # None: a single-block mark
    ended: int = -1  # a mark: the segment that ends there


class LinuxCNCDriver:
    def __init__(self, runner, card):
        self.runner, self.card, self.job = runner, card, runner.job
        self.row = 0
        self.position: tuple[float, ...] = positions_of(card.position())
        self.notes: list[Event] = []
        self.sent: list[str] = []  # commands of the driver's own (a resume past a mark)
        self.optional_stop = runner.status.optional_stop
        self.single_block = runner.status.single_block
        self.feed = 100.0
        self.paused: Pause | None = None
        self.next_stop = 0
        self.stops: list[_Stop] = []
        self.seg = np.zeros(1, dtype=np.int64)
        self.line_rows = np.zeros(1, dtype=np.int64)
        self.period = 0.0
        self.positions = np.zeros((1, 1))
        self.axes: tuple[str, ...] = ()
        self.sb_from: int | None = None  # single block switched on without marks: the segment it was in
        self.sb_ended = -1
        self.passed = -1  # the segment of the last program stop resumed from
        self.motion, self.signals = self.job.motion, self.job.signals  # what LinuxCNC runs
        self.original: np.ndarray | None = None  # a start at segment N: each row's row in the program (-1: approach)
        self.first = 0  # ... and the program's row it starts at

    # ------------------------------------------------------------------ the program
    def _program(self) -> str:
        """LinuxCNC's program with the job's stops, and the tables that read LinuxCNC's lines back."""
        card, runner = self.card, self.runner
        motion, signals = self.motion, self.signals
        self.positions, self.seg, self.period, self.axes = card.setpoint_rows(motion)
        n = len(self.positions)
        last = max(n - 1, 1)
        merged = motion.signals.merged(signals)
        rows = merged.rows(self.period, 1, last)
        own = rows[:len(motion.signals)]
        sorted_rows = np.sort(rows)
        planned: list[tuple[int, int, str, Pause | None, int]] = []
        for row, place, pause in program_pauses(motion, self.seg, sorted_rows.tolist(), own):
            if row >= n - 1:
                runner.emit("log", f"{pause.describe().split(';')[0]}: the program ends there")
                continue
            row = max(row, 1)
            before = place - int(np.searchsorted(sorted_rows, row, side="left"))
            planned.append((row, before, "M1" if pause.event.kind == "optional_pause" else "M0", pause, -1))
        if self.single_block:
            firm = {row for row, _b, code, _p, _e in planned if code == "M0"}
            for b in np.flatnonzero(np.diff(self.seg) != 0) + 1:
                if 1 <= b < n - 1 and int(b) not in firm:
                    planned.append((int(b), 0, "M0", None, int(self.seg[b - 1])))
        planned.sort(key=lambda p: (p[0], p[1]))
        lines, self.line_rows = card.program_lines(motion, signals, [(r, b, c) for r, b, c, _p, _e in planned])
        numbers = [i for i, text in enumerate(lines, 1) if text in ("M0", "M1")]
        self.stops = [_Stop(number, pause, ended) for number, (_r, _b, _c, pause, ended) in zip(numbers, planned)]
        return "\n".join(lines) + "\n"

    # ------------------------------------------------------------------ where the job is
    def _segment(self) -> int | None:
        """The segment of the move that reached the current row (a stop on a segment's first row is
        reached by the segment before it), or, resumed from a program stop, the stop's own until the
        next move."""
        seg = max(int(self.seg[min(max(self.row - 1, 0), len(self.seg) - 1)]), self.passed)
        return None if seg < 0 else seg

    def _where(self) -> str:
        return self.paused.where if self.paused is not None else self.job.where(self._segment())

    def _tick(self, **extra) -> None:
        job, n = self.job, len(self.seg)
        seg = self._segment()
        names = job.segment_names
        where, line = job.where(seg), (gcode_line(names[seg]) if seg is not None and seg < len(names) else None)
        if self.paused is not None:  # stopped for the operator: the stop's own place and line (the M0, the M6)
            seg, where, line = self.paused.event.segment, self.paused.where, self.paused.line
        if self.original is None:
            progress = self.row / (n - 1) if n > 1 else 1.0
            left = max(job.duration - self.row * self.period, 0.0) * 100.0 / self.feed
        else:  # started at segment N: progress in the user's program, time left of what LinuxCNC was given
            rows = self.original  # its last row is the program's last
            row = int(rows[min(self.row, len(rows) - 1)])
            if row < 0:
                seg, line, where = None, None, f"approach to {job.where(self.runner.start_at)}"
            progress = max(row, self.first) / max(int(rows[-1]), 1)
            left = max((n - 1 - self.row) * self.period, 0.0) * 100.0 / self.feed
        self.runner.emit("tick", **{"commanded": self.position, "actual": None, "segment": seg, "where": where,
                                    "line": line, "progress": progress, "time_left": left, **extra})

    # ------------------------------------------------------------------ commands and events
    def commands(self) -> list[str]:
        out, self.sent = self.sent, []
        runner = self.runner
        for name, value in runner.take_commands():
            if name in ("feed", "rapid", "spindle"):  # checked by the runner: feed 10-200, rapid 25/50/100 %
                out.append(f"{name} {float(value):g}")
                if name == "feed":
                    self.feed = float(value)
                runner.emit("log", f"{name} override {value:g} %", **{name: float(value)})
            elif name == "optional_stop":
                self.optional_stop = bool(value)
                out.append(f"optional_stop {int(self.optional_stop)}")
                runner.emit("log", f"optional stop (M1) {'on' if value else 'off'}", optional_stop=bool(value))
            elif name == "single_block":
                self._single_block(bool(value))
            elif name in _SENT:
                sent, when, state, said = _SENT[name]
                if runner.state in when:
                    out.append(sent)
                    where = self._where()
                    if name == "resume" and self.paused is not None:
                        self.passed, self.paused = self.paused.event.segment, None
                    runner.set_state(state, f"{said} at {where}")
                    self.notes.append(Event("job", 0.0, "", f"{name} at {where}"))
            else:
                runner.emit("log", f"{name} is not passed to LinuxCNC: ignored")
        return out

    def _single_block(self, on: bool) -> None:
        self.single_block = on
        marks = any(s.pause is None for s in self.stops)
        said = f"single block {'on' if on else 'off'}"
        if on and not marks:
            self.sb_from = self._segment() if self._segment() is not None else -1
            said += (": this job started without it, so LinuxCNC's program has no stops at block ends; the job "
                     "feeds hold as it enters the next segment")
        elif not on:
            self.sb_from = None
        self.runner.emit("log", said, single_block=on)
        self.notes.append(Event("job", 0.0, "", f"{said} at {self._where()}"))

    def _stopped(self, line: int) -> None:
        """LinuxCNC paused by itself (its motion line ``line``): the program stop or block end it is on."""
        runner, stop = self.runner, None
        while stop is None and self.next_stop < len(self.stops):
            ahead = self.stops[self.next_stop]
            self.next_stop += 1
            if ahead.line > line and (ahead.pause is None or ahead.pause.stops(self.optional_stop)):
                stop = ahead
        if stop is None:
            runner.set_state("held", f"LinuxCNC paused at {self._where()}")
            return
        if stop.pause is None:
            where = self.job.where(stop.ended)
            if self.single_block:
                runner.set_state("held", f"single block: held at the end of {where}")
            else:
                self.sent.append("resume")
                runner.emit("log", f"single block is off: runs on past the end of {where}")
            return
        self.paused = stop.pause
        text = stop.pause.describe()
        self.notes.append(Event("pause", 0.0, "", text))
        self._tick()  # the stop's own place and line
        runner.set_state("held", text)

    def on_event(self, event: dict) -> None:
        runner, kind = self.runner, event.get("kind")
        if "line" in event and "position" in event:  # a position event, or held at rest
            line = int(event["line"])
            self._reach(int(self.line_rows[min(max(line, 0), len(self.line_rows) - 1)]), event["position"])
        if "position" in event:
            self.position = self._cols(event["position"])
        if kind == "position":
            self._tick()
            self._single_block_without_marks()
        elif kind == "state" and event.get("state") == "held":
            self._tick()  # where it rests (the last position event may be 40 ms old)
            if runner.state == "holding":
                if self.sb_from is not None and self.single_block:
                    runner.set_state("held", f"single block: held just past the end of {self.job.where(self.sb_ended)} "
                                             "(LinuxCNC's program has no stop there)")
                else:
                    runner.set_state("held", f"held at {self._where()}")
            elif runner.state == "running":
                self._stopped(int(event.get("line", 0)))
        elif kind == "state" and event.get("state") == "safe":
            runner.emit("log", f"outputs left safe: {self.job.safe.describe()}")

    def _single_block_without_marks(self) -> None:
        seg = self._segment()
        if (self.sb_from is not None and self.single_block and self.runner.state == "running"
                and seg is not None and seg != self.sb_from):
            self.sb_ended, self.sb_from = self.sb_from, seg
            self.sent.append("pause")
            self.runner.set_state("holding", f"single block: feed hold on entering {self.job.where(seg)}")

    def _reach(self, upto: int, xyz) -> None:
        """The row the machine is at: LinuxCNC's motion line names the last row of the move it runs, and
        its planner joins straight runs of setpoint lines into one move (the line then leads the machine
        by up to a second), so within that run the row is the setpoint nearest LinuxCNC's position."""
        lo = min(self.row, upto)
        if upto <= lo + 1:
            self.row = upto
            return
        here = np.asarray([xyz["XYZ".index(a.upper())] for a in self.axes], dtype=float)
        window = self.positions[lo:upto + 1]
        self.row = lo + int(np.argmin(np.linalg.norm(window - here, axis=1)))

    def _cols(self, xyz) -> tuple[float, ...]:
        return positions_of([xyz["XYZ".index(a.upper())] for a in self.job.machine.names])

    def run(self) -> DeviceLog:
        runner, job = self.runner, self.job
        if runner.start_at is not None:  # the approach and the program from segment N on (linuxcnc_restart)
            self.motion, self.original, assumptions = start_motion(job, self.card, runner.start_at)
            self.signals = Signal()
            self.first = int(self.original[self.original >= 0].min())
            runner.assumptions = ([runner.line_note] if runner.line_note else []) + assumptions
            for text in runner.assumptions:
                runner.emit("log", text)
                self.notes.append(Event("restart", 0.0, "", text))
        runner.emit("tick", commanded=self.position, actual=None)
        gcode = self._program()
        log = self.card.run_gcode(gcode, name="trajectory.ngc", commands=self.commands, on_event=self.on_event,
                                  keep_on=tuple(self.job.safe.keep_on), optional_stop=self.optional_stop)
        for change in log.changes:
            runner.emit("io", change=change)
        end = positions_of(log.position[-1]) if len(log.position) else self.position
        if log.outcome == "done":
            runner.emit("tick", commanded=end, actual=None, progress=1.0, time_left=0.0, t=float(log.duration))
            return log.amended(events=self.notes)
        said = "e-stop" if log.outcome == "estop" else "stopped by the operator"
        message = f"{said} at {self._where()}; outputs left safe: {self.job.safe.describe()}"
        runner.emit("tick", commanded=end, actual=None, t=float(log.duration))
        runner.message = message
        runner.set_state("aborted", message)
        return log.amended(events=[*self.notes, Event("stop", float(log.duration), "", message)])
