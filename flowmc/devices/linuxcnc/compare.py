"""flowmc's plan of a program beside what LinuxCNC executed for the same program.

``compare_trajectories`` takes two sampled trajectories and the programmed path and
measures both the same way (flowmc.motion.metrics): cycle time of the feed moves, the
largest deviation of each tool path from the other and from the programmed path, and
peak velocity and acceleration per axis from finite differences of the samples.
``compare_path`` plans the path with flowmc's look-ahead planner (unless given a
trajectory), runs it as G-code on LinuxCNC and compares (``flowmc compare`` and the
Compare node use it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flowmc.devices.linuxcnc.backend import MOTION_ARC, MOTION_FEED, SERVO_PERIOD, LinuxCNCRun, run_program
from flowmc.motion.gcode_write import path_to_gcode
from flowmc.motion.machine import Machine, default_machine
from flowmc.motion.metrics import contour_error, programmed_polyline
from flowmc.motion.path import Dwell, Path
from flowmc.motion.table import Table
from flowmc.motion.trajectory import Trajectory

__all__ = ["Comparison", "compare_trajectories", "compare_path", "flowmc_feed_time"]

AXES = ("X", "Y", "Z")


@dataclass(frozen=True, eq=False)
class Comparison:
    """The report (a Table: quantity, unit, flowmc, linuxcnc) and what it was measured on."""

    table: Table
    flowmc: Trajectory
    linuxcnc: LinuxCNCRun
    gcode: str

    def value(self, quantity: str, side: str) -> float:
        """One cell, e.g. ``value("feed cycle time", "linuxcnc")``."""
        rows = list(self.table["quantity"])
        return float(self.table[side][rows.index(quantity)])

    def text(self) -> str:
        """The table as aligned text."""
        rows = [("quantity", "unit", "flowmc", "linuxcnc")]
        rows += [(q, u, f"{f:.4f}", f"{lc:.4f}") for q, u, f, lc in zip(self.table["quantity"], self.table["unit"],
                                                                       self.table["flowmc"], self.table["linuxcnc"])]
        widths = [max(len(r[i]) for r in rows) for i in range(4)]
        return "\n".join("  ".join(c.ljust(w) if i < 2 else c.rjust(w) for i, (c, w) in enumerate(zip(r, widths)))
                         for r in rows)


def flowmc_feed_time(traj: Trajectory, path: Path) -> float:
    """Periods flowmc's trajectory spends on feed moves (segments that are neither rapid nor a dwell)."""
    feed = np.array([not (seg.rapid or isinstance(seg, Dwell)) for seg in path.segments] + [False])
    seg = np.clip(traj.segment[1:], 0, len(path.segments))
    moved = np.any(np.diff(traj.positions, axis=0) != 0, axis=1)
    return float(np.count_nonzero(feed[seg] & moved)) * traj.period


def _peaks(positions: np.ndarray, period: float) -> tuple[np.ndarray, np.ndarray]:
    v = np.diff(positions, axis=0) / period
    a = np.diff(v, axis=0) / period
    vmax = np.abs(v).max(axis=0) if len(v) else np.zeros(positions.shape[1])
    amax = np.abs(a).max(axis=0) if len(a) else np.zeros(positions.shape[1])
    return vmax, amax


def compare_trajectories(flowmc: Trajectory, linuxcnc: LinuxCNCRun, path: Path) -> Table:
    """Side-by-side measures of flowmc's trajectory and LinuxCNC's executed motion for ``path``.

    LinuxCNC's record starts where it homed; the traverse from there to the path's start is left
    out of the deviations (it is not part of ``path``). Deviations are chord distances as in
    ``flowmc.motion.metrics.contour_error``.
    """
    cols = [AXES.index(a.upper()) for a in flowmc.axes if a.upper() in AXES]
    ours = np.zeros((len(flowmc), 3))
    ours[:, cols] = flowmc.positions[:, [i for i, a in enumerate(flowmc.axes) if a.upper() in AXES]]
    feed_rows = np.flatnonzero(np.isin(linuxcnc.motion_type, (MOTION_FEED, MOTION_ARC)))
    first = max(feed_rows[0] - 1, 0) if feed_rows.size else 0
    theirs = linuxcnc.samples[first:]
    programmed = programmed_polyline(path)
    v_ours, a_ours = _peaks(ours, flowmc.period)
    v_theirs, a_theirs = _peaks(linuxcnc.samples, linuxcnc.servo_period)
    rows = [
        ("feed cycle time", "s", flowmc_feed_time(flowmc, path), linuxcnc.feed_time),
        ("total time", "s", flowmc.duration, linuxcnc.duration),
        ("period", "s", flowmc.period, linuxcnc.servo_period),
        ("deviation from the other tool path", "mm", contour_error(ours, theirs), contour_error(theirs, ours)),
        ("deviation from the programmed path", "mm", contour_error(ours, programmed),
         contour_error(theirs, programmed)),
    ]
    rows += [(f"peak velocity {a}", "mm/s", v_ours[i], v_theirs[i]) for i, a in enumerate(AXES)]
    rows += [(f"peak acceleration {a}", "mm/s^2", a_ours[i], a_theirs[i]) for i, a in enumerate(AXES)]
    return Table({"quantity": [r[0] for r in rows], "unit": [r[1] for r in rows],
                  "flowmc": [float(r[2]) for r in rows], "linuxcnc": [float(r[3]) for r in rows]})


def compare_path(path: Path, machine: Machine | None = None, *, tolerance: float = 0.05,
                 flowmc: Trajectory | None = None, servo_period: float = SERVO_PERIOD) -> Comparison:
    """Plan ``path`` with flowmc (look-ahead, corners blended within ``tolerance`` mm) unless a
    trajectory is given, run it on LinuxCNC as G-code with ``G64 P<tolerance>``, and compare."""
    machine = machine if machine is not None else default_machine()
    if flowmc is None:
        from flowmc.motion.lookahead import plan_lookahead

        flowmc = plan_lookahead(path, machine, rule="blend", tolerance=tolerance).trajectory
    gcode = path_to_gcode(path, blend_tolerance=tolerance, comment="flowmc compare", events="dwells")
    run = run_program(gcode, machine, servo_period=servo_period, name="compare.ngc")
    return Comparison(compare_trajectories(flowmc, run, path), flowmc, run, gcode)
