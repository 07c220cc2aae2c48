"""The Python API as users call it: the runtime with the default registry filled in.

``flowmc.Runtime()``, ``flowmc.run(...)`` and ``flowmc.validate(...)`` are these; pass
``registry=`` to run with another one (tests build their own, ``flowmc.plugins`` builds
the default).
"""

from __future__ import annotations

import os
from typing import Any

from flowmc.graph import Graph, Issue, load
from flowmc.plugins import default_registry
from flowmc.registry import Registry
from flowmc.runtime import RunResult, Start
from flowmc.runtime import Runtime as BaseRuntime

__all__ = ["Runtime", "run", "validate"]


class Runtime(BaseRuntime):
    """``flowmc.runtime.Runtime`` with the default registry unless one is given."""

    def __init__(self, registry: Registry | None = None) -> None:
        super().__init__(registry if registry is not None else default_registry())


def run(graph: Graph | str | os.PathLike, inputs: dict[str, Any] | None = None,
        runtime: BaseRuntime | None = None, *, registry: Registry | None = None,
        base_dir: str | os.PathLike | None = None, start: Start | bool | None = None) -> RunResult:
    """Run ``graph`` (a Graph or a file path) once; pass a ``runtime`` to keep its cache between runs.

    Device nodes only prepare their jobs (nothing moves) unless ``start`` is given: True (jobs at the
    instant pace) or a ``flowmc.runtime.Start`` (options for the job runners, a hook for each job)."""
    return (runtime or Runtime(registry)).run(graph, inputs, base_dir=base_dir, start=start)


def validate(graph: Graph | str | os.PathLike, *, registry: Registry | None = None,
             base_dir: str | os.PathLike | None = None) -> list[Issue]:
    """Every problem in ``graph`` (empty list: it can run). Nothing runs."""
    if isinstance(graph, (str, os.PathLike)):
        graph = load(graph)
    return Runtime(registry).validate(graph, base_dir=base_dir)
