"""The editor's Sweep tab: controls from the front panel, a real sweep in worker processes, progress,
stop, refusal, and the plot, driven through its viser handles and shown in a real browser."""

from __future__ import annotations

import csv
import os
from pathlib import Path

import pytest

import flowmc
from browser_helpers import EditorPage, chromium, wait_until
from flowmc.graph import InterfaceInput
from flowmc.ui.app import Editor
from flowmc.ui.front_panel import ControlSpec
from flowmc.ui.sweep_panel import suggested_values
from flowmc.ui.text import unescape_md

REPO = Path(__file__).resolve().parents[2]


def arm_lookahead(check_max: float) -> flowmc.Graph:
    """The example with its check's limit set here: the planner's times move, the tests' outcomes must not
    (ratios today: blend 0.693, arm_weighted 0.698, junction_deviation 0.501; blend at tolerance 0.02 0.827)."""
    graph = flowmc.load(REPO / "graphs" / "arm_lookahead.flowmc.json")
    next(n for n in graph.nodes if n.id == "check").params["max"] = check_max
    return graph


@pytest.fixture
def editor(tmp_path, open_editor):
    flowmc.save(arm_lookahead(0.695), tmp_path / "arm_lookahead.flowmc.json")  # arm_weighted misses it
    return open_editor(tmp_path / "arm_lookahead.flowmc.json")


@pytest.fixture
def tol_editor(tmp_path, open_editor):
    """arm_lookahead with a second front-panel control: the look-ahead tolerance."""
    graph = arm_lookahead(0.9)
    graph.interface.inputs.append(InterfaceInput(name="tol", type="Number", default=0.05, to=["lookahead.tolerance"]))
    flowmc.save(graph, tmp_path / "arm.flowmc.json")
    return open_editor(tmp_path / "arm.flowmc.json")


def test_suggested_values_come_from_the_control():
    assert suggested_values(ControlSpec("f", "slider", 0.05, "Number", 0.0, 10.0, low_open=True, step=0.05)) \
        == "0.025, 0.05, 0.1"
    assert suggested_values(ControlSpec("f", "slider", 8.0, "Number", 0.0, 10.0, step=0.05)) == "4, 8"
    assert suggested_values(ControlSpec("f", "slider", 0.0, "Number", 0.0, 10.0, step=0.05)) == "0, 2.5, 5, 7.5, 10"
    assert suggested_values(ControlSpec("n", "slider", 2, "Number", 1.0, 3.0, integer=True, step=1)) == "1, 2, 3"
    assert suggested_values(ControlSpec("n", "slider", 20, "Number", 1.0, 100.0, integer=True, step=1)) == "10, 20, 40"
    assert suggested_values(ControlSpec("r", "number", 4.0, "Number")) == "2, 4, 8"
    assert suggested_values(ControlSpec("m", "dropdown", "a", "Text", options=("a", "b"))) == "a, b"
    assert suggested_values(ControlSpec("on", "checkbox", True, "Bool")) == "true, false"


def test_a_sweep_of_a_front_panel_control_runs_and_plots(editor, tmp_path):
    panel = editor.sweep_panel
    assert list(panel.controls) == ["rule"]
    box, values = panel.controls["rule"]
    assert box.value and values.value == "blend, arm_weighted, junction_deviation"
    progress = []
    panel._show_progress = lambda p, show=panel._show_progress: (progress.append(p), show(p))
    panel.begin().join(180)
    assert [r["status"] for r in panel.outcome.rows] == ["done", "failed", "done"]  # arm_weighted misses 0.695
    assert progress[-1].left == 0 and progress[-1].done == 2
    shown = unescape_md(panel.status.content)
    assert "2 done, 1 failed" in shown and "First failure, variant 1: node 'check': check failed" in shown
    with open(tmp_path / "arm_lookahead-sweep" / "rows.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [r["rule"] for r in rows] == ["blend", "arm_weighted", "junction_deviation"]
    assert (tmp_path / "arm_lookahead-sweep" / "report.html").exists()
    assert "metrics.contour_error" in panel.output.options  # table outputs can be plotted after the sweep
    assert len(panel.plots) == 1
    panel.pareto.value = "metrics.contour_error"
    assert len(panel.plots) == 2 and "Pareto" in panel.plots[1].figure.layout.title.text
    assert not panel.start.disabled and panel.stop.disabled


def test_unticked_controls_keep_their_front_panel_value(tol_editor):
    editor = tol_editor
    panel = editor.sweep_panel
    assert list(panel.controls) == ["rule", "tol"]
    editor.extensions.front.controls["rule"].value = "junction_deviation"
    panel.controls["rule"][0].value = False
    panel.begin()
    assert "tick at least one control" in unescape_md(panel.status.content) and panel.thread is None
    panel.controls["tol"][0].value = True
    panel.controls["tol"][1].value = "0.02, 0.1"
    panel.begin().join(180)
    rows = panel.outcome.rows
    assert [r["rule"] for r in rows] == ["junction_deviation"] * 2 and [r["tol"] for r in rows] == [0.02, 0.1]
    assert rows[0]["out.lookahead_s"] > rows[1]["out.lookahead_s"]  # a looser tolerance is faster


def test_stop_keeps_the_rows_done(tol_editor):
    panel = tol_editor.sweep_panel
    panel.controls["rule"][0].value = False
    panel.controls["tol"][0].value = True
    panel.controls["tol"][1].value = "0.002:0.6:0.002"
    thread = panel.begin()
    wait_until(lambda: panel.progress.value > 3, timeout=120)
    panel.stop.value = True  # a click
    thread.join(120)
    outcome = panel.outcome
    assert outcome.interrupted and 0 < len(outcome.rows) < 300 and outcome.left > 0
    assert unescape_md(panel.status.content).startswith("Stopped:")


def test_hardware_devices_are_refused_in_the_panel(tmp_path):
    g = flowmc.GraphBuilder()
    path = g.add("path.polyline", id="path", points=[[0, 0, 0], [10, 0, 0]])
    plan = g.add("plan.lookahead", id="plan")
    card = g.add("device.card_output", id="card", device="grbl:/dev/ttyUSB0")
    g.wire(path.path, plan.path)
    g.wire(plan.trajectory, card.motion)
    g.input("tol", "Number", plan.tolerance, default=0.05)
    g.save(tmp_path / "card.flowmc.json")
    ed = Editor(tmp_path / "card.flowmc.json", port=0)
    try:
        assert ed.sweep_panel.begin() is None
        assert "node 'card': device 'grbl:/dev/ttyUSB0' moves hardware" in unescape_md(ed.sweep_panel.status.content)
    finally:
        ed.close()


SCALE_NODE = """
from pydantic import BaseModel, ConfigDict, Field
from flowmc.registry import In, NodeType, Out, register

class ScaleParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    factor: float = Field(2.0, gt=0)

@register
class Scale(NodeType):
    type_id, title, category = "panel.scale", "Scale", "Path"
    description = "Scale a path about the origin."
    Params = ScaleParams
    inputs, outputs = (In("path", "Path", doc="Path"),), (Out("path", "Path", doc="Scaled path"),)
    def run(self, ctx, params, path):
        return {"path": path.scaled(params.factor)}
"""


def test_the_workers_use_the_editors_node_folders(tmp_path, monkeypatch):
    """An editor started with ``--nodes DIR`` sweeps a graph of that folder's node types (the worker
    processes start fresh, so they must load the folder too)."""
    from flowmc import plugins

    folder = tmp_path / "nodes"
    folder.mkdir()
    (folder / "scale.py").write_text(SCALE_NODE, encoding="utf-8")
    registry = plugins.default_registry().copy()
    assert plugins.add_node_folder(registry, folder) == ["panel.scale"], registry.failures
    monkeypatch.setattr(plugins, "_default", registry)  # what `flowmc serve --nodes DIR` leaves (this process only)
    g = flowmc.GraphBuilder()
    pts = g.add("path.polyline", id="pts", points=[(0, 0, 0), (10, 0, 0)], feed=10.0)
    scale = g.add("panel.scale", id="scale")
    measure = g.add("path.measure", id="measure")
    g.wire(pts.path, scale.path)
    g.wire(scale.path, measure.path)
    g.input("factor", "Number", scale.factor, default=2.0)
    g.output("length", "Number", measure.length)
    g.save(tmp_path / "part.flowmc.json")
    ed = Editor(tmp_path / "part.flowmc.json", port=0)
    try:
        panel = ed.sweep_panel
        panel.controls["factor"][1].value = "1, 3"
        panel.workers.value = 1
        panel.begin().join(180)
        assert [(r["status"], r["error"]) for r in panel.outcome.rows] == [("done", "")] * 2
        assert [r["out.length"] for r in panel.outcome.rows] == pytest.approx([10.0, 30.0])
    finally:
        ed.close()


def test_a_sweep_on_a_running_dask_cluster(tol_editor, tmp_path):
    """The scheduler address of a running cluster: the rows come from its workers (the graph's folder is
    shipped to them)."""
    from distributed import Client, LocalCluster

    panel = tol_editor.sweep_panel
    panel.controls["rule"][0].value = False
    panel.controls["tol"][0].value = True
    panel.controls["tol"][1].value = "0.02, 0.1"
    panel.address.value = "tcp://127.0.0.1:1"
    panel.begin()
    assert "goes with the Dask executor" in unescape_md(panel.status.content) and panel.thread is None
    panel.executor.value = "Dask"
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        panel.address.value = cluster.scheduler_address
        panel.begin().join(180)
        pids = set(client.run(os.getpid).values())
    rows = panel.outcome.rows
    assert [(r["status"], r["tol"]) for r in rows] == [("done", 0.02), ("done", 0.1)]
    assert {int(r["worker"].rpartition(":")[2]) for r in rows} == pids
    assert panel.sweep.job.shipped is not None


@pytest.mark.browser
def test_the_sweep_tab_in_a_browser_shows_the_plot(editor, tmp_path):
    panel = editor.sweep_panel
    panel.begin().join(180)
    panel.pareto.value = "metrics.contour_error"
    with chromium() as browser:
        ui = EditorPage(browser, editor)
        ui.open()
        ui.dismiss_toasts()
        ui.page.get_by_role("tab", name="Sweep").click()
        ui.page.wait_for_function("document.querySelectorAll('.js-plotly-plot').length >= 2", timeout=30000)
        assert ui.page.get_by_text("2 done, 1 failed").count() >= 1
        ui.page.screenshot(path=str(tmp_path / "sweep_tab.png"))
