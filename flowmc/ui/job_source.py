"""Where a running job is, shown in its source: the G-code lines around the current one, or the segment
table's rows around the current row, with the current one highlighted.

A program's segments are named by where they came from (``part.ngc:12``, ``text:5``, ``row 3``). The
G-code text is the graph's own: a G-code node's ``text``, or its ``file`` (read once, resolved inside
the graph's folder with the core's ``resolve_inside``). Every piece of that text is untrusted and goes
to the page through ``escape_html``. Without a source to show, the segment names around the current
segment are shown instead.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any, Iterator

from flowmc.errors import FlowmcError
from flowmc.runtime import resolve_inside
from flowmc.ui.text import escape_html

__all__ = ["SourceView", "BEFORE", "AFTER", "empty_html"]

BEFORE, AFTER = 2, 4  # lines shown before and after the current one
MAX_BYTES = 64 * 2**20  # a G-code file larger than this is not read for the view
_NAMED = re.compile(r"^(.*):(\d+)$")
_ROW = re.compile(r"^row (\d+)$")
_CURRENT = "#ffe066"


def _nodes(nodes: Any) -> Iterator[Any]:
    for node in nodes:
        yield node
        for body in getattr(node, "bodies", {}).values():
            yield from _nodes(body.nodes)


class SourceView:
    """The sources of one graph's programs, by the name their segments carry."""

    def __init__(self, graph: Any, base_dir: Path):
        self.base_dir = Path(base_dir)
        self.gcode: dict[str, tuple[str, Any]] = {}  # segment source name -> ("text", str) or ("file", name)
        self.tables: list[list[Any]] = []
        for node in _nodes(graph.nodes):
            params = node.params or {}
            if node.type == "path.gcode_in":
                if params.get("file"):
                    self.gcode.setdefault(str(params["file"]), ("file", str(params["file"])))
                elif str(params.get("text") or "").strip():
                    self.gcode.setdefault("text", ("text", str(params["text"])))
            elif node.type == "path.segment_table" and isinstance(params.get("rows"), list):
                self.tables.append(params["rows"])
        self._lines: dict[str, list[str] | None] = {}

    def lines(self, source: str) -> list[str] | None:
        """The text of ``source`` as lines (None when it is not one of the graph's or cannot be read)."""
        if source not in self._lines:
            self._lines[source] = self._read(source)
        return self._lines[source]

    def _read(self, source: str) -> list[str] | None:
        kind, value = self.gcode.get(source, ("", None))
        if kind == "text":
            return value.splitlines()
        if kind != "file":
            return None
        try:
            path = resolve_inside(self.base_dir, self.base_dir, value)
            if path.stat().st_size > MAX_BYTES:
                return None
            return path.read_text(encoding="utf-8", errors="replace").splitlines()
        except (OSError, FlowmcError):
            return None

    def html(self, names: tuple[str, ...], segment: int | None, line: int | None) -> str:
        """The lines around where the job is (``segment`` 0-based, ``line`` the G-code line, 1-based)."""
        name = names[segment] if segment is not None and 0 <= segment < len(names) else ""
        named = _NAMED.match(name)
        source = named.group(1) if named else (next(iter(self.gcode)) if len(self.gcode) == 1 else "")
        if line is None and named:
            line = int(named.group(2))
        text = self.lines(source) if source and line is not None else None
        if text is not None and line is not None and 1 <= line <= len(text):
            return _window("gcode", source, text, line)
        row = _ROW.match(name)
        if row and len(self.tables) == 1:
            rows = [_row_text(r) for r in self.tables[0]]
            if 1 <= int(row.group(1)) <= len(rows):
                return _window("table", "segment table", rows, int(row.group(1)), "row ")
        if segment is None or not names:
            return empty_html()
        shown = [f"{n}" if n else "-" for n in names]
        return _window("segments", "segments", shown, segment + 1, "segment ")


def _row_text(row: Any) -> str:
    if isinstance(row, dict):
        return " ".join(f"{k}={json.dumps(v, separators=(',', ':'))}" for k, v in row.items())
    return str(row)


def empty_html() -> str:
    return "<div class='flowmc-source' data-kind='none'></div>"


def _window(kind: str, title: str, lines: list[str], current: int, label: str = "") -> str:
    """Lines ``current - BEFORE`` .. ``current + AFTER`` (1-based), the current one highlighted."""
    first, last = max(1, current - BEFORE), min(len(lines), current + AFTER)
    width = len(str(last))
    rows = []
    for n in range(first, last + 1):
        on = n == current
        style = f"background:{_CURRENT};font-weight:600" if on else "color:#444"
        rows.append(f"<div class='flowmc-src-line{' flowmc-src-current' if on else ''}' data-n='{n}' "
                    f"data-current='{int(on)}' style='white-space:pre;overflow:hidden;text-overflow:ellipsis;"
                    f"{style}'><span style='color:#999;user-select:none'>{n:>{width}} </span>"
                    f"{escape_html(lines[n - 1], 300)}</div>")
    where = f"{label}{current}" if label else f"line {current}"
    return (f"<div class='flowmc-source' data-kind='{kind}' data-line='{current}' "
            f"style='contain:inline-size;font-family:monospace;font-size:12px;margin-top:6px;border:1px solid #dee2e6;"
            f"border-radius:4px;padding:2px 4px'><div style='color:#666;font-family:sans-serif;font-size:11px'>"
            f"{escape_html(title)} · {escape_html(where)}</div>{''.join(rows)}</div>")
