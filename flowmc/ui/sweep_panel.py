"""The Sweep tab: run the open graph over values of chosen front-panel controls, on worker processes, a
Dask LocalCluster or a running Dask cluster (its scheduler address), with live progress and the plot
when it ends. The workers use the editor's node types (its plugins and node folders).

Each front-panel control (an interface input) gets a checkbox and a list of values, suggested from its
bounds or choices (``0.01, 0.05`` or ranges ``start:stop:step``, as ``flowmc sweep --grid`` takes).
Controls left unticked keep their front-panel value in every variant. The sweep runs the graph as it is
when Start is pressed, in processes of its own (the editor's runtime is not used), and writes its rows,
tables and report into ``<graph>-sweep/`` beside the graph (a temporary folder for an unsaved graph).
After the sweep the plot's output and Pareto objective can be changed without running again.
"""

from __future__ import annotations

import math
import tempfile
import threading
from pathlib import Path
from typing import TYPE_CHECKING, Any

from flowmc.errors import FlowmcError
from flowmc.ui.front_panel import ControlSpec, control_specs
from flowmc.ui.text import md, plain

if TYPE_CHECKING:
    from flowmc.ui.session import PanelHost

__all__ = ["SweepPanel", "suggested_values"]

_NONE = "(none)"
_EXECUTORS = {"processes on this machine": "local", "Dask": "dask"}


def _fmt(value: float) -> str:
    return f"{value:.6g}"


def suggested_values(spec: ControlSpec) -> str:
    """Values to start from: a dropdown's choices, both states of a checkbox, a small whole-number range in
    full, else half, once and twice the control's value (within its bounds; across its range from 0)."""
    if spec.kind == "dropdown":
        return ", ".join(spec.options)
    if spec.kind == "checkbox":
        return "true, false"
    if spec.kind == "text":
        return str(spec.initial)
    low = None if spec.low is None else spec.low + ((spec.step or 0.0) if spec.low_open else 0.0)
    high = None if spec.high is None else spec.high - ((spec.step or 0.0) if spec.high_open else 0.0)
    if spec.integer and low is not None and high is not None and high - low <= 5:
        return ", ".join(str(v) for v in range(math.ceil(low), math.floor(high) + 1))
    value = float(spec.initial or 0.0)
    if value == 0.0 or not math.isfinite(value):
        if low is None or high is None:
            return "0, 1"
        values = [low + (high - low) * k / 4 for k in range(5)]
    else:
        values = [value * f for f in (0.5, 1.0, 2.0)]
    inside = sorted({v for v in values if spec.problem(v) is None})
    return ", ".join(str(round(v)) if spec.integer else _fmt(v) for v in inside)


class SweepPanel:
    """Built in the container current when it is made (the editor's Sweep tab)."""

    def __init__(self, host: PanelHost):
        self.host = host
        gui = host.gui
        self.session = host.session
        self.controls: dict[str, tuple[Any, Any]] = {}  # input name -> (checkbox, values text)
        self.thread: threading.Thread | None = None
        self.stop_event = threading.Event()
        self.outcome: Any = None
        self.sweep: Any = None
        self.folder: Path | None = None
        self.plots: list[Any] = []
        self.run_on: dict[str, Any] = {}  # where the sweep going runs: executor kind, address, workers
        gui.add_markdown("Run the graph over values of its front-panel controls (a, b, c or start:stop:step); "
                         "unticked controls keep their front-panel value.")
        self.controls_folder = gui.add_folder("Controls")
        with self.controls_folder:
            self.empty = gui.add_markdown("This graph declares no Number, Bool or Text inputs: add interface inputs "
                                          "to sweep them.", visible=False)
        with gui.add_folder("Where it runs", expand_by_default=False):
            self.executor = gui.add_dropdown("Executor", tuple(_EXECUTORS),
                                             hint="Worker processes, or Dask: a LocalCluster, or the cluster at "
                                                  "the scheduler address")
            self.workers = gui.add_number("Workers", 2, min=1, max=64, step=1,
                                          hint="Worker processes (not used with a scheduler address)")
            self.address = gui.add_text("Dask scheduler", "", hint="A running Dask cluster, e.g. tcp://host:8786 "
                                                              "(the graph's folder is shipped to its workers); "
                                                              "empty: a LocalCluster")
            self.devices = gui.add_dropdown("Hardware devices", ("refuse", "sim"),
                                            hint="Device nodes that drive hardware: refuse the sweep, or run them "
                                                 "on the simulated card")
        self.output = gui.add_dropdown("Plot", (_NONE,), hint="The output to plot against the swept controls")
        self.pareto = gui.add_dropdown("Pareto with", (_NONE,), hint="A second objective: the Pareto front of both "
                                                                     "(both minimised)")
        self.start = gui.add_button("Start sweep", color="green", hint="Run every variant in worker processes")
        self.stop = gui.add_button("Stop", color="red", disabled=True, hint="Stop after the batches running; "
                                                                            "the rows done are kept")
        self.progress = gui.add_progress_bar(0.0, visible=False)
        self.status = gui.add_markdown("")
        self.plot_folder = gui.add_folder("Plot")
        self.start.on_click(lambda _e: self.begin())
        self.stop.on_click(lambda _e: self.stop_event.set())
        self.output.on_update(lambda _e: self.replot())
        self.pareto.on_update(lambda _e: self.replot())
        self._interface = None
        self.rebuild()
        self._unsubscribe = self.session.state.subscribe(self._on_state)

    # ------------------------------------------------------------------ controls
    def _on_state(self, kind: str) -> None:
        if kind in ("graph", "document"):
            self.rebuild()

    def rebuild(self) -> None:
        """Controls for the graph's interface inputs (again only when the interface changed)."""
        graph = self.session.state.graph
        key = graph.interface.model_dump_json() if graph.interface is not None else ""
        if key == self._interface:
            return
        self._interface = key
        gui = self.host.gui
        for box, text in self.controls.values():
            box.remove()
            text.remove()
        self.controls = {}
        specs = [s for s in control_specs(graph, self.session.runtime.registry) if s.kind != "note"]
        self.empty.visible = not specs
        with self.controls_folder:
            for k, spec in enumerate(specs):
                box = gui.add_checkbox(plain(spec.name), k == 0, hint=plain(spec.hint or "Sweep this control"))
                text = gui.add_text(plain(f"{spec.name} values"), plain(suggested_values(spec)),
                                    hint="a, b, c or start:stop:step")
                self.controls[spec.name] = (box, text)
        numbers = [o.name for o in graph.interface.outputs if o.type == "Number"] if graph.interface else []
        self._set_options(numbers)

    def _set_options(self, outputs: list[str]) -> None:
        keep_y, keep_p = self.output.value, self.pareto.value
        outputs = [plain(o) for o in outputs]
        self.output.options = tuple(outputs) or (_NONE,)
        self.output.value = keep_y if keep_y in outputs else self.output.options[0]
        self.pareto.options = (_NONE, *outputs)
        self.pareto.value = keep_p if keep_p in outputs else _NONE

    # ------------------------------------------------------------------ running
    def _prepare(self) -> Any:
        """The Sweep of the graph as it is now: ticked controls are axes, the others their front-panel values."""
        from flowmc.sweep import Sweep, grid_axis, values_axis

        with self.session.lock:
            state = self.session.state
            graph = state.graph.model_copy(deep=True)
            graph.path = state.path if state.path is not None else state.folder / state.suggested_name
            fixed = self.session.inputs_provider()
        registry = self.session.runtime.registry
        axes, swept = [], []
        for name, (box, text) in self.controls.items():
            if box.value:
                axes.append(grid_axis(graph, f"{name}={text.value}", registry=registry))
                swept.append(name)
            elif name in fixed:
                axes.append(values_axis(graph, name, [fixed[name]], registry=registry))
        if not swept:
            raise FlowmcError("tick at least one control to sweep")
        kind, address = _EXECUTORS[self.executor.value], self.address.value.strip()
        if address and kind != "dask":
            raise FlowmcError("a scheduler address goes with the Dask executor")
        self.run_on = {"kind": kind, "address": address or None, "workers": int(self.workers.value)}
        self.folder = (graph.base_dir / f"{graph.path.name.removesuffix('.json').removesuffix('.flowmc')}-sweep"
                       if state.path is not None else Path(tempfile.mkdtemp(prefix="flowmc-sweep-")))
        return Sweep(graph, axes, devices=self.devices.value, ship=bool(address), skip=(self.folder,),
                     registry=registry), swept

    def begin(self) -> threading.Thread | None:
        """Start the sweep in a thread of its own (returned); a problem is shown, and nothing runs."""
        if self.thread is not None and self.thread.is_alive():
            self.host.notify("info", "a sweep is already going")
            return None
        try:
            self.sweep, self.swept = self._prepare()
        except FlowmcError as exc:
            self.status.content = md("**Cannot sweep:** {}", exc)
            self.host.notify("error", f"sweep: {exc}")
            return None
        self.stop_event.clear()
        self.start.disabled, self.stop.disabled = True, False
        self.progress.value, self.progress.visible = 0.0, True
        self.status.content = md("Starting {} variants…", len(self.sweep.variants))
        self.thread = threading.Thread(target=self._work, name="flowmc-sweep", daemon=True)
        self.thread.start()
        return self.thread

    def _work(self) -> None:
        from flowmc.sweep import Journal, open_executor

        journal = None
        try:
            journal = Journal(self.folder, overwrite=True)
            with open_executor(self.run_on["kind"], self.sweep.job, workers=self.run_on["workers"],
                               address=self.run_on["address"], resources=self.sweep.resources) as executor:
                self.outcome = self.sweep.run(executor, journal, on_progress=self._show_progress,
                                              stop=self.stop_event)
            self._finish()
        except Exception as exc:  # noqa: BLE001 - any failure is shown on the page; the editor goes on
            self.status.content = md("**Sweep stopped:** {}", exc)
            self.host.notify("error", f"sweep: {exc}")
        finally:
            if journal is not None:
                journal.close()
            self.start.disabled, self.stop.disabled = False, True

    def _show_progress(self, p: Any) -> None:
        self.progress.value = 100.0 * (p.done + p.failed) / max(1, p.total)
        self.status.content = md("{} done, {} failed, {} left" + (", {:.1f} variants/s" if p.rate else ""),
                                 p.done, p.failed, p.left, *([p.rate] if p.rate else []))

    def _finish(self) -> None:
        from flowmc.sweep import write_tables
        from flowmc.sweep.report import choose, write_report

        outcome = self.outcome
        write_tables(self.folder, outcome.columns, outcome.rows)
        numeric = [c.removeprefix("out.") for c in outcome.columns if c.startswith("out.")
                   and any(isinstance(r.get(c), (int, float)) and not isinstance(r.get(c), bool) for r in outcome.rows)]
        self._set_options(numeric)
        failed = next((r for r in outcome.rows if r["status"] != "done"), None)
        summary = (("Stopped: " if outcome.interrupted else "") + f"{outcome.done} done, {outcome.failed} failed"
                   + (f", {outcome.left} not run" if outcome.left else "") + f" in {outcome.elapsed:.1f} s.")
        choice = choose(outcome.columns, outcome.rows, self.sweep.params, outputs=None, against=self._against())
        write_report(self.folder / "report.html", title=f"Sweep of {self.session.state.graph.title or 'the graph'}",
                     summary=[summary], choice=choice, rows=outcome.rows, params=self.sweep.params)
        self.status.content = (md("{} Rows and report: {}", summary, self.folder)
                               + (md("\n\nFirst failure, variant {}: {}", failed["variant"], failed["error"])
                                  if failed else ""))
        self.progress.visible = False
        self.replot()

    def _against(self) -> list[str]:
        """The swept controls to plot against: numeric ones first (a line over a range reads best)."""
        rows = self.outcome.rows
        return sorted(self.swept, key=lambda name: not all(isinstance(r.get(name), (int, float)) for r in rows))

    def replot(self) -> None:
        """Draw the chosen output against the swept controls (and the Pareto front) from the last sweep."""
        if self.outcome is None or self.output.value == _NONE:
            return
        from flowmc.sweep.report import choose, figures

        outcome = self.outcome
        pareto = [self.output.value, self.pareto.value] if self.pareto.value != _NONE else None
        try:
            choice = choose(outcome.columns, outcome.rows, self.sweep.params, outputs=[self.output.value],
                            against=self._against(), pareto=pareto)
        except FlowmcError as exc:
            self.status.content = md("**Cannot plot:** {}", exc)
            return
        figs, _front = figures(choice, outcome.rows, self.sweep.params)
        for handle in self.plots:
            handle.remove()
        self.plots = []
        with self.plot_folder:
            for fig in figs:
                fig.update_layout(height=340, margin={"l": 50, "r": 10, "t": 50, "b": 40}, title_font_size=13,
                                  legend={"orientation": "h", "y": -0.25})
                self.plots.append(self.host.gui.add_plotly(fig, aspect=1.2))

    def close(self) -> None:
        self.stop_event.set()
        self._unsubscribe()
        if self.thread is not None:
            self.thread.join(timeout=30.0)
