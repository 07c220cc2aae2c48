"""Motion algorithms and the values that flow on wires; numpy/scipy only, no graph knowledge."""
