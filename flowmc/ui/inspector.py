"""The inspector: the selected node's params as a form generated from its params model.

Numbers carry their unit and bounds, choices are dropdowns, fixed tuples are vector fields,
point lists are one "x, y, z" line per point, lists of objects (segment-table rows, machine
axes) are a table of rows with add / move up / remove. Every value goes to the document as
typed (``EditorState.set_param``), and each problem is shown under the field it is about.
"""

from __future__ import annotations

import copy
import json
import threading
from typing import Any, Callable

import viser

from flowmc.errors import GraphError
from flowmc.graph import split_ref
from flowmc.ui import forms, grid
from flowmc.ui.forms import MISSING, FieldSpec
from flowmc.ui.state import EditorState
from flowmc.ui.text import md

__all__ = ["Inspector", "parse_text"]

MAX_TABLE_ROWS = grid.MAX_ROWS  # longer tables are edited as JSON text


class ParseError(ValueError):
    pass


def _number(text: str, integer: bool) -> float | int:
    try:
        value = float(text)
    except ValueError:
        raise ParseError(f"{text.strip()!r} is not a number") from None
    return int(value) if integer and value.is_integer() else value


def parse_text(spec: FieldSpec, text: str) -> Any:
    """The value a text box holds for ``spec`` (optional, list, points, json, text); ParseError says why not."""
    if spec.kind == "optional":
        inner = spec.inner
        if not text.strip():
            return None
        if inner.kind in ("number", "integer"):
            return _number(text, inner.kind == "integer")
        return parse_text(inner, text) if inner.kind in ("list", "json", "text", "points") else _json(text)
    if spec.kind == "list":
        parts = [p.strip() for p in text.replace("\n", ",").split(",") if p.strip()]
        return parts if spec.inner.kind == "string" else [_number(p, spec.inner.kind == "integer") for p in parts]
    if spec.kind == "points":
        points = []
        for k, line in enumerate(ln for ln in text.splitlines() if ln.strip()):
            try:
                points.append([_number(p, False) for p in line.replace(";", ",").split(",")])
            except ParseError as exc:
                raise ParseError(f"line {k + 1}: {exc}") from None
        return points
    if spec.kind == "json":
        return _json(text)
    return text


def _json(text: str) -> Any:
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise ParseError(f"not valid JSON: {exc.msg} (line {exc.lineno}, column {exc.colno})") from None


def _text_of(spec: FieldSpec, value: Any) -> str:
    if value is None or value is MISSING:
        return ""
    if spec.kind == "optional":
        return _text_of(spec.inner, value)
    if spec.kind == "list" and isinstance(value, list):
        return ", ".join(f"{v:g}" if isinstance(v, float) else str(v) for v in value)
    if spec.kind == "points" and isinstance(value, list):
        return "\n".join(", ".join(f"{c:g}" if isinstance(c, (int, float)) else str(c) for c in p) for p in value)
    if spec.kind in ("number", "integer") and isinstance(value, (int, float)):
        return f"{value:g}"
    return value if spec.kind == "text" and isinstance(value, str) else json.dumps(value)


class Inspector:
    """Builds its form in ``container`` (a tab or folder). ``fields`` and ``errors`` (the message
    under each field) are keyed by the path into the params: ``("feed",)``, ``("rows", 2, "radius")``."""

    def __init__(self, gui: viser.GuiApi, container: Any, state: EditorState, lock: threading.RLock,
                 on_structure: Callable[[], None] | None = None):
        self.gui, self.container, self.state, self.lock = gui, container, state, lock
        self.on_structure = on_structure
        self.node_id: str | None = None
        self.fields: dict[tuple, Any] = {}
        self.errors: dict[tuple, Any] = {}
        self.specs: dict[str, FieldSpec] = {}
        self.grids: dict[str, FieldSpec] = {}  # grid id ("node/param") -> its rows field
        self.editing = False  # True while the form itself is changing the document
        self.root: Any = None
        self.general: Any = None
        self.show()

    # ------------------------------------------------------------------ building
    def show(self) -> None:
        """Rebuild the form for the selection (one node: its params; else a short note)."""
        with self.lock:
            if self.root is not None:
                self.root.remove()
            self.fields, self.errors, self.specs, self.grids, self.general = {}, {}, {}, {}, None
            nodes = self.state.selected_nodes
            self.node_id = nodes[0] if len(nodes) == 1 and self.state.has_node(nodes[0]) else None
            with self.container:
                self.root = self.gui.add_folder("Params", order=10.0)
            with self.root:
                if self.node_id is None:
                    text = f"{len(nodes)} nodes selected." if nodes else "Click a node to edit its params."
                    self.gui.add_markdown(text)
                    return
                self._build(self.node_id)
            self.show_errors(self.state.param_errors(self.node_id))

    def _build(self, node_id: str) -> None:
        node = self.state.node(node_id)
        try:
            cls = self.state.runtime.registry.lookup(node.type, self.state.base_dir)
        except GraphError as exc:
            self.gui.add_markdown(md("**{}**: {}", node_id, exc.message))
            return
        self.gui.add_markdown(md("**{}** · {} (_{}_)  \n{}", node_id, cls.title, cls.type_id, cls.description))
        self.general = self.gui.add_markdown("", visible=False)
        wired = {split_ref(w.to)[1]: w.from_ for w in self.state.graph.wires if split_ref(w.to)[0] == node_id}
        for spec in forms.form_fields(cls.Params.model_json_schema()):
            self.specs[spec.name] = spec
            value = node.params.get(spec.name, spec.default)
            source = wired.get(spec.name)
            if spec.kind == "rows" and isinstance(value, list) and len(value) <= MAX_TABLE_ROWS:
                self._add_rows(spec, (spec.name,), value)
            else:
                self._add_field(spec, (spec.name,), value, f"fed by {source}" if source else None)
        if not self.specs:
            self.gui.add_markdown("This node has no params.")

    def _add_field(self, spec: FieldSpec, path: tuple, value: Any, wired: str | None = None) -> None:
        gui, hint = self.gui, (f"{wired}. " if wired else "") + spec.hint
        label, disabled = spec.label + (" ⟵ wire" if wired else ""), wired is not None
        kind = spec.kind
        fits = {"number": (int, float), "integer": (int,), "checkbox": (bool,), "text": (str,), "dropdown": (str,),
                "vector2": (list, tuple), "vector3": (list, tuple)}.get(kind)
        if fits is not None and (value is MISSING or isinstance(value, bool) != (kind == "checkbox")
                                 or not isinstance(value, fits)):
            value = forms.blank_value(spec) if value is MISSING else value
            if not isinstance(value, fits) or isinstance(value, bool) != (kind == "checkbox"):
                kind = "json"  # a stored value the widget cannot hold: edit it as text
        if kind in ("number", "integer"):
            low = spec.minimum if spec.minimum is not None and value >= spec.minimum else None  # an invalid stored
            high = spec.maximum if spec.maximum is not None and value <= spec.maximum else None  # value stays shown
            handle = gui.add_number(label, value, min=low, max=high, step=1 if kind == "integer" else None,
                                    hint=hint, disabled=disabled)
        elif kind == "checkbox":
            handle = gui.add_checkbox(label, value, hint=hint, disabled=disabled)
        elif kind == "dropdown":
            options = spec.options if value in spec.options else (value, *spec.options)
            handle = gui.add_dropdown(label, options, initial_value=value, hint=hint, disabled=disabled)
        elif kind in ("vector2", "vector3") and len(value) == int(kind[-1]):
            add_vector = gui.add_vector2 if kind == "vector2" else gui.add_vector3
            handle = add_vector(label, tuple(value), hint=hint, disabled=disabled)
        else:
            plain_kind = kind == spec.kind and kind not in ("vector2", "vector3")
            text_spec = spec if plain_kind else FieldSpec(spec.name, "json", spec.label)
            multiline = text_spec.kind in ("points", "json") or (
                text_spec.kind == "optional" and text_spec.inner.kind == "points")
            handle = gui.add_text(label, _text_of(text_spec, value), multiline=multiline, hint=hint, disabled=disabled)
            handle.on_update(lambda _e, s=text_spec, h=handle: self._text_changed(s, path, h.value))
            self._register(path, handle)
            return
        handle.on_update(lambda _e, h=handle: self._changed(path, list(h.value) if isinstance(h.value, tuple) else h.value))
        self._register(path, handle)

    def _register(self, path: tuple, handle: Any) -> None:
        self.fields[path] = handle
        self.errors[path] = self.gui.add_markdown("", visible=False)

    def _add_rows(self, spec: FieldSpec, path: tuple, rows: list) -> None:
        """A table param as a grid (``grid``): cells edited in place, arrow keys, tab-separated paste."""
        self.fields[(*path, "count")] = self.gui.add_markdown(self._count(spec, rows))
        self.errors[path] = self.gui.add_markdown("", visible=False)
        node_id = self.node_id or ""
        grid_id = f"{node_id}/{spec.name}"
        self.grids[grid_id] = spec
        self.fields[path] = self.gui.add_html(grid.render(grid_id, spec, rows, self.state.param_errors(node_id)))
        add = self.gui.add_button_group(f"add {spec.name}", tuple(v or "row" for v in spec.variants))

        def add_row(event: Any) -> None:
            self.grid_event(grid_id, {"op": "add", "kind": "" if event.target.value == "row" else event.target.value})

        add.on_click(add_row)
        self.fields[(*path, "add")] = add

    @staticmethod
    def _count(spec: FieldSpec, rows: list) -> str:
        return md("**{}**: {} row{} (paste cells from a spreadsheet into a cell)", spec.label, len(rows),
                  "s" if len(rows) != 1 else "")

    def grid_event(self, grid_id: Any, event: Any) -> str | None:
        """Apply one grid event (from the page, so checked here) to its table param; returns why not, or None."""
        with self.lock:
            spec = self.grids.get(grid_id) if isinstance(grid_id, str) else None
            if spec is None or self.node_id is None or not isinstance(event, dict):
                return "that table is not shown any more"
            try:
                rows = grid.apply(spec, self._current(spec.name), event)
            except grid.GridError as exc:
                self._show((spec.name,), str(exc))
                return str(exc)
            self.editing = True
            try:
                errors = self.state.set_param(self.node_id, spec.name, rows)
            finally:
                self.editing = False
            handle = self.fields.get((spec.name,))
            if handle is not None:  # the page keeps the focused cell across the redraw
                handle.content = grid.render(grid_id, spec, rows, errors)
                self.fields[(spec.name, "count")].content = self._count(spec, rows)
            self.show_errors(errors)
            if event.get("op") != "set" and self.on_structure is not None:
                self.on_structure()  # the node's preview rows
            return None

    # ------------------------------------------------------------------ changes
    def _current(self, name: str) -> Any:
        node = self.state.node(self.node_id)
        spec = self.specs[name]
        value = node.params.get(name, spec.default)
        return copy.deepcopy(forms.blank_value(spec) if value is MISSING else value)

    def _changed(self, path: tuple, value: Any) -> None:
        """One field changed: write it into the param it belongs to and show the problems."""
        with self.lock:
            if self.node_id is None or not self.state.has_node(self.node_id):
                return
            name = path[0]
            new = value
            if len(path) > 1:
                new = self._current(name)
                target = new
                for part in path[1:-1]:
                    target = target[part]
                target[path[-1]] = value
            self.editing = True
            try:
                errors = self.state.set_param(self.node_id, name, new)
            finally:
                self.editing = False
            self.show_errors(errors)

    def _text_changed(self, spec: FieldSpec, path: tuple, text: str) -> None:
        try:
            value = parse_text(spec, text)
        except ParseError as exc:
            with self.lock:
                self._show(path, str(exc))
            return
        self._changed(path, value)

    # ------------------------------------------------------------------ problems
    def _target(self, path: tuple, message: str) -> tuple[Any, str]:
        """The message handle for a problem at ``path`` (its field, else the table above it, else the top)
        and the text to show there (naming the row and field when it lands on a table)."""
        for cut in range(len(path), 0, -1):
            handle = self.errors.get(path[:cut])
            if handle is not None:
                rest = path[cut:]
                if rest and isinstance(rest[0], int):
                    message = f"row {rest[0] + 1}" + "".join(f", {p}" for p in rest[1:]) + f": {message}"
                return handle, message
        return self.general, ".".join(str(p) for p in path) + f": {message}"

    def _show(self, path: tuple, message: str) -> None:
        handle, text = self._target(path, message)
        if handle is not None:
            handle.content, handle.visible = md("⚠ **{}**", text), True

    def show_errors(self, errors: dict[tuple, str]) -> None:
        """Each problem under its field (or the nearest table above it); the rest at the top."""
        with self.lock:
            for handle in self.errors.values():
                if handle.visible:
                    handle.visible = False
            if self.general is not None and self.general.visible:
                self.general.visible = False
            shown: dict[int, tuple[Any, list[str]]] = {}
            for path, message in errors.items():  # a table's problems are listed together under it
                handle, text = self._target(path, message)
                if handle is not None:
                    shown.setdefault(id(handle), (handle, []))[1].append(text)
            for handle, texts in shown.values():
                handle.content, handle.visible = "  \n".join(md("⚠ **{}**", t) for t in texts), True
