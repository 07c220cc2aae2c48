"""The front panel: a graph's interface inputs as controls, as on a LabVIEW VI's front panel.

Each Number, Bool or Text input becomes a slider, number field, checkbox, text field or dropdown,
chosen from the schema of the params it feeds (bounds, Literal choices). Changing a control calls
``on_change(values)`` with every input's value; in the editor that queues a run on its session (the
one way to run: the runtime's cache runs only the affected nodes, and the 3D view hears the result).
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass
from typing import Any, Callable

from flowmc.errors import FlowmcError
from flowmc.ui.text import md, plain

__all__ = ["ControlSpec", "control_specs", "FrontPanel"]


@dataclass(frozen=True)
class ControlSpec:
    """One control: ``kind`` in slider, number, checkbox, text, dropdown (or ``note`` for inputs of
    other types, which are wired, not set). Bounds say whether they are exclusive (``gt``/``lt``).
    ``unset``: nothing gives a value (an optional param left empty), so it is not sent until changed."""

    name: str
    kind: str
    initial: Any
    type: str
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    integer: bool = False
    step: float | None = None
    options: tuple[str, ...] = ()
    hint: str = ""
    unset: bool = False

    def problem(self, value: Any) -> str | None:
        """Why ``value`` is not allowed here, or None."""
        if self.type != "Number":
            return None if not self.options or value in self.options else f"choose one of {', '.join(self.options)}"
        if not isinstance(value, (int, float)) or not math.isfinite(value):
            return "must be a number"
        if self.integer and value != int(value):
            return "must be a whole number"
        if self.low is not None and (value < self.low or (self.low_open and value == self.low)):
            return f"must be {'>' if self.low_open else '≥'} {self.low:g}"
        if self.high is not None and (value > self.high or (self.high_open and value == self.high)):
            return f"must be {'<' if self.high_open else '≤'} {self.high:g}"
        return None


def _param_schema(graph: Any, ref: str, registry: Any) -> tuple[dict, Any]:
    """The JSON schema of the param a 'node.port' target names (empty for data inputs) and its current value."""
    node_id, _, port = ref.partition(".")
    with contextlib.suppress(FlowmcError, KeyError, LookupError):
        node = graph.node(node_id)
        desc = registry.describe(node.type, node.params, graph_dir=graph.base_dir)
        prop = dict(desc["params_schema"].get("properties", {}).get(port, {}))
        for option in prop.pop("anyOf", []):  # `float | None` and the like: keep the non-null branch
            if option.get("type") != "null":
                prop = {**option, **prop}
        return prop, node.params.get(port, prop.get("default"))
    return {}, None


def _nice_step(span: float) -> float:
    """A 1-2-5 step giving about 200 slider positions over ``span``."""
    raw = span / 200.0
    base = 10.0 ** math.floor(math.log10(raw))
    return next(m * base for m in (1.0, 2.0, 5.0, 10.0) if m * base >= raw)


def _spec(item: Any, graph: Any, registry: Any) -> ControlSpec:
    """The control for one interface input, from the bounds and choices of every param it feeds."""
    schemas = [_param_schema(graph, ref, registry) for ref in item.to]
    current = next((v for _, v in schemas if v is not None), None)
    initial = item.default if item.default is not None else current
    low = high = None
    low_open = high_open = integer = False
    options: list | None = None
    hint = item.description or next((s.get("description", "") for s, _ in schemas if s.get("description")), "")
    for s, _ in schemas:
        for key, is_open in (("minimum", False), ("exclusiveMinimum", True)):
            if key in s and (low is None or s[key] > low or (s[key] == low and is_open)):
                low, low_open = float(s[key]), is_open
        for key, is_open in (("maximum", False), ("exclusiveMaximum", True)):
            if key in s and (high is None or s[key] < high or (s[key] == high and is_open)):
                high, high_open = float(s[key]), is_open
        integer = integer or s.get("type") == "integer"
        choices = s.get("enum") or ([s["const"]] if "const" in s else None)
        if choices is not None:
            options = list(choices) if options is None else [o for o in options if o in choices]
    if item.type == "Bool":
        return ControlSpec(item.name, "checkbox", bool(initial), "Bool", hint=hint)
    if item.type == "Text":
        opts = tuple(str(o) for o in options) if options else ()
        if opts:
            chosen = initial if initial in opts else opts[0]
            return ControlSpec(item.name, "dropdown", chosen, "Text", options=opts, hint=hint)
        return ControlSpec(item.name, "text", "" if initial is None else str(initial), "Text", hint=hint)
    if item.type != "Number":
        return ControlSpec(item.name, "note", None, item.type, hint=hint)
    value = float(initial) if initial is not None else (low if low is not None and not low_open else 0.0)
    value = int(value) if integer else value
    slider = low is not None and high is not None and high > low and low <= value <= high
    step = 1 if integer else (_nice_step(high - low) if slider else None)
    return ControlSpec(item.name, "slider" if slider else "number", value, "Number", low, high, low_open, high_open,
                       integer, step, hint=hint, unset=initial is None)


def control_specs(graph: Any, registry: Any) -> list[ControlSpec]:
    """One ControlSpec per interface input of ``graph`` (node types from ``registry``), in the interface's order."""
    iface = getattr(graph, "interface", None)
    return [_spec(item, graph, registry) for item in (iface.inputs if iface else [])]


class FrontPanel:
    """Controls for ``graph``'s interface inputs, in a folder of ``gui`` (a ``viser`` GuiApi), placed in
    the container that is current when it is made (``with panel.add_tab(...): FrontPanel(...)``).

    ``controls`` and ``messages`` (per-control problem text) are keyed by input name.
    """

    def __init__(self, gui: Any, graph: Any, on_change: Callable[[dict[str, Any]], Any], registry: Any, *,
                 label: str = "Front panel"):
        self.gui = gui
        self.on_change = on_change
        self.specs = {s.name: s for s in control_specs(graph, registry)}
        self.controls: dict[str, Any] = {}
        self.messages: dict[str, Any] = {}
        self._touched: set[str] = set()
        self.folder = gui.add_folder(label)
        with self.folder:
            if not self.specs:
                gui.add_markdown("This graph declares no inputs. Add interface inputs to get controls here.")
            for spec in self.specs.values():
                self._add(spec)
            self.status = gui.add_markdown("")

    def _add(self, spec: ControlSpec) -> None:
        gui, hint = self.gui, plain(spec.hint) if spec.hint else None
        if spec.kind == "note":
            gui.add_markdown(md("**{}** ({}): fed by a wire, not set here", spec.name, spec.type))
            return
        if spec.kind == "slider":
            lo = spec.low + (spec.step if spec.low_open else 0.0)
            hi = spec.high - (spec.step if spec.high_open else 0.0)
            handle = gui.add_slider(spec.name, min=lo, max=hi, step=spec.step, initial_value=spec.initial, hint=hint)
        elif spec.kind == "number":
            handle = gui.add_number(spec.name, spec.initial, hint=hint, step=spec.step,
                                    min=None if spec.low_open else spec.low, max=None if spec.high_open else spec.high)
        elif spec.kind == "checkbox":
            handle = gui.add_checkbox(spec.name, spec.initial, hint=hint)
        elif spec.kind == "dropdown":
            handle = gui.add_dropdown(spec.name, spec.options, initial_value=spec.initial, hint=hint)
        else:
            handle = gui.add_text(spec.name, spec.initial, hint=hint)
        self.controls[spec.name] = handle
        self.messages[spec.name] = gui.add_markdown("", visible=False)
        handle.on_update(lambda _event, name=spec.name: self._changed(name))

    def values(self) -> dict[str, Any]:
        """Every control's value by input name (whole numbers as int); an ``unset`` one only once changed."""
        return {name: int(h.value) if self.specs[name].integer else h.value for name, h in self.controls.items()
                if not self.specs[name].unset or name in self._touched}

    def _changed(self, name: str) -> None:
        self._touched.add(name)
        problem = self.specs[name].problem(self.controls[name].value)
        message = self.messages[name]
        message.content, message.visible = (md("**{}** {}", name, problem), True) if problem else ("", False)
        if problem:
            return
        try:
            self.on_change(self.values())
            self.status.content = ""
        except FlowmcError as err:
            self.status.content = md("**Run failed:** {}", err)

    def show_result(self, ok: bool, message: str = "") -> None:
        """What the run a change caused did: nothing shown when it went well, else why not."""
        self.status.content = "" if ok else md("**Run failed:** {}", message)

    def remove(self) -> None:
        """Take the panel off the page (to rebuild it for a changed interface)."""
        self.folder.remove()

