"""The LabVIEW thesis's segment table: rows of moves, each starting where the previous one ended.

Arc convention (the thesis's, see ``tests/data/reference/thesis_pattern.json``): an arc starts at the
current point; ``start_angle`` is the polar angle of that point about the arc centre, so
``centre = start - R (cos a0, sin a0)``; it sweeps from ``start_angle`` to ``end_angle``, counter-
clockwise when ``end_angle > start_angle``. Angles are in degrees. A sweep past 360 degrees adds
full turns; with ``dz`` the arc climbs into a helix.
"""

# No ``from __future__ import annotations``: pydantic would compile every model field's annotation from
# its text when a cold ``flowmc validate`` builds the models (docs/architecture.md).
import math
from typing import TYPE_CHECKING, Annotated, Literal, Union

from pydantic import BaseModel, ConfigDict, Field

import flowmc.budget as budget
from flowmc.errors import PathError

if TYPE_CHECKING:  # the rows are a node's params: they validate without numpy or the path types
    import numpy as np

    from flowmc.motion.path import Arc, EllipseArc, Path, Segment

__all__ = ["LineRow", "ArcRow", "EllipseRow", "Row", "path_from_rows"]


class _RowBase(BaseModel):
    model_config = ConfigDict(extra="forbid")

    feed: Annotated[float | None, Field(gt=0, description="Feed for this row (default: the table's)",
                                        json_schema_extra={"unit": "mm/s"})] = None
    tool_down: Annotated[bool, Field(description="Pen/tool down along this row")] = True


class LineRow(_RowBase):
    """Straight move to a point (absolute, or relative to the current point)."""

    type: Literal["line"] = "line"
    end: Annotated[tuple[float, float, float], Field(description="End point", json_schema_extra={"unit": "mm"})]
    relative: Annotated[bool, Field(description="End is relative to the current point")] = False


class ArcRow(_RowBase):
    """Circular arc in XY by radius and start/end angles; ``dz`` makes it a helix."""

    type: Literal["arc"] = "arc"
    direction: Annotated[Literal["ccw", "cw"], Field(description="Turn direction (must match the angles)")]
    radius: Annotated[float, Field(gt=0, description="Radius", json_schema_extra={"unit": "mm"})]
    start_angle: Annotated[float, Field(description="Polar angle of the start point about the centre",
                                        json_schema_extra={"unit": "deg"})]
    end_angle: Annotated[float, Field(description="Polar angle of the end point", json_schema_extra={"unit": "deg"})]
    dz: Annotated[float, Field(description="Climb along the arc (helix)", json_schema_extra={"unit": "mm"})] = 0.0


class EllipseRow(_RowBase):
    """Elliptical arc in XY: semi-axes a, b, the a-axis turned by ``rotation``; angles are the ellipse parameter."""

    type: Literal["ellipse"] = "ellipse"
    direction: Annotated[Literal["ccw", "cw"], Field(description="Turn direction (must match the angles)")]
    a: Annotated[float, Field(gt=0, description="Semi-axis along the rotated X", json_schema_extra={"unit": "mm"})]
    b: Annotated[float, Field(gt=0, description="Semi-axis along the rotated Y", json_schema_extra={"unit": "mm"})]
    start_angle: Annotated[float, Field(description="Parameter angle at the start", json_schema_extra={"unit": "deg"})]
    end_angle: Annotated[float, Field(description="Parameter angle at the end", json_schema_extra={"unit": "deg"})]
    rotation: Annotated[float, Field(description="Angle of the a-axis from X", json_schema_extra={"unit": "deg"})] = 0.0


Row = Annotated[Union[LineRow, ArcRow, EllipseRow], Field(discriminator="type")]


def _check_direction(row, where: str) -> float:
    sweep = row.end_angle - row.start_angle
    budget.check("turns", abs(sweep) / 360.0, what=f"sweeping {row.start_angle:g} to {row.end_angle:g} deg",
                 change="give the row angles fewer turns apart", where=where)
    if sweep == 0:
        raise PathError("start_angle equals end_angle: the arc sweeps nothing", where=where)
    if (sweep > 0) != (row.direction == "ccw"):
        need = ">" if row.direction == "ccw" else "<"
        raise PathError(
            f"a {row.direction} arc needs end_angle {need} start_angle (got {row.start_angle} -> {row.end_angle})",
            where=where,
        )
    return math.radians(sweep)


def _arc(row: ArcRow, start: "np.ndarray", state: dict, where: str) -> "Arc":
    import numpy as np

    from flowmc.motion.path import Arc

    sweep = _check_direction(row, where)
    a0 = math.radians(row.start_angle)
    center = start - row.radius * np.array([math.cos(a0), math.sin(a0), 0.0])
    a1 = a0 + sweep
    end = center + row.radius * np.array([math.cos(a1), math.sin(a1), 0.0])
    end[2] = start[2] + row.dz
    turns = max(0, math.ceil(abs(sweep) / (2 * math.pi) - 1e-9) - 1)
    if abs(abs(sweep) - 2 * math.pi * (turns + 1)) < 1e-9:
        end[:2] = start[:2]  # whole turns: land exactly on the start in the plane
    return Arc(start, end, center, normal_axis=2, ccw=sweep > 0, turns=turns, **state)


def _ellipse(row: EllipseRow, start: "np.ndarray", state: dict, where: str) -> "EllipseArc":
    from flowmc.motion.path import EllipseArc

    sweep = _check_direction(row, where)
    t0 = math.radians(row.start_angle)
    probe = EllipseArc.from_axes((0.0, 0.0, 0.0), row.a, row.b, math.radians(row.rotation), t0, t0 + sweep, **state)
    return EllipseArc(start - probe.start, probe.u_axis, probe.v_axis, t0, t0 + sweep, **state)


def path_from_rows(rows, start=(0.0, 0.0, 0.0), feed: float = 100.0) -> "Path":
    """Build a Path from table rows (LineRow/ArcRow/EllipseRow or dicts), starting at ``start``.

    Errors name the row (1-based), e.g. ``row 3: a cw arc needs end_angle < start_angle``.
    """
    import numpy as np
    from pydantic import TypeAdapter, ValidationError

    from flowmc.motion.path import Line, Path

    budget.check("rows", len(rows), what=f"a table of {len(rows):,} rows",
                 change="split the table, or read long programs from a G-code file")
    adapter = TypeAdapter(Row)
    current = np.asarray(start, dtype=float).reshape(3)
    segments: list[Segment] = []
    for i, raw in enumerate(rows, start=1):
        where = f"row {i}"
        try:
            row = raw if isinstance(raw, (LineRow, ArcRow, EllipseRow)) else adapter.validate_python(raw)
        except ValidationError as exc:
            first = exc.errors()[0]
            loc = ".".join(str(p) for p in first["loc"])
            raise PathError(f"{loc}: {first['msg']}" if loc else first["msg"], where=where) from None
        state = {"feed": float(row.feed or feed), "tool_down": row.tool_down, "source": where}
        if isinstance(row, LineRow):
            end = current + np.asarray(row.end) if row.relative else np.asarray(row.end, dtype=float)
            seg: Segment = Line(current, end, **state)
        elif isinstance(row, ArcRow):
            seg = _arc(row, current, state, where)
        else:
            seg = _ellipse(row, current, state, where)
        segments.append(seg)
        current = np.array(seg.end)
    return Path(segments)
