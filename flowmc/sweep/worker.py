"""What runs on a worker: batches of variants through one long-lived runtime per worker thread.

A worker gets the ``Job`` once (the graph as JSON, where it lives, which settings go to the simulated
card) and then batches of variants. Each variant is the job's graph with the variant's settings applied,
run as ``flowmc run`` runs it; the runtime and its cache stay between variants and batches, so unchanged
upstream nodes are not run again. The answer is one plain row per variant (JSON-able; no wire values).
"""

from __future__ import annotations

import hashlib
import io
import os
import socket
import tempfile
import threading
import time
import zipfile
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from flowmc.errors import FlowmcError
from flowmc.graph import Graph, loads
from flowmc.runtime import Runtime, summarize
from flowmc.settings import Target
from flowmc.sweep.variants import Variant

__all__ = ["Job", "run_batch", "warm_up", "pack_folder", "MAX_SHIPPED_BYTES"]

MAX_SHIPPED_BYTES = 64 * 1024 * 1024
_KEPT_JOBS = 4  # graphs a worker thread keeps a runtime for


@dataclass(frozen=True)
class Job:
    """Everything a worker needs once. ``graph_name``: the graph file's name in ``folder`` (the folder that
    relative file params resolve against); ``shipped``: that folder zipped, for workers that do not share
    this file system (unpacked once per worker host)."""

    graph_json: str
    folder: str
    graph_name: str | None
    targets: dict[str, Target]
    to_sim: tuple[str, ...] = ()
    node_folders: tuple[str, ...] = ()
    shipped: bytes | None = field(default=None, repr=False)

    key: str = field(init=False, repr=False)  # names the job's runtime on a worker

    def __post_init__(self) -> None:
        h = hashlib.blake2b(self.graph_json.encode(), digest_size=12)
        h.update(f"\0{self.folder}\0{self.graph_name}\0{self.to_sim}\0{self.node_folders}".encode())
        if self.shipped is not None:
            h.update(hashlib.blake2b(self.shipped, digest_size=12).digest())
        object.__setattr__(self, "key", h.hexdigest())


def pack_folder(folder: Path, skip: tuple[Path, ...] = ()) -> bytes:
    """The folder's files (hidden ones and ``skip`` folders left out) as zip bytes, refused over the cap."""
    buffer, total = io.BytesIO(), 0
    skipped = tuple(p.resolve() for p in skip)
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for path in sorted(folder.rglob("*")):
            rel = path.relative_to(folder)
            if any(part.startswith(".") for part in rel.parts) or not path.is_file() or path.is_symlink():
                continue
            if any(path.resolve().is_relative_to(s) for s in skipped):
                continue
            total += path.stat().st_size
            if total > MAX_SHIPPED_BYTES:
                raise FlowmcError(f"the graph's folder holds over {MAX_SHIPPED_BYTES // 2**20} MiB; put the graph and "
                                  "its files in a folder of their own, or give the workers a shared file system",
                                  where=str(folder))
            archive.write(path, rel.as_posix())
    return buffer.getvalue()


_unpack_lock = threading.Lock()


def _unpacked(job: Job) -> Path:
    """The shipped folder on this host (unpacked once, into a folder named by its content)."""
    assert job.shipped is not None
    name = hashlib.blake2b(job.shipped, digest_size=12).hexdigest()
    target = Path(tempfile.gettempdir()) / f"flowmc-sweep-{name}"
    with _unpack_lock:
        if not target.is_dir():
            staging = Path(tempfile.mkdtemp(prefix=f".flowmc-sweep-{name}-"))
            with zipfile.ZipFile(io.BytesIO(job.shipped)) as archive:
                for member in archive.namelist():  # names were written by pack_folder: relative, no '..'
                    if member.startswith("/") or ".." in Path(member).parts:
                        raise FlowmcError(f"shipped folder: refused member {member!r}")
                archive.extractall(staging)
            try:
                os.replace(staging, target)
            except OSError:  # another process on this host unpacked it first
                pass
    return target


class _Loaded:
    """A job's graph on this worker, and the runtime that keeps its cache."""

    def __init__(self, job: Job):
        folder = _unpacked(job) if job.shipped is not None else Path(job.folder)
        self.graph: Graph = loads(job.graph_json, where=job.graph_name or "<graph>")
        self.graph.path = folder / (job.graph_name or "unsaved.flowmc.json")
        self.runtime = Runtime(_registry(job.node_folders))
        wired = {w.from_ for w in self.graph.wires}
        self.loose = [] if self.graph.interface is not None else [
            (n.id, o) for n in self.graph.nodes for o in self._outputs(n.id) if f"{n.id}.{o}" not in wired]

    def _outputs(self, node_id: str) -> list[str]:
        plan = self.runtime.plan(self.graph)
        return list(plan.nodes[node_id].outputs) if node_id in plan.nodes else []


_registries: dict[tuple[str, ...], Any] = {}
_registry_lock = threading.Lock()


def _registry(node_folders: tuple[str, ...]) -> Any:
    """The default registry when it holds the sweep's node folders, else one with them too (built once per
    process)."""
    from flowmc.plugins import build_registry, default_registry

    default = default_registry()
    if set(node_folders) <= {str(f) for f in default.node_folders}:
        return default
    with _registry_lock:
        if node_folders not in _registries:
            _registries[node_folders] = build_registry(node_folders=node_folders)
        return _registries[node_folders]


_local = threading.local()


def _loaded(job: Job) -> _Loaded:
    jobs: OrderedDict[str, _Loaded] | None = getattr(_local, "jobs", None)
    if jobs is None:
        jobs = _local.jobs = OrderedDict()
    key = job.key
    if key not in jobs:
        jobs[key] = _Loaded(job)
        while len(jobs) > _KEPT_JOBS:
            jobs.popitem(last=False)
    jobs.move_to_end(key)
    return jobs[key]


def _message(exc: BaseException) -> str:
    issues = getattr(exc, "issues", None)
    if issues:
        return "; ".join(i.message for i in issues)
    if isinstance(exc, FlowmcError):
        return str(exc)
    return f"internal error: {type(exc).__name__}: {exc}"


def run_variant(job: Job, loaded: _Loaded, variant: Variant) -> dict[str, Any]:
    """One variant, as ``flowmc run`` with the same settings would run it."""
    start, t0 = time.time(), time.perf_counter()
    graph = loaded.graph.model_copy(deep=True)
    graph.path = loaded.graph.path
    inputs: dict[str, Any] = {}
    row: dict[str, Any] = {"variant": variant.index, "key": variant.key, "params": variant.params}
    try:
        for name, value in variant.settings:
            job.targets[name].apply(graph, value, inputs)
        for name in job.to_sim:
            job.targets[name].apply(graph, "sim", inputs)
        result = loaded.runtime.run(graph, inputs, start=True)  # only simulators are left (safety.py): they run
    except Exception as exc:  # noqa: BLE001 - an invalid variant, or a bug: still one row, never a dead worker
        row.update(status="failed", error=_message(exc), outputs={}, ran=0, cached=0)
    else:
        if loaded.loose:
            outputs = {f"{n}.{p}": summarize(result.nodes[n].outputs[p]) for n, p in loaded.loose
                       if p in result.nodes[n].outputs}
        else:
            outputs = {name: summarize(value) for name, value in result.outputs.items()}
        row.update(status="done" if result.ok else "failed", error="; ".join(result.errors), outputs=outputs,
                   ran=len(result.executed), cached=len(result.cached), executed=result.executed)
    row.update(duration_s=time.perf_counter() - t0, start=start, end=time.time(), worker=_worker_name())
    return row


def warm_up(node_folders: tuple[str, ...] = ()) -> None:
    """Build the registry (importing every node module) before the first variant: worker start-up, not a
    variant's time."""
    _registry(node_folders)


def _worker_name() -> str:
    return f"{socket.gethostname()}:{os.getpid()}"


def run_batch(job: Job, batch: list[Variant]) -> list[dict[str, Any]]:
    """Run a batch of variants on this worker's long-lived runtime for ``job``; one row each."""
    loaded = _loaded(job)
    return [run_variant(job, loaded, v) for v in batch]
