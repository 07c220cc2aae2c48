"""Tool tables in LinuxCNC's ``.tbl`` format: one tool per line, ``T<n> P<pocket> [X Y Z ... D I J Q] ;comment``.

Values are in the machine's length units (LinuxCNC's [TRAJ]LINEAR_UNITS; flowmc machines are mm,
LinuxCNC's standalone rs274 reads inches); ``ToolTable.load(..., units_mm=25.4)`` converts an inch
table. ``D`` is the diameter, ``X``/``Z`` the length offsets G43 applies, ``I``/``J``/``Q`` the
lathe front angle, back angle and orientation.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path as FsPath

import flowmc.budget as budget
from flowmc.errors import GcodeError
from flowmc.fileio import read_bytes

__all__ = ["Tool", "ToolTable", "parse_tool_table"]

_MAX_TOOLS = 100_000


@dataclass(frozen=True)
class Tool:
    """One tool: number, pocket, offsets (X, Y, Z in mm), diameter (mm), lathe angles and orientation."""

    number: int
    pocket: int = 0
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    diameter: float = 0.0
    front_angle: float = 0.0
    back_angle: float = 0.0
    orientation: int = 0
    comment: str = ""


@dataclass(frozen=True)
class ToolTable:
    """Tools by number; ``source`` names the file in messages."""

    tools: dict[int, Tool] = field(default_factory=dict)
    source: str = ""

    def get(self, number: int) -> Tool | None:
        if number == 0:
            return self.tools.get(0, Tool(0))
        return self.tools.get(number)

    def with_tool(self, tool: Tool) -> "ToolTable":
        tools = dict(self.tools)
        tools[tool.number] = tool
        return ToolTable(tools, self.source)

    @classmethod
    def load(cls, path: str | os.PathLike, *, units_mm: float = 1.0, source: str | None = None) -> "ToolTable":
        path = FsPath(path)
        name = source or path.name
        try:
            data = read_bytes(path, limit=budget.cap("bytes"), what="tool table", error=GcodeError)
        except GcodeError as exc:
            raise GcodeError(exc.message, where=name) from None
        return parse_tool_table(data.decode("utf-8-sig", errors="replace"), name, units_mm=units_mm)


def parse_tool_table(text: str, source: str = "tool.tbl", *, units_mm: float = 1.0) -> ToolTable:
    """Read ``.tbl`` text; a malformed line is an error naming ``source:line``."""
    tools: dict[int, Tool] = {}
    for k, raw in enumerate(text.lstrip("\ufeff").splitlines()):
        where = f"{source}:{k + 1}"
        body, _, comment = raw.partition(";")
        words = body.split()
        if not words:
            continue
        values: dict[str, float] = {}
        for word in words:
            letter, number = word[:1].upper(), word[1:]
            if letter not in "TPXYZABCUVWDIJQ" or not number:
                raise GcodeError(f"tool table: cannot read {word!r}", where=where)
            if letter in values:
                raise GcodeError(f"tool table: two {letter} values on one line", where=where)
            try:
                value = float(number)
            except ValueError:
                raise GcodeError(f"tool table: {word!r} is not a letter and a number", where=where) from None
            if not math.isfinite(value):
                raise GcodeError(f"tool table: {word!r} is not a finite number", where=where)
            values[letter] = value
        if "T" not in values:
            raise GcodeError("tool table: each line needs a T (tool number)", where=where)
        number = values["T"]
        if number != int(number) or not 0 <= number <= 99_999_999:
            raise GcodeError(f"tool table: tool number must be a whole number >= 0, got {number:g}", where=where)
        if int(number) in tools:
            raise GcodeError(f"tool table: tool T{int(number)} is listed twice", where=where)
        if len(tools) >= _MAX_TOOLS:
            raise GcodeError(f"tool table: more than {_MAX_TOOLS} tools", where=where)
        tools[int(number)] = Tool(
            number=int(number), pocket=int(values.get("P", number)),
            offset=(values.get("X", 0.0) * units_mm, values.get("Y", 0.0) * units_mm, values.get("Z", 0.0) * units_mm),
            diameter=values.get("D", 0.0) * units_mm, front_angle=values.get("I", 0.0),
            back_angle=values.get("J", 0.0), orientation=int(values.get("Q", 0)), comment=comment.strip())
    return ToolTable(tools, source)
