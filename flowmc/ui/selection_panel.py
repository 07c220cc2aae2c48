"""What can be done with the selection, above the inspector: delete it, align it, open a sub-graph
node's file, make a sub-graph from the selected nodes, go back to the graph a sub-graph was opened
from; edit a comment's or label's text, rename an interface terminal."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from flowmc.errors import FlowmcError
from flowmc.ui.arrange import ALIGNMENTS
from flowmc.ui.layout import terminal_of
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
            self.align = gui.add_dropdown("Align", ("choose…", *ALIGNMENTS), hint="Line up or spread the selected nodes")
            self.note_text = gui.add_text("Text", "", multiline=True, hint="The comment's or label's text")
            self.terminal_name = gui.add_text("Port name", "", hint="The interface port's name (its wires follow)")
        self.delete_button.on_click(lambda _e: host.edit("Delete"))
        self.align.on_update(lambda _e: self._align())
        self.note_text.on_update(lambda _e: self._note_text())
        self.terminal_name.on_update(lambda _e: self._rename())
        self._showing = False  # True while show() sets the fields (their updates are not edits)
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
        notes = state.selected_notes
        if notes:
            parts.append(("note " if len(notes) == 1 else f"{len(notes)} notes: ") + ", ".join(n[1:] for n in notes[:8]))
        self.summary.content = md("Selected: {}", "; ".join(parts)) if parts else \
            "Nothing selected. Click a node, a wire or a note; shift-click to add to the selection."
        real = [n for n in nodes if terminal_of(n) is None]
        self.delete_button.visible = bool(nodes or wires or notes)
        self.open_button.visible = len(nodes) == 1 and not nodes[0].startswith("@") and self._file_of(nodes[0]) is not None
        self.back_button.visible = bool(state.parents)
        self.sub_name.visible = self.make_button.visible = bool(real)
        self.align.visible = len(nodes) + len(notes) >= 2
        one_note = state.note(notes[0]) if len(notes) == 1 and not nodes else None
        one_terminal = terminal_of(nodes[0]) if len(nodes) == 1 and not notes else None
        self._showing = True
        try:
            self.note_text.visible = one_note is not None
            if one_note is not None and self.note_text.value != one_note.text:
                self.note_text.value = one_note.text
            self.terminal_name.visible = one_terminal is not None
            if one_terminal is not None and self.terminal_name.value != one_terminal[1]:
                self.terminal_name.value = one_terminal[1]
        finally:
            self._showing = False

    def _align(self) -> None:
        how = self.align.value
        if how in ALIGNMENTS:
            self.host.edit(f"Align:{how}")
            self.align.value = "choose…"

    def _note_text(self) -> None:
        state = self.session.state
        if self._showing or len(state.selected_notes) != 1:
            return
        with self.session.lock:
            state.set_note(state.selected_notes[0], text=self.note_text.value)

    def _rename(self) -> None:
        state = self.session.state
        if self._showing or len(state.selected_nodes) != 1 or terminal_of(state.selected_nodes[0]) is None:
            return
        with self.session.lock:
            try:
                state.rename_terminal(state.selected_nodes[0], self.terminal_name.value.strip())
            except FlowmcError as exc:
                self.host.notify("error", str(exc))

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
        """Save the sub-graph (asking first if that breaks its parents) and return to the graph that opened it."""
        host, state = self.host, self.session.state
        with self.session.lock:
            if state.dirty:
                host.edit("Save")
                if state.dirty:
                    return False  # not saved: a dialog asks, or the save failed and said why
            try:
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
