"""The Interface folder of the Node tab: the graph's inputs and outputs as a sub-graph, added and
removed here and wired on the canvas, where they are drawn as terminals (inputs on the left, outputs
on the right). An input is added with a name and a type, then wired from its terminal to node
inputs; an output is added with a name and the node output it gives."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from flowmc.errors import FlowmcError
from flowmc.ports import PORT_TYPES
from flowmc.ui.text import md, plain

if TYPE_CHECKING:
    from flowmc.ui.session import PanelHost

__all__ = ["InterfacePanel"]


class InterfacePanel:
    def __init__(self, host: "PanelHost"):
        self.host = host
        self.state = host.session.state
        gui = host.gui
        self.folder = gui.add_folder("Interface", order=20.0, expand_by_default=False)
        with self.folder:
            self.summary = gui.add_markdown("")
            self.in_name = gui.add_text("Input name", "", hint="Letters, digits and _ (e.g. feed)")
            self.in_type = gui.add_dropdown("Input type", PORT_TYPES, initial_value="Number")
            self.add_in = gui.add_button("Add input", hint="Then wire its terminal (left of the nodes) to node inputs")
            self.out_name = gui.add_text("Output name", "")
            self.out_source = gui.add_dropdown("Output from", ("(no outputs)",))
            self.add_out = gui.add_button("Add output", hint="The graph gives this node output as a sub-graph")
        self.add_in.on_click(lambda e: self.add("in", e.client))
        self.add_out.on_click(lambda e: self.add("out", e.client))

    def show(self) -> None:
        """List the interface and offer every node output as an output's source."""
        iface = self.state.graph.interface
        ins = [f"{i.name} ({i.type})" for i in iface.inputs] if iface else []
        outs = [f"{o.name} ({o.type})" for o in iface.outputs] if iface else []
        self.summary.content = (md("Inputs: {}  \nOutputs: {}", ", ".join(ins) or "none", ", ".join(outs) or "none")
                                + "  \nSelect a terminal and press Delete to remove it.")
        plan = self.state.plan()
        sources = tuple(f"{n}.{name}" for n in plan.order if n in plan.nodes for name in plan.ports(n)[1])
        options = tuple(plain(s, 200) for s in sources) or ("(no outputs)",)
        if tuple(self.out_source.options) != options:
            self.out_source.options = options

    def add(self, kind: str, client: Any = None) -> str | None:
        name = (self.in_name if kind == "in" else self.out_name).value.strip()
        with self.host.session.lock:
            try:
                key = (self.state.add_terminal("in", name, self.in_type.value) if kind == "in"
                       else self.state.add_terminal("out", name, source=self.out_source.value))
            except FlowmcError as exc:
                self.host.notify("error", str(exc), client)
                return None
            self.state.select(nodes=[key])
        self.host.edit("Fit")  # the new terminal in view
        self.host.notify("info", f"interface {'input' if kind == 'in' else 'output'} {name} added: "
                                 + ("wire its terminal to the inputs it feeds" if kind == "in" else "it is wired"))
        return key
