"""Path sources that need no file format: the thesis's segment table, polylines, and NURBS curves."""

# No ``from __future__ import annotations``: pydantic would compile every model field's annotation from
# its text when a cold ``flowmc validate`` builds the models (docs/architecture.md).
from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

from flowmc.motion.segment_table import Row, path_from_rows
from flowmc.registry import NodeType, Out, register

_MM = {"unit": "mm"}
_MM_S = {"unit": "mm/s"}


class SegmentTableParams(BaseModel):
    model_config = ConfigDict(extra="forbid", defer_build=True)

    start: Annotated[tuple[float, float, float], Field(description="Start point", json_schema_extra=_MM)] = (0, 0, 0)
    feed: Annotated[float, Field(gt=0, description="Feed for rows that set none", json_schema_extra=_MM_S)] = 50.0
    rows: Annotated[list[Row], Field(description="Moves in order: line, arc (cw/ccw, helix with dz), ellipse")] = []


@register
class SegmentTable(NodeType):
    type_id = "path.segment_table"
    title = "Segment table"
    category = "Path"
    description = "Rows of lines, arcs, helices and ellipse arcs, each from where the last ended (the thesis's form)."
    Params = SegmentTableParams
    outputs = (Out("path", "Path", doc="The moves as a path"),)

    def run(self, ctx, params: SegmentTableParams):
        return {"path": path_from_rows(params.rows, start=params.start, feed=params.feed)}


class PolylineParams(BaseModel):
    model_config = ConfigDict(extra="forbid", defer_build=True)

    points: Annotated[list[tuple[float, float, float]], Field(min_length=2, description="Points in order",
                                                              json_schema_extra=_MM)] = [(0, 0, 0), (10, 0, 0)]
    feed: Annotated[float, Field(gt=0, description="Feed", json_schema_extra=_MM_S)] = 50.0
    closed: Annotated[bool, Field(description="Return to the first point at the end")] = False


@register
class Polyline(NodeType):
    type_id = "path.polyline"
    title = "Polyline"
    category = "Path"
    description = "Straight lines through a list of points."
    Params = PolylineParams
    outputs = (Out("path", "Path", doc="Lines through the points"),)

    def run(self, ctx, params: PolylineParams):
        from flowmc.motion.path import Path

        pts = list(params.points) + ([params.points[0]] if params.closed else [])
        return {"path": Path.polyline(pts, feed=params.feed)}


class NurbsParams(BaseModel):
    model_config = ConfigDict(extra="forbid", defer_build=True)

    control_points: Annotated[list[tuple[float, float, float]], Field(min_length=2, description="Control points",
                                                                      json_schema_extra=_MM)]
    weights: Annotated[list[float] | None, Field(description="One weight > 0 per control point (default all 1)")] = None
    degree: Annotated[int, Field(ge=1, le=7, description="Degree (3: cubic)")] = 3
    knots: Annotated[list[float] | None, Field(description="Knot vector, n + degree + 1 values "
                                                           "(default clamped uniform)")] = None
    feed: Annotated[float, Field(gt=0, description="Feed", json_schema_extra=_MM_S)] = 50.0


@register
class Nurbs(NodeType):
    type_id = "path.nurbs"
    title = "NURBS curve"
    category = "Path"
    description = "A NURBS curve from control points, weights, degree and knots."
    Params = NurbsParams
    outputs = (Out("path", "Path", doc="One NURBS segment"),)

    def run(self, ctx, params: NurbsParams):
        from flowmc.motion.path import NurbsCurve, Path

        curve = NurbsCurve(params.control_points, params.weights, params.knots, params.degree, feed=params.feed,
                           source=f"node {ctx.node_id}")
        return {"path": Path([curve])}
