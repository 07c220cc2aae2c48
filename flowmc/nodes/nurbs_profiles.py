"""Interpolator nodes: the NURBS Taylor interpolator and the time-division one.

Thin adapters over flowmc.motion.interpolation, which holds both loops and their limits.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field

from flowmc.errors import NodeError
from flowmc.motion.interpolation import nurbs_taylor, time_division
from flowmc.motion.machine import Machine, default_machine
from flowmc.motion.path import NurbsCurve, Path
from flowmc.registry import In, NodeType, Out, register

_MM = {"unit": "mm"}
_MM_S = {"unit": "mm/s"}

_PATH_IN = In("path", "Path", doc="Path to interpolate")
_MACHINE_IN = In("machine", "Machine", doc="Axis limits and period T (default: the default machine)", default=None)
_TRAJ_OUT = Out("trajectory", "Trajectory", doc="Setpoints at period T")


# ---------------------------------------------------------------- NURBS interpolator

class NurbsInterpParams(BaseModel):
    model_config = ConfigDict(extra="forbid", defer_build=True)

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
        res = nurbs_taylor(path, machine, feed=params.feed, eps=params.eps, corrector=params.corrector)
        traj, worst_fluct, worst_chord = res.trajectory, res.fluctuation, res.chord_error
        ctx.log(f"{len(traj)} setpoints, max feed fluctuation {100 * worst_fluct:.3g} %, "
                f"max chord error {worst_chord * 1e3:.3g} um")
        return {"trajectory": traj, "fluctuation_pct": 100.0 * worst_fluct, "chord_error": worst_chord}


# ---------------------------------------------------------------- time-division interpolator

class TimeDivisionParams(BaseModel):
    model_config = ConfigDict(extra="forbid", defer_build=True)

    profile: Annotated[Literal["trapezoid", "exponential", "scurve"],
                       Field(description="Velocity profile of each segment (stop and go)")] = "scurve"
    arc_method: Annotated[Literal["exact", "second_order"],
                          Field(description="Arc step: exact rotation, or cos ~ 1 - d^2/2, sin ~ d (drifts)")] = "exact"
    eps: Annotated[float, Field(gt=0, description="Chord error bound on arcs and curves",
                                json_schema_extra=_MM)] = 0.001


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
        res = time_division(path, machine, profile=params.profile, arc_method=params.arc_method, eps=params.eps)
        traj = res.trajectory
        ctx.log(f"{len(traj)} setpoints over {traj.duration:.3f} s ({params.profile}, arcs {params.arc_method})")
        return {"trajectory": traj, "chord_error": res.chord_error, "radial_error": res.radial_error}
