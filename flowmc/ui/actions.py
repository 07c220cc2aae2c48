"""Editing commands beyond a single click: copy, cut, paste and duplicate; auto-layout, align and
distribute; comments and labels; select all. The editor's buttons and hotkeys call them.

The clipboard is kept per editor process (``CLIPBOARD``), so a piece copied in one graph pastes
into any other the editor opens, and it is also put on the browser's clipboard, so it pastes
into an editor in another tab or process (the page sends pasted text back: ``paste_text``).
"""

from __future__ import annotations

import json
from typing import TYPE_CHECKING, Any

from flowmc.errors import GraphError
from flowmc.ui import arrange, clipboard, layout, viser_internals

if TYPE_CHECKING:
    from flowmc.ui.app import Editor

__all__ = ["Actions", "CLIPBOARD"]

CLIPBOARD: dict[str, str | None] = {"text": None}


class Actions:
    def __init__(self, editor: "Editor"):
        self.editor = editor

    @property
    def state(self) -> Any:
        return self.editor.state

    def rects(self, keys: list[str] | None = None) -> dict[str, arrange.Rect]:
        """Canvas-pixel rectangles of nodes, terminals and notes (all, or ``keys``)."""
        canvas, s = self.editor.canvas, layout.SCALE
        out = {b.node_id: arrange.Rect(b.x / s, -b.y / s, b.w / s, b.h / s) for b in canvas.boxes}
        out.update({n.note_id: arrange.Rect(n.x / s, -n.y / s, n.w / s, n.h / s) for n in canvas.notes})
        return out if keys is None else {k: out[k] for k in keys if k in out}

    # ------------------------------------------------------------------ clipboard
    def copy(self, cut: bool = False) -> bool:
        with self.editor.lock:
            text = self.state.copy_selection()
            if text is None:
                self.editor.notify("info", "select nodes, comments or labels to copy")
                return False
            CLIPBOARD["text"] = text
            count = len([n for n in self.state.selected_nodes if not n.startswith("@")]) + len(self.state.selected_notes)
            if cut:
                self.state.delete_selection()
        for client in self.editor.server.get_clients().values():
            viser_internals.run_js(client, f"navigator.clipboard && navigator.clipboard.writeText({json.dumps(text)})"
                                           ".catch(() => {});")
        self.editor.notify("info", f"{'cut' if cut else 'copied'} {count} item{'s' if count != 1 else ''}")
        return True

    def paste_text(self, text: str | None, near: tuple[float, float] | None = None) -> list[str]:
        """Paste ``text`` if it is a flowmc piece, else the editor's own clipboard, at a free spot near
        ``near`` (canvas px; default the middle of the view). Returns the new node ids."""
        text = text if clipboard.parse(text or "") is not None else CLIPBOARD["text"]
        if text is None:
            self.editor.notify("info", "nothing to paste: copy nodes first (Ctrl+C)")
            return []
        fragment = clipboard.parse(text)
        if fragment is None:
            return []
        with self.editor.lock:
            items = [*fragment["nodes"], *fragment["comments"], *fragment["labels"]]
            x0, y0 = min(i.pos[0] for i in items), min(i.pos[1] for i in items)
            size = (max(i.pos[0] for i in items) - x0 + 220.0, max(i.pos[1] for i in items) - y0 + 120.0)
            centre = near or self.editor.canvas.view_centre()
            at = arrange.free_spot(self.rects().values(), size, centre)
            try:
                nodes = self.state.paste(text, at)
            except GraphError as exc:
                self.editor.notify("error", str(exc))
                return []
        self.editor.notify("info", f"pasted {len(nodes)} node{'s' if len(nodes) != 1 else ''}")
        return nodes

    def duplicate(self) -> list[str]:
        """Copy the selection and paste it beside itself."""
        with self.editor.lock:
            keys = [*self.state.selected_nodes, *self.state.selected_notes]
            rects = self.rects(keys)
            text = self.state.copy_selection()
            if not rects or text is None:
                self.editor.notify("info", "select nodes to duplicate")
                return []
            right = max(r.x + r.w for r in rects.values()) + 40.0
            top = min(r.y for r in rects.values())
            height = max(r.y + r.h for r in rects.values()) - top
            return self.paste_text(text, (right + (right - min(r.x for r in rects.values())) / 2, top + height / 2))

    # ------------------------------------------------------------------ arranging
    def auto_layout(self) -> None:
        """Layered layout of the whole graph (one undo step), then frame it."""
        with self.editor.lock:
            keys = [b.node_id for b in self.editor.canvas.boxes]
            rects = self.rects(keys)
            edges = [(self._owner(a), self._owner(b)) for a, b in self.state.wire_keys()]
            places = arrange.auto_layout(rects, edges)
            self.state.record()
            self._carry_comments(rects, places)
            self.state.move_nodes(places, record=False)
            self.editor.canvas.fit()

    @staticmethod
    def _owner(ref: str) -> str:
        return ref if ref.startswith("@") else ref.partition(".")[0]

    def _carry_comments(self, rects: dict[str, arrange.Rect], places: dict[str, tuple[float, float]]) -> None:
        """A comment that framed some nodes frames them again after they moved (it grows or shrinks to fit)."""
        for comment in self.state.graph.view.comments:
            x, y, (w, h) = comment.pos[0], comment.pos[1], comment.size
            inside = [k for k, r in rects.items() if x <= r.x and r.x + r.w <= x + w and y <= r.y and r.y + r.h <= y + h]
            if not inside:
                continue
            moved = [rects[k].moved(*places[k]) for k in inside]
            left, top = min(r.x for r in moved) - 20, min(r.y for r in moved) - layout.COMMENT_BAR - 20
            places[f"#{comment.id}"] = (left, top)
            comment.size = (max(r.x + r.w for r in moved) + 20 - left, max(r.y + r.h for r in moved) + 20 - top)

    def align(self, how: str) -> None:
        with self.editor.lock:
            rects = self.rects([*self.state.selected_nodes, *self.state.selected_notes])
            if len(rects) < 2:
                self.editor.notify("info", "select two or more nodes to align them")
                return
            self.state.move_nodes(arrange.align(rects, how))

    def select_all(self) -> None:
        with self.editor.lock:
            self.state.select(nodes=[b.node_id for b in self.editor.canvas.boxes],
                              notes=[n.note_id for n in self.editor.canvas.notes])

    # ------------------------------------------------------------------ notes
    def add_note(self, kind: str) -> str:
        """A comment around the selected nodes (or at a free spot), or a label at a free spot; selected."""
        with self.editor.lock:
            rects = self.rects(self.state.selected_nodes)
            if kind == "comment" and rects:
                left, top = min(r.x for r in rects.values()) - 20, min(r.y for r in rects.values()) - layout.COMMENT_BAR - 20
                size = (max(r.x + r.w for r in rects.values()) + 20 - left, max(r.y + r.h for r in rects.values()) + 20 - top)
                key = self.state.add_note("comment", "Comment", (left, top), size)
            else:
                size = (320.0, 200.0) if kind == "comment" else (160.0, 24.0)
                at = arrange.free_spot(self.rects().values(), size, self.editor.canvas.view_centre())
                key = self.state.add_note(kind, "Comment" if kind == "comment" else "Label", at,
                                          size if kind == "comment" else None)
            self.state.select(notes=[key])
            return key
