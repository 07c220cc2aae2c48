"""flowmc's plan of a program beside what LinuxCNC executed for the same program, like with like.

Both sides are set up alike unless told otherwise: the same per-axis limits (the Machine), the same
period (LinuxCNC's servo period; flowmc plans at it), the same corner tolerance (G64 P for LinuxCNC,
the blend tolerance for flowmc) and the same kind of profile (LinuxCNC 2.9's planner limits
acceleration, not jerk, so flowmc plans trapezoids). Anything that still differs (a jerk-limited flowmc
profile, a trajectory planned elsewhere at another period, rapids LinuxCNC runs at its maximum
velocity) is listed in ``Comparison.differences`` and printed at the top of ``text()``.

Both sides are then measured the same way, from their samples (flowmc.motion.metrics): cycle time of
the feed moves, deviation from the programmed path both ways (samples to path and path to samples)
and from each other, the path speed over the programmed feed, and per-axis peak velocity,
acceleration and jerk over each axis's limit. A side that breaks a limit (feed over F, deviation over
the tolerance, an axis over its vmax, its amax with the README's 1 % sampling margin, or its jmax
when the side limits jerk) is flagged in the table's ``over`` column.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from flowmc.devices.linuxcnc.backend import MOTION_ARC, MOTION_FEED, SERVO_PERIOD, LinuxCNCRun, run_program
from flowmc.motion.gcode_write import path_to_gcode
from flowmc.motion.limits import AxisLimits
from flowmc.motion.machine import Machine, default_machine
from flowmc.motion.metrics import contour_error, coverage_error, feed_ratio, programmed_polyline
from flowmc.motion.path import Dwell, Path
from flowmc.motion.table import Table
from flowmc.motion.trajectory import Trajectory

__all__ = ["Settings", "Comparison", "compare_trajectories", "compare_path", "flowmc_feed_time"]

AXES = ("X", "Y", "Z")
ACCEL_MARGIN = 0.01  # sampled acceleration may exceed amax by this share (reference README)
SPEED_MARGIN = 1e-3  # and the path speed the feed by this (rounding of positions)


@dataclass(frozen=True)
class Settings:
    """How one side moves: profile kind, period (s), corner tolerance (mm) and whether jerk is limited."""

    profile: str
    period: float
    tolerance: float | None
    jerk_limited: bool

    def describe(self) -> str:
        tol = "unknown tolerance" if self.tolerance is None else f"tolerance {self.tolerance:g} mm"
        jerk = "jerk limited per axis" if self.jerk_limited else "jerk not limited"
        return f"{self.profile}, T = {self.period * 1e3:g} ms, {tol}, {jerk}"


def linuxcnc_settings(tolerance: float, servo_period: float) -> Settings:
    """LinuxCNC 2.9's trajectory planner: trapezoidal velocity (acceleration-limited), G64 P blends."""
    return Settings("trapezoid", servo_period, tolerance, False)


@dataclass(frozen=True, eq=False)
class Comparison:
    """The report and what it was measured on.

    ``table``: columns quantity, unit, flowmc, linuxcnc, limit (the bound a value is judged by, NaN for
    none) and over ("", "flowmc", "linuxcnc" or "both"). ``differences``: how the two sides were not
    set up alike (empty when they were).
    """

    table: Table
    flowmc: Trajectory
    linuxcnc: LinuxCNCRun
    gcode: str
    settings: tuple[Settings, Settings]
    differences: tuple[str, ...]

    def value(self, quantity: str, side: str) -> float:
        """One cell, e.g. ``value("feed cycle time", "linuxcnc")``."""
        rows = list(self.table["quantity"])
        return float(self.table[side][rows.index(quantity)])

    @property
    def broken(self) -> list[str]:
        """One line for every limit a side breaks."""
        out = []
        for q, u, f, lc, lim, over in zip(*(self.table[c] for c in ("quantity", "unit", "flowmc", "linuxcnc",
                                                                   "limit", "over"))):
            if over:
                sides = {"flowmc": [("flowmc", f)], "linuxcnc": [("LinuxCNC", lc)],
                         "both": [("flowmc", f), ("LinuxCNC", lc)]}[over]
                out += [f"{name}: {q} {v:.4g} {u} over {lim:.4g} {u}" for name, v in sides]
        return out

    def text(self) -> str:
        """Settings and differences at the top, then the table (a ``!`` marks a broken limit), then what broke."""
        head = [f"flowmc:   {self.settings[0].describe()}", f"LinuxCNC: {self.settings[1].describe()}"]
        head += ["differences: " + ("none" if not self.differences else "")]
        head += [f"  - {d}" for d in self.differences]
        cols = ("quantity", "unit", "flowmc", "linuxcnc", "limit")
        rows = [cols]
        for q, u, f, lc, lim, over in zip(*(self.table[c] for c in (*cols, "over"))):
            mark_f = "!" if over in ("flowmc", "both") else " "
            mark_l = "!" if over in ("linuxcnc", "both") else " "
            rows.append((q, u, f"{f:.4f}{mark_f}", f"{lc:.4f}{mark_l}", "" if np.isnan(lim) else f"{lim:.4g}"))
        widths = [max(len(r[i]) for r in rows) for i in range(len(cols))]
        body = ["  ".join(c.ljust(w) if i < 2 else c.rjust(w) for i, (c, w) in enumerate(zip(r, widths)))
                for r in rows]
        tail = ["limits broken: " + ("none" if not self.broken else "")] + [f"  ! {b}" for b in self.broken]
        return "\n".join(head + body + tail)


def flowmc_feed_time(traj: Trajectory, path: Path) -> float:
    """Periods flowmc's trajectory spends on feed moves (segments that are neither rapid nor a dwell)."""
    feed = np.array([not (seg.rapid or isinstance(seg, Dwell)) for seg in path.segments] + [False])
    seg = np.clip(traj.segment[1:], 0, len(path.segments))
    moved = np.any(np.diff(traj.positions, axis=0) != 0, axis=1)
    return float(np.count_nonzero(feed[seg] & moved)) * traj.period


def _xyz(traj_positions: np.ndarray, axes) -> np.ndarray:
    out = np.zeros((len(traj_positions), 3))
    for i, a in enumerate(axes):
        if a.upper() in AXES:
            out[:, AXES.index(a.upper())] = traj_positions[:, i]
    return out


def _peaks(positions: np.ndarray, period: float) -> list[np.ndarray]:
    """Largest sampled |v|, |a|, |j| per axis."""
    out, d = [], positions
    for _ in range(3):
        d = np.diff(d, axis=0) / period
        out.append(np.abs(d).max(axis=0) if len(d) else np.zeros(positions.shape[1]))
    return out


def compare_trajectories(flowmc: Trajectory, linuxcnc: LinuxCNCRun, path: Path, machine: Machine | None = None,
                         tolerance: float = 0.05, jerk_limited: tuple[bool, bool] = (False, False)) -> Table:
    """Side-by-side measures of flowmc's trajectory and LinuxCNC's executed motion for ``path``, each
    judged against ``machine``'s per-axis limits and the corner ``tolerance`` (see the module docstring).

    LinuxCNC's record starts where it homed; the traverse from there to the path's start is left
    out of the deviations (it is not part of ``path``).
    """
    machine = machine if machine is not None else default_machine()
    lim = AxisLimits.of(machine, [a for a in AXES if a in machine.names])
    vmax, amax, jmax = (np.array([getattr(lim, f)[list(lim.names).index(a)] if a in lim.names else np.inf
                                  for a in AXES]) for f in ("vmax", "amax", "jmax"))
    ours = _xyz(flowmc.positions, flowmc.axes)
    feed_rows = np.flatnonzero(np.isin(linuxcnc.motion_type, (MOTION_FEED, MOTION_ARC)))
    first = max(feed_rows[0] - 1, 0) if feed_rows.size else 0
    theirs = linuxcnc.samples[first:]
    programmed = programmed_polyline(path)
    peaks_ours = _peaks(ours, flowmc.period)
    peaks_theirs = _peaks(linuxcnc.samples, linuxcnc.servo_period)
    lc_feed = np.isin(linuxcnc.motion_type[first + 1:], (MOTION_FEED, MOTION_ARC))
    nan = float("nan")
    # (quantity, unit, flowmc, linuxcnc, limit for flowmc, limit for linuxcnc)
    rows = [
        ("feed cycle time", "s", flowmc_feed_time(flowmc, path), linuxcnc.feed_time, nan, nan),
        ("total time", "s", flowmc.duration, linuxcnc.duration, nan, nan),
        ("period", "s", flowmc.period, linuxcnc.servo_period, nan, nan),
        ("deviation from the programmed path", "mm", contour_error(ours, programmed),
         contour_error(theirs, programmed), tolerance, tolerance),
        ("deviation of the programmed path from the tool path", "mm", coverage_error(ours, programmed),
         coverage_error(theirs, programmed), tolerance, tolerance),
        ("deviation from the other tool path", "mm", contour_error(ours, theirs), contour_error(theirs, ours),
         nan, nan),
        ("peak path speed over the feed", "x F", feed_ratio(ours, flowmc.period, path),
         feed_ratio(theirs, linuxcnc.servo_period, path, lc_feed), 1.0 + SPEED_MARGIN, 1.0 + SPEED_MARGIN),
    ]
    for name, unit, k, limit, margin in (("velocity", "mm/s", 0, vmax, 0.0), ("acceleration", "mm/s^2", 1, amax,
                                                                            ACCEL_MARGIN),
                                         ("jerk", "mm/s^3", 2, jmax, 0.0)):
        for i, axis in enumerate(AXES):
            if not np.isfinite(limit[i]):
                continue
            bound = limit[i] * (1.0 + margin)
            bounds = [bound, bound]
            if name == "jerk":  # only a side that limits jerk is held to it
                bounds = [bound if jerk_limited[0] else nan, bound if jerk_limited[1] else nan]
            rows.append((f"peak {name} {axis}", unit, peaks_ours[k][i], peaks_theirs[k][i], *bounds))
    over = []
    for r in rows:
        f_over = not np.isnan(r[4]) and r[2] > r[4]
        l_over = not np.isnan(r[5]) and r[3] > r[5]
        over.append({(True, True): "both", (True, False): "flowmc", (False, True): "linuxcnc"}.get((f_over, l_over), ""))
    limit_col = [r[4] if not np.isnan(r[4]) else r[5] for r in rows]
    return Table({"quantity": [r[0] for r in rows], "unit": [r[1] for r in rows],
                  "flowmc": [float(r[2]) for r in rows], "linuxcnc": [float(r[3]) for r in rows],
                  "limit": [float(x) for x in limit_col], "over": over})


def compare_path(path: Path, machine: Machine | None = None, *, tolerance: float = 0.05,
                 profile: Literal["trapezoid", "scurve"] = "trapezoid",
                 flowmc: Trajectory | None = None, flowmc_settings: Settings | None = None,
                 servo_period: float = SERVO_PERIOD) -> Comparison:
    """Plan ``path`` with flowmc like LinuxCNC (same limits, period, tolerance; ``profile`` trapezoid unless
    told otherwise), run it on LinuxCNC as G-code with ``G64 P<tolerance>``, and compare.

    ``flowmc`` compares a trajectory planned elsewhere instead (``flowmc_settings``: how, when known);
    how it differs from LinuxCNC's set-up is listed in the comparison's ``differences``.
    """
    machine = machine if machine is not None else default_machine()
    theirs = linuxcnc_settings(tolerance, servo_period)
    if flowmc is None:
        from flowmc.motion.planner import plan_smooth

        flowmc = plan_smooth(path, machine.model_copy(update={"period": servo_period}), tolerance=tolerance,
                             profile=profile).trajectory
        ours = Settings(profile, servo_period, tolerance, profile == "scurve")
    else:
        ours = flowmc_settings or Settings("as given", flowmc.period, None, False)
    gcode = path_to_gcode(path, blend_tolerance=tolerance, comment="flowmc compare", events="dwells")
    run = run_program(gcode, machine, servo_period=servo_period, name="compare.ngc")
    table = compare_trajectories(flowmc, run, path, machine, tolerance, (ours.jerk_limited, theirs.jerk_limited))
    return Comparison(table, flowmc, run, gcode, (ours, theirs), tuple(_differences(ours, theirs, path, machine)))


def _differences(ours: Settings, theirs: Settings, path: Path, machine: Machine) -> list[str]:
    out = []
    if ours.profile != theirs.profile:
        out.append(f"profile: flowmc {ours.profile}, LinuxCNC {theirs.profile}")
    if ours.jerk_limited != theirs.jerk_limited:
        out.append("jerk: " + ("flowmc limits it per axis, LinuxCNC does not" if ours.jerk_limited
                               else "LinuxCNC limits it, flowmc does not"))
    if abs(ours.period - theirs.period) > 1e-12:
        out.append(f"period: flowmc {ours.period * 1e3:g} ms, LinuxCNC {theirs.period * 1e3:g} ms")
    if ours.tolerance is None:
        out.append(f"tolerance: flowmc's plan was made elsewhere (unknown), LinuxCNC G64 P{theirs.tolerance:g}")
    elif theirs.tolerance is None or abs(ours.tolerance - theirs.tolerance) > 1e-12:
        out.append(f"tolerance: flowmc {ours.tolerance:g} mm, LinuxCNC G64 P{theirs.tolerance:g}")
    xyz = [a for a in machine.axes if a.name.upper() in AXES]
    rapid_rate = max(a.vmax for a in xyz) if xyz else 0.0
    rapids = {float(s.feed) for s in path.segments if s.rapid}
    if any(abs(f - rapid_rate) > 1e-9 for f in rapids):
        out.append(f"rapids: flowmc runs each at its feed ({', '.join(f'{f:g}' for f in sorted(rapids))} mm/s), "
                   f"LinuxCNC at its maximum velocity ({rapid_rate:g} mm/s)")
    return out
