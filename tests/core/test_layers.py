"""The layers of docs/architecture.md, checked on the source: every import of every flowmc module, read
with ``ast`` (function-level imports and ``importlib.import_module("...")`` with a constant included),
must go where the table below allows, and no modules may import each other in a loop."""

from __future__ import annotations

import ast
from pathlib import Path

import networkx as nx

import flowmc

ROOT = Path(flowmc.__file__).parent

# Lowest first. A module belongs to the layer of its longest matching prefix.
LAYERS: dict[str, tuple[str, ...]] = {
    "leaf": ("flowmc.errors", "flowmc.ports", "flowmc.budget", "flowmc.fileio", "flowmc.lazy"),
    "motion": ("flowmc.motion",),
    "devices": ("flowmc.devices",),
    "core": ("flowmc.graph", "flowmc.migrations", "flowmc.digest", "flowmc.registry", "flowmc.builder",
             "flowmc.settings"),
    "runtime": ("flowmc.runtime",),
    "nodes": ("flowmc.nodes",),
    "start-up": ("flowmc.plugins", "flowmc.api"),
    "sweep": ("flowmc.sweep",),
    "ui": ("flowmc.ui",),
    "app": ("flowmc.cli", "flowmc.__main__", "flowmc"),  # "flowmc": the package's lazy facade
}
# What each layer may import besides itself. The core knows no motion, device, node or UI module;
# the UI gets node types and devices from whoever composes it (the CLI), never by importing them.
MAY_IMPORT: dict[str, set[str]] = {
    "leaf": set(),
    "motion": {"leaf"},
    "devices": {"leaf", "motion"},
    "core": {"leaf"},
    "runtime": {"leaf", "core"},
    "nodes": {"leaf", "motion", "devices", "core", "runtime"},
    "start-up": {"leaf", "core", "runtime", "nodes"},
    "sweep": {"leaf", "motion", "core", "runtime", "start-up"},
    "ui": {"leaf", "motion", "core", "runtime", "start-up", "sweep"},
    "app": {"leaf", "motion", "devices", "core", "runtime", "nodes", "start-up", "sweep", "ui"},
}
# Imports against the table that are known and owned by someone, each with the reason. Keep it empty.
ALLOWED: dict[tuple[str, str], str] = {}
# Third-party packages only some layers may import (viser is the editor's; nothing else starts it).
THIRD_PARTY = {"viser": {"ui"}, "playwright": set()}


def modules() -> dict[str, Path]:
    found = {}
    for path in sorted(ROOT.rglob("*.py")):
        parts = ("flowmc", *path.relative_to(ROOT).with_suffix("").parts)
        found[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return found


def layer_of(module: str) -> str | None:
    best = max(((prefix, name) for name, prefixes in LAYERS.items() for prefix in prefixes
                if module == prefix or module.startswith(prefix + ".")), default=None, key=lambda p: len(p[0]))
    return best[1] if best else None


def _type_checking_lines(tree: ast.AST) -> set[int]:
    lines: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for inner in node.body:
                lines.update(range(inner.lineno, (inner.end_lineno or inner.lineno) + 1))
    return lines


def imports(module: str, path: Path, known: dict[str, Path]) -> list[tuple[int, str, bool, bool]]:
    """``(line, imported name, only for type checking, a string import)`` for every import in the file."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    typing_only = _type_checking_lines(tree)
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found = []
    for node in ast.walk(tree):
        names: list[str] = []
        dynamic = False
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                base = ".".join(parts + ([base] if base else []))
            names = [base] + [f"{base}.{a.name}" for a in node.names if f"{base}.{a.name}" in known]
        elif (isinstance(node, ast.Call) and getattr(node.func, "attr", getattr(node.func, "id", None))
              in ("import_module", "__import__") and node.args and isinstance(node.args[0], ast.Constant)):
            names, dynamic = [str(node.args[0].value)], True
        found += [(node.lineno, name, node.lineno in typing_only, dynamic) for name in names]
    return found


def resolve(name: str, known: dict[str, Path]) -> str | None:
    """The flowmc module an imported name lives in (``flowmc.x.y.Name`` -> ``flowmc.x.y``)."""
    while name and name not in known:
        name = name.rpartition(".")[0]
    return name or None


def edges() -> list[tuple[str, str, int, bool, bool]]:
    known = modules()
    out = []
    for module, path in known.items():
        for line, name, typing_only, dynamic in imports(module, path, known):
            target = resolve(name, known) if name.startswith("flowmc") else None
            if target is not None and target != module:
                out.append((module, target, line, typing_only, dynamic))
    return out


def where(module: str, line: int) -> str:
    return f"{modules()[module].relative_to(ROOT.parent)}:{line}"


def test_every_module_has_a_layer():
    assert [m for m in modules() if layer_of(m) is None] == []


def test_imports_go_the_stated_direction():
    wrong = []
    for src, dst, line, _typing, _dynamic in edges():
        a, b = layer_of(src), layer_of(dst)
        if a != b and b not in MAY_IMPORT[a] and (src, dst) not in ALLOWED:
            wrong.append(f"{where(src, line)}: {src} ({a}) imports {dst} ({b}); {a} may import "
                         f"{', '.join(sorted(MAY_IMPORT[a])) or 'nothing'} (docs/architecture.md)")
    assert wrong == []


def test_flowmc_modules_are_imported_by_name_not_by_string():
    """Dynamic imports hide a dependency from readers and from this test; only plugins load by name."""
    assert [f"{where(src, line)}: {dst}" for src, dst, line, _t, dynamic in edges() if dynamic] == []


def test_no_import_loops():
    """Imports that run (a TYPE_CHECKING block does not) form no loop, package __init__ files included."""
    graph = nx.DiGraph()
    known = modules()
    for src, dst, _line, typing_only, _dynamic in edges():
        if typing_only:
            continue
        graph.add_edge(src, dst)
        parent = dst.rpartition(".")[0]
        while parent and parent != "flowmc" and src != parent and not src.startswith(parent + "."):
            if parent in known:  # importing a.b.c runs a/b/__init__.py first
                graph.add_edge(src, parent)
            parent = parent.rpartition(".")[0]
    loops = [" -> ".join(cycle + cycle[:1]) for cycle in nx.simple_cycles(graph)]
    assert loops == []


def test_third_party_packages_stay_in_their_layer():
    known = modules()
    wrong = []
    for module, path in known.items():
        for line, name, _typing, _dynamic in imports(module, path, known):
            top = name.partition(".")[0]
            if top in THIRD_PARTY and layer_of(module) not in THIRD_PARTY[top]:
                wrong.append(f"{where(module, line)}: {name}")
    assert wrong == []


def test_the_checks_see_what_they_claim(tmp_path):
    """Function-level, relative, TYPE_CHECKING and string imports are all found."""
    source = ("from typing import TYPE_CHECKING\nfrom . import ports\nif TYPE_CHECKING:\n    from flowmc.ui import app\n"
              "def f():\n    from flowmc.nodes.basic import Add\n    importlib.import_module('flowmc.devices.card')\n")
    path = tmp_path / "probe.py"
    path.write_text(source)
    known = modules()
    found = {(name, typing_only, dynamic) for _line, name, typing_only, dynamic in imports("flowmc.probe", path, known)}
    assert {("flowmc.ports", False, False), ("flowmc.ui.app", True, False), ("flowmc.nodes.basic", False, False),
            ("flowmc.devices.card", False, True)} <= found
    assert layer_of("flowmc.nodes.basic") == "nodes" and layer_of("flowmc.plugins") == "start-up"
    assert layer_of("flowmc") == "app" and layer_of("flowmc.ports") == "leaf"
