"""The core imports in one direction: no node, device or UI module, and no viser."""

from __future__ import annotations

import math
import subprocess
import sys

import pytest

CODE = """
import sys
import flowmc
assert [m for m in sys.modules if m.startswith("flowmc.")] == ["flowmc.lazy"], "import flowmc must stay light"
import flowmc.graph, flowmc.registry, flowmc.runtime, flowmc.ports, flowmc.builder, flowmc.cli, flowmc.digest
g = flowmc.GraphBuilder()
g.add("basic.number", id="n")
flowmc.save(g.build(), sys.argv[1])
flowmc.load(sys.argv[1])
bad = [m for m in sys.modules if m.startswith(("flowmc.nodes.", "flowmc.devices", "flowmc.ui", "viser"))]
print(bad)
"""


def test_core_imports_no_nodes_devices_or_ui(tmp_path):
    proc = subprocess.run([sys.executable, "-c", CODE, str(tmp_path / "g.flowmc.json")],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "[]"


def test_console_script_and_module_entry_points_agree():
    import shutil
    from pathlib import Path

    beside = Path(sys.executable).with_name("flowmc")  # pip installs the script beside the interpreter
    script = str(beside) if beside.exists() else shutil.which("flowmc")
    assert script is not None, "pip install -e . provides the flowmc command"
    via_script = subprocess.run([script, "schema"], capture_output=True, text=True, timeout=60)
    via_module = subprocess.run([sys.executable, "-m", "flowmc", "schema"], capture_output=True, text=True, timeout=60)
    assert via_script.returncode == via_module.returncode == 0
    assert via_script.stdout == via_module.stdout


VALIDATE = """
import sys
from flowmc.cli import main
code = main(["validate", sys.argv[1]])
heavy = ("numpy", "flowmc.motion.path", "scipy", "skimage", "viser", "networkx", "PIL", "serial", "dask",
         "flowmc.ui", "flowmc.sweep", "flowmc.devices", "flowmc.runtime.executor", "flowmc.nodes.signals",
         "flowmc.motion.gcode", "flowmc.nodes.gcode", "flowmc.nodes.basic")
print(code, sorted({m for m in sys.modules for h in heavy if m == h or m.startswith(h + ".")}))
"""


def test_validate_starts_light(tmp_path):
    """Cold start (benchmarks/cold_start.py times it): ``flowmc validate`` imports only the node modules
    of the types the graph uses, and nothing heavy (numpy, the path types, scipy, scikit-image, viser, networkx,
    device backends, the executor, the signal nodes beside Card output): validating reads params and ports, and
    node modules import their algorithms when they run."""
    from core_helpers import REPO

    graph = REPO / "graphs" / "thesis_3axis.flowmc.json"
    proc = subprocess.run([sys.executable, "-c", VALIDATE, str(graph)], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().splitlines()[-1] == "0 []"


@pytest.mark.parametrize("name", ["arm_lookahead", "case_planner", "probe_branch", "wait_for_clamp"])
def test_loops_cases_reports_and_planners_validate_without_numpy(name):
    """The basic, structure, planning and device node modules hold params and ports; numpy comes when they run."""
    from core_helpers import REPO

    code = "import sys\nfrom flowmc.cli import main\nprint(main(['validate', sys.argv[1]]), 'numpy' in sys.modules)"
    graph = REPO / "graphs" / f"{name}.flowmc.json"
    proc = subprocess.run([sys.executable, "-c", code, str(graph)], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().splitlines()[-1] == "0 False"


BUILT = """
import sys
from flowmc.cli import main
from pydantic import BaseModel
code = main(["validate", sys.argv[1]])
models = {f"{m.__module__}.{m.__qualname__}": m.__pydantic_complete__ for m in BaseModel.__subclasses__()}
models.update((f"{m.__module__}.{m.__qualname__}", m.__pydantic_complete__) for n in list(sys.modules)
              if n.startswith("flowmc.") for m in vars(sys.modules[n]).values()
              if isinstance(m, type) and issubclass(m, BaseModel) and m is not BaseModel)
print(code, sorted(n for n, done in models.items() if done and n.startswith("flowmc.")))
"""


def test_validate_builds_only_the_models_it_uses():
    """pydantic builds a model's validator when it first validates (``defer_build``): validating a graph builds
    the graph file's model and the params of the node types the graph uses, not every model of the node
    modules it imports (the Jog, PWM or Pre-flight params beside Home and Card output)."""
    from core_helpers import REPO

    graph = REPO / "graphs" / "thesis_3axis.flowmc.json"
    proc = subprocess.run([sys.executable, "-c", BUILT, str(graph)], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    code, built = proc.stdout.strip().splitlines()[-1].split(" ", 1)
    assert code == "0"
    assert "flowmc.graph.Graph" in built and "flowmc.nodes.devices.HomeParams" in built
    for unused in ("flowmc.nodes.devices.JogParams", "flowmc.nodes.devices.WaitInputParams",
                   "flowmc.nodes.devices.PreflightParams", "flowmc.nodes.planning.StopAndGoParams"):
        assert unused not in built


PLAN = """
import sys
from flowmc.motion.gcode import read_gcode
from flowmc.motion.machine import Axis, Machine
from flowmc.motion.planner import plan_smooth
path = read_gcode(sys.argv[1])
machine = Machine(axes=tuple(Axis(name=n, min=-500, max=500, vmax=200, amax=200, jmax=5000) for n in "XYZ"))
plan = plan_smooth(path, machine, tolerance=0.05)
print(plan.smoothed.fitted > 0, sorted(m for m in sys.modules if m.startswith("scipy.") and m.count(".") == 1
                                          and not m.startswith(("scipy._", "scipy.__"))))
"""


def test_trapezoid_planning_imports_only_scipy_linalg(tmp_path):
    """Cold start of a plan (benchmarks/cam_programs.py --cold-only times it): reading G-code and planning a
    trapezoid plan needs scipy's banded solver only; scipy.interpolate, optimize and sparse (about 0.5 s of CPU
    to import) come when a program has tabulated curves or an S-curve plan is retimed."""
    program = tmp_path / "wave.ngc"  # short lines turning every way: runs of them are fitted by splines
    program.write_text("G21 G90\nG1 F3000 X0 Y0\n" + "".join(
        f"X{0.3 * i:.3f} Y{math.sin(0.5 * i) + (i % 3) * 0.04:.3f}\n" for i in range(1, 200)) + "M2\n")
    proc = subprocess.run([sys.executable, "-c", PLAN, str(program)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().splitlines()[-1] == "True ['scipy.linalg', 'scipy.version']"
