"""G-code nodes: a program (typed in, or a file beside the graph) into a Path, and a Path out as G-code."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from flowmc.errors import GcodeError
from flowmc.motion.machine import RAPID_FEED
from flowmc.registry import In, NodeType, Out, register

if TYPE_CHECKING:
    from flowmc.motion.path import Path

_MM = {"unit": "mm"}
_UNITS = {"mm": 1.0, "inch": 25.4}
_SHOWN = 5  # warnings and messages logged per run


class GcodeInParams(BaseModel):
    model_config = ConfigDict(extra="forbid", defer_build=True)

    text: Annotated[str, Field(description="G-code program (used when no file is given)",
                               json_schema_extra={"multiline": True})] = ""
    file: Annotated[str | None, Field(description="G-code file (.ngc, .nc, .gcode), relative to the graph's "
                                                  "folder; when set, the text is not used")] = None
    rapid_feed: Annotated[float, Field(gt=0, description="Feed given to G0 moves (G-code leaves it to the machine)",
                                       json_schema_extra={"unit": "mm/s"})] = RAPID_FEED
    block_delete: Annotated[bool, Field(description="Skip lines that start with '/' (LinuxCNC's block-delete "
                                                    "switch)")] = False
    tool_table: Annotated[str | None, Field(description="Tool table in LinuxCNC's .tbl format, relative to the "
                                                        "graph's folder (T, M6, G43, G41/G42 use it)")] = None
    parameter_file: Annotated[str | None, Field(description="LinuxCNC parameter file (.var) with the work offsets, "
                                                            "G28/G30 homes and other persistent parameters")] = None
    machine_units: Annotated[Literal["mm", "inch"], Field(description="Units of the tool table and parameter file "
                                                                      "(LinuxCNC's machine units)")] = "mm"
    subroutine_folder: Annotated[str | None, Field(description="Folder of subroutine files: 'o<name> call' reads "
                                                               "<name>.ngc there when the program does not define "
                                                               "it")] = None
    flood_output: Annotated[int, Field(ge=0, le=64, description="Digital output that M8 (flood coolant) switches "
                                                                "on and M9 off")] = 1
    mist_output: Annotated[int, Field(ge=0, le=64, description="Digital output that M7 (mist coolant) switches on "
                                                               "and M9 off")] = 2


@register
class GcodeIn(NodeType):
    type_id = "path.gcode_in"
    title = "G-code in"
    category = "Path"
    description = "Read G-code as LinuxCNC does (parameters, O-words, offsets, tools, cycles, cutter comp) as a path."
    fixed_params = ("file", "tool_table", "parameter_file", "subroutine_folder")
    # cached while these files (and the subroutine folder's files) are unchanged: their sizes and times are in the key
    reads = ("file", "tool_table", "parameter_file", "subroutine_folder")
    version = 2
    Params = GcodeInParams
    outputs = (Out("path", "Path", doc="The program's moves, dwells, pauses and tool changes, in machine "
                                       "coordinates, mm and mm/s"),)

    def run(self, ctx, params: GcodeInParams):
        from flowmc.motion.gcode import GcodeOptions, ToolTable, interpret, interpret_file, read_var_file

        units = _UNITS[params.machine_units]
        tools = None
        if params.tool_table:
            tools = ToolTable.load(ctx.resolve(params.tool_table), units_mm=units, source=params.tool_table)
        values = None
        if params.parameter_file:
            values = read_var_file(ctx.resolve(params.parameter_file), source=params.parameter_file)
        folders = (ctx.resolve(params.subroutine_folder),) if params.subroutine_folder else ()
        options = GcodeOptions(rapid_feed=params.rapid_feed, block_delete=params.block_delete, tool_table=tools,
                               parameters=values, machine_units_mm=units, subroutine_dirs=folders,
                               flood_output=params.flood_output, mist_output=params.mist_output)
        if params.file:
            result = interpret_file(ctx.resolve(params.file), options, source=params.file)
        elif params.text.strip():
            result = interpret(params.text, "text", options)
        else:
            raise GcodeError("no G-code: type a program into 'text' or name a file")
        path = result.path
        kinds = path.kind_counts()
        ctx.log(f"{len(path)} segments ({kinds.get('arc', 0)} arcs, "
                f"{kinds.get('dwell', 0)} dwells, {len(path.events())} pauses and tool changes), "
                f"{path.length:.3f} mm")
        for where, text in result.messages[:_SHOWN]:
            ctx.log(f"{where}: {text}")
        for where, text in result.warnings[:_SHOWN]:
            ctx.log(f"warning: {where}: {text}")
        if result.warning_count > _SHOWN:
            ctx.log(f"... {result.warning_count - _SHOWN} more warnings")
        return {"path": path}


class GcodeOutParams(BaseModel):
    model_config = ConfigDict(extra="forbid", defer_build=True)

    file: Annotated[str | None, Field(description="Also write the program to this file, relative to the "
                                                  "graph's folder (atomically)")] = None
    decimals: Annotated[int, Field(ge=5, le=12, description="Decimal places of coordinates (mm)")] = 6
    blend_tolerance: Annotated[float | None, Field(ge=0, description="Add G64 P<tolerance> (LinuxCNC path "
                                                                     "blending); none: say nothing",
                                                   json_schema_extra=_MM)] = None
    chord_tolerance: Annotated[float, Field(gt=0, description="Ellipses and NURBS (other than single "
                                                                    "G5/G5.1 spans) become G1 chords within this",
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
        from flowmc.motion.gcode_write import path_to_gcode, write_gcode

        options: dict[str, Any] = dict(decimals=params.decimals, blend_tolerance=params.blend_tolerance,
                                       chord_tolerance=params.chord_tolerance)
        if not params.file:
            return {"text": path_to_gcode(path, **options)}
        target = ctx.resolve_output(params.file)
        try:
            text = write_gcode(path, target, **options)
        except GcodeError as exc:
            raise GcodeError(exc.message, where=params.file if exc.where == str(target) else exc.where) from None
        ctx.log(f"wrote {text.count(chr(10))} lines to {params.file}")
        return {"text": text}
