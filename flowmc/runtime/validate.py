"""Validation: check a whole graph before anything runs and collect EVERY problem.

Each problem is an ``Issue(code, location, message)``; the message names the node id and
port, the location points into the file for the editor. A node whose type or ports are
unknown is reported once: the wires touching it are not flagged again.

Codes: unknown-node-type, unknown-param, invalid-param, missing-input, unknown-node,
unknown-port, broken-wire, input-wired-twice, duplicate-node-id, interface-port,
interface-type, interface-duplicate, cycle (schedule.py), subgraph, subgraph-recursion,
path-escape (the last three from sub-graph nodes), bodies (a node holding bodies its type cannot),
structure (a loop's or case's bodies, from structure nodes).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any, Callable

from pydantic import BaseModel, ValidationError

import flowmc.budget as budget
from flowmc.errors import GraphError
from flowmc.graph import Graph, Issue, Node, split_ref
from flowmc.ports import SCALAR_PORT_TYPES, In, Out, Ports
from flowmc.registry import NodeType, Registry, check_ports
from flowmc.runtime.binding import BindContext, binder_of, holds_bodies
from flowmc.runtime.cache import static_key
from flowmc.runtime.context import Site

__all__ = ["BoundNode", "Checked", "check_graph", "value_matches"]


def value_matches(port_type: str, value: Any) -> bool:
    """Scalar port types are checked; object types are trusted to their node's declaration."""
    np = sys.modules.get("numpy")  # a numpy scalar exists only once numpy is imported: validating needs none
    if port_type == "Number":
        if isinstance(value, (int, float)):
            return not isinstance(value, bool)
        return np is not None and isinstance(value, (np.integer, np.floating))
    if port_type == "Bool":
        return isinstance(value, bool) or (np is not None and isinstance(value, np.bool_))
    if port_type == "Text":
        return isinstance(value, str)
    return True


class BoundNode:
    """A node with its type resolved, params validated and ports known. (A plain class, not a dataclass:
    Python builds a dataclass's methods from source text, a cost every cold start paid.)"""

    __slots__ = ("id", "cls", "raw_params", "params", "inputs", "outputs", "pure", "static", "binding", "moves",
                 "sources", "fed")

    def __init__(self, id: str, cls: type[NodeType], raw_params: dict[str, Any], params: BaseModel | None,
                 inputs: dict[str, In], outputs: dict[str, Out], pure: bool, static: bytes = b"",
                 binding: Any = None, moves: bool = False) -> None:
        self.id = id
        self.cls = cls
        self.raw_params = raw_params
        self.params = params  # None: some stored param is invalid but wired (checked at run time)
        self.inputs = inputs  # data inputs and param ports by name
        self.outputs = outputs
        self.pure = pure
        self.static = static
        self.binding = binding  # types that hold a graph (runtime.binding): the inner plan
        self.moves = moves  # a device node, or a sub-graph holding one: two phases (runtime.start)
        self.sources: dict[str, tuple[str, str]] = {}  # input -> (node, output)
        self.fed: dict[str, str] = {}  # input -> interface input name


class Checked:
    """What ``check_graph`` found: the issues, the bound nodes, the wires and the interface."""

    __slots__ = ("issues", "nodes", "node_ids", "edges", "iface_inputs", "iface_outputs", "deps")

    def __init__(self, issues: list[Issue], nodes: dict[str, BoundNode], node_ids: list[str],
                 edges: list[tuple[str, str]], iface_inputs: dict[str, tuple[Any, list[tuple[str, str]]]],
                 iface_outputs: dict[str, tuple[Any, tuple[str, str]]], deps: dict[Path, str | None]) -> None:
        self.issues = issues
        self.nodes = nodes
        self.node_ids = node_ids  # every distinct id, sorted (also those whose type is unknown)
        self.edges = edges
        self.iface_inputs = iface_inputs
        self.iface_outputs = iface_outputs
        self.deps = deps


def check_graph(graph: Graph, site: Site, registry: Registry, plan: Callable[[Graph, Site], Any],
                memo: dict[Any, Any] | None = None) -> Checked:
    """Every problem of ``graph`` with its node types from ``registry``; ``plan`` plans held graphs
    (``memo``: what binding held graphs already did in this planning pass)."""
    issues: list[Issue] = []
    nodes = _unique_nodes(graph, issues)
    targets = _targets_by_node(graph)
    deps: dict[Path, str | None] = {}
    bound: dict[str, BoundNode] = {}
    memo = {} if memo is None else memo
    for node in nodes.values():
        b = _bind_node(node, graph, site, registry, plan, targets.get(node.id, set()), issues, deps, memo)
        if b is not None:
            bound[node.id] = b
    edges, fed_by = _check_wires(graph, nodes, bound, issues)
    iface_in, iface_out = _check_interface(graph, nodes, bound, fed_by, issues)
    _check_required(bound, targets, issues)
    return Checked(issues, bound, sorted(nodes), edges, iface_in, iface_out, deps)


def _unique_nodes(graph: Graph, issues: list[Issue]) -> dict[str, Node]:
    nodes: dict[str, Node] = {}
    counts: dict[str, int] = {}
    for node in graph.nodes:
        counts[node.id] = counts.get(node.id, 0) + 1
        nodes.setdefault(node.id, node)
    for node_id, n in sorted(counts.items()):
        if n > 1:
            issues.append(Issue("duplicate-node-id", ("nodes", node_id), f"node {node_id!r}: id used by {n} nodes"))
    return nodes


def _targets_by_node(graph: Graph) -> dict[str, set[str]]:
    """Ports fed from outside the node (wires and interface inputs), by node id."""
    out: dict[str, set[str]] = {}
    refs = [w.to for w in graph.wires]
    if graph.interface is not None:
        refs += [ref for item in graph.interface.inputs for ref in item.to]
    for ref in refs:
        node_id, port = split_ref(ref)
        out.setdefault(node_id, set()).add(port)
    return out


# ---------------------------------------------------------------- nodes

def _bind_node(node: Node, graph: Graph, site: Site, registry: Registry, plan: Callable[[Graph, Site], Any],
               fed_ports: set[str], issues: list[Issue], deps: dict, memo: dict) -> BoundNode | None:
    try:
        cls = registry.lookup(node.type, site.graph_dir)
    except GraphError:
        message = f"node {node.id!r}: unknown node type {node.type!r}{registry.unknown_type_hint()}"
        issues.append(Issue("unknown-node-type", ("nodes", node.id, "type"), message))
        return None
    params, param_issues = _validate_params(node, cls, fed_ports)
    issues.extend(param_issues)
    binder = binder_of(cls)
    if node.bodies and not holds_bodies(cls):
        issues.append(Issue("bodies", ("nodes", node.id, "bodies"),
                            f"node {node.id!r}: a {node.type} holds no bodies (only loops and case structures do)"))
        return None
    if (binder is not None or cls.dynamic_ports()) and params is None:
        return None  # ports depend on params we could not read
    binding, pure, extra = None, cls.pure, ""
    if binder is not None:
        bodies = {name: body.as_graph(graph) for name, body in node.bodies.items()}
        try:
            bound = binder.bind_graph(params, BindContext(site, node.id, plan, memo, bodies))
        except GraphError as exc:
            issues.extend(exc.issues or [Issue("subgraph", ("nodes", node.id, "params"), f"node {node.id!r}: {exc}")])
            return None
        ports, pure, extra, binding = bound.ports, bound.pure, bound.key, bound.plan
        deps.update(bound.deps)
    elif cls.dynamic_ports() and params is not None:
        try:
            ports = cls.ports(params)
            check_ports(f"node {node.id!r} ({node.type})", ports)
        except Exception as exc:
            issues.append(Issue("invalid-param", ("nodes", node.id, "params"), f"node {node.id!r}: {exc}"))
            return None
    else:
        ports = Ports(cls.inputs, cls.outputs)
    inputs = {p.name: p for p in ports.inputs + cls.param_ports()}
    outputs = {p.name: p for p in ports.outputs}
    params_json = params.model_dump_json() if params is not None else json.dumps(node.params, sort_keys=True, default=str)
    static = static_key(cls.type_id, cls.version, params_json, extra)
    moves = bool(cls.moves or (binding is not None and getattr(binding, "moves", False)))
    return BoundNode(node.id, cls, node.params, params, inputs, outputs, pure, static, binding, moves=moves)


def _validate_params(node: Node, cls: type[NodeType], fed_ports: set[str]) -> tuple[BaseModel | None, list[Issue]]:
    """Validated params, or None with the issues. Errors on params fed by a wire are left to run time."""
    limit = budget.cap("rows")
    for name, value in node.params.items():
        if isinstance(value, list) and len(value) > limit:  # refused before pydantic builds a model per item
            return None, [Issue("budget", ("nodes", node.id, "params", name),
                                f"node {node.id!r}: param {name!r} has {len(value):,} items, over the budget of "
                                f"{limit:,}: split it over several nodes, keep long programs in G-code files, "
                                "or raise the memory budget (flowmc run --memory-mb, FLOWMC_MEMORY_MB)")]
    try:
        return cls.Params.model_validate(node.params), []
    except ValidationError as exc:
        errors = exc.errors()
    known = ", ".join(cls.Params.model_fields) or "none"
    issues = []
    for err in errors:
        loc = tuple(err["loc"])
        name = ".".join(str(p) for p in loc) or "(params)"
        if err["type"] == "extra_forbidden":
            issues.append(Issue("unknown-param", ("nodes", node.id, "params", *loc),
                                f"node {node.id!r}: unknown param {name!r} ({cls.type_id} params: {known})"))
        elif not (len(loc) == 1 and loc[0] in fed_ports):
            issues.append(Issue("invalid-param", ("nodes", node.id, "params", *loc),
                                f"node {node.id!r}: param {name!r}: {err['msg']}"))
    return None, issues


# ---------------------------------------------------------------- wires

def _wire_text(src: str, dst: str) -> str:
    return f"wire {src} -> {dst}"


def _check_wires(graph: Graph, nodes: dict[str, Node], bound: dict[str, BoundNode], issues: list[Issue]):
    """Check each wire; returns the graph edges and ``{(node, input): wire text}``."""
    edges = []
    fed_by: dict[tuple[str, str], str] = {}
    for i, wire in enumerate(graph.wires):
        (s_node, s_port), (d_node, d_port) = split_ref(wire.from_), split_ref(wire.to)
        text = _wire_text(wire.from_, wire.to)
        ok = True
        for end, node_id in (("from", s_node), ("to", d_node)):
            if node_id not in nodes:
                issues.append(Issue("unknown-node", ("wires", i, end), f"{text}: no node {node_id!r}"))
                ok = False
        if not ok:
            continue
        edges.append((s_node, d_node))
        src, dst = bound.get(s_node), bound.get(d_node)
        out = src.outputs.get(s_port) if src else None
        inp = dst.inputs.get(d_port) if dst else None
        if src is not None and out is None:
            issues.append(Issue("unknown-port", ("wires", i, "from"),
                                f"{text}: node {s_node!r} has no output {s_port!r} "
                                f"(outputs: {', '.join(src.outputs) or 'none'})"))
        if dst is not None and inp is None:
            issues.append(Issue("unknown-port", ("wires", i, "to"),
                                f"{text}: node {d_node!r} has no input {d_port!r} (inputs: {', '.join(dst.inputs) or 'none'})"))
        if inp is None:
            continue
        previous = fed_by.get((d_node, d_port))
        if previous is not None:
            issues.append(Issue("input-wired-twice", ("wires", i, "to"),
                                f"{text}: node {d_node!r} input {d_port!r} is already fed by {previous}"))
            continue
        fed_by[(d_node, d_port)] = text
        if out is None:
            continue
        if not inp.accepts(out.type):
            issues.append(Issue("broken-wire", ("wires", i),
                                f"{text}: node {s_node!r} output {s_port!r} is {out.type} but node {d_node!r} "
                                f"input {d_port!r} takes {' or '.join(inp.types)}"))
            continue
        if dst is not None:
            dst.sources[d_port] = (s_node, s_port)
    return edges, fed_by


def _check_interface(graph: Graph, nodes: dict[str, Node], bound: dict[str, BoundNode], fed_by: dict, issues: list[Issue]):
    iface_in: dict[str, tuple[Any, list[tuple[str, str]]]] = {}
    iface_out: dict[str, tuple[Any, tuple[str, str]]] = {}
    if graph.interface is None:
        return iface_in, iface_out
    for item in graph.interface.inputs:
        loc = ("interface", "inputs", item.name)
        if item.name in iface_in:
            issues.append(Issue("interface-duplicate", loc, f"interface input {item.name!r} is declared twice"))
            continue
        if item.default is not None and (item.type not in SCALAR_PORT_TYPES or not value_matches(item.type, item.default)):
            issues.append(Issue("interface-type", (*loc, "default"),
                                f"interface input {item.name!r}: default {item.default!r} is not a {item.type} "
                                "(defaults are Number, Bool or Text)"))
        targets = []
        for k, ref in enumerate(item.to):
            node_id, port = split_ref(ref)
            where = f"interface input {item.name!r} -> {ref}"
            inp = _interface_port(node_id, port, "input", nodes, bound, issues, (*loc, "to", k), where)
            if inp is None:
                continue
            node = bound[node_id]
            if (node_id, port) in fed_by or port in node.fed:
                issues.append(Issue("input-wired-twice", (*loc, "to", k),
                                    f"{where}: node {node_id!r} input {port!r} is already fed"))
            elif not inp.accepts(item.type):
                issues.append(Issue("interface-type", (*loc, "to", k),
                                    f"{where}: interface type {item.type} but node {node_id!r} input {port!r} "
                                    f"takes {' or '.join(inp.types)}"))
            else:
                node.fed[port] = item.name
                targets.append((node_id, port))
        iface_in[item.name] = (item, targets)
    for out_item in graph.interface.outputs:
        loc = ("interface", "outputs", out_item.name)
        if out_item.name in iface_out:
            issues.append(Issue("interface-duplicate", loc, f"interface output {out_item.name!r} is declared twice"))
            continue
        node_id, port = split_ref(out_item.from_)
        where = f"interface output {out_item.name!r} <- {out_item.from_}"
        out = _interface_port(node_id, port, "output", nodes, bound, issues, (*loc, "from"), where)
        if out is None:
            continue
        if out.type != out_item.type:
            issues.append(Issue("interface-type", (*loc, "from"),
                                f"{where}: interface type {out_item.type} but node {node_id!r} output {port!r} is {out.type}"))
            continue
        iface_out[out_item.name] = (out_item, (node_id, port))
    return iface_in, iface_out


def _interface_port(node_id, port, kind, nodes, bound, issues, loc, where):
    if node_id not in nodes:
        issues.append(Issue("interface-port", loc, f"{where}: no node {node_id!r}"))
        return None
    node = bound.get(node_id)
    if node is None:
        return None  # its own problem is reported already
    ports = node.inputs if kind == "input" else node.outputs
    if port not in ports:
        issues.append(Issue("interface-port", loc,
                            f"{where}: node {node_id!r} has no {kind} {port!r} ({kind}s: {', '.join(ports) or 'none'})"))
        return None
    return ports[port]


def _check_required(bound: dict[str, BoundNode], targets: dict[str, set[str]], issues: list[Issue]) -> None:
    for node in bound.values():
        fed = targets.get(node.id, ())
        for name, port in node.inputs.items():
            if port.required and not port.param and name not in fed:
                issues.append(Issue("missing-input", ("nodes", node.id, "inputs", name),
                                    f"node {node.id!r}: required input {name!r} ({' or '.join(port.types)}) is not wired"))
