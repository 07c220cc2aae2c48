"""The editor's side-panel tabs other than the inspector: the node palette and the problem list."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from flowmc.graph import Issue
from flowmc.ui import canvas_draw, palette_list
from flowmc.ui.palette import PaletteItem, categories, palette_items, search
from flowmc.ui.text import md, plain

if TYPE_CHECKING:
    from flowmc.ui.session import PanelHost

__all__ = ["PalettePanel", "ProblemsPanel"]

MAX_PROBLEMS = 25


class PalettePanel:
    """The node palette, built in ``container`` (a tab): a search box and the entries as one HTML list
    (``palette_list``), in category folders (or, while searching, the matches best first). A click on an
    entry adds the node at a free spot in the middle of the view (the page script sends ``palette-add``);
    dragging it onto the canvas adds it where it is dropped (``palette-drop``). ``shown`` is what the list
    shows, in order."""

    def __init__(self, host: "PanelHost", container: Any):
        self.host, self.container = host, container
        gui = host.gui
        with container:
            gui.add_html('<div style="font-size:12px;opacity:.75;padding:0 var(--mantine-spacing-xs) .4em">'
                         'Click to add at the middle of the view, or drag onto the canvas.</div>')
            self.search = gui.add_text("Search", "", hint="Part of a name, category, description or port type (e.g. Trajectory)")
            self.count = gui.add_markdown("")
            self.list = gui.add_html("")
        self.items: list[PaletteItem] = []
        self.shown: list[PaletteItem] = []
        self.search.on_update(lambda _e: self.refresh(reload=False))
        self.refresh()

    def refresh(self, reload: bool = True) -> None:
        """Show the entries matching the search text (``reload``: look at the node types and files again)."""
        state = self.host.session.state
        with self.host.session.lock:
            if reload or not self.items:
                self.items = palette_items(self.host.session.runtime.registry, state.base_dir, exclude=state.path)
            query = self.search.value.strip()
            found = search(self.items, query)
            self.count.content = (md("{} of {} entries match", len(found), len(self.items)) if query
                                  else md("{} entries", len(self.items)))
            groups = {"Matches": found} if query else categories(found)
            self.shown = [item for items in groups.values() for item in items]
            self.list.content = palette_list.render(groups)

    def add(self, item: PaletteItem, at: tuple[float, float] | None = None) -> str:
        """Add ``item`` at the free spot nearest ``at`` (canvas pixels; default the middle of the view), and select it."""
        node_id = self.host.add_node(item.type_id, dict(item.params), at)
        self.host.notify("info", f"added {node_id} ({item.title})")
        return node_id

    def picked(self, key: Any, at: tuple[float, float] | None = None) -> str | None:
        """The entry with ``key`` clicked (``at`` None) or dropped on the canvas at ``at`` (canvas px): add it.
        A key the palette does not hold (the page is not trusted) is ignored."""
        item = next((i for i in self.items if i.key == key), None) if isinstance(key, str) else None
        return self.add(item, at) if item is not None else None


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
