"""Scheduling: one Plan per graph revision (validated, ordered, ready to run).

The order is the graph's topological generations (what networkx's ``topological_generations``
gives) with ids sorted inside each generation, so two runs of the same graph always visit nodes
in the same order. The standard library's ``graphlib`` computes them: networkx takes a tenth of a
second to import, which ``flowmc validate`` cannot spare. When there is no order, networkx names
each cycle (``nx.find_cycle``, rotated to start at its smallest id).
"""

from __future__ import annotations

import graphlib
from pathlib import Path
from typing import Any

import flowmc.budget as budget
from flowmc.fileio import fingerprint
from flowmc.graph import Graph, Issue
from flowmc.ports import In, Out
from flowmc.registry import Registry
from flowmc.runtime.context import Site
from flowmc.runtime.validate import BoundNode, check_graph

__all__ = ["Plan", "make_plan", "generations", "find_cycles"]


class Plan:
    """A validated graph: ``issues`` (empty when it can run), ``order``, ``generations``, ports per node.
    (A plain class, not a dataclass: those have their methods compiled from text at every start.)"""

    __slots__ = ("graph", "site", "registry", "issues", "nodes", "successors", "generations", "iface_inputs",
                 "iface_outputs", "deps", "size")

    def __init__(self, graph: Graph, site: Site, registry: Registry, issues: list[Issue],
                 nodes: dict[str, BoundNode], successors: dict[str, set[str]], generations: list[list[str]],
                 iface_inputs: dict[str, tuple[Any, list[tuple[str, str]]]],
                 iface_outputs: dict[str, tuple[Any, tuple[str, str]]], deps: dict[Path, str | None] | None = None,
                 size: int = 0) -> None:
        self.graph = graph
        self.site = site
        self.registry = registry
        self.issues = issues
        self.nodes = nodes
        self.successors = successors  # node id -> the nodes its outputs feed
        self.generations = generations
        self.iface_inputs = iface_inputs
        self.iface_outputs = iface_outputs
        self.deps = {} if deps is None else deps  # files read (sub-graphs) and their content hash
        self.size = size  # nodes the graph expands to: its own, and those of the graphs they hold, in turn

    @property
    def ok(self) -> bool:
        return not self.issues

    @property
    def order(self) -> list[str]:
        return [node_id for generation in self.generations for node_id in generation]

    @property
    def pure(self) -> bool:
        return all(node.pure for node in self.nodes.values())

    @property
    def moves(self) -> bool:
        """Some node drives a device: running the plan prepares jobs, only Start runs them."""
        return any(node.moves for node in self.nodes.values())

    def ports(self, node_id: str) -> tuple[dict[str, In], dict[str, Out]]:
        """Inputs (data and param ports) and outputs of a node as bound in this graph."""
        node = self.nodes[node_id]
        return node.inputs, node.outputs

    def outputs_of(self, *port_types: str) -> list[tuple[str, str]]:
        """(node id, output) of every output port of these types, in run order (a node's in declared order):
        the one way to find a graph's Path, Machine or motion, before a run or in its result."""
        return [(node_id, name) for node_id in self.order if node_id in self.nodes
                for name, port in self.nodes[node_id].outputs.items() if port.type in port_types]

    def downstream(self, node_id: str) -> set[str]:
        """Every node that depends on ``node_id``, directly or through others."""
        found: set[str] = set()
        todo = [node_id]
        while todo:
            for nxt in self.successors.get(todo.pop(), ()):
                if nxt not in found:
                    found.add(nxt)
                    todo.append(nxt)
        return found

    def deps_unchanged(self) -> bool:
        return all(fingerprint(path) == digest for path, digest in self.deps.items())


def find_cycles(edges: list[tuple[str, str]]) -> list[list[str]]:
    """One named cycle per strongly connected knot (enough to show each loop the user drew)."""
    import networkx as nx  # only a graph with a cycle pays for it

    digraph = nx.DiGraph(edges)
    cycles = []
    for component in sorted((c for c in nx.strongly_connected_components(digraph) if len(c) > 1), key=min):
        sub = digraph.subgraph(component)
        ids = [u for u, _v in nx.find_cycle(sub, source=min(component))]
        start = ids.index(min(ids))
        cycles.append(ids[start:] + ids[:start])
    for node_id in sorted(n for n in digraph if digraph.has_edge(n, n)):
        cycles.append([node_id])
    return sorted(cycles, key=lambda ids: ids[0])


def generations(node_ids: list[str], edges: list[tuple[str, str]]) -> list[list[str]] | None:
    """Topological generations, ids sorted in each; None when there is a cycle."""
    sorter: graphlib.TopologicalSorter[str] = graphlib.TopologicalSorter({n: () for n in node_ids})
    for src, dst in edges:
        sorter.add(dst, src)
    try:
        sorter.prepare()
    except graphlib.CycleError:
        return None
    out = []
    while sorter.is_active():
        ready = sorted(sorter.get_ready())
        sorter.done(*ready)
        out.append(ready)
    return out


def make_plan(graph: Graph, site: Site, registry: Registry, memo: dict[Any, Any] | None = None) -> Plan:
    """Validate ``graph`` against ``registry`` and order it; graphs that nodes hold are planned the same way,
    each file once per planning pass (``memo``), so a file used many times costs no more than once."""
    memo = {} if memo is None else memo
    checked = check_graph(graph, site, registry, lambda inner, inner_site: make_plan(inner, inner_site, registry, memo),
                          memo)
    edges = sorted(set(checked.edges))
    successors: dict[str, set[str]] = {}
    for src, dst in edges:
        successors.setdefault(src, set()).add(dst)
    issues = checked.issues
    order = generations(checked.node_ids, edges)
    if order is None:
        order = []
        for ids in find_cycles(edges):
            text = " -> ".join(ids + ids[:1])
            issues.append(Issue("cycle", ("nodes", ids[0]), f"node {ids[0]!r}: cycle {text}"))
    size = len(checked.node_ids) + sum(getattr(n.binding, "size", 0) for n in checked.nodes.values())
    limit = budget.cap("expansion")
    if size > limit:
        issues.append(Issue("budget", (), f"the graph expands to {size:,} nodes through its sub-graphs and "
                                          f"structures, over the budget of {limit:,}: use a sub-graph fewer times, "
                                          "or raise the limit "
                                          "(FLOWMC_BUDGET_EXPANSION)"))
    return Plan(graph, site, registry, issues, checked.nodes, successors, order,
                checked.iface_inputs, checked.iface_outputs, checked.deps, size)
