"""Sweep definitions: grid values and ranges, CSV tables and file folders, their product, keys and batches."""

from __future__ import annotations

import re

import pytest
from sweep_helpers import ARM, PROGRAMS, gcode_graph

import flowmc
from flowmc.settings import UsageError
from flowmc.sweep import Sweep
from flowmc.sweep.batches import batch_size, batches, upstream_first
from flowmc.sweep.variants import files_axis, grid_axis, table_axis, variants
from flowmc.sweep.worker import run_batch


@pytest.fixture(scope="module")
def arm():
    return flowmc.load(ARM)


def values(axis):
    return [row[0] for row in axis.rows]


def test_grid_values_are_typed_by_the_port_they_reach(arm):
    assert values(grid_axis(arm, "lookahead.tolerance=0.01,0.05, 0.1")) == [0.01, 0.05, 0.1]
    assert values(grid_axis(arm, "rule=blend,arm_weighted")) == ["blend", "arm_weighted"]
    assert values(grid_axis(arm, "check.max=1,2")) == [1, 2]


def test_ranges_include_their_stop_and_read_cleanly(arm):
    assert values(grid_axis(arm, "lookahead.tolerance=0.01:0.05:0.01")) == [0.01, 0.02, 0.03, 0.04, 0.05]
    assert values(grid_axis(arm, "lookahead.tolerance=0.1:0.3:0.1,1")) == [0.1, 0.2, 0.3, 1]
    assert values(grid_axis(arm, "check.max=1:7:3")) == [1, 4, 7]
    assert values(grid_axis(arm, "check.max=5:1:-2")) == [5, 3, 1]


def test_fixed_params_are_typed_by_their_declared_type(tmp_path):
    """A fixed Text param (a file name) stays text whatever it looks like; a fixed Number param is a number."""
    graph = flowmc.load(gcode_graph(tmp_path))
    assert values(grid_axis(graph, "gcode.file=12,true,null,[1]")) == ["12", "true", "null", "[1]"]
    (tmp_path / "t.csv").write_text("gcode.file\n12\n")
    assert values(table_axis(graph, tmp_path / "t.csv")) == ["12"]
    (tmp_path / "12").write_text(PROGRAMS["a_square.ngc"])
    sweep = Sweep(graph, [grid_axis(graph, "gcode.file=12,programs/a_square.ngc")])
    first, second = run_batch(sweep.job, sweep.variants)  # the worker's own code, in this process
    assert (first["status"], first["error"]) == ("done", "")
    assert first["outputs"] == second["outputs"]  # the same program under either name
    joined = flowmc.GraphBuilder()
    joined.add("path.join", id="join")
    join = joined.build()
    assert values(grid_axis(join, "join.count=2,3")) == [2, 3]
    with pytest.raises(UsageError, match="'two' is not a number"):
        grid_axis(join, "join.count=two")


@pytest.mark.parametrize("spec, message", [
    ("lookahead.tolerance=0.1:0.01:0.01", "never reaches its stop"),
    ("lookahead.tolerance=0:1:0", "never reaches its stop"),
    ("lookahead.tolerance=0:1", "a range is start:stop:step"),
    ("lookahead.tolerance=a,b", "'a' is not a number"),
    ("lookahead.speed=1", "node 'lookahead' (plan.lookahead) has no param 'speed'"),
    ("nowhere.x=1", "no node 'nowhere'"),
    ("lookahead.rule=blend", "fed by the graph input 'rule'"),
    ("lookahead.path=1", "has no param 'path'"),
    ("colour=red", "the graph has no input 'colour' (inputs: rule)"),
    ("tolerance", "expected TARGET=V1,V2"),
])
def test_bad_grid_axes_say_what_and_where(arm, spec, message):
    with pytest.raises(UsageError, match=re.escape(message)) as err:
        grid_axis(arm, spec)
    assert str(err.value).startswith("--grid")


def test_the_product_of_axes_with_stable_keys(arm):
    axes = [grid_axis(arm, "lookahead.tolerance=0.01,0.02,0.03"), grid_axis(arm, "rule=blend,junction_deviation")]
    found = variants(arm, axes)
    assert len(found) == 6
    assert found[1].params == {"lookahead.tolerance": 0.01, "rule": "junction_deviation"}
    assert [v.key for v in found] == [v.key for v in variants(arm, axes)]
    assert len({v.key for v in found}) == 6
    changed = arm.model_copy(deep=True)
    changed.node("metrics").params["bound"] = 7.0
    assert variants(changed, axes)[0].key != found[0].key  # another graph: resume must not reuse the rows
    with pytest.raises(UsageError, match="already swept"):
        variants(arm, [axes[0], grid_axis(arm, "lookahead.tolerance=0.5")])


def test_a_csv_table_is_one_variant_per_row(arm, tmp_path):
    table = tmp_path / "variants.csv"
    table.write_text("lookahead.tolerance,rule,lookahead.profile\n0.01,blend,scurve\n0.2,,trapezoid\n\n")
    axis = table_axis(arm, table)
    found = variants(arm, [axis, grid_axis(arm, "check.max=0.6,0.7")])
    assert len(found) == 4
    assert found[2].params == {"lookahead.tolerance": 0.2, "lookahead.profile": "trapezoid", "check.max": 0.6}
    table.write_text("lookahead.tolerance,rule\n0.01,blend\nfast,blend\n")
    with pytest.raises(UsageError, match=f"{table}:3: lookahead.tolerance: 'fast' is not a number"):
        table_axis(arm, table)
    table.write_text("lookahead.tolerance,rule\n0.01\n")
    with pytest.raises(UsageError, match=f"{table}:2: 1 cells, the header has 2"):
        table_axis(arm, table)
    table.write_text("lookahead.nothing\n1\n")
    with pytest.raises(UsageError, match=f"{table}:1: column 'lookahead.nothing'"):
        table_axis(arm, table)


def test_files_axis_gives_paths_relative_to_the_graph(tmp_path, monkeypatch):
    graph = flowmc.load(gcode_graph(tmp_path / "job"))
    monkeypatch.chdir(tmp_path)
    axis = files_axis(graph, "gcode.file=job/programs/*.ngc")
    assert values(axis) == ["programs/a_square.ngc", "programs/b_chamfer.ngc", "programs/c_triangle.ngc"]
    (tmp_path / "elsewhere.ngc").write_text("G0 X1\n")
    with pytest.raises(UsageError, match="elsewhere.ngc is outside the graph's folder"):
        files_axis(graph, "gcode.file=*.ngc")
    with pytest.raises(UsageError, match="no file matches 'job/\\*.nc'"):
        files_axis(graph, "gcode.file=job/*.nc")
    with pytest.raises(UsageError, match="takes file names, but it is a Number"):
        files_axis(graph, "plan.tolerance=job/programs/*.ngc")


def test_batches_keep_groups_and_go_upstream_first(tmp_path, monkeypatch):
    graph = flowmc.load(gcode_graph(tmp_path))
    monkeypatch.chdir(tmp_path)
    # the downstream axis is given first: the order still puts the G-code file (upstream) outermost
    axes = [grid_axis(graph, "plan.tolerance=0.01:0.05:0.01"), files_axis(graph, "gcode.file=programs/*.ngc")]
    found = variants(graph, axes)
    plan = flowmc.Runtime().plan(graph)
    assert upstream_first(plan, axes) == [1, 0]
    cut = batches(found, upstream_first(plan, axes), 3)
    assert sorted(v.index for b in cut for v in b) == list(range(15))
    for batch in cut:
        assert len({v.params["gcode.file"] for v in batch}) == 1  # a batch never mixes files
    files_in_order = [b[0].params["gcode.file"] for b in cut]
    assert files_in_order == sorted(files_in_order)  # a file's batches go out together
    assert [len(b) for b in cut] == [3, 2] * 3
    assert batch_size(300, 2) == 8 and batch_size(10, 2) == 1 and batch_size(100, 1) == 8
