"""What can be done with the selection, above the inspector: delete it, open a sub-graph node's file,
make a sub-graph from the selected nodes, or go back to the graph a sub-graph was opened from."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from flowmc.errors import FlowmcError
from flowmc.ui.text import md

if TYPE_CHECKING:
    from flowmc.ui.app import Editor

__all__ = ["SelectionPanel"]


class SelectionPanel:
    def __init__(self, editor: "Editor"):
        self.editor = editor
        gui = editor.server.gui
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
        self.delete_button.on_click(lambda _e: editor.edit("Delete"))
        self.open_button.on_click(lambda _e: self.open_subgraph())
        self.back_button.on_click(lambda _e: self.go_back())
        self.make_button.on_click(lambda _e: self.make_subgraph())

    def show(self) -> None:
        state = self.editor.state
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
            return self.editor.state.subgraph_file(node_id)
        except FlowmcError:
            return None

    def open_subgraph(self) -> bool:
        editor = self.editor
        with editor.lock:
            nodes = editor.state.selected_nodes
            path = self._file_of(nodes[0]) if len(nodes) == 1 else None
            if path is None:
                editor.notify("error", "select one sub-graph node (type subgraph or lib.*) with a file to open")
                return False
            try:
                editor.state.enter(path)
            except FlowmcError as exc:
                editor.notify("error", str(exc))
                return False
        editor.notify("info", f"editing {path.name}: Save and go back returns to the graph that uses it")
        return True

    def go_back(self) -> bool:
        editor = self.editor
        with editor.lock:
            try:
                if editor.state.dirty:
                    editor.state.save()
                editor.state.leave()
            except FlowmcError as exc:
                editor.notify("error", str(exc))
                return False
        return True

    def make_subgraph(self) -> str | None:
        editor = self.editor
        with editor.lock:
            try:
                new_id = editor.state.make_subgraph(editor.state.selected_nodes, self.sub_name.value)
            except FlowmcError as exc:
                editor.notify("error", str(exc))
                return None
            file = editor.state.node(new_id).params["file"]
        editor.palette.refresh()
        editor.notify("info", f"made {file}; {new_id} runs it")
        return new_id
