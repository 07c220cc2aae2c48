"""A program job on a GRBL board, through its real-time bytes.

The program streams with character counting (``GrblStreamer.stream``) while the driver polls status
with ``?`` at 10 Hz and, between reads, turns the runner's commands into GRBL's real-time bytes:
feed hold ``!``, resume ``~``, and the override bytes (feed 0x90 reset to 100 %, 0x91/0x92 +-10 %,
0x93/0x94 +-1 %; rapid 0x95/0x96/0x97 for 100/50/25 %; spindle 0x99 reset, 0x9A-0x9D steps). A stop
is a feed hold and, once GRBL reports ``Hold:0`` (at rest on the path, position kept), a soft reset
(Ctrl-X), which clears the rest of the job and switches spindle and coolant off. The e-stop is the
soft reset at once: GRBL stops without deceleration and, as it was moving, loses its position
(ALARM:3; home or unlock before the next job). Each status report is a tick: GRBL's machine position
(its own setpoint; it has no encoder), the line it is executing (lines acknowledged minus the blocks
still in its planner, with its segment, G-code line and progress in the user's program), the overrides
and the spindle/coolant state it reports. A start at segment N streams the approach and the program
from there (``grbl_restart``).

Single block is not a GRBL feature, so the driver single-steps as senders do: a block is the lines
of one program segment (``_block_starts``). With single block on, only the current block is
streamed; once all its lines are acknowledged and a status report taken after the last ``ok`` says
Idle with an empty planner, the job is ``held`` at the block's end point ("single block: held at the
end of segment ...") and Resume streams the next block. Switched on mid-job, streaming stops at the
first block boundary not yet sent: the lines already in GRBL's buffers run, and the job holds at the
end of the block of the last line sent (with 15 planner blocks and 128 bytes buffered, possibly some
blocks after the one moving when the switch came). Switched off while held, Resume streams the rest.
Stop from a single-block hold is the soft reset at once (GRBL is Idle, at rest: no alarm).
"""

from __future__ import annotations

import time

import numpy as np

from flowmc.devices.grbl_program import motion_gcode, program_rows
from flowmc.devices.jobs.grbl_restart import grbl_start
from flowmc.devices.jobs.job import gcode_line, positions_of
from flowmc.devices.log import DeviceLog, Event
from flowmc.errors import DeviceError

__all__ = ["GrblDriver", "override_bytes"]

PLANNER_BLOCKS = 15
POLL = 0.1  # s between ``?`` status requests while a job runs (10 Hz; the issue asks for 5 Hz or more)


class _Ended(Exception):
    def __init__(self, state: str, message: str):
        super().__init__(message)
        self.state, self.message = state, message


def override_bytes(kind: str, now: float, want: float) -> bytes:
    """The real-time bytes that take GRBL's ``kind`` override from ``now`` to ``want`` (%)."""
    if kind == "rapid":
        return {100: b"\x95", 50: b"\x96", 25: b"\x97"}[int(want)]
    reset, up10, down10, up1, down1 = (0x90, 0x91, 0x92, 0x93, 0x94) if kind == "feed" else (0x99, 0x9A, 0x9B, 0x9C, 0x9D)
    out = bytearray([reset])
    step = int(round(want)) - 100
    out += bytes([up10 if step > 0 else down10]) * (abs(step) // 10)
    out += bytes([up1 if step > 0 else down1]) * (abs(step) % 10)
    return bytes(out)


class GrblDriver:
    def __init__(self, runner, card):
        self.runner, self.card, self.job = runner, card, runner.job
        self.overrides = {"feed": 100.0, "rapid": 100.0, "spindle": 100.0}
        self.lines: list = []
        self.ended: _Ended | None = None
        self.paused: str | None = None  # the program stop GRBL is paused on (its line's source)
        self._reports = 0
        self.until: int | None = None  # single block: the lines sent up to this one (its block's first)
        self.block_held = False  # held at a block's end by single block (GRBL Idle, nothing queued)
        self._acked_report: int | None = None  # reports seen when the block's last line was acknowledged

    def run(self) -> DeviceLog:
        card, job, runner = self.card, self.job, self.runner
        streamer = card.streamer
        self.events: list[Event] = []
        optional_stop = runner.status.optional_stop
        _pos, _dt, self.segment, *_ = program_rows(job.motion, card.machine, job.signals)
        self.first_row = 0
        if runner.start_at is None:
            self.lines = motion_gcode(job.motion, card.machine, job.signals, card.tolerance, card.pen,
                                      optional_stop=optional_stop)
        else:  # the state at the segment rebuilt, a safe approach, then the program from there
            self.lines, assumptions = grbl_start(job, card, runner.start_at, streamer.status(), optional_stop)
            self.first_row = int(np.flatnonzero(self.segment == runner.start_at)[0])
            runner.assumptions = ([runner.line_note] if runner.line_note else []) + assumptions
            for text in runner.assumptions:
                runner.emit("log", text)
                self.events.append(Event("restart", 0.0, "", text))
        self.stops = {i for i, line in enumerate(self.lines) if line.text == "M0"}
        self.blocks = self._block_starts()
        self.single_block = runner.status.single_block
        if self.single_block:
            self.until = self._next_block(1)
        streamer.poll = min(streamer.poll, POLL)
        try:
            st = streamer.stream(self.lines, control=self._control, until=lambda: self.until)
        except _Ended as end:
            return self._finish(end)
        except DeviceError as err:  # an error, an alarm or a lost port: the streamer has stopped GRBL
            stream = getattr(err, "stream", None)
            if stream is not None:
                err.log = card._log(stream, "alarm" if "ALARM" in err.message else "error")
            raise
        self._tick(st, final=True)
        return card._log(st, "done", [*self.events, Event("done", st.reports[-1][0] if st.reports else 0.0, "",
                                                          f"{st.acked} lines acknowledged")])

    # ------------------------------------------------------------------ between reads
    def _control(self, st) -> None:
        self.st = st
        if len(st.reports) != self._reports:
            self._reports = len(st.reports)
            self._tick(st)
        for name, value in self.runner.take_commands():
            self._command(name, value, st)
        state = st.status.get("state", "")
        if self.runner.state == "holding" and state.startswith("Hold:0"):
            self.runner.set_state("held", f"held at {self._where(st)}")
        elif self.runner.state == "running" and state.startswith("Hold:0") and st.acked - 1 in self.stops:
            self.stops.discard(st.acked - 1)  # once: a report from before the resume still says Hold:0
            self.paused = self.lines[st.acked - 1].source  # GRBL paused on the program's M0 (its last line taken)
            text = f"{self.paused}; Resume carries on"
            self.events.append(Event("pause", self._t(st), "", text))
            self._tick(st)
            self.runner.set_state("held", text)
        elif self.runner.state == "stopping" and (state.startswith("Hold:0") or self._block_done(st)):
            self.card.streamer.soft_reset()  # at rest: the reset keeps the position and clears the rest
            raise _Ended("aborted", f"stopped by the operator at {self._where(st)}")
        elif self.runner.state in ("running", "holding") and self._block_done(st):  # a hold as the block ended
            self.block_held = True
            end = self.until
            assert end is not None  # _block_done: only while single block holds lines back
            seg = self.line_segment[end - 1]
            text = f"single block: held at the end of {self.job.where(seg)}"
            self.events.append(Event("pause", self._t(st), "", text))
            self._tick(st)
            self.runner.set_state("held", text)

    # ------------------------------------------------------------------ single block
    def _block_starts(self) -> list[int]:
        """The first line of each block after the first, and each line's segment (``self.line_segment``).

        A move's segment is that of the row before the one it ends at (the end row is the next move's
        start row, the last row for the last move; a planned segment's first row has already left its
        start, so a move ending there finishes the segment before, as the simulated card's block end
        does); a signal's or stop's code has the segment of the row it is given at (it comes after the
        move ending there). The preamble and a start's approach (row -1) go with the first block."""
        segs: list[int | None] = [None] * len(self.lines)
        end = len(self.segment) - 1
        for i in range(len(self.lines) - 1, -1, -1):
            line = self.lines[i]
            if line.row < 0:
                continue
            if line.source.startswith("signal ") or line.text == "M0":
                segs[i] = int(self.segment[line.row])
            else:
                segs[i], end = int(self.segment[max(end - 1, line.row)]), line.row
        self.line_segment = segs
        starts, last = [], None
        for i, seg in enumerate(segs):
            if seg is None:
                continue
            if last is not None and seg != last:
                starts.append(i)
            last = seg
        return starts

    def _next_block(self, sent: int) -> int | None:
        """The first block start at or after line ``sent`` (None: none, the rest streams to the end)."""
        return next((b for b in self.blocks if b >= sent), None)

    def _block_done(self, st) -> bool:
        """Single block: every line up to the block's end acknowledged, and a report taken after the last
        ``ok`` says Idle with nothing in the planner (the block executed, the machine at rest)."""
        if self.until is None or self.block_held or st.acked < self.until:
            self._acked_report = None
            return False
        if self._acked_report is None:
            self._acked_report = len(st.reports)  # a report from before the last ok may predate its move
            return False
        buf = st.status.get("Bf") or [0]
        return (len(st.reports) > self._acked_report and st.status.get("state", "").startswith("Idle")
                and int(buf[0]) >= PLANNER_BLOCKS)

    def _command(self, name: str, value, st) -> None:
        runner, streamer = self.runner, self.card.streamer
        state = runner.state
        runner.command_times.setdefault(f"applied:{name}", time.perf_counter())
        if name == "estop":
            streamer.realtime(b"\x18")
            raise _Ended("aborted", f"e-stop: soft reset at {self._where(st)} (GRBL stops at once)")
        if name == "hold" and state == "running":
            streamer.realtime(b"!")
            runner.set_state("holding", f"feed hold at {self._where(st)}")
        elif name == "resume" and state == "held" and self.block_held:  # GRBL is Idle: stream the next block
            self.block_held = False
            end = self.until
            assert end is not None  # held by single block: lines were held back from there
            self.until = self._next_block(end + 1) if self.single_block else None
            runner.set_state("running", f"resumed at {self._where(st)}")
        elif name == "resume" and state in ("holding", "held"):
            self.paused = None
            streamer.realtime(b"~")
            runner.set_state("running", f"resumed at {self._where(st)}")
        elif name == "stop" and state == "held" and self.block_held:  # Idle, at rest: the soft reset at once
            streamer.soft_reset()
            raise _Ended("aborted", f"stopped by the operator at {self._where(st)}")
        elif name == "stop" and state in ("running", "holding", "held"):
            streamer.realtime(b"!")
            runner.set_state("stopping", f"stopping at {self._where(st)}")
        elif name in ("feed", "rapid", "spindle"):
            streamer.realtime(override_bytes(name, self.overrides[name], float(value)))
            self.overrides[name] = float(value)
            runner.emit("log", f"{name} override {value:g} %", **{name: float(value)})
        elif name == "single_block":
            self.single_block = bool(value)
            if not self.block_held:  # held: Resume reads the switch
                self.until = self._next_block(st.sent) if value else None
            runner.emit("log", f"single block {'on' if value else 'off'}", single_block=bool(value))
        elif name == "optional_stop":
            runner.emit("log", "the optional stop (M1) is set at Start on GRBL (GRBL ignores M1): unchanged")
        self.events.append(Event("job", self._t(st), "", f"{name} at {self._where(st)}"))

    # ------------------------------------------------------------------ telling
    def _t(self, st) -> float:
        return st.reports[-1][0] if st.reports else 0.0

    def _executing(self, st) -> int:
        """The line GRBL is executing (0-based): acknowledged lines minus the blocks still in its planner."""
        buf = st.status.get("Bf") or [PLANNER_BLOCKS]
        queued = max(PLANNER_BLOCKS - int(buf[0]), 0)
        return min(max(st.acked - queued, 0), max(len(self.lines) - 1, 0))

    def _where(self, st) -> str:
        if not self.lines:
            return "the start"
        i = self._executing(st)
        return f"line {i + 1} ({self.lines[i].source})"

    def _tick(self, st, final: bool = False) -> None:
        status, runner = st.status, self.runner
        pos = status.get("MPos") or status.get("WPos")
        if pos is None:
            return
        n = len(self.job.machine.names)
        here = positions_of([pos[i] if i < len(pos) else 0.0 for i in range(n)])
        i = self._executing(st)
        row = self.lines[i].row if self.lines and self.lines[i].row >= 0 else self.first_row
        progress = 1.0 if final else row / max(len(self.segment) - 1, 1)  # of the program as the user has it
        segment = int(self.segment[row]) if self.lines and self.lines[i].row >= 0 else None
        acc = str(status.get("A", ""))
        fs = status.get("FS") or [0.0, 0.0]
        outputs = {"spindle_rpm": float(fs[1]) if len(fs) > 1 and ("S" in acc or "C" in acc) else 0.0,
                   "dout": [1] if "F" in acc else [], "tool_down": "S" in acc and self.card.pen is not None}
        source = self.lines[i].source if self.lines else ""
        where = f"line {i + 1} ({source})"
        names = self.job.segment_names
        line = gcode_line(names[segment]) if segment is not None and segment < len(names) else None
        if self.paused is not None:  # the stop's own place and G-code line
            where, line = self.paused, gcode_line(self.paused)
        runner.emit("tick", t=self._t(st), commanded=here, actual=None, where=where, segment=segment,
                    line=line, progress=progress,
                    time_left=self.job.duration * (1.0 - progress) * 100.0 / max(self.overrides["feed"], 1.0),
                    outputs=outputs)

    def _finish(self, end: _Ended) -> DeviceLog:
        card, runner, st = self.card, self.runner, self.st
        try:
            st.status = card.streamer.status()
            st.reports.append((time.monotonic() - card.streamer._t0, st.status["state"], list(st.status.get("MPos", []))))
        except DeviceError:
            pass
        self.events += [Event("stop", self._t(st), "", end.message),
                        Event("safe", self._t(st), "", "outputs left safe: GRBL's soft reset switched spindle and "
                                                       "coolant off (M5 M9)")]
        self._tick(st)
        runner.message = end.message
        outcome = "estop" if end.message.startswith("e-stop") else "aborted"
        log = card._log(st, outcome, self.events)
        runner.set_state(end.state, end.message)
        return log
