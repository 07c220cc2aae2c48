"""The editor's layer rule (docs/architecture.md): flowmc/ui imports no device and no node module, at
module level or inside functions; it gets a device session and node types from whoever composes it."""

from __future__ import annotations

import ast
from pathlib import Path

import flowmc.ui

UI = Path(flowmc.ui.__file__).parent
FORBIDDEN = ("flowmc.devices", "flowmc.nodes")


def imported_modules(tree: ast.AST) -> list[tuple[int, str]]:
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module:
            found.append((node.lineno, node.module))
            if node.module == "flowmc":
                found += [(node.lineno, f"flowmc.{alias.name}") for alias in node.names]
        elif isinstance(node, ast.Call) and getattr(node.func, "attr", getattr(node.func, "id", "")) in (
                "import_module", "__import__") and node.args and isinstance(node.args[0], ast.Constant):
            found.append((node.lineno, str(node.args[0].value)))
    return found


def test_ui_imports_no_device_or_node_module():
    bad = [f"{path.name}:{line}: {name}" for path in sorted(UI.rglob("*.py"))
           for line, name in imported_modules(ast.parse(path.read_text(encoding="utf-8")))
           if name.startswith(FORBIDDEN)]
    assert bad == []


def test_the_check_sees_function_level_and_string_imports():
    tree = ast.parse("def f():\n    from flowmc.nodes import load_all\n    importlib.import_module('flowmc.devices.card')\n"
                     "from flowmc import devices\n")
    assert sorted(name for _, name in imported_modules(tree)) == ["flowmc", "flowmc.devices", "flowmc.devices.card",
                                                                  "flowmc.nodes"]
