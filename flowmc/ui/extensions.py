"""The panels built beside the editor's core: the 3D toolpath view (``view3d``: a second viser server,
shown in a panel docked left), the front panel and the device panel (tabs of the side panel).

Each is optional: a module that is missing or fails to start is reported in its place and the
editor works on without it. They plug into the editor's session, not into the editor:
- the 3D view and the front panel hear every run's result (``session.on_result``);
- a front-panel change queues a run (``host.run(values, source="front panel")``), and the
  session asks the front panel for the interface inputs of every other run (``inputs_provider``);
- the device panel drives the session's device session (``session.devices``).
``graph_changed(kind)`` after edits rebuilds the front panel when the graph's interface changed.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from flowmc.errors import FlowmcError
from flowmc.runtime.views import views
from flowmc.ui import view3d_data
from flowmc.ui.session import RunRequest
from flowmc.ui.text import md

if TYPE_CHECKING:
    from flowmc.ui.app import Editor

__all__ = ["Extensions"]

VIEW_WIDTH = 460


class Extensions:
    def __init__(self, editor: "Editor"):
        self.editor = editor
        self.session = editor.session
        self.view: Any = None
        self.view_open = False
        self.last: tuple[Any, Any] | None = None  # the last run's (result, plan)
        self.view_key = ""  # the 3D View node shown
        self.front: Any = None
        self.device: Any = None
        self.failures: dict[str, str] = {}
        gui = editor.server.gui
        self.front_tab = editor.tab_group.add_tab("Front panel")
        self.device_tab = editor.tab_group.add_tab("Device")
        self._interface = self._interface_key()
        self._start_view(gui)
        self._start_front(gui)
        self._start_device(gui)
        self.session.inputs_provider = self.inputs
        self._unsubscribe = self.session.on_result(self._on_result)

    def _failed(self, what: str, exc: BaseException, container: Any = None) -> None:
        text = f"{type(exc).__name__}: {exc}"
        self.failures[what] = text
        if container is not None:
            with container:
                self.editor.server.gui.add_markdown(md("The {} is not available: {}", what, text))

    def _on_result(self, request: RunRequest) -> None:
        if self.front is not None and request.source == "front panel":
            result = request.result
            if result is None:
                self.front.show_result(False, request.error or "it did not run")
            else:
                self.front.show_result(result.ok, "; ".join(result.errors))
        if self.view is not None and request.result is not None:
            self.last = (request.result, request.plan)
            self.show_view()

    def show_view(self) -> None:
        """Show the selected 3D View node (or the one shown before, or the first), inside sub-graphs too; a
        graph with none shows the run's most downstream values, as before there were View nodes."""
        if self.view is None or self.last is None:
            return
        result, plan = self.last
        try:
            found = views(result, plan, self.session.runtime)
            if found:
                chosen = self._chosen(found)
                self.view_key = chosen.key
                self.view.show_view(chosen)
                something = not chosen.empty
            else:
                shown = self.view.show_result(result, plan.graph)
                something = bool(shown.paths or shown.trajectories or shown.logs)
        except Exception as exc:  # noqa: BLE001 - a view that cannot show a result must not break the editor
            self.editor.notify("error", f"could not show the result: {type(exc).__name__}: {exc}")
            return
        self._view_has(something)

    def _chosen(self, found: list[Any]) -> Any:
        """The view a selected node names (its id, or the id inside a sub-graph), else the last one, else the first."""
        for node_id in self.session.state.selected_nodes:
            match = next((v for v in found if v.key == node_id or v.key.endswith("/" + node_id)), None)
            if match is not None:
                return match
        return next((v for v in found if v.key == self.view_key), found[0])

    def selection_changed(self) -> None:
        """A 3D View node was selected: show it (when the last run reached it)."""
        if self.last is None or self.view is None:
            return
        selected = set(self.session.state.selected_nodes)
        keys = [v.key for v in views(*self.last, self.session.runtime)]
        if any(k.rpartition("/")[2] in selected for k in keys if k != self.view_key):
            self.show_view()

    def _view_has(self, something: bool) -> None:
        """Open the docked 3D view when it gets something to show; it starts collapsed, out of the canvas's way."""
        if something and not self.view_open:
            self.view_panel.expand()
        self.view_open = self.view_open or something

    # ------------------------------------------------------------------ 3D view
    def _start_view(self, gui: Any) -> None:
        try:
            from flowmc.ui.view3d import ToolpathView, embed_html

            self.view = ToolpathView(host=self.editor.host, port=0, guard=self.editor.guard)
        except Exception as exc:  # noqa: BLE001 - the editor runs without a 3D view
            self._failed("3D view", exc)
            return
        self.view_panel = gui.add_panel()
        with self.view_panel.add_tab("3D view"):
            self.view_html = gui.add_html(embed_html(self.view))
        self.view_panel.dock_left()
        self.view_panel.set_width(VIEW_WIDTH)
        self.view_panel.minimize()
        self.view_open = False

    def _show_log(self, log: Any) -> None:
        """A device operation's log in the 3D view, with what the last run produced."""
        if self.view is None:
            return
        result = self.session.last_result
        shown = view3d_data.collect(result, self.session.state.graph) if result is not None else None
        self.view.show(shown.paths if shown else (), shown.trajectories if shown else (), shown.machine if shown else None,
                       [*(shown.logs if shown else ()), log])
        self._view_has(True)

    # ------------------------------------------------------------------ front panel
    def _interface_key(self) -> str:
        iface = self.session.state.graph.interface
        return iface.model_dump_json() if iface is not None else ""

    def _start_front(self, gui: Any) -> None:
        try:
            from flowmc.ui.front_panel import FrontPanel

            with self.front_tab:
                self.front = FrontPanel(gui, self.session.state.graph,
                                        lambda values: self.editor.run(values, source="front panel"),
                                        self.session.runtime.registry)
        except Exception as exc:  # noqa: BLE001 - the editor runs without a front panel
            self._failed("front panel", exc, self.front_tab)

    def graph_changed(self, kind: str) -> None:
        key = self._interface_key()
        if kind == "document" or key != self._interface:
            self._interface = key
            if self.front is not None:
                self.front.remove()
                self.front = None
            self._start_front(self.editor.server.gui)

    def inputs(self) -> dict[str, Any]:
        try:
            return self.front.values() if self.front is not None else {}
        except (FlowmcError, ValueError):
            return {}

    # ------------------------------------------------------------------ device panel
    def _machine(self) -> Any:
        result = self.session.last_result
        if result is None:
            return None
        return view3d_data.collect(result, self.session.state.graph).machine

    def _start_device(self, gui: Any) -> None:
        devices = self.session.devices
        if devices is None:
            with self.device_tab:
                gui.add_markdown("No device session: start the editor with `flowmc serve` to drive a card here.")
            return
        try:
            from flowmc.ui.device_panel import DevicePanel

            with self.device_tab:
                self.device = DevicePanel(gui, devices, self._machine, on_log=self._show_log)
        except Exception as exc:  # noqa: BLE001 - the editor runs without a device panel
            self._failed("device panel", exc, self.device_tab)

    def close(self) -> None:
        self._unsubscribe()
        for part in (self.device, self.view):
            if part is not None:
                try:
                    part.close()
                except Exception:  # noqa: BLE001 - closing is best effort
                    pass
