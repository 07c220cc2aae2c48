"""The runtime: validate (every problem at once), schedule on networkx, execute with a cache.

Public API (the CLI and the editor use only this)::

    rt = Runtime(registry)          # flowmc.Runtime() gives the default registry
    plan = rt.plan(graph)          # validated + ordered, reused per graph revision
    plan.issues, plan.order, plan.generations, plan.ports("n3")
    unsubscribe = rt.subscribe(lambda event: ...)
    result = rt.run(graph, inputs={"feed": 20.0})   # second call: cached nodes do not run
    result.jobs                    # device nodes: prepared jobs; nothing has moved
    started = rt.start(result, Start(options={"pace": "realtime"}, on_job=...))   # the explicit Start
"""

from __future__ import annotations

from typing import Any

from flowmc.lazy import load as _load
from flowmc.lazy import names as _names

# Names are imported on first use, as ``flowmc`` does: the modules that plan a graph (schedule, validate,
# binding, context) are imported without the executor, events and jobs, which ``flowmc validate`` and
# the node modules holding graphs never need.
_LAZY = {
    "Runtime": "flowmc.runtime.executor",
    "RunResult": "flowmc.runtime.executor",
    "NodeResult": "flowmc.runtime.executor",
    "summarize": "flowmc.runtime.executor",
    "value_matches": "flowmc.runtime.validate",
    "Plan": "flowmc.runtime.schedule",
    "Start": "flowmc.runtime.start",
    "Issue": "flowmc.graph",
    "Event": "flowmc.runtime.events",
    "EVENT_KINDS": "flowmc.runtime.events",
    "EventBus": "flowmc.runtime.events",
    "NodeContext": "flowmc.runtime.context",
    "Site": "flowmc.runtime.context",
    "resolve_inside": "flowmc.runtime.context",
    "Binding": "flowmc.runtime.binding",
    "BindContext": "flowmc.runtime.binding",
    "GraphBinder": "flowmc.runtime.binding",
}

__all__ = [
    "Runtime",
    "RunResult",
    "NodeResult",
    "Plan",
    "Start",
    "Issue",
    "Event",
    "EVENT_KINDS",
    "EventBus",
    "NodeContext",
    "Site",
    "resolve_inside",
    "Binding",
    "BindContext",
    "GraphBinder",
    "summarize",
    "value_matches",
]


def __getattr__(name: str) -> Any:
    return _load(__name__, globals(), _LAZY, name)


def __dir__() -> list[str]:
    return _names(globals())
