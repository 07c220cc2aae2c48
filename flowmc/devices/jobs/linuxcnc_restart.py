"""Starting a LinuxCNC program at segment N: the setpoints LinuxCNC is handed instead of the program's.

LinuxCNC runs the setpoints it is given as a G1 polyline (``card.trajectory_gcode``), so a start at
segment N hands it ``restart.plan_start``'s setpoints instead of the program's: the approach rows
(Z up, across, the restored outputs and spindle with a spin-up dwell, Z down) and then the program
from the segment's first row, with the signals at their rows and the program's stops from N on.
The driver reads LinuxCNC's lines back as rows of these setpoints, and ``original`` names each row's
row in the user's program (-1 on the approach).
"""

from __future__ import annotations

import numpy as np

from flowmc.devices.jobs.restart import plan_job_start
from flowmc.motion.trajectory import Signal, Trajectory

__all__ = ["start_motion"]


def start_motion(job, card, start_segment: int) -> tuple[Trajectory, np.ndarray, list[str]]:
    """The setpoints that start ``job`` at ``start_segment`` (0-based) from where ``card`` stands, the
    original row of each (-1 on the approach), and what that assumes."""
    motion, machine = job.motion, card.machine
    pos, seg, period, _axes = card.setpoint_rows(motion)
    names = machine.names
    here = card.position()
    nominal = np.tile(here, (len(pos), 1))
    for k, axis in enumerate(motion.axes):
        nominal[:, names.index(axis)] = pos[:, k]
    sig = motion.signals.merged(job.signals)
    sig_rows = sig.rows(period, 0, len(pos) - 1)
    signals = sorted(((int(r), str(k), int(c), float(v)) for r, k, c, v in  # the tool drives no LinuxCNC output
                      zip(sig_rows, sig.kind, sig.channel, sig.value) if k != "tool"), key=lambda s: s[0])
    state = card.state()
    now = {("dout", ch): float(on) for ch, on in enumerate(state["dout"], 1)}
    now.update({("spindle_rpm", 1): float(state["spindle_rpm"]), ("da", 1): float(state["aout"][0]), ("tool", 0): 0.0})
    plan = plan_job_start(job, nominal, seg, signals, np.zeros(len(pos), dtype=bool), here, machine, now,
                          start_segment)
    shift = plan.junction - plan.program_row
    new_sig = Signal([row * period for row, *_ in plan.signals], [s[1] for s in plan.signals],
                     [s[2] for s in plan.signals], [s[3] for s in plan.signals])
    own_rows = motion.signals.rows(period, 0, len(pos) - 1)
    new_rows = np.array([row for row, *_ in plan.signals], dtype=int)
    events = []
    for e in motion.events:  # the stops from the start on, after the same signals as in the program
        if e.segment < start_segment:
            continue
        row = min(int(np.searchsorted(seg, e.segment, side="left")), len(pos) - 1)
        same_row = int(np.count_nonzero(own_rows[:e.signals_before] == row))
        events.append(e._replace(signals_before=int(np.count_nonzero(new_rows < row + shift)) + same_row))
    seg_new = np.maximum(plan.segment, start_segment)  # the approach is named by the segment it goes to
    # a step of rounding noise (1e-16 mm where a move ends) would be a G1 with feed 0, which LinuxCNC refuses
    moved = np.r_[True, np.linalg.norm(np.diff(plan.positions, axis=0), axis=1) >= 1e-9]
    positions = plan.positions[np.maximum.accumulate(np.where(moved, np.arange(len(moved)), 0))]
    trajectory = Trajectory(positions, period, seg_new, names, new_sig, motion.segment_names,
                            motion.segment_rapid, events)
    original = np.concatenate([np.full(plan.junction, -1), np.arange(plan.program_row, len(pos))])
    return trajectory, original, list(plan.assumptions)
