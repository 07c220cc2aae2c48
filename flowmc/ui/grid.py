"""A compact grid for table params (segment-table rows, machine axes): one row per table row, one
column per field (a point's X, Y, Z apart), titles with units, a row's kind as a choice.

Plain data and HTML here; the page script (``viser_internals``) turns edits, arrow keys and pastes
inside the grid into page events, and the inspector applies them with ``apply``. Pasting tab-
separated text (cells copied from a spreadsheet) fills the grid from the cell it lands in, adding
rows as needed; a first line that repeats the column titles is skipped. Every value is checked by
the node's params model afterwards, so a bad cell is kept, outlined red and named under the grid.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Any

from flowmc.ui.forms import FieldSpec, blank_value, new_row
from flowmc.ui.text import escape_html

__all__ = ["Column", "columns", "render", "apply", "GridError", "MAX_ROWS"]

MAX_ROWS = 400
MAX_PASTE = 200_000  # characters
_TRUE, _FALSE = {"true", "1", "yes", "y", "x", "on", "down"}, {"false", "0", "no", "n", "", "off", "up"}


class GridError(ValueError):
    """A cell value that cannot be read (the message says which cell and why)."""


@dataclass(frozen=True)
class Column:
    key: str  # "type", "radius", "end.0"
    field: str  # the row's field ("end")
    index: int | None  # component of a point field, else None
    kind: str  # tag, number, integer, checkbox, dropdown, text, optional
    title: str  # "end X (mm)"
    options: tuple[str, ...] = ()
    variants: frozenset[str] = frozenset()  # row kinds that have this field (empty: every row)


def _title(spec: FieldSpec, part: str = "") -> str:
    name = spec.name.replace("_", " ") + (f" {part}" if part else "")
    unit = spec.label[len(spec.name):].strip()
    return f"{name} {unit}".strip()


def columns(spec: FieldSpec) -> list[Column]:
    """The grid's columns for a ``rows`` field: its kind first, then each field (fields every kind has last)."""
    out = [Column(spec.tag, spec.tag, None, "tag", spec.tag, tuple(spec.variants))] if spec.tag else []
    seen: dict[str, tuple[FieldSpec, set[str]]] = {}
    for variant, fields in spec.variants.items():
        for f in fields:
            seen.setdefault(f.name, (f, set()))[1].add(variant)
    everywhere = set(spec.variants)
    ordered = [n for n in seen if seen[n][1] != everywhere] + [n for n in seen if seen[n][1] == everywhere]
    for name in ordered:
        f, kinds = seen[name]
        only = frozenset() if kinds == everywhere else frozenset(kinds)
        if f.kind in ("vector2", "vector3"):
            out += [Column(f"{name}.{i}", name, i, "number", _title(f, "XYZ"[i]), variants=only) for i in range(int(f.kind[-1]))]
        else:
            kind = f.inner.kind if f.kind == "optional" and f.inner is not None and f.inner.kind in ("number", "integer") \
                else f.kind
            out.append(Column(name, name, None, "optional" if f.kind == "optional" else kind, _title(f), f.options, only))
    return out


def _cell_text(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def _variant(spec: FieldSpec, row: Any) -> str:
    return str(row.get(spec.tag, "")) if spec.tag and isinstance(row, dict) else ""


def render(grid_id: str, spec: FieldSpec, rows: list[Any], errors: dict[tuple, str]) -> str:
    """The grid as HTML: inputs carry their row and column (``data-r``, ``data-c``); a row's fields its
    kind does not have are greyed out; cells with a problem are outlined red with the message as title."""
    cols = columns(spec)
    head = "".join(f"<th style='{_TH}'>{escape_html(c.title)}</th>" for c in cols) + f"<th style='{_TH}'></th>"
    body = []
    for r, row in enumerate(rows):
        variant = _variant(spec, row)
        cells = []
        for c in cols:
            applies = not c.variants or variant in c.variants
            value = row.get(c.field) if isinstance(row, dict) else None
            if c.index is not None and isinstance(value, (list, tuple)):
                value = value[c.index] if c.index < len(value) else None
            problem = errors.get((spec.name, r, c.field)) if applies else None
            border = "1px solid #e03131" if problem else "1px solid #ced4da"
            title = f" title='{escape_html(problem)}'" if problem else ""
            attrs = f"data-r='{r}' data-c='{escape_html(c.key)}'{title}"
            if not applies:
                cells.append(f"<td style='{_TD}'><input {attrs} disabled style='{_IN}background:#f1f3f5;border:{border}'></td>")
            elif c.kind in ("tag", "dropdown"):
                opts = "".join(f"<option{' selected' if o == _cell_text(value) else ''}>{escape_html(o)}</option>"
                               for o in (c.options if _cell_text(value) in c.options else (_cell_text(value), *c.options)))
                cells.append(f"<td style='{_TD}'><select {attrs} style='{_IN}border:{border}'>{opts}</select></td>")
            elif c.kind == "checkbox":
                cells.append(f"<td style='{_TD};text-align:center'><input type='checkbox' {attrs}"
                             f"{' checked' if value else ''}></td>")
            else:
                cells.append(f"<td style='{_TD}'><input {attrs} value='{escape_html(_cell_text(value))}' "
                             f"style='{_IN}border:{border}'></td>")
        cells.append(f"<td style='{_TD}'><button data-r='{r}' data-act='up' title='move up' style='{_BTN}'>↑</button>"
                     f"<button data-r='{r}' data-act='delete' title='remove this row' style='{_BTN}'>✕</button></td>")
        body.append(f"<tr><td style='{_TD};color:#868e96'>{r + 1}</td>{''.join(cells)}</tr>")
    return (f"<div style='overflow-x:auto;max-height:420px;overflow-y:auto;margin:0'>"
            f"<table data-flowmc-grid='{escape_html(grid_id)}' style='border-collapse:collapse;font-size:12px'>"
            f"<thead><tr><th style='{_TH}'>#</th>{head}</tr></thead>"
            f"<tbody>{''.join(body)}</tbody></table></div>")


_TH = "position:sticky;top:0;background:#f8f9fa;color:#495057;font-weight:600;padding:2px 4px;white-space:nowrap;text-align:left"
_TD = "padding:1px 2px;line-height:18px;vertical-align:middle"
_IN = "width:64px;height:20px;box-sizing:border-box;font-size:12px;padding:0 3px;margin:0;border-radius:3px;"
_BTN = "font-size:11px;line-height:16px;padding:0 4px;margin:0 0 0 2px;cursor:pointer"


def _parse(column: Column, text: str, where: str) -> Any:
    text = text.strip()
    if column.kind in ("number", "integer", "optional"):
        if column.kind == "optional" and text == "":
            return None
        try:
            value = float(text.replace(",", ".")) if text.count(",") == 1 and "." not in text else float(text)
        except ValueError:
            raise GridError(f"{where}: {text!r} is not a number") from None
        return int(value) if column.kind == "integer" and value.is_integer() else value
    if column.kind == "checkbox":
        low = text.lower()
        if low not in _TRUE | _FALSE:
            raise GridError(f"{where}: {text!r} is not yes or no")
        return low in _TRUE
    if column.kind in ("tag", "dropdown") and column.options and text not in column.options:
        raise GridError(f"{where}: {text!r} is not one of {', '.join(column.options)}")
    return text


def _set(spec: FieldSpec, rows: list[Any], r: int, column: Column, value: Any) -> None:
    """Put ``value`` in cell (r, column); a row's kind changes through ``new_row`` (keeping shared fields)."""
    row = rows[r]
    if column.kind == "tag":
        if _variant(spec, row) != value:
            rows[r] = new_row(spec, value, row if isinstance(row, dict) else None)
        return
    if column.variants and _variant(spec, row) not in column.variants:
        return  # this kind of row has no such field
    if column.index is None:
        if value is None:
            row.pop(column.field, None)
        else:
            row[column.field] = value
        return
    field = next(f for f in spec.variants[_variant(spec, row)] if f.name == column.field)
    point = list(row.get(column.field) or blank_value(field) or [0.0] * int(field.kind[-1]))
    point[column.index] = value
    row[column.field] = point


def apply(spec: FieldSpec, rows: list[Any], event: dict[str, Any]) -> list[Any]:
    """The table after one grid event: ``set`` (row, col, value), ``paste`` (row, col, text: tab-separated
    lines), ``delete`` / ``up`` (row) or ``add`` (kind). GridError says which cell is wrong (nothing changes)."""
    rows = copy.deepcopy(rows)
    cols = {c.key: c for c in columns(spec)}
    op = event.get("op")
    r = event.get("row")
    if op == "add":
        kind = event.get("kind") or (next(iter(spec.variants)) if spec.variants else "")
        if kind not in spec.variants:
            raise GridError(f"unknown row kind {kind!r}")
        return [*rows, new_row(spec, kind)][:MAX_ROWS]
    if not isinstance(r, int) or isinstance(r, bool) or not 0 <= r < len(rows) + (op == "paste"):
        raise GridError(f"there is no row {r!r}")
    if op == "delete":
        return rows[:r] + rows[r + 1:]
    if op == "up":
        if r > 0:
            rows[r - 1], rows[r] = rows[r], rows[r - 1]
        return rows
    column = cols.get(str(event.get("col")))
    if column is None:
        raise GridError(f"there is no column {event.get('col')!r}")
    if op == "set":
        _set(spec, rows, r, column, _parse(column, str(event.get("value", "")), f"row {r + 1}, {column.title}"))
        return rows
    if op == "paste":
        return _paste(spec, rows, r, list(cols.values()), list(cols).index(column.key), str(event.get("text", "")))
    raise GridError(f"unknown grid operation {op!r}")


def _paste(spec: FieldSpec, rows: list[Any], r0: int, cols: list[Column], c0: int, text: str) -> list[Any]:
    if len(text) > MAX_PASTE:
        raise GridError(f"the pasted text is longer than {MAX_PASTE} characters")
    lines = [line.split("\t") for line in text.replace("\r\n", "\n").replace("\r", "\n").split("\n")]
    while lines and lines[-1] == [""]:
        lines.pop()
    titles = [c.title.lower() for c in cols[c0:]]
    if lines and [cell.strip().lower() for cell in lines[0]] == titles[:len(lines[0])]:
        lines = lines[1:]  # the spreadsheet's header row
    if r0 + len(lines) > MAX_ROWS:
        raise GridError(f"a table holds at most {MAX_ROWS} rows")
    tag = next((k for k, c in enumerate(cols) if c.kind == "tag"), None)
    for k, cells in enumerate(lines):
        r = r0 + k
        if r >= len(rows):
            kind = _variant(spec, rows[-1]) if rows else next(iter(spec.variants))
            rows.append(new_row(spec, kind))
        ordered = sorted(range(len(cells)), key=lambda i: c0 + i != tag)  # the row's kind first
        for i in ordered:
            if c0 + i >= len(cols):
                raise GridError(f"row {r + 1}: {len(cells)} cells, but only {len(cols) - c0} columns from "
                                f"{cols[c0].title}")
            column = cols[c0 + i]
            if cells[i].strip() == "" and column.variants and _variant(spec, rows[r]) not in column.variants:
                continue  # a blank where this kind of row has no field
            _set(spec, rows, r, column, _parse(column, cells[i], f"row {r + 1}, {column.title}"))
    return rows
