"""The editor: ``flowmc serve [FILE]`` starts it. One viser server holds the node canvas (the scene),
the palette and examples docked on the left, and the side panel on the right (Run, edit and canvas
buttons, and tabs for the selection and its params, problems, files, the front panel, the device
and sweeps); the 3D toolpath view runs on a second server shown in a panel docked beside the palette,
collapsed until it has something to show (``extensions``). The canvas gets the rest of the page.

The editor edits and runs graphs only through the core's public API, by way of its
``EditorSession`` (document, runtime, run queue, results, device session). Panels get the editor as
a ``session.PanelHost``. Every change goes through ``session.lock``: viser runs callbacks on a
thread pool.
"""

from __future__ import annotations

import contextlib
import json
import socket
import sys
import threading
import time
from pathlib import Path
from typing import Any, Callable

import viser

from flowmc.errors import FlowmcError
from flowmc.graph import load
from flowmc.ui import arrange, camera, layout, viser_internals
from flowmc.ui.actions import Actions
from flowmc.ui.canvas import Canvas
from flowmc.ui.examples import OPEN_EVENT, ExamplesPanel
from flowmc.ui.extensions import Extensions
from flowmc.ui.files_panel import FilesPanel
from flowmc.ui.guard import Guard, is_loopback
from flowmc.ui.inspector import Inspector
from flowmc.ui.interface_panel import InterfacePanel
from flowmc.ui.job_panel import JobPanel
from flowmc.ui.minimap import Minimap
from flowmc.ui.panels import PalettePanel, ProblemsPanel
from flowmc.ui.selection_panel import SelectionPanel
from flowmc.ui.session import DeviceAccess, EditorSession, JobAccess, RunRefused, RunRequest
from flowmc.ui.structure_panel import StructureUI
from flowmc.ui.sweep_panel import SweepPanel
from flowmc.ui.text import escape_md, md, plain

__all__ = ["Editor", "serve_main"]

MAX_TOASTS = 3
SETTLE_DELAY_S = 0.06
COMMANDS = (("Undo", "Z", "cmd/ctrl", "Undo"), ("Redo", "Z", "cmd/ctrl+shift", "Redo"),
            ("Delete selection", "delete", None, "Delete"), ("Fit to view", "F", None, "Fit"),
            ("Save", "S", "cmd/ctrl", "Save"), ("Run", "enter", "cmd/ctrl", "Run"),
            ("Copy", "C", "cmd/ctrl", "Copy"), ("Cut", "X", "cmd/ctrl", "Cut"), ("Duplicate", "D", "cmd/ctrl", "Duplicate"),
            ("Select all", "A", "cmd/ctrl", "Select all"), ("Auto-layout", "L", "shift", "Layout"),
            ("Add a comment", "C", "shift", "Comment"), ("Add a label", "T", "shift", "Label"))
NETWORK_WARNING = ("warning: the editor is listening on {host}: anyone who can reach this machine on the network "
                   "can open it, edit graphs and run the machine (motion, outputs, spindle). Use only on a trusted network.")


class Editor:
    """The whole editor on one viser server, over an ``EditorSession`` (``session``). It is the
    ``PanelHost`` its panels get. ``devices`` / ``jobs``: the device session and job runner the
    application hands in (None: the Device tab says there is none)."""

    def __init__(self, path: str | Path | None = None, *, host: str = "127.0.0.1", port: int = 8080,
                 folder: str | Path | None = None, extensions: bool = True, devices: DeviceAccess | None = None,
                 jobs: JobAccess | None = None, guard: Guard | None = None):
        graph = load(path) if path is not None else None
        self.session = EditorSession(graph, folder=folder, devices=devices, jobs=jobs)
        self.lock, self.state = self.session.lock, self.session.state
        self.session.state.plan()  # bind the graph once before the panels look at node types
        self.host = host
        self.guard = guard or Guard(host)  # this launch's token; only the editor's own page may connect
        self.messages: list[tuple[str, str]] = []
        self.pending_modal: Any = None
        self._titles: dict[int, str] = {}
        self._toasts: dict[int, list[Any]] = {}
        self._settles = 0
        self._settle_timer: threading.Timer | None = None
        self._page_handlers: dict[str, Callable[[Any, Any], object]] = {}
        self.server = viser_internals.guarded_server(self.guard, host=host, port=port, label="flowmc", verbose=False)
        self.gui = self.server.gui
        self.server.gui.configure_theme(show_share_button=False, show_logo=False, control_width="medium")
        self.server.gui.main_panel.dock_right()
        self.canvas = Canvas(self.server, self.state, self.notify, self.lock, status=self.session.status)
        self.actions = Actions(self)
        self._build_gui()
        self.minimap = Minimap(self)
        self.extensions = Extensions(self) if extensions else None
        if self.extensions is not None and self.extensions.view is not None:
            self.job_panel.attach_view(self.extensions.view)
        self.sweep_panel: SweepPanel | None = None
        if extensions:
            with self.tab_group.add_tab("Sweep"):
                self.sweep_panel = SweepPanel(self)
        self.session.on_progress(self.canvas.sync)
        self.session.on_result(self._run_finished)
        self.state.subscribe(self._on_state)
        self.server.on_client_connect(self._on_connect)
        self.structure_ui = StructureUI(self)  # after the editor's own listeners: the canvas is drawn first
        self.canvas.geometry()
        self.canvas.fit()  # where the first page starts: its zoom decides whether the first drawing has details
        self.canvas.sync()
        self._refresh_side()

    @property
    def last_result(self) -> Any:
        return self.session.last_result

    @property
    def url(self) -> str:
        """The address to open, with this launch's secret token (without it the server refuses)."""
        host = "127.0.0.1" if self.host in ("0.0.0.0", "", "::") else self.host
        return self.guard.url(host, self.server.get_port())

    # ------------------------------------------------------------------ layout
    def _build_gui(self) -> None:
        gui = self.server.gui
        self.channel = gui.add_text(viser_internals.CHANNEL_LABEL, "")  # the page script hides its row
        self.channel.on_update(self._page_event)
        self.header = gui.add_markdown("")
        self.run_button = gui.add_button("Run", color="green", icon=viser.Icon.PLAYER_PLAY, hint="Validate, then run the graph")
        self.edit_ops = gui.add_button_group("Edit", ("Undo", "Redo", "Delete"))
        self.clip_ops = gui.add_button_group("Clipboard", ("Copy", "Cut", "Paste"))
        self.canvas_ops = gui.add_button_group("Canvas", ("Fit", "Layout"))
        self.note_ops = gui.add_button_group("Add", ("Comment", "Label"))
        self.status_line = gui.add_markdown("")
        self.job_panel = JobPanel(self)  # Start, Hold, Stop, E-stop and the DRO: always in sight, above the tabs
        group = gui.add_tab_group()
        self.tabs = {key: group.add_tab(label) for key, label in
                     (("node", "Node"), ("problems", "Problems"), ("files", "Files"))}
        with self.tabs["node"]:
            self.selection = SelectionPanel(self)
            self.interface = InterfacePanel(self)
        self.inspector = Inspector(gui, self.tabs["node"], self.state, self.lock, on_structure=self.canvas.sync)
        with self.tabs["files"]:
            self.files = FilesPanel(self)
            self.dark = gui.add_checkbox("Dark theme", False, hint="Dark page and canvas")
        with self.tabs["problems"]:
            self.problems = ProblemsPanel(self)
        self.tab_group = group
        self.palette_panel = gui.add_panel()
        self.palette = PalettePanel(self, self.palette_panel.add_tab("Nodes", viser.Icon.LAYOUT_GRID_ADD))
        with self.palette_panel.add_tab("Examples", viser.Icon.BOOK):
            self.examples = ExamplesPanel(self)
        self.palette_panel.dock_above(gui.main_panel)  # the right column: palette on top, the side panel below
        self.run_button.on_click(lambda _e: self.run())
        for ops in (self.edit_ops, self.clip_ops, self.canvas_ops, self.note_ops):
            ops.on_click(lambda e: self.edit(e.target.value))
        self.dark.on_update(lambda _e: self.set_theme("dark" if self.dark.value else "light"))
        for label, key, mod, action in COMMANDS:
            command = gui.add_command(label, hotkey=key, modifier=mod)
            command.on_trigger(lambda _e, a=action: self.edit(a))
        self.on_page_event("paste", lambda _client, data: self.actions.paste_text(data if isinstance(data, str) else None))
        self.on_page_event("palette-add", lambda _client, data: self.palette.picked(data.get("key"))
                           if isinstance(data, dict) else None)
        self.on_page_event("palette-drop", self._palette_drop)
        self.on_page_event("view", camera.resized)  # the page's size in CSS pixels: framing and legibility use it
        self.on_page_event(OPEN_EVENT, lambda client, data: self.examples.picked(data.get("key"), client)
                           if isinstance(data, dict) else None)
        self.on_page_event("grid", lambda _client, data: self.inspector.grid_event(data.get("grid"), data)
                           if isinstance(data, dict) else None)

    def set_theme(self, name: str) -> None:
        """Light or dark: the page (viser's theme) and the canvas."""
        self.gui.configure_theme(show_share_button=False, show_logo=False, control_width="medium", dark_mode=name == "dark")
        with self.lock:
            self.canvas.set_theme(name)

    def _palette_drop(self, client: Any, data: Any) -> None:
        """A palette entry dragged onto the canvas: ``data`` is its key and where it was let go (0..1 of the view)."""
        try:
            key, u, v = data["key"], float(data["u"]), float(data["v"])
        except (TypeError, KeyError, ValueError):
            return
        if not (0.0 <= u <= 1.0 and 0.0 <= v <= 1.0):
            return
        at = layout.to_canvas(*camera.world_at(client.camera, u, v))
        self.palette.picked(key, at)

    def _on_connect(self, client: viser.ClientHandle) -> None:
        viser_internals.install_page(client, self.channel)
        self.canvas.setup_client(client)
        client.camera.on_update(lambda _cam: self.minimap.refresh(force=False))
        self._titles.pop(client.client_id, None)
        self._refresh_title([client])
        clients = list(self.server.get_clients().values())
        if len(clients) > 1:  # one document for every tab: say so rather than let edits surprise
            for target in clients:
                target.add_notification("Shared editor", plain(f"{len(clients)} browser tabs are open on this editor: "
                                        "they edit the same graph, and share one undo history"),
                                        color="yellow", auto_close_seconds=10.0)

    def on_page_event(self, kind: str, handler: Callable[[Any, Any], object]) -> None:
        """Call ``handler(client, data)`` for page events of ``kind`` (``window.flowmc.send(kind, data)``)."""
        self._page_handlers[kind] = handler

    def _page_event(self, event: Any) -> None:
        """One event from the page script. The page is not trusted: malformed events are dropped."""
        try:
            message = json.loads(event.target.value)
            kind, data = message["kind"], message.get("data")
        except (ValueError, TypeError, KeyError):
            return
        handler = self._page_handlers.get(kind) if isinstance(kind, str) else None
        if handler is not None:
            handler(event.client, data)

    # ------------------------------------------------------------------ messages and refreshes
    def notify(self, kind: str, text: str, client: viser.ClientHandle | None = None) -> None:
        """Tell the user: the line under the Run button, and a notification in the browser."""
        self.messages.append((kind, text))
        del self.messages[:-200]
        self.status_line.content = ("⚠ " if kind == "error" else "") + escape_md(text)
        title = "Problem" if kind == "error" else "flowmc"
        for target in [client] if client is not None else list(self.server.get_clients().values()):
            shown = self._toasts.setdefault(target.client_id, [])
            while len(shown) >= MAX_TOASTS:  # the oldest goes: a burst of messages never stacks up
                with contextlib.suppress(Exception):
                    shown.pop(0).remove()
            shown.append(target.add_notification(title, plain(text), color="red" if kind == "error" else "blue",
                                                  auto_close_seconds=8.0 if kind == "error" else 3.0))

    def _on_state(self, kind: str) -> None:
        with self.lock:
            if kind == "selection":  # the fast path: say what is selected, recolour, then build its form
                with self.server.atomic():
                    self.selection.show()
                self.server.flush()
                self.canvas.sync_selection()
                self._settle_soon()
                if self.extensions is not None:
                    self.extensions.selection_changed()
                return
            if kind in ("graph", "document"):
                self.canvas.status.clear()
            if kind == "document":  # framed before it is drawn: zoomed out to fit, its port names are never made
                self.canvas.geometry()
                self.canvas.fit()
            self.canvas.sync()
            self.minimap.refresh()
            if kind == "move":
                self._refresh_title()
                return
            if kind == "document":
                self.files.refresh()
                self.palette.refresh()
            self.settle()
        if self.extensions is not None and kind in ("graph", "document"):
            self.extensions.graph_changed(kind)

    def _settle_soon(self) -> None:
        """The form of a new selection, a moment after its summary and frame went out, so that the page draws
        those first (a browser page shows them about 100 ms sooner); at once when no page is open."""
        self._settles += 1
        if not self.server.get_clients():
            self.settle()
            return
        ticket = self._settles
        timer = self._settle_timer = threading.Timer(SETTLE_DELAY_S, lambda: self.settle() if ticket == self._settles else None)
        timer.daemon = True
        timer.start()

    def settle(self) -> None:
        """Bring the inspector and the side panel up to date with the document."""
        with self.lock:
            with self.server.atomic():  # the page applies the side-panel changes in one go
                if not self.inspector.editing:
                    self.inspector.show()
                self._refresh_side()
            self.server.flush()

    def _refresh_side(self) -> None:
        self.selection.show()
        self.interface.show()
        self.problems.show(self.state.issues(), self.session.run_errors())
        self._refresh_title()

    def files_changed(self) -> None:
        """Graph files appeared or changed on disk (a new sub-graph): list them again."""
        with self.lock:
            self.palette.refresh()
            self.files.refresh()

    def _refresh_title(self, clients: list[viser.ClientHandle] | None = None) -> None:
        state = self.state
        name = state.path.name if state.path is not None else state.suggested_name + " (not saved)"
        if state.body_place is not None:
            name = f"{state.body_place[0]} · body {state.body_place[1]}"
        mark = " ●" if state.dirty else ""
        opened_from = " ← ".join(reversed(state.parents))
        self.header.content = md("### {}{}", name, mark) + (md("\nopened from {}", opened_from) if opened_from else "")
        title = plain(f"{'● ' if mark else ''}{name} — flowmc", 200)
        for client in clients if clients is not None else list(self.server.get_clients().values()):
            if self._titles.get(client.client_id) != title:
                self._titles[client.client_id] = title
                viser_internals.set_page_title(client, title)

    # ------------------------------------------------------------------ actions
    def edit(self, action: str) -> None:
        """An edit command by name (the buttons' labels and the hotkeys' actions)."""
        simple: dict[str, Callable[[], object]] = {
            "Fit": self.canvas.fit, "Save": self.files.save, "Run": self.run, "Copy": self.actions.copy,
            "Cut": lambda: self.actions.copy(cut=True), "Paste": lambda: self.actions.paste_text(None),
            "Duplicate": self.actions.duplicate, "Select all": self.actions.select_all,
            "Layout": self.actions.auto_layout, "Comment": lambda: self.actions.add_note("comment"),
            "Label": lambda: self.actions.add_note("label")}
        with self.lock:
            if action == "Undo" and not self.state.undo():
                self.notify("info", "nothing to undo")
            elif action == "Redo" and not self.state.redo():
                self.notify("info", "nothing to redo")
            elif action == "Delete" and not self.state.delete_selection():
                self.notify("info", "nothing selected to delete")
            elif action in simple:
                simple[action]()
            elif action.startswith("Align:"):
                self.actions.align(action.partition(":")[2])

    def select_node(self, node_id: str) -> None:
        with self.lock:
            if self.state.has_node(node_id):
                self.state.select(nodes=[node_id])

    def add_node(self, type_id: str, params: dict[str, Any], at: tuple[float, float] | None = None) -> str:
        """Add a node with its centre at the free spot nearest ``at`` (canvas pixels; default the middle of the
        view), overlapping no node, terminal or note, and select it."""
        with self.lock:
            centre = at if at is not None else self.canvas.view_centre()
            node_id = self.state.add_node(type_id, centre, params)
            self.place_free(node_id, centre)
            self.state.select(nodes=[node_id])
            return node_id

    def place_free(self, node_id: str, near: tuple[float, float] | None = None) -> None:
        """Move a node (in the current undo step) to the free spot nearest ``near`` (canvas pixels; default
        its own centre), where it overlaps no node, terminal or note."""
        with self.lock:
            box = self.canvas.by_id.get(node_id)
            size = (box.w / layout.SCALE, box.h / layout.SCALE) if box is not None else (200.0, 120.0)
            if near is None:
                pos = self.state.node(node_id).pos
                near = (pos[0] + size[0] / 2, pos[1] + size[1] / 2)
            taken = [r for k, r in self.actions.rects().items() if k != node_id]
            self.state.move_nodes({node_id: arrange.free_spot(taken, size, near)}, record=False)

    def confirm(self, title: str, text: str, button: str, action: Callable[[], object], client: Any = None) -> Any:
        """A dialog with ``button`` (does ``action`` under the lock) and "Keep editing"; returns the modal."""
        gui = client.gui if client is not None else self.gui
        with gui.add_modal(title) as modal:
            gui.add_markdown(text)
            go_button = gui.add_button(button, color="red")
            keep = gui.add_button("Keep editing")
        self.pending_modal = (modal, go_button)

        def go(_e: Any) -> None:
            modal.close()
            with self.lock:
                action()

        go_button.on_click(go)
        keep.on_click(lambda _e: modal.close())
        return modal

    def download(self, name: str, text: str, client: Any = None) -> None:
        for target in [client] if client is not None else list(self.server.get_clients().values()):
            viser_internals.download(target, name, text)

    def run(self, inputs: dict[str, Any] | None = None, source: str = "run") -> RunRequest | None:
        """Queue a run through the session (the one way to run); None, with the problems shown, when the
        graph cannot run. ``inputs``: interface input values (default: the front panel's)."""
        with self.lock:
            request = self.session.run(inputs, source=source)
            if isinstance(request, RunRefused):
                self.problems.show(request.issues, {})
                self.notify("error", request.message)
                return None
            self.status_line.content = "running…" if source == "run" else md("running ({})…", source)
            return request

    def wait(self, timeout: float = 60.0) -> Any:
        """Wait for the runs going and waiting (tests, scripts); returns the last result."""
        return self.session.wait(timeout)

    def _run_finished(self, request: RunRequest) -> None:
        with self.lock:
            if request.error is not None:
                self.notify("error", f"the run did not start: {request.error}")
                return
            result = request.result
            errors = self.session.run_errors()
            self.problems.show(self.state.issues(), errors)
            if request.source != "run":
                self.status_line.content = md("{}: {}", request.source, "done" if result.ok else "a node failed")
            elif result.ok:
                self.notify("info", f"run done in {request.seconds:.2f} s: {len(result.executed)} ran, "
                                    f"{len(result.cached)} cached")
            else:
                first = next(iter(errors.values()), "a node failed")
                self.notify("error", f"run failed: {first}" + (f" (+{len(errors) - 1} more)" if len(errors) > 1 else ""))

    def export_gcode(self, client: viser.ClientHandle | None = None) -> Path | None:
        """Run the graph (cached) and write its Path output as ``<graph>.ngc`` in the folder, and offer it
        as a download. The path: the graph's Path interface output, else the selected node's, else the last.
        An existing file is replaced only after the user agrees (a dialog; None until then)."""
        from flowmc.ui.gcode_export import prepare_export

        try:
            export = prepare_export(self.session)
        except FlowmcError as exc:
            self.notify("error", f"G-code export: {exc}", client)
            return None
        if export.replaces:
            self.confirm("Replace the G-code file?", md("**{}** exists in the graph's folder. Replace it?",
                                                        export.target.name),
                         "Replace", lambda: self._write_export(export, client), client)
            return None
        return self._write_export(export, client)

    def _write_export(self, export: Any, client: viser.ClientHandle | None) -> Path | None:
        try:
            text = export.write()
        except FlowmcError as exc:
            self.notify("error", f"G-code export: {exc}", client)
            return None
        self.download(export.target.name, text, client)
        self.notify("info", f"wrote {export.target.name}", client)
        return export.target

    def close(self) -> None:
        """Stop the running job first (the machine comes to rest at once, not after the wait below), let the
        callbacks going end (a click still rebuilding the panels) and start no more, then stop the session (run
        queue, job runner, device session), the extensions, the timers and the server: work that outlived the
        server would queue messages for pages that are gone. A Start still being handled is stopped with the rest."""
        self.job_panel.stop()
        viser_internals.quiet(self.server)
        self.session.close()
        self.job_panel.close()
        if self.extensions is not None:
            self.extensions.close()
        if self.sweep_panel is not None:
            self.sweep_panel.close()
        self.minimap.close()
        if self._settle_timer is not None:
            self._settle_timer.cancel()
            self._settle_timer.join()
        self.server.stop()


def serve_main(args: Any, *, devices: DeviceAccess | None = None, jobs: JobAccess | None = None) -> int:
    """``flowmc serve [FILE] [--host] [--port]``: start the editor, print its URL, serve until Ctrl+C.
    The command line hands in the device session (and job runner) the editor shares with its panels."""
    host, port = getattr(args, "host", "127.0.0.1"), getattr(args, "port", 8080)
    file = getattr(args, "file", None)
    if not is_loopback(host):
        print(NETWORK_WARNING.format(host=host), file=sys.stderr)
    editor = Editor(file, host=host, port=port, folder=None if file else Path.cwd(), devices=devices, jobs=jobs)
    print(f"flowmc editor: {editor.url}" + (f"  ({file})" if file else ""), flush=True)
    if not is_loopback(host):
        name = socket.gethostname() if host in ("0.0.0.0", "::", "") else host
        print(f"  from other machines: {editor.guard.url(name, editor.server.get_port())}", flush=True)
    try:
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        pass
    finally:
        editor.close()
    return 0
