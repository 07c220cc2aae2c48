"""Programs for GRBL: a Trajectory or Steps as G1 moves, or G-code text as given.

GRBL plans its own acceleration, so flowmc sends it the *geometry* and the *speed*: the trajectory's
setpoints thinned by Douglas-Peucker to within ``tolerance`` mm (every signal time is kept as a
point), each kept point a ``G1`` whose F is the average speed since the previous kept point, so a
planned slow-down survives. Where the trajectory stands still the gap becomes a ``G4`` dwell. A
step stream (the linkage pulse table) becomes the positions it steps through, thinned the same way.

Signals become M-codes before the move that starts at their time: ``spindle_rpm`` -> M3/M4 S or M5,
digital output 1 -> M8/M9 (GRBL's flood-coolant pin, the usual relay for a pen or air valve), and
the tool (pen) state -> a pair of commands when a pen is configured (``pen=PEN_COMMANDS`` =
("M3 S1000", "M5") for down and up: the usual GRBL pen plotter drives its pen servo or solenoid from
the spindle PWM output, M3 S<power> down, M5 up). Without a pen (the default, as on a mill, where a
rapid does not lift anything) tool events are not sent. A program with tool events starts with the tool up: the up command
follows the preamble, before the move to the start. With commands that use the spindle, a program
that also sets the spindle is refused (one would overwrite the other). GRBL has no other outputs that flowmc can drive;
other signals
are refused, naming the signal. The program's operator stops (its ``events``: M0, M60, M6, an
indexing stop, and M1 when ``optional_stop``) become ``M0`` (GRBL 1.1 pauses on M0 once its planner
has run empty and waits for cycle start ``~``; it ignores M1 and refuses M6), placed among the
signal codes as the program orders them, each with a source that says what it was. A step stream's
signal times are in ticks when it is untimed (the
``Steps`` convention).
"""

from __future__ import annotations

import re
from typing import NamedTuple, Sequence

import numpy as np

from flowmc.errors import DeviceError
from flowmc.motion.machine import Machine
from flowmc.motion.path import describe_segment
from flowmc.motion.trajectory import Signal, Steps, Trajectory

__all__ = ["ProgramLine", "motion_gcode", "program_rows", "signal_code", "text_gcode", "decimate", "PEN_COMMANDS",
           "check_pen_commands"]

PREAMBLE = ("G21", "G90", "G94")  # millimetres, absolute, feed per minute
#: Tool (pen) down and up: the spindle output as GRBL pen plotters wire it.
PEN_COMMANDS = ("M3 S1000", "M5")
_SPINDLE_WORD = re.compile(r"(?:^|[^A-Z])(?:M0*[345](?!\d)|S)", re.IGNORECASE)
_MIN_DWELL_S = 0.001


class ProgramLine(NamedTuple):
    """A line to send and where it came from (``"setpoint 120 of segment 5 (row 4)"``, ``"part.ngc:12"``,
    ``"preamble"``); ``row``: the program's setpoint row it belongs to (-1: none, e.g. the preamble)."""

    text: str
    source: str
    row: int = -1


def _num(x: float) -> str:
    text = f"{x:.4f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def decimate(points: np.ndarray, tolerance: float, keep=()) -> np.ndarray:
    """Indices of the points Douglas-Peucker keeps (first, last, ``keep`` and any point off the chord by > tol)."""
    n = len(points)
    if n <= 2:
        return np.arange(n)
    forced = np.unique(np.concatenate([[0, n - 1], np.asarray(keep, dtype=int)]))
    kept = set(forced.tolist())
    stack = list(zip(forced[:-1].tolist(), forced[1:].tolist()))
    while stack:
        i, j = stack.pop()
        if j - i < 2:
            continue
        a, b = points[i], points[j]
        ab = b - a
        inner = points[i + 1:j] - a
        denom = float(ab @ ab)
        if denom > 0:
            u = np.clip(inner @ ab / denom, 0.0, 1.0)
            dist = np.linalg.norm(inner - np.outer(u, ab), axis=1)
        else:
            dist = np.linalg.norm(inner, axis=1)
        k = int(np.argmax(dist))
        if dist[k] > tolerance:
            m = i + 1 + k
            kept.add(m)
            stack += [(i, m), (m, j)]
    return np.array(sorted(kept))


def _row_source(unit: str, row: int, segment: np.ndarray, names: tuple[str, ...]) -> str:
    """Where a move line came from: its setpoint (or step) and that row's segment as users count it."""
    if not len(segment):
        return f"{unit} {row}"
    return f"{unit} {row} of {describe_segment(int(segment[row]), names)}"


def check_pen_commands(pen) -> tuple[str, str] | None:
    """The (down, up) tool commands, checked: one printable line each; None (no pen) passes as None."""
    if pen is None:
        return None
    if len(pen) != 2:
        raise DeviceError(f"pen commands are a (down, up) pair, got {pen!r}", where="grbl")
    for name, text in zip(("down", "up"), pen):
        if not isinstance(text, str) or not text.strip() or not text.isprintable() or not text.isascii():
            raise DeviceError(f"pen {name} command must be one line of G-code, got {text!r}", where="grbl")
    return pen[0].strip(), pen[1].strip()


def _signal_codes(sig: Signal, i: int, pen: tuple[str, str] | None) -> str:
    """The line for signal ``i``; "" for a tool signal when there is no pen."""
    return signal_code(str(sig.kind[i]), int(sig.channel[i]), float(sig.value[i]), pen,
                       f"signal {i} at t={sig.t[i]:g} s")


def signal_code(kind: str, ch: int, value: float, pen: tuple[str, str] | None, where: str) -> str:
    """The G-code line that sets output ``kind``/``ch`` to ``value``; "" for the tool without a pen."""
    if kind == "tool":
        return "" if pen is None else pen[0] if value else pen[1]
    if kind == "spindle_rpm":
        return "M5" if value == 0 else f"{'M3' if value > 0 else 'M4'} S{_num(abs(value))}"
    if kind == "dout" and ch == 1:
        return "M8" if value else "M9"
    raise DeviceError(f"GRBL cannot drive {kind} channel {ch} (only the spindle, and output 1 as flood "
                      f"coolant M8/M9)", where=where)


def program_rows(motion: Trajectory | Steps, machine: Machine, signals: Signal | None = None):
    """(positions, seconds per row, segment per row, "setpoint"/"step", merged signals, row per signal,
    seconds per signal-time unit) of a program as GRBL gets it; DeviceError for axes GRBL lacks."""
    bad = [a for a in motion.axes if a not in ("X", "Y", "Z")]
    if bad:
        raise DeviceError(f"GRBL drives X, Y and Z; the program also moves {', '.join(bad)}", where="grbl")
    if isinstance(motion, Trajectory):
        pos, dt = np.asarray(motion.positions), motion.period
        seg, unit = np.asarray(motion.segment), "setpoint"
    elif isinstance(motion, Steps):
        pos = motion.positions()
        seg, unit = np.concatenate([motion.segment[:1], motion.segment]), "step"  # row 0 is the origin
        if motion.tick > 0:
            dt = motion.tick
        else:  # untimed: as fast as the slowest moving axis allows
            cols = [machine.names.index(a) for a in motion.axes]
            dt = float(np.max(motion.step_mm / machine.column("vmax")[cols]))
    else:
        raise DeviceError(f"GRBL runs a Trajectory, Steps or G-code text, not {type(motion).__name__}", where="grbl")
    sig = motion.signals if signals is None else motion.signals.merged(signals)
    per_row = dt if not (isinstance(motion, Steps) and motion.tick <= 0) else 1.0  # untimed: ticks
    sig_rows = sig.rows(per_row, 0, len(pos) - 1)
    return pos, dt, seg, unit, sig, sig_rows, per_row


def motion_gcode(motion: Trajectory | Steps, machine: Machine, signals: Signal | None = None,
                 tolerance: float = 0.01, pen: tuple[str, str] | None = None, optional_stop: bool = False,
                 *, start_row: int | None = None, approach: Sequence[ProgramLine] = ()) -> list[ProgramLine]:
    """G-code lines for a trajectory or step stream (axes X, Y, Z only: GRBL's).

    ``pen``: the (down, up) commands for tool signals, or None to send none. ``start_row``: start the
    program at this row instead of its first, after the ``approach`` lines (which bring the machine
    there in the state the program built before it: the signals up to that row are not sent again,
    nor the stops before it).
    """
    pen = check_pen_commands(pen)
    pos, dt, seg, unit, sig, sig_rows, per_row = program_rows(motion, machine, signals)
    kinds = set(sig.kind.tolist())
    if pen is not None and {"tool", "spindle_rpm"} <= kinds and any(_SPINDLE_WORD.search(c) for c in pen):
        i = int(np.flatnonzero(sig.kind == "tool")[0])
        raise DeviceError(f"the program sets the spindle and lifts and lowers the tool, whose commands "
                          f"({pen[0]!r} / {pen[1]!r}) drive the spindle too; give the pen commands that do not "
                          f"(e.g. M8 / M9) or none", where=f"signal {i} at t={sig.t[i]:g}")
    r0 = 0 if start_row is None else int(start_row)
    stops = _stop_rows(motion, seg, optional_stop, per_row, len(pos), int(seg[r0]) if start_row is not None else None)
    keep = np.concatenate([sig_rows, [row for row, _n, _s in stops]]).astype(int)
    kept = r0 + decimate(pos[r0:], tolerance, keep=keep[keep >= r0] - r0)
    lines = [ProgramLine(t, "preamble") for t in PREAMBLE]
    if pen is not None and "tool" in kinds:  # a program's tool starts up, before the move to its start
        lines.append(ProgramLine(pen[1], "preamble (tool up)"))
    source = lambda row: _row_source(unit, int(row), seg, motion.segment_names)  # noqa: E731
    if start_row is None:
        start = " ".join(f"{a}{_num(v)}" for a, v in zip(motion.axes, pos[0]))
        lines.append(ProgramLine(f"G0 {start}", source(0), 0))
    else:
        lines += approach
    codes: dict[int, list[ProgramLine]] = {}  # row -> signal lines (every signal row is a kept point)
    for i in np.argsort(sig_rows, kind="stable"):
        code = _signal_codes(sig, int(i), pen)
        row = int(sig_rows[i])
        if code and (start_row is None or row > r0):  # up to the start row: the approach restored it
            codes.setdefault(row, []).append(ProgramLine(code, f"signal {int(i)}", row))
    for row, before, said in reversed(stops):  # after the program's own signals that come before it
        at = codes.setdefault(row, [])
        at.insert(min(before, len(at)), ProgramLine("M0", said, row))
    for prev, row in zip(kept[:-1], kept[1:]):
        lines += codes.get(int(prev), [])
        step = pos[row] - pos[prev]
        length = float(np.linalg.norm(step))
        seconds = (row - prev) * dt
        if length < 1e-9:
            if seconds >= _MIN_DWELL_S:
                lines.append(ProgramLine(f"G4 P{_num(seconds)}", source(row), int(prev)))
            continue
        words = " ".join(f"{a}{_num(v)}" for a, v, d in zip(motion.axes, pos[row], step) if abs(d) > 0)
        lines.append(ProgramLine(f"G1 {words} F{_num(length / seconds * 60.0)}", source(row), int(prev)))
    lines += codes.get(int(kept[-1]), [])
    return lines


def _stop_rows(motion, seg: np.ndarray, optional_stop: bool, per_row: float, n: int,
               from_segment: int | None = None) -> list[tuple[int, int, str]]:
    """(row, how many of the row's signal codes come first, source) of each operator stop, in order;
    ``from_segment``: only the stops at it and after it (a stop before a mid-program start is behind it)."""
    own = motion.signals.rows(per_row, 0, n - 1)
    out = []
    for e in motion.events:
        if e.kind == "optional_pause" and not optional_stop or from_segment is not None and e.segment < from_segment:
            continue
        row = min(int(np.searchsorted(seg, e.segment, side="left")), n - 1)
        said = e.said
        where = motion.segment_names[e.segment] if e.segment < len(motion.segment_names) else ""
        out.append((row, int(np.count_nonzero(own[:e.signals_before] >= row)),
                    f"{e.what}{': ' + said if said else ''} at {where or describe_segment(e.segment, ())}"))
    return out


def text_gcode(text: str, name: str = "program") -> list[ProgramLine]:
    """Lines of G-code text as GRBL takes them: comments, blank lines and ``%`` removed, sources kept."""
    out = []
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.split(";", 1)[0]
        while "(" in line and ")" in line[line.index("("):]:
            a = line.index("(")
            line = line[:a] + line[line.index(")", a) + 1:]
        line = line.strip()
        if line and line != "%":
            out.append(ProgramLine(line, f"{name}:{number}"))
    return out
