"""Resource budgets (issue 18 items 4 and 5): every probe of the issue ends at once in a clean error that
names the node and says what to change, checked before anything big is allocated. Peak memory and
time of the same probes are measured in benchmarks/security.py."""

from __future__ import annotations

import json
import os
import time

import numpy as np
import pytest

import flowmc
import flowmc.budget as budget
from flowmc.errors import BudgetError, GcodeError, GraphError, PathError
from flowmc.motion.contour import simplify, simplify_all
from flowmc.motion.gcode import parse_gcode
from flowmc.motion.lookahead import plan_lookahead
from flowmc.motion.machine import Machine
from flowmc.motion.path import Arc, Line, Path
from probes import PROBES, run_probe


@pytest.mark.parametrize("probe", PROBES, ids=[p.name for p in PROBES])
def test_each_probe_of_the_issue_is_a_clean_error(probe, tmp_path):
    outcome = run_probe(probe, tmp_path)
    assert outcome.code in (1, 2), outcome  # 1: a node failed, 2: the graph is invalid; never killed
    last = outcome.stderr.strip().splitlines()[-1]
    assert "internal error" not in outcome.stderr and "Traceback" not in outcome.stderr
    assert "budget" in last and ("raise" in last or "FLOWMC_" in last), last
    if probe.node is not None and outcome.code == 1:
        assert last.startswith(f"error: node '{probe.node}': "), last


def test_caps_come_from_the_memory_budget_and_the_axes():
    with budget.limits(memory_mb=100):
        three, six = budget.cap("setpoints", 3), budget.cap("setpoints", 6)
        assert six < three and three == 100 * 2**20 // (80 + 3 * 30)
        with budget.limits(memory_mb=200):
            assert budget.cap("setpoints", 3) == 2 * three or budget.cap("setpoints", 3) == 2 * three + 1
        assert budget.cap("setpoints", 3) == three
    with budget.limits(turns=5):
        assert budget.cap("turns") == 5
    with pytest.raises(ValueError):
        with budget.limits(memory_mb=0):
            pass
    with pytest.raises(ValueError):
        with budget.limits(nonsense=1):
            pass


def test_the_error_says_how_many_the_cap_and_what_to_change():
    with budget.limits(memory_mb=1):
        with pytest.raises(BudgetError) as err:
            budget.check("points", 10**9, what="sampling", change="loosen it")
    text = str(err.value)
    assert "1,000,000,000 points" in text and "loosen it" in text and "--memory-mb" in text
    with pytest.raises(BudgetError, match="unboundedly many"):
        budget.check("setpoints", float("inf"), what="x", change="y")
    with pytest.raises(BudgetError, match="FLOWMC_BUDGET_TURNS"):
        budget.check("turns", 1e300, what="an arc", change="fewer turns")


def test_the_environment_sets_the_budget(tmp_path):
    import subprocess
    import sys

    code = "import flowmc.budget as budget; print(budget.current().memory_mb, budget.cap('turns'))"
    env = {**os.environ, "FLOWMC_MEMORY_MB": "64", "FLOWMC_BUDGET_TURNS": "7"}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["64.0", "7"]


def test_planners_check_before_they_allocate():
    path = Path([Line((0, 0, 0), (1000, 0, 0), feed=0.05 / 60)])
    start = time.perf_counter()
    with pytest.raises(BudgetError, match="raise the feeds"):
        plan_lookahead(path, Machine())
    assert time.perf_counter() - start < 5  # refused up front, not after filling memory
    with budget.limits(memory_mb=4096):  # the same plan with a budget that allows it starts allocating
        assert budget.cap("setpoints") > 1_000_000 * 4


def test_arc_turns_and_sampling_are_bounded():
    with pytest.raises(BudgetError, match="turns"):
        Arc((10, 0, 0), (10, 0, 0), (0, 0, 0), turns=10**6)
    with pytest.raises(GcodeError, match="p.ngc:1: the arc makes 100,000 turns"):  # names the line
        parse_gcode("G2 X0 Y0 I10 J0 P100000 F600\n", "p.ngc")
    arc = Arc((10, 0, 0), (10, 0, 0), (0, 0, 0), turns=9000)
    with pytest.raises(BudgetError, match="chord tolerance"):
        arc.sample(1e-9)


def test_graph_files_are_bounded_in_size_depth_and_text(tmp_path):
    deep = {"schema_version": 1, "nodes": [{"id": "n", "type": "basic.number", "params": {"value": 1, "x": []}}]}
    inner = deep["nodes"][0]["params"]["x"]
    for _ in range(900):
        inner.append([])
        inner = inner[0]
    with pytest.raises(GraphError, match="nested deeper than 64 levels"):
        flowmc.loads(json.dumps(deep))
    with pytest.raises(GraphError, match="nested deeper"):
        flowmc.loads("[" * 100_000 + "]" * 100_000)
    with pytest.raises(GraphError, match="lone surrogate"):
        flowmc.loads('{"schema_version": 1, "title": "\\ud800"}')
    with budget.limits(memory_mb=1):
        with pytest.raises(GraphError, match="over the budget"):
            flowmc.loads(json.dumps({"schema_version": 1, "description": "x" * 2_000_000}))
    rows = [{"type": "line", "end": [i, 0, 0]} for i in range(2000)]
    g = {"schema_version": 1, "nodes": [{"id": "t", "type": "path.segment_table", "params": {"rows": rows}}]}
    (tmp_path / "t.flowmc.json").write_text(json.dumps(g))
    with budget.limits(memory_mb=3):  # the file fits (131 kB), its 2,000 rows do not (1,572)
        issues = flowmc.validate(tmp_path / "t.flowmc.json")
    assert [i.code for i in issues] == ["budget"] and "node 't': param 'rows' has 2,000 items" in issues[0].message


def test_sub_graph_fan_out_is_bound_once_per_file(tmp_path, monkeypatch):
    from flowmc.nodes import subgraph
    from probes import _fan_out

    top = _fan_out(10)(tmp_path)
    reads = []
    original = subgraph._read
    monkeypatch.setattr(subgraph, "_read", lambda path: reads.append(path) or original(path))
    assert flowmc.validate(top) == []
    assert len(reads) == len(set(reads)) == 10  # 2**10 uses, 10 files: each read and planned once
    assert flowmc.Runtime().plan(flowmc.load(top)).size == 4 * 2 ** 10 - 3  # 3 per level, 1 at the leaves
    result = flowmc.run(top)
    assert result.ok and result.outputs["y"] == 2 ** 10
    with budget.limits(expansion=1000):
        issues = flowmc.validate(top)
    assert issues and "expands to" in issues[0].message and "FLOWMC_BUDGET_EXPANSION" in issues[0].message


def test_a_changed_sub_graph_is_seen_even_with_the_same_size_and_time(tmp_path):
    def inner(value):
        g = flowmc.GraphBuilder()
        n = g.add("basic.number", id="n", value=value)
        g.output("y", "Number", n.value)
        return g

    inner(1.0).save(tmp_path / "inner.flowmc.json")
    s = flowmc.GraphBuilder()
    sub = s.add("subgraph", id="s", file="inner.flowmc.json")
    s.output("y", "Number", sub.y)
    graph = s.build()
    graph.path = tmp_path / "outer.flowmc.json"
    runtime = flowmc.Runtime()
    assert runtime.run(graph).outputs["y"] == 1.0
    file = tmp_path / "inner.flowmc.json"
    before = file.stat()
    text = file.read_text().replace("1.0", "2.0")
    assert len(text) == before.st_size
    file.write_text(text)
    os.utime(file, ns=(before.st_atime_ns, before.st_mtime_ns))
    assert file.stat().st_mtime_ns == before.st_mtime_ns and file.stat().st_size == before.st_size
    assert runtime.run(graph).outputs["y"] == 2.0


def test_pictures_are_bounded_in_pixels_and_outline(tmp_path):
    from PIL import Image

    from flowmc.motion.contour import image_to_path

    Image.fromarray(np.full((300, 300), 255, np.uint8)).save(tmp_path / "big.png")
    with budget.limits(memory_mb=1), pytest.raises(BudgetError, match="300 x 300 px picture"):
        image_to_path(tmp_path / "big.png")
    yy, xx = np.indices((200, 200))
    Image.fromarray((((yy + xx) % 2) * 255).astype(np.uint8)).save(tmp_path / "checker.png")
    with budget.limits(memory_mb=2), pytest.raises(BudgetError, match="outline pixels"):
        image_to_path(tmp_path / "checker.png", "report_4neighbour")


def test_douglas_peucker_in_pieces_matches_scikit_image_and_stays_within_tolerance():
    from skimage.measure import approximate_polygon

    rng = np.random.default_rng(7)
    lines = []
    for k in range(200):
        pts = np.cumsum(rng.normal(size=(int(rng.integers(3, 200)), 2)), 0)
        lines.append(np.round(pts) if k % 2 else pts)
    for pts, got in zip(lines, simplify_all(lines, 0.8)):
        assert np.array_equal(got, approximate_polygon(pts, 0.8))
    zigzag = np.column_stack([np.arange(5000.0), np.arange(5000) % 2 * 3.0])
    start = time.perf_counter()
    kept = simplify(zigzag, 0.5)
    assert time.perf_counter() - start < 5 and np.array_equal(kept[[0, -1]], zigzag[[0, -1]])
    # every dropped point is within the tolerance of the simplified chain
    wave = np.column_stack([np.linspace(0, 100, 3000), np.sin(np.linspace(0, 20, 3000))])
    out = simplify(wave, 0.05)
    a, b = out[:-1], out[1:]
    ab = b - a
    t = np.clip(np.einsum("pkj,kj->pk", wave[:, None] - a[None], ab) / np.einsum("kj,kj->k", ab, ab), 0, 1)
    nearest = a[None] + t[..., None] * ab[None]
    assert np.linalg.norm(wave[:, None] - nearest, axis=2).min(axis=1).max() <= 0.05 + 1e-12
    assert len(out) < len(wave) / 5


def test_line_chain_builds_the_same_lines():
    pts = np.array([[0, 0, 0], [1, 2, 3], [4, 5, 6.5]])
    fast = Line.chain(pts, feed=7.0, source="x")
    slow = [Line(a, b, feed=7.0, source="x") for a, b in zip(pts[:-1], pts[1:])]
    assert [(f.start.tolist(), f.end.tolist(), f.length, f.feed, f.source, f.tool_down) for f in fast] == \
        [(s.start.tolist(), s.end.tolist(), s.length, s.feed, s.source, s.tool_down) for s in slow]
    assert not fast[0].start.flags.writeable
    with pytest.raises(PathError):
        Line.chain([[0, 0, 0], [np.nan, 0, 0]])
