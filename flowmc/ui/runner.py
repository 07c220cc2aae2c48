"""Runs the editor's graph through its Runtime in a worker thread, so the page stays live, and turns
the runtime's events into node colours.

Events arrive on the running thread, many per node; the listener only records each node's latest
state and raises a flag. A ticker thread redraws the canvas when the flag is up, at most every
``interval`` seconds, so a fast graph of many nodes costs a few redraws, not one per event.
"""

from __future__ import annotations

import threading
from typing import Any, Callable

from flowmc.errors import FlowmcError
from flowmc.runtime import Event, Runtime

__all__ = ["Runner"]


class Runner:
    """``start(plan, inputs)`` runs once at a time; ``on_finished(result, error)`` follows each run
    (``error`` is the message when the run could not start, e.g. an invalid interface input)."""

    def __init__(self, runtime: Runtime, status: dict[str, tuple], redraw: Callable[[], None],
                 on_finished: Callable[[Any, str | None], None], interval: float = 0.05):
        self.runtime, self.status, self.redraw, self.on_finished = runtime, status, redraw, on_finished
        self.interval = interval
        self.thread: threading.Thread | None = None
        self._dirty = threading.Event()
        self._closed = threading.Event()
        self._unsubscribe = runtime.subscribe(self._on_event)
        self._ticker = threading.Thread(target=self._tick, name="flowmc-editor-redraw", daemon=True)
        self._ticker.start()

    @property
    def running(self) -> bool:
        return self.thread is not None and self.thread.is_alive()

    def start(self, plan: Any, inputs: dict[str, Any] | None = None) -> threading.Thread | None:
        """Run ``plan`` (a validated ``Runtime.plan``) in a worker thread; None when one is running."""
        if self.running:
            return None
        self.status.clear()
        self.thread = threading.Thread(target=self._work, args=(plan, dict(inputs or {})), name="flowmc-editor-run",
                                       daemon=True)
        self.thread.start()
        return self.thread

    def _work(self, plan: Any, inputs: dict[str, Any]) -> None:
        result, error = None, None
        try:
            result = self.runtime.run(plan, inputs)
        except FlowmcError as exc:  # invalid inputs: the plan itself was checked before
            error = "; ".join(i.message for i in getattr(exc, "issues", [])) or str(exc)
        except Exception as exc:  # a bug must reach the page as a message, not kill the thread silently
            error = f"{type(exc).__name__}: {exc}"
        self._dirty.clear()
        self.redraw()
        self.on_finished(result, error)

    def _on_event(self, event: Event) -> None:
        if event.kind != "log":
            self.status[event.node_id] = (event.kind, event.duration, event.message)
            self._dirty.set()

    def _tick(self) -> None:
        while not self._closed.is_set():
            if not self._dirty.wait(timeout=0.5):
                continue
            self._dirty.clear()
            if self._closed.is_set():
                return
            try:
                self.redraw()
            except Exception:  # the page went away mid-redraw; the next event redraws again
                pass
            self._closed.wait(self.interval)

    def close(self) -> None:
        self._closed.set()
        self._dirty.set()
        self._unsubscribe()
        self._ticker.join(timeout=2.0)
        if self.thread is not None:
            self.thread.join(timeout=10.0)
