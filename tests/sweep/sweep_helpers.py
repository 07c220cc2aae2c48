"""Graphs and runners for the sweep tests: real node types, files written into the test's folder."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import flowmc

REPO = Path(__file__).resolve().parents[2]
ARM = REPO / "graphs" / "arm_lookahead.flowmc.json"

# Three small programs: a square, a square with a chamfer, a triangle (mm, mm/min).
PROGRAMS = {
    "a_square.ngc": "G21 G90 G17\nG0 X0 Y0\nG1 X40 F3000\nG1 Y40\nG1 X0\nG1 Y0\nM2\n",
    "b_chamfer.ngc": "G21 G90 G17\nG0 X0 Y0\nG1 X40 F3000\nG1 Y30\nG1 X30 Y40\nG1 X0\nG1 Y0\nM2\n",
    "c_triangle.ngc": "G21 G90 G17\nG0 X0 Y0\nG1 X50 F3000\nG1 X0 Y30\nG1 X0 Y0\nM2\n",
}


def gcode_graph(folder: Path, *, max_cycle_time: float = 100.0) -> Path:
    """G-code file -> look-ahead -> check(cycle time); programs in ``folder/programs``. Outputs: cycle time
    and the check's value (fails when the cycle time is over ``max_cycle_time``)."""
    programs = folder / "programs"
    programs.mkdir(parents=True, exist_ok=True)
    for name, text in PROGRAMS.items():
        (programs / name).write_text(text)
    g = flowmc.GraphBuilder(title="gcode sweep")
    src = g.add("path.gcode_in", id="gcode", file="programs/a_square.ngc")
    plan = g.add("plan.lookahead", id="plan", tolerance=0.05, profile="scurve")
    check = g.add("basic.check", id="check", max=max_cycle_time, label="cycle time")
    g.wire(src.path, plan.path)
    g.wire(plan.cycle_time, check.value)
    g.input("rule", "Text", plan.rule, default="blend")
    g.output("cycle_time", "Number", plan.cycle_time)
    g.output("checked", "Number", check.value)
    g.save(folder / "gcode.flowmc.json")
    return folder / "gcode.flowmc.json"


def device_graph(folder: Path, device: str = "sim", *, device_input: bool = False) -> Path:
    """Polyline -> look-ahead -> Card output on ``device``; the device stored, or given as an input."""
    folder.mkdir(parents=True, exist_ok=True)
    g = flowmc.GraphBuilder(title="device sweep")
    path = g.add("path.polyline", id="path", feed=50.0, points=[[0, 0, 0], [20, 0, 0], [20, 10, 0]])
    plan = g.add("plan.lookahead", id="plan")
    card = g.add("device.card_output", id="card", **({} if device_input else {"device": device}))
    g.wire(path.path, plan.path)
    g.wire(plan.trajectory, card.motion)
    if device_input:
        g.input("device", "Text", card.device, default=device)
    g.output("cycle_time", "Number", plan.cycle_time)
    g.output("log", "Log", card.log)
    g.save(folder / "device.flowmc.json")
    return folder / "device.flowmc.json"


def run_cli(*args: Any, cwd: Path | None = None, timeout: float = 300) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.run([sys.executable, "-m", "flowmc", *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, cwd=cwd, env=env)


def run_alone(graph: Path, params: dict[str, Any], out: Path) -> dict[str, Any]:
    """``flowmc run`` of one variant in a process of its own: ``--set`` for node.param, ``--input`` for inputs."""
    args: list[str] = []
    for name, value in params.items():
        args += ["--set" if "." in name else "--input", f"{name}={value}"]
    proc = run_cli("run", graph, *args, "--out", out, "-q")
    assert proc.returncode in (0, 1), proc.stderr
    return json.loads(out.read_text())


def journal(folder: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in (folder / "rows.jsonl").read_text().splitlines() if line.strip()]
