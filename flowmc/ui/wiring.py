"""The wiring rules: what may feed what. A refusal is a sentence that says why, for the status line."""

from __future__ import annotations

from typing import Callable

import networkx as nx

from flowmc.graph import Graph, split_ref
from flowmc.ui.ports import NodePorts

__all__ = ["refusal", "terminal_refusal", "loop_through"]


def refusal(graph: Graph, ports: Callable[[str], NodePorts], src: str, dst: str) -> str | None:
    """Why output ``src`` ("node.output") may not feed input ``dst`` ("node.input"), or None when it may.
    An input that is already fed is not a refusal: the new wire replaces the old one."""
    (sn, sp), (dn, dp) = split_ref(src), split_ref(dst)
    ids = {n.id for n in graph.nodes}
    for node_id in (sn, dn):
        if node_id not in ids:
            return f"there is no node {node_id!r}"
    if sn == dn:
        return f"a node cannot feed itself ({src} -> {dst})"
    out, inp = ports(sn).output(sp), ports(dn).input(dp)
    if out is None:
        return f"node {sn!r} has no output {sp!r}"
    if inp is None:
        return f"node {dn!r} has no input {dp!r}"
    if not inp.accepts(out.type):
        return (f"cannot wire {src} to {dst}: output {sp!r} of {sn!r} is a {out.type}, "
                f"but input {dp!r} of {dn!r} takes {' or '.join(inp.types)}")
    iface = graph.interface
    fed_by = next((i.name for i in iface.inputs if dst in i.to), None) if iface is not None else None
    if fed_by is not None:
        return f"input {dst} is fed by the graph's interface input {fed_by!r}; take it off the interface first"
    if any(w.from_ == src and w.to == dst for w in graph.wires):
        return f"{src} is already wired to {dst}"
    loop = loop_through([(w.from_, w.to) for w in graph.wires if w.to != dst], sn, dn)
    if loop:
        return f"wiring {src} -> {dst} would close a loop: {' -> '.join(loop)}"
    return None


def terminal_refusal(graph: Graph, ports: Callable[[str], NodePorts], src: str, dst: str) -> str | None:
    """Why an interface input terminal ``@in:x`` may not feed input ``dst``, or why output ``src`` may
    not feed the interface output terminal ``@out:y`` (None when it may)."""
    iface = graph.interface
    ids = {n.id for n in graph.nodes}
    if src.startswith("@in:") and not dst.startswith("@"):
        item = next((i for i in iface.inputs if i.name == src[4:]), None) if iface is not None else None
        node_id, port = split_ref(dst)
        inp = ports(node_id).input(port) if node_id in ids else None
        if item is None or inp is None:
            return f"there is no interface input {src[4:]!r} or no input {dst}"
        if not inp.accepts(item.type):
            return (f"cannot wire interface input {item.name!r} ({item.type}) to {dst}: it takes "
                    f"{' or '.join(inp.types)}")
        return None if dst not in item.to else f"interface input {item.name!r} already feeds {dst}"
    if dst.startswith("@out:") and not src.startswith("@"):
        given = next((o for o in iface.outputs if o.name == dst[5:]), None) if iface is not None else None
        node_id, port = split_ref(src)
        out = ports(node_id).output(port) if node_id in ids else None
        if given is None or out is None:
            return f"there is no interface output {dst[5:]!r} or no output {src}"
        if out.type != given.type:
            return f"cannot wire {src} ({out.type}) to interface output {given.name!r}: it is a {given.type}"
        return None
    return "wire an interface input to a node input, or a node output to an interface output"


def loop_through(wires: list[tuple[str, str]], src_node: str, dst_node: str) -> list[str]:
    """The loop a wire src_node -> dst_node would close over ``wires`` (node ids, first = last), or []."""
    digraph = nx.DiGraph((split_ref(a)[0], split_ref(b)[0]) for a, b in wires)
    if src_node in digraph and dst_node in digraph and nx.has_path(digraph, dst_node, src_node):
        return [src_node, *nx.shortest_path(digraph, dst_node, src_node)]
    return []
