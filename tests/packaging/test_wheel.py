"""flowmc as a user installs it: the wheel built from this tree, installed into a fresh venv.

Checks that the library graphs travel inside the package (``flowmc nodes`` lists every ``lib.*``),
that every example graph runs from another folder, and that a plugin package installed with pip
is used by ``flowmc run`` and shown in the editor's palette (in Chromium).

The venv sees the host's site-packages for flowmc's dependencies (numpy, scipy, viser, ...), so
the check needs no network for them; flowmc itself must come from the wheel (asserted).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import socket
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
LIB_TYPES = {f"lib.{p.name.removesuffix('.flowmc.json')}" for p in (REPO / "flowmc" / "lib").glob("*.flowmc.json")}
EXAMPLES = sorted(p.name for p in (REPO / "graphs").glob("*.flowmc.json"))

pytestmark = pytest.mark.packaging


def sh(*args: str | Path, cwd: Path | None = None, timeout: float = 300) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "FLOWMC_CONFIG")}
    env["XDG_CONFIG_HOME"] = str(cwd or REPO)  # no user config of this machine's
    proc = subprocess.run([str(a) for a in args], cwd=cwd, capture_output=True, text=True, timeout=timeout, env=env)
    return proc


def ok(proc: subprocess.CompletedProcess) -> str:
    assert proc.returncode == 0, f"{proc.args}: exit {proc.returncode}\n{proc.stdout[-2000:]}\n{proc.stderr[-3000:]}"
    return proc.stdout


@pytest.fixture(scope="module")
def venv(tmp_path_factory) -> Path:
    """A fresh venv with flowmc installed from a wheel built from a copy of this tree."""
    work = tmp_path_factory.mktemp("wheel")
    src = work / "src"
    src.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(REPO / name, src / name)
    shutil.copytree(REPO / "flowmc", src / "flowmc", ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    ok(sh(sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", work / "dist", src))
    [wheel] = (work / "dist").glob("flowmc-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    assert {f"flowmc/lib/{t[4:]}.flowmc.json" for t in LIB_TYPES} <= set(names)
    assert "flowmc/devices/linuxcnc/config/flowmc_sim.hal" in names
    env = work / "venv"
    ok(sh(sys.executable, "-m", "venv", "--system-site-packages", env))
    ok(sh(env / "bin" / "python", "-m", "pip", "install", "-q", "--no-deps", "--no-index", wheel))
    where = ok(sh(env / "bin" / "python", "-c", "import flowmc; print(flowmc.__file__)", cwd=work))
    assert Path(where.strip()).is_relative_to(env), f"flowmc came from {where.strip()}, not the wheel"
    return env


def test_flowmc_nodes_lists_every_library_graph(venv, tmp_path):
    proc = sh(venv / "bin" / "flowmc", "nodes", "--json", cwd=tmp_path)
    described = json.loads(ok(proc))
    assert proc.stderr == ""  # every node module loaded
    ids = {d["type_id"] for d in described}
    assert LIB_TYPES and LIB_TYPES <= ids
    assert {"subgraph", "path.gcode_in", "plan.lookahead", "device.card_output"} <= ids


@pytest.mark.parametrize("name", EXAMPLES)
def test_every_example_graph_runs_from_another_folder(venv, tmp_path, name):
    shutil.copytree(REPO / "graphs", tmp_path / "graphs")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    ok(sh(venv / "bin" / "flowmc", "run", "-q", Path("..") / "graphs" / name, cwd=elsewhere))


@pytest.fixture(scope="module")
def plugin(venv, tmp_path_factory) -> Path:
    """The example plugin package, installed into the venv with pip (from a copy: pip builds in the tree)."""
    src = tmp_path_factory.mktemp("plugin") / "flowmc-example-plugin"
    shutil.copytree(REPO / "examples" / "flowmc-example-plugin", src)
    ok(sh(venv / "bin" / "python", "-m", "pip", "install", "-q", "--no-deps", src))
    return src


def spiral_length(turns: float, pitch: float) -> float:
    """The example node's polyline, measured here from its definition (36 chords per turn)."""
    angle = np.linspace(0.0, 2 * np.pi * turns, int(36 * turns) + 1)
    radius = pitch * angle / (2 * np.pi)
    xy = np.column_stack([radius * np.cos(angle), radius * np.sin(angle)])
    return float(np.linalg.norm(np.diff(xy, axis=0), axis=1).sum())


def test_an_installed_plugin_runs_in_flowmc_run(venv, plugin, tmp_path):
    out = ok(sh(venv / "bin" / "flowmc", "run", "-q", plugin / "spiral.flowmc.json", cwd=tmp_path))
    name, _, value = out.strip().partition(" = ")
    assert name == "length" and float(value) == pytest.approx(spiral_length(4.0, 2.5), rel=1e-12)
    listing = ok(sh(venv / "bin" / "flowmc", "nodes", cwd=tmp_path))
    assert "example.spiral  [Examples] Spiral: An Archimedean spiral" in listing


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.browser
def test_an_installed_plugin_is_in_the_editors_palette(venv, plugin, tmp_path):
    from browser_helpers import EditorPage, chromium

    port = free_port()
    server = subprocess.Popen([str(venv / "bin" / "flowmc"), "serve", str(plugin / "spiral.flowmc.json"),
                               "--port", str(port)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                              cwd=tmp_path)
    try:
        url, seen = None, []
        while url is None and server.poll() is None and len(seen) < 200:  # viser prints a banner first
            seen.append(server.stdout.readline())
            url = re.search(r"flowmc editor: (http://\S+)", seen[-1])
        assert url, f"no editor URL in {seen!r}"
        with chromium() as browser:
            ui = EditorPage(browser, editor=None)  # the editor runs in the venv's process, not here
            page = ui.page
            page.goto(url.group(1))
            ui.field("Search").fill("spiral")  # the palette shows on load, above the side panel
            button = page.get_by_role("button", name="Spiral", exact=True)
            button.wait_for(timeout=30000)
            time.sleep(0.5)
            page.screenshot(path=str(tmp_path / "palette.png"))
            assert button.is_visible()
    finally:
        server.terminate()
        server.wait(timeout=30)
