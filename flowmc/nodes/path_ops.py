"""Path nodes that trace pictures, compensate the tool radius, clear pockets, move paths about and join them."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from flowmc.errors import BudgetError, PathError
from flowmc.motion.clearance import pocket_path
from flowmc.motion.contour import DEFAULT_METHOD, image_to_path
from flowmc.motion.offset import offset_path
from flowmc.motion.path import Path
from flowmc.registry import In, NodeType, Out, Ports, register

_MM = {"unit": "mm"}
_MM_S = {"unit": "mm/s"}
_DEG = {"unit": "deg"}


class _Params(BaseModel):
    model_config = ConfigDict(extra="forbid", defer_build=True)


_PATH_IN = (In("path", "Path", doc="Path to change"),)


# ---------------------------------------------------------------- image contour

class ImageContourParams(_Params):
    file: Annotated[str, Field(description="PNG/JPEG/BMP picture, relative to the graph's folder")]
    method: Annotated[Literal["marching_squares", "report_4neighbour"],
                      Field(description="marching_squares: sub-pixel outlines (closer); report_4neighbour: the "
                                        "course report's boundary pixels")] = DEFAULT_METHOD
    threshold: Annotated[float | None, Field(ge=0, le=255, description="Gray level splitting ink from paper "
                                                                       "(none: Otsu's automatic level)")] = None
    invert: Annotated[bool, Field(description="Trace light shapes on a dark ground instead of dark ink on paper")] = False
    mm_per_pixel: Annotated[float | None, Field(gt=0, description="Scale (none: fit width/height, else 0.1)",
                                                json_schema_extra=_MM)] = None
    width_mm: Annotated[float | None, Field(gt=0, description="Fit the picture into this width",
                                            json_schema_extra=_MM)] = None
    height_mm: Annotated[float | None, Field(gt=0, description="Fit the picture into this height",
                                             json_schema_extra=_MM)] = None
    origin_x: Annotated[float, Field(description="X of the picture's lower-left corner", json_schema_extra=_MM)] = 0.0
    origin_y: Annotated[float, Field(description="Y of the picture's lower-left corner", json_schema_extra=_MM)] = 0.0
    feed: Annotated[float, Field(gt=0, description="Drawing feed", json_schema_extra=_MM_S)] = 20.0
    simplify_mm: Annotated[float, Field(ge=0, description="Largest deviation allowed when merging short moves",
                                        json_schema_extra=_MM)] = 0.05


@register
class ImageContour(NodeType):
    type_id = "path.image_contour"
    title = "Image contour"
    category = "Path"
    description = "Trace a picture's outlines into pen-down strokes with pen-up rapids between them (XY plotter)."
    reads = ("file",)  # cached while the picture is unchanged (its content hash is in the key)
    Params = ImageContourParams
    outputs = (Out("path", "Path", doc="Outlines in machine mm, from (0, 0)"),)

    def run(self, ctx, params: ImageContourParams):
        file = ctx.resolve(params.file)
        try:
            path = image_to_path(file, params.method, params.threshold, params.invert, params.mm_per_pixel,
                                 params.width_mm, params.height_mm, (params.origin_x, params.origin_y),
                                 params.feed, params.simplify_mm)
        except (PathError, BudgetError) as exc:
            raise type(exc)(exc.message, where=params.file if exc.where == str(file) else exc.where) from None
        ctx.log(f"{sum(s.rapid for s in path)} outlines, {len(path)} moves")
        return {"path": path}


# ---------------------------------------------------------------- tool-radius offset

class ToolOffsetParams(_Params):
    side: Annotated[Literal["left", "right"], Field(description="Side of travel to offset to (left: G41, right: G42)")] = "left"
    radius: Annotated[float, Field(ge=0, description="Tool radius", json_schema_extra=_MM)] = 1.0
    gouge: Annotated[Literal["refuse", "trim"], Field(description="Where the tool would cut into the contour (a slot "
                                                                  "narrower than the tool, a concave arc smaller "
                                                                  "than the radius): refuse, naming the segment, or "
                                                                  "trim (lift over it, leaving it uncut)")] = "refuse"


@register
class ToolOffset(NodeType):
    type_id = "path.tool_offset"
    title = "Tool-radius offset"
    category = "Path"
    description = "Offset lines and XY arcs by the tool radius: arcs round convex corners, trims at concave ones."
    Params = ToolOffsetParams
    inputs = (In("path", "Path", doc="Programmed contour (lines and XY arcs)"),)
    outputs = (Out("path", "Path", doc="Tool-centre path"),)

    def run(self, ctx, params: ToolOffsetParams, path: Path):
        out = offset_path(path, params.radius, params.side, params.gouge)
        lifted = sum(1 for seg in out if "gouge lifted over" in seg.source)
        if lifted:
            ctx.log(f"{lifted} stretches left uncut where the tool would gouge the contour")
        return {"path": out}


# ---------------------------------------------------------------- pocket

class PocketParams(_Params):
    radius: Annotated[float, Field(gt=0, description="Tool radius", json_schema_extra=_MM)] = 1.0
    stepover: Annotated[float, Field(gt=0, description="Distance between rings (at most the tool diameter)",
                                     json_schema_extra=_MM)] = 1.0
    direction: Annotated[Literal["climb", "conventional"], Field(description="climb: clockwise rings (spindle "
                                                                             "M3); conventional: counter-"
                                                                             "clockwise")] = "climb"
    feed: Annotated[float | None, Field(gt=0, description="Cutting feed (none: the boundary's)",
                                        json_schema_extra=_MM_S)] = None
    tolerance: Annotated[float, Field(gt=0, description="Largest distance between a ring's lines and the round "
                                                        "offset", json_schema_extra=_MM)] = 0.005


@register
class Pocket(NodeType):
    type_id = "path.pocket"
    title = "Pocket"
    category = "Path"
    description = "Clear the inside of closed contours (islands left standing): rings inward by the step-over."
    Params = PocketParams
    inputs = (In("path", "Path", doc="Closed boundary contours (lines and XY arcs); inner ones are islands"),)
    outputs = (Out("path", "Path", doc="Tool-centre rings from the middle out, the last one the tool radius inside "
                                       "the boundary, tool-up rapids between them"),)

    def run(self, ctx, params: PocketParams, path: Path):
        out = pocket_path(path, params.radius, params.stepover, direction=params.direction, feed=params.feed,
                          tolerance=params.tolerance)
        ctx.log(f"{sum(seg.rapid for seg in out) + 1} loops, {out.length:.1f} mm")
        return {"path": out}


# ---------------------------------------------------------------- transforms

class TranslateParams(_Params):
    dx: Annotated[float, Field(description="Shift along X", json_schema_extra=_MM)] = 0.0
    dy: Annotated[float, Field(description="Shift along Y", json_schema_extra=_MM)] = 0.0
    dz: Annotated[float, Field(description="Shift along Z", json_schema_extra=_MM)] = 0.0


@register
class Translate(NodeType):
    type_id = "path.translate"
    title = "Translate"
    category = "Path"
    description = "Shift a path by (dx, dy, dz)."
    Params = TranslateParams
    inputs = _PATH_IN
    outputs = (Out("path", "Path", doc="Shifted path"),)

    def run(self, ctx, params: TranslateParams, path: Path):
        return {"path": path.translated((params.dx, params.dy, params.dz))}


class RotateParams(_Params):
    degrees: Annotated[float, Field(description="Counter-clockwise angle about Z", json_schema_extra=_DEG)] = 0.0
    about_x: Annotated[float, Field(description="X of the centre of rotation", json_schema_extra=_MM)] = 0.0
    about_y: Annotated[float, Field(description="Y of the centre of rotation", json_schema_extra=_MM)] = 0.0


@register
class Rotate(NodeType):
    type_id = "path.rotate"
    title = "Rotate"
    category = "Path"
    description = "Rotate a path about a vertical axis through (about_x, about_y)."
    Params = RotateParams
    inputs = _PATH_IN
    outputs = (Out("path", "Path", doc="Rotated path"),)

    def run(self, ctx, params: RotateParams, path: Path):
        return {"path": path.rotated(params.degrees, (params.about_x, params.about_y, 0.0))}


class ScaleParams(_Params):
    factor: Annotated[float, Field(gt=0, description="Scale factor (use Mirror to flip)")] = 1.0
    about_x: Annotated[float, Field(description="X of the fixed point", json_schema_extra=_MM)] = 0.0
    about_y: Annotated[float, Field(description="Y of the fixed point", json_schema_extra=_MM)] = 0.0
    about_z: Annotated[float, Field(description="Z of the fixed point", json_schema_extra=_MM)] = 0.0


@register
class Scale(NodeType):
    type_id = "path.scale"
    title = "Scale"
    category = "Path"
    description = "Scale a path about a fixed point."
    Params = ScaleParams
    inputs = _PATH_IN
    outputs = (Out("path", "Path", doc="Scaled path"),)

    def run(self, ctx, params: ScaleParams, path: Path):
        return {"path": path.scaled(params.factor, (params.about_x, params.about_y, params.about_z))}


class MirrorParams(_Params):
    axis: Annotated[Literal["X", "Y", "Z"], Field(description="Coordinate that changes sign (X: mirror left-right)")] = "X"
    about: Annotated[float, Field(description="Position of the mirror plane on that axis", json_schema_extra=_MM)] = 0.0


@register
class Mirror(NodeType):
    type_id = "path.mirror"
    title = "Mirror"
    category = "Path"
    description = "Mirror a path across the plane axis = about (arcs change direction)."
    Params = MirrorParams
    inputs = _PATH_IN
    outputs = (Out("path", "Path", doc="Mirrored path"),)

    def run(self, ctx, params: MirrorParams, path: Path):
        return {"path": path.mirrored(params.axis, params.about)}


# ---------------------------------------------------------------- join

class JoinParams(_Params):
    count: Annotated[int, Field(ge=2, le=16, description="Number of paths to join (one input each)")] = 2
    rapid_feed: Annotated[float | None, Field(gt=0, description="Feed of the linking rapids (none: the next "
                                                                "path's first feed)", json_schema_extra=_MM_S)] = None


@register
class Join(NodeType):
    type_id = "path.join"
    title = "Join"
    category = "Path"
    description = "Concatenate paths in order, with a tool-up rapid wherever one does not start where the last ended."
    Params = JoinParams
    fixed_params = ("count",)
    inputs = tuple(In(f"path{k}", "Path", doc=f"Path {k}") for k in (1, 2))
    outputs = (Out("path", "Path", doc="The paths one after another"),)

    @classmethod
    def ports(cls, params: JoinParams) -> Ports:
        return Ports(tuple(In(f"path{k}", "Path", doc=f"Path {k}") for k in range(1, params.count + 1)), cls.outputs)

    def run(self, ctx, params: JoinParams, **paths: Any):
        joined = Path()
        for k in range(1, params.count + 1):
            joined = joined.concat(paths[f"path{k}"], rapid_feed=params.rapid_feed)
        return {"path": joined}
