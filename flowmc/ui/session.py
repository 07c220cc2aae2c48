"""The editor's session: the document, the runtime, the one run queue, the last result and the device
session, with no viser in it. The page (``app.Editor``) and its panels sit on top of it.

One way to run: the Run button, Ctrl+Enter, the front panel and G-code export all call
``EditorSession.run``. Runs go one at a time on one worker thread; a request made while a run is
going waits, and a newer request replaces a waiting one (a front-panel slider dragged through ten
values runs the first and the last). Each request is planned when its turn comes, so it runs the
graph as it is then.

Panels get a ``PanelHost`` (the narrow protocol below), never the whole editor. A device session
and a job runner are handed in by whoever composes the editor (``flowmc serve``): the UI imports
no device or node module (see docs/architecture.md).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

from flowmc.api import Runtime
from flowmc.errors import FlowmcError
from flowmc.graph import Graph, Issue
from flowmc.runtime import Event
from flowmc.ui.state import EditorState

__all__ = ["EditorSession", "RunRequest", "RunRefused", "PanelHost", "DeviceAccess", "JobAccess"]


class DeviceAccess(Protocol):
    """The device session an application hands the editor (``flowmc.devices.session.DeviceSession``):
    one open connection, shared by the Device tab and the job runner."""

    card: Any  # the open ``MotionCard``, or None

    def known(self) -> list[str]: ...

    def connect(self, spec: str, machine: Any = None, **options: Any) -> Any: ...

    def disconnect(self) -> None: ...

    def input_names(self) -> dict[int, str]: ...

    def close(self) -> None: ...


class JobAccess(Protocol):
    """What a job panel drives (``flowmc.devices`` JobRunner). The session only holds it and closes it."""

    def close(self) -> None: ...


class PanelHost(Protocol):
    """What a side panel sees of the editor: the session, the GUI to build in, and a few actions."""

    session: "EditorSession"
    gui: Any  # viser.GuiApi

    def notify(self, kind: str, text: str, client: Any = None) -> None: ...

    def select_node(self, node_id: str) -> None: ...

    def files_changed(self) -> None:
        """Graph files changed on disk (a new sub-graph): the palette and file lists look again."""

    def edit(self, action: str) -> None:
        """An edit command by name: Undo, Redo, Fit, Delete, Save, Run, ..."""

    def add_node(self, type_id: str, params: dict[str, Any], at: tuple[float, float] | None = None) -> str:
        """Add a node at a free spot (near ``at``, canvas pixels, else the middle of the view); its id."""

    def export_gcode(self, client: Any = None) -> Any: ...

    def download(self, name: str, text: str, client: Any = None) -> None:
        """Hand ``text`` to the browser as the file ``name`` (one click, no second prompt)."""

    def confirm(self, title: str, text: str, button: str, action: Callable[[], object], client: Any = None) -> Any:
        """Ask in a dialog; ``action()`` runs (under the lock) when the user presses ``button``."""


@dataclass
class RunRefused:
    """Why a run did not start: the plan's issues (the graph cannot run as it is)."""

    issues: list[Issue]

    @property
    def message(self) -> str:
        more = f" (and {len(self.issues) - 1} more: see Problems)" if len(self.issues) > 1 else ""
        return f"cannot run yet: {self.issues[0].message}{more}"


@dataclass
class RunRequest:
    """One queued run. ``source`` says who asked ("run", "front panel", "export"); ``inputs`` None means
    the session's ``inputs_provider`` (the front panel's values) at the time it runs."""

    inputs: dict[str, Any] | None = None
    source: str = "run"
    plan: Any = None  # the plan it ran (its ``graph`` is the graph as it was then)
    result: Any = None
    error: str | None = None
    seconds: float = 0.0
    superseded: bool = False
    started: threading.Event = field(default_factory=threading.Event, repr=False)
    done: threading.Event = field(default_factory=threading.Event, repr=False)

    def wait(self, timeout: float | None = 60.0) -> Any:
        """The RunResult once this request ran (None when it failed to start or was replaced)."""
        self.done.wait(timeout)
        return self.result


class EditorSession:
    """Document, runtime, run queue, results and the device session of one editor.

    Listeners: ``on_result(fn)`` hears ``fn(request)`` after every run (``request.result`` is the
    RunResult, or ``request.error`` says why it did not start); ``on_progress(fn)`` hears ``fn()`` at
    most every ``interval`` seconds while node states change (``status`` holds each node's latest
    ``(kind, duration, message)``). Everything that changes the document takes ``lock``.
    """

    def __init__(self, graph: Graph | None = None, *, folder: Any = None, runtime: Runtime | None = None,
                 devices: DeviceAccess | None = None, jobs: JobAccess | None = None, interval: float = 0.05):
        self.lock = threading.RLock()
        self.runtime = runtime or Runtime()
        self.state = EditorState(graph, folder=folder, runtime=self.runtime)
        self.devices = devices
        self.jobs = jobs
        self.inputs_provider: Callable[[], dict[str, Any]] = dict
        self.last_result: Any = None
        self.status: dict[str, tuple[str, float | None, str | None]] = {}
        self.interval = interval
        self._result_listeners: list[Callable[[RunRequest], None]] = []
        self._progress_listeners: list[Callable[[], None]] = []
        self._queue_lock = threading.Lock()
        self._pending: RunRequest | None = None
        self._current: RunRequest | None = None
        self._wake = threading.Event()
        self._dirty = threading.Event()
        self._closed = threading.Event()
        self._unsubscribe = self.runtime.subscribe(self._on_event)
        self._worker = threading.Thread(target=self._work, name="flowmc-editor-run", daemon=True)
        self._ticker = threading.Thread(target=self._tick, name="flowmc-editor-progress", daemon=True)
        self._worker.start()
        self._ticker.start()

    # ------------------------------------------------------------------ listeners
    def on_result(self, listener: Callable[[RunRequest], None]) -> Callable[[], None]:
        self._result_listeners.append(listener)
        return lambda: self._result_listeners.remove(listener) if listener in self._result_listeners else None

    def on_progress(self, listener: Callable[[], None]) -> Callable[[], None]:
        self._progress_listeners.append(listener)
        return lambda: self._progress_listeners.remove(listener) if listener in self._progress_listeners else None

    # ------------------------------------------------------------------ running
    @property
    def running(self) -> bool:
        """True while a run is going or waiting."""
        return self._current is not None or self._pending is not None

    def run(self, inputs: dict[str, Any] | None = None, *, source: str = "run") -> RunRequest | RunRefused:
        """Queue a run of the graph as it is when its turn comes; RunRefused when it cannot run now."""
        with self.lock:
            plan = self.state.plan()
            if plan.issues:
                return RunRefused(list(plan.issues))
        request = RunRequest(None if inputs is None else dict(inputs), source)
        with self._queue_lock:
            if self._pending is not None:
                self._pending.superseded = True
                self._pending.done.set()
            self._pending = request
        self._wake.set()
        return request

    def wait(self, timeout: float = 60.0) -> Any:
        """Wait until no run is going or waiting (tests, scripts); returns the last result."""
        end = time.monotonic() + timeout
        while self.running and time.monotonic() < end:
            current = self._current or self._pending
            if current is not None:
                current.done.wait(max(0.0, end - time.monotonic()))
            else:
                time.sleep(0.005)
        return self.last_result

    def run_errors(self) -> dict[str, str]:
        """The last run's failures by node id (nodes no longer in the graph left out)."""
        result = self.last_result
        if result is None:
            return {}
        ids = {n.id for n in self.state.graph.nodes}
        return {n: r.error for n, r in result.nodes.items() if r.status == "failed" and n in ids and r.error}

    def _work(self) -> None:
        while not self._closed.is_set():
            self._wake.wait(0.5)
            with self._queue_lock:
                request, self._pending = self._pending, None
                self._current = request
                self._wake.clear()
            if request is None:
                continue
            try:
                self._execute(request)
            finally:
                self._current = None
                request.done.set()

    def _execute(self, request: RunRequest) -> None:
        started = time.perf_counter()
        request.started.set()
        try:
            with self.lock:
                plan = request.plan = self.state.plan()
                inputs = request.inputs if request.inputs is not None else self.inputs_provider()
                self.status.clear()
            if plan.issues:
                request.error = RunRefused(list(plan.issues)).message
            else:
                request.result = self.runtime.run(plan, inputs)
        except FlowmcError as exc:  # invalid interface inputs: the plan itself was checked
            request.error = "; ".join(i.message for i in getattr(exc, "issues", [])) or str(exc)
        except Exception as exc:  # a bug reaches the page as a message, never kills the worker silently
            request.error = f"{type(exc).__name__}: {exc}"
        request.seconds = time.perf_counter() - started
        if request.result is not None:
            self.last_result = request.result
        self._dirty.clear()
        self._progress()
        for listener in tuple(self._result_listeners):
            listener(request)

    def _on_event(self, event: Event) -> None:
        if event.kind != "log":
            self.status[event.node_id] = (event.kind, event.duration, event.message)
            self._dirty.set()

    def _progress(self) -> None:
        for listener in tuple(self._progress_listeners):
            try:
                listener()
            except Exception:  # noqa: BLE001 - a page that went away mid-redraw; the next event redraws
                pass

    def _tick(self) -> None:
        while not self._closed.is_set():
            if not self._dirty.wait(timeout=0.5):
                continue
            self._dirty.clear()
            if self._closed.is_set():
                return
            self._progress()
            self._closed.wait(self.interval)

    # ------------------------------------------------------------------ closing
    def close(self) -> None:
        """Stop the worker (after the run going, if any), the job runner and the device session."""
        if self._closed.is_set():
            return
        self._closed.set()
        self._wake.set()
        self._dirty.set()
        self._unsubscribe()
        self._worker.join(timeout=10.0)
        self._ticker.join(timeout=2.0)
        for part in (self.jobs, self.devices):
            if part is not None:
                try:
                    part.close()
                except Exception:  # noqa: BLE001 - closing is best effort
                    pass
