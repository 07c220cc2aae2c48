"""Measure a path: per-segment lengths and chords, set against an expected table (the thesis's Table 6-1)."""

# No ``from __future__ import annotations``: pydantic would compile every model field's annotation from
# its text when a cold ``flowmc validate`` builds the models (docs/architecture.md).
from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

from flowmc.errors import PathError
from flowmc.registry import In, NodeType, Out, register


class MeasureParams(BaseModel):
    model_config = ConfigDict(extra="forbid", defer_build=True)

    expected_xy: Annotated[list[float] | None, Field(description="Expected XY length per segment (lines: XY "
                                                                 "length, arcs: chord), to compare against",
                                                     json_schema_extra={"unit": "mm"})] = None


@register
class MeasurePath(NodeType):
    type_id = "path.measure"
    title = "Measure path"
    category = "Path"
    description = "Per-segment kind, length and XY chord, with the difference from an expected table."
    Params = MeasureParams
    inputs = (In("path", "Path", doc="Path to measure"),)
    outputs = (
        Out("table", "Table", doc="segment, kind, length_mm, xy_chord_mm (and expected_mm, diff_mm)"),
        Out("length", "Number", doc="Total length (mm)"),
        Out("max_diff", "Number", doc="Largest |xy_chord - expected| (mm; 0 without an expected table)"),
    )

    def run(self, ctx, params: MeasureParams, path):
        import numpy as np

        from flowmc.motion.table import Table

        starts = np.array([s.start for s in path.segments]).reshape(-1, 3)
        ends = np.array([s.end for s in path.segments]).reshape(-1, 3)
        chord = np.linalg.norm((ends - starts)[:, :2], axis=1)
        columns = {
            "segment": np.arange(1, len(path) + 1),
            "kind": [s.kind for s in path.segments],
            "length_mm": path.lengths,
            "xy_chord_mm": chord,
        }
        max_diff = 0.0
        if params.expected_xy is not None:
            if len(params.expected_xy) != len(path):
                raise PathError(f"expected_xy has {len(params.expected_xy)} values but the path has "
                                f"{len(path)} segments", where=f"node {ctx.node_id}")
            diff = chord - np.asarray(params.expected_xy)
            columns.update(expected_mm=params.expected_xy, diff_mm=diff)
            max_diff = float(np.abs(diff).max()) if len(diff) else 0.0
        return {"table": Table(columns), "length": float(path.length), "max_diff": max_diff}
