"""The protocol for node types that hold a graph: sub-graphs (a file) and structures (bodies).

Such a type binds its graph when the outer graph is planned: it loads and plans it (with the
``plan`` function it is handed, so the same registry and checks apply) and returns a
``Binding``: its ports, purity, a cache-key part and the inner plan. At run time the node finds
that plan as ``ctx.binding`` and runs it on ``ctx.child_runtime()``, or, for a body it runs again
and again, with ``ctx.run_body`` (``flowmc.runtime.iterations``: cached by content, announced as
iteration events). Structures (``holds_bodies = True``) find the graphs a node holds in the file
in ``at.bodies``; a node of any other type that holds bodies is refused. The runtime knows only
this protocol, never the classes that implement it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, Protocol, runtime_checkable

from flowmc.ports import Ports
from flowmc.runtime.context import Site

__all__ = ["Binding", "BindContext", "GraphBinder", "binder_of", "holds_bodies"]


@dataclass(frozen=True)
class Binding:
    """A held graph bound at one place: its ports, purity, cache-key part and inner plan."""

    ports: Ports
    pure: bool
    key: str  # content of the bound graph (and of what it binds): part of the node's cache key
    plan: Any  # the inner Plan, handed to the node at run time as ctx.binding
    deps: dict[Path, str | None]  # files read and a hash of their content: re-plan when one changes


@dataclass(frozen=True)
class BindContext:
    """Where a node binds: the outer graph's site, the node's id, and how to plan a graph."""

    site: Site
    node_id: str
    plan: Callable[[Any, Site], Any]  # plan(graph, site) -> Plan, with the outer plan's registry
    memo: dict[Any, Any] = field(default_factory=dict)  # one planning pass's shared work (a file bound once)
    bodies: Mapping[str, Any] = field(default_factory=dict)  # structures: the node's bodies as Graphs, by name


@runtime_checkable
class GraphBinder(Protocol):
    """A node type whose ports come from a graph it binds at plan time (raises GraphError with issues)."""

    @classmethod
    def bind_graph(cls, params: Any, at: BindContext) -> Binding: ...


def binder_of(cls: type) -> type[GraphBinder] | None:
    """``cls`` when it implements the protocol, else None."""
    return cls if callable(getattr(cls, "bind_graph", None)) else None


def holds_bodies(cls: type) -> bool:
    """True for structure types: binders whose graphs are the bodies a node holds in the file."""
    return binder_of(cls) is not None and getattr(cls, "holds_bodies", False) is True
