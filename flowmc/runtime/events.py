"""Run events: a small closed set, delivered to listeners registered on one runtime."""

from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import Callable, Literal

__all__ = ["EVENT_KINDS", "Event", "Listener", "EventBus"]

EventKind = Literal["queued", "running", "done", "cached", "failed", "skipped", "log", "ready", "stale", "waiting",
                    "iteration"]
EVENT_KINDS: tuple[str, ...] = ("queued", "running", "done", "cached", "failed", "skipped", "log", "ready", "stale",
                                "waiting", "iteration")


@dataclass(frozen=True, slots=True)
class Event:
    """``duration`` (s) on done/failed/ready/stale; ``message`` on failed/skipped/waiting (why), log,
    ready/stale (what the prepared job is), and iteration
    ("iteration 3 of 5": a loop starts its third pass; ``iteration`` is ``(3, 5)``, or ``(3, None)``
    for a While loop, whose count is known only at its end). An iteration of a loop inside a loop's
    body is announced too, its node id the path ``outer/inner``."""

    kind: EventKind
    node_id: str
    duration: float | None = None
    message: str | None = None
    iteration: tuple[int, int | None] | None = None


Listener = Callable[[Event], None]


class EventBus:
    """Listeners of one runtime. A listener that raises is reported once and dropped, not fatal."""

    def __init__(self) -> None:
        self._listeners: list[Listener] = []

    def subscribe(self, listener: Listener) -> Callable[[], None]:
        """Add ``listener``; returns a function that removes it."""
        self._listeners.append(listener)

        def unsubscribe() -> None:
            if listener in self._listeners:
                self._listeners.remove(listener)

        return unsubscribe

    def emit(self, event: Event) -> None:
        for listener in tuple(self._listeners):
            try:
                listener(event)
            except Exception as exc:
                self._listeners.remove(listener)
                print(f"flowmc: event listener {listener!r} failed and was removed: {exc}", file=sys.stderr)
