"""Read a device log: the numbers a graph checks or reports (cycle time, following error, I/O changes)."""

from __future__ import annotations

import numpy as np

from flowmc.motion.table import Table
from flowmc.registry import In, NodeType, Out, register


@register
class LogReport(NodeType):
    type_id = "device.log_report"
    title = "Log report"
    category = "Devices"
    description = "Duration, end position, peak following error and I/O changes of what a device did."
    inputs = (In("log", "Log", doc="A device node's log"),)
    outputs = (
        Out("duration", "Number", doc="Time the operation took (s)"),
        Out("max_following_error", "Number", doc="Largest |commanded - actual| over all axes (mm; 0 in open loop)"),
        Out("changes", "Table", doc="I/O changes: t, kind, channel, value"),
        Out("summary", "Table", doc="Per axis: end position and peak following error"),
    )

    def run(self, ctx, params, log):
        ferr = log.following_error
        per_axis = np.zeros(len(log.axes)) if ferr is None or not len(ferr) else np.abs(ferr).max(axis=0)
        changes = Table({
            "t": [c.t for c in log.changes],
            "kind": np.array([c.kind for c in log.changes], dtype=str),
            "channel": np.array([c.channel for c in log.changes], dtype=int),
            "value": [c.value for c in log.changes],
        })
        summary = Table({"axis": list(log.axes), "end_mm": log.position[-1] if len(log.position) else
                         np.zeros(len(log.axes)), "max_following_error_mm": per_axis})
        duration = float(log.t[-1] - log.t[0]) if len(log.t) else 0.0
        return {"duration": duration, "max_following_error": float(per_axis.max(initial=0.0)),
                "changes": changes, "summary": summary}
