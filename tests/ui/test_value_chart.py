"""The probes' and indicators' small charts (value_view.chart): inline SVG, so no chart library loads in the page."""

from __future__ import annotations

import re

import numpy as np

from flowmc.motion.path import Line, Path
from flowmc.motion.table import Table
from flowmc.ui import value_view


def _points(svg: str) -> list[np.ndarray]:
    return [np.array([[float(v) for v in p.split(",")] for p in m.split()])
            for m in re.findall(r'<polyline points="([^"]*)"', svg)]


def test_a_path_is_drawn_with_equal_axes_inside_the_plot_box():
    path = Path(Line.chain([[0.0, 0.0, 0.0], [40.0, 0.0, 0.0], [40.0, 10.0, 0.0]], feed=10.0))
    svg = value_view.chart(path)
    assert svg is not None and svg.startswith("<svg") and svg.endswith("</svg>")
    (pts,) = _points(svg)
    span = pts.max(axis=0) - pts.min(axis=0)
    assert abs(span[0] / span[1] - 4.0) < 0.05  # 40 mm by 10 mm keeps its shape
    assert pts[:, 0].min() >= 46 - 0.1 and pts[:, 0].max() <= 300 - 8 + 0.1
    assert "X (mm)" in svg and "Y (mm)" in svg


def test_table_columns_are_series_and_their_names_are_escaped():
    table = Table({"t": np.arange(5.0), "<b>a</b>": np.arange(5.0) ** 2, "b": -np.arange(5.0)})
    svg = value_view.chart(table)
    assert len(_points(svg)) == 2
    assert "<b>" not in svg and "&lt;b&gt;a&lt;/b&gt;" in svg


def test_values_without_a_chart_give_none():
    assert value_view.chart(3.5) is None and value_view.chart("text") is None
    assert value_view.chart(Table({"name": np.array(["a", "b"])})) is None
