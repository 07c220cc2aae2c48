"""Where a streamed job starts: the safe approach to its first point, and starting from segment N.

Starting mid-program is starting in a machine state the program built before that point. The plan
replays the program's signals up to there (spindle, outputs, PWM, DA, pen), then approaches
safely: pen up, Z up to the higher of where it is and where it goes, across at the axes' vmax and
amax, the outputs and spindle set (with a spin-up dwell when the spindle starts), Z down at a
quarter of its vmax, the pen set, and the program carries on from rest at its planned speed. What
was assumed is said in words, for the job log.

A whole job starts the same way when the tool is not at the program's start (without the restore).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from flowmc.devices.jobs.pauses import last_tool_before
from flowmc.devices.sim.moves import line_move
from flowmc.errors import DeviceError
from flowmc.motion.machine import Machine

__all__ = ["StartPlan", "plan_start", "plan_job_start", "SPIN_UP_S"]

SPIN_UP_S = 1.0  # seconds a restored spindle gets to reach speed before the tool goes down
PLUNGE_SHARE = 0.25  # Z goes down at this share of its vmax

# (row, kind, channel, value): a signal at a row of the nominal setpoints
SignalRow = tuple[int, str, int, float]


@dataclass
class StartPlan:
    """The setpoints to run (approach rows, then the program from its start row), the segment of each
    row (-1 on the approach), the signals by row, the row where the approach ends (the job comes to
    rest there, then the program starts from rest) and what was assumed."""

    positions: np.ndarray
    segment: np.ndarray
    signals: list[SignalRow]
    rapid: np.ndarray
    junction: int
    program_row: int  # row of the original program the plan's row ``junction`` is
    assumptions: list[str] = field(default_factory=list)


def _fmt_state(key: tuple[str, int], value: float) -> str:
    kind, ch = key
    if kind == "spindle_rpm":
        return "spindle off" if value == 0 else f"spindle {abs(value):,.0f} rpm {'cw' if value > 0 else 'ccw'}"
    if kind == "dout":
        return f"output {ch} {'on' if value else 'off'}"
    if kind == "tool":
        return f"pen/tool {'down' if value else 'up'}"
    if kind == "pwm_freq":
        return f"PWM {value:,.0f} Hz"
    if kind == "pwm_duty":
        return f"PWM duty {value:g} %"
    return f"DA {value:g} V"


def plan_start(nominal: np.ndarray, segment: np.ndarray, signals: list[SignalRow], rapid: np.ndarray,
               here: np.ndarray, machine: Machine, outputs_now: dict[tuple[str, int], float], *,
               start_segment: int | None = None, where=lambda seg: f"segment {seg + 1}") -> StartPlan:
    """The plan for a job whose tool is at ``here``; ``start_segment``: 0-based, None for the start."""
    row0 = 0
    assumptions: list[str] = []
    restore: list[tuple[str, int, float]] = []
    tool_at_start = None
    if start_segment is not None:
        rows = np.flatnonzero(segment == start_segment)
        if not len(rows):
            known = sorted(set(segment.tolist()) - {-1})
            raise ValueError(f"segment {start_segment + 1} has no setpoints in this job "
                             f"(it has segments {known[0] + 1}-{known[-1] + 1})" if known else "this job has no segments")
        row0 = int(rows[0])
        state = dict(outputs_now)
        for row, kind, ch, value in signals:
            if row <= row0 and kind != "pause":  # the segment's own start signals too; a stop is no state
                state[(kind, 0 if kind == "tool" else ch)] = value
        changed = {k: v for k, v in state.items() if outputs_now.get(k, 0.0) != v}
        tool_at_start = changed.pop(("tool", 0), None)
        order = sorted(changed, key=lambda k: (k[0] != "pwm_freq", k[0] == "spindle_rpm", k))
        restore = [(k[0], k[1], changed[k]) for k in order]
        point = nominal[row0]
        coords = ", ".join(f"{a} {v:.3f}" for a, v in zip(machine.names, point))
        assumptions.append(f"started at {where(start_segment)} at {coords} mm")
        if restore or tool_at_start is not None:
            said = [_fmt_state((k, c), v) for k, c, v in restore]
            if tool_at_start is not None:
                said.append(_fmt_state(("tool", 0), tool_at_start))
            assumptions.append("machine state rebuilt from the program before it: " + ", ".join(said))
        else:
            assumptions.append("the program sets no outputs before it: outputs left as they are")
        assumptions.append("assumed: the same tool, work offsets and workpiece as when the program reached this "
                           "point (no tool change, nothing moved by hand)")
        assumptions.append("feed: the program's planned speed, reached from rest within the axes' acceleration")
    target = nominal[row0]
    vmax, amax = machine.column("vmax"), machine.column("amax")
    T = machine.period
    pieces: list[np.ndarray] = []
    out_signals: list[SignalRow] = []
    offset = 0

    def add(move: np.ndarray) -> None:
        nonlocal offset
        pieces.append(move[1:] if pieces else move)
        offset = sum(len(p) for p in pieces) - 1

    add(here[None, :].astype(float))
    if not np.allclose(here, target, atol=1e-9) or restore:
        names = machine.names
        z = names.index("Z") if "Z" in names else None
        if z is not None:
            z_safe = max(here[z], target[z])
            up, across = here.copy(), target.copy()
            up[z] = across[z] = z_safe
            add(line_move(here, up, vmax, amax, T))
            add(line_move(up, across, vmax, amax, T))
            for kind, ch, value in restore:
                out_signals.append((offset, kind, ch, value))
            if any(k == "spindle_rpm" and v != 0 for k, _c, v in restore):
                add(np.repeat(across[None, :], int(round(SPIN_UP_S / T)) + 1, axis=0))
                assumptions.append(f"the spindle was given {SPIN_UP_S:g} s to reach speed before going down")
            add(line_move(across, target, vmax, amax, T, speed=PLUNGE_SHARE * vmax[z]))
            text = (f"approach: Z up to {z_safe:.3f} mm, across at the axes' vmax/amax, down to Z {target[z]:.3f} mm "
                    f"at {PLUNGE_SHARE * vmax[z]:g} mm/s")
        else:
            add(line_move(here, target, vmax, amax, T))
            for kind, ch, value in restore:
                out_signals.append((offset, kind, ch, value))
            text = "approach: a straight move at the axes' vmax/amax"
        if start_segment is not None or not np.allclose(here, target, atol=1e-9):
            assumptions.append(text)
    junction = offset
    if tool_at_start is not None:
        out_signals.append((junction, "tool", 0, tool_at_start))
    approach = np.vstack(pieces)
    body = nominal[row0:]
    positions = np.vstack([approach[:-1], body]) if len(approach) > 1 else body
    shift = junction - row0
    seg = np.concatenate([np.full(junction, -1, dtype=int), segment[row0:]])
    out_signals += [(row + shift, kind, ch, value) for row, kind, ch, value in signals
                    if row > row0 or row == row0 and (start_segment is None or kind == "pause")]
    out_signals.sort(key=lambda s: s[0])
    rapid_rows = np.concatenate([np.zeros(junction, dtype=bool), rapid[row0:]])
    return StartPlan(positions, seg, out_signals, rapid_rows, junction, row0, assumptions)


def plan_job_start(job, nominal: np.ndarray, segment: np.ndarray, signals: list[SignalRow], rapid: np.ndarray,
                   here: np.ndarray, machine: Machine, outputs_now: dict[tuple[str, int], float],
                   start_segment: int | None) -> StartPlan:
    """``plan_start`` for ``job`` on any device: a refusal is a DeviceError naming the job, and a start
    mid-program also assumes the last tool change before it is the tool loaded."""
    try:
        plan = plan_start(nominal, segment, signals, rapid, here, machine, outputs_now,
                          start_segment=start_segment, where=job.where)
    except ValueError as exc:
        raise DeviceError(str(exc), where=job.name or "job") from None
    tool = last_tool_before(job.motion, start_segment) if start_segment is not None and job.motion is not None else None
    if tool is not None:
        plan.assumptions.append(f"assumed: tool T{tool.tool} is loaded (the last tool change before it, "
                                f"{job.where(tool.segment)})")
    return plan
