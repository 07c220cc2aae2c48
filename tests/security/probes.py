"""The issue-18 probes: tiny inputs that once exhausted memory or time, as graph folders run by the real
``flowmc`` command in a child process whose peak RSS is measured (``os.wait4``).

Shared by tests/security/test_budgets.py (each probe ends in a clean error naming the node) and
benchmarks/security.py (peak RSS and time of each, against the 500 MB target)."""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

ADDRESS_SPACE = 6 * 1024**3  # the child's address-space ceiling: a probe that runs away fails fast, not the machine


def _graph(folder: Path, nodes: list[dict], wires: list[tuple[str, str]] = (), name: str = "probe.flowmc.json") -> Path:
    doc = {"schema_version": 1, "title": "probe", "nodes": nodes,
           "wires": [{"from": a, "to": b} for a, b in wires]}
    path = folder / name
    path.write_text(json.dumps(doc), encoding="utf-8")
    return path


def _gcode_plan(text: str, planner: str = "plan.lookahead") -> Callable[[Path], Path]:
    def build(folder: Path) -> Path:
        (folder / "probe.ngc").write_text(text, encoding="utf-8")
        return _graph(folder, [{"id": "gcode", "type": "path.gcode_in", "params": {"file": "probe.ngc"}},
                               {"id": "plan", "type": planner}], [("gcode.path", "plan.path")])
    return build


def _table_plan(rows: list[dict], planner: str = "plan.stop_and_go") -> Callable[[Path], Path]:
    def build(folder: Path) -> Path:
        return _graph(folder, [{"id": "table", "type": "path.segment_table", "params": {"rows": rows}},
                               {"id": "plan", "type": planner}], [("table.path", "plan.path")])
    return build


def _image(size: int, pattern: str, method: str) -> Callable[[Path], Path]:
    def build(folder: Path) -> Path:
        from PIL import Image

        if pattern == "checker":
            yy, xx = np.indices((size, size))
            pixels = (((yy + xx) % 2) * 255).astype(np.uint8)
        else:
            pixels = np.full((size, size), 255, np.uint8)
            pixels[size // 4: 3 * size // 4, size // 4: 3 * size // 4] = 0
        Image.fromarray(pixels).save(folder / "picture.png")
        return _graph(folder, [{"id": "trace", "type": "path.image_contour",
                                "params": {"file": "picture.png", "method": method, "mm_per_pixel": 0.1}}])
    return build


def _big_table(n: int) -> Callable[[Path], Path]:
    def build(folder: Path) -> Path:
        rows = [{"type": "line", "end": [float(i % 100), float(i // 100 % 100), 0.0]} for i in range(n)]
        return _graph(folder, [{"id": "table", "type": "path.segment_table", "params": {"rows": rows}}])
    return build


def _fan_out(depth: int) -> Callable[[Path], Path]:
    """``depth`` files, each using the next one twice: 2**depth expansions if nothing is shared."""
    def build(folder: Path) -> Path:
        leaf = {"schema_version": 1, "nodes": [{"id": "n", "type": "basic.number", "params": {"value": 1}}],
                "wires": [], "interface": {"inputs": [], "outputs": [{"name": "y", "type": "Number", "from": "n.value"}]}}
        (folder / f"f{depth}.flowmc.json").write_text(json.dumps(leaf))
        for k in range(depth - 1, -1, -1):
            doc = {"schema_version": 1, "wires": [{"from": "a.y", "to": "s.a"}, {"from": "b.y", "to": "s.b"}],
                   "nodes": [{"id": "a", "type": "subgraph", "params": {"file": f"f{k + 1}.flowmc.json"}},
                             {"id": "b", "type": "subgraph", "params": {"file": f"f{k + 1}.flowmc.json"}},
                             {"id": "s", "type": "basic.add"}],
                   "interface": {"inputs": [], "outputs": [{"name": "y", "type": "Number", "from": "s.result"}]}}
            (folder / f"f{k}.flowmc.json").write_text(json.dumps(doc))
        return folder / "f0.flowmc.json"
    return build


@dataclass(frozen=True)
class Probe:
    name: str
    build: Callable[[Path], Path]
    command: str = "run"  # or "validate"
    node: str | None = None  # the node the clean error must name
    ok: bool = False  # the probe is fine to run through (it must only stay within the budget)


PROBES = [
    Probe("G1 X1000 F0.05 into plan.lookahead", _gcode_plan("G1 X1000 F0.05\n"), node="plan"),
    Probe("G2 X0 Y0 I10 J0 P100000", _gcode_plan("G2 X0 Y0 I10 J0 P100000 F600\n"), node="gcode"),
    Probe("table line at feed 0.0008 into plan.stop_and_go",
          _table_plan([{"type": "line", "end": [100.0, 0.0, 0.0], "feed": 0.0008}]), node="plan"),
    Probe("arc row with end_angle 36,000,000", _table_plan(
        [{"type": "arc", "direction": "ccw", "radius": 10.0, "start_angle": 0.0, "end_angle": 36_000_000.0}]),
        node="table"),
    Probe("6000x6000 PNG into image contours", _image(6000, "square", "marching_squares"), node="trace"),
    Probe("2000x2000 checkerboard, report_4neighbour", _image(2000, "checker", "report_4neighbour"), node="trace"),
    Probe("1,000,000-row segment table", _big_table(1_000_000), node="table"),
    Probe("16 sub-graph files, each using the next twice", _fan_out(16), command="validate"),
]

# Just under the caps: these run through, and show what the budget lets a node use (benchmark only).
NEAR_CAPS = [
    Probe("G1 X1000 F10.1: 1.49 M setpoints (cap 1.58 M)", _gcode_plan("G1 X1000 F10.1\n"), ok=True),
    Probe("590x590 checkerboard, report_4neighbour (174 k of 179 k)", _image(590, "checker", "report_4neighbour"),
          ok=True),
    Probe("12 sub-graph levels each used twice, run (16 k nodes)", _fan_out(12), ok=True),
]


@dataclass
class Outcome:
    probe: str
    code: int | None  # None: killed by the time limit
    seconds: float
    peak_mb: float
    stderr: str


def run_probe(probe: Probe, folder: Path, timeout: float = 120.0) -> Outcome:
    """Build ``probe`` in ``folder`` and run ``flowmc <command>`` on it in a child process."""
    folder.mkdir(parents=True, exist_ok=True)
    graph = probe.build(folder)

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE, ADDRESS_SPACE))

    env = {**os.environ, "PYTHONWARNINGS": "error::RuntimeWarning"}
    start = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "flowmc", probe.command, str(graph)], cwd=folder,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, preexec_fn=limit, env=env)
    deadline = start + timeout
    while True:
        pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
        if pid:
            break
        if time.perf_counter() > deadline:
            proc.kill()
            pid, status, usage = os.wait4(proc.pid, 0)
            return Outcome(probe.name, None, time.perf_counter() - start, usage.ru_maxrss / 1024, "")
        time.sleep(0.02)
    seconds = time.perf_counter() - start
    stderr = proc.stderr.read().decode("utf-8", "replace")
    proc.stderr.close()
    proc.returncode = os.waitstatus_to_exitcode(status)
    return Outcome(probe.name, proc.returncode, seconds, usage.ru_maxrss / 1024, stderr)
