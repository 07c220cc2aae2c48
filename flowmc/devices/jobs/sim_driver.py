"""Jobs on the simulated card: at once (the instant pace) or period by period (realtime and virtual).

Streamed, a program runs through a ``Retimer`` (hold, stop, overrides and single block re-time the
rest within every axis's limits) into a ``CardStream`` (limits, the e-stop input, the closed loop).
Signals fire when the job's place in the program passes their time, and so do the program's
operator stops (M0, M1 with the optional stop on, M60, M6: ``pauses``): the job comes to rest on
the stop's row, holds (held) and Resume carries on. Homing and "I/O now" run at
once on every pace (the card computes homing as one operation; it cannot be held), and so does a wait
for an input (on the card's own clock: the world's input changes are scheduled on it).
"""

from __future__ import annotations

import math
import time

import numpy as np

from flowmc.devices.jobs.card_driver import InstantDriver
from flowmc.devices.jobs.job import Job, gcode_line, positions_of
from flowmc.devices.jobs.pauses import program_pauses
from flowmc.devices.jobs.restart import plan_job_start
from flowmc.devices.log import Change, DeviceLog, Event
from flowmc.devices.sim.moves import line_move
from flowmc.devices.sim.stream import CardStream
from flowmc.errors import DeviceError, LimitError
from flowmc.motion.retime import Retimer
from flowmc.motion.trajectory import Steps

__all__ = ["SimInstant", "SimStream", "safe_changes"]


def safe_changes(card, job: Job) -> list[tuple[str, int, float]]:
    """What leaves the card's outputs safe, in order: spindle off, pen up, PWM 0, DA 0, outputs off."""
    out = card._outputs
    todo: list[tuple[str, int, float]] = []
    if out.spindle_rpm:
        todo.append(("spindle_rpm", 1, 0.0))
    if out.tool_down:
        todo.append(("tool", 0, 0.0))
    if card.ranges.analog == "pwm" and out.pwm[1] > 0:
        todo.append(("pwm_duty", 1, 0.0))
    if card.ranges.analog == "da" and out.da:
        todo.append(("da", 1, 0.0))
    spindle = set(out.spindle_outputs) if out.spindle_rpm else set()
    for ch, on in enumerate(out.bits, 1):
        if on and ch not in job.safe.keep_on and ch not in spindle and ch != out.pen_output:
            todo.append(("dout", ch, 0.0))
    return todo


def _make_safe(card, job: Job) -> list[Change]:
    changes: list[Change] = []
    for kind, ch, value in safe_changes(card, job):
        try:
            changes += card.output_now(kind, ch, value, where="safe outputs")
        except (LimitError, DeviceError):
            continue  # an output this card cannot set is not on
    return changes


def _outputs_status(card) -> dict:
    out = card._outputs
    return {"dout": [i + 1 for i, on in enumerate(out.bits) if on], "spindle_rpm": out.spindle_rpm,
            "tool_down": out.tool_down, "pwm": list(out.pwm), "da": out.da}


class SimInstant(InstantDriver):
    """The whole operation at once on the simulated card (its own outputs made safe after a fault)."""

    def outputs(self) -> dict:
        return _outputs_status(self.card)

    def make_safe(self) -> list[Change]:
        return _make_safe(self.card, self.job)


class SimStream:
    """A program (or a jog) period by period, paced by the wall clock (realtime) or not at all (virtual)."""

    def __init__(self, runner, card):
        self.runner, self.card, self.job = runner, card, runner.job

    # ------------------------------------------------------------------ setting up
    def _nominal(self):
        """Setpoints (mm, every axis, per card period), segment per row, signals by row, rapid rows."""
        card, job = self.card, self.job
        T = card.period
        if job.operation == "jog":
            axis, distance, speed = job.args
            i = card._axis_index(axis)
            here = card._counts * card.step_mm
            there = here.copy()
            there[i] += distance
            pos = line_move(here, there, card.machine.column("vmax"), card.machine.column("amax"), T, speed)
            return pos, np.full(len(pos), -1), [], np.zeros(len(pos), dtype=bool)
        motion = job.motion
        pos, seg, _T, tick = card.program_positions(motion)
        sig = card.checked_signals(motion, job.signals, tick, len(pos))
        rows = sorted([(max(math.ceil(t / T - 1e-9), 0), str(k), int(c), float(v))
                       for t, k, c, v in zip(sig.t, sig.kind, sig.channel, sig.value)], key=lambda r: r[0])
        scale = tick if isinstance(motion, Steps) and motion.tick <= 0 else 1.0  # untimed: times are ticks
        own = np.maximum(np.ceil(np.asarray(motion.signals.t) * scale / T - 1e-9), 0).astype(int)
        start = self.runner.start_at
        found = [p for p in program_pauses(motion, np.asarray(seg), [r[0] for r in rows], own)
                 if start is None or p[2].event.segment >= start]  # a stop before the start is behind it
        self.pauses = [pause for _row, _place, pause in found]
        for k, (row, place, _pause) in enumerate(found):
            rows.insert(place + k, (row, "pause", k, 0.0))
        flags = np.asarray(motion.segment_rapid, dtype=bool)
        rapid = flags[seg] if flags.any() else np.zeros(len(pos), dtype=bool)
        return pos, np.asarray(seg), rows, rapid

    def _outputs_now(self) -> dict:
        out = self.card._outputs
        state = {("dout", ch): float(on) for ch, on in enumerate(out.bits, 1)}
        state.update({("spindle_rpm", 1): out.spindle_rpm, ("tool", 0): float(out.tool_down), ("da", 1): out.da,
                      ("pwm_freq", 1): out.pwm_request[0], ("pwm_duty", 1): out.pwm_request[1]})
        return state

    # ------------------------------------------------------------------ running
    def run(self) -> DeviceLog:
        runner, card, job = self.runner, self.card, self.job
        if job.operation in ("home", "io", "wait"):
            return SimInstant(runner, card).run()
        stream = CardStream(card)
        self.pauses, self.paused = [], None
        self.optional_stop = runner.status.optional_stop
        nominal, segment, signals, rapid = self._nominal()
        here = card._counts * card.step_mm
        plan = plan_job_start(job, nominal, segment, signals, rapid, here, card.machine, self._outputs_now(),
                              runner.start_at)
        if runner.line_note:
            plan.assumptions.insert(0, runner.line_note)
        runner.assumptions = plan.assumptions
        for text in plan.assumptions:
            runner.emit("log", text)
        self.segment, self.plan = plan.segment, plan
        T = card.period
        machine = card.machine
        rt = Retimer(plan.positions, T, machine.column("vmax"), machine.column("amax"), rapid=plan.rapid,
                     quantised=isinstance(job.motion, Steps), start=0.0, rate=1.0)
        if plan.junction > 0:
            rt.stop_at(plan.junction)
        self.rt, self.stream = rt, stream
        self.pending = list(plan.signals)
        self.program_rpm = card._outputs.spindle_rpm
        self.spindle_pct = 100.0
        self.single_block = runner.status.single_block
        self.events: list[Event] = [Event("restart", card.clock, "", text) for text in plan.assumptions]
        self.boundaries = np.flatnonzero(np.diff(plan.segment) != 0) + 1  # first row of each new segment
        if self.single_block and plan.junction == 0:
            rt.stop_at(self._next_stop())
        return self._loop()

    def _loop(self) -> DeviceLog:
        runner, card, rt, stream = self.runner, self.card, self.rt, self.stream
        T = card.period
        chunk = max(1, int(round(1.0 / (runner.tick_hz * T))))  # periods per tick on the virtual pace
        realtime = runner.pace == "realtime"
        most = max(chunk, int(4 * runner.speed / (runner.tick_hz * T)))  # catching up after a stall
        t_wall0 = time.monotonic()
        executed = 0
        while True:
            cmds = runner.take_commands(clock=executed * T)
            if cmds and self._apply(cmds):
                return self._finish("aborted", "e-stop: every axis stopped at once")
            if realtime:
                due = int((time.monotonic() - t_wall0) * runner.speed / T) - executed
                due = min(due, most)
            else:
                due = chunk
            if due > 0:
                self._advance(due)
                executed += due
                if stream.fault is not None:
                    return self._fault()
                self._tick()
            state = runner.state
            if rt.at_rest and state in ("holding", "stopping", "running") and not rt.done:
                if state == "stopping":
                    return self._finish("aborted", f"stopped by the operator at {self._where()}")
                if state == "holding":
                    runner.set_state("held", f"held at {self._where()}")
                elif self.paused is not None:
                    self._tick()
                    text = self.paused.describe()
                    self.events.append(Event("pause", card.clock, "", text))
                    runner.set_state("held", text)
                elif self._single_block_stop():
                    done = int(self.segment[max(int(rt.tau + 1e-9) - 1, 0)])
                    runner.set_state("held", f"single block: held at the end of {self.job.where(done)}")
                elif rt.stop_tau is not None and rt.tau >= rt.stop_tau - 1e-9:
                    rt.stop_at(self._next_stop())  # the approach ended at rest: the program starts
            if rt.done and not self.pending:
                stream.settle()
                return self._finish("done", "done")
            if realtime:
                runner.sleep(1.0 / runner.tick_hz)

    def _fire(self, tau: float) -> None:
        """Fire the signals due by ``tau``, up to an operator stop (nothing after it fires until Resume)."""
        while self.paused is None and self.pending and self.pending[0][0] <= tau + 1e-9:
            self._signal(*self.pending.pop(0)[1:])

    def _advance(self, periods: int) -> None:
        """Run ``periods`` setpoints through the card, firing signals where the job passes them."""
        rt, stream = self.rt, self.stream
        self._fire(rt.tau)  # due where the job stands now
        points, taus = self._run_periods(periods)
        periods = len(points)
        if self.runner.trace is not None:
            self.runner.trace.append(points)
        j = 0
        while self.pending and self.paused is None and j < periods:
            row = self.pending[0][0]
            k = int(np.searchsorted(taus[j:], row - 1e-9)) + j
            if k >= periods:
                break
            ran = stream.move(points[j:k + 1])
            if stream.fault is not None or ran < k + 1 - j:
                return
            j = k + 1
            self._fire(taus[k])
        if j < periods:
            stream.move(points[j:])
        if rt.done:  # signals (and stops) at or after the last setpoint
            self._fire(math.inf)

    def _run_periods(self, periods: int) -> tuple[np.ndarray, np.ndarray]:
        """``periods`` setpoints from the retimer, coming to rest exactly on the next operator stop's row.

        The planner already stops the motion there (a dwell), so the job runs the plan as it is up to
        the last whole period before the row and only then aims at the row itself, which it reaches at
        rest within a period: a stop aimed at from afar would re-time the whole approach.
        """
        rt = self.rt
        row = self._next_pause_row()
        if row is None or rt.hold or rt.r <= 0 or (rt.stop_tau is not None and rt.stop_tau <= row):
            return rt.advance(periods)
        before = max(int(math.floor((row - rt.tau) / rt.r + 1e-9)), 0)
        if before > periods:
            return rt.advance(periods)
        first = rt.advance(before) if before else (np.empty((0, rt.q.shape[1])), np.empty(0))
        rt.stop_at(row)
        rest = rt.advance(periods - len(first[0]))
        return np.vstack([first[0], rest[0]]), np.concatenate([first[1], rest[1]])

    def _next_pause_row(self) -> float | None:
        return next((float(row) for row, kind, ch, _v in self.pending
                     if kind == "pause" and self.pauses[ch].stops(self.optional_stop)), None)

    def _signal(self, kind: str, channel: int, value: float) -> None:
        if kind == "pause":
            pause = self.pauses[channel]
            if not pause.stops(self.optional_stop):
                self.runner.emit("log", f"optional stop is off: {pause.where} (M1) runs on")
            elif self.rt.done:
                self.runner.emit("log", f"{pause.describe().split(';')[0]}: the program ends there")
            else:
                self.paused = pause
                rt = self.rt
                if rt.stop_tau is None or rt.tau < rt.stop_tau - 1e-9:  # not aimed at (cannot happen): hold
                    rt.hold = True
            return
        if kind == "spindle_rpm":
            self.program_rpm = value
            value = self._spindle_value()
        for change in self.stream.output(kind, channel, value, where=f"signal at {self._where()}"):
            self.runner.emit("io", change=change)

    def _spindle_value(self) -> float:
        limit = self.card.ranges.spindle_rpm_max
        return float(np.clip(self.program_rpm * self.spindle_pct / 100.0, -limit, limit))

    def _apply(self, cmds) -> bool:
        """Apply commands; True when an e-stop ended the job."""
        runner, rt, card = self.runner, self.rt, self.card
        for name, value in cmds:
            state = runner.state
            runner.command_times.setdefault(f"applied:{name}", time.perf_counter())
            note = None
            if name == "estop":
                card._estopped = True
                self.events.append(Event("estop", card.clock, "", "software e-stop: all axes stopped"))
                return True
            if name == "hold" and state == "running":
                rt.hold = True
                runner.set_state("holding", f"feed hold at {self._where()}")
                note = "feed hold"
            elif name == "resume" and state in ("holding", "held"):
                rt.hold = False
                if self.paused is not None and state == "held":
                    runner.emit("log", f"resumed after the {self.paused.describe().split(';')[0]}")
                    self.paused = None
                    if rt.stop_tau is not None and abs(rt.tau - rt.stop_tau) < 1e-9:
                        rt.r = 1.0  # the plan itself starts from rest here: run it as planned, sample for sample
                if rt.stop_tau is None or rt.tau >= rt.stop_tau - 1e-9:  # the stop it was heading for is passed
                    rt.stop_at(self._next_stop())
                runner.set_state("running", f"resumed at {self._where()}")
                note = "resume"
            elif name == "stop" and state in ("running", "holding", "held"):
                rt.hold = True
                runner.set_state("stopping", f"stopping at {self._where()}")
                note = "stop"
            elif name == "feed":
                rt.set_overrides(feed=value / 100.0)
                runner.emit("log", f"feed override {value:g} %", feed=value)
                note = f"feed override {value:g} %"
            elif name == "rapid":
                rt.set_overrides(rapid=value / 100.0)
                runner.emit("log", f"rapid override {value:g} %", rapid=value)
                note = f"rapid override {value:g} %"
            elif name == "spindle":
                self.spindle_pct = value
                runner.emit("log", f"spindle override {value:g} %", spindle=value)
                note = f"spindle override {value:g} %"
                if self.program_rpm:
                    for change in self.stream.output("spindle_rpm", 1, self._spindle_value(), where="spindle override"):
                        runner.emit("io", change=change)
            elif name == "single_block":
                self.single_block = bool(value)
                runner.emit("log", f"single block {'on' if value else 'off'}", single_block=bool(value))
                self._retarget()
                note = f"single block {'on' if value else 'off'}"
            elif name == "optional_stop":
                self.optional_stop = bool(value)
                runner.emit("log", f"optional stop (M1) {'on' if value else 'off'}", optional_stop=bool(value))
                self._retarget()
                note = f"optional stop {'on' if value else 'off'}"
            if note:
                self.events.append(Event("job", card.clock, "", f"{note} at {self._where()}"))
        return False

    def _retarget(self) -> None:
        """Aim at the next stop after a switch changed; not while held (Resume does) or on the approach."""
        rt = self.rt
        if self.runner.state == "running" and self.paused is None and not (rt.stop_tau is not None
                                                                           and rt.tau < self.plan.junction):
            rt.stop_at(self._next_stop())

    def _next_stop(self) -> float | None:
        """Single block: the first segment end the job can still stop at (None: run on). The program's
        operator stops are aimed at as the job comes to them (``_run_periods``)."""
        rt = self.rt
        if not self.single_block:
            return None
        speed = float(np.linalg.norm(rt.velocity()))
        need = speed * speed / (2 * rt.brake)
        s_now = float(np.interp(rt.tau, np.arange(rt.n), rt.s))
        for b in self.boundaries:
            if b > rt.tau + 1e-9 and rt.s[b] - s_now >= need:
                return float(b)
        return None

    def _single_block_stop(self) -> bool:
        rt = self.rt
        return self.single_block and rt.stop_tau is not None and rt.tau >= rt.stop_tau - 1e-9

    # ------------------------------------------------------------------ telling
    def _segment_now(self) -> int | None:
        k = min(int(self.rt.tau + 1e-9), len(self.segment) - 1)
        seg = int(self.segment[k])
        return None if seg < 0 else seg

    def _where(self) -> str:
        return self.job.where(self._segment_now())

    def _tick(self) -> None:
        rt, card, job = self.rt, self.card, self.job
        seg = self._segment_now()
        names = job.segment_names
        commanded = card._counts * card.step_mm
        where = job.where(seg)
        line = gcode_line(names[seg]) if seg is not None and seg < len(names) else None
        if self.paused is not None:  # stopped for the operator: the stop's own line (the M0, the M6)
            seg, where, line = self.paused.event.segment, self.paused.where, self.paused.line
        self.runner.emit("tick", t=card.clock, commanded=positions_of(commanded),
                         actual=positions_of(card.position()), segment=seg, where=where, line=line,
                         progress=float(rt.tau / rt.end) if rt.end > 0 else 1.0, time_left=rt.time_left(),
                         outputs=_outputs_status(card))

    def _finish(self, state: str, message: str) -> DeviceLog:
        runner, card, job = self.runner, self.card, self.job
        events = list(self.events)
        changes: list[Change] = []
        if state != "done":
            if card.loop is not None and not card._estopped:
                self.stream.settle()
            changes = _make_safe(card, job)
            for change in changes:
                runner.emit("io", change=change)
            events.append(Event("safe", card.clock, "", f"outputs left safe: {job.safe.describe()}"))
            events.append(Event("stop", card.clock, "", message))
        outcome = None if state == "done" else "estop" if card._estopped else "aborted"
        log = self.stream.log(outcome, events)
        runner.message = message
        self._tick()
        runner.set_state(state, message)
        return log

    def _fault(self) -> DeviceLog:
        fault = self.stream.fault
        message = f"{fault.message} ({self._where()})"
        self.events.append(Event("fault", self.card.clock, fault.axis, message))
        card, job, runner = self.card, self.job, self.runner
        changes = _make_safe(card, job)
        for change in changes:
            runner.emit("io", change=change)
        events = self.events + [Event("safe", card.clock, "", f"outputs left safe: {job.safe.describe()}")]
        log = self.stream.log(None, events)
        self._tick()
        err = DeviceError(message, where=job.device)
        err.log = log
        raise err
