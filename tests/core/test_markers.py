"""Tests of real parts carry their marker (so ``-m`` selects them), and a skip of one is a failure."""

from __future__ import annotations

import ast
import shutil
import subprocess
import sys
from pathlib import Path

TESTS = Path(__file__).resolve().parents[1]


def _marks(decorators: list[ast.expr]) -> set[str]:
    found = set()
    for node in decorators:
        for inner in ast.walk(node):
            if isinstance(inner, ast.Attribute) and isinstance(inner.value, ast.Attribute) and inner.value.attr == "mark":
                found.add(inner.attr)
    return found


def _module_marks(tree: ast.Module) -> set[str]:
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", "") == "pytestmark" for t in node.targets):
            return _marks([node.value])
    return set()


def _needs(path: Path, test: ast.FunctionDef) -> set[str]:
    needs = set()
    calls = {getattr(n.func, "id", getattr(n.func, "attr", "")) for n in ast.walk(test) if isinstance(n, ast.Call)}
    if "chromium" in calls or "browser" in {a.arg for a in test.args.args}:
        needs.add("browser")
    if path.parent.name == "linuxcnc":
        needs.add("linuxcnc")
    if path.parent.name == "packaging":
        needs.add("packaging")
    return needs


def test_every_test_of_a_real_part_is_marked():
    missing = []
    for path in sorted(TESTS.rglob("test_*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        module = _module_marks(tree)
        for node in tree.body:
            if isinstance(node, ast.FunctionDef) and node.name.startswith("test_"):
                lacking = _needs(path, node) - module - _marks(node.decorator_list)
                missing += [f"{path.relative_to(TESTS)}::{node.name}: {m}" for m in sorted(lacking)]
    assert missing == []


def test_a_skipped_real_part_test_fails(tmp_path):
    shutil.copy(TESTS / "conftest.py", tmp_path / "conftest.py")
    (tmp_path / "pytest.ini").write_text("[pytest]\nmarkers =\n    browser: b\n    linuxcnc: l\n    packaging: p\n")
    (tmp_path / "test_probe.py").write_text(
        "import pytest\n\n@pytest.mark.browser\ndef test_marked():\n    pytest.skip('no chromium here')\n\n"
        "def test_plain():\n    pytest.skip('fine to skip')\n")
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(tmp_path)],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1
    assert "1 failed, 1 skipped" in proc.stdout
    assert "a browser test may not skip (Skipped: no chromium here)" in proc.stdout
