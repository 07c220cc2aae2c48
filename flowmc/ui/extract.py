"""Sub-graph files in the editor: which file a node runs, and making a sub-graph from a selection.

Making one: the selected nodes move into their own graph file, and every wire that crossed the
selection's edge becomes part of that file's interface.

A wire coming in becomes an interface input (one per outside source, feeding every inside port
it fed); a wire going out becomes an interface output (one per inside source). The graph's own
interface entries that pointed inside are passed through the new node the same way. The
selection is replaced by one ``subgraph`` node wired where the crossing wires were.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Callable

from flowmc.errors import GraphError
from flowmc.graph import Graph, Interface, InterfaceInput, InterfaceOutput, Node, Wire, split_ref
from flowmc.runtime import resolve_inside
from flowmc.ui.ports import NodePorts

__all__ = ["extract", "drop_interface_refs", "fresh_id", "node_file", "SUFFIX"]

SUFFIX = ".flowmc.json"


def node_file(node: Node, base_dir: Path) -> Path | None:
    """The graph file a ``subgraph`` node (its ``file`` param, inside ``base_dir``) or a ``lib.*`` node runs."""
    if node.type == "subgraph":
        file = node.params.get("file")
        if not isinstance(file, str) or not file:
            return None
        return resolve_inside(base_dir, base_dir, file, where=f"node {node.id!r}")
    if node.type.startswith("lib."):
        from flowmc.plugins import default_registry

        return getattr(default_registry().lookup(node.type, base_dir), "file_path", None)
    return None


def drop_interface_refs(graph: Graph, gone: set[str]) -> None:
    """Take interface entries pointing at deleted nodes out: inputs stop feeding them (an input left
    feeding nothing stays, as an unwired terminal), outputs they fed go."""
    iface = graph.interface
    if iface is None or not gone:
        return
    for item in iface.inputs:
        item.to = [ref for ref in item.to if split_ref(ref)[0] not in gone]
    iface.outputs = [item for item in iface.outputs if split_ref(item.from_)[0] not in gone]


def fresh_id(stem: str, used: set[str]) -> str:
    """``stem`` plus the first number that makes an unused node id (``translate1``, ``translate2``)."""
    stem = re.sub(r"[^A-Za-z0-9_]", "_", stem) or "node"
    stem = stem if re.match(r"[A-Za-z_]", stem) else f"n{stem}"
    k = 1
    while f"{stem}{k}" in used:
        k += 1
    return f"{stem}{k}"


def _unique(name: str, used: set[str]) -> str:
    candidate, k = name, 2
    while candidate in used:
        candidate, k = f"{name}_{k}", k + 1
    used.add(candidate)
    return candidate


def _target(file: str, base_dir: Path) -> tuple[Path, str]:
    name = file.strip()
    if not name:
        raise GraphError("give the new sub-graph a file name", where="make sub-graph")
    if not name.endswith(SUFFIX):
        name += SUFFIX
    target = resolve_inside(base_dir, base_dir, name, where="make sub-graph")
    if target.exists():
        raise GraphError(f"{name} already exists; choose another name", where="make sub-graph")
    return target, Path(name).as_posix()


def _port_type(ports: Callable[[str], NodePorts], ref: str) -> str:
    node_id, port = split_ref(ref)
    out = ports(node_id).output(port)
    if out is None:
        raise GraphError(f"cannot tell the type of {ref} (unknown node type or port)", where="make sub-graph")
    return out.type


def extract(graph: Graph, ids: list[str], file: str, base_dir: Path,
            ports: Callable[[str], NodePorts]) -> tuple[Graph, Graph, Path]:
    """Split ``graph``: returns (the graph with the selection replaced by a sub-graph node, the new
    sub-graph, the file to write it to). Nothing is written here; GraphError says why it cannot."""
    chosen = set(ids)
    if not chosen:
        raise GraphError("select the nodes to put into the sub-graph first", where="make sub-graph")
    target, rel = _target(file, base_dir)
    used_ids = {n.id for n in graph.nodes} - chosen
    new_id = fresh_id(Path(rel).name.split(".")[0], used_ids)
    inside = lambda ref: split_ref(ref)[0] in chosen  # noqa: E731
    in_names: set[str] = set()
    out_names: set[str] = set()
    inputs: dict[str, InterfaceInput] = {}  # outside source ref -> interface input
    outputs: dict[str, InterfaceOutput] = {}  # inside source ref -> interface output
    parent_wires: list[Wire] = []
    child_wires: list[Wire] = []
    for w in graph.wires:
        a, b = inside(w.from_), inside(w.to)
        if a and b:
            child_wires.append(w.model_copy())
        elif not a and not b:
            parent_wires.append(w.model_copy())
        elif b:  # coming in
            item = inputs.get(w.from_)
            if item is None:
                name = _unique(split_ref(w.to)[1], in_names)
                item = inputs[w.from_] = InterfaceInput(name=name, type=_port_type(ports, w.from_), to=[w.to])
                parent_wires.append(Wire(**{"from": w.from_, "to": f"{new_id}.{name}"}))
            else:
                item.to.append(w.to)
        else:  # going out
            item = _output_for(outputs, out_names, w.from_, ports)
            parent_wires.append(Wire(**{"from": f"{new_id}.{item.name}", "to": w.to}))
    parent_iface = graph.interface.model_copy(deep=True) if graph.interface is not None else None
    child_inputs = list(inputs.values())
    if parent_iface is not None:
        for item in parent_iface.inputs:
            refs = [r for r in item.to if inside(r)]
            if refs:
                name = _unique(item.name, in_names)
                child_inputs.append(InterfaceInput(name=name, type=item.type, to=refs, description=item.description))
                item.to = [r for r in item.to if not inside(r)] + [f"{new_id}.{name}"]
        for item in parent_iface.outputs:
            if inside(item.from_):
                item.from_ = f"{new_id}.{_output_for(outputs, out_names, item.from_, ports).name}"
    picked = [n for n in graph.nodes if n.id in chosen]
    x0, y0 = min(n.pos[0] for n in picked), min(n.pos[1] for n in picked)
    child_nodes = [Node(id=n.id, type=n.type, params=dict(n.params), pos=(n.pos[0] - x0, n.pos[1] - y0)) for n in picked]
    centre = (sum(n.pos[0] for n in picked) / len(picked), sum(n.pos[1] for n in picked) / len(picked))
    stem = Path(rel).name[: -len(SUFFIX)]
    child = Graph(title=stem, nodes=child_nodes, wires=child_wires,
                  interface=Interface(inputs=child_inputs, outputs=list(outputs.values())))
    parent_nodes = [n.model_copy(deep=True) for n in graph.nodes if n.id not in chosen]
    parent_nodes.append(Node(id=new_id, type="subgraph", params={"file": rel}, pos=centre))
    parent = Graph(title=graph.title, description=graph.description, nodes=parent_nodes,
                   wires=parent_wires, interface=parent_iface)
    parent.path = graph.path
    return parent, child, target


def _output_for(outputs: dict[str, InterfaceOutput], used: set[str], ref: str,
                ports: Callable[[str], NodePorts]) -> InterfaceOutput:
    item = outputs.get(ref)
    if item is None:
        name = _unique(split_ref(ref)[1], used)
        item = outputs[ref] = InterfaceOutput(**{"name": name, "type": _port_type(ports, ref), "from": ref})
    return item
