"""Interpolator nodes over flowmc.motion: the NURBS Taylor interpolator and the time-division one.

Both turn a Path into setpoints at the machine's period T. Limits come from the machine's X/Y/Z
axes (the smallest vmax, amax, jmax among them). Where a move turns, the normal and the tangential
acceleration each get amax/sqrt(2), so the total stays within amax.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from flowmc.errors import NodeError, PathError, PlanningError
from flowmc.motion import nurbs, profiles, timediv
from flowmc.motion.machine import Machine, default_machine
from flowmc.motion.path import PLANES, Arc, Dwell, Line, NurbsCurve, Path, describe_segment
from flowmc.motion.signals import path_signals
from flowmc.motion.trajectory import Trajectory
from flowmc.registry import In, NodeType, Out, register

_MM = {"unit": "mm"}
_MM_S = {"unit": "mm/s"}
_SPLIT = 1.0 / math.sqrt(2.0)  # share of amax for each of the normal and tangential accelerations

_PATH_IN = In("path", "Path", doc="Path to interpolate")
_MACHINE_IN = In("machine", "Machine", doc="Axis limits and period T (default: the default machine)", default=None)
_TRAJ_OUT = Out("trajectory", "Trajectory", doc="Setpoints at period T")


def _limits(machine: Machine) -> tuple[float, float, float]:
    axes = [a for a in machine.axes if a.name in ("X", "Y", "Z")] or list(machine.axes)
    return min(a.vmax for a in axes), min(a.amax for a in axes), min(a.jmax for a in axes)


def _check_joined(path: Path) -> None:
    if not path.segments:
        raise NodeError("the path is empty")
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
                      segment_names=path.segment_names())


# ---------------------------------------------------------------- NURBS interpolator

class NurbsInterpParams(BaseModel):
    model_config = ConfigDict(extra="forbid")

    feed: Annotated[float | None, Field(gt=0, description="Feed; empty: each segment's own feed",
                                        json_schema_extra=_MM_S)] = None
    eps: Annotated[float, Field(gt=0, description="Chord error bound", json_schema_extra=_MM)] = 0.001
    corrector: Annotated[int, Field(ge=0, le=4, description="Newton steps making each Taylor step's chord "
                                                             "exactly V*T (0: predictor only)")] = 1
    control_points: Annotated[list[tuple[float, float, float]] | None,
                              Field(description="Control points, used when no path is wired",
                                    json_schema_extra=_MM)] = None
    weights: Annotated[list[float] | None, Field(description="Weights (default all 1)")] = None
    knots: Annotated[list[float] | None, Field(description="Knots, n + degree + 1 (default clamped uniform)")] = None
    degree: Annotated[int, Field(ge=1, le=7, description="Degree")] = 3


@register
class NurbsInterpolator(NodeType):
    type_id = "interp.nurbs"
    title = "NURBS interpolator"
    category = "Interpolation"
    description = "Second-order Taylor NURBS interpolation with a chord corrector, feed adapted to curvature."
    Params = NurbsInterpParams
    inputs = (In("path", "Path", doc="Path of NURBS segments (else the control points below)", default=None),
              _MACHINE_IN)
    outputs = (_TRAJ_OUT,
               Out("fluctuation_pct", "Number", doc="Largest feed fluctuation |chord/T - V|/V, percent"),
               Out("chord_error", "Number", doc="Largest chord error (mm)"))

    def run(self, ctx, params: NurbsInterpParams, path: Path | None = None, machine: Machine | None = None):
        machine = machine or default_machine()
        if path is None:
            if params.control_points is None:
                raise NodeError("wire a path or give control points")
            path = Path([NurbsCurve(params.control_points, params.weights, params.knots, params.degree,
                                    feed=params.feed or 50.0, source=f"node {ctx.node_id}")])
        _check_joined(path)
        vmax, amax, _ = _limits(machine)
        period = machine.period
        chunks, worst_fluct, worst_chord = [], 0.0, 0.0
        for i, seg in enumerate(path.segments):
            where = describe_segment(i, seg.source)
            if not isinstance(seg, NurbsCurve):
                raise PathError(f"is a {seg.kind}, not a NURBS curve: use the time-division interpolator",
                                where=where)
            curve = nurbs.Nurbs(seg.control_points, seg.weights, seg.knots, seg.degree, where=where)
            feed = min(params.feed or seg.feed, vmax)
            steps = nurbs.taylor_steps(curve, feed, period, eps=params.eps, amax=amax * _SPLIT,
                                       corrector=params.corrector)
            fluct = nurbs.feed_fluctuation(steps)[:-1]  # the last, partial step is exact by definition
            worst_fluct = max(worst_fluct, float(fluct.max()) if len(fluct) else 0.0)
            worst_chord = max(worst_chord, float(nurbs.chord_errors(curve, steps.u).max()))
            chunks.append(steps.points)
        traj = _assemble(chunks, period, path)
        ctx.log(f"{len(traj)} setpoints, max feed fluctuation {100 * worst_fluct:.3g} %, "
                f"max chord error {worst_chord * 1e3:.3g} um")
        return {"trajectory": traj, "fluctuation_pct": 100.0 * worst_fluct, "chord_error": worst_chord}


# ---------------------------------------------------------------- time-division interpolator

class TimeDivisionParams(BaseModel):
    model_config = ConfigDict(extra="forbid")

    profile: Annotated[Literal["trapezoid", "exponential", "scurve"],
                       Field(description="Velocity profile of each segment (stop and go)")] = "scurve"
    arc_method: Annotated[Literal["exact", "second_order"],
                          Field(description="Arc step: exact rotation, or cos ~ 1 - d^2/2, sin ~ d (drifts)")] = "exact"
    eps: Annotated[float, Field(gt=0, description="Chord error bound on arcs and curves",
                                json_schema_extra=_MM)] = 0.001


def _profile(kind: str, length: float, vcap: float, amax: float, jmax: float) -> profiles.Profile:
    if kind == "trapezoid":
        return profiles.plan_trapezoid(length, 0.0, 0.0, vcap, amax)
    if kind == "exponential":
        return profiles.plan_exponential(length, 0.0, 0.0, vcap, amax)
    return profiles.plan_scurve(length, 0.0, 0.0, vcap, amax, jmax)


@register
class TimeDivisionInterpolator(NodeType):
    type_id = "interp.time_division"
    title = "Time-division interpolator"
    category = "Interpolation"
    description = "Data-sampling interpolation at period T: each segment from rest to rest with the chosen profile."
    Params = TimeDivisionParams
    inputs = (_PATH_IN, _MACHINE_IN)
    outputs = (_TRAJ_OUT,
               Out("chord_error", "Number", doc="Largest chord error on arcs (mm)"),
               Out("radial_error", "Number", doc="Largest |radius error| of arc setpoints (mm): the drift"))

    def run(self, ctx, params: TimeDivisionParams, path: Path, machine: Machine | None = None):
        machine = machine or default_machine()
        _check_joined(path)
        vmax, amax, jmax = _limits(machine)
        period, eps = machine.period, params.eps
        chunks, worst_chord, worst_radial = [], 0.0, 0.0
        for i, seg in enumerate(path.segments):
            where = describe_segment(i, seg.source)
            if isinstance(seg, Dwell):
                chunks.append(np.repeat(seg.start[None, :], max(math.ceil(seg.seconds / period - 1e-9), 0) + 1, 0))
                continue
            feed = vmax if seg.rapid else min(seg.feed, vmax)
            accel = amax
            if isinstance(seg, Arc):
                radius = seg.radius
            elif isinstance(seg, Line):
                radius = math.inf
            else:  # ellipse or NURBS: sampled by arc length, bounded by its tightest radius
                radius = seg.min_radius
            if math.isfinite(radius):
                accel = amax * _SPLIT
                feed = min(feed, timediv.arc_feed_limit(radius, period, eps), math.sqrt(accel * radius))
            try:
                s = profiles.sample_profile(_profile(params.profile, seg.length, feed, accel, jmax), period)
            except PlanningError as exc:
                raise PlanningError(exc.message, where=where) from None
            if isinstance(seg, Line):
                pts = timediv.line_points(seg.start, seg.end, s)
            elif isinstance(seg, Arc):
                plane = PLANES[seg.normal_axis][1]
                pts = timediv.arc_points(seg.start, seg.end, seg.center, s, ccw=seg.ccw, plane=plane,
                                         turns=seg.turns, method=params.arc_method)
                chord, radial = timediv.circle_errors(pts, seg.center, radius, plane)
                worst_chord = max(worst_chord, float(chord.max()) if len(chord) else 0.0)
                worst_radial = max(worst_radial, float(np.abs(radial).max()))
            else:
                pts = seg.point_at(s)
            chunks.append(pts)
        traj = _assemble(chunks, period, path)
        ctx.log(f"{len(traj)} setpoints over {traj.duration:.3f} s ({params.profile}, arcs {params.arc_method})")
        return {"trajectory": traj, "chord_error": worst_chord, "radial_error": worst_radial}
