"""What can be done with the selection, above the inspector: delete it, open a sub-graph node's file,
make a sub-graph from the selected nodes, or go back to the graph a sub-graph was opened from."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from flowmc.errors import FlowmcError
from flowmc.ui.text import md

if TYPE_CHECKING:
    from flowmc.ui.session import PanelHost

__all__ = ["SelectionPanel"]


class SelectionPanel:
    def __init__(self, host: "PanelHost"):
        self.host = host
        self.session = host.session
        gui = host.gui
        self.folder = gui.add_folder("Selection", order=1.0)
        with self.folder:
            self.summary = gui.add_markdown("")
            self.delete_button = gui.add_button("Delete selected", color="red", hint="Delete key")
            self.open_button = gui.add_button("Open sub-graph", hint="Edit the graph file this node runs")
            self.back_button = gui.add_button("Save and go back", hint="Back to the graph this sub-graph was opened from")
            self.sub_name = gui.add_text("Sub-graph file", "part_sub.flowmc.json",
                                         hint="New file for the selected nodes, in this graph's folder")
            self.make_button = gui.add_button("Make sub-graph from selection",
                                              hint="Wires crossing the selection become the new file's interface")
        self.delete_button.on_click(lambda _e: host.edit("Delete"))
        self.open_button.on_click(lambda _e: self.open_subgraph())
        self.back_button.on_click(lambda _e: self.go_back())
        self.make_button.on_click(lambda _e: self.make_subgraph())

    def show(self) -> None:
        state = self.session.state
        nodes, wires = state.selected_nodes, state.selected_wires
        parts = []
        if nodes:
            parts.append(("node " if len(nodes) == 1 else f"{len(nodes)} nodes: ") + ", ".join(nodes[:8])
                         + ("…" if len(nodes) > 8 else ""))
        if wires:
            parts.append(f"wire {wires[0][0]} → {wires[0][1]}" if len(wires) == 1 else f"{len(wires)} wires")
        self.summary.content = md("Selected: {}", "; ".join(parts)) if parts else \
            "Nothing selected. Click a node or a wire; shift-click to add to the selection."
        self.delete_button.visible = bool(nodes or wires)
        self.open_button.visible = len(nodes) == 1 and self._file_of(nodes[0]) is not None
        self.back_button.visible = bool(state.parents)
        self.sub_name.visible = self.make_button.visible = bool(nodes)

    def _file_of(self, node_id: str) -> Any:
        try:
            return self.session.state.subgraph_file(node_id)
        except FlowmcError:
            return None

    def open_subgraph(self) -> bool:
        host, state = self.host, self.session.state
        with self.session.lock:
            nodes = state.selected_nodes
            path = self._file_of(nodes[0]) if len(nodes) == 1 else None
            if path is None:
                host.notify("error", "select one sub-graph node (type subgraph or lib.*) with a file to open")
                return False
            try:
                state.enter(path)
            except FlowmcError as exc:
                host.notify("error", str(exc))
                return False
        host.notify("info", f"editing {path.name}: Save and go back returns to the graph that uses it")
        return True

    def go_back(self) -> bool:
        host, state = self.host, self.session.state
        with self.session.lock:
            try:
                if state.dirty:
                    state.save()
                state.leave()
            except FlowmcError as exc:
                host.notify("error", str(exc))
                return False
        return True

    def make_subgraph(self) -> str | None:
        host, state = self.host, self.session.state
        with self.session.lock:
            try:
                new_id = state.make_subgraph(state.selected_nodes, self.sub_name.value)
            except FlowmcError as exc:
                host.notify("error", str(exc))
                return None
            file = state.node(new_id).params["file"]
        host.files_changed()
        host.notify("info", f"made {file}; {new_id} runs it")
        return new_id
