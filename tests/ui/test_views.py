"""3D View nodes: what each shows (inside sub-graphs too), the headless PNG snapshot, and the editor's
docked view following the selected one; graphs without one keep the old behaviour."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
from PIL import Image

import flowmc
from flowmc.runtime.views import snapshot, views
from flowmc.ui.session import EditorSession


def planned_graph(second_view: bool = False) -> flowmc.GraphBuilder:
    g = flowmc.GraphBuilder(title="views")
    square = g.add("path.polyline", id="square", points=[(0, 0, 0), (60, 0, 0), (60, 40, 0), (0, 40, 0)], feed=50.0,
                   closed=True)
    plan = g.add("interp.time_division", id="plan", profile="trapezoid")
    machine = g.add("machine", id="machine")
    g.wire(square.path, plan.path)
    view = g.add("view.view3d", id="view", title="Square")
    g.wire(square.path, view.path)
    g.wire(plan.trajectory, view.trajectory)
    g.wire(machine.machine, view.machine)
    if second_view:
        raw = g.add("view.view3d", id="raw", title="Programmed only")
        g.wire(square.path, raw.path)
    return g


def test_a_view_collects_what_is_wired_to_it():
    runtime = flowmc.Runtime()
    graph = planned_graph().build()
    plan = runtime.plan(graph)
    result = runtime.run(plan)
    assert result.ok, result.errors
    (view,) = views(result, plan, runtime)
    assert (view.key, view.title) == ("view", "Square") and not view.empty
    assert view.values["trajectory"] is result.output("plan", "trajectory")
    assert view.values["path"] is result.output("square", "path") and view.values["steps"] is None


def test_a_view_inside_a_sub_graph_is_found_through_the_interface(tmp_path):
    inner = flowmc.GraphBuilder(title="inner")
    plan = inner.add("interp.time_division", id="plan", profile="trapezoid")
    view = inner.add("view.view3d", id="look")
    inner.wire(plan.trajectory, view.trajectory)
    inner.input("path", "Path", [plan.path, view.path])
    inner.output("trajectory", "Trajectory", plan.trajectory)
    inner.save(tmp_path / "inner.flowmc.json")
    outer = flowmc.GraphBuilder(title="outer")
    line = outer.add("path.polyline", id="line", points=[(0, 0, 0), (30, 0, 0)], feed=20.0)
    sub = outer.add("subgraph", id="part", file="inner.flowmc.json")
    outer.wire(line.path, sub.path)
    outer.save(tmp_path / "outer.flowmc.json")
    runtime = flowmc.Runtime()
    plan = runtime.plan(flowmc.load(tmp_path / "outer.flowmc.json"))
    result = runtime.run(plan)
    assert result.ok, result.errors
    (found,) = views(result, plan, runtime)
    assert found.key == "part/look"
    assert found.values["path"] is result.output("line", "path")  # fed through the sub-graph's interface
    assert found.values["trajectory"].digest() == result.output("part", "trajectory").digest()


def test_the_snapshot_draws_the_trajectory_in_speed_colours():
    runtime = flowmc.Runtime()
    plan = runtime.plan(planned_graph().build())
    result = runtime.run(plan)
    image = np.asarray(snapshot(views(result, plan, runtime)[0]).convert("RGB")).astype(int)
    r, g, b = image[..., 0], image[..., 1], image[..., 2]
    assert ((r > 180) & (g < 80) & (b < 80)).sum() > 200  # fast: red
    assert ((b > 150) & (r < 90)).sum() > 20  # slow (the ramps): blue
    assert ((abs(r - 185) < 3) & (abs(g - 185) < 3)).sum() > 100  # the travel box


def test_flowmc_run_writes_a_png_per_view_only_when_asked(tmp_path):
    planned_graph().save(tmp_path / "g.flowmc.json")
    plain = subprocess.run([sys.executable, "-m", "flowmc", "run", "g.flowmc.json", "-q"], cwd=tmp_path,
                           capture_output=True, text=True, timeout=120)
    assert plain.returncode == 0, plain.stderr
    assert not list(tmp_path.rglob("*.png"))  # headless runs ignore views
    shot = subprocess.run([sys.executable, "-m", "flowmc", "run", "g.flowmc.json", "-q", "--snapshot", "views"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert shot.returncode == 0, shot.stderr
    png = tmp_path / "views" / "view.png"
    assert Image.open(png).size == (960, 720) and "views/view.png" in shot.stderr


def test_the_docked_view_follows_the_selected_view_node(tmp_path):
    from flowmc.ui.app import Editor

    planned_graph(second_view=True).save(tmp_path / "two.flowmc.json")
    editor = Editor(tmp_path / "two.flowmc.json", port=0)
    try:
        editor.run()
        editor.wait()
        ext = editor.extensions
        assert ext.view_key == "raw" and "Programmed only" in ext.view.info.content  # the first in run order
        assert "/trajectory/0" not in ext.view.nodes
        editor.select_node("view")
        assert ext.view_key == "view" and "/trajectory/0" in ext.view.nodes
    finally:
        editor.close()


def test_a_graph_without_view_nodes_shows_the_most_downstream_values(tmp_path):
    g = flowmc.GraphBuilder(title="old")
    line = g.add("path.polyline", id="line", points=[(0, 0, 0), (20, 0, 0)], feed=10.0)
    plan = g.add("interp.time_division", id="plan")
    g.wire(line.path, plan.path)
    session = EditorSession(g.build(), folder=tmp_path)
    try:
        session.run()
        result = session.wait()
        assert views(result, session.state.plan(), session.runtime) == []
    finally:
        session.close()
