"""Two phases for device nodes: a run prepares, only an explicit Start moves.

A node type with ``moves = True`` (a device node) never moves anything when a graph runs. The run
calls its ``prepare(ctx, params, **inputs)``, which returns a job (pure, cached like a pure node,
pre-flighted); the node is then *ready* (or *stale*: prepared, and different from the job this
runtime last started for it), and nodes that need its outputs *wait*. ``Runtime.start(prepared,
start)`` is the Start: it hands each ready job to the node's ``start(ctx, job, **start_inputs)``
in order, then runs the nodes that waited. ``start_inputs`` are inputs only Start needs (the log of
the device operation before, which exists only once that one has run).

What the runtime knows of a job is ``digest()`` (and ``summary()`` for reports). ``Start`` carries
what the caller wants the job runners to know (``options``, e.g. the pace), a hook told of each
job as it starts (``on_job(node_id, runner)``: the editor's controls and the CLI's progress bar
subscribe there) and a flag that keeps every job not yet started from starting (a stop).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from typing import Any, Callable

__all__ = ["Start", "PREPARED", "job_digest"]

#: Statuses of a prepared run that are not failures: ready and stale device nodes, and nodes waiting
#: for them.
PREPARED = ("ready", "stale", "waiting")


@dataclass
class Start:
    """An explicit Start. ``options`` go to the job runners as they are; ``on_job(node_id, runner)`` hears
    each job as it starts (node ids of jobs inside a sub-graph are ``outer/inner``); ``stop()`` keeps the
    jobs not yet started from starting (the one running is stopped through its runner)."""

    options: dict[str, Any] = field(default_factory=dict)
    on_job: Callable[[str, Any], None] | None = None
    stopped: threading.Event = field(default_factory=threading.Event)

    def stop(self) -> None:
        self.stopped.set()

    def within(self, node_id: str) -> "Start":
        """The same Start as seen inside a sub-graph node: job ids prefixed, one stop flag."""
        outer = self.on_job
        hook = (lambda inner, runner: outer(f"{node_id}/{inner}", runner)) if outer is not None else None
        return Start(self.options, hook, self.stopped)


def job_digest(job: Any) -> str:
    """A job's content hash (its ``digest()``), what tells a stale job from the one that ran."""
    digest = getattr(job, "digest", None)
    return digest() if callable(digest) else repr(job)
