"""G-code nodes: a program (typed in, or a file beside the graph) into a Path, and a Path out as G-code."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

from flowmc.errors import GcodeError
from flowmc.motion.gcode_read import RAPID_FEED, parse_gcode, read_gcode
from flowmc.motion.gcode_write import path_to_gcode, write_gcode
from flowmc.motion.path import Path
from flowmc.registry import In, NodeType, Out, register

_MM = {"unit": "mm"}


class GcodeInParams(BaseModel):
    model_config = ConfigDict(extra="forbid")

    text: Annotated[str, Field(description="G-code program (used when no file is given)",
                               json_schema_extra={"multiline": True})] = ""
    file: Annotated[str | None, Field(description="G-code file (.ngc, .nc, .gcode), relative to the graph's "
                                                  "folder; when set, the text is not used")] = None
    rapid_feed: Annotated[float, Field(gt=0, description="Feed given to G0 moves (G-code leaves it to the machine)",
                                       json_schema_extra={"unit": "mm/s"})] = RAPID_FEED
    block_delete: Annotated[bool, Field(description="Skip lines that start with '/' (LinuxCNC's block-delete "
                                                    "switch)")] = False


@register
class GcodeIn(NodeType):
    type_id = "path.gcode_in"
    title = "G-code in"
    category = "Path"
    description = "Read G-code (LinuxCNC's RS274/NGC subset: G0-G4, planes, units, modes, spindle, outputs) as a path."
    reads = ("file",)  # cached while the file is unchanged (its size and modification time are in the key)
    Params = GcodeInParams
    outputs = (Out("path", "Path", doc="The program's moves, dwells and tool state, in mm and mm/s"),)

    def run(self, ctx, params: GcodeInParams):
        if params.file:
            file = ctx.resolve(params.file)
            path = read_gcode(file, rapid_feed=params.rapid_feed, block_delete=params.block_delete,
                              source=params.file)
        elif params.text.strip():
            path = parse_gcode(params.text, "text", rapid_feed=params.rapid_feed, block_delete=params.block_delete)
        else:
            raise GcodeError("no G-code: type a program into 'text' or name a file")
        ctx.log(f"{len(path)} segments ({sum(s.kind == 'arc' for s in path)} arcs, "
                f"{sum(s.kind == 'dwell' for s in path)} dwells), {path.length:.3f} mm")
        return {"path": path}


class GcodeOutParams(BaseModel):
    model_config = ConfigDict(extra="forbid")

    file: Annotated[str | None, Field(description="Also write the program to this file, relative to the "
                                                  "graph's folder (atomically)")] = None
    decimals: Annotated[int, Field(ge=5, le=12, description="Decimal places of coordinates (mm)")] = 6
    blend_tolerance: Annotated[float | None, Field(ge=0, description="Add G64 P<tolerance> (LinuxCNC path "
                                                                     "blending); none: say nothing",
                                                   json_schema_extra=_MM)] = None
    chord_tolerance: Annotated[float, Field(gt=0, description="Ellipses and NURBS become G1 chords within this",
                                            json_schema_extra=_MM)] = 0.001


@register
class GcodeOut(NodeType):
    type_id = "path.gcode_out"
    title = "G-code out"
    category = "Path"
    description = "Write a path as G-code (mm, absolute, G2/G3 with I/J/K) that LinuxCNC and 'G-code in' read back."
    pure = False  # it may write a file
    Params = GcodeOutParams
    inputs = (In("path", "Path", doc="Path to write"),)
    outputs = (Out("text", "Text", doc="The G-code program"),)

    def run(self, ctx, params: GcodeOutParams, path: Path):
        options = dict(decimals=params.decimals, blend_tolerance=params.blend_tolerance,
                       chord_tolerance=params.chord_tolerance)
        if not params.file:
            return {"text": path_to_gcode(path, **options)}
        target = ctx.resolve(params.file)
        try:
            text = write_gcode(path, target, **options)
        except GcodeError as exc:
            raise GcodeError(exc.message, where=params.file if exc.where == str(target) else exc.where) from None
        ctx.log(f"wrote {text.count(chr(10))} lines to {params.file}")
        return {"text": text}
