"""Settings given from outside a graph file: ``NODE.PARAM=VALUE`` changes a stored param, ``NAME=VALUE``
gives an interface input. Text is typed by the type the param or input declares.

``flowmc run --set/--input`` and every sweep axis use these rules, so a sweep variant means exactly
what ``flowmc run`` with the same settings means.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any

from flowmc.errors import GraphError, UsageError

__all__ = ["UsageError", "Target", "parse_value", "target", "param_target", "input_target"]


def parse_value(port_type: str | None, text: str, what: str) -> Any:
    """Turn command-line text into a value for a port type (None: a param that is not scalar, read as
    JSON, else the text).

    >>> parse_value("Number", "3", "--input n"), parse_value("Number", "2.5", "--input n")
    (3, 2.5)
    >>> parse_value("Bool", "on", "--input b"), parse_value(None, "[1, 2]", "--input v")
    (True, [1, 2])
    >>> parse_value("Path", "x", "--input p")
    Traceback (most recent call last):
    ...
    flowmc.errors.UsageError: --input p: a Path cannot be given on the command line
    """
    if port_type == "Text":
        return text
    if port_type == "Number":
        try:
            value = float(text)
        except ValueError:
            raise UsageError(f"{what}: {text!r} is not a number") from None
        if not math.isfinite(value):
            raise UsageError(f"{what}: {text!r} is not a finite number")
        return int(value) if value.is_integer() and "." not in text and "e" not in text.lower() else value
    if port_type == "Bool":
        lowered = text.strip().lower()
        if lowered in ("true", "1", "yes", "on"):
            return True
        if lowered in ("false", "0", "no", "off"):
            return False
        raise UsageError(f"{what}: {text!r} is not true or false")
    if port_type is not None:
        raise UsageError(f"{what}: a {port_type} cannot be given on the command line")
    try:
        value = json.loads(text)
    except json.JSONDecodeError:
        return text
    if not _finite(value):
        raise UsageError(f"{what}: {text!r} holds a number that is not finite (NaN, Infinity, or too large)")
    return value


def _finite(value: Any) -> bool:
    if isinstance(value, float):
        return math.isfinite(value)
    if isinstance(value, list):
        return all(_finite(v) for v in value)
    if isinstance(value, dict):
        return all(_finite(v) for v in value.values())
    return True


@dataclass(frozen=True)
class Target:
    """Where a setting goes: a stored param (``node`` and ``param``) or an interface input (``node`` None)."""

    name: str
    port_type: str | None
    node: str | None = None
    param: str = ""

    def parse(self, text: str, what: str | None = None) -> Any:
        return parse_value(self.port_type, text, what or self.name)

    def apply(self, graph: Any, value: Any, inputs: dict[str, Any]) -> None:
        """Set ``value`` in ``graph`` (a stored param) or in ``inputs`` (an interface input)."""
        if self.node is None:
            inputs[self.name] = value
        else:
            graph.node(self.node).params[self.param] = value


def param_target(graph: Any, name: str, what: str, registry: Any) -> Target:
    """``NODE.PARAM``: a stored param of a node (its type looked up in ``registry``); unknown nodes or
    params, and params that a wire or an interface input feeds (the stored value would be ignored), are errors."""
    node_id, dot, param = name.partition(".")
    if not dot or not param:
        raise UsageError(f"{what}: expected NODE.PARAM")
    node = next((n for n in graph.nodes if n.id == node_id), None)
    if node is None:
        raise UsageError(f"{what}: no node {node_id!r} (nodes: {', '.join(sorted(n.id for n in graph.nodes))})")
    try:
        cls = registry.lookup(node.type, graph.base_dir)
    except GraphError:
        raise UsageError(f"{what}: node {node_id!r} has unknown type {node.type!r}") from None
    fields = cls.Params.model_fields
    if param not in fields:
        raise UsageError(f"{what}: node {node_id!r} ({node.type}) has no param {param!r} "
                         f"(params: {', '.join(fields) or 'none'})")
    feeding = next((w.from_ for w in graph.wires if w.to == name), None)
    if feeding is not None:
        raise UsageError(f"{what}: that param is fed by the wire from {feeding}; the stored value is not used")
    for inp in graph.interface.inputs if graph.interface else ():
        if name in inp.to:
            raise UsageError(f"{what}: that param is fed by the graph input {inp.name!r}; set {inp.name} instead")
    return Target(name, cls.param_type(param), node_id, param)


def input_target(graph: Any, name: str, what: str) -> Target:
    """``NAME``: an interface input of the graph."""
    declared = {i.name: i.type for i in graph.interface.inputs} if graph.interface else {}
    if name not in declared:
        raise UsageError(f"{what}: the graph has no input {name!r} (inputs: {', '.join(declared) or 'none'})")
    return Target(name, declared[name])


def target(graph: Any, name: str, what: str, registry: Any) -> Target:
    """``NODE.PARAM`` (a dot: a stored param) or ``NAME`` (an interface input)."""
    name = name.strip()
    return param_target(graph, name, what, registry) if "." in name else input_target(graph, name, what)
