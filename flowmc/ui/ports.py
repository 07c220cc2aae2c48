"""The ports a node shows on the canvas, resolved through the core's public API.

A node's ports come from its bound plan entry when the graph was planned (this covers
sub-graph nodes, whose ports are their file's interface), else from its registered type
(``ports(params)`` for types whose ports depend on params). A node of an unknown type has
no ports; the canvas still draws it, flagged.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass
from typing import Any

from flowmc.errors import GraphError
from flowmc.graph import Node
from flowmc.ports import In, Out, Ports

__all__ = ["PORT_COLORS", "PortInfo", "NodePorts", "node_ports", "port_color"]

PORT_COLORS: dict[str, tuple[int, int, int]] = {
    "Path": (52, 120, 246),
    "Trajectory": (142, 68, 173),
    "Steps": (141, 110, 99),
    "Signal": (243, 156, 18),
    "Machine": (96, 125, 139),
    "Number": (39, 174, 96),
    "Bool": (231, 76, 60),
    "Text": (214, 51, 132),
    "Table": (0, 150, 136),
    "Log": (128, 128, 0),
}


def port_color(port_type: str) -> tuple[int, int, int]:
    return PORT_COLORS.get(port_type, (120, 120, 120))


@dataclass(frozen=True)
class PortInfo:
    """One port as the editor needs it: ``kind`` is "in" or "out"; ``param`` marks scalar-param inputs."""

    name: str
    kind: str
    types: tuple[str, ...]
    param: bool = False
    required: bool = False
    doc: str = ""

    @property
    def type(self) -> str:
        return self.types[0]

    @property
    def color(self) -> tuple[int, int, int]:
        return port_color(self.type)

    def accepts(self, port_type: str) -> bool:
        return port_type in self.types


@dataclass(frozen=True)
class NodePorts:
    """Inputs (data inputs, then param inputs) and outputs; ``known`` is False for unknown types."""

    inputs: tuple[PortInfo, ...] = ()
    outputs: tuple[PortInfo, ...] = ()
    known: bool = True

    def input(self, name: str) -> PortInfo | None:
        return next((p for p in self.inputs if p.name == name), None)

    def output(self, name: str) -> PortInfo | None:
        return next((p for p in self.outputs if p.name == name), None)


def _in(port: In) -> PortInfo:
    return PortInfo(port.name, "in", port.types, port.param, port.required, port.doc)


def _out(port: Out) -> PortInfo:
    return PortInfo(port.name, "out", (port.type,), doc=port.doc)


def node_ports(node: Node, registry: Any, graph_dir: Any = None, plan: Any = None) -> NodePorts:
    """Ports of ``node``: from ``plan`` (``Runtime.plan``) when it bound the node, else from its type in ``registry``."""
    if plan is not None and node.id in plan.nodes:
        inputs, outputs = plan.ports(node.id)
        ins = [_in(p) for p in inputs.values()]
        ins.sort(key=lambda p: p.param)  # data inputs first, stable otherwise
        return NodePorts(tuple(ins), tuple(_out(p) for p in outputs.values()))
    try:
        cls = registry.lookup(node.type, graph_dir)
    except GraphError:
        return NodePorts(known=False)
    ports = Ports(cls.inputs, cls.outputs)
    if cls.dynamic_ports():
        with contextlib.suppress(Exception):  # invalid params: the declared ports
            ports = cls.ports(cls.Params.model_validate(node.params))
    ins = tuple(_in(p) for p in ports.inputs) + tuple(_in(p) for p in cls.param_ports())
    return NodePorts(ins, tuple(_out(p) for p in ports.outputs))
