"""A sweep never moves a machine: hardware device nodes are refused, or switched to the simulated card."""

from __future__ import annotations

import pytest
from sweep_helpers import REPO, device_graph, run_cli

import flowmc
from flowmc.settings import UsageError
from flowmc.sweep import Sweep, grid_axis
from flowmc.sweep.worker import run_batch

HARDWARE = "grbl:/dev/ttyUSB0"


def sweep_of(path, *grid, devices="refuse"):
    graph = flowmc.load(path)
    return Sweep(graph, [grid_axis(graph, g) for g in grid], devices=devices)


def test_a_hardware_device_node_is_refused_before_anything_runs(tmp_path):
    path = device_graph(tmp_path, HARDWARE)
    with pytest.raises(UsageError, match=f"node 'card': device '{HARDWARE}' moves hardware"):
        sweep_of(path, "plan.tolerance=0.01,0.1")
    proc = run_cli("sweep", path, "--grid", "plan.tolerance=0.01,0.1", "--out", tmp_path / "out")
    assert proc.returncode == 2
    assert f"node 'card': device '{HARDWARE}' moves hardware, and a sweep never moves a machine" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert not (tmp_path / "out").exists()


def test_every_value_an_axis_gives_a_device_is_checked(tmp_path):
    path = device_graph(tmp_path, "sim")
    assert sweep_of(path, "card.device=sim,grbl-sim").safety.to_sim == ()
    with pytest.raises(UsageError, match=f"device '{HARDWARE}' moves hardware"):
        sweep_of(path, f"card.device=sim,{HARDWARE}")
    by_input = device_graph(tmp_path / "input", HARDWARE, device_input=True)
    with pytest.raises(UsageError, match="node 'card'"):
        sweep_of(by_input, "plan.tolerance=0.05")  # the input's default drives hardware
    assert sweep_of(by_input, "device=sim,grbl-sim").safety.to_sim == ()  # every value given is a simulator


def test_devices_sim_runs_hardware_nodes_on_the_simulated_card(tmp_path):
    path = device_graph(tmp_path, HARDWARE)
    sweep = sweep_of(path, "plan.tolerance=0.01,0.1", devices="sim")
    assert sweep.safety.to_sim == ("card.device",)
    assert "simulated card" in sweep.safety.notes[0]
    rows = run_batch(sweep.job, sweep.variants)  # in this process: the worker's own code
    assert [r["status"] for r in rows] == ["done", "done"]
    assert {r["outputs"]["log"]["device"] for r in rows} == {"sim"}
    by_input = device_graph(tmp_path / "input", "sim", device_input=True)
    sweep = sweep_of(by_input, f"device=sim,{HARDWARE}", devices="sim")
    assert sweep.safety.to_sim == ("device",)
    rows = run_batch(sweep.job, sweep.variants)
    assert [r["params"]["device"] for r in rows] == ["sim", HARDWARE]
    assert [r["outputs"]["log"]["device"] for r in rows] == ["sim", "sim"]


def test_devices_inside_library_sub_graphs_are_found(tmp_path):
    graph = flowmc.load(REPO / "graphs" / "thesis_3axis.flowmc.json")
    graph.node("home").params["device"] = HARDWARE
    flowmc.save(graph, tmp_path / "thesis.flowmc.json")
    with pytest.raises(UsageError, match=f"node 'home/home': device '{HARDWARE}'"):
        sweep_of(tmp_path / "thesis.flowmc.json", "feed=10,20")
    sweep = sweep_of(tmp_path / "thesis.flowmc.json", "feed=10,20", devices="sim")
    assert sweep.safety.to_sim == ("home.device",)


def test_devices_the_sweep_cannot_see_or_reach_are_refused(tmp_path):
    g = flowmc.GraphBuilder()
    text = g.add("basic.text", id="which", value="sim")
    path = g.add("path.polyline", id="path", points=[[0, 0, 0], [5, 0, 0]])
    plan = g.add("plan.lookahead", id="plan")
    card = g.add("device.card_output", id="card")
    g.wire(path.path, plan.path)
    g.wire(plan.trajectory, card.motion)
    g.wire(text.value, card.device)
    g.save(tmp_path / "wired.flowmc.json")
    for devices in ("refuse", "sim"):
        with pytest.raises(UsageError, match="node 'card': its device is fed by a wire"):
            sweep_of(tmp_path / "wired.flowmc.json", "plan.tolerance=0.1", devices=devices)
    inner = flowmc.GraphBuilder()
    card = inner.add("device.card_output", id="card", device=HARDWARE)
    inner.input("motion", "Trajectory", card.motion)
    inner.output("log", "Log", card.log)
    inner.save(tmp_path / "inner.flowmc.json")
    outer = flowmc.GraphBuilder()
    path = outer.add("path.polyline", id="path", points=[[0, 0, 0], [5, 0, 0]])
    plan = outer.add("plan.lookahead", id="plan")
    sub = outer.add("subgraph", id="send", file="inner.flowmc.json")
    outer.wire(path.path, plan.path)
    outer.wire(plan.trajectory, sub.motion)
    outer.save(tmp_path / "outer.flowmc.json")
    with pytest.raises(UsageError, match=f"node 'send/card': device '{HARDWARE}' is stored inside a sub-graph file"):
        sweep_of(tmp_path / "outer.flowmc.json", "plan.tolerance=0.1", devices="sim")


def test_linuxcnc_runs_hold_the_linuxcnc_host_resource(tmp_path):
    assert sweep_of(device_graph(tmp_path / "sim", "sim"), "plan.tolerance=0.1").resources == ()
    assert sweep_of(device_graph(tmp_path / "lcnc", "linuxcnc"), "plan.tolerance=0.1").resources == ("linuxcnc",)
    g = flowmc.GraphBuilder()
    path = g.add("path.polyline", id="path", points=[[0, 0, 0], [5, 0, 0]])
    compare = g.add("device.linuxcnc_compare", id="compare")
    g.wire(path.path, compare.path)
    g.save(tmp_path / "compare.flowmc.json")
    assert sweep_of(tmp_path / "compare.flowmc.json", "compare.tolerance=0.05").resources == ("linuxcnc",)
