"""Run G-code on a simulated LinuxCNC machine and read back what it executed.

``run_program`` writes the simulator configuration (config/flowmc_sim.ini.in with
the Machine's limits, config/flowmc_sim.hal, config/tool.tbl) and the program into
a fresh directory, starts LinuxCNC with our display program (display.py, under the
system Python that has the ``linuxcnc`` module), and returns the joint positions
HAL's ``sampler`` recorded every servo period, with the motion type and program
line of each period. A program LinuxCNC refuses raises GcodeError naming the line;
the machine is stopped and every LinuxCNC process ended before it is raised.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path
from string import Template
from typing import Callable

import numpy as np

from flowmc.devices.linuxcnc.rs274 import run_rs274
from flowmc.devices.linuxcnc.session import Session
from flowmc.errors import DeviceError, GcodeError, LimitError
from flowmc.motion.machine import Machine
from flowmc.motion.trajectory import Trajectory

__all__ = ["LinuxCNCRun", "StartState", "run_program", "render_ini", "home_position", "SERVO_PERIOD",
           "MOTION_TRAVERSE", "MOTION_FEED", "MOTION_ARC"]

HERE = Path(__file__).resolve().parent
CONFIG = HERE / "config"
SERVO_PERIOD = 0.001
#: motion.motion-type values (LinuxCNC's EMC_MOTION_TYPE_*): 0 is idle.
MOTION_TRAVERSE, MOTION_FEED, MOTION_ARC = 1, 2, 3
_COLUMNS = 14  # halsampler -t: tag, then the 13 columns flowmc_sim.hal samples
_STARTUP_S = 60.0  # start-up plus shut-down allowance on a busy machine


@dataclass(frozen=True, eq=False)
class LinuxCNCRun:
    """What LinuxCNC executed, one row per servo period, from rest before the first move to rest after the last.

    samples: (N, 3) joint (= axis) positions X Y Z in mm; motion_type: (N,) 0 idle, 1 traverse,
    2 feed, 3 arc; program_line: (N,) line of the program being executed; dout (N, 4) bool,
    aout (N, 2) V, spindle_rpm (N,) signed; messages: what LinuxCNC told the operator on the way
    ((MSG, ...) comments; an error stops the run and raises instead); end_position: where
    LinuxCNC reports the machine at the end; gcode: the program as run; outcome: "done", or
    "aborted"/"estop" when a command ended the program early (the rows then end with the outputs safe).
    """

    samples: np.ndarray
    motion_type: np.ndarray
    program_line: np.ndarray
    dout: np.ndarray
    aout: np.ndarray
    spindle_rpm: np.ndarray
    servo_period: float
    messages: tuple[str, ...]
    end_position: np.ndarray
    gcode: str
    outcome: str = "done"

    @property
    def feed_time(self) -> float:
        """Cycle time of the feed moves: servo periods spent in feed or arc motion."""
        return float(np.count_nonzero(np.isin(self.motion_type, (MOTION_FEED, MOTION_ARC)))) * self.servo_period

    @property
    def duration(self) -> float:
        return (len(self.samples) - 1) * self.servo_period

    def trajectory(self) -> Trajectory:
        """The executed motion as a flowmc Trajectory (period = servo period, segment = program line)."""
        return Trajectory(self.samples, self.servo_period, self.program_line)


def home_position(machine: Machine) -> np.ndarray:
    """Where the machine homes by default: X Y Z = 0, each clipped into its axis's travel."""
    by_name = {a.name.upper(): a for a in machine.axes}
    return np.array([min(max(0.0, by_name[n].min), by_name[n].max) if n in by_name else 0.0 for n in "XYZ"])


def _axis_limits(machine: Machine, home: np.ndarray) -> dict[str, str]:
    """INI fields for X, Y, Z from the Machine (an axis it lacks is held still at 0)."""
    fields = {}
    by_name = {a.name.upper(): a for a in machine.axes}
    for k, name in enumerate("XYZ"):
        ax = by_name.get(name)
        lo, hi, v, a = (ax.min, ax.max, ax.vmax, ax.amax) if ax else (-1.0, 1.0, 1.0, 1.0)
        if not lo <= home[k] <= hi:
            raise DeviceError(f"home {home[k]:g} mm is outside axis {name}'s travel {lo:g}..{hi:g} mm",
                              where="linuxcnc")
        fields.update({f"{name}_MIN": repr(float(lo)), f"{name}_MAX": repr(float(hi)),
                       f"{name}_VMAX": repr(float(v)), f"{name}_AMAX": repr(float(a)),
                       f"{name}_HOME": repr(float(home[k]))})
    return fields


@dataclass(frozen=True)
class StartState:
    """What the machine starts a run with: home position X Y Z (None: ``home_position``), the
    four digital outputs, the two analog outputs (V) and the spindle (rpm, signed)."""

    home: np.ndarray | None = None
    dout: tuple[bool, bool, bool, bool] = (False, False, False, False)
    aout: tuple[float, float] = (0.0, 0.0)
    spindle_rpm: float = 0.0


def _check_period(servo_period: float) -> None:
    if not (1e-4 <= servo_period <= 0.01):
        raise DeviceError(f"servo period must be between 0.1 and 10 ms, got {servo_period * 1e3:g} ms",
                          where="linuxcnc")


def render_ini(machine: Machine, *, program: str, display: str, dir: Path, servo_period: float,
               timeout: float, start: "StartState", keep_on: tuple[int, ...] = (),
               optional_stop: bool = False) -> str:
    """The simulator INI for this machine; ``program`` and ``display`` are absolute paths, ``dir`` the run directory."""
    _check_period(servo_period)
    fields = _axis_limits(machine, start.home if start.home is not None else home_position(machine))
    xyz = [a for a in machine.axes if a.name.upper() in ("X", "Y", "Z")]
    fields.update(
        DISPLAY=display, PROGRAM=program, EVENTS=str(dir / "events.jsonl"), RESULT=str(dir / "result.json"),
        SAMPLES=str(dir / "samples.txt"), COMMANDS=str(dir / "commands"), KEEP_ON=" ".join(map(str, keep_on)),
        OPTIONAL_STOP="1" if optional_stop else "0",
        TIMEOUT=repr(float(timeout)), SERVO_PERIOD_NS=str(round(servo_period * 1e9)),
        TRAJ_VMAX=repr(max(a.vmax for a in xyz)) if xyz else "1.0",
        TRAJ_AMAX=repr(max(a.amax for a in xyz)) if xyz else "1.0",
        DOUT=" ".join("1" if on else "0" for on in start.dout),
        AOUT=" ".join(repr(float(v)) for v in start.aout), SPINDLE_RPM=repr(float(start.spindle_rpm)),
    )
    return Template((CONFIG / "flowmc_sim.ini.in").read_text()).substitute(fields)


def _parse_samples(text: str) -> np.ndarray:
    rows = [r for r in text.splitlines() if len(r.split()) == _COLUMNS]  # a torn last line is dropped
    data = np.array(" ".join(rows).split(), dtype=float).reshape(-1, _COLUMNS)
    if len(data) and np.any(np.diff(data[:, 0]) != 1):
        raise DeviceError("halsampler lost samples (the machine was too busy to keep up)", where="linuxcnc")
    return data[:, 1:]


_LIMIT = re.compile(r"on line (\d+) would exceed")


def _refusal(result: dict, gcode: str, name: str) -> GcodeError | LimitError:
    """LinuxCNC's first error, naming the program line.

    Soft-limit refusals say their line. Interpreter messages do not, and by the time one arrives
    the task has reset its line counters; the standalone interpreter (rs274, the same code) stops
    on the same line with the same message, so it names the line when the messages agree.
    """
    messages = [m["text"].strip() for m in result.get("messages", []) if m.get("error")]
    text = messages[0] if messages else (result.get("errors") or [{"text": "unknown failure"}])[0]["text"]
    limit = _LIMIT.search(text)
    if limit:
        return LimitError(f"LinuxCNC refused the program: {text}", where=f"{name}:{limit.group(1)}")
    where = name
    try:
        run_rs274(gcode, name=name)
    except GcodeError as exc:
        if exc.message.startswith(text[:60]):
            where = exc.where
    return GcodeError(f"LinuxCNC refused the program: {text}", where=where)


def run_program(gcode: str, machine: Machine | None = None, *, servo_period: float = SERVO_PERIOD,
                timeout: float = 300.0, name: str = "program.ngc", start: StartState = StartState(),
                on_progress: Callable[[int], None] | None = None, keep_dir: bool = False,
                on_event: Callable[[dict], None] | None = None,
                commands: Callable[[], list[str]] | None = None, keep_on: tuple[int, ...] = (),
                optional_stop: bool = False) -> LinuxCNCRun:
    """Run G-code text on the simulated LinuxCNC machine with ``machine``'s X/Y/Z limits.

    The machine homes in place at ``start.home`` (default: 0 clipped into each axis's travel) and
    sets its outputs and spindle as ``start`` says; the program moves from there. ``timeout`` (s)
    bounds the program; ``on_progress(line)`` is called as the executed program line changes. Raises GcodeError
    (``name:line``) for a program LinuxCNC refuses and
    LimitError (``name:line``) for one that would leave an axis's travel, DeviceError when LinuxCNC
    cannot run or does not finish; LinuxCNC is shut down either way.

    While the program runs, ``commands()`` is asked every 20 ms for operator commands (``pause``,
    ``resume``, ``abort``, ``estop``; see display.py), which LinuxCNC's task carries out; an abort or
    e-stop leaves the spindle off and the outputs off but ``keep_on`` (1-based) and returns the run so
    far with that ``outcome``. ``on_event(event)`` gets every event the display program writes
    (state: holding/held/running/stopping/safe, position at 25 Hz, progress, messages).
    """
    machine = machine if machine is not None else Machine()
    _check_period(servo_period)

    def follow(event: dict) -> None:
        if on_progress is not None and event.get("kind") == "progress":
            on_progress(int(event["line"]))
        if on_event is not None:
            on_event(event)

    session = Session(keep=keep_dir)

    def poll() -> None:
        for command in commands() if commands is not None else ():
            session.send(command)

    try:
        program = session.write("program.ngc", gcode)
        session.write("flowmc_sim.hal", (CONFIG / "flowmc_sim.hal").read_text())
        session.write("tool.tbl", (CONFIG / "tool.tbl").read_text())
        ini = session.write("flowmc_sim.ini", render_ini(
            machine, program=str(program), display=str(session.display_wrapper(HERE / "display.py")),
            dir=session.dir, servo_period=servo_period, timeout=timeout, start=start, keep_on=keep_on,
            optional_stop=optional_stop))
        session.run(ini, timeout + _STARTUP_S, follow, poll)
        result_path = session.path("result.json")
        if not result_path.exists():
            tail = "\n".join(session.log.strip().splitlines()[-8:])
            raise DeviceError(f"LinuxCNC ended without running the program:\n{tail}", where="linuxcnc")
        result = json.loads(result_path.read_text())
        data = _parse_samples(session.path("samples.txt").read_text())
    finally:
        session.cleanup()
    if result["status"] == "timeout":
        raise DeviceError(result["errors"][0]["text"], where="linuxcnc")
    if result.get("overruns"):
        raise DeviceError(f"the sampler lost {result['overruns']} samples (the machine was too busy to keep up)",
                          where="linuxcnc")
    if result["status"] not in ("done", "aborted", "estop"):
        raise _refusal(result, gcode, name)
    return _make_run(data, result, servo_period, gcode)


def _make_run(data: np.ndarray, result: dict, servo_period: float, gcode: str) -> LinuxCNCRun:
    # From the last rest row before anything moves to the first rest row after. motion-type drops
    # to 0 one period before the final position step, so position changes count as well.
    mtype = data[:, 3].astype(int)
    active = mtype != 0
    active[1:] |= np.any(data[1:, 0:3] != data[:-1, 0:3], axis=1)
    active[1:] |= np.any(data[1:, 5:] != data[:-1, 5:], axis=1)  # outputs and spindle changing
    rows = np.flatnonzero(active)
    lo, hi = (max(rows[0] - 1, 0), min(rows[-1] + 1, len(data))) if rows.size else (0, len(data))
    d = data[lo:hi]
    return LinuxCNCRun(
        samples=d[:, 0:3].copy(), motion_type=d[:, 3].astype(int), program_line=d[:, 4].astype(int),
        dout=d[:, 5:9].astype(bool), aout=d[:, 9:11].copy(), spindle_rpm=d[:, 11] * np.where(d[:, 12] > 0, 1.0, 0.0),
        servo_period=servo_period,
        messages=tuple(m["text"] for m in result.get("messages", [])),
        end_position=np.array(result["position"], dtype=float), gcode=gcode, outcome=result["status"],
    )
