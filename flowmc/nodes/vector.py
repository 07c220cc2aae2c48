"""Vector drawing nodes: an SVG or DXF file into a pen/tool path (strokes with the tool down, rapids up)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field

from flowmc.motion.vector import Style, read_vector, strokes_to_path
from flowmc.registry import NodeType, Out, register

_MM = {"unit": "mm"}
_MM_S = {"unit": "mm/s"}


class LayerRule(BaseModel):
    model_config = ConfigDict(extra="forbid", defer_build=True)

    layer: Annotated[str, Field(description="Layer name (DXF layer, SVG group label or id), or * for any")] = "*"
    colour: Annotated[str, Field(description="Stroke colour: '#rrggbb' (SVG, DXF true colour) or a DXF colour "
                                             "number, or * for any")] = "*"
    tool: Annotated[int, Field(ge=0, description="Tool or pen number (a change is a tool-change event)")] = 1
    feed: Annotated[float, Field(gt=0, description="Drawing feed", json_schema_extra=_MM_S)] = 20.0
    skip: Annotated[bool, Field(description="Leave these strokes out")] = False


class VectorInParams(BaseModel):
    model_config = ConfigDict(extra="forbid", defer_build=True)

    file: Annotated[str, Field(description="SVG or DXF drawing, relative to the graph's folder")]
    curves: Annotated[Literal["arcs", "exact"], Field(description="arcs: Béziers, splines and ellipses become "
                                                                  "circular arcs within the tolerance; exact: NURBS "
                                                                  "and ellipse segments")] = "arcs"
    tolerance: Annotated[float, Field(gt=0, description="Largest distance between a curve and its arcs",
                                      json_schema_extra=_MM)] = 0.01
    layers: Annotated[list[LayerRule], Field(description="Rules, first match wins: which layers/colours are "
                                                         "drawn with which tool and feed")] = []
    feed: Annotated[float, Field(gt=0, description="Drawing feed where no rule matches",
                                 json_schema_extra=_MM_S)] = 20.0
    rapid_feed: Annotated[float, Field(gt=0, description="Feed of the pen-up moves", json_schema_extra=_MM_S)] = 50.0
    scale: Annotated[float, Field(gt=0, description="Scale factor applied to the drawing")] = 1.0
    origin_x: Annotated[float, Field(description="Where the drawing's (0, 0) goes, X", json_schema_extra=_MM)] = 0.0
    origin_y: Annotated[float, Field(description="Where the drawing's (0, 0) goes, Y", json_schema_extra=_MM)] = 0.0


@register
class VectorIn(NodeType):
    type_id = "path.vector_in"
    title = "SVG / DXF in"
    category = "Path"
    description = "Read an SVG or DXF drawing as pen-down strokes and pen-up rapids, layers mapped to tools and feeds."
    pure = False  # the file may change between runs
    fixed_params = ("file",)
    Params = VectorInParams
    outputs = (Out("path", "Path", doc="Strokes in mm (Y up), grouped by tool, with a tool-change event between "
                                       "tools"),)

    def run(self, ctx, params: VectorInParams):
        strokes = read_vector(ctx.resolve(params.file), curves=params.curves, tolerance=params.tolerance,
                              name=params.file)
        rules = [Style(r.layer, r.colour, r.tool, r.feed, r.skip) for r in params.layers]
        path = strokes_to_path(strokes, rules, default=Style(feed=params.feed), origin=(params.origin_x,
                               params.origin_y), scale=params.scale, rapid_feed=params.rapid_feed)
        layers = sorted({s.layer or s.colour for s in strokes})
        ctx.log(f"{len(strokes)} strokes on {len(layers)} layers/colours ({', '.join(layers[:8])}), "
                f"{len(path)} segments, {len(path.events())} tool changes")
        return {"path": path}
