"""The editor's side-panel tabs other than the inspector: the node palette and the problem list."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from flowmc.graph import Issue
from flowmc.ui import canvas_draw, layout
from flowmc.ui.palette import PaletteItem, palette_items, search
from flowmc.ui.text import md, plain

if TYPE_CHECKING:
    from flowmc.ui.session import PanelHost

__all__ = ["PalettePanel", "ProblemsPanel", "free_spot"]

MAX_RESULTS = 14
MAX_PROBLEMS = 25


class PalettePanel:
    """A search box and one button per matching entry; a click adds that node in the middle of the view.
    ``buttons`` is keyed by ``PaletteItem.key`` (``path.translate``, ``lib.pocket``, ``subgraph:part.flowmc.json``)."""

    def __init__(self, host: "PanelHost"):
        self.host = host
        gui = host.gui
        self.search = gui.add_text("Search", "", hint="Type part of a name, category or description")
        self.count = gui.add_markdown("")
        self.folder = gui.add_folder("Results", expand_by_default=True)
        self.buttons: dict[str, Any] = {}
        self.items: list[PaletteItem] = []
        self.search.on_update(lambda _e: self.refresh(reload=False))
        self.refresh()

    def refresh(self, reload: bool = True) -> None:
        """Show the entries matching the search text (``reload``: look at the node types and files again)."""
        state, gui = self.host.session.state, self.host.gui
        with self.host.session.lock:
            if reload or not self.items:
                self.items = palette_items(self.host.session.runtime.registry, state.base_dir, exclude=state.path)
            found = search(self.items, self.search.value)
            self.count.content = md("{} of {} entries", len(found), len(self.items)) + (
                md("; the first {} shown", MAX_RESULTS) if len(found) > MAX_RESULTS else "")
            for button in self.buttons.values():
                button.remove()
            self.buttons = {}
            with self.folder:
                for item in found[:MAX_RESULTS]:
                    button = gui.add_button(plain(f"{item.title}  ·  {item.category}", 120),
                                            hint=plain(f"{item.key}: {item.description}"))
                    button.on_click(lambda _e, item=item: self.add(item))
                    self.buttons[item.key] = button

    def add(self, item: PaletteItem, at: tuple[float, float] | None = None) -> str:
        """Add ``item`` at the free spot nearest ``at`` (canvas pixels; default the middle of the view), and select it."""
        node_id = self.host.add_node(item.type_id, dict(item.params), at)
        self.host.notify("info", f"added {node_id} ({item.title})")
        return node_id


def free_spot(boxes: list[layout.NodeBox], centre: tuple[float, float], size: tuple[float, float] = (200.0, 140.0),
              gap: float = 30.0) -> tuple[float, float]:
    """Top-left (canvas pixels) of a ``size`` box near ``centre`` that overlaps no node, searched ring by ring."""
    taken = [(b.x / layout.SCALE, -b.y / layout.SCALE, b.w / layout.SCALE, b.h / layout.SCALE) for b in boxes]
    step_x, step_y = size[0] + gap, size[1] + gap
    x0, y0 = centre[0] - size[0] / 2, centre[1] - size[1] / 2
    for ring in range(0, 40):
        cells = [(i, j) for i in range(-ring, ring + 1) for j in range(-ring, ring + 1) if max(abs(i), abs(j)) == ring]
        cells.sort(key=lambda c: ((c[0] * step_x) ** 2 + (c[1] * step_y) ** 2, -c[0], -c[1]))
        for i, j in cells:
            x, y = x0 + i * step_x, y0 + j * step_y
            if all(x + size[0] + gap <= bx or bx + bw + gap <= x or y + size[1] + gap <= by or by + bh + gap <= y
                   for bx, by, bw, bh in taken):
                return round(x, 1), round(y, 1)
    return round(x0, 1), round(y0, 1)


class ProblemsPanel:
    """What stops the graph running (validation issues) and what failed in the last run, one button
    per problem: clicking it selects the node it is about."""

    def __init__(self, host: "PanelHost"):
        self.host = host
        self.summary = host.gui.add_markdown("No problems.")
        self.folder = host.gui.add_folder("List", expand_by_default=True)
        self.buttons: list[Any] = []
        self.lines: list[str] = []

    def show(self, issues: list[Issue], run_errors: dict[str, str]) -> None:
        host, gui = self.host, self.host.gui
        wires = host.session.state.graph.wires
        entries = [(canvas_draw.issue_node(i, wires), i.message) for i in issues] + [(n, m) for n, m in run_errors.items()]
        lines = [m for _, m in entries]
        if lines == self.lines:
            return
        self.lines = lines
        parts = []
        if issues:
            parts.append(f"**{len(issues)} problem{'s' if len(issues) != 1 else ''}** stop the graph from running.")
        if run_errors:
            parts.append(f"**{len(run_errors)} node{'s' if len(run_errors) != 1 else ''} failed** in the last run.")
        self.summary.content = " ".join(parts) or "No problems."
        for button in self.buttons:
            button.remove()
        self.buttons = []
        with self.folder:
            for node_id, message in entries[:MAX_PROBLEMS]:
                button = gui.add_button(plain(canvas_draw.shorten(message, 90)), hint=plain(message), color="red")
                if node_id is not None:
                    button.on_click(lambda _e, n=node_id: host.select_node(n))
                self.buttons.append(button)
