"""The look-ahead planner for real programs: smooth within the tolerance, then the fastest per-axis time law.

``plan_smooth`` = flowmc.motion.smoothing (corners and runs of short segments within the tolerance:
tangent-continuous for the trapezoid profile, curvature-continuous for the jerk-limited one) +
flowmc.motion.timelaw (per-axis velocity, acceleration and, for ``profile="scurve"``, jerk limits
along the curve; the whole program at once, so "look-ahead" is the entire program) + sampling at
t = kT. The tool is on the smoothed curve at every setpoint; every setpoint is tagged with the
programmed segment it is on. A jerk-limited law is first planned without mending the swings of its
acceleration (timelaw's ``mend_swings``: a bound that stacks every jerk term at its worst), and planned on
to mend them (timelaw.plan_jerk_limited: from where the first try stopped) only if its sampled setpoints break a
jerk limit. Where the curvature-change term of the
jerk holds the speed, the samples are then retimed by flowmc.motion.jerk_retime (within every per-axis
limit, from the samples), and kept if faster.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from flowmc.errors import PlanningError
from flowmc.motion.curve import PlannedCurve
from flowmc.motion.jerk_retime import retime_curvature_bound
from flowmc.motion.limits import PathLimits
from flowmc.motion.machine import Machine
from flowmc.motion.path import Path
from flowmc.motion.pieces import _check_axes
from flowmc.motion.reshape import faster_reshaped
from flowmc.motion.signals import path_signals, program_events, segment_start_times
from flowmc.motion.smoothing import Smoothed, raw_curve, smooth_path
from flowmc.motion.timelaw import (
    TimeLaw,
    plan_jerk_limited,
    sample_time_law,
    sampled_accel,
    sampled_jerk,
    samples_of,
    trapezoid_laws,
)
from flowmc.motion.trajectory import Trajectory

__all__ = ["SmoothPlan", "plan_smooth", "PROFILES"]

PROFILES = ("trapezoid", "scurve")
_BLEND_SHARE = 0.015  # lone corners are weighed for blends where stops at them make up this share of the plan
_BLEND_SLACK = 0.02  # a blended jerk-limited plan is retimed when its time law takes at most this much longer
_TIGHT_REACH = (0.5, 2.0, 8.0, np.inf)  # mm of curve parameter either side of samples over amax where a trapezoid
# law is planned again under the normal terms' own cap, round by round


@dataclass(frozen=True, eq=False)
class SmoothPlan:
    """A planned program: setpoints, the curve parameter u of each, and how it was smoothed and timed.

    ``corner_times`` is empty: every corner is smoothed (or stopped at), none is passed sharply. ``law`` is
    the time law the setpoints come from; where flowmc.motion.jerk_retime retimed a stretch, they run faster.
    """

    trajectory: Trajectory
    u: np.ndarray
    smoothed: Smoothed
    law: TimeLaw
    corner_times: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def cycle_time(self) -> float:
        return self.trajectory.duration

    @property
    def jerk_window(self) -> float:
        """Tj of the jerk-limiting filter (0 for trapezoid plans)."""
        return self.law.window


def plan_smooth(path: Path, machine: Machine, *, tolerance: float = 0.05,
                profile: Literal["trapezoid", "scurve"] = "trapezoid") -> SmoothPlan:
    """Plan ``path`` on ``machine`` with corners and short-segment runs smoothed within ``tolerance`` mm.

    PlanningError names the segment for bad input (gaps, feeds, axes the machine lacks).
    """
    if profile not in PROFILES:
        raise PlanningError(f"unknown profile {profile!r}; choose one of {', '.join(PROFILES)}", where="planner")
    lim = PathLimits.of(machine)
    jerk = profile == "scurve"
    _check_axes(path, list(lim.cols), machine)  # the one check every planner makes (flowmc.motion.pieces)
    raw = raw_curve(path)  # the programmed path as a curve: smoothing and reshaping both measure against it
    sm = smooth_path(path, lim, tolerance, continuity=2 if jerk else 1, as_curve=raw)
    known = None  # the trapezoid time law of sm.curve and its laws for other tight ranges, where reshaping worked them out
    if not jerk:  # programmed arcs reshaped for the per-axis limits, where the time law passes them faster
        sm, known = faster_reshaped(sm, raw[0], lim, tolerance, lambda curve: trapezoid_laws(
            curve, sm.stop_u, sm.stop_dwell, sm.stop_segment, _feed(sm.seg_feed, curve), lim))
    if sm.stopped is None:
        law, u, dwell_seg, pos = _timed(path, machine, lim, sm, jerk, known)
        if jerk:
            law, u, dwell_seg, pos = _retimed(path, machine, lim, sm, law, u, dwell_seg, pos)
    else:
        sm, (law, u, dwell_seg, pos) = _blended_or_stopped(path, machine, lim, sm, sm.stopped, jerk)
    tags = np.where(dwell_seg >= 0, dwell_seg, sm.curve.segment_at(u))
    tags = np.maximum.accumulate(tags)
    cols = list(lim.cols)
    traj = Trajectory(pos[:, cols], machine.period, tags, axes=lim.axes,
                      signals=path_signals(path, segment_start_times(tags, machine.period, len(path))),
                      segment_names=path.segment_names(), segment_rapid=path.segment_rapid(), events=program_events(path))
    return SmoothPlan(traj, u, sm, law)


def _blended_or_stopped(path: Path, machine: Machine, lim: PathLimits, sm: Smoothed, stopped: Smoothed, jerk: bool):
    """The smoothing (``sm`` or ``stopped``, ``sm.stopped``) and its timed, retimed samples that pass ``sm``'s lone corners
    soonest: on jerk-limited blends, or stopped at. The time law alone passes a blend at its slowest all through
    it; the retiming (linear programs, costly) lets the speed dip at its middle only; stopping wins at sharp
    turns (star10's 144 degrees). Blends are weighed only where the stops at them (a rest of Tj each, and more)
    are _BLEND_SHARE of the stopped plan or more; the blended plan is retimed where its time law takes at most
    _BLEND_SLACK longer than the stopped one's, and kept if it then beats that law; else the stopped plan is
    retimed too and the faster kept."""
    law, u, dwell_seg, pos = _timed(path, machine, lim, stopped, jerk)
    fast = None
    if sm.blends * law.window >= _BLEND_SHARE * len(u) * machine.period:
        blended = _timed(path, machine, lim, sm, jerk, most=(1.0 + _BLEND_SLACK) * len(u))
        if blended is not None:
            fast = _retimed(path, machine, lim, sm, *blended)
    if fast is None or len(fast[1]) >= len(u):
        slow = _retimed(path, machine, lim, stopped, law, u, dwell_seg, pos)
        if fast is None or len(slow[1]) < len(fast[1]):
            return stopped, slow
    return sm, fast


def _timed(path: Path, machine: Machine, lim: PathLimits, sm: Smoothed, jerk: bool,
           known: tuple[TimeLaw, Callable] | None = None, most: float = np.inf):
    """The time law on a smoothed curve (``known``: the trapezoid law already worked out for it, and the function
    that gives it for tight ranges, ``trapezoid_laws``) and its samples; None if a jerk-limited plan has more
    than ``most`` samples (a blended plan no use against the stopped one; its mended law is then not sampled)."""
    curve = sm.curve

    def sampled(law: TimeLaw):
        u, dwell_seg = sample_time_law(law, curve, machine.period, axes=len(lim.cols))
        pos = curve.points(u)
        pos[0], pos[-1] = path.start, path.end
        return law, u, dwell_seg, pos

    args = (curve, sm.stop_u, sm.stop_dwell, sm.stop_segment, _feed(sm.seg_feed, curve), lim)
    if jerk:
        law, mended = plan_jerk_limited(*args)
        law, u, dwell_seg, pos = sampled(law)
        if sampled_jerk(pos[:, list(lim.cols)], lim) > 1.0:  # a swing of the acceleration broke the jerk limit: mend them all
            better = mended()
            if better is not law:
                if samples_of(better, machine.period) > most:
                    return None
                law, u, dwell_seg, pos = sampled(better)
        return (law, u, dwell_seg, pos) if len(u) <= most else None
    if known is None:
        laws = trapezoid_laws(*args)
        law = laws(None)
    else:
        law, laws = known
    law, u, dwell_seg, pos = sampled(law)
    tight = np.zeros((0, 2))
    for reach in _TIGHT_REACH:
        # above the normal terms' own cap the law keeps the limits at three points of each interval only: where
        # a sample breaks one, that cap again about it (the last reach: everywhere, the law before branch spiral12)
        over = sampled_accel(pos[:, list(lim.cols)], lim)
        if not over.size:
            break
        tight = np.r_[tight, np.c_[u[over - 1] - reach, u[over + 1] + reach]]
        law, u, dwell_seg, pos = sampled(laws(tight))
    return law, u, dwell_seg, pos


def _feed(seg_feed: np.ndarray, curve: PlannedCurve):
    """The path-speed cap at curve parameter u: its programmed segment's feed."""
    def feed_of_u(u):
        return seg_feed[curve.segment_at(u)]
    return feed_of_u


def _retimed(path: Path, machine: Machine, lim: PathLimits, sm: Smoothed, law, u, dwell_seg, pos):
    """A jerk-limited plan's samples, retimed by flowmc.motion.jerk_retime where that gains."""
    retimed = retime_curvature_bound(law, sm.curve, lim, _feed(sm.seg_feed, sm.curve), machine.period, sm.blend_u)
    if retimed is not None and len(retimed[0]) < len(u):
        u, dwell_seg, pos = retimed
        pos[0], pos[-1] = path.start, path.end
    return law, u, dwell_seg, pos
