"""The canvas's texts as viser labels: node titles always, the rest (port names, table previews,
run status) only when the view is close enough to read them.

Labels live under two scene frames, ``/canvas/titles`` and ``/canvas/detail``. Zoomed out, the
detail frame is hidden and its labels are dropped; they are made again when the view comes close
again. The editor decides before its first page connects, from the first framing: opening a
120-node graph at Fit sends titles only.
A label is resent only when its text changed; a move is a position update.
Each label sits directly under its frame (``/canvas/titles/t12.title``: the key's ``/`` becomes
``.``, which no key holds): a deeper name made viser add an anchor frame per node and part, and a
120-node page was sent about 480 more scene nodes to mount than it has labels.
"""

from __future__ import annotations

from typing import Any

from flowmc.ui.canvas_draw import Z_LABELS
from flowmc.ui.text import plain

__all__ = ["Texts", "DETAIL_ON", "DETAIL_OFF"]

# Screen pixels per canvas pixel at which details appear and disappear (a 10.5 px port name is then
# 7.3 or 6.3 px on screen); the gap keeps them from flickering at one zoom.
DETAIL_ON = 0.7
DETAIL_OFF = 0.6


class Texts:
    def __init__(self, scene: Any):
        self.scene = scene
        self.detail = True
        self.handles: dict[str, tuple[Any, str, tuple[float, float], float]] = {}
        self.wanted: dict[str, tuple[str, tuple[float, float], float, str, bool]] = {}
        self._frames = {False: scene.add_frame("/canvas/titles", show_axes=False),
                        True: scene.add_frame("/canvas/detail", show_axes=False)}

    def show(self, wanted: dict[str, tuple[str, tuple[float, float], float, str, bool]]) -> None:
        """Make the labels match ``wanted``: key -> (text, world (x, y), font height, anchor, is_detail)."""
        self.wanted = wanted
        for key in [k for k in self.handles if k not in wanted]:
            self.handles.pop(key)[0].remove()
        for key, (text, pos, size, anchor, detail) in wanted.items():
            if detail and not self.detail and key not in self.handles:
                continue  # made when the view comes close enough to read it
            self._put(key, text, pos, size, anchor, detail)

    def _put(self, key: str, text: str, pos: tuple[float, float], size: float, anchor: str, detail: bool) -> None:
        old = self.handles.get(key)
        if old is not None and old[1] == text and old[2] == pos and old[3] == size:
            return
        if old is not None and old[1] == text and old[3] == size:
            old[0].position = (pos[0], pos[1], Z_LABELS)
            self.handles[key] = (old[0], text, pos, size)
            return
        if old is not None:
            old[0].remove()
        parent = "/canvas/detail" if detail else "/canvas/titles"
        handle = self.scene.add_label(f"{parent}/{key.replace('/', '.')}", plain(text, 400), position=(pos[0], pos[1], Z_LABELS),
                                      font_size_mode="scene", font_scene_height=size, anchor=anchor)
        self.handles[key] = (handle, text, pos, size)

    def set_detail(self, on: bool) -> bool:
        """Show or hide the detail labels (made now if they were left out); True when it changed."""
        if on == self.detail:
            return False
        self.detail = on
        self._frames[True].visible = on
        if on:
            self.show(self.wanted)
        else:  # dropped, not just hidden: a page that opens now is not sent hundreds of labels it does not show
            for key, (*_rest, detail) in self.wanted.items():
                if detail and key in self.handles:
                    self.handles.pop(key)[0].remove()
        return True

    def zoom(self, screen_px_per_canvas_px: float) -> bool:
        """Details on or off for a view showing one canvas pixel as this many screen pixels."""
        if self.detail and screen_px_per_canvas_px < DETAIL_OFF:
            return self.set_detail(False)
        if not self.detail and screen_px_per_canvas_px >= DETAIL_ON:
            return self.set_detail(True)
        return False
