"""Wiring on the canvas: drag from a port to a port, or click one port and then the other.

While a wire is dragged, a rubber band follows the pointer from the port it started at, the ports
it may end on grow and the others turn grey; letting go near a compatible port wires it, anywhere
else drops it. Either end may be the start (an output dragged to an input, or the other way).
The rules and the refusal messages are ``EditorState.connect``'s (``wiring``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from flowmc.ui import canvas_draw as draw
from flowmc.ui import layout
from flowmc.ui.ports import port_color

if TYPE_CHECKING:
    from flowmc.ui.canvas import Canvas

__all__ = ["WireDrag", "ref_of"]

SNAP = 0.25  # world units (25 canvas px): how near a port the pointer must be let go to wire it


def ref_of(box_id: str, port: str) -> str:
    """How a wire names a port: "node.port", or a terminal's own id (it has one port)."""
    return box_id if box_id.startswith("@") else f"{box_id}.{port}"


class WireDrag:
    def __init__(self, canvas: "Canvas"):
        self.canvas = canvas
        self.start: tuple[str, layout.PortSpot] | None = None
        self.band: Any = None

    # ------------------------------------------------------------------ which ports fit
    def compatible(self, box_id: str, spot: layout.PortSpot) -> dict[tuple[str, str, str], bool]:
        """Every port on the canvas, True where a wire from (box_id, spot) may end."""
        out: dict[tuple[str, str, str], bool] = {}
        for other, s in self.canvas.port_index:
            ok = other != box_id and s.info.kind != spot.info.kind
            if ok and spot.info.kind == "out":
                ok = s.info.accepts(spot.info.type)
            elif ok:
                ok = spot.info.accepts(s.info.type)
            out[(other, s.info.kind, s.info.name)] = ok
        return out

    def connect(self, a: tuple[str, Any], b: tuple[str, Any]) -> str | None:
        """Wire port ``a`` to port ``b`` (either order: the output feeds the input); the refusal, or None."""
        (box_a, info_a), (box_b, info_b) = a, b
        if info_a.kind == info_b.kind:
            both = "outputs" if info_a.kind == "out" else "inputs"
            return (f"{ref_of(box_a, info_a.name)} and {ref_of(box_b, info_b.name)} are both {both}: "
                    "wire an output to an input")
        (src, s_info), (dst, d_info) = (a, b) if info_a.kind == "out" else (b, a)
        return self.canvas.state.connect(ref_of(src, s_info.name), ref_of(dst, d_info.name))

    # ------------------------------------------------------------------ click, then click
    def port_clicked(self, got: layout.Hit) -> None:
        canvas = self.canvas
        first, canvas.pending = canvas.pending, None
        if got.port is None:
            return
        if first is None or first.port is None:
            canvas.pending = got
            other = "an input" if got.port.kind == "out" else "an output"
            canvas.notify("info", f"{ref_of(got.node_id, got.port.name)} picked: now click {other} to wire it "
                                  "(or drag from a port to a port)")
            canvas.sync()
            return
        if (first.node_id, first.port.name, first.port.kind) != (got.node_id, got.port.name, got.port.kind):
            reason = self.connect((first.node_id, first.port), (got.node_id, got.port))
            if reason is not None:
                canvas.notify("error", reason)
        canvas.sync()

    # ------------------------------------------------------------------ drag
    async def on_drag(self, event: Any) -> None:
        canvas = self.canvas
        with canvas.lock:
            if event.phase == "start":
                k = event.instance_index
                if k is None or k >= len(canvas.port_index):
                    return
                self.start = canvas.port_index[k]
                canvas.pending = None
                canvas.highlight = self.compatible(*self.start)
                self._band(np.asarray(event.end_position[:2]))
                canvas.sync_selection()
                return
            if self.start is None:
                return
            point = np.asarray(event.end_position[:2])
            if event.phase == "update":
                self._band(point)
                canvas.server.flush()
                return
            start, self.start = self.start, None
            target = self._target(point, canvas.highlight or {})
            canvas.highlight = None
            if self.band is not None:
                self.band.remove()
                self.band = None
            if target is not None:
                reason = self.connect((start[0], start[1].info), (target[0], target[1].info))
                if reason is not None:
                    canvas.notify("error", reason)
            canvas.sync()

    def _target(self, point: np.ndarray, fits: dict[tuple[str, str, str], bool]) -> tuple[str, layout.PortSpot] | None:
        """The compatible port nearest the point where the wire was let go (within SNAP), else None."""
        best = None
        for box_id, spot in self.canvas.port_index:
            if not fits.get((box_id, spot.info.kind, spot.info.name)):
                continue
            d = float(np.hypot(spot.x - point[0], spot.y - point[1]))
            if d <= SNAP and (best is None or d < best[0]):
                best = (d, (box_id, spot))
        return best[1] if best is not None else None

    def _band(self, point: np.ndarray) -> None:
        """The rubber band from the start port to the pointer (a wire curve, in the start port's colour)."""
        if self.start is None:
            return
        _, spot = self.start
        a, b = (spot.x, spot.y), (float(point[0]), float(point[1]))
        pts = layout.wire_points(a, b) if spot.info.kind == "out" else layout.wire_points(b, a)
        p = np.column_stack([pts, np.full(len(pts), draw.Z_LABELS - 0.01)])
        segs = np.stack([p[:-1], p[1:]], axis=1).astype(np.float32)
        if self.band is not None and self.band.points.shape == segs.shape:
            self.band.points = segs
            return
        colors = np.broadcast_to(np.asarray(port_color(spot.info.type), np.uint8), segs.shape).copy()
        self.band = self.canvas.server.scene.add_line_segments("/canvas/rubber", segs, colors, thickness=0.045)
