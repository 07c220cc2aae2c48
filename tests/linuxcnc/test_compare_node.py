"""The compare node runs the real LinuxCNC simulator from a graph and reports both sides."""

import json
from pathlib import Path

import numpy as np
import pytest

import flowmc

pytestmark = pytest.mark.linuxcnc

REFERENCE = Path(__file__).resolve().parents[1] / "data" / "reference"


def test_compare_node_reports_linuxcnc_and_flowmc_side_by_side():
    star = json.loads((REFERENCE / "paths" / "star10.json").read_text())
    g = flowmc.GraphBuilder()
    src = g.add("path.polyline", id="star", points=[[x, y, 0.0] for x, y in star["points"]], feed=200.0)
    cmp_ = g.add("device.linuxcnc_compare", id="cmp", tolerance=0.05)
    g.wire(src.path, cmp_.path)
    result = flowmc.run(g.build())
    assert result.ok, result.errors
    rows = {r["quantity"]: r for r in result.nodes["cmp"].outputs["report"].to_rows()}
    cycle = rows["feed cycle time"]
    assert abs(cycle["linuxcnc"] - 11.89) / 11.89 < 0.02
    assert cycle["flowmc"] < cycle["linuxcnc"]
    executed = result.nodes["cmp"].outputs["linuxcnc"]
    np.testing.assert_allclose(executed.positions[-1][:2], star["points"][-1], atol=1e-3)
