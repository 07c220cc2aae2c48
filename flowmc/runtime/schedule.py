"""Scheduling on networkx: one Plan per graph revision (validated, ordered, ready to run).

The order is ``nx.topological_generations`` with ids sorted inside each generation, so two
runs of the same graph always visit nodes in the same order. When there is no order, each
cycle is named with ``nx.find_cycle`` (rotated to start at its smallest id).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import networkx as nx

import flowmc.budget as budget
from flowmc.fileio import fingerprint
from flowmc.graph import Graph, Issue
from flowmc.ports import In, Out
from flowmc.registry import Registry
from flowmc.runtime.context import Site
from flowmc.runtime.validate import BoundNode, check_graph

__all__ = ["Plan", "make_plan", "find_cycles"]


@dataclass
class Plan:
    """A validated graph: ``issues`` (empty when it can run), ``order``, ``generations``, ports per node."""

    graph: Graph
    site: Site
    registry: Registry
    issues: list[Issue]
    nodes: dict[str, BoundNode]
    digraph: nx.DiGraph
    generations: list[list[str]]
    iface_inputs: dict[str, tuple[Any, list[tuple[str, str]]]]
    iface_outputs: dict[str, tuple[Any, tuple[str, str]]]
    deps: dict[Path, str | None] = field(default_factory=dict)  # files read (sub-graphs) and their content hash
    size: int = 0  # nodes the graph expands to: its own, and those of the graphs they hold, in turn

    @property
    def ok(self) -> bool:
        return not self.issues

    @property
    def order(self) -> list[str]:
        return [node_id for generation in self.generations for node_id in generation]

    @property
    def pure(self) -> bool:
        return all(node.pure for node in self.nodes.values())

    def ports(self, node_id: str) -> tuple[dict[str, In], dict[str, Out]]:
        """Inputs (data and param ports) and outputs of a node as bound in this graph."""
        node = self.nodes[node_id]
        return node.inputs, node.outputs

    def downstream(self, node_id: str) -> set[str]:
        return nx.descendants(self.digraph, node_id)

    def deps_unchanged(self) -> bool:
        return all(fingerprint(path) == digest for path, digest in self.deps.items())


def find_cycles(digraph: nx.DiGraph) -> list[list[str]]:
    """One named cycle per strongly connected knot (enough to show each loop the user drew).

    ``find_cycle`` runs only inside knots: on a large acyclic graph it is far slower than
    the topological sort that already proves there is none.
    """
    cycles = []
    for component in sorted((c for c in nx.strongly_connected_components(digraph) if len(c) > 1), key=min):
        sub = digraph.subgraph(component)
        ids = [u for u, _v in nx.find_cycle(sub, source=min(component))]
        start = ids.index(min(ids))
        cycles.append(ids[start:] + ids[:start])
    for node_id in sorted(n for n in digraph if digraph.has_edge(n, n)):
        cycles.append([node_id])
    return sorted(cycles, key=lambda ids: ids[0])


def make_plan(graph: Graph, site: Site, registry: Registry, memo: dict[Any, Any] | None = None) -> Plan:
    """Validate ``graph`` against ``registry`` and order it; graphs that nodes hold are planned the same way,
    each file once per planning pass (``memo``), so a file used many times costs no more than once."""
    memo = {} if memo is None else memo
    checked = check_graph(graph, site, registry, lambda inner, inner_site: make_plan(inner, inner_site, registry, memo),
                          memo)
    digraph = nx.DiGraph()
    digraph.add_nodes_from(checked.node_ids)
    digraph.add_edges_from(sorted(set(checked.edges)))
    issues = checked.issues
    try:
        generations = [sorted(g) for g in nx.topological_generations(digraph)]
    except nx.NetworkXUnfeasible:
        generations = []
        for ids in find_cycles(digraph):
            text = " -> ".join(ids + ids[:1])
            issues.append(Issue("cycle", ("nodes", ids[0]), f"node {ids[0]!r}: cycle {text}"))
    size = len(checked.node_ids) + sum(n.binding.size for n in checked.nodes.values() if isinstance(n.binding, Plan))
    limit = budget.cap("expansion")
    if size > limit:
        issues.append(Issue("budget", (), f"the graph expands to {size:,} nodes through its sub-graphs, over the "
                                          f"budget of {limit:,}: use a sub-graph fewer times, or raise the limit "
                                          "(FLOWMC_BUDGET_EXPANSION)"))
    return Plan(graph, site, registry, issues, checked.nodes, digraph, generations,
                checked.iface_inputs, checked.iface_outputs, checked.deps, size)
