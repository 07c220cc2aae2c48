"""GraphBuilder: write graphs in code (tests, examples, scripts) instead of JSON by hand.

>>> g = GraphBuilder(title="demo")
>>> a = g.add("basic.number", id="a", value=2.0)
>>> s = g.add("basic.add", id="s", b=3.0)
>>> g.wire(a.value, s.a)
>>> g.output("sum", "Number", s.result)
>>> graph = g.build()
"""

from __future__ import annotations

from typing import Any, NamedTuple

from flowmc.errors import GraphError
from flowmc.graph import Body, Graph, Interface, InterfaceInput, InterfaceOutput, Node, Wire, save

__all__ = ["GraphBuilder", "NodeRef", "PortRef"]


class PortRef(NamedTuple):
    node: str
    port: str

    def __str__(self) -> str:
        return f"{self.node}.{self.port}"


class NodeRef:
    """A node added to a builder; ``ref.<port>`` (or ``ref["port"]``) names one of its ports."""

    def __init__(self, node_id: str):
        self.id = node_id

    def __getattr__(self, name: str) -> PortRef:
        if name.startswith("_"):
            raise AttributeError(name)
        return PortRef(self.id, name)

    def __getitem__(self, name: str) -> PortRef:
        return PortRef(self.id, name)

    def __repr__(self) -> str:
        return f"NodeRef({self.id!r})"


def _ref(ref: PortRef | str) -> str:
    return str(ref)


def _as_body(graph: Graph | Body) -> Body:
    if isinstance(graph, Body):
        return graph
    return Body(nodes=graph.nodes, wires=graph.wires, interface=graph.interface or Interface())


class GraphBuilder:
    """Builds a Graph; ids default to the type's last part plus a number, positions to a row."""

    def __init__(self, title: str = "", description: str = ""):
        self.title, self.description = title, description
        self._nodes: list[Node] = []
        self._wires: list[Wire] = []
        self._inputs: list[InterfaceInput] = []
        self._outputs: list[InterfaceOutput] = []

    def add(self, type_id: str, id: str | None = None, *, pos: tuple[float, float] | None = None,
            params: dict[str, Any] | None = None, bodies: dict[str, Graph | Body] | None = None,
            **kwargs: Any) -> NodeRef:
        """Add a node; params by keyword (or ``params=`` for names like ``id`` and ``pos``); a structure's
        ``bodies`` by name (graphs built with another builder: their nodes, wires and interface)."""
        node_id = id or self._fresh_id(type_id)
        if any(n.id == node_id for n in self._nodes):
            raise GraphError(f"node id {node_id!r} is already used", where="builder")
        position = pos if pos is not None else (240.0 * len(self._nodes), 0.0)
        held = {name: _as_body(body) for name, body in (bodies or {}).items()}
        self._nodes.append(Node(id=node_id, type=type_id, params={**(params or {}), **kwargs}, pos=position,
                                bodies=held))
        return NodeRef(node_id)

    def _fresh_id(self, type_id: str) -> str:
        stem = type_id.rsplit(".", 1)[-1].replace("-", "_")
        used = {n.id for n in self._nodes}
        k = 1
        while f"{stem}{k}" in used:
            k += 1
        return f"{stem}{k}"

    def wire(self, src: PortRef | str, dst: PortRef | str) -> None:
        """Wire output ``src`` to input (or scalar param) ``dst``."""
        self._wires.append(Wire(**{"from": _ref(src), "to": _ref(dst)}))

    def input(self, name: str, type: str, to: PortRef | str | list, *, default: Any = None, description: str = "") -> None:
        """Declare an interface input feeding one or more internal ports."""
        targets = [_ref(t) for t in (to if isinstance(to, list) else [to])]
        self._inputs.append(InterfaceInput(name=name, type=type, to=targets, default=default, description=description))

    def output(self, name: str, type: str, src: PortRef | str, *, description: str = "") -> None:
        """Declare an interface output taken from an internal output port."""
        self._outputs.append(InterfaceOutput(**{"name": name, "type": type, "from": _ref(src), "description": description}))

    def build(self) -> Graph:
        interface = Interface(inputs=self._inputs, outputs=self._outputs) if self._inputs or self._outputs else None
        return Graph(title=self.title, description=self.description, nodes=list(self._nodes),
                     wires=list(self._wires), interface=interface).model_copy(deep=True)

    def save(self, path: Any) -> Graph:
        graph = self.build()
        save(graph, path)
        return graph
