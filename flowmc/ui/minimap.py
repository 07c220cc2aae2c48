"""The minimap: a small floating picture of the whole graph in the canvas's bottom-right corner, with
the part in view outlined; a click on it moves the view there. It shows for graphs of more than
``MIN_BOXES`` boxes (a small graph fits the view anyway) and follows every edit and camera move
(at most ``RATE`` times a second).
"""

from __future__ import annotations

import threading
import time
from typing import TYPE_CHECKING, Any

from flowmc.ui import camera, layout
from flowmc.ui.text import escape_html

if TYPE_CHECKING:
    from flowmc.ui.app import Editor

__all__ = ["Minimap", "svg"]

MIN_BOXES = 20
W, H = 220, 150
RATE = 5.0


def svg(boxes: list[Any], view: tuple[float, float, float, float] | None, selected: set[str]) -> str:
    """The minimap picture: node boxes (selected ones orange) and the view's rectangle, in world units."""
    box = layout.bounds(boxes)
    if box is None:
        return ""
    x0, y0, x1, y1 = box
    if view is not None:
        x0, y0, x1, y1 = min(x0, view[0]), min(y0, view[1]), max(x1, view[2]), max(y1, view[3])
    scale = min((W - 8) / max(x1 - x0, 1e-9), (H - 8) / max(y1 - y0, 1e-9))

    def rect(a: float, b: float, c: float, d: float) -> str:  # world (xmin, ymin, xmax, ymax) -> svg attributes
        return (f"x='{4 + (a - x0) * scale:.1f}' y='{4 + (y1 - d) * scale:.1f}' "
                f"width='{max((c - a) * scale, 1):.1f}' height='{max((d - b) * scale, 1):.1f}'")

    parts = [f"<rect {rect(*b.rect)} fill='{'#ff8c00' if b.node_id in selected else '#8792a2'}'/>" for b in boxes]
    if view is not None:
        parts.append(f"<rect {rect(*view)} fill='rgba(34,139,230,.12)' stroke='#228be6' stroke-width='1.5'/>")
    return (f"<svg data-flowmc-minimap='{escape_html(f'{x0},{y1},{scale}')}' width='{W}' height='{H}' "
            f"style='display:block;cursor:pointer;background:#f8f9fa;border-radius:4px'>{''.join(parts)}</svg>")


class Minimap:
    def __init__(self, editor: "Editor"):
        self.editor = editor
        gui = editor.gui
        self.panel = gui.add_panel(visible=False)
        with self.panel.add_tab("Minimap"):
            self.html = gui.add_html("")
        self.panel.float(x=-16, y=-16, width=W + 24, height=H + 56)
        self._last = 0.0
        self._trailing: threading.Timer | None = None
        editor.on_page_event("minimap", self._clicked)

    def _view(self) -> tuple[float, float, float, float] | None:
        clients = list(self.editor.server.get_clients().values())
        if not clients:
            return None
        cam = clients[0].camera
        return camera.screen_rect_to_world(cam, (0.0, 0.0), (1.0, 1.0))

    def refresh(self, force: bool = True) -> None:
        """Redraw (``force``: after an edit; else a camera move, at most ``RATE`` a second)."""
        now = time.monotonic()
        if not force and now - self._last < 1.0 / RATE:
            if self._trailing is None or not self._trailing.is_alive():  # the view where the camera came to rest
                self._trailing = threading.Timer(1.0 / RATE, self.refresh, kwargs={"force": True})
                self._trailing.daemon = True
                self._trailing.start()
            return
        self._last = now
        canvas = self.editor.canvas
        big = len(canvas.boxes) > MIN_BOXES
        if self.panel.visible != big:
            self.panel.visible = big
        if big:
            picture = svg(canvas.boxes, self._view(), set(self.editor.state.selected_nodes))
            if picture != self.html.content:
                self.html.content = picture

    def close(self) -> None:
        """Cancel the trailing redraw (or wait for it): the editor is stopping its server."""
        if self._trailing is not None:
            self._trailing.cancel()
            self._trailing.join()

    def _clicked(self, client: Any, data: Any) -> None:
        """Centre the view on the world point the minimap was clicked at (``data``: x, y in world units)."""
        try:
            x, y = float(data["x"]), float(data["y"])
        except (TypeError, KeyError, ValueError):
            return
        box = layout.bounds(self.editor.canvas.boxes)
        if box is None or not (box[0] - 50 <= x <= box[2] + 50 and box[1] - 50 <= y <= box[3] + 50):
            return
        cam = client.camera
        with client.atomic():
            cam.position = (x, y, float(cam.position[2]))
            cam.look_at = (x, y, 0.0)
