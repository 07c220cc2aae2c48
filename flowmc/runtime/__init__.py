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

from flowmc.graph import Issue
from flowmc.runtime.binding import BindContext, Binding, GraphBinder
from flowmc.runtime.context import NodeContext, Site, resolve_inside
from flowmc.runtime.events import EVENT_KINDS, Event, EventBus
from flowmc.runtime.executor import NodeResult, RunResult, Runtime, summarize, value_matches
from flowmc.runtime.schedule import Plan
from flowmc.runtime.start import Start

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
