"""Hook points for the panels built beside the editor: the 3D toolpath view (``view3d``: a second viser
server, shown in a panel docked left), the front panel and the device panel (tabs of the side panel).

Each is optional: a module that is missing or fails to start is reported in its place and the
editor works on without it. The editor calls:
- ``show_result(result)`` after every run (a run listener): the 3D view shows what it produced;
- ``graph_changed(kind)`` after edits: the front panel is rebuilt when the graph's interface changed;
- ``inputs()`` before a Run: the front panel's values are the interface inputs.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from flowmc.errors import FlowmcError
from flowmc.ui.text import md

if TYPE_CHECKING:
    from flowmc.ui.app import Editor

__all__ = ["Extensions"]

VIEW_WIDTH = 600
VIEW_HEIGHT = 640


class Extensions:
    def __init__(self, editor: "Editor"):
        self.editor = editor
        self.view: Any = None
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

    def _failed(self, what: str, exc: BaseException, container: Any = None) -> None:
        text = f"{type(exc).__name__}: {exc}"
        self.failures[what] = text
        if container is not None:
            with container:
                self.editor.server.gui.add_markdown(md("The {} is not available: {}", what, text))

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
            self.view_html = gui.add_html(embed_html(self.view.url, height=VIEW_HEIGHT))
        self.view_panel.dock_left()
        self.view_panel.set_width(VIEW_WIDTH)
        self.editor.run_listeners.append(self.show_result)

    def show_result(self, result: Any) -> None:
        if self.view is not None and result is not None:
            self.view.show_result(result, self.editor.state.graph)

    def _show_log(self, log: Any) -> None:
        """A device operation's log in the 3D view, with what the last run produced."""
        if self.view is None:
            return
        from flowmc.ui import view3d_data

        shown = view3d_data.collect(self.editor.last_result, self.editor.state.graph) if self.editor.last_result else None
        self.view.show(shown.paths if shown else (), shown.trajectories if shown else (), shown.machine if shown else None,
                       [*(shown.logs if shown else ()), log])

    # ------------------------------------------------------------------ front panel
    def _interface_key(self) -> str:
        iface = self.editor.state.graph.interface
        return iface.model_dump_json() if iface is not None else ""

    def _start_front(self, gui: Any) -> None:
        try:
            from flowmc.ui.front_panel import FrontPanel, rerun_callback

            state = self.editor.state
            rerun = rerun_callback(self.editor.runtime, lambda: state.graph, self.view, on_result=self._front_result)
            with self.front_tab:
                self.front = FrontPanel(gui, state.graph, rerun)
        except Exception as exc:  # noqa: BLE001 - the editor runs without a front panel
            self._failed("front panel", exc, self.front_tab)

    def _front_result(self, result: Any) -> None:
        with self.editor.lock:
            self.editor.last_result = result
            self.editor.problems.show(self.editor.state.issues(), self.editor._run_errors())

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
        if self.editor.last_result is None:
            return None
        from flowmc.ui import view3d_data

        return view3d_data.collect(self.editor.last_result, self.editor.state.graph).machine

    def _start_device(self, gui: Any) -> None:
        try:
            from flowmc.ui.device_panel import DevicePanel

            with self.device_tab:
                self.device = DevicePanel(gui, self._machine, on_log=self._show_log)
        except Exception as exc:  # noqa: BLE001 - the editor runs without a device panel
            self._failed("device panel", exc, self.device_tab)

    def close(self) -> None:
        for part in (self.device, self.view):
            if part is not None:
                try:
                    part.close()
                except Exception:  # noqa: BLE001 - closing is best effort
                    pass
