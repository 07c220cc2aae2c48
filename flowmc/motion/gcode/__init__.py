"""G-code in, with LinuxCNC's semantics: the RS274/NGC that post-processors and LinuxCNC's samples use.

The LinuxCNC G-code and O-code reference is the specification, and the tests compare every move
with LinuxCNC's own interpreter (``rs274 -g``). What is read:

- motion G0, G1, G2/G3 (I/J/K or R, full circles, helices, P turns; an end point off its circle is
  accepted within LinuxCNC's rule, as a spiral, with a warning), G4 dwell, G5/G5.1 splines,
  canned cycles G73, G81-G89 with G98/G99 and L repeats, G80;
- parameters (#1-#5602, #<local>, #<_global>, the predefined #<_x>, #<_metric>, ...), expressions
  with LinuxCNC's operators and functions, O-word subroutines (also from files in the configured
  folders), if/elseif/else, while, do-while, repeat, break, continue, return values;
- modes: planes, units, distance and arc-distance modes, feed modes G93/G94/G95, path control,
  lathe diameter mode G7/G8, M70-M73 modal state;
- offsets: G54-G59.3, G10 L2/L20 (with XY rotation), G92/G92.1/G92.2/G92.3, G52, G28/G30 and
  G28.1/G30.1, G53; the parameter file's persistent values;
- tools: T, M6 (a tool-change path event), M61, G43/G43.1/G43.2/G49 from a LinuxCNC tool table,
  G10 L1/L10/L11; cutter compensation G41/G42/G41.1/G42.1/G40 with LinuxCNC's gouge refusals;
- spindle M3/M4/M5 and S, coolant M7/M8/M9 and M62-M68 as outputs, M0/M1/M60 as pause events,
  M2/M30 end.

Refused by name, on their line: probing (G38.x), spindle-synchronised motion (G33, G76), lathe
cycles G70-G72, NURBS G5.2, rotary and UVW axes, user M codes, M66. The Path is in machine
coordinates, mm and mm/s; ``GcodeResult`` adds the warnings, messages and the final persistent
parameters (what LinuxCNC writes back to its parameter file).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path as FsPath

from flowmc.errors import GcodeError
from flowmc.motion.gcode.interp import GcodeOptions, Interpreter
from flowmc.motion.gcode.params import format_var_file, read_var_file
from flowmc.motion.gcode.program import read_program_file
from flowmc.motion.gcode.tools import Tool, ToolTable, parse_tool_table
from flowmc.motion.machine import RAPID_FEED
from flowmc.motion.path import Path

__all__ = ["RAPID_FEED", "GcodeOptions", "GcodeResult", "Tool", "ToolTable", "parse_tool_table", "read_var_file",
           "format_var_file", "interpret", "interpret_file", "parse_gcode", "read_gcode"]



@dataclass(frozen=True)
class GcodeResult:
    """A program read: the Path, warnings and messages as ``(where, text)``, how many warnings there
    were in all (only the first ``max_warnings`` are kept), and the persistent parameters at the end."""

    path: Path
    warnings: tuple[tuple[str, str], ...]
    warning_count: int
    messages: tuple[tuple[str, str], ...]
    parameters: dict[int, float]


def _check_options(options: GcodeOptions, source: str) -> None:
    rapid = options.rapid_feed
    if not (isinstance(rapid, (int, float)) and rapid > 0 and math.isfinite(rapid)):
        raise GcodeError(f"rapid feed must be > 0 mm/s, got {rapid!r}", where=source)
    if not (isinstance(options.machine_units_mm, (int, float)) and 0.5 <= options.machine_units_mm <= 30):
        raise GcodeError(f"machine units must be 1 (mm) or about 25.4 (inch) mm per unit, got "
                         f"{options.machine_units_mm!r}", where=source)


def interpret(text: str, source: str = "<text>", options: GcodeOptions | None = None) -> GcodeResult:
    """Read a program's text; errors name ``source:line`` (or the subroutine file's line)."""
    options = options or GcodeOptions()
    if not isinstance(text, str):
        raise GcodeError(f"G-code must be text, got {type(text).__name__}", where=source)
    _check_options(options, source)
    interp = Interpreter(options)
    canon = interp.run(text, source)
    columns = canon.columns([s.name for s in interp.sources])
    path = Path() if columns is None else Path.from_columns(columns)
    return GcodeResult(path, tuple(interp.warnings), interp.warning_count, tuple(interp.messages),
                       interp.params.persistent())


def interpret_file(path: str | os.PathLike, options: GcodeOptions | None = None,
                   source: str | None = None) -> GcodeResult:
    """Read a G-code file; errors and segment sources name it (``part.ngc:12``)."""
    path = FsPath(path)
    name = source or path.name
    return interpret(read_program_file(path, name), name, options)


def parse_gcode(text: str, source: str = "<text>", *, rapid_feed: float = RAPID_FEED, block_delete: bool = False,
                **options) -> Path:
    """Read G-code text into a Path (``GcodeOptions`` fields as keywords)."""
    return interpret(text, source, GcodeOptions(rapid_feed=rapid_feed, block_delete=block_delete, **options)).path


def read_gcode(path: str | os.PathLike, *, rapid_feed: float = RAPID_FEED, block_delete: bool = False,
               source: str | None = None, **options) -> Path:
    """Read a G-code file into a Path; errors and segment sources name the file (``part.ngc:12``)."""
    return interpret_file(path, GcodeOptions(rapid_feed=rapid_feed, block_delete=block_delete, **options),
                          source).path
