"""The simulated LinuxCNC machine behind flowmc's motion-card interface (``open_device("linuxcnc")``).

Every operation is one LinuxCNC session: start, home in place where the last operation
left the axes, restore outputs and spindle, run a short G-code program, shut down. So
the card keeps the state between operations, and each operation returns the DeviceLog
of the servo periods LinuxCNC executed.

What maps to what: a Trajectory (or timed Steps) becomes a G1 polyline through its
setpoints, each with the feed of its chord (F = chord / T), which LinuxCNC re-plans
under its own limits with ``G64 P<tolerance>``: the path is the setpoints', the timing
LinuxCNC's. A Path goes through flowmc's G-code exporter. Digital outputs 1-4 are
LinuxCNC's motion digital outputs 0-3 (M62/M63 with motion, M64/M65 at once), the DA
is analog output 0 (M67/M68 E0), the spindle is S with M3/M4/M5. There is no PWM
output and no wired input. Programs are written between ``%`` lines rather than ended
with M2, which would switch the spindle off. A job's operator stops and single-block marks go in as
M0/M1 lines after the move to their setpoint row (``trajectory_lines``' ``stops``).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from flowmc.devices.card import MotionCard
from flowmc.devices.linuxcnc.backend import SERVO_PERIOD, LinuxCNCRun, StartState, home_position, run_program
from flowmc.devices.log import Change, DeviceLog, Event
from flowmc.devices.ranges import CardRanges
from flowmc.errors import DeviceError
from flowmc.motion.gcode_write import path_to_gcode
from flowmc.motion.machine import Machine
from flowmc.motion.path import Path
from flowmc.motion.trajectory import Signal, Steps, Trajectory

__all__ = ["LinuxCNCCard", "LINUXCNC_RANGES", "trajectory_gcode", "trajectory_lines"]

#: Four digital outputs, analog output 0 as the DA, no PWM, no wired inputs.
LINUXCNC_RANGES = CardRanges(inputs=0, outputs=4, analog="da")
_XYZ = ("X", "Y", "Z")


def _num(value: float) -> str:
    text = f"{value:.6f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def _signal_words(kind: str, channel: int, value: float, where: str) -> str:
    if kind == "dout":
        if not 1 <= channel <= 4:
            raise DeviceError(f"digital output {channel} does not exist (outputs 1-4)", where=where)
        return f"M{62 if value else 63} P{channel - 1}"
    if kind == "da":
        return f"M67 E0 Q{_num(value)}"
    if kind == "spindle_rpm":
        return "M5" if value == 0 else f"S{_num(abs(value))} {'M3' if value > 0 else 'M4'}"
    if kind == "tool":
        return ""  # a mill's rapids lift nothing: the tool state drives no LinuxCNC output
    raise DeviceError(f"the LinuxCNC machine has no {kind} output (no PWM)", where=where)


def trajectory_gcode(positions: np.ndarray, axes, period: float, signals: Signal | None = None,
                     tolerance: float = 0.001, stops: Sequence[tuple[int, int, str]] = ()) -> str:
    """Setpoints as a G1 polyline, each line with the feed of its chord; pauses become G4 dwells.

    The program first moves (G0) to the first setpoint, which is a no-op when the machine is there.

    Signal events go before the line of the setpoint at or after their time (dout and DA with
    the motion, M62/M63/M67; spindle S/M3/M4/M5). ``stops``: ``(row, before, line)``, a line (an M0
    or M1) that LinuxCNC stops on once the motion has reached setpoint ``row`` (its queue runs empty
    there), after the first ``before`` of that row's signals; the row's other signals follow it.
    """
    return "\n".join(trajectory_lines(positions, axes, period, signals, tolerance, stops)[0]) + "\n"


def trajectory_lines(positions: np.ndarray, axes, period: float, signals: Signal | None = None,
                     tolerance: float = 0.001, stops: Sequence[tuple[int, int, str]] = ()
                     ) -> tuple[list[str], np.ndarray]:
    """``trajectory_gcode``'s lines, and for each line (1-based: index 0 is unused) the setpoint row the
    machine has reached when LinuxCNC reports it as its motion line (what a job's progress reads)."""
    cols = [_XYZ.index(a.upper()) for a in axes]
    pos = np.asarray(positions, dtype=float)
    chord = np.linalg.norm(np.diff(pos, axis=0), axis=1)
    last = max(len(pos) - 1, 1)
    by_row: dict[int, list[str]] = {}
    if signals is not None:
        for row, t, kind, channel, value in zip(signals.rows(period, 1, last).tolist(), signals.t, signals.kind,
                                                 signals.channel, signals.value):
            words = _signal_words(str(kind), int(channel), float(value), f"signal at t={t:g} s")
            if words:
                by_row.setdefault(row, []).append(words)
    after: dict[int, list[str]] = {}  # lines that follow the move to a row: its stops, the signals after them
    grouped: dict[int, list[tuple[int, str]]] = {}
    for row, before, line in stops:
        grouped.setdefault(min(max(int(row), 1), last), []).append((int(before), line))
    for row, here in grouped.items():
        at = by_row.pop(row, [])
        cut = min(here[0][0], len(at))
        by_row[row], after[row] = at[:cut], []
        for i, (_before, line) in enumerate(here):
            upto = here[i + 1][0] if i + 1 < len(here) else len(at)
            after[row] += [line, *at[cut:max(cut, upto)]]
            cut = max(cut, upto)
    first = " ".join(f"{_XYZ[c]}{_num(v)}" for c, v in zip(cols, pos[0])) if len(pos) else ""
    out = ["%", "G21 G90 G17 G94", f"G64 P{_num(tolerance)}"] + ([f"G0 {first}"] if first else [])
    rows = [0] * (len(out) + 1)

    def put(lines: list[str], row: int) -> None:
        out.extend(lines)
        rows.extend([row] * len(lines))

    pause = 0
    for k in range(1, len(pos)):
        put(by_row.get(k, []), k - 1)
        if chord[k - 1] == 0.0:
            pause += 1
        else:
            if pause:
                put([f"G4 P{_num(pause * period)}"], k - 1)
                pause = 0
            words = " ".join(f"{_XYZ[c]}{_num(v)}" for c, v in zip(cols, pos[k]))
            put([f"G1 {words} F{_num(chord[k - 1] / period * 60.0)}"], k)
        if k in after:
            if pause:
                put([f"G4 P{_num(pause * period)}"], k)
                pause = 0
            put(after[k], k)
    if pause:
        put([f"G4 P{_num(pause * period)}"], len(pos) - 1)
    if len(pos) <= 1:
        put(by_row.get(1, []) + after.get(1, []), 0)
    put(["%"], max(len(pos) - 1, 0))
    return out, np.asarray(rows, dtype=np.int64)


class LinuxCNCCard(MotionCard):
    """The simulated LinuxCNC machine for ``machine`` (axes among X, Y, Z).

    Options: ``servo_period`` (s, LinuxCNC's servo thread and sampling), ``tolerance`` (mm, the
    G64 P used for trajectories), ``timeout`` (s per operation), ``state`` (a previous log's state).
    """

    def __init__(self, machine: Machine | None = None, *, servo_period: float = SERVO_PERIOD,
                 tolerance: float = 0.001, timeout: float = 300.0, state: dict | None = None):
        self.machine = machine if machine is not None else Machine()
        self.spec = "linuxcnc"
        self.ranges = LINUXCNC_RANGES
        odd = [a.name for a in self.machine.axes if a.name.upper() not in _XYZ]
        if odd:
            raise DeviceError(f"the LinuxCNC machine has axes X, Y, Z; not {', '.join(odd)}", where="linuxcnc")
        self.servo_period = servo_period
        self.tolerance = tolerance
        self.timeout = timeout
        state = dict(state or {})
        self._pos = np.array(state.get("position_xyz", home_position(self.machine)), dtype=float)  # X Y Z
        self._dout = [bool(v) for v in state.get("dout", [False] * 4)]
        self._aout = [float(v) for v in state.get("aout", [0.0, 0.0])]
        self._spindle = float(state.get("spindle_rpm", 0.0))
        self._cols = [_XYZ.index(a.name.upper()) for a in self.machine.axes]

    # ---------------------------------------------------------------- state
    def position(self) -> np.ndarray:
        return self._pos[self._cols].copy()

    def state(self) -> dict:
        return {"device": "linuxcnc", "axes": list(self.machine.names), "position_xyz": self._pos.tolist(),
                "dout": list(self._dout), "aout": list(self._aout),
                "spindle_rpm": self._spindle}

    def status(self) -> dict:
        return {"device": "linuxcnc", "position_mm": self.position().round(6).tolist(),
                "outputs": [i + 1 for i, on in enumerate(self._dout) if on], "da_v": self._aout[0],
                "spindle_rpm": self._spindle, "servo_period_s": self.servo_period}

    def read_inputs(self) -> dict[int, bool]:
        return {}  # the simulator has no wired inputs

    # ---------------------------------------------------------------- operations
    def run_gcode(self, gcode: str, name: str = "program.ngc", **job) -> DeviceLog:
        """Run G-code as it is (starting where the card is) and return the log. ``job``: run_program's
        ``commands``, ``on_event`` and ``keep_on``, for a job that can be held, resumed and aborted."""
        start = StartState(home=self._pos.copy(), dout=tuple(self._dout), aout=tuple(self._aout),
                           spindle_rpm=self._spindle)
        run = run_program(gcode, self.machine, servo_period=self.servo_period, timeout=self.timeout, name=name,
                          start=start, **job)
        return self._log(run)

    def run_path(self, path: Path, tolerance: float | None = None) -> DeviceLog:
        """Run a Path through flowmc's G-code exporter with ``G64 P<tolerance>`` (default: the card's),
        after a G0 from where the card is to the path's start."""
        # Path events as zero-second dwells: the run goes straight through (a pause would wait for a
        # resume this card does not send, and the simulated machine has no rotary axis to index).
        text = path_to_gcode(path, blend_tolerance=self.tolerance if tolerance is None else tolerance,
                             program_end=False, events="dwells")
        to_start = " ".join(f"{a}{_num(v)}" for a, v in zip(_XYZ, path.start))
        return self.run_gcode(f"%\nG21 G90\nG0 {to_start}\n{text}%\n", name="path.ngc")

    def run(self, motion: Trajectory | Steps, signals: Signal | None = None, *, check: bool = True, **job) -> DeviceLog:
        if check:
            self.check(motion, signals)
        return self.run_gcode(self._program(motion, signals), name="trajectory.ngc", **job)

    def check_program(self, motion: Trajectory | Steps, signals: Signal | None = None):
        report = self.check(motion, signals)
        self._program(motion, signals)  # what LinuxCNC cannot take is refused here
        return report

    def _program(self, motion: Trajectory | Steps, signals: Signal | None) -> str:
        """The program as G-code for LinuxCNC (G64 P tolerance, signals as M-codes)."""
        return "\n".join(self.program_lines(motion, signals)[0]) + "\n"

    def program_lines(self, motion: Trajectory | Steps, signals: Signal | None,
                      stops: Sequence[tuple[int, int, str]] = ()) -> tuple[list[str], np.ndarray]:
        """The program's G-code lines for LinuxCNC, with ``stops`` placed (``trajectory_lines``), and the
        setpoint row each line number reaches."""
        positions, period, axes = self.setpoints(motion)
        missing = [a for a in axes if a not in self.machine.names]
        if missing:
            raise DeviceError(f"program axes {missing} are not machine axes {self.machine.names}", where="linuxcnc")
        merged = motion.signals.merged(signals) if signals is not None else motion.signals
        return trajectory_lines(positions, axes, period, merged, self.tolerance, stops)

    @staticmethod
    def setpoints(motion: Trajectory | Steps) -> tuple[np.ndarray, float, tuple[str, ...]]:
        """The rows LinuxCNC's program goes through (mm), their time step (s) and axes."""
        if isinstance(motion, Steps):
            if motion.tick <= 0:
                raise DeviceError("an untimed step stream has no speeds for LinuxCNC; give a trajectory "
                                  "or a timed step stream", where="linuxcnc")
            return motion.positions(), motion.tick, motion.axes
        return motion.positions, motion.period, motion.axes

    @staticmethod
    def setpoint_rows(motion: Trajectory | Steps) -> tuple[np.ndarray, np.ndarray, float, tuple[str, ...]]:
        """``setpoints`` with the segment of each row: a step stream's row 0 is its origin, before its
        first step, and counts as the first step's segment."""
        positions, period, axes = LinuxCNCCard.setpoints(motion)
        positions = np.asarray(positions, dtype=float)
        n = len(positions)
        seg = np.asarray(motion.segment if motion.segment is not None else np.zeros(n, dtype=np.int64))
        return positions, (seg if len(seg) == n else np.concatenate([seg[:1], seg])[:n]), period, axes

    def home(self, axes: tuple[str, ...] | None = None, method: str = "switch") -> DeviceLog:
        """LinuxCNC homes in place (HOME_SEARCH_VEL = 0): the named axes become 0 where they stand."""
        names = tuple(axes) if axes else self.machine.names
        unknown = [a for a in names if a not in self.machine.names]
        if unknown:
            raise DeviceError(f"no axis {unknown}; axes: {', '.join(self.machine.names)}", where="linuxcnc")
        zero = home_position(self.machine)
        for a in names:
            k = _XYZ.index(a.upper())
            self._pos[k] = zero[k]
        log = self.run_gcode("%\nG4 P0\n%\n", name="home.ngc")
        events = tuple(log.events) + tuple(Event("home", 0.0, a, "homed in place") for a in names)
        return DeviceLog(log.device, log.axes, log.period, log.t, log.steps, log.position, None, log.changes,
                         events, log.outcome, log.state)

    def jog(self, axis: str, distance: float, speed: float) -> DeviceLog:
        if axis not in self.machine.names:
            raise DeviceError(f"no axis {axis!r}; axes: {', '.join(self.machine.names)}", where="linuxcnc")
        if not speed > 0:
            raise DeviceError(f"jog speed must be > 0 mm/s, got {speed}", where="linuxcnc")
        letter = axis.upper()
        return self.run_gcode(f"%\nG21 G91 G1 {letter}{_num(distance)} F{_num(speed * 60)}\nG90\n%\n", name="jog.ngc")

    def estop(self) -> DeviceLog:
        """Nothing runs between operations, so an e-stop only switches outputs and spindle off."""
        self._dout = [False] * 4
        self._aout = [0.0, 0.0]
        self._spindle = 0.0
        pos = self.position()
        return DeviceLog(self.spec, self.machine.names, self.servo_period, [0.0], np.zeros((1, len(pos))),
                         pos[None, :], events=(Event("estop", 0.0, "", "outputs and spindle off"),),
                         outcome="estop", state=self.state())

    def set_output(self, channel: int, on: bool) -> DeviceLog:
        _signal_words("dout", channel, on, "set_output")  # checks the channel
        return self.run_gcode(f"%\nM{64 if on else 65} P{channel - 1}\n%\n", name="output.ngc")

    def set_pwm(self, freq: float, duty: float) -> DeviceLog:
        raise DeviceError("the LinuxCNC machine has no PWM output", where="linuxcnc")

    def set_da(self, volts: float) -> DeviceLog:
        return self.run_gcode(f"%\nM68 E0 Q{_num(volts)}\n%\n", name="da.ngc")

    def set_spindle(self, rpm: float) -> DeviceLog:
        return self.run_gcode(f"%\n{_signal_words('spindle_rpm', 0, rpm, 'set_spindle')}\nG4 P0.05\n%\n",
                              name="spindle.ngc")

    # ---------------------------------------------------------------- logs
    def _log(self, run: LinuxCNCRun) -> DeviceLog:
        """A DeviceLog of the run, and the card's state updated to where it ended."""
        n = len(run.samples)
        t = np.arange(n) * run.servo_period
        position = run.samples[:, self._cols]
        counts = np.rint(position / self.machine.column("step_mm")).astype(np.int64)
        steps = np.vstack([np.zeros((1, len(self._cols)), dtype=np.int64), np.diff(counts, axis=0)])
        changes: list[Change] = []
        before = (np.array(self._dout), np.array(self._aout), self._spindle)
        for ch in range(4):
            seq = np.r_[before[0][ch], run.dout[:, ch]].astype(int)
            changes += [Change(t[k], "dout", ch + 1, float(seq[k + 1])) for k in np.flatnonzero(np.diff(seq))]
        seq = np.r_[before[1][0], run.aout[:, 0]]
        changes += [Change(t[k], "da", 1, float(seq[k + 1])) for k in np.flatnonzero(np.diff(seq))]
        seq = np.r_[before[2], run.spindle_rpm]
        changes += [Change(t[k], "spindle_rpm", 1, float(seq[k + 1])) for k in np.flatnonzero(np.diff(seq))]
        self._pos = run.samples[-1].copy()
        self._dout = run.dout[-1].tolist()
        self._aout = run.aout[-1].tolist()
        self._spindle = float(run.spindle_rpm[-1])
        events = tuple(Event("message", 0.0, "", text) for text in run.messages)
        return DeviceLog(self.spec, self.machine.names, run.servo_period, t, steps, position, None, changes,
                         events, run.outcome, self.state())
