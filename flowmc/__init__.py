"""flowmc: LabVIEW-style dataflow graphs for motion control.

The Python API, kept light to import (no UI, no devices, nothing heavy until used)::

    import flowmc
    graph = flowmc.load("part.flowmc.json")
    result = flowmc.run(graph, inputs={"feed": 20.0})
    result.ok, result.outputs, result.nodes["plan"].status

    g = flowmc.GraphBuilder(title="demo")
    a = g.add("basic.number", id="a", value=2.0)
    s = g.add("basic.add", id="s")
    g.wire(a.value, s.a)
"""

from __future__ import annotations

from typing import Any

from flowmc.lazy import load as _load
from flowmc.lazy import names as _names

__version__ = "0.1.0"  # with CHANGELOG.md's newest release; pyproject.toml reads it from here

__all__ = [
    "load",
    "save",
    "loads",
    "dumps",
    "run",
    "validate",
    "Graph",
    "Runtime",
    "RunResult",
    "Issue",
    "Event",
    "GraphBuilder",
    "FlowmcError",
    "GraphError",
]

_LAZY = {
    "load": "flowmc.graph",
    "save": "flowmc.graph",
    "loads": "flowmc.graph",
    "dumps": "flowmc.graph",
    "Graph": "flowmc.graph",
    "run": "flowmc.api",
    "validate": "flowmc.api",
    "Runtime": "flowmc.api",
    "RunResult": "flowmc.runtime",
    "Issue": "flowmc.runtime",
    "Event": "flowmc.runtime",
    "GraphBuilder": "flowmc.builder",
    "FlowmcError": "flowmc.errors",
    "GraphError": "flowmc.errors",
}


def __getattr__(name: str) -> Any:
    return _load(__name__, globals(), _LAZY, name)


def __dir__() -> list[str]:
    return _names(globals())
