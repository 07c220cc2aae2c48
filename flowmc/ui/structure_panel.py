"""The editor's structure, probe and indicator controls, beside the editor's core (one hook in app.py).

- **Structure** (a folder in the Node tab): make a For loop, While loop or Case from the selected nodes;
  for a selected structure, open its body (a case: pick the case), add a case, make a body output a
  shift register or collect it every iteration, put a For loop's N on the front panel; inside a body,
  switch to another case and go back to the graph that holds it.
- **Probes** (a tab): probe the selected wire; after each run every probe shows its wire's value (a
  number, a table's first rows, a path's size with an XY plot, a trajectory's cycle time and speed
  plot, a log's summary), and the canvas shows it beside the wire. Probes are saved as view state.
- **Indicators** (on the front panel): the graph's outputs after each run, numbers with units, tables
  and charts.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Callable

from flowmc.errors import FlowmcError
from flowmc.graph import Graph, split_ref
from flowmc.ui import layout, structures, value_view
from flowmc.ui.layout import terminal_of
from flowmc.ui.text import md

if TYPE_CHECKING:
    from flowmc.ui.app import Editor

__all__ = ["StructureUI", "MAKE"]

#: The "Make structure" buttons and the node types they make.
MAKE = {"Into a For loop": "struct.for", "Into a While loop": "struct.while", "Into a Case": "struct.case"}
_PROBE_FONT = 10.0  # canvas pixels, as the status line under a node


def _quietly(action: Callable[[], Any]) -> Callable[[Any], None]:
    """A GUI callback running ``action`` (what it returns is for tests, not for viser)."""
    def callback(_event: Any) -> None:
        action()
    return callback


class StructureUI:
    def __init__(self, editor: "Editor"):
        self.editor, self.session, self.state = editor, editor.session, editor.session.state
        gui = self.gui = editor.server.gui
        with editor.tabs["node"]:
            self.folder: Any = gui.add_folder("Structure", order=1.2)
        with self.folder:
            self.info: Any = gui.add_markdown("")
            self.make: Any = gui.add_button_group("Make structure", tuple(MAKE),
                                             hint="Put the selected nodes into a new loop or case; wires crossing "
                                                  "the selection become the body's interface")
            self.open_body: Any = gui.add_button("Open body", hint="Edit the loop's body (Back returns)")
            self.case: Any = gui.add_dropdown("Case", ("",), hint="The case to open")
            self.open_case: Any = gui.add_button("Open case", hint="Edit this case's body (Back returns)")
            self.new_case: Any = gui.add_text("New case label", "", hint="e.g. 2, 3..5, or a text; a copy of the case "
                                                                    "picked above")
            self.add_case: Any = gui.add_button("Add case")
            self.output: Any = gui.add_dropdown("Body output", ("",), hint="A loop body's output")
            self.shift: Any = gui.add_button("Make shift register", hint="Its value enters the next iteration (wire "
                                                                    "the new body input inside the body)")
            self.collect: Any = gui.add_checkbox("Collect every iteration", False, hint="Auto-indexing: paths joined, "
                                                                                   "numbers into a table")
            self.count: Any = gui.add_button("N on the front panel", hint="A front-panel control for the loop's count")
            self.switch: Any = gui.add_dropdown("Switch case", ("",), hint="Edit another case of this structure")
            self.back: Any = gui.add_button("Back to the graph", hint="Put the body back into its structure")
        self.probe_tab: Any = editor.tab_group.add_tab("Probes")
        with self.probe_tab:
            self.probe_mode: Any = gui.add_checkbox("Click wires to probe them", False,
                                                    hint="While on, a click on a wire adds its probe (or removes it)")
            self.probe_button: Any = gui.add_button("Probe the selected wire", hint="Select a wire on the canvas first")
            self.probe_list: Any = gui.add_markdown("")
            self.probe_folder: Any = gui.add_folder("Probe values", expand_by_default=True)
        self.indicators_folder: Any = None
        front = getattr(editor.extensions, "front_tab", None) if editor.extensions is not None else None
        if front is not None:
            with front:
                self.indicators_folder = gui.add_folder("Indicators", expand_by_default=True)
        self._shown: list[Any] = []
        self._indicators: list[Any] = []
        self._quiet = False  # True while show() sets controls (their updates are not edits)
        self.make.on_click(lambda e: _quietly(lambda: self.make_structure(MAKE[e.target.value]))(e))
        self.open_body.on_click(_quietly(lambda: self.open("body")))
        self.open_case.on_click(_quietly(lambda: self.open(self.case.value)))
        self.add_case.on_click(_quietly(self.new_case_from_panel))
        self.shift.on_click(_quietly(lambda: self._edit(
            lambda g, n: structures.add_shift_register(g, n, self.output.value))))
        self.collect.on_update(_quietly(self._collect))
        self.count.on_click(_quietly(self.count_on_front_panel))
        self.switch.on_update(_quietly(self._switch))
        self.back.on_click(_quietly(self.go_back))
        self.probe_button.on_click(_quietly(self.toggle_probe))
        editor.canvas.decorations.append(self._probe_labels)
        self.state.subscribe(self._state_changed)
        self.session.on_result(lambda _request: self.show_values())
        self.session.on_progress(self._progress)
        self.show()

    def _state_changed(self, kind: str) -> None:
        if kind == "move":
            return
        if kind == "selection" and self.probe_mode.value and self._selected_probe() is not None \
                and not self.state.selected_nodes:
            self.toggle_probe()  # probe mode: a click on a wire probes it
        self.show()

    # ------------------------------------------------------------------ what is selected
    def _one_structure(self) -> str | None:
        nodes = self.state.selected_nodes
        if len(nodes) == 1 and self.state.has_node(nodes[0]) and self.state.node(nodes[0]).type in structures.STRUCTURES:
            return nodes[0]
        return None

    def show(self) -> None:
        state = self.state
        chosen = self._one_structure()
        node: Any = state.node(chosen) if chosen else None
        real = [n for n in state.selected_nodes if terminal_of(n) is None and state.has_node(n)]
        place = state.body_place
        self._quiet = True
        try:
            self.make.visible = bool(real) and node is None
            is_case, is_loop = node is not None and node.type == "struct.case", node is not None and not (
                node.type == "struct.case")
            self.info.content = self._info(chosen, place)
            self.open_body.visible = is_loop
            self.case.visible = self.open_case.visible = self.new_case.visible = self.add_case.visible = is_case
            if is_case:
                labels = tuple(node.bodies)
                self.case.options = labels
                if self.case.value not in labels:
                    self.case.value = labels[0]
            outputs = [name for name, _t in structures.body_outputs(state.graph, chosen)] if chosen and is_loop else []
            self.output.visible = self.shift.visible = self.collect.visible = bool(outputs)
            if outputs:
                self.output.options = tuple(outputs)
                if self.output.value not in outputs:
                    self.output.value = outputs[0]
                self.collect.value = self.output.value in node.params.get("indexed", [])
            self.count.visible = node is not None and node.type == "struct.for"
            self.back.visible = place is not None
            cases = self._sibling_cases()
            self.switch.visible = len(cases) > 1
            if cases and place is not None:
                self.switch.options = cases
                self.switch.value = place[1]
            probed = self._selected_probe()
            self.probe_button.label = "Remove the probe" if probed in state.graph.view.probes else \
                "Probe the selected wire"
            self.probe_button.disabled = probed is None
            self.probe_list.content = md("Probes: {}", ", ".join(state.graph.view.probes)) if state.graph.view.probes \
                else "No probes. Select a wire on the canvas, then probe it: its value shows here after each run."
        finally:
            self._quiet = False

    def _info(self, chosen: str | None, place: tuple[str, str] | None) -> str:
        if chosen is None:
            return md("Editing the body **{}** of node **{}**", place[1], place[0]) if place else \
                "Select nodes to make a loop or case of them."
        text = md("**{}**: {}", chosen, structures.caption(self.state.graph, chosen))
        status = self.session.status.get(chosen)
        if status is not None and status[2] and status[2].startswith("iteration"):  # the run going, or the last
            text += md("\n\n{}: {}", "running" if status[0] == "running" else "last run", status[2])
        return text

    def _progress(self) -> None:
        chosen = self._one_structure()
        if chosen is not None:
            self.info.content = self._info(chosen, self.state.body_place)

    def _sibling_cases(self) -> tuple[str, ...]:
        place, waiting = self.state.body_place, self.state.waiting
        if place is None or not waiting:
            return ()
        holder = waiting[-1].node(place[0])
        return tuple(holder.bodies) if holder.type == "struct.case" else ()

    # ------------------------------------------------------------------ structure edits
    def _notify_error(self, exc: FlowmcError) -> None:
        self.editor.notify("error", str(exc))

    def make_structure(self, type_id: str) -> str | None:
        with self.session.lock:
            try:
                new_id = self.state.make_structure(self.state.selected_nodes, type_id)
            except FlowmcError as exc:
                self._notify_error(exc)
                return None
        self.editor.notify("info", f"made {new_id}: open its body to edit it")
        return new_id

    def _edit(self, edit: Callable[[Graph, str], Any]) -> bool:
        node_id = self._one_structure()
        if node_id is None:
            return False
        with self.session.lock:
            try:
                self.state.change(lambda graph: edit(graph, node_id))
            except FlowmcError as exc:
                self._notify_error(exc)
                return False
        return True

    def _collect(self) -> None:
        if not self._quiet:
            on, name = bool(self.collect.value), self.output.value
            self._edit(lambda g, n: structures.set_collected(g, n, name, on))

    def count_on_front_panel(self) -> str | None:
        names: list[str] = []
        if self._edit(lambda g, n: names.append(structures.expose_count(g, n))):
            self.editor.notify("info", f"{names[0]} is on the front panel")
            return names[0]
        return None

    def new_case_from_panel(self) -> bool:
        label, like = self.new_case.value, self.case.value
        done = self._edit(lambda g, n: structures.add_case(g, n, label, like))
        if done:
            self.new_case.value = ""
        return done

    def open(self, name: str) -> bool:
        node_id = self._one_structure()
        if node_id is None:
            return False
        with self.session.lock:
            try:
                self.state.enter_body(node_id, name)
            except FlowmcError as exc:
                self._notify_error(exc)
                return False
        self.editor.canvas.fit()
        return True

    def go_back(self) -> bool:
        with self.session.lock:
            place = self.state.body_place
            if place is None:
                return False
            try:
                self.state.leave()
            except FlowmcError as exc:
                self._notify_error(exc)
                return False
            self.state.select(nodes=[place[0]])
        self.editor.canvas.fit()
        return True

    def _switch(self) -> None:
        place = self.state.body_place
        target = self.switch.value
        if self._quiet or place is None or target == place[1]:
            return
        if self.go_back():
            self.open(target)

    # ------------------------------------------------------------------ probes
    def _selected_probe(self) -> str | None:
        wires = self.state.selected_wires
        if len(wires) != 1:
            return None
        source = wires[0][0]
        return source if self.state.has_node(split_ref(source)[0]) else None  # not an interface terminal

    def toggle_probe(self) -> bool:
        """Probe the selected wire (its source output), or remove its probe. Returns whether it is probed."""
        source = self._selected_probe()
        if source is None:
            self.editor.notify("error", "select one wire between two nodes to probe it")
            return False
        on = source not in self.state.graph.view.probes

        def edit(graph: Graph) -> None:
            graph.view.probes = [p for p in graph.view.probes if p != source] + ([source] if on else [])

        with self.session.lock:
            self.state.change(edit)
        self.show_values()
        return on

    def probe_value(self, source: str) -> Any:
        result = self.session.last_result
        node_id, port = split_ref(source)
        node = result.nodes.get(node_id) if result is not None else None
        return None if node is None or not node.outputs else node.outputs.get(port)

    def _probe_labels(self, canvas: Any) -> dict[str, tuple]:
        out: dict[str, tuple] = {}
        for source in self.state.graph.view.probes:
            curve = next((c for (a, _b), c in canvas.curves.items() if a == source and len(c)), None)
            if curve is None:
                continue
            x, y = curve[len(curve) // 2][:2]
            text = "probe: " + value_view.short(self.probe_value(source), value_view.unit_of(split_ref(source)[1]))
            out[f"probe/{source.replace('.', '_')}"] = (text, (float(x), float(y) + 0.12), _PROBE_FONT * layout.SCALE,
                                                         "bottom-center", False)
        return out

    # ------------------------------------------------------------------ after a run
    def show_values(self) -> None:
        """Probes and indicators from the last run (plots made again)."""
        with self.session.lock:
            probes = [(p, self.probe_value(p)) for p in self.state.graph.view.probes]
            result = self.session.last_result
            iface = self.state.graph.interface
            indicators = [(o.name, o.description, result.outputs.get(o.name) if result is not None else None)
                          for o in (iface.outputs if iface is not None else [])]
        self._fill(self.probe_folder, self._shown, [(p, "", v) for p, v in probes])
        if self.indicators_folder is not None:
            self._fill(self.indicators_folder, self._indicators, indicators)

    def _fill(self, folder: Any, handles: list[Any], items: list[tuple[str, str, Any]]) -> None:
        gui = self.gui
        for handle in handles:
            handle.remove()
        handles.clear()
        with folder:
            for name, description, value in items:
                unit = value_view.unit_of(split_ref(name)[1] if "." in name else name, description)
                handles.append(gui.add_markdown(md("**{}**{}", name, f" ({description})" if description else "")
                                                + "\n\n" + value_view.describe(value, unit)))
                svg = value_view.chart(value)
                if svg is not None:
                    handles.append(gui.add_html(svg))
