"""Where node types come from: node folders (--nodes, the user config), entry points, and failures."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import flowmc
from flowmc.plugins import add_node_folder, build_registry
from flowmc.registry import Registry

REPO = Path(__file__).resolve().parents[2]


def doc_node() -> str:
    """The node type docs/nodes.md shows (the test keeps the page true)."""
    text = (REPO / "docs" / "nodes.md").read_text(encoding="utf-8")
    return re.search(r"```python\n(.*?)```", text, re.S).group(1)


def node_folder(tmp_path: Path) -> Path:
    folder = tmp_path / "my_nodes"
    folder.mkdir()
    (folder / "scale.py").write_text(doc_node(), encoding="utf-8")
    return folder


def scale_graph(tmp_path: Path) -> Path:
    g = flowmc.GraphBuilder(title="uses my.scale")
    pts = g.add("path.polyline", id="pts", points=[(0, 0, 0), (10, 0, 0)], feed=10.0)
    scale = g.add("my.scale", id="scale", factor=3.0)
    measure = g.add("path.measure", id="measure")
    g.wire(pts.path, scale.path)
    g.wire(scale.path, measure.path)
    g.output("length", "Number", measure.length)
    file = tmp_path / "part.flowmc.json"
    g.save(file)
    return file


def cli(*args: str, env: dict | None = None, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "flowmc", *args], capture_output=True, text=True, timeout=120,
                          env={**os.environ, **(env or {})}, cwd=cwd)


def test_the_documented_node_is_fifteen_lines_and_runs_from_a_folder(tmp_path):
    assert len(doc_node().strip().splitlines()) <= 15
    registry = build_registry(entry_points=False, config=False)
    assert add_node_folder(registry, node_folder(tmp_path)) == ["my.scale"]
    result = flowmc.run(scale_graph(tmp_path), registry=registry)
    assert result.ok and result.outputs["length"] == 30.0
    assert registry.origin("my.scale").endswith("scale.py")


def test_run_refuses_an_unknown_type_and_runs_it_with_nodes_dir(tmp_path):
    graph = scale_graph(tmp_path)
    proc = cli("run", str(graph), "-q")
    assert proc.returncode == 2 and "unknown node type 'my.scale'" in proc.stderr
    proc = cli("run", str(graph), "-q", "--nodes", str(node_folder(tmp_path)))
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "length = 30.0"
    proc = cli("validate", str(graph), "--nodes", str(tmp_path / "nowhere"))
    assert proc.returncode == 2 and "--nodes" in proc.stderr and "not a folder" in proc.stderr


def test_node_folders_from_the_user_config(tmp_path):
    node_folder(tmp_path)
    config = tmp_path / "config.toml"
    config.write_text('node_folders = ["my_nodes"]\n', encoding="utf-8")
    proc = cli("nodes", "--json", env={"FLOWMC_CONFIG": str(config)})
    assert proc.returncode == 0, proc.stderr
    assert "my.scale" in {d["type_id"] for d in json.loads(proc.stdout)}
    config.write_text("node_folders = 3\n", encoding="utf-8")
    proc = cli("nodes", env={"FLOWMC_CONFIG": str(config)})
    assert proc.returncode == 0
    assert f"warning: config {config} failed to load: node_folders must be a list" in proc.stderr


def test_failures_are_recorded_not_fatal(tmp_path):
    folder = node_folder(tmp_path)
    (folder / "broken.py").write_text("raise RuntimeError('no such motor')\n", encoding="utf-8")
    (folder / "clash.py").write_text(doc_node().replace('"my.scale"', '"basic.add"'), encoding="utf-8")
    (folder / "bad_decl.py").write_text(doc_node().replace('"my.scale"', '"My Scale"'), encoding="utf-8")
    registry = build_registry(entry_points=False, config=False, node_folders=[folder])
    assert "my.scale" in registry and registry.types()["basic.add"].__module__ == "flowmc.nodes.basic"
    failures = {re.search(r"\w+\.py", where).group(): error for where, error in registry.failures.items()}
    assert failures.keys() == {"broken.py", "clash.py", "bad_decl.py"}
    assert "RuntimeError: no such motor" in failures["broken.py"]
    assert "'basic.add'" in failures["clash.py"] and "already used" in failures["clash.py"]
    assert "must look like 'area.name'" in failures["bad_decl.py"]
    g = flowmc.GraphBuilder()
    g.add("my.other", id="o")
    [issue] = flowmc.validate(g.build(), registry=registry)
    assert "unknown node type 'my.other'" in issue.message and "broken.py" in issue.message


def test_entry_points_in_the_flowmc_nodes_group(tmp_path):
    """A package's entry point may name a module, a class or a list; one that fails is a warning."""
    site = tmp_path / "site"
    (site / "plug_pkg").mkdir(parents=True)
    (site / "plug_pkg" / "__init__.py").write_text(doc_node().replace('"my.scale"', '"plug.scale"'), encoding="utf-8")
    info = site / "plug_pkg-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: plug-pkg\nVersion: 1.0\n", encoding="utf-8")
    (info / "entry_points.txt").write_text(
        "[flowmc.nodes]\nscale = plug_pkg\nalso = plug_pkg:Scale\nmissing = plug_missing\n", encoding="utf-8")
    proc = cli("nodes", "--json", env={"PYTHONPATH": str(site)}, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "plug.scale" in {d["type_id"] for d in json.loads(proc.stdout)}
    assert "warning: entry point missing (plug_missing) failed to load: ModuleNotFoundError" in proc.stderr
    assert "entry point also" not in proc.stderr  # the same class twice is not a clash


def test_a_registry_of_only_some_types():
    from flowmc.nodes.basic import Add, NumberConst

    registry = Registry([NumberConst, Add])
    g = flowmc.GraphBuilder()
    a = g.add("basic.number", id="a", value=2.0)
    s = g.add("basic.add", id="s", b=3.0)
    g.wire(a.value, s.a)
    assert flowmc.run(g.build(), registry=registry).output("s", "result") == 5.0
    g.add("path.polyline", id="p")
    assert [i.code for i in flowmc.validate(g.build(), registry=registry)] == ["unknown-node-type"]


def test_the_id_index_of_built_in_modules_matches_what_they_declare():
    """build_registry defers each built-in node module under the ids flowmc.nodes.BUILT_IN gives it:
    the index names every module of the package, and each module's ids in the order it declares them."""
    import importlib
    import pkgutil

    import flowmc.nodes
    from flowmc.registry import declared_in

    modules = sorted(info.name for info in pkgutil.iter_modules(flowmc.nodes.__path__))
    assert sorted(flowmc.nodes.BUILT_IN) == modules
    for module in modules:
        name = f"flowmc.nodes.{module}"
        importlib.import_module(name)
        assert flowmc.nodes.BUILT_IN[module] == tuple(c.type_id for c in declared_in(name)), name
