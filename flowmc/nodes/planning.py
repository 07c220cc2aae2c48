"""Feed-planning nodes: the look-ahead planner, the stop-and-go baseline, and trajectory metrics.

The work is in flowmc.motion.lookahead and flowmc.motion.metrics; these adapt ports and params, and
# No ``from __future__ import annotations``: pydantic would compile every model field's annotation from
# its text when a cold ``flowmc validate`` builds the models (docs/architecture.md).
import the algorithms when they run (validating a graph needs only params and ports).
"""


from typing import TYPE_CHECKING, Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field

from flowmc.motion.machine import Machine, default_machine
from flowmc.registry import In, NodeType, Out, register

if TYPE_CHECKING:
    from flowmc.motion.path import Path
    from flowmc.motion.trajectory import Trajectory

_PATH_IN = In("path", "Path", doc="Program to plan")
_MACHINE_IN = In("machine", "Machine", doc="Per-axis limits and period T (default: the default machine)", default=None)
_TRAJ_OUT = Out("trajectory", "Trajectory", doc="Setpoints at period T, each tagged with its segment")
_CYCLE_OUT = Out("cycle_time", "Number", doc="Time to the last setpoint (s)")


class LookaheadParams(BaseModel):
    model_config = ConfigDict(extra="forbid", defer_build=True)

    rule: Annotated[Literal["blend", "arm_weighted", "junction_deviation"], Field(
        description="Junction speeds: round corners within the tolerance (G64 P style), the ARM paper's "
                    "angle-weighted rule, or GRBL's junction deviation")] = "blend"
    tolerance: Annotated[float, Field(gt=0, le=10.0, description="Corner tolerance (blend) or junction "
                                                                 "deviation (GRBL rule)",
                                      json_schema_extra={"unit": "mm"})] = 0.05
    profile: Annotated[Literal["trapezoid", "scurve"], Field(
        description="Velocity profile between junctions: trapezoid (acceleration-limited) or S-curve "
                    "(jerk-limited)")] = "trapezoid"


@register
class LookaheadPlanner(NodeType):
    type_id = "plan.lookahead"
    title = "Look-ahead planner"
    category = "Planning"
    description = "Plan the whole program: junction speeds by a rule, backward/forward passes, trapezoid or S-curve."
    Params = LookaheadParams
    inputs = (_PATH_IN, _MACHINE_IN)
    outputs = (_TRAJ_OUT, _CYCLE_OUT)

    def run(self, ctx, params: LookaheadParams, path: "Path", machine: Machine | None = None):
        from flowmc.motion.lookahead import plan_lookahead

        plan = plan_lookahead(path, machine or default_machine(), rule=params.rule, tolerance=params.tolerance,
                              profile=params.profile)
        ctx.log(f"{len(plan.trajectory)} setpoints, {plan.cycle_time:.3f} s, {len(plan.corner_times)} corners "
                f"passed at speed")
        return {"trajectory": plan.trajectory, "cycle_time": plan.cycle_time}


class StopAndGoParams(BaseModel):
    model_config = ConfigDict(extra="forbid", defer_build=True)

    profile: Annotated[Literal["trapezoid", "exponential", "scurve"], Field(
        description="Velocity profile of each segment, from rest to rest")] = "trapezoid"


@register
class StopAndGoPlanner(NodeType):
    type_id = "plan.stop_and_go"
    title = "Stop-and-go planner"
    category = "Planning"
    description = "Every segment on its own, from rest to rest: the baseline look-ahead is measured against."
    Params = StopAndGoParams
    inputs = (_PATH_IN, _MACHINE_IN)
    outputs = (_TRAJ_OUT, _CYCLE_OUT)

    def run(self, ctx, params: StopAndGoParams, path: "Path", machine: Machine | None = None):
        from flowmc.motion.lookahead import plan_stop_and_go

        plan = plan_stop_and_go(path, machine or default_machine(), profile=params.profile)
        ctx.log(f"{len(plan.trajectory)} setpoints, {plan.cycle_time:.3f} s")
        return {"trajectory": plan.trajectory, "cycle_time": plan.cycle_time}


class MetricsParams(BaseModel):
    model_config = ConfigDict(extra="forbid", defer_build=True)

    bound: Annotated[float | None, Field(gt=0, description="Time-optimal bound of the path, for the ratio "
                                                           "(empty: no ratio)", json_schema_extra={"unit": "s"})] = None


@register
class TrajectoryMetrics(NodeType):
    type_id = "plan.metrics"
    title = "Trajectory metrics"
    category = "Planning"
    description = "Cycle time, peak per-axis velocity and acceleration over their limits, and contour error."
    Params = MetricsParams
    inputs = (In("trajectory", "Trajectory", doc="Setpoints to judge"),
              In("path", "Path", doc="The programmed path, for the contour error"),
              _MACHINE_IN)
    outputs = (Out("table", "Table", doc="Columns name, value, unit"),
               Out("cycle_time", "Number", doc="Time to the last setpoint (s)"),
               Out("peak_accel", "Number", doc="Largest sampled per-axis acceleration over its limit, "
                                               "corners included"),
               Out("contour_error", "Number", doc="Largest distance of a chord from the path (mm)"))

    def run(self, ctx, params: MetricsParams, trajectory: "Trajectory", path: "Path", machine: Machine | None = None):
        from flowmc.motion.metrics import trajectory_report
        from flowmc.motion.table import Table

        rep = trajectory_report(trajectory, path, machine or default_machine(), params.bound)
        rows = [("cycle_time", rep["cycle_time"], "s"), ("peak_velocity", rep["peak_velocity"], "x limit"),
                ("peak_accel", rep["peak_accel"], "x limit"), ("contour_error", rep["contour_error"], "mm")]
        if params.bound is not None:
            rows.insert(1, ("time_ratio", rep["time_ratio"], "x bound"))
        table = Table({"name": [r[0] for r in rows], "value": [r[1] for r in rows], "unit": [r[2] for r in rows]})
        return {"table": table, "cycle_time": rep["cycle_time"], "peak_accel": rep["peak_accel"],
                "contour_error": rep["contour_error"]}
