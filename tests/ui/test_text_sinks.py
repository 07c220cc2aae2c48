"""No UI code builds markdown or HTML by string formatting: text put into ``add_markdown``, ``add_html``
or a ``.content`` goes through ``flowmc.ui.text`` (``md``, ``escape_md``, ``escape_html``), so a value
from a file can never become markup. Checked on the source of every module in flowmc/ui."""

from __future__ import annotations

import ast
from pathlib import Path

import flowmc.ui

UI = Path(flowmc.ui.__file__).parent
SAFE_CALLS = {"md", "escape_md", "escape_html", "plain", "embed_html"}


def _formatting(expr: ast.AST) -> list[ast.AST]:
    """f-strings, ``.format`` and ``%`` formatting in ``expr`` that are not inside a safe call."""
    found: list[ast.AST] = []

    def walk(node: ast.AST) -> None:
        if isinstance(node, ast.Call):
            name = node.func.attr if isinstance(node.func, ast.Attribute) else getattr(node.func, "id", "")
            if name in SAFE_CALLS:
                return
            if name == "format" and isinstance(node.func, ast.Attribute):
                found.append(node)
        if isinstance(node, ast.JoinedStr) or (isinstance(node, ast.BinOp) and isinstance(node.op, ast.Mod)
                                               and isinstance(node.left, ast.Constant)):
            found.append(node)
            return
        for child in ast.iter_child_nodes(node):
            walk(child)

    walk(expr)
    return found


def _sinks(tree: ast.AST):
    """(expression, line) of every value that reaches markdown or HTML."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr in ("add_markdown", "add_html"):
            yield from ((a, node.lineno) for a in node.args[:1])
            yield from ((k.value, node.lineno) for k in node.keywords if k.arg == "content")
        elif isinstance(node, (ast.Assign, ast.AugAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for target in targets:
                if isinstance(target, ast.Attribute) and target.attr == "content":
                    yield node.value, node.lineno
                elif isinstance(target, ast.Tuple) and isinstance(node.value, (ast.Tuple, ast.IfExp)):
                    for element in target.elts:
                        if isinstance(element, ast.Attribute) and element.attr == "content":
                            yield node.value, node.lineno


def test_markdown_and_html_are_never_built_by_string_formatting():
    problems = []
    for file in sorted(UI.glob("*.py")):
        tree = ast.parse(file.read_text(encoding="utf-8"))
        for expr, line in _sinks(tree):
            if _formatting(expr):
                problems.append(f"{file.name}:{line}")
    assert not problems, f"use flowmc.ui.text.md(...) for markdown built from values: {problems}"


def test_the_check_finds_formatting():
    tree = ast.parse('h.content = f"**{x}**"\ngui.add_markdown("a {}".format(x))\nh.content = md("{}", f"{x}")\n'
                     'h.content, h.visible = ("%s" % x, True)\n')
    assert [bool(_formatting(e)) for e, _ in sorted(_sinks(tree), key=lambda s: s[1])] == [True, True, False, True]
