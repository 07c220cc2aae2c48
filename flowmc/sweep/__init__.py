"""Sweeps: one graph run over many settings, on worker processes or a Dask cluster, into a results table.

    from flowmc.sweep import Journal, Sweep, grid_axis, open_executor
    sweep = Sweep(graph, [grid_axis(graph, "lookahead.tolerance=0.01:0.1:0.01")])
    with open_executor("dask", sweep.job, workers=2, resources=sweep.resources) as executor:
        outcome = sweep.run(executor, Journal(folder))

Layer 6 of docs/architecture.md: it uses the runtime's public API only and never moves a machine.
Light to import (``flowmc sweep --help`` loads nothing heavy): names load on first use.
"""

from __future__ import annotations

import importlib
from typing import Any

_LAZY = {
    "Sweep": "flowmc.sweep.sweep",
    "Progress": "flowmc.sweep.sweep",
    "Outcome": "flowmc.sweep.sweep",
    "Axis": "flowmc.sweep.variants",
    "Variant": "flowmc.sweep.variants",
    "grid_axis": "flowmc.sweep.variants",
    "values_axis": "flowmc.sweep.variants",
    "files_axis": "flowmc.sweep.variants",
    "table_axis": "flowmc.sweep.variants",
    "Journal": "flowmc.sweep.results",
    "flatten_outputs": "flowmc.sweep.results",
    "write_tables": "flowmc.sweep.results",
    "open_executor": "flowmc.sweep.executors",
    "LocalExecutor": "flowmc.sweep.executors",
    "DaskExecutor": "flowmc.sweep.executors",
    "EXECUTORS": "flowmc.sweep.options",
    "POLICIES": "flowmc.sweep.options",
}

__all__ = list(_LAZY)


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'flowmc.sweep' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value
