"""Structures in the editor (no viser here): making a loop or case from a selection, a body as a graph
to edit and put back, shift registers, collected outputs, N on the front panel, and how a structure
names itself on the canvas ("For loop · N = 5").

A body is edited in place of the graph that holds it (``EditorState.enter_body``), as a sub-graph file
is; going back puts it into the structure as one undoable edit of the outer graph."""

from __future__ import annotations

from typing import Callable

from flowmc.errors import GraphError
from flowmc.graph import Body, Graph, Interface, InterfaceInput
from flowmc.ui import extract
from flowmc.ui.ports import NodePorts

__all__ = ["STRUCTURES", "wrap", "body_graph", "body_changed", "put_body", "body_outputs", "add_shift_register",
           "set_collected", "expose_count", "add_case", "caption"]

#: Structure node types the editor makes, with the stem of their new ids.
STRUCTURES = {"struct.for": "loop", "struct.while": "while_loop", "struct.case": "case"}


def _structure(graph: Graph, node_id: str):
    node = graph.node(node_id)
    if node.type not in STRUCTURES:
        raise GraphError(f"node {node_id!r} is not a loop or case structure", where=f"node {node_id!r}")
    return node


def wrap(graph: Graph, ids: list[str], type_id: str, ports: Callable[[str], NodePorts]) -> Graph:
    """``graph`` with the nodes ``ids`` moved into a new structure of ``type_id`` (last in its nodes); a
    case gets them as its True and its False case (edit one of them), a While loop stops after 100."""
    if type_id not in STRUCTURES:
        raise GraphError(f"{type_id!r} is not a structure; choose one of {', '.join(STRUCTURES)}", where="make structure")
    if not ids:
        raise GraphError("select the nodes to put into the structure first", where="make structure")
    new_id = extract.fresh_id(STRUCTURES[type_id], {n.id for n in graph.nodes} - set(ids))
    parent, child = extract.split(graph, ids, new_id, ports, type_id)
    body = Body(nodes=child.nodes, wires=child.wires, interface=child.interface or Interface())
    node = parent.nodes[-1]
    if type_id == "struct.case":
        node.params = {"selector_type": "Bool"}
        node.bodies = {"True": body, "False": body.model_copy(deep=True)}
    else:
        node.params = {"max_iterations": 100} if type_id == "struct.while" else {"count": 1}
        node.bodies = {"body": body}
    return parent


def body_graph(graph: Graph, node_id: str, name: str) -> Graph:
    """Body ``name`` of structure ``node_id`` as a graph to edit (files inside resolve beside ``graph``)."""
    node = _structure(graph, node_id)
    if name not in node.bodies:
        raise GraphError(f"node {node_id!r} has no body {name!r}; it has {', '.join(map(repr, node.bodies))}",
                         where=f"node {node_id!r}")
    body = node.bodies[name].model_copy(deep=True).as_graph(graph)
    body.title = f"{node_id}: {name}"
    return body


def _as_body(edited: Graph) -> Body:
    return Body(nodes=edited.nodes, wires=edited.wires, interface=edited.interface or Interface())


def body_changed(graph: Graph, place: tuple[str, str], edited: Graph) -> bool:
    node_id, name = place
    return graph.node(node_id).bodies[name].model_dump() != _as_body(edited).model_dump()


def put_body(graph: Graph, place: tuple[str, str], edited: Graph) -> None:
    node_id, name = place
    graph.node(node_id).bodies[name] = _as_body(edited).model_copy(deep=True)


def body_outputs(graph: Graph, node_id: str) -> list[tuple[str, str]]:
    """A loop body's outputs, (name, type), that can be shift registers or collected."""
    node = _structure(graph, node_id)
    body = node.bodies.get("body")
    return [(o.name, o.type) for o in body.interface.outputs if o.name != "stop"] if body is not None else []


def add_shift_register(graph: Graph, node_id: str, name: str) -> None:
    """Make the loop body's output ``name`` a shift register: the body gets an input of that name and
    type (wire it inside the body), the loop an input for the first value."""
    node = _structure(graph, node_id)
    types = dict(body_outputs(graph, node_id))
    if name not in types:
        raise GraphError(f"the body has no output {name!r} to feed back; its outputs: {', '.join(types) or 'none'}",
                         where=f"node {node_id!r}")
    shift = list(node.params.get("shift", []))
    if name in shift:
        return
    iface = node.bodies["body"].interface
    if not any(i.name == name for i in iface.inputs):
        iface.inputs.append(InterfaceInput(name=name, type=types[name], to=[], default=None,
                                           description="Shift register: the last iteration's value"))
    node.params["shift"] = shift + [name]
    node.params["indexed"] = [n for n in node.params.get("indexed", []) if n != name]


def set_collected(graph: Graph, node_id: str, name: str, on: bool) -> None:
    """Auto-index the loop output ``name`` (every iteration's value) or give the last value."""
    node = _structure(graph, node_id)
    indexed = [n for n in node.params.get("indexed", []) if n != name]
    node.params["indexed"] = indexed + ([name] if on else [])
    if not node.params["indexed"]:
        del node.params["indexed"]


def expose_count(graph: Graph, node_id: str) -> str:
    """A front-panel control for the For loop's N: an interface input feeding its count. Returns its name."""
    node = _structure(graph, node_id)
    if node.type != "struct.for":
        raise GraphError("only a For loop has a count N", where=f"node {node_id!r}")
    iface = graph.interface if graph.interface is not None else Interface()
    ref = f"{node_id}.count"
    for item in iface.inputs:
        if ref in item.to:
            return item.name
    used = {i.name for i in iface.inputs}
    name = next(n for n in (f"{node_id}_N", *(f"{node_id}_N{k}" for k in range(2, 999))) if n not in used)
    iface.inputs.append(InterfaceInput(name=name, type="Number", to=[ref], default=float(node.params.get("count", 1)),
                                       description=f"N of the For loop {node_id}"))
    graph.interface = iface
    return name


def add_case(graph: Graph, node_id: str, label: str, like: str) -> None:
    """A new case ``label``, a copy of case ``like`` (so it shares the interface from the start)."""
    node = _structure(graph, node_id)
    label = label.strip()
    if node.type != "struct.case":
        raise GraphError("only a Case structure has cases", where=f"node {node_id!r}")
    if not label or label in node.bodies:
        raise GraphError(f"give the new case a label that is not taken ({', '.join(node.bodies)})",
                         where=f"node {node_id!r}")
    node.bodies[label] = node.bodies[like].model_copy(deep=True)


def _fed(graph: Graph, ref: str) -> str | None:
    """What feeds input ``ref``: the interface input's name or the wire's source, else None."""
    for item in graph.interface.inputs if graph.interface is not None else ():
        if ref in item.to:
            return item.name
    return next((w.from_ for w in graph.wires if w.to == ref), None)


def caption(graph: Graph, node_id: str) -> str:
    """What a structure says of itself on the canvas: kind and count (``For loop · N = 5``, or the
    name of what feeds N)."""
    node = graph.node(node_id)
    if node.type == "struct.for":
        return f"For loop · N = {_fed(graph, f'{node_id}.count') or node.params.get('count', 1)}"
    if node.type == "struct.while":
        return f"While loop · at most {node.params.get('max_iterations', '?')}"
    count = len(node.bodies)
    return f"Case · {count} case{'s' if count != 1 else ''}"
