"""The Runtime: plans graphs (once per revision), runs them in order, caches pure nodes.

A failing node (FlowmcError or any exception) is reported by message; its downstream
nodes are skipped; independent branches still run. Nothing here prints.

Device nodes run in two phases (``runtime.start``): a run prepares their jobs and never moves
anything; ``Runtime.start`` (or ``run(..., start=...)``) is the explicit Start that does.
"""

from __future__ import annotations

import hashlib
import os
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from pydantic import ValidationError

from flowmc.digest import Undigestable, digest
from flowmc.errors import FlowmcError, GraphError, printable
from flowmc.fileio import fingerprint
from flowmc.graph import Graph, Issue, load
from flowmc.registry import Registry
from flowmc.runtime.cache import CacheEntry, IterationCache, NodeCache, signature
from flowmc.runtime.context import NodeContext, Site, files_read, resolve_inside
from flowmc.runtime.events import Event, EventBus, Listener
from flowmc.runtime.schedule import Plan, make_plan
from flowmc.runtime.start import PREPARED, Start, job_digest
from flowmc.runtime.validate import BoundNode, value_matches

__all__ = ["Runtime", "RunResult", "NodeResult", "summarize", "value_matches"]

_MAX_PLANS = 16


@dataclass
class NodeResult:
    """``status``: done (ran), cached (reused), failed, skipped (an upstream node failed); for device
    nodes before Start: ready (``job`` prepared), stale (prepared, and not the job last started for this
    node); waiting (needs what a device node makes: it runs at Start)."""

    node_id: str
    status: str
    duration: float = 0.0
    outputs: dict[str, Any] = field(default_factory=dict)
    error: str | None = None
    logs: list[str] = field(default_factory=list)
    job: Any = None


@dataclass
class RunResult:
    nodes: dict[str, NodeResult]
    outputs: dict[str, Any]  # the graph's interface outputs (those produced)
    events: list[Event]
    order: list[str]
    run: Any = field(default=None, repr=False, compare=False)  # the run, to carry on at Start

    @property
    def ok(self) -> bool:
        return all(r.status in ("done", "cached", *PREPARED) for r in self.nodes.values())

    @property
    def jobs(self) -> dict[str, Any]:
        """Prepared jobs by node id (ready or stale device nodes): what Start would run."""
        return {n: self.nodes[n].job for n in self.order if self.nodes[n].status in ("ready", "stale")}

    @property
    def started(self) -> bool:
        return self.run is not None and self.run.start is not None

    def digest(self) -> str:
        """The jobs as they were prepared (a sub-graph's prepared run is its node's job)."""
        h = hashlib.blake2b(digest_size=16)
        for node_id, job in (self.run.prepared if self.run is not None else self.jobs).items():
            h.update(f"{node_id}={job_digest(job)};".encode())
        return h.hexdigest()

    def summary_of_jobs(self) -> dict[str, Any]:
        return {n: summarize(job) for n, job in self.jobs.items()}

    def values_of(self, *port_types: str) -> list[tuple[str, str, Any]]:
        """(node id, output, value) of every value produced on outputs of these port types, in run order
        (``Plan.outputs_of``): e.g. the last Path a graph made is ``result.values_of("Path")[-1]``."""
        plan = self.run.plan
        return [(node_id, name, self.nodes[node_id].outputs[name]) for node_id, name in plan.outputs_of(*port_types)
                if node_id in self.nodes and name in self.nodes[node_id].outputs]

    @property
    def errors(self) -> list[str]:
        return [r.error for r in self.nodes.values() if r.status == "failed" and r.error]

    @property
    def executed(self) -> list[str]:
        return [n for n in self.order if self.nodes[n].status in ("done", "failed")]

    @property
    def cached(self) -> list[str]:
        return [n for n in self.order if self.nodes[n].status == "cached"]

    def output(self, node_id: str, port: str) -> Any:
        return self.nodes[node_id].outputs[port]

    def summary(self) -> dict[str, Any]:
        """JSON-able: per-node status, duration and output summaries, interface outputs."""
        return {
            "ok": self.ok,
            "errors": self.errors,
            "nodes": {
                n: {
                    "status": r.status,
                    "duration_s": round(r.duration, 6),
                    **({"error": r.error} if r.error else {}),
                    **({"logs": r.logs} if r.logs else {}),
                    **({"job": summarize(r.job)} if r.job is not None and r.status in ("ready", "stale") else {}),
                    "outputs": {k: summarize(v) for k, v in r.outputs.items()},
                }
                for n, r in ((n, self.nodes[n]) for n in self.order)
            },
            "outputs": {k: summarize(v) for k, v in self.outputs.items()},
        }


def summarize(value: Any) -> Any:
    """``value.summary()`` when it has one, plain scalars as they are, else the type name."""
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    np = sys.modules.get("numpy")  # no numpy value without numpy imported; `flowmc validate` imports none
    if np is not None and isinstance(value, np.generic):
        return value.item()
    if callable(getattr(value, "summary", None)):
        return value.summary()
    if isinstance(value, (list, tuple)) and len(value) <= 20 and all(isinstance(v, (bool, int, float, str)) for v in value):
        return list(value)
    return {"type": type(value).__name__}


class Runtime:
    """Runs graphs with the node types of ``registry``; owns an output cache, an event bus and
    the child runtimes of nodes that hold graphs (sub-graphs).

    Runs from several threads (editor callbacks) take turns; planning has its own lock, so a
    graph can be validated while another runs. Listeners run on the thread that runs.
    ``flowmc.Runtime()`` is this class with the default registry (``flowmc.plugins``)."""

    def __init__(self, registry: Registry) -> None:
        self.registry = registry
        self._plan_lock = threading.RLock()
        self._run_lock = threading.RLock()
        self.events = EventBus()
        self.cache = NodeCache()
        self._plans: dict[tuple, Plan] = {}
        self._children: dict[str, Runtime] = {}
        self._started: dict[str, str] = {}  # node id -> digest of the job last started for it
        self.iterations = IterationCache()  # a structure's child runtime: its body's runs by content
        self.last_result: RunResult | None = None  # a sub-graph's child runtime keeps its inner run (views, probes)

    def subscribe(self, listener: Listener) -> Callable[[], None]:
        """Call ``listener(event)`` for every event of every run; returns an unsubscribe function."""
        return self.events.subscribe(listener)

    def clear_cache(self) -> None:
        with self._run_lock:
            self.cache.clear()
            self.iterations.clear()
            self._children.clear()

    def child(self, key: str) -> "Runtime":
        runtime = self._children.get(key)
        if runtime is None:
            runtime = self._children[key] = Runtime(self.registry)
        return runtime

    # ------------------------------------------------------------ planning

    def plan(self, graph: Graph, *, base_dir: str | os.PathLike | None = None) -> Plan:
        """Validate and schedule; reused while the graph (positions aside), the registry and
        the sub-graph files it reads are unchanged. Check ``plan.issues``."""
        site = Site.for_graph(Path(base_dir) if base_dir is not None else graph.base_dir, graph.path)
        key = (graph.fingerprint_json(), site, self.registry.generation)
        with self._plan_lock:
            plan = self._plans.get(key)
            if plan is not None and plan.deps_unchanged():
                return plan
            frozen = graph.model_copy(deep=True)  # the plan must not change when the caller edits the graph
            frozen.path = graph.path
            plan = make_plan(frozen, site, self.registry)
            if plan.ok:  # invalid plans are redone: a missing file or library graph may appear
                if len(self._plans) >= _MAX_PLANS:
                    self._plans.pop(next(iter(self._plans)))
                self._plans[key] = plan
            return plan

    def validate(self, graph: Graph, *, base_dir: str | os.PathLike | None = None) -> list[Issue]:
        return list(self.plan(graph, base_dir=base_dir).issues)

    # ------------------------------------------------------------ running

    def run(self, graph: Graph | Plan | str | os.PathLike, inputs: dict[str, Any] | None = None, *,
            base_dir: str | os.PathLike | None = None, start: Start | bool | None = None) -> RunResult:
        """Run the whole graph; device nodes only prepare their jobs (nothing moves) unless ``start`` is
        given (True or a ``Start``): then this is the explicit Start as well. Raises GraphError
        (``.issues``) when the graph is invalid or an input is wrong; node failures are reported in the
        result (``result.ok`` is False), not raised."""
        if isinstance(graph, (str, os.PathLike)):
            graph = load(graph)
        with self._run_lock:
            plan = graph if isinstance(graph, Plan) else self.plan(graph, base_dir=base_dir)
            where = plan.graph.where
            if not plan.ok:
                raise GraphError(_count(plan.issues, "problem"), where=where, issues=plan.issues)
            fed, issues = _interface_values(plan, inputs or {})
            if issues:
                raise GraphError(_count(issues, "problem") + " with the inputs", where=where, issues=issues)
            prepared = self.last_result = _Run(self, plan, fed).execute()
        return self.start(prepared, start) if start else prepared

    def start(self, prepared: RunResult, start: Start | bool = True) -> RunResult:
        """The explicit Start: hand each prepared job (in graph order) to its node's ``start``, then run
        the nodes that waited for them. A failed or stopped job skips what depends on it, and
        ``start.stop()`` keeps every job not yet started from starting. A prepared run starts once."""
        run = prepared.run
        if run is None or run.runtime is not self:
            raise GraphError("Start takes a run prepared by this runtime", where=None)
        if run.start is not None:
            raise GraphError("this run has been started already; run the graph again to prepare it anew",
                             where=run.plan.graph.where)
        self.last_result = run.begin(start if isinstance(start, Start) else Start())
        return self.last_result


def _count(items: list, noun: str) -> str:
    return f"{len(items)} {noun}{'s' if len(items) != 1 else ''}"


def _interface_values(plan: Plan, inputs: dict[str, Any]) -> tuple[dict[tuple[str, str], tuple[Any, str]], list[Issue]]:
    """Values fed into internal ports by the graph's interface inputs, and any problems with them."""
    issues, fed = [], {}
    for name in inputs:
        if name not in plan.iface_inputs:
            known = ", ".join(plan.iface_inputs) or "none"
            issues.append(Issue("unknown-input", ("interface", "inputs", name), f"no interface input {name!r} (inputs: {known})"))
    for name, (item, targets) in plan.iface_inputs.items():
        if name in inputs:
            value = inputs[name]
        elif item.default is not None:
            value = item.default
        else:
            needed = [f"{n}.{p}" for n, p in targets if plan.nodes[n].inputs[p].required and not plan.nodes[n].inputs[p].param]
            if needed:
                issues.append(Issue("missing-input", ("interface", "inputs", name),
                                    f"interface input {name!r} ({item.type}) is required by {', '.join(needed)}"))
            continue
        if not value_matches(item.type, value):
            issues.append(Issue("invalid-input", ("interface", "inputs", name),
                                f"interface input {name!r} must be a {item.type}, got {type(value).__name__} {value!r}"))
            continue
        try:
            value_digest = digest(value)
        except Undigestable as exc:
            issues.append(Issue("invalid-input", ("interface", "inputs", name), f"interface input {name!r}: {exc}"))
            continue
        for target in targets:
            fed[target] = (value, value_digest)
    return fed, issues


class _Run:
    """One execution of a plan: values on wires, per-node results, events."""

    def __init__(self, runtime: Runtime, plan: Plan, fed: dict[tuple[str, str], tuple[Any, str]]):
        self.runtime, self.plan, self.fed = runtime, plan, fed
        self.values: dict[tuple[str, str], tuple[Any, str]] = {}
        self.results: dict[str, NodeResult] = {}
        self.events: list[Event] = []
        self.blocked: dict[str, str] = {}
        self._reads: frozenset[Path] | None = None
        self.start: Start | None = None  # set by begin(): the explicit Start this run carries on with
        self.prepared: dict[str, Any] = {}  # the jobs as the run prepared them

    def emit(self, kind: str, node_id: str, duration: float | None = None, message: str | None = None) -> None:
        self.announce(Event(kind, node_id, duration, message))  # type: ignore[arg-type]

    def announce(self, event: Event) -> None:
        self.events.append(event)
        self.runtime.events.emit(event)

    def files_read(self) -> frozenset[Path]:
        if self._reads is None:
            self._reads = files_read(self.plan)
        return self._reads

    def execute(self) -> RunResult:
        order = self.plan.order
        for node_id in order:
            self.emit("queued", node_id)
        for node_id in order:
            if node_id in self.blocked:
                self.skip(node_id)
            else:
                self.step(self.plan.nodes[node_id])
        self.prepared = {n: r.job for n, r in self.results.items() if r.status in ("ready", "stale")}
        return self.result()

    def result(self) -> RunResult:
        outputs = {name: self.values[src][0] for name, (_item, src) in self.plan.iface_outputs.items() if src in self.values}
        return RunResult(self.results, outputs, self.events, self.plan.order, self)

    def skip(self, node_id: str) -> None:
        reason = f"skipped: upstream node {self.blocked[node_id]!r} failed"
        self.results[node_id] = NodeResult(node_id, "skipped", error=reason)
        self.emit("skipped", node_id, message=reason)

    def begin(self, start: Start) -> RunResult:
        """Start: the ready jobs in order (no run lock while a machine moves), then what waited for them."""
        self.start = start
        for node_id in self.plan.order:
            status = self.results[node_id].status
            if node_id in self.blocked and status in (*PREPARED,):
                self.skip(node_id)
            elif status in ("ready", "stale"):
                self.go(self.plan.nodes[node_id])
            elif status == "waiting":
                with self.runtime._run_lock:
                    self.step(self.plan.nodes[node_id])
        return self.result()

    def waits_for(self, node: BoundNode) -> str | None:
        """The device node whose outputs this node needs and which has not run (None: it can go now)."""
        for name, (src, _port) in node.sources.items():
            upstream = self.results.get(src)
            if upstream is None or upstream.status not in PREPARED:
                continue
            if node.moves and name in node.cls.start_inputs and upstream.status != "waiting":
                continue  # an earlier device's log: only Start needs it
            return src
        return None

    def gather(self, node: BoundNode) -> tuple[dict[str, Any], list[tuple[str, str]]]:
        """Values arriving on the node's inputs (wired or fed by the interface) and their digests."""
        wired, digests = {}, []
        for name in node.inputs:
            src = node.sources.get(name)
            item = self.values.get(src) if src is not None else self.fed.get((node.id, name))
            if item is not None:
                wired[name] = item[0]
                digests.append((name, item[1]))
        return wired, digests

    def step(self, node: BoundNode) -> None:
        upstream = self.waits_for(node)
        if upstream is not None:
            message = f"waits for Start: node {upstream!r} has not run"
            self.results[node.id] = NodeResult(node.id, "waiting", error=None, logs=[message])
            self.emit("waiting", node.id, message=message)
            return
        if node.moves:
            self.prepare(node)
            if self.start is not None and self.results[node.id].status in ("ready", "stale"):
                self.go(node)
            return
        wired, digests = self.gather(node)
        sig = signature(node.static, digests + _file_stamps(node, wired, self.plan.site))
        if node.pure:
            entry = self.runtime.cache.get(node.id, sig)
            if entry is not None:
                self.publish(node, entry.outputs, entry.digests)
                self.results[node.id] = NodeResult(node.id, "cached", outputs=entry.outputs)
                self.emit("cached", node.id, 0.0)
                return
        result = self.results[node.id] = NodeResult(node.id, "running")
        self.emit("running", node.id)
        start = time.perf_counter()
        try:
            outputs = self.invoke(node, wired, result)
            out_digests = _digest_outputs(node, outputs)
        except Exception as exc:  # every failure becomes a message, never a traceback
            self.fail(node, result, exc, start)
            return
        result.status, result.duration, result.outputs = "done", time.perf_counter() - start, outputs
        self.publish(node, outputs, out_digests)
        if node.pure:
            self.runtime.cache.put(node.id, CacheEntry(sig, outputs, out_digests))
        self.emit("done", node.id, result.duration)

    def fail(self, node: BoundNode, result: NodeResult, exc: BaseException, started: float) -> None:
        result.status, result.duration = "failed", time.perf_counter() - started
        result.error = _failure_message(node.id, exc)
        self.runtime.cache.drop(node.id)
        for down in sorted(self.plan.downstream(node.id)):
            self.blocked.setdefault(down, node.id)
        self.emit("failed", node.id, result.duration, result.error)

    def prepare(self, node: BoundNode) -> None:
        """A device node's job, cached on the inputs it is prepared from (not the Start-only ones)."""
        wired, digests = self.gather(node)
        sig = signature(node.static, [(n, d) for n, d in digests if n not in node.cls.start_inputs])
        key = node.id + "\0job"
        result = self.results[node.id] = NodeResult(node.id, "running")
        begun = time.perf_counter()
        entry = self.runtime.cache.get(key, sig) if node.binding is None else None  # a sub-graph's run starts once
        if entry is not None:
            job = entry.outputs["job"]
        else:
            self.emit("running", node.id)
            try:
                job = self.invoke(node, wired, result, "prepare")
            except Exception as exc:  # a job that cannot be prepared (pre-flight refused it) fails the node
                self.fail(node, result, exc, begun)
                return
            self.runtime.cache.put(key, CacheEntry(sig, {"job": job}, {}))
        last = self.runtime._started.get(node.id)
        result.status = "stale" if last is not None and last != job_digest(job) else "ready"
        result.job, result.duration = job, time.perf_counter() - begun
        describe = getattr(job, "describe", None)
        self.emit(result.status, node.id, result.duration, describe() if callable(describe) else None)

    def go(self, node: BoundNode) -> None:
        """Start one prepared job: the node's ``start`` hands it to its device and returns the outputs."""
        result = self.results[node.id]
        job = result.job
        if self.start is None or self.start.stopped.is_set():
            self.blocked.setdefault(node.id, node.id)
            result.status, result.error = "skipped", "not started: the run was stopped"
            for down in sorted(self.plan.downstream(node.id)):
                self.blocked.setdefault(down, node.id)
            self.emit("skipped", node.id, message=result.error)
            return
        self.runtime._started[node.id] = job_digest(job)
        wired, _digests = self.gather(node)
        result.status = "running"
        self.emit("running", node.id)
        begun = time.perf_counter()
        try:
            outputs = self.invoke(node, wired, result, "start", job)
            out_digests = _digest_outputs(node, outputs)
        except Exception as exc:  # a fault or a stop: the node fails, what depends on it is skipped
            self.fail(node, result, exc, begun)
            return
        result.status, result.duration, result.outputs = "done", time.perf_counter() - begun, outputs
        self.publish(node, outputs, out_digests)
        self.emit("done", node.id, result.duration)

    def publish(self, node: BoundNode, outputs: dict[str, Any], digests: dict[str, str]) -> None:
        for name, value in outputs.items():
            self.values[(node.id, name)] = (value, digests[name])

    def invoke(self, node: BoundNode, wired: dict[str, Any], result: NodeResult, phase: str = "run",
               job: Any = None) -> Any:
        """Call the node: ``run``, or for a device node ``prepare`` (without the Start-only inputs; returns
        the job) or ``start`` (the job and the Start-only inputs)."""
        params = _params_with_wires(node, wired)
        kwargs = {name: wired.get(name, port.default) for name, port in node.inputs.items() if not port.param}

        def log(message: str) -> None:
            result.logs.append(message)
            self.emit("log", node.id, message=message)

        ctx = NodeContext(node.id, self.plan.site, log, node.binding, lambda: self.runtime.child(node.id),
                          self.start, _announce=self.announce, _reads=self.files_read)
        later = node.cls.start_inputs
        if phase == "prepare":
            return node.cls().prepare(ctx, params, **{k: v for k, v in kwargs.items() if k not in later})
        if phase == "start":
            outputs = node.cls().start(ctx, job, **{k: v for k, v in kwargs.items() if k in later})
        else:
            outputs = node.cls().run(ctx, params, **kwargs)
        _check_outputs(node, outputs)
        return outputs


def _file_stamps(node: BoundNode, wired: dict[str, Any], site: Site) -> list[tuple[str, str]]:
    """Content hashes of what a node reads (``NodeType.reads``: files, or folders whose files it may read):
    a pure node that reads files is cached while they are unchanged. Hashes, not sizes and modification
    times: an edit that keeps both (a copy with ``cp -p``, a coarse clock) must still be seen."""
    stamps = []
    for name in node.cls.reads:
        rel = wired[name] if name in wired else node.raw_params.get(name)
        if not rel:
            continue
        try:
            path = resolve_inside(site.root, site.graph_dir, rel)
            entries = sorted(Path(e.path) for e in os.scandir(path) if e.is_file()) if path.is_dir() else [path]
            listing = ";".join(f"{e.name}:{fingerprint(e)}" for e in entries)
            stamps.append((f"file:{name}", digest(listing)))
        except (FlowmcError, OSError, TypeError):
            stamps.append((f"file:{name}", "unreadable"))  # the node runs, and says what is wrong
    return stamps


def _params_with_wires(node: BoundNode, wired: dict[str, Any]) -> Any:
    """The stored params with wired values merged in, validated against the params model."""
    fed = {name: wired[name] for name, port in node.inputs.items() if port.param and name in wired}
    if not fed and node.params is not None:
        return node.params
    try:
        return node.cls.Params.model_validate({**node.raw_params, **fed})
    except ValidationError as exc:
        problems = []
        for err in exc.errors():
            name = ".".join(str(p) for p in err["loc"])
            how = "fed by wire" if err["loc"] and err["loc"][0] in fed else "stored"
            problems.append(f"param {name!r} ({how}): {err['msg']}")
        raise FlowmcError("; ".join(problems)) from None


def _check_outputs(node: BoundNode, outputs: Any) -> None:
    if not isinstance(outputs, dict):
        raise FlowmcError(f"{node.cls.type_id}.run returned {type(outputs).__name__}, expected a dict of outputs")
    missing = [n for n in node.outputs if n not in outputs]
    extra = [n for n in outputs if n not in node.outputs]
    if missing or extra:
        raise FlowmcError(f"{node.cls.type_id}.run returned outputs {sorted(outputs)}, declared {list(node.outputs)}")
    for name, port in node.outputs.items():
        if not value_matches(port.type, outputs[name]):
            raise FlowmcError(f"output {name!r} should be a {port.type}, got {type(outputs[name]).__name__}")


def _digest_outputs(node: BoundNode, outputs: dict[str, Any]) -> dict[str, str]:
    try:
        return {name: digest(value) for name, value in outputs.items()}
    except Undigestable as exc:
        raise FlowmcError(f"an output of {node.cls.type_id} cannot be cached: {exc}") from None


def _failure_message(node_id: str, exc: BaseException) -> str:
    """One line naming the node. A FlowmcError says what and where; a value a model refused, memory or
    recursion running out are said plainly; anything else is a bug and keeps its type name."""
    if isinstance(exc, FlowmcError):
        text = str(exc)
    elif isinstance(exc, ValidationError):
        first = exc.errors()[0]
        loc = ".".join(str(p) for p in first["loc"])
        text = f"invalid value{f' for {loc}' if loc else ''}: {first['msg']}"
    elif isinstance(exc, MemoryError):
        text = ("ran out of memory: ask for less (a coarser tolerance, a shorter program), or lower the memory "
                "budget so the request is refused before it starts (flowmc run --memory-mb)")
    elif isinstance(exc, RecursionError):
        text = "its input is nested too deeply to process"
    else:
        text = f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__
    text = printable(text, 2000)
    prefix = f"node {node_id!r}"
    return text if text.startswith(prefix) else f"{prefix}: {text}"
