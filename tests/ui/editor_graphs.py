"""Graphs the editor tests open: built with flowmc.GraphBuilder from node types that exist, saved to tmp dirs."""

from __future__ import annotations

from pathlib import Path

import flowmc

ROWS = [
    {"type": "line", "end": [40.0, 0.0, 0.0]},
    {"type": "arc", "direction": "ccw", "radius": 10.0, "start_angle": -90.0, "end_angle": 90.0},
    {"type": "line", "end": [0.0, 20.0, 0.0]},
    {"type": "line", "end": [0.0, 0.0, 0.0]},
]


def example_builder(title: str = "example") -> flowmc.GraphBuilder:
    """table (segment table) -> shift (translate) -> both (join, with a polyline 'edge')."""
    g = flowmc.GraphBuilder(title=title)
    table = g.add("path.segment_table", id="table", rows=ROWS, feed=40.0, pos=(0, 0))
    edge = g.add("path.polyline", id="edge", points=[[0, -10, 0], [50, -10, 0]], feed=30.0, pos=(0, 260))
    shift = g.add("path.translate", id="shift", dx=5.0, pos=(320, 0))
    both = g.add("path.join", id="both", pos=(640, 120))
    g.wire(table.path, shift.path)
    g.wire(shift.path, both.path1)
    g.wire(edge.path, both.path2)
    g.output("path", "Path", both.path)
    return g


def example_file(folder: Path, name: str = "example.flowmc.json") -> Path:
    path = Path(folder) / name
    example_builder().save(path)
    return path


def chain_file(folder: Path, n: int = 100, name: str = "big.flowmc.json") -> Path:
    """``n`` nodes: polylines each feeding a chain of translates, laid out on a grid (the benchmark graph)."""
    g = flowmc.GraphBuilder(title=f"{n} nodes")
    prev = None
    for i in range(n):
        pos = ((i % 10) * 300.0, (i // 10) * 200.0)
        if i % 10 == 0:
            prev = g.add("path.polyline", id=f"p{i}", points=[[0, 0, 0], [10, i, 0]], pos=pos)
        else:
            node = g.add("path.translate", id=f"t{i}", dx=1.0, pos=pos)
            g.wire(prev.path, node.path)
            prev = node
    path = Path(folder) / name
    g.save(path)
    return path
