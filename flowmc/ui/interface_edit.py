"""Editing a graph's interface (the ports it has as a sub-graph) the way the canvas shows it: input
terminals on the left feeding node inputs, output terminals on the right fed by node outputs.

On the canvas a terminal is a box with id ``@in:<name>`` or ``@out:<name>`` (``layout.terminal_id``);
its wires have those ids as their "from" (inputs) or "to" (outputs). These functions change the
``Graph`` in place and return why not (a sentence) when they refuse, like ``wiring.refusal``.
"""

from __future__ import annotations

import re

from flowmc.graph import Graph, Interface, InterfaceInput, InterfaceOutput
from flowmc.ports import PORT_TYPES

__all__ = ["add_input", "add_output", "remove", "feed", "unfeed", "take_from", "rename", "terminal_wires"]

NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


def _iface(graph: Graph) -> Interface:
    if graph.interface is None:
        graph.interface = Interface()
    return graph.interface


def _name_refusal(graph: Graph, name: str) -> str | None:
    if not NAME.match(name):
        return f"{name!r} is not a port name: letters, digits and _, not starting with a digit"
    iface = graph.interface
    if iface is not None and name in {i.name for i in iface.inputs} | {o.name for o in iface.outputs}:
        return f"the interface already has a port {name!r}"
    return None


def add_input(graph: Graph, name: str, port_type: str, description: str = "") -> str | None:
    """A new interface input feeding nothing yet (wire its terminal to node inputs)."""
    if port_type not in PORT_TYPES:
        return f"unknown port type {port_type!r}; one of {', '.join(PORT_TYPES)}"
    refusal = _name_refusal(graph, name)
    if refusal is None:
        _iface(graph).inputs.append(InterfaceInput(name=name, type=port_type, description=description, default=None))
    return refusal


def add_output(graph: Graph, name: str, source: str, port_type: str, description: str = "") -> str | None:
    """A new interface output taken from node output ``source`` ("node.output") of type ``port_type``."""
    refusal = _name_refusal(graph, name)
    if refusal is None:
        _iface(graph).outputs.append(InterfaceOutput(**{"name": name, "type": port_type, "from": source,
                                                       "description": description}))
    return refusal


def remove(graph: Graph, kind: str, name: str) -> bool:
    """Take the input or output ``name`` off the interface (its wires go with it); False when there is none."""
    iface = graph.interface
    if iface is None:
        return False
    before = len(iface.inputs) + len(iface.outputs)
    if kind == "in":
        iface.inputs = [item for item in iface.inputs if item.name != name]
    else:
        iface.outputs = [item for item in iface.outputs if item.name != name]
    if len(iface.inputs) + len(iface.outputs) == before:
        return False
    graph.view.terminals.pop(f"{kind}.{name}", None)
    if not iface.inputs and not iface.outputs:
        graph.interface = None
    return True


def rename(graph: Graph, kind: str, old: str, new: str) -> str | None:
    """Give a terminal another name (its place on the canvas follows it)."""
    if old == new:
        return None
    refusal = _name_refusal(graph, new)
    if refusal is not None:
        return refusal
    iface = _iface(graph)
    for item in iface.inputs if kind == "in" else iface.outputs:
        if item.name == old:
            item.name = new
            if f"{kind}.{old}" in graph.view.terminals:
                graph.view.terminals[f"{kind}.{new}"] = graph.view.terminals.pop(f"{kind}.{old}")
            return None
    return f"the interface has no {'input' if kind == 'in' else 'output'} {old!r}"


def feed(graph: Graph, name: str, ref: str) -> None:
    """Interface input ``name`` feeds input ``ref`` too; a wire that fed ``ref`` goes (one source per input)."""
    item = next(i for i in _iface(graph).inputs if i.name == name)
    graph.wires = [w for w in graph.wires if w.to != ref]
    for other in _iface(graph).inputs:
        other.to = [r for r in other.to if r != ref]
    item.to = [*item.to, ref]


def unfeed(graph: Graph, name: str, ref: str) -> bool:
    iface = graph.interface
    item = next((i for i in iface.inputs if i.name == name), None) if iface is not None else None
    if item is None or ref not in item.to:
        return False
    item.to = [r for r in item.to if r != ref]
    return True


def take_from(graph: Graph, name: str, source: str) -> None:
    """Interface output ``name`` takes its value from node output ``source``."""
    item = next(o for o in _iface(graph).outputs if o.name == name)
    item.from_ = source


def terminal_wires(graph: Graph) -> list[tuple[str, str, str]]:
    """The terminal wires the canvas draws: ``(from, to, type)``, with ``@in:<name>`` / ``@out:<name>`` ends."""
    iface = graph.interface
    if iface is None:
        return []
    out = [(f"@in:{item.name}", ref, item.type) for item in iface.inputs for ref in item.to]
    return out + [(item.from_, f"@out:{item.name}", item.type) for item in iface.outputs]
