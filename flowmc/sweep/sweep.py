"""A sweep: one graph, its variants, the device policy, and the loop that collects rows as batches finish.

``Sweep(graph, axes)`` checks everything before anything runs (targets, values, device nodes) and makes
the Job the workers get. ``Sweep.run(executor, journal)`` sends the variants the journal does not hold
yet, keeps each batch's rows as it comes back, and stops cleanly on Ctrl-C or ``stop``: the rows done so
far stay in the journal, and ``--resume`` skips them.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from flowmc.errors import FlowmcError, GraphError
from flowmc.graph import Graph, dumps
from flowmc.runtime import Runtime
from flowmc.settings import target
from flowmc.sweep.batches import batch_size, batches, upstream_first
from flowmc.sweep.results import Journal, table
from flowmc.sweep.safety import check_devices, device_uses
from flowmc.sweep.variants import Axis, Variant, variants
from flowmc.sweep.worker import Job, pack_folder

__all__ = ["Sweep", "Progress", "Outcome"]


@dataclass(frozen=True)
class Progress:
    """Counts over the whole sweep (``resumed``: rows an earlier run left, counted in done/failed too)."""

    total: int
    done: int
    failed: int
    left: int
    elapsed: float
    resumed: int = 0

    @property
    def rate(self) -> float:
        """Variants finished per second in this run."""
        finished = self.done + self.failed - self.resumed
        return finished / self.elapsed if self.elapsed > 0 and finished > 0 else 0.0


@dataclass
class Outcome:
    """What a run of the sweep left: the table (``columns``, ``rows``), counts, and whether it was stopped."""

    columns: list[str]
    rows: list[dict[str, Any]]
    done: int
    failed: int
    lost: int
    left: int
    skipped: int  # already in the journal (resumed)
    elapsed: float
    interrupted: bool = False
    notes: list[str] = field(default_factory=list)


class Sweep:
    """``graph`` over ``axes`` with a device policy (``refuse`` or ``sim``, see ``flowmc.sweep.safety``).
    ``ship``: pack the graph's folder for workers that do not share this file system (``skip``: folders
    left out of the pack, e.g. the results folder). ``registry`` checks the graph here (default: the
    default registry); workers rebuild it in their own process: the built-in nodes, installed plugins, and
    the node folders it loaded plus ``node_folders`` (the same paths must exist on them)."""

    def __init__(self, graph: Graph, axes: list[Axis], *, devices: str = "refuse", ship: bool = False,
                 skip: tuple[Path, ...] = (), registry: Any = None, node_folders: tuple[str, ...] = ()):
        from flowmc.plugins import default_registry

        self.graph, self.axes = graph, axes
        registry = registry if registry is not None else default_registry()
        plan = Runtime(registry).plan(graph)
        if plan.issues:
            raise GraphError(f"{len(plan.issues)} problem{'s' if len(plan.issues) != 1 else ''}", where=graph.where,
                             issues=plan.issues)
        self.variants: list[Variant] = variants(graph, axes)
        self.params = [t.name for a in axes for t in a.targets]
        swept: dict[str, list[Any]] = {}
        for axis in axes:
            for j, tgt in enumerate(axis.targets):
                swept[tgt.name] = [row[j] for row in axis.rows]
        self.safety = check_devices(device_uses(plan), swept, devices)
        self.order = upstream_first(plan, axes)
        targets = {t.name: t for a in axes for t in a.targets}
        for name in self.safety.to_sim:
            targets.setdefault(name, target(graph, name, f"device {name}", registry))
        folder = graph.base_dir.resolve()
        folders = dict.fromkeys(str(Path(f).expanduser().resolve())
                                for f in (*getattr(registry, "node_folders", ()), *node_folders))
        self.job = Job(dumps(graph), str(folder), graph.path.name if graph.path is not None else None, targets,
                       self.safety.to_sim, tuple(folders), pack_folder(folder, skip) if ship else None)

    @property
    def resources(self) -> tuple[str, ...]:
        return self.safety.resources

    def run(self, executor: Any, journal: Journal, *, on_progress: Callable[[Progress], Any] | None = None,
            stop: threading.Event | None = None, size: int | None = None) -> Outcome:
        """Run the variants ``journal`` does not hold yet on ``executor``; Ctrl-C (or ``stop``) ends it cleanly."""
        finished = journal.finished
        todo = [v for v in self.variants if v.key not in finished]
        skipped = len(self.variants) - len(todo)
        earlier = [journal.rows[v.key]["status"] for v in self.variants if v.key in finished]
        done_before = earlier.count("done")
        size = size or batch_size(len(todo), executor.workers)
        work = batches(todo, self.order, size)
        done = failed = lost = 0
        start = time.perf_counter()
        interrupted = False

        def report() -> None:
            if on_progress is not None:
                on_progress(Progress(len(self.variants), done_before + done, skipped - done_before + failed,
                                     len(todo) - done - failed - lost, time.perf_counter() - start, skipped))

        report()
        try:
            for batch, answer in executor.results(work):
                rows = answer if isinstance(answer, list) else [_lost(v, answer) for v in batch]
                journal.add(rows)
                done += sum(r["status"] == "done" for r in rows)
                failed += sum(r["status"] == "failed" for r in rows)
                lost += sum(r["status"] == "lost" for r in rows)
                report()
                if stop is not None and stop.is_set():
                    interrupted = True
                    break
        except KeyboardInterrupt:
            interrupted = True
        elapsed = time.perf_counter() - start
        columns, rows = self.table(journal)
        return Outcome(columns, rows, done, failed, lost, len(todo) - done - failed - lost, skipped, elapsed,
                       interrupted, list(self.safety.notes))

    def table(self, journal: Journal) -> tuple[list[str], list[dict[str, Any]]]:
        """This sweep's rows from the journal, one per variant that has one, numbered as in this sweep."""
        rows = []
        for v in self.variants:
            row = journal.rows.get(v.key)
            if row is not None:
                rows.append({**row, "variant": v.index, "params": v.params})
        return table(rows, self.params)


def _lost(variant: Variant, exc: BaseException) -> dict[str, Any]:
    """The row of a variant whose batch never answered (its worker died)."""
    message = str(exc) if isinstance(exc, FlowmcError) else f"{type(exc).__name__}: {exc}"
    return {"variant": variant.index, "key": variant.key, "params": variant.params, "status": "lost",
            "error": f"the worker running it was lost: {message}", "outputs": {}, "ran": 0, "cached": 0,
            "duration_s": None, "worker": ""}
