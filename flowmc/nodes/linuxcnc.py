"""LinuxCNC as a peer: run the same program on LinuxCNC's real planner and compare its motion with flowmc's."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field

from flowmc.registry import In, NodeType, Out, register


class CompareParams(BaseModel):
    model_config = ConfigDict(extra="forbid", defer_build=True)

    tolerance: Annotated[float, Field(gt=0, le=5, description="Corner tolerance: G64 P for LinuxCNC, blend "
                                                              "tolerance for flowmc", json_schema_extra={"unit": "mm"})] = 0.05
    servo_period: Annotated[float, Field(gt=0, le=0.01, description="LinuxCNC's servo period",
                                         json_schema_extra={"unit": "s"})] = 0.001
    profile: Annotated[Literal["trapezoid", "scurve"], Field(
        description="flowmc's profile when it plans here (LinuxCNC's planner is trapezoidal)")] = "trapezoid"


@register
class LinuxCNCCompare(NodeType):
    type_id = "device.linuxcnc_compare"
    title = "Compare with LinuxCNC"
    category = "Devices"
    description = "Run the path on LinuxCNC's simulator and report cycle time, deviations and peaks beside flowmc's plan."
    pure = False  # starts an external machine
    host_resources = ("linuxcnc",)  # LinuxCNC instances on one host collide
    Params = CompareParams
    inputs = (
        In("path", "Path", doc="The programmed path"),
        In("machine", "Machine", doc="Axis limits (default: the default machine)", default=None),
        In("trajectory", "Trajectory", doc="flowmc's plan (default: planned here like LinuxCNC)", default=None),
    )
    outputs = (
        Out("report", "Table", doc="quantity, unit, flowmc, linuxcnc, limit, over (which side breaks it)"),
        Out("linuxcnc", "Trajectory", doc="What LinuxCNC executed, every servo period"),
    )

    def run(self, ctx, params: CompareParams, path, machine=None, trajectory=None):
        from flowmc.devices.linuxcnc.compare import compare_path

        result = compare_path(path, machine, tolerance=params.tolerance, profile=params.profile, flowmc=trajectory,
                              servo_period=params.servo_period)
        ctx.log(result.text())
        return {"report": result.table, "linuxcnc": result.linuxcnc.trajectory()}
