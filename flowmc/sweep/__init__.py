"""Sweeps: one graph run over many settings, on worker processes or a Dask cluster, into a results table.

    from flowmc.sweep import Journal, Sweep, grid_axis, open_executor
    sweep = Sweep(graph, [grid_axis(graph, "lookahead.tolerance=0.01:0.1:0.01")])
    with open_executor("dask", sweep.job, workers=2, resources=sweep.resources) as executor:
        outcome = sweep.run(executor, Journal(folder))

The sweep layer of docs/architecture.md: it uses the runtime's public API only and never moves a machine
(docs/sweeps.md).
"""

from flowmc.sweep.executors import EXECUTORS, DaskExecutor, LocalExecutor, open_executor
from flowmc.sweep.results import Journal, flatten_outputs, write_tables
from flowmc.sweep.safety import POLICIES
from flowmc.sweep.sweep import Outcome, Progress, Sweep
from flowmc.sweep.variants import Axis, Variant, files_axis, grid_axis, table_axis, values_axis

__all__ = ["Sweep", "Progress", "Outcome", "Axis", "Variant", "grid_axis", "values_axis", "files_axis",
           "table_axis", "Journal", "flatten_outputs", "write_tables", "open_executor", "LocalExecutor",
           "DaskExecutor", "EXECUTORS", "POLICIES"]
