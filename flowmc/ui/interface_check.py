"""Before a sub-graph is saved with a changed interface: which graphs that use it would it break?

A parent is any graph file in the editor's folder (two levels deep, as the Files tab lists them) or
waiting on the sub-graph stack, with a ``subgraph`` node whose ``file`` is this file. It breaks
where a wire runs to an input the new interface no longer has (or of a type it no longer takes),
or from an output that is gone or changed type.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Iterable

from flowmc.errors import GraphError
from flowmc.graph import Graph, load, split_ref
from flowmc.runtime import resolve_inside
from flowmc.ui.ports import node_ports

__all__ = ["interface_changed", "broken_parents"]

SUFFIX = ".flowmc.json"


def _ports(graph: Graph) -> tuple[dict[str, str], dict[str, str]]:
    iface = graph.interface
    if iface is None:
        return {}, {}
    return {i.name: i.type for i in iface.inputs}, {o.name: o.type for o in iface.outputs}


def interface_changed(graph: Graph, path: Path) -> bool:
    """Whether ``graph``'s interface differs from the one saved at ``path`` (False when there is no file)."""
    try:
        return _ports(load(path)) != _ports(graph)
    except GraphError:
        return False


def _uses(parent: Graph, node: Any, child: Path) -> bool:
    if node.type != "subgraph" or parent.path is None or not isinstance(node.params.get("file"), str):
        return False
    try:
        base = parent.path.parent
        return resolve_inside(base, base, node.params["file"]) == child.resolve()
    except GraphError:
        return False


def _node_ports(parent: Graph, node_id: str, registry: Any) -> tuple[dict[str, tuple[str, ...]], dict[str, str]]:
    """(input name -> types it takes, output name -> type) of a node in ``parent`` (a sub-graph's from its file)."""
    node = next((n for n in parent.nodes if n.id == node_id), None)
    if node is None or parent.path is None:
        return {}, {}
    base = parent.path.parent
    if node.type == "subgraph":
        try:
            ins, outs = _ports(load(resolve_inside(base, base, node.params["file"])))
        except (GraphError, KeyError, TypeError):
            return {}, {}
        return {k: (v,) for k, v in ins.items()}, outs
    ports = node_ports(node, registry, base)
    return {p.name: p.types for p in ports.inputs}, {p.name: p.type for p in ports.outputs}


def broken_parents(graph: Graph, path: Path, folder: Path, registry: Any, waiting: Iterable[Graph] = ()) -> list[str]:
    """One line per wire that saving ``graph`` at ``path`` would break in a graph that uses it: an input
    or output that is gone, or a wire whose ends no longer fit (the new type against the other end)."""
    ins, outs = _ports(graph)
    parents: dict[Path, Graph] = {}
    for candidate in [*Path(folder).glob(f"*{SUFFIX}"), *Path(folder).glob(f"*/*{SUFFIX}")]:
        if candidate.resolve() != path.resolve():
            try:
                parents[candidate.resolve()] = load(candidate)
            except GraphError:
                continue
    for parent in waiting:  # the open parents, with their unsaved changes
        if parent.path is not None:
            parents[parent.path.resolve()] = parent
    found = []
    for where, parent in sorted(parents.items()):
        for node in (n for n in parent.nodes if _uses(parent, n, path)):
            for wire in parent.wires:
                (src, sp), (dst, dp) = split_ref(wire.from_), split_ref(wire.to)
                line = f"{where.name}: {wire.from_} → {wire.to}: "
                if dst == node.id and dp not in ins:
                    found.append(line + f"the sub-graph has no input {dp!r} any more")
                elif dst == node.id:
                    given = _node_ports(parent, src, registry)[1].get(sp)
                    if given is not None and given != ins[dp]:
                        found.append(line + f"input {dp!r} now takes {ins[dp]}, {wire.from_} gives {given}")
                if src == node.id and sp not in outs:
                    found.append(line + f"the sub-graph has no output {sp!r} any more")
                elif src == node.id:
                    takes = _node_ports(parent, dst, registry)[0].get(dp)
                    if takes is not None and outs[sp] not in takes:
                        found.append(line + f"output {sp!r} now gives {outs[sp]}, {wire.to} takes {' or '.join(takes)}")
    return found
