"""The simulated motion card, modelled on the 4-axis 6050 PCI card of the LabVIEW thesis.

Pulse/direction axes (up to 4) counted in steps; 20 inputs (9-20 the axes' limit and home switches
by default), 8 outputs, an e-stop on one of inputs 1-8, the shared PWM/DA terminal, a spindle on
the DA, optional closed loop (PID + first-order motor), soft limits, and homing. It runs on a
simulated clock: an operation is computed for all its periods at once (see ``executor``), so it is
deterministic and much faster than real time. Every operation returns a ``DeviceLog``.

The world outside the card is part of the simulation: where the switches sit (``AxisSwitches``)
and what plain inputs do (``schedule_input``: close input 1 at t = 0.8 s, say, to press the e-stop).
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field

import numpy as np

from flowmc.devices.card import HOME_METHODS, MotionCard
from flowmc.devices.log import Change, DeviceLog, Event
from flowmc.devices.preflight import axis_columns, preflight, program_signals
from flowmc.devices.ranges import CARD_6050
from flowmc.devices.sim.encoder import ab_levels
from flowmc.devices.sim.executor import Executed, StopRule, Trip, execute
from flowmc.devices.sim.homing import HomingSettings, home_axis
from flowmc.devices.sim.io import Outputs
from flowmc.devices.sim.moves import line_move, ramp
from flowmc.devices.sim.pid import LoopSettings, PositionLoop
from flowmc.devices.sim.world import N_CARD_AXES, N_INPUTS, AxisSwitches, default_switches, switch_inputs
from flowmc.errors import DeviceError
from flowmc.motion.machine import Machine
from flowmc.motion.path import describe_segment
from flowmc.motion.trajectory import Signal, Steps, Trajectory

__all__ = ["SimCard"]

_FAULTS = ("+limit", "-limit", "soft_max", "soft_min")


class _Stopped(Exception):
    """An e-stop ended the operation (raised inside a homing or program sequence)."""


@dataclass
class _Piece:
    """One executed stretch of periods, before it is joined into a log."""

    t0: int  # first period (card ticks)
    command: np.ndarray
    actual: np.ndarray
    changes: list = field(default_factory=list)
    events: list = field(default_factory=list)
    trips: tuple = ()
    estop_row: int | None = None  # row at which an e-stop stopped it

    @property
    def estop(self) -> bool:
        return self.estop_row is not None


class SimCard(MotionCard):
    """The simulated 6050 card for ``machine`` (its axes map to card axes 1..n in order).

    Options: ``closed_loop`` with ``loop`` settings; ``switches`` per axis name; ``estop_input``
    (1-8, or None: the card's default, no e-stop input); ``analog`` ("da" or "pwm": the jumper on
    the shared terminal); ``spindle_outputs`` (run, counter-clockwise); ``pen_output``: the digital
    output a program's tool (pen) signal drives, down = on (None, the default, or 0: none, the tool
    state is only logged; a plotter names its pen output); ``homing`` speeds; ``state``: start from the end state of an
    earlier log (``log.state``).
    """

    def __init__(self, machine: Machine | None = None, *, closed_loop: bool = False,
                 loop: LoopSettings = LoopSettings(), switches: dict[str, AxisSwitches] | None = None,
                 estop_input: int | None = None, analog: str = "da", spindle_outputs: tuple[int, int] = (1, 2),
                 pen_output: int | None = None, homing: HomingSettings = HomingSettings(), state: dict | None = None):
        self.machine = machine if machine is not None else Machine()
        self.spec = "sim"
        if len(self.machine.axes) > N_CARD_AXES:
            raise DeviceError(f"the card has {N_CARD_AXES} axes, the machine {len(self.machine.axes)}",
                              where="sim card")
        if estop_input is not None and not 1 <= estop_input <= 8:
            raise DeviceError(f"the e-stop can be input 1-8, not {estop_input}", where="sim card")
        if analog not in ("da", "pwm"):
            raise DeviceError(f"the PWM/DA terminal is 'da' or 'pwm', not {analog!r}", where="sim card")
        self.ranges = CARD_6050.with_analog(analog)
        self.period = self.machine.period
        self.step_mm = self.machine.column("step_mm")
        self.homing = homing
        self.estop_input = estop_input
        self.loop = PositionLoop(loop, self.period) if closed_loop else None
        unknown = sorted(set(switches or {}) - set(self.machine.names))
        if unknown:
            raise DeviceError(f"switches given for unknown axis {unknown}; axes: {self.machine.names}",
                              where="sim card")
        self.switches = tuple((switches or {}).get(a.name) or default_switches(a) for a in self.machine.axes)
        n = len(self.machine.axes)
        state = dict(state or {})
        if state and state.get("axes") != list(self.machine.names):
            raise DeviceError(f"the saved state is for axes {state.get('axes')}, the machine has "
                              f"{list(self.machine.names)}", where="sim card")
        self._tick = int(state.get("tick", 0))
        self._counts = np.array(state.get("counts", [0] * n), dtype=np.int64)
        self._actual = np.array(state.get("actual", self._counts * self.step_mm), dtype=float)
        self._zero = np.array(state.get("zero", [0.0] * n), dtype=float)
        self._homed = list(state.get("homed", [False] * n))
        self._axis_io = list(state.get("axis_io", [True] * n))
        self._plain = {int(k): bool(v) for k, v in state.get("plain_inputs", {}).items()}
        self._estopped = bool(state.get("estop", False))
        self._outputs = Outputs(self.ranges, spindle_outputs, state, pen_output)
        self._schedule: list[tuple[float, int, bool]] = []
        self._pieces: list[_Piece] = []

    # ---------------------------------------------------------------- state
    @property
    def clock(self) -> float:
        """Simulated time in seconds (a whole number of periods)."""
        return self._tick * self.period

    def position(self) -> np.ndarray:
        return self._actual.copy()

    def count(self, axis: int) -> int:
        return int(self._counts[axis])

    def world_position(self, axis: int) -> float:
        return float(self._zero[axis] + self._actual[axis])

    def state(self) -> dict:
        """What ``SimCard(machine, state=...)`` needs to carry on from here (also ``log.state``)."""
        return {"device": "sim", "axes": list(self.machine.names), "tick": self._tick, "period": self.period,
                "counts": self._counts.tolist(), "actual": self._actual.tolist(), "zero": self._zero.tolist(),
                "homed": list(self._homed), "axis_io": list(self._axis_io), "estop": self._estopped,
                "plain_inputs": {str(k): v for k, v in sorted(self._plain.items())}, **self._outputs.state()}

    def snapshot(self) -> DeviceLog:
        return self._log("done")

    def status(self) -> dict:
        encoder = np.rint(self._actual / self.step_mm).astype(np.int64)  # one x4 count per step
        a, b = ab_levels(encoder)
        return {"device": "sim", "clock_s": self.clock, "position_mm": self._actual.round(6).tolist(),
                "counts": self._counts.tolist(), "encoder": encoder.tolist(),
                "encoder_ab": [f"{x}{y}" for x, y in zip(a.tolist(), b.tolist())],
                "homed": list(self._homed), "estop": self._estopped, "closed_loop": self.loop is not None,
                "inputs": [ch for ch, on in self.read_inputs().items() if on],
                "outputs": [i + 1 for i, on in enumerate(self._outputs.bits) if on],
                "pwm_hz_duty": list(self._outputs.pwm), "da_v": self._outputs.da,
                "spindle_rpm": self._outputs.spindle_rpm, "tool_down": self._outputs.tool_down}

    # ---------------------------------------------------------------- inputs
    def input_names(self) -> dict[int, str]:
        """Each axis's limit and home switch inputs, by channel (``{9: "X +lim", 10: "X home", ...}``)."""
        return {ch: f"{name} {label}" for i, name in enumerate(self.machine.names)
                for ch, label in zip(switch_inputs(i), ("+lim", "home", "-lim"))}

    def _switch_levels(self, axis: int, world: np.ndarray) -> tuple[np.ndarray, ...]:
        sw = self.switches[axis]
        return world >= sw.pos_limit, world <= sw.home, world <= sw.neg_limit

    def read_inputs(self) -> dict[int, bool]:
        self._inputs_now()
        levels = {ch: self._plain.get(ch, False) for ch in range(1, N_INPUTS + 1)}
        for axis in range(len(self.machine.axes)):
            if self._axis_io[axis]:
                world = np.array([self.world_position(axis)])
                for ch, closed in zip(switch_inputs(axis), self._switch_levels(axis, world)):
                    levels[ch] = bool(closed[0])
        return levels

    def set_axis_io(self, axis: str, enabled: bool) -> None:
        """Use the axis's three switch inputs as switches (default) or as plain inputs (SetAxisIO_6050)."""
        self._axis_io[self._axis_index(axis)] = bool(enabled)

    def schedule_input(self, t: float, channel: int, closed: bool) -> None:
        """The world outside: plain input ``channel`` goes to ``closed`` at card time ``t`` (s)."""
        if not 1 <= channel <= N_INPUTS:
            raise DeviceError(f"input {channel} does not exist (inputs 1-{N_INPUTS})", where="sim card")
        for axis in range(len(self.machine.axes)):
            if self._axis_io[axis] and channel in switch_inputs(axis):
                raise DeviceError(f"input {channel} is axis {self.machine.names[axis]}'s switch; turn its axis "
                                  "I/O off to use it as a plain input", where="sim card")
        if t < self.clock:
            raise DeviceError(f"t = {t} s is in the past (card clock {self.clock} s)", where="sim card")
        self._schedule.append((float(t), int(channel), bool(closed)))
        self._schedule.sort()

    # ---------------------------------------------------------------- rules
    def _axis_index(self, name: str) -> int:
        if name not in self.machine.names:
            raise DeviceError(f"no axis {name!r}; axes: {', '.join(self.machine.names)}", where="sim card")
        return self.machine.names.index(name)

    def rule(self, axis: int, kind: str, direction: int, world_mm: float, strict: bool = False) -> StopRule:
        """A switch-like rule at a world position (``strict``: beyond it, not at it)."""
        at = (world_mm - self._zero[axis]) / self.step_mm[axis] + (1e-6 * direction if strict else 0.0)
        return StopRule(axis, kind, direction, at)

    def limit_rule(self, axis: int, direction: int) -> StopRule:
        sw = self.switches[axis]
        return self.rule(axis, "+limit" if direction > 0 else "-limit", direction,
                         sw.pos_limit if direction > 0 else sw.neg_limit)

    def _motion_rules(self) -> list[StopRule]:
        rules = []
        for axis, ax in enumerate(self.machine.axes):
            step = self.step_mm[axis]
            rules.append(StopRule(axis, "soft_max", +1, math.floor(ax.max / step + 1e-9) + 1, False, True))
            rules.append(StopRule(axis, "soft_min", -1, math.ceil(ax.min / step - 1e-9) - 1, False, True))
            if self._axis_io[axis]:
                rules += [self.limit_rule(axis, +1), self.limit_rule(axis, -1)]
        return rules

    # ---------------------------------------------------------------- executing
    def _inputs_now(self) -> None:
        """Take scheduled input changes that are due by now (they go into the next log)."""
        changes: list = []
        self._take_inputs(self._tick, self._tick, changes)
        if changes:
            self._pieces.append(_Piece(self._tick, self._counts[None, :].copy(), self._actual[None, :].copy(),
                                       changes))

    def _ready(self) -> None:
        self._inputs_now()
        if self._estopped:
            raise DeviceError("the card is in e-stop; release the e-stop and call reset()", where="sim card")

    def _take_inputs(self, t0: int, t_last: int, changes: list) -> int | None:
        """Apply scheduled input changes up to period ``t_last``; returns the e-stop row, if one closed."""
        estop_row = None
        while self._schedule and self._schedule[0][0] <= t_last * self.period + 1e-12:
            t, ch, closed = self._schedule.pop(0)
            row = max(math.ceil(t / self.period - 1e-9) - t0, 0)
            if self._plain.get(ch, False) != closed:
                self._plain[ch] = closed
                changes.append(Change((t0 + row) * self.period, "din", ch, float(closed)))
            if ch == self.estop_input and closed and estop_row is None:
                estop_row = row
                self._estopped = True
        return estop_row

    def _estop_row(self, t0: int, rows: int) -> int | None:
        """First row of a coming stretch at which the e-stop input closes (scheduled inputs, not consumed)."""
        if self.estop_input is None:
            return None
        for t, ch, closed in self._schedule:
            if ch == self.estop_input and closed:
                row = max(math.ceil(t / self.period - 1e-9) - t0, 0)
                return row if row < rows else None
        return None

    def _execute(self, command: np.ndarray, rules, until_trip: bool = False, loop=None) -> _Piece:
        """Run a stretch of commanded counts from the current state; updates the state; appends a piece.

        ``loop``: a ``LoopStream`` carrying the closed loop between stretches (a job in real time)."""
        t0 = self._tick
        estop_row = self._estop_row(t0, len(command))
        done: Executed = execute(command, rules, self.step_mm, estop_row=estop_row,
                                 loop=loop if loop is not None else self.loop, until_trip=until_trip)
        rows = len(done.command)
        changes: list = []
        estop_row = self._take_inputs(t0, t0 + rows - 1, changes)
        piece = _Piece(t0, done.command, done.actual, changes, [], done.trips, estop_row)
        for trip in done.trips:
            if trip.rule.kind in _FAULTS:
                piece.events.append(self._trip_event(trip, t0, done))
        if estop_row is not None:
            piece.events.append(Event("estop", (t0 + estop_row) * self.period, "",
                                      f"e-stop input {self.estop_input} closed: all axes stopped"))
        world = done.actual + self._zero
        for axis in range(len(self.machine.axes)):
            if self._axis_io[axis]:
                for ch, level in zip(switch_inputs(axis), self._switch_levels(axis, world[:, axis])):
                    for k in np.flatnonzero(np.diff(level.astype(np.int8))) + 1:
                        changes.append(Change((t0 + k) * self.period, "din", ch, float(level[k])))
        self._tick = t0 + rows - 1
        self._counts = done.command[-1].copy()
        self._actual = done.actual[-1].copy()
        self._pieces.append(piece)
        return piece

    def _trip_event(self, trip: Trip, t0: int, done: Executed) -> Event:
        axis, kind = trip.rule.axis, trip.rule.kind
        name = self.machine.names[axis]
        t = (t0 + trip.row) * self.period
        at = float(done.actual[trip.row, axis])
        if kind in ("+limit", "-limit"):
            ch = switch_inputs(axis)[0 if kind == "+limit" else 2]
            return Event("limit", t, name, f"{kind} switch (input {ch}) closed at {name} = {at:.4f} mm; "
                                           f"{name} stopped")
        limit = self.machine.axes[axis].max if kind == "soft_max" else self.machine.axes[axis].min
        return Event("soft_limit", t, name, f"{name} stopped at its soft limit "
                                            f"{'max' if kind == 'soft_max' else 'min'} {limit:g} mm")

    def phase(self, axis: int, direction: int, speed: float, distance: float, rules) -> Trip | None:
        """One homing move of ``axis`` ended by the first rule that trips; raises _Stopped on e-stop."""
        col = ramp(self._counts[axis] * self.step_mm[axis], direction, speed, max(distance, 0.0), self.period)
        command = np.repeat(self._counts[None, :], len(col), axis=0)
        command[:, axis] = np.rint(col / self.step_mm[axis])
        piece = self._execute(command, rules, until_trip=True)
        if piece.estop:
            raise _Stopped()
        return piece.trips[0] if piece.trips else None

    def _log(self, outcome: str | None = None, extra_events=()) -> DeviceLog:
        """Join the pieces since the last log into one DeviceLog."""
        pieces, self._pieces = self._pieces, []
        n = len(self.machine.axes)
        if not pieces:
            pieces = [_Piece(self._tick, self._counts[None, :].copy(), self._actual[None, :].copy())]
        command = np.vstack([pieces[0].command] + [p.command[1:] for p in pieces[1:]])
        actual = np.vstack([pieces[0].actual] + [p.actual[1:] for p in pieces[1:]])
        t = (pieces[0].t0 + np.arange(len(command))) * self.period
        steps = np.vstack([np.zeros((1, n), dtype=np.int64), np.diff(command, axis=0)])
        changes = [c for p in pieces for c in p.changes]
        events = [e for p in pieces for e in p.events] + list(extra_events)
        if outcome is None:
            kinds = {e.kind for e in events}
            outcome = next((k for k in ("estop", "limit", "soft_limit") if k in kinds), "done")
        fe = command * self.step_mm - actual if self.loop is not None else None
        return DeviceLog("sim", self.machine.names, self.period, t, steps, actual, fe, changes,
                         sorted(events, key=lambda e: e.t), outcome, self.state())

    # ---------------------------------------------------------------- programs
    def run(self, motion: Trajectory | Steps, signals: Signal | None = None, *, check: bool = True) -> DeviceLog:
        if check:
            preflight(motion, self.machine, signals, ranges=self.ranges)
        self._ready()
        program, segment, program_dt, tick = self._program_counts(motion)
        sig = self.checked_signals(motion, signals, tick, len(program))
        rules = self._motion_rules()
        start = program[0]
        if np.any(start != self._counts):
            here = self._counts * self.step_mm
            path = line_move(here, start * self.step_mm, self.machine.column("vmax"), self.machine.column("amax"),
                             self.period)
            piece = self._execute(np.rint(path / self.step_mm).astype(np.int64), rules)
            piece.events.append(Event("approach", piece.t0 * self.period, "",
                                      f"moved from {here.round(4).tolist()} to the program's start "
                                      f"{(start * self.step_mm).round(4).tolist()} in "
                                      f"{(len(path) - 1) * self.period:.3f} s"))
            if piece.estop or piece.trips:
                return self._log()
        piece = self._execute(program, rules)
        piece.events = [self._in_segment(e, piece.t0, segment, motion.segment_names) for e in piece.events]
        last = len(program) - 1 if piece.estop_row is None else min(len(program) - 1, piece.estop_row)
        piece.changes += self._apply_signals(sig, self._outputs, piece.t0, last, program_dt)
        return self._log()

    def check_program(self, motion, signals: Signal | None = None):
        report = self.check(motion, signals)
        pos, _seg, _T, tick = self.program_positions(motion)
        self.checked_signals(motion, signals, tick, len(pos))
        return report

    def checked_signals(self, motion, signals: Signal | None, tick: float, rows: int) -> Signal:
        """The program's signals in card seconds, all checked against the outputs before anything moves;
        lifts the tool first when the program uses it and it is down (before any approach move too)."""
        sig = program_signals(motion, signals)
        if isinstance(motion, Steps) and motion.tick <= 0:  # untimed: signal times are tick indices
            sig = Signal(sig.t * tick, sig.kind, sig.channel, sig.value)
        lift = "tool" in sig.kind.tolist() and self._outputs.tool_down  # a program's tool starts up
        trial = copy.deepcopy(self._outputs)
        if lift:
            trial.apply("tool", 0, 0.0, self.clock, where="program start (the tool starts up)")
        self._apply_signals(sig, trial, 0, rows - 1, self.period)  # all valid?
        if lift:  # before the approach move too: the pen must not draw it
            self.output_now("tool", 0, 0.0)
        return sig

    def output_now(self, kind: str, channel: int, value: float, where: str = "sim card") -> list[Change]:
        """Set one output at the card's clock now (a job applying its program's signals as it goes)."""
        changes = self._outputs.apply(kind, channel, value, self.clock, where=where)
        self._pieces.append(_Piece(self._tick, self._counts[None, :].copy(), self._actual[None, :].copy(), changes))
        return changes

    def _in_segment(self, event: Event, t0: int, segment: np.ndarray, names: tuple[str, ...]) -> Event:
        row = min(int(round(event.t / self.period)) - t0, len(segment) - 1)
        return event._replace(message=f"{event.message} ({describe_segment(int(segment[row]), names)})")

    def _apply_signals(self, sig: Signal, outputs: Outputs, t0: int, last_row: int, dt: float) -> list[Change]:
        """Set the outputs a program's signals ask for, each at the first period at or after its time."""
        changes = []
        for t, kind, ch, value in zip(sig.t, sig.kind, sig.channel, sig.value):
            row = max(math.ceil(t / dt - 1e-9), 0)
            if row <= last_row:
                changes += outputs.apply(str(kind), int(ch), float(value), (t0 + row) * self.period,
                                         where=f"signal at t={t:g} s")
        return changes

    def _program_counts(self, motion) -> tuple[np.ndarray, np.ndarray, float, float]:
        """The program as commanded counts per card period for every machine axis, with segments, the
        period and the program's own time step (a step stream's tick: the one chosen when untimed)."""
        pos, seg, T, tick = self.program_positions(motion)
        return np.rint(pos / self.step_mm).astype(np.int64), seg, T, tick

    def program_positions(self, motion) -> tuple[np.ndarray, np.ndarray, float, float]:
        """The program in mm per card period for every machine axis (axes it does not name stay where
        they are), with segments, the period and the program's own time step."""
        cols = axis_columns(motion.axes, self.machine)
        T = self.period
        if isinstance(motion, Trajectory):
            pos = np.asarray(motion.positions)
            if abs(motion.period - T) > 1e-12 * T:
                rows = math.ceil(motion.duration / T - 1e-9) + 1
                times = np.minimum(np.arange(rows) * T, motion.duration)
                pos = np.column_stack([np.interp(times, motion.times, pos[:, j]) for j in range(pos.shape[1])])
                seg = motion.segment[np.searchsorted(motion.times, times, side="right") - 1]
            else:
                seg = np.asarray(motion.segment)
            part = pos
            tick = motion.period
        elif isinstance(motion, Steps):
            tick = motion.tick if motion.tick > 0 else self._untimed_tick(motion, cols)
            origin = np.rint(motion.origin / self.step_mm[cols]).astype(np.int64)
            counts = np.vstack([np.zeros((1, len(cols)), dtype=np.int64), motion.counts()])
            rows = math.ceil(len(motion) * tick / T - 1e-9) + 1
            done = np.minimum(np.floor(np.arange(rows) * T / tick + 1e-9).astype(np.int64), len(motion))
            part = (origin + counts[done]) * self.step_mm[cols]
            seg = np.concatenate([motion.segment[:1], motion.segment])[done] if len(motion) else np.zeros(1, int)
        else:
            raise DeviceError(f"a card runs a Trajectory or Steps, not {type(motion).__name__}", where="sim card")
        program = np.repeat((self._counts * self.step_mm)[None, :], len(part), axis=0)
        program[:, cols] = part
        return program, seg, T, tick

    def _untimed_tick(self, steps: Steps, cols) -> float:
        """An untimed pulse table runs at the fastest rate every moving axis allows."""
        moving = np.abs(steps.steps).sum(axis=0) > 0
        if not moving.any():
            return self.period
        limits = np.maximum(1.0 / self.machine.column("max_step_rate")[cols],
                            self.step_mm[cols] / self.machine.column("vmax")[cols])
        return float(limits[moving].max())

    # ---------------------------------------------------------------- manual operations
    def home(self, axes: tuple[str, ...] | None = None, method: str = "switch") -> DeviceLog:
        if method not in HOME_METHODS:
            raise DeviceError(f"unknown homing method {method!r}; known: {', '.join(HOME_METHODS)}", where="sim card")
        self._ready()
        names = tuple(axes) if axes else self.machine.names
        order = [self._axis_index(a) for a in names]
        for axis in order:
            if not self._axis_io[axis]:
                raise DeviceError(f"axis {self.machine.names[axis]}'s switch inputs are plain inputs (axis I/O "
                                  "off): it cannot home", where="sim card")
        events = []
        for axis in order:
            name = self.machine.names[axis]
            try:
                failure = home_axis(self, axis, method)
            except _Stopped:
                return self._log("estop")
            if failure is not None:
                return self._log("home_failed", [Event("home_failed", self.clock, name, failure)])
            shift = self._counts[axis] * self.step_mm[axis]
            for piece in self._pieces:  # the log shows homing in the new frame: it ends at zero
                piece.command[:, axis] -= self._counts[axis]
                piece.actual[:, axis] -= shift
            self._zero[axis] += shift
            self._actual[axis] -= shift
            self._counts[axis] = 0
            self._homed[axis] = True
            events.append(Event("home", self.clock, name, f"{name} homed ({method}): counter zeroed at world "
                                                          f"{self._zero[axis]:.4f} mm"))
        return self._log("done", events)

    def jog(self, axis: str, distance: float, speed: float) -> DeviceLog:
        i = self._axis_index(axis)
        if not (math.isfinite(distance) and speed > 0):
            raise DeviceError(f"jog needs a finite distance and a speed > 0, got {distance}, {speed}", where="sim card")
        self._ready()
        here = self._counts * self.step_mm
        there = here.copy()
        there[i] += distance
        path = line_move(here, there, self.machine.column("vmax"), self.machine.column("amax"), self.period, speed)
        self._execute(np.rint(path / self.step_mm).astype(np.int64), self._motion_rules())
        return self._log()

    def estop(self) -> DeviceLog:
        self._estopped = True
        return self._log("estop", [Event("estop", self.clock, "", "software e-stop: all axes stopped")])

    def reset(self) -> DeviceLog:
        """Clear a latched e-stop once its input is open again (DeviceError while it is closed)."""
        self._inputs_now()
        if self.estop_input is not None and self._plain.get(self.estop_input, False):
            raise DeviceError(f"e-stop input {self.estop_input} is still closed", where="sim card")
        was, self._estopped = self._estopped, False
        return self._log("done", [Event("reset", self.clock, "", "e-stop cleared" if was else "nothing latched")])

    def _set(self, *items: tuple[str, int, float]) -> DeviceLog:
        """Set outputs now; all are checked before any changes (outputs work in e-stop too)."""
        trial = copy.deepcopy(self._outputs)
        changes = [c for kind, ch, value in items for c in trial.apply(kind, ch, value, self.clock)]
        self._outputs = trial
        self._pieces.append(_Piece(self._tick, self._counts[None, :].copy(), self._actual[None, :].copy(), changes))
        return self._log("done")

    def set_output(self, channel: int, on: bool) -> DeviceLog:
        return self._set(("dout", channel, float(bool(on))))

    def set_pwm(self, freq: float, duty: float) -> DeviceLog:
        return self._set(("pwm_freq", 1, freq), ("pwm_duty", 1, duty))

    def set_da(self, volts: float) -> DeviceLog:
        return self._set(("da", 1, volts))

    def set_spindle(self, rpm: float) -> DeviceLog:
        return self._set(("spindle_rpm", 1, rpm))
