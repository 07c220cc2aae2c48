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
from flowmc.ui import forms
from flowmc.ui.forms import MISSING, FieldSpec
from flowmc.ui.state import EditorState
from flowmc.ui.text import md, plain

__all__ = ["Inspector", "parse_text"]

MAX_TABLE_ROWS = 60  # longer tables are edited as JSON text


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
            self.fields, self.errors, self.specs, self.general = {}, {}, {}, None
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
        self.gui.add_markdown(md("**{}**: {} row{}", spec.label, len(rows), "s" if len(rows) != 1 else ""))
        self.errors[path] = self.gui.add_markdown("", visible=False)
        for k, row in enumerate(rows):
            variant = str(row.get(spec.tag, "")) if isinstance(row, dict) and spec.tag else ""
            title = plain(f"{spec.name} {k + 1}" + (f" · {variant}" if variant else ""), 80)
            with self.gui.add_folder(title, expand_by_default=len(rows) <= 8):
                if not isinstance(row, dict) or variant not in spec.variants:
                    self._add_field(FieldSpec(str(k), "json", "row"), (*path, k), row)
                    continue
                if spec.tag:
                    kind = self.gui.add_dropdown(spec.tag, tuple(spec.variants), initial_value=variant)
                    kind.on_update(lambda _e, k=k, h=kind: self._row_op(spec, path, "kind", k, h.value))
                for f in spec.variants[variant]:
                    self._add_field(f, (*path, k, f.name), row.get(f.name, f.default))
                ops = self.gui.add_button_group("row", ("Up", "Copy", "Remove"))
                ops.on_click(lambda e, k=k: self._row_op(spec, path, e.target.value, k))
                self.fields[(*path, k, "ops")] = ops
        add = self.gui.add_button_group(f"add {spec.name}", tuple(v or "row" for v in spec.variants))
        add.on_click(lambda e: self._row_op(spec, path, "Add", None, e.target.value))
        self.fields[(*path, "add")] = add

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

    def _row_op(self, spec: FieldSpec, path: tuple, op: str, k: int | None, arg: Any = None) -> None:
        """Add, copy, move up, remove or change the kind of a table row; the form is rebuilt."""
        with self.lock:
            if self.node_id is None:
                return
            rows = self._current(path[0])
            if op == "Add":
                rows.append(forms.new_row(spec, "" if arg == "row" else arg))
            elif op == "Remove":
                rows.pop(k)
            elif op == "Copy":
                rows.insert(k + 1, copy.deepcopy(rows[k]))
            elif op == "Up" and k > 0:
                rows[k - 1], rows[k] = rows[k], rows[k - 1]
            elif op == "kind" and rows[k].get(spec.tag) != arg:
                rows[k] = forms.new_row(spec, arg, rows[k])
            else:
                return
            self.editing = True
            try:
                self.state.set_param(self.node_id, path[0], rows)
            finally:
                self.editing = False
            self.show()
            if self.on_structure is not None:
                self.on_structure()

    # ------------------------------------------------------------------ problems
    def _show(self, path: tuple, message: str) -> None:
        for cut in range(len(path), 0, -1):
            handle = self.errors.get(path[:cut])
            if handle is not None:
                handle.content, handle.visible = md("⚠ **{}**", message), True
                return
        if self.general is not None:
            where = ".".join(str(p) for p in path)
            self.general.content, self.general.visible = md("⚠ **{}: {}**", where, message), True

    def show_errors(self, errors: dict[tuple, str]) -> None:
        """Each problem under its field (or the nearest table above it); the rest at the top."""
        with self.lock:
            for handle in self.errors.values():
                if handle.visible:
                    handle.visible = False
            if self.general is not None and self.general.visible:
                self.general.visible = False
            for path, message in errors.items():
                self._show(path, message)
