"""Sub-graphs, as LabVIEW sub-VIs: a graph file with an ``interface`` used as one node.

Two ways in: the ``subgraph`` type with a ``file`` param (relative to the using graph's
folder, never leaving the root folder), and library types ``lib.<stem>`` for the graphs in
the library folders a ``GraphLibrary`` is given and in a ``lib/`` folder beside the graph
(which wins on a clash). Both bind through the runtime's ``GraphBinder`` protocol.
A graph that uses itself, directly or through others, is refused with the chain named.
Nothing is imported or executed from a file: a sub-graph is only more nodes of known types.
"""

from __future__ import annotations

import hashlib
from dataclasses import replace
from pathlib import Path
from typing import Any, Callable, Iterable

from pydantic import BaseModel, ConfigDict, Field, create_model

import flowmc.budget as budget
from flowmc.errors import FlowmcError, GraphError, NodeError
from flowmc.fileio import fingerprint, read_text
from flowmc.graph import Graph, Issue, dumps, loads
from flowmc.ports import REQUIRED, In, Out, Ports
from flowmc.registry import NodeType, NoParams, Registry, register
from flowmc.runtime.binding import BindContext, Binding
from flowmc.runtime.context import Site, resolve_inside
from flowmc.runtime.schedule import Plan, make_plan

__all__ = ["Subgraph", "LibraryGraph", "GraphLibrary", "interface_ports"]

SUFFIX = ".flowmc.json"


def interface_ports(graph: Graph, plan: Plan | None = None) -> Ports:
    """Ports of a graph used as a node. An input with no default is required only when it
    feeds a required data input inside; otherwise leaving it unwired keeps the inner values."""
    if graph.interface is None:
        return Ports((), ())
    inputs = []
    for item in graph.interface.inputs:
        default: Any = item.default
        if default is None and plan is not None:
            targets = plan.iface_inputs.get(item.name, (None, []))[1]
            needed = any(plan.nodes[n].inputs[p].required and not plan.nodes[n].inputs[p].param for n, p in targets)
            default = REQUIRED if needed else None
        inputs.append(In(item.name, item.type, doc=item.description, default=default))
    outputs = tuple(Out(item.name, item.type, doc=item.description) for item in graph.interface.outputs)
    return Ports(tuple(inputs), outputs)


def _read(path: Path) -> tuple[Graph, str]:
    """The graph at ``path`` and a hash of the file's content (what tells a changed file)."""
    text = read_text(path, limit=budget.cap("json_bytes"), what="graph file", error=GraphError)
    graph = loads(text, where=str(path))
    graph.path = path
    return graph, hashlib.blake2b(text.encode("utf-8", "surrogatepass"), digest_size=16).hexdigest()


def bind_file(path: Path, site: Site, node_id: str, plan_graph: Callable[[Graph, Site], Plan],
              memo: dict[Any, Any] | None = None) -> Binding:
    """Load, check and plan the sub-graph at ``path`` (already inside the root). GraphError with issues.
    ``memo`` (one planning pass) holds what each file came to, so a file used many times, however
    deep, is read and planned once: fan-out stays linear."""
    loc = ("nodes", node_id, "params", "file")
    shown = site.name(path)

    def fail(code: str, message: str) -> GraphError:
        return GraphError(message, issues=[Issue(code, loc, f"node {node_id!r}: {message}")])

    if path in site.chain:
        names = " -> ".join(site.name(p) for p in site.chain + (path,))
        raise fail("subgraph-recursion", f"sub-graph recursion: {names}")
    try:  # each level is a few stack frames: a chain of hundreds would exhaust Python's stack
        budget.check("depth", len(site.chain) + 1, what="sub-graphs nested in sub-graphs",
                     change="use fewer levels of sub-graphs")
    except FlowmcError as exc:
        raise fail("budget", str(exc)) from None
    key = _memo_key(path, site.root)
    outcome = memo.get(key) if memo is not None else None
    if outcome is None:
        outcome = _bind_outcome(path, site, shown, plan_graph)
        if memo is not None:
            memo[key] = outcome
    if isinstance(outcome, tuple):  # (code, message) or (code, [issue messages])
        code, detail = outcome
        if isinstance(detail, str):
            raise fail(code, detail)
        issues = [Issue(c, loc, _nested(f"node {node_id!r}: sub-graph {shown}: {m}")) for c, m in detail]
        raise GraphError(issues[0].message, issues=issues)
    return outcome


def _memo_key(path: Path, root: Path) -> tuple[str, Path, Path]:
    """What a file bound under ``root`` came to, in a planning pass's memo."""
    return ("subgraph", path, root)


def _nested(message: str, keep: int = 600) -> str:
    """A message from deep inside nested sub-graphs, its middle cut: each level adds its name."""
    return message if len(message) <= keep else f"{message[: keep // 2]} ... {message[-keep // 2:]}"


def _bind_outcome(path: Path, site: Site, shown: str, plan_graph: Callable[[Graph, Site], Plan],
                  read: tuple[Graph, str] | None = None) -> Any:
    """The Binding of the file at ``path`` (``read``: the file as ``_read`` gave it already), or why it
    cannot be bound (not yet naming the node)."""
    try:
        graph, digest = read or _read(path)
    except GraphError as exc:
        detail = "; ".join(i.message for i in exc.issues) if exc.issues else exc.message
        return ("subgraph", f"sub-graph {shown}: {detail}")
    if graph.interface is None:
        return ("subgraph", f"sub-graph {shown} declares no interface, so it cannot be used as a node")
    plan = plan_graph(graph, Site(path.parent, site.root, site.chain + (path,)))
    if plan.issues:
        return ("subgraph", [(i.code if i.code in ("subgraph-recursion", "budget") else "subgraph", i.message)
                             for i in plan.issues])
    h = hashlib.blake2b(dumps(graph).encode(), digest_size=16)
    for node_id_inner in plan.order:
        h.update(plan.nodes[node_id_inner].static)
    deps = {path: digest, **plan.deps}
    return Binding(interface_ports(graph, plan), plan.pure, h.hexdigest(), plan, deps)


def _run_bound(ctx: Any, inputs: dict[str, Any], name: str) -> dict[str, Any]:
    given = {k: v for k, v in inputs.items() if v is not None}
    result = ctx.child_runtime().run(ctx.binding, given)
    if not result.ok:
        raise NodeError("; ".join(result.errors), where=f"sub-graph {name}")
    return dict(result.outputs)


def _prepare_bound(ctx: Any, inputs: dict[str, Any], name: str) -> Any:
    """A sub-graph that drives a device: its prepared run (its device nodes ready) is the node's job."""
    given = {k: v for k, v in inputs.items() if v is not None}
    result = ctx.child_runtime().run(ctx.binding, given)
    if not result.ok:
        raise NodeError("; ".join(result.errors), where=f"sub-graph {name}")
    return result


def _start_bound(ctx: Any, job: Any, name: str) -> dict[str, Any]:
    result = ctx.child_runtime().start(job, ctx.start.within(ctx.node_id))
    if not result.ok:
        raise NodeError("; ".join(result.errors), where=f"sub-graph {name}")
    return dict(result.outputs)


class SubgraphParams(BaseModel):
    model_config = ConfigDict(extra="forbid", defer_build=True)
    file: str = Field(description="Graph file with an interface, relative to this graph's folder")


@register
class Subgraph(NodeType):
    type_id = "subgraph"
    title = "Sub-graph"
    category = "Graph"
    description = "Run a saved graph that declares an interface as one node; its ports are that interface."
    Params = SubgraphParams
    fixed_params = ("file",)

    @classmethod
    def bind_graph(cls, params: SubgraphParams, at: BindContext) -> Binding:
        try:
            path = resolve_inside(at.site.root, at.site.graph_dir, params.file)
        except GraphError as exc:
            issue = Issue("path-escape", ("nodes", at.node_id, "params", "file"), f"node {at.node_id!r}: file {exc.message}")
            raise GraphError(issue.message, issues=[issue]) from None
        return bind_file(path, at.site, at.node_id, at.plan, at.memo)

    def run(self, ctx: Any, params: SubgraphParams, **inputs: Any) -> dict[str, Any]:
        return _run_bound(ctx, inputs, params.file)

    def prepare(self, ctx: Any, params: SubgraphParams, **inputs: Any) -> Any:
        return _prepare_bound(ctx, inputs, params.file)

    def start(self, ctx: Any, job: Any) -> dict[str, Any]:
        return _start_bound(ctx, job, ctx.node_id)


class LibraryGraph(NodeType):
    """Base of the generated ``lib.<stem>`` types; ``file_path`` and ``lib_dir`` are set per type.

    Scalar interface inputs (Number, Bool, Text) are params of the node, as constants on a LabVIEW
    sub-VI's terminals are: stored in the graph file, editable in the inspector, and (like every
    scalar param) fed by a wire when one is connected. Other inputs are data ports.
    """

    category = "Library"
    Params = NoParams
    file_path: Path
    lib_dir: Path
    outcome: Any = None  # what binding the file came to when the type was built (its ports come from it)

    @classmethod
    def bind_graph(cls, params: BaseModel, at: BindContext) -> Binding:
        if cls.outcome is not None:  # the type is rebuilt when the file or the registry changes: still valid
            at.memo.setdefault(_memo_key(cls.file_path, cls.lib_dir), cls.outcome)
        binding = bind_file(cls.file_path, Site(cls.lib_dir, cls.lib_dir, at.site.chain), at.node_id, at.plan, at.memo)
        data = tuple(p for p in binding.ports.inputs if p.name not in cls.Params.model_fields)
        return replace(binding, ports=Ports(data, binding.ports.outputs))

    def run(self, ctx: Any, params: BaseModel, **inputs: Any) -> dict[str, Any]:
        return _run_bound(ctx, {**params.model_dump(), **inputs}, self.type_id)

    def prepare(self, ctx: Any, params: BaseModel, **inputs: Any) -> Any:
        return _prepare_bound(ctx, {**params.model_dump(), **inputs}, self.type_id)

    def start(self, ctx: Any, job: Any) -> dict[str, Any]:
        return _start_bound(ctx, job, self.type_id)


_SCALAR_TYPES = {"Number": float, "Bool": bool, "Text": str}


def _split_scalars(ports: Ports, stem: str) -> tuple[type[BaseModel], Ports]:
    """Scalar inputs become an optional-field params model; the rest stay data ports."""
    fields: dict[str, Any] = {
        p.name: (_SCALAR_TYPES[p.type] | None, Field(None if p.default is REQUIRED else p.default, description=p.doc))
        for p in ports.inputs if isinstance(p.type, str) and p.type in _SCALAR_TYPES
    }
    params = create_model(f"Lib_{stem}_Params", __config__=ConfigDict(extra="forbid"), **fields)
    data = tuple(p for p in ports.inputs if p.name not in fields)
    return params, Ports(data, ports.outputs)


# ---------------------------------------------------------------- library folders

def _others_unchanged(cls: type[LibraryGraph]) -> bool:
    """Whether the other files a library type's graph bound (sub-graphs, library graphs it uses) are as
    they were when the type was built: its ports and its binding came from them."""
    deps = cls.outcome.deps if cls.outcome is not None else {}
    return all(fingerprint(dep) == digest for dep, digest in deps.items() if dep != cls.file_path)


class GraphLibrary:
    """``lib.<stem>`` types for the graph files in ``folders`` and in a ``lib/`` beside the graph.

    A registry is given one (``Registry(library=GraphLibrary([...]))``) and asks it for
    ``lib.*`` ids; types are built from the files on demand and rebuilt when a file changes.
    """

    def __init__(self, folders: Iterable[Path] = ()) -> None:
        self.folders = [Path(f).resolve() for f in folders]
        self._cache: dict[Path, tuple[int, str | None, type[LibraryGraph]]] = {}  # path -> (generation, content hash, type)
        self._building: set[Path] = set()

    def _dirs(self, graph_dir: Path | None) -> list[Path]:
        """Library folders seen from a graph: ``lib/`` beside it, its own folder when that is a
        ``lib/`` (library graphs use their siblings), then the given folders."""
        dirs: list[Path] = []
        if graph_dir is not None:
            here = Path(graph_dir).resolve()
            for candidate in (here / "lib", here if here.name == "lib" else None):
                if candidate is not None and candidate.is_dir() and candidate not in dirs:
                    dirs.append(candidate)
        dirs += [f for f in self.folders if f.is_dir() and f not in dirs]
        return dirs

    def _class(self, path: Path, lib_dir: Path, registry: Registry) -> type[LibraryGraph]:
        """The ``lib.<stem>`` type for a file, rebuilt when the file or the registry changes."""
        stat = fingerprint(path, budget.cap("json_bytes"))
        cached = self._cache.get(path)
        if cached is not None and cached[:2] == (registry.generation, stat) and _others_unchanged(cached[2]):
            return cached[2]
        stem = path.name[: -len(SUFFIX)]
        title, description, ports = stem, f"Library graph {stem}", Ports((), ())
        params: type[BaseModel] = NoParams
        outcome = None
        building = path in self._building  # library graphs using each other: binding reports the recursion
        self._building.add(path)
        try:
            read = _read(path)
            title = read[0].title or stem
            description = (read[0].description.strip().splitlines() or [description])[0]
            if not building:  # the file is read and planned once: the first use binds from this outcome
                plan_graph = lambda g, s: make_plan(g, s, registry)  # noqa: E731
                outcome = _bind_outcome(path, Site(lib_dir, lib_dir), path.name, plan_graph, read)
                memo = {_memo_key(path, lib_dir): outcome}
                params, ports = _split_scalars(bind_file(path, Site(lib_dir, lib_dir), "lib", plan_graph, memo).ports,
                                               stem)
        except GraphError:
            pass  # described without ports; using it reports the problem on the node
        finally:
            if not building:
                self._building.discard(path)
        attrs = {"type_id": f"lib.{stem}", "title": title, "description": description, "Params": params,
                 "inputs": ports.inputs, "outputs": ports.outputs, "file_path": path, "lib_dir": lib_dir,
                 "outcome": outcome if isinstance(outcome, Binding) else None, "__module__": __name__}
        cls = type(f"Lib_{stem}", (LibraryGraph,), attrs)
        if not building:
            self._cache[path] = (registry.generation, stat, cls)
        return cls

    def lookup(self, type_id: str, graph_dir: Path | None, registry: Registry) -> type[LibraryGraph] | None:
        """The type for ``lib.<stem>``: ``<graph_dir>/lib`` first, then the library folders."""
        stem = type_id[len("lib."):]
        if not stem or "/" in stem or "\\" in stem or stem.startswith("."):
            return None
        for lib_dir in self._dirs(graph_dir):
            if (lib_dir / f"{stem}{SUFFIX}").is_file():
                try:  # a symlink out of the library folder is not a library graph
                    return self._class(resolve_inside(lib_dir, lib_dir, f"{stem}{SUFFIX}"), lib_dir, registry)
                except GraphError:
                    return None
        return None

    def types(self, graph_dir: Path | None, registry: Registry) -> dict[str, type[NodeType]]:
        found: dict[str, type[NodeType]] = {}
        for lib_dir in reversed(self._dirs(graph_dir)):  # the local lib/ overrides the package one
            for path in sorted(lib_dir.glob(f"*{SUFFIX}")):
                if not path.resolve().is_relative_to(lib_dir):
                    continue
                cls = self._class(path.resolve(), lib_dir, registry)
                found[cls.type_id] = cls
        return dict(sorted(found.items()))
