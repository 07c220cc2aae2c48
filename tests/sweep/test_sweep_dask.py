"""Sweeps on a real 2-worker Dask LocalCluster (worker processes): every row is what ``flowmc run`` of the
same variant gives, failures are rows, upstream nodes stay cached per worker, shipped folders, LinuxCNC
runs one per host."""

from __future__ import annotations

import json
import shutil

import pyarrow.parquet as pq
import pytest
from distributed import LocalCluster
from sweep_helpers import ARM, device_graph, gcode_graph, journal, run_alone, run_cli

import flowmc
from flowmc.sweep import Journal, Sweep, files_axis, flatten_outputs, grid_axis, open_executor, write_tables

HARDWARE = "grbl:/dev/ttyUSB0"


@pytest.fixture(scope="module")
def cluster():
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as c:
        yield c


def sweep_on(cluster, sweep, folder, **options):
    with open_executor("dask", sweep.job, address=cluster.scheduler_address, resources=sweep.resources) as ex:
        assert ex.workers == 2
        outcome = sweep.run(ex, Journal(folder), **options)
    return outcome


def assert_same_as_run_alone(graph_path, rows, tmp_path):
    for row in rows:
        alone = run_alone(graph_path, row["params"], tmp_path / f"alone{row['variant']}.json")
        assert row["status"] == ("done" if alone["ok"] else "failed"), row
        assert row["error"] == "; ".join(alone["errors"])
        assert json.loads(json.dumps(row["outputs"])) == alone["outputs"], row["params"]


def test_rows_equal_flowmc_run_alone_and_failures_are_rows(cluster, tmp_path):
    graph = flowmc.load(ARM)
    # tolerance 0.001 with the blend rule misses the graph's own check (ratio <= 0.68): that variant fails
    sweep = Sweep(graph, [grid_axis(graph, "lookahead.tolerance=0.001,0.08"),
                          grid_axis(graph, "rule=blend,junction_deviation")])
    progress = []
    outcome = sweep_on(cluster, sweep, tmp_path / "out", on_progress=progress.append)
    journal = Journal(tmp_path / "out", resume=True).rows
    rows = sorted(journal.values(), key=lambda r: r["variant"])
    assert [r["status"] for r in rows] == ["failed", "done", "done", "done"]
    assert "node 'check': check failed" in rows[0]["error"] and rows[0]["outputs"]["ratio"] > 0.68
    assert_same_as_run_alone(ARM, rows, tmp_path)
    # each worker runs machine, path, stop-and-go and its 3D view once (they do not depend on what is swept);
    # after that they come from its cache
    upstream = {"machine", "path", "stop_and_go", "view_stop_and_go"}
    for worker in {r["worker"] for r in rows}:
        mine = sorted((r for r in rows if r["worker"] == worker), key=lambda r: r["start"])
        assert all(not upstream & set(r["executed"]) and r["cached"] >= len(upstream) for r in mine[1:]), mine
        assert len({r["ran"] + r["cached"] for r in mine}) == 1  # every node ran or came from the cache
    assert (outcome.done, outcome.failed, outcome.left) == (3, 1, 0)
    assert (progress[0].left, progress[-1].left, progress[-1].done, progress[-1].failed) == (4, 0, 3, 1)
    # the tables hold the same numbers, flattened
    write_tables(tmp_path / "out", outcome.columns, outcome.rows)
    table = pq.read_table(tmp_path / "out" / "rows.parquet").to_pylist()
    for row, flat in zip(rows, table):
        assert flat["variant"] == row["variant"] and flat["rule"] == row["params"]["rule"]
        assert {k: flat[k] for k in flatten_outputs(row["outputs"])} == flatten_outputs(row["outputs"])
    assert table[1]["out.metrics.contour_error"] == rows[1]["outputs"]["metrics"]["data"][4]["value"]


def test_a_folder_of_programs_shipped_to_the_workers(cluster, tmp_path, monkeypatch):
    job = tmp_path / "job"
    graph_path = gcode_graph(job, max_cycle_time=5.87)
    monkeypatch.chdir(tmp_path)
    graph = flowmc.load(graph_path)
    sweep = Sweep(graph, [files_axis(graph, "gcode.file=job/programs/*.ngc"), grid_axis(graph, "rule=blend,arm_weighted")],
                  ship=True, skip=(job / "out",))
    kept = tmp_path / "kept"
    shutil.move(job / "programs", kept)  # from here on, only the shipped copy has the programs
    sweep_on(cluster, sweep, job / "out", size=2)  # a batch holds one program's two variants
    shutil.move(kept, job / "programs")
    rows = sorted(Journal(job / "out", resume=True).rows.values(), key=lambda r: r["variant"])
    assert [r["params"]["gcode.file"] for r in rows] == ["programs/a_square.ngc"] * 2 + ["programs/b_chamfer.ngc"] * 2 \
        + ["programs/c_triangle.ngc"] * 2
    assert {r["status"] for r in rows[2:4]} == {"failed"}  # the chamfered square takes 6.50 s (blend) and 6.24 s (arm) > 5.87
    for k in (0, 2, 4):  # the rows of one program ran on one worker, which parsed it once
        assert rows[k]["worker"] == rows[k + 1]["worker"]
        assert ["gcode" in r["executed"] for r in rows[k:k + 2]] == [True, False]
    assert_same_as_run_alone(graph_path, rows, tmp_path)


def test_device_nodes_start_on_the_simulated_card_as_flowmc_run_starts_them(cluster, tmp_path):
    """Device nodes prepare a job and only a Start moves: a sweep's variant is the prepare and the Start that
    ``flowmc run`` makes, on the simulated card. A graph on ``sim``; one on hardware under ``--devices sim``
    (its lone run: ``--set card.device=sim``); the same sweep again on the same workers (jobs their
    long-lived runtimes started before) gives the same rows; ``--devices refuse`` still refuses."""
    grid = ("plan.tolerance=0.01,0.1", "path.feed=20,50")
    sim_path = device_graph(tmp_path / "sim", "sim")
    graph = flowmc.load(sim_path)
    sweep = Sweep(graph, [grid_axis(graph, g) for g in grid])
    sweep_on(cluster, sweep, tmp_path / "sim-out")
    rows = sorted(Journal(tmp_path / "sim-out", resume=True).rows.values(), key=lambda r: r["variant"])
    assert [(r["status"], r["outputs"]["log"]["outcome"]) for r in rows] == [("done", "done")] * 4  # it moved
    assert_same_as_run_alone(sim_path, rows, tmp_path)
    sweep_on(cluster, sweep, tmp_path / "again")
    again = sorted(Journal(tmp_path / "again", resume=True).rows.values(), key=lambda r: r["variant"])
    assert [r["outputs"] for r in again] == [r["outputs"] for r in rows]

    hw_path = device_graph(tmp_path / "hw", HARDWARE)
    refused = run_cli("sweep", hw_path, "--grid", grid[1], "--out", tmp_path / "refused")
    assert refused.returncode == 2 and f"device '{HARDWARE}' moves hardware" in refused.stderr
    assert not (tmp_path / "refused").exists()
    proc = run_cli("sweep", hw_path, "--grid", grid[1], "--devices", "sim", "--workers", "2", "--out", tmp_path / "hw-out")
    assert proc.returncode == 0, proc.stderr
    assert f"node 'card': {HARDWARE} -> simulated card (--devices sim)" in proc.stderr
    rows = journal(tmp_path / "hw-out")
    assert len(rows) == 2 and {r["outputs"]["log"]["device"] for r in rows} == {"sim"}
    for row in rows:
        alone = run_alone(hw_path, {**row["params"], "card.device": "sim"}, tmp_path / f"hw{row['variant']}.json")
        assert (row["status"], row["error"]) == ("done", "") and alone["ok"]
        assert json.loads(json.dumps(row["outputs"])) == alone["outputs"], row["params"]


def test_linuxcnc_runs_go_to_one_worker_per_host(cluster, tmp_path):
    graph = flowmc.load(device_graph(tmp_path, "sim"))
    sweep = Sweep(graph, [grid_axis(graph, "plan.tolerance=0.01:0.06:0.01")])
    with open_executor("dask", sweep.job, address=cluster.scheduler_address, resources=("linuxcnc",)) as ex:
        workers = ex.client.scheduler_info(n_workers=-1)["workers"]
        holders = [a for a, w in workers.items() if w["resources"].get("linuxcnc")]
        assert len(workers) == 2 and len(holders) == 1  # one per host: this host has two workers
        outcome = sweep.run(ex, Journal(tmp_path / "out"), size=1)
    assert outcome.done == 6
    assert len({r["worker"] for r in Journal(tmp_path / "out", resume=True).rows.values()}) == 1


def test_a_real_linuxcnc_comparison_sweep(cluster, tmp_path):
    g = flowmc.GraphBuilder()
    path = g.add("path.polyline", id="path", feed=50.0, points=[[0, 0, 0], [20, 0, 0], [20, 10, 0]])
    compare = g.add("device.linuxcnc_compare", id="compare")
    g.wire(path.path, compare.path)
    g.output("report", "Table", compare.report)
    g.save(tmp_path / "compare.flowmc.json")
    graph = flowmc.load(tmp_path / "compare.flowmc.json")
    sweep = Sweep(graph, [grid_axis(graph, "compare.tolerance=0.01,0.2")])
    assert sweep.resources == ("linuxcnc",)
    sweep_on(cluster, sweep, tmp_path / "out")
    rows = sorted(Journal(tmp_path / "out", resume=True).rows.values(), key=lambda r: r["start"])
    assert [r["status"] for r in rows] == ["done", "done"], [r["error"] for r in rows]
    assert rows[0]["end"] <= rows[1]["start"]  # never two LinuxCNC instances at once
    cycle = [next(d["linuxcnc"] for d in r["outputs"]["report"]["data"] if d["quantity"] == "feed cycle time")
             for r in rows]
    assert all(c > 0.5 for c in cycle)
