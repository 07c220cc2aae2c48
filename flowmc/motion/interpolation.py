"""Whole-path interpolators: the time-division loop and the NURBS Taylor interpolator over a Path.

Both turn a Path into setpoints at the machine's period T, one segment after another, and apply
one limit to every direction: the smallest vmax and amax among the machine's X, Y, Z
(``PathLimits.smallest``), so every axis keeps its own limit whichever way the path goes. Every
segment's feed, rapids included, is its path-speed cap (flowmc.motion.limits). Where a move
turns, the normal and the tangential acceleration each get amax/sqrt(2), so the total stays
within amax.

- ``time_division``: the data-sampling interpolator of the DSP and LabVIEW theses. Every segment
  runs from rest to rest with a trapezoid, exponential or S-curve profile; lines map distance to
  points exactly, arcs step by the exact rotation or the second-order recurrence (flowmc.motion.timediv),
  ellipses and NURBS by arc length. Arcs and curves are held to the chord error eps.
- ``nurbs_taylor``: the second-order Taylor interpolator with a chord corrector (flowmc.motion.nurbs)
  over every segment of a path of NURBS curves.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

import flowmc.budget as budget
from flowmc.errors import PathError, PlanningError
from flowmc.motion import nurbs, profiles, timediv
from flowmc.motion.limits import PathLimits, segment_feed
from flowmc.motion.machine import Machine
from flowmc.motion.path import PLANES, Arc, Dwell, EllipseArc, Line, NurbsCurve, Path, describe_segment
from flowmc.motion.signals import path_signals, program_events
from flowmc.motion.trajectory import Trajectory

__all__ = ["TimeDivision", "NurbsTaylor", "time_division", "nurbs_taylor", "check_joined"]

_SPLIT = 1.0 / math.sqrt(2.0)  # share of amax for each of the normal and tangential accelerations


def check_joined(path: Path) -> None:
    """PathError unless the path has segments and each starts where the one before ends."""
    if not path.segments:
        raise PathError("the path is empty", where="path")
    gaps = path.gaps(1e-6)
    if gaps:
        i = gaps[0]
        raise PathError(f"does not start where {describe_segment(i - 1, path.segments[i - 1].source)} ends",
                        where=describe_segment(i, path.segments[i].source))


def _assemble(chunks: list[np.ndarray], period: float, path: Path) -> Trajectory:
    """Join per-segment setpoints (each starting where the previous ended) into one trajectory."""
    pts, seg_idx, starts = [], [], []
    count = 0
    for i, chunk in enumerate(chunks):
        starts.append(max(count - 1, 0) * period)
        if count:
            chunk = chunk[1:]  # its first point is the previous segment's last
        pts.append(chunk)
        seg_idx.append(np.full(len(chunk), i, dtype=int))
        count += len(chunk)
    return Trajectory(np.vstack(pts), period, np.concatenate(seg_idx), signals=path_signals(path, starts),
                      segment_names=path.segment_names(), segment_rapid=path.segment_rapid(), events=program_events(path))


# ---------------------------------------------------------------- time division

@dataclass(frozen=True, eq=False)
class TimeDivision:
    """Setpoints, the largest chord error on arcs and the largest |radius error| of arc setpoints (the drift)."""

    trajectory: Trajectory
    chord_error: float
    radial_error: float


def _profile(kind: str, length: float, vcap: float, amax: float, jmax: float) -> profiles.Profile:
    if kind == "trapezoid":
        return profiles.plan_trapezoid(length, 0.0, 0.0, vcap, amax)
    if kind == "exponential":
        return profiles.plan_exponential(length, 0.0, 0.0, vcap, amax)
    if kind == "scurve":
        return profiles.plan_scurve(length, 0.0, 0.0, vcap, amax, jmax)
    raise PlanningError(f"unknown profile {kind!r}; choose trapezoid, exponential or scurve", where="time division")


def time_division(path: Path, machine: Machine, *, profile: Literal["trapezoid", "exponential", "scurve"] = "scurve",
                  arc_method: Literal["exact", "second_order"] = "exact", eps: float = 0.001) -> TimeDivision:
    """Interpolate every segment from rest to rest at the machine's period (see the module docstring)."""
    check_joined(path)
    vmax, amax, jmax = PathLimits.of(machine).smallest()
    period = machine.period
    chunks: list[np.ndarray] = []
    worst_chord, worst_radial = 0.0, 0.0
    for i, seg in enumerate(path.segments):
        where = describe_segment(i, seg.source)
        budget.check("setpoints", sum(len(c) for c in chunks), what=f"interpolating up to {where}",
                     change="raise the feeds, shorten the program, or lengthen the machine's period")
        if isinstance(seg, Dwell):
            budget.check("setpoints", seg.seconds / period, what=f"a dwell of {seg.seconds:g} s", where=where,
                         change="shorten the dwell, or lengthen the machine's period")
            chunks.append(np.repeat(seg.start[None, :], max(math.ceil(seg.seconds / period - 1e-9), 0) + 1, 0))
            continue
        feed = min(segment_feed(seg, where), vmax)
        accel = amax
        if isinstance(seg, Arc):
            radius = seg.radius
        elif isinstance(seg, Line):
            radius = math.inf
        else:  # ellipse or NURBS: sampled by arc length, bounded by its tightest radius
            assert isinstance(seg, (EllipseArc, NurbsCurve)), type(seg).__name__
            radius = seg.min_radius
        if math.isfinite(radius):
            accel = amax * _SPLIT
            feed = min(feed, timediv.arc_feed_limit(radius, period, eps), math.sqrt(accel * radius))
        budget.check("setpoints", seg.length / feed / period if feed > 0 else math.inf, where=where,
                     what=f"interpolating {seg.length:.6g} mm at {feed:.6g} mm/s",
                     change="raise the feed, shorten the move, or lengthen the machine's period")
        try:
            s = profiles.sample_profile(_profile(profile, seg.length, feed, accel, jmax), period)
        except PlanningError as exc:
            raise PlanningError(exc.message, where=where) from None
        if isinstance(seg, Line):
            pts = timediv.line_points(seg.start, seg.end, s)
        elif isinstance(seg, Arc):
            plane = PLANES[seg.normal_axis][1]
            pts = timediv.arc_points(seg.start, seg.end, seg.center, s, ccw=seg.ccw, plane=plane,
                                     turns=seg.turns, method=arc_method)
            chord, radial = timediv.circle_errors(pts, seg.center, radius, plane)
            worst_chord = max(worst_chord, float(chord.max()) if len(chord) else 0.0)
            worst_radial = max(worst_radial, float(np.abs(radial).max()))
        else:
            pts = seg.point_at(s)
        chunks.append(pts)
    return TimeDivision(_assemble(chunks, period, path), worst_chord, worst_radial)


# ---------------------------------------------------------------- NURBS, Taylor

@dataclass(frozen=True, eq=False)
class NurbsTaylor:
    """Setpoints, the largest feed fluctuation |chord/T - V|/V (a fraction) and the largest chord error (mm)."""

    trajectory: Trajectory
    fluctuation: float
    chord_error: float


def nurbs_taylor(path: Path, machine: Machine, *, feed: float | None = None, eps: float = 0.001,
                 corrector: int = 1) -> NurbsTaylor:
    """Interpolate every NURBS segment of ``path`` by the Taylor step with ``corrector`` Newton steps,
    at ``feed`` (mm/s; None: each segment's own), capped by the machine's smallest vmax."""
    check_joined(path)
    vmax, amax, _ = PathLimits.of(machine).smallest()
    period = machine.period
    chunks, worst_fluct, worst_chord = [], 0.0, 0.0
    for i, seg in enumerate(path.segments):
        where = describe_segment(i, seg.source)
        if not isinstance(seg, NurbsCurve):
            raise PathError(f"is a {seg.kind}, not a NURBS curve: use the time-division interpolator", where=where)
        curve = nurbs.Nurbs(seg.control_points, seg.weights, seg.knots, seg.degree, where=where)
        speed = min(feed or segment_feed(seg, where), vmax)
        steps = nurbs.taylor_steps(curve, speed, period, eps=eps, amax=amax * _SPLIT, corrector=corrector)
        fluct = nurbs.feed_fluctuation(steps)[:-1]  # the last, partial step is exact by definition
        worst_fluct = max(worst_fluct, float(fluct.max()) if len(fluct) else 0.0)
        worst_chord = max(worst_chord, float(nurbs.chord_errors(curve, steps.u).max()))
        chunks.append(steps.points)
    return NurbsTaylor(_assemble(chunks, period, path), worst_fluct, worst_chord)
