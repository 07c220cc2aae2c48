"""A machine's limits as planners, interpolators, metrics and pre-flight read them: one place, one meaning.

- **Per axis, by name.** ``AxisLimits`` holds vmax, amax and jmax of named axes (a trajectory's
  axes, or X/Y/Z for path columns). Limits are always per axis: a diagonal move may be faster
  along the path than any one axis's limit, never on an axis.
- **Path columns.** Planners move along paths in X, Y, Z. ``PathLimits`` gives each column its
  axis's limits (``inf`` for a column the machine lacks: a path must not move along it) and the
  path-speed, acceleration and jerk limits along a direction, ``min_i limit_i / |u_i|``.
- **A rapid's feed.** Every segment's ``feed`` is its path-speed cap in mm/s, rapids included: a
  rapid's feed is the rapid rate that its source gave it (G-code leaves the rate to the machine;
  flowmc's G-code reader gives G0 moves ``RAPID_FEED`` = 200 mm/s unless told otherwise). Every
  axis stays within its own vmax as well. So a diagonal rapid is no faster than the rapid rate
  along the path, and no axis is faster than its vmax, as on LinuxCNC, whose rapids run at the
  trajectory's maximum velocity with each axis capped.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from flowmc.errors import PlanningError
from flowmc.motion.machine import Machine

__all__ = ["FIELDS", "AxisLimits", "PathLimits", "axis_limits", "segment_feed"]

FIELDS = ("vmax", "amax", "jmax")
_XYZ = "XYZ"


@dataclass(frozen=True, eq=False)
class AxisLimits:
    """vmax (mm/s), amax (mm/s^2) and jmax (mm/s^3) of the named axes, in the order given."""

    names: tuple[str, ...]
    vmax: np.ndarray
    amax: np.ndarray
    jmax: np.ndarray

    @classmethod
    def of(cls, machine: Machine, names) -> "AxisLimits":
        """The limits of the machine's axes called ``names`` (case-insensitive); ValueError naming any it lacks."""
        by_name = {ax.name.upper(): ax for ax in machine.axes}
        names = tuple(names)
        missing = [n for n in names if n.upper() not in by_name]
        if missing:
            raise ValueError(f"axes {missing} are not machine axes {machine.names}")
        cols = [by_name[n.upper()] for n in names]
        return cls(names, *(np.array([getattr(ax, f) for ax in cols], dtype=float) for f in FIELDS))

    def field(self, name: str) -> np.ndarray:
        """One of vmax, amax, jmax as an array over the axes."""
        if name not in FIELDS:
            raise ValueError(f"unknown limit {name!r}; one of {', '.join(FIELDS)}")
        return getattr(self, name)


def axis_limits(machine: Machine, names, field: str) -> np.ndarray:
    """One limit (vmax, amax or jmax) for each named axis: ``axis_limits(m, traj.axes, "amax")``."""
    return AxisLimits.of(machine, names).field(field)


@dataclass(frozen=True, eq=False)
class PathLimits:
    """Limits of the path columns X, Y, Z and the interpolation period.

    ``cols``: the columns the machine drives, in the machine's axis order; ``vmax``/``amax``/``jmax``: (3,)
    arrays with ``inf`` for columns the machine lacks.
    """

    cols: tuple[int, ...]
    vmax: np.ndarray
    amax: np.ndarray
    jmax: np.ndarray
    period: float

    @classmethod
    def of(cls, machine: Machine) -> "PathLimits":
        """PlanningError when the machine has none of X, Y, Z."""
        cols, lim = [], {f: np.full(3, np.inf) for f in FIELDS}
        for ax in machine.axes:
            k = _XYZ.find(ax.name.upper())
            if len(ax.name) != 1 or k < 0:
                continue
            cols.append(k)
            for f in FIELDS:
                lim[f][k] = getattr(ax, f)
        if not cols:
            raise PlanningError("the machine has none of the axes X, Y, Z", where="machine")
        return cls(tuple(cols), lim["vmax"], lim["amax"], lim["jmax"], machine.period)

    @property
    def axes(self) -> tuple[str, ...]:
        return tuple(_XYZ[c] for c in self.cols)

    def along(self, u) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Path speed, acceleration and jerk limits along unit directions ``u`` (n, 3): exact for a line,
        ``min_i limit_i / |u_i|`` over the axes that move."""
        mag = np.abs(np.asarray(u, dtype=float)).reshape(-1, 3)
        moving = mag > 1e-12
        safe = np.where(moving, mag, 1.0)
        return tuple(np.min(np.where(moving, lim / safe, np.inf), axis=1) for lim in (self.vmax, self.amax, self.jmax))

    def over(self, moved) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The smallest vmax, amax and jmax among the axes each row of ``moved`` (n, 3) bool moves."""
        moved = np.asarray(moved, dtype=bool).reshape(-1, 3)
        return tuple(np.min(np.broadcast_to(lim, moved.shape), axis=1, initial=np.inf, where=moved)
                     for lim in (self.vmax, self.amax, self.jmax))

    def smallest(self) -> tuple[float, float, float]:
        """The smallest vmax, amax and jmax among the machine's X, Y, Z: the bound of an interpolator
        that applies one limit to every direction."""
        v, a, j = (float(np.min(lim[list(self.cols)])) for lim in (self.vmax, self.amax, self.jmax))
        return v, a, j


def segment_feed(seg, where: str) -> float:
    """A segment's path-speed cap (mm/s): its ``feed``, for rapids as for feed moves.

    PlanningError naming ``where`` when the feed is not a positive finite number.
    """
    feed = seg.feed
    if not (isinstance(feed, (int, float)) and not isinstance(feed, bool) and feed > 0 and math.isfinite(feed)):
        raise PlanningError(f"feed must be > 0 mm/s, got {feed!r}", where=where)
    return float(feed)
