"""The Files tab: open, save, save as, upload, download, new, and export G-code.

Files are read and written only inside the editor's folder (the folder of the graph it was started
on): names typed here are resolved with the core's ``resolve_inside``. Saving is flowmc's atomic
canonical save. Opening another file over unsaved changes asks first.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from flowmc.errors import FlowmcError, GraphError
from flowmc.graph import Graph, dumps
from flowmc.runtime import resolve_inside
from flowmc.ui.interface_check import broken_parents, interface_changed
from flowmc.ui.text import md

if TYPE_CHECKING:
    from flowmc.ui.session import PanelHost

__all__ = ["FilesPanel", "graph_files"]

SUFFIX = ".flowmc.json"


def graph_files(folder: Path) -> list[str]:
    """Graph files under ``folder`` (two levels deep), as relative paths, sorted."""
    found = list(folder.glob(f"*{SUFFIX}")) + list(folder.glob(f"*/*{SUFFIX}"))
    return sorted(p.relative_to(folder).as_posix() for p in found if not p.name.startswith("."))


class FilesPanel:
    def __init__(self, host: "PanelHost"):
        self.host = host
        self.state = host.session.state
        gui = host.gui
        self.where = gui.add_markdown("")
        self.open_choice = gui.add_dropdown("File", ("(none)",))
        self.open_button = gui.add_button("Open", hint="Open the chosen graph file")
        self.save_button = gui.add_button("Save", hint="Save to the open file (Ctrl+S)")
        self.save_as_name = gui.add_text("Save as", "", hint="File name, relative to the folder")
        self.save_as_button = gui.add_button("Save as…")
        self.new_button = gui.add_button("New graph")
        self.upload_button = gui.add_upload_button("Upload a graph", mime_type=".json,application/json")
        self.download_button = gui.add_button("Download the graph")
        self.gcode_button = gui.add_button("Export G-code", hint="Run the graph and write its Path output as G-code")
        self.open_button.on_click(lambda e: self.open(self.open_choice.value, client=e.client))
        self.save_button.on_click(lambda e: self.save())
        self.save_as_button.on_click(lambda e: self.save_as(self.save_as_name.value, e.client))
        self.new_button.on_click(lambda e: self.confirm_discard(self._new, e.client))
        self.upload_button.on_upload(lambda e: self.upload(e.target.value.name, e.target.value.content, e.client))
        self.download_button.on_click(lambda e: self.download(e.client))
        self.gcode_button.on_click(lambda e: self.host.export_gcode(e.client))
        self.refresh()

    def refresh(self) -> None:
        """Re-list the folder's graph files and show where the editor reads and writes."""
        state = self.state
        files = graph_files(state.folder) or ["(none)"]
        self.open_choice.options = tuple(files)
        current = state.path.resolve().relative_to(state.folder).as_posix() if state.path is not None and \
            state.path.resolve().is_relative_to(state.folder) else None
        if current in files:
            self.open_choice.value = current
        self.save_as_name.value = current or state.suggested_name
        self.where.content = md("Folder: {}", state.folder)

    def _inside(self, name: str) -> Path:
        name = name.strip()
        if name and not name.endswith(SUFFIX):
            name += SUFFIX
        return resolve_inside(self.state.folder, self.state.folder, name, where="file name")

    def open(self, name: str, client: Any = None, confirmed: bool = False) -> bool:
        if not confirmed:
            return self.confirm_discard(lambda: self.open(name, client, confirmed=True), client)
        try:
            self.state.load(self._inside(name))
        except GraphError as exc:
            self.host.notify("error", str(exc))
            return False
        self.host.notify("info", f"opened {name}")
        return True

    def _new(self) -> None:
        self.state.load_text(dumps(Graph()), "untitled.flowmc.json")

    def save(self, client: Any = None, confirmed: bool = False) -> bool:
        """Save to the open file. A file outside the editor's folder (an example) is not overwritten; a
        sub-graph whose interface changed asks first when that breaks wires in graphs that use it."""
        state = self.state
        if state.path is None:
            return self.save_as(self.save_as_name.value)
        if not state.path.resolve().is_relative_to(state.folder):
            self.host.notify("error", f"{state.path.name} is outside the editor's folder (an example?): "
                                      "use Save as to keep a copy in your folder", client)
            return False
        if not confirmed and interface_changed(state.graph, state.path):
            broken = broken_parents(state.graph, state.path, state.folder, self.host.session.runtime.registry,
                                    state.waiting)
            if broken:
                shown = "  \n".join(md("- {}", line) for line in broken[:12]) + (
                    md("  \n… and {} more", len(broken) - 12) if len(broken) > 12 else "")
                self.host.confirm("Saving changes the interface",
                                  md("Saving {} changes its interface and breaks {} wire{} in graphs that use it:",
                                     state.path.name, len(broken), "s" if len(broken) != 1 else "") + "  \n" + shown,
                                  "Save anyway", lambda: self.save(client, confirmed=True), client)
                self.host.notify("error", f"saving {state.path.name} would break {len(broken)} wire(s) in graphs "
                                          "that use it: confirm or undo", client)
                return False
        try:
            target = state.save()
        except FlowmcError as exc:
            self.host.notify("error", str(exc))
            return False
        self.host.notify("info", f"saved {target.name}")
        return True

    def save_as(self, name: str, client: Any = None, confirmed: bool = False) -> bool:
        """Save under ``name``; another file of that name is replaced only after the user agrees."""
        try:
            target = self._inside(name)
            if not confirmed and target != self.state.path and (target.is_file() or target.is_symlink()):
                self.host.confirm("Replace the file?", md("**{}** exists. Replace it with this graph?", target.name),
                                  "Replace", lambda: self.save_as(name, client, confirmed=True), client)
                return False
            target = self.state.save(target)
        except FlowmcError as exc:
            self.host.notify("error", str(exc))
            return False
        self.refresh()
        self.host.notify("info", f"saved {target.name}")
        return True

    def upload(self, name: str, content: bytes, client: Any = None) -> bool:
        try:
            text = content.decode("utf-8-sig")  # a byte-order mark is not part of the graph
        except UnicodeDecodeError:
            self.host.notify("error", f"{name}: not a text file")
            return False

        def load() -> None:
            try:
                self.state.load_text(text, name)
            except GraphError as exc:
                detail = "; ".join(i.message for i in exc.issues[:3]) if exc.issues else ""
                self.host.notify("error", f"{exc}" + (f" ({detail})" if detail and detail not in str(exc) else ""))
                return
            self.save_as_name.value = self.state.suggested_name
            self.host.notify("info", f"uploaded {name}: not saved yet (Save as to keep it)")

        return self.confirm_discard(load, client)

    def download(self, client: Any = None) -> None:
        state = self.state
        name = state.path.name if state.path is not None else state.suggested_name
        self.host.download(name, dumps(state.graph), client)

    def confirm_discard(self, action: Any, client: Any = None) -> bool:
        """Do ``action`` now, or after the user agrees to lose unsaved changes (a dialog in the browser)."""
        if not self.state.dirty:
            action()
            return True
        self.host.confirm("Unsaved changes", "The open graph has unsaved changes. Discard them?", "Discard changes",
                          action, client)
        return False
