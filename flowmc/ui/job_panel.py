"""The job panel: Start, Hold/Resume, Stop and E-stop for the graph's device nodes, with feed, rapid and
spindle overrides, a DRO, progress with time left, I/O lamps, the source lines around where the job is
(``job_source``) and a job log. The E-STOP sits above the folded Machine section, in sight from load.

Running the graph (Run, a front-panel change) only prepares device jobs: nothing moves until Start
here. Start runs the graph as it is now through the editor's one run queue (the pre-flight: each
device node prepares and checks its job), then hands that prepared run to the runtime's ``start``
with a ``Start`` whose hook tells this panel of each job's runner. Runners (``flowmc.devices.jobs``)
are reached only through their methods (hold, resume, stop, estop, set_overrides, subscribe): the UI
imports no device module. Their events arrive on the job's thread; the panel keeps the latest status
and a refresher pushes it to the page at ``RATE`` Hz, so a slow page never slows a machine.
"""

from __future__ import annotations

import collections
import threading
import time
from typing import Any

import viser

from flowmc.errors import FlowmcError
from flowmc.runtime import Start
from flowmc.ui.job_source import SourceView, empty_html
from flowmc.ui.session import RunRefused
from flowmc.ui.text import escape_html, md

__all__ = ["JobPanel", "RATE", "PACES", "SHORTCUTS"]

RATE = 25.0  # page updates per second while a job runs (the DRO, progress, lamps)
SOURCE_RATE = 4.0  # at most this many updates a second of the source lines around the current one
#: The tool in the 3D view moves less often: each move redraws that scene, which a browser without a
#: GPU (software WebGL) renders on the page's one main thread, where Esc and E-stop clicks wait.
TOOL_RATE = 8.0
LOG_LINES = 14
PACES = {"Real time": "realtime", "Instant": "instant"}
RAPIDS = ("100 %", "50 %", "25 %")
#: (label, key, modifier, action): Esc is feed hold, as on most controllers.
SHORTCUTS = (("Job: feed hold", "escape", None, "hold"), ("Job: resume", "enter", "shift", "resume"),
             ("Job: stop", "escape", "shift", "stop"), ("Job: E-stop", "E", "cmd/ctrl+shift", "estop"),
             ("Job: start", "enter", "cmd/ctrl+shift", "start"))
_LAMP_ON, _LAMP_OFF = "#2fb344", "#c9cdd3"


class JobPanel:
    """Built where the host's GUI is being filled (the top of the side panel, so the E-stop is always
    in sight). ``view``: the 3D view (``show_tool``), set by whoever owns it. ``record``: ask the runners
    to keep every commanded setpoint (tests check limits from them)."""

    def __init__(self, host: Any):
        self.host = host
        self.session = host.session
        self.gui = host.gui
        self.view: Any = None
        self.record = False
        self.rapid_pct = 100.0
        self.active = False  # from Start until the started run ends
        self.runner: Any = None  # the job running now, or the last one
        self.node_id = ""
        self.runners: list[tuple[str, Any]] = []  # every job of the last Start, in order
        self.result: Any = None  # the last started run
        self.log: collections.deque[str] = collections.deque(maxlen=200)
        self.pushed = 0  # page updates sent (the DRO rate benchmark compares with what the page saw)
        self._status: Any = None
        self._start: Start | None = None
        self._lock = threading.RLock()
        self._dirty = threading.Event()
        self._closed = threading.Event()
        self._shown: dict[str, Any] = {}
        self._tool_at: Any = None
        self._tool_time = 0.0
        self._source: SourceView | None = None  # the started graph's G-code and segment tables
        self._source_at: Any = None
        self._source_time = 0.0
        self._last: tuple[Any, Any] | None = None  # the last run's request and the front panel's values then
        self._build()
        self.session.on_result(self._on_result)
        self._refresher = threading.Thread(target=self._refresh_loop, name="flowmc-job-panel", daemon=True)
        self._refresher.start()

    # ------------------------------------------------------------------ layout
    def _build(self) -> None:
        gui = self.gui
        # Outside the folder: in sight from the page's load, folded panel or not, job or no job.
        self.estop_button = gui.add_button("E-STOP", color="red", icon=viser.Icon.ALERT_OCTAGON,
                                           hint="Stop every axis at once; outputs safe (Ctrl+Shift+E)")
        self.folder = gui.add_folder("Machine", expand_by_default=False)  # unfolded to Start; then in sight
        with self.folder:
            self.start_button = gui.add_button("Start", color="green", icon=viser.Icon.PLAYER_PLAY,
                                               hint="Pre-flight the graph, then run its device nodes (Ctrl+Shift+Enter)")
            self.hold_button = gui.add_button("Hold", color="yellow", icon=viser.Icon.PLAYER_PAUSE, disabled=True,
                                              hint="Feed hold: decelerate along the path and wait (Esc)")
            self.stop_button = gui.add_button("Stop", color="orange", icon=viser.Icon.PLAYER_STOP, disabled=True,
                                              hint="Controlled stop along the path, then clear the rest (Shift+Esc)")
            self.live = gui.add_html(live_html(None, "", False))
            self.source_view = gui.add_html(empty_html())
            with gui.add_folder("Overrides", expand_by_default=True):
                self.feed = gui.add_slider("Feed %", min=10, max=200, step=5, initial_value=100)
                self.rapid = gui.add_button_group("Rapid", RAPIDS)
                self.rapid_line = gui.add_markdown("Rapid 100 %")
                self.spindle = gui.add_slider("Spindle %", min=50, max=200, step=5, initial_value=100)
            with gui.add_folder("Start options", expand_by_default=False):
                self.pace = gui.add_dropdown("Pace", tuple(PACES), initial_value="Real time",
                                             hint="Real time: the simulated card follows the wall clock; "
                                                  "Instant: the whole job at once")
                self.speed = gui.add_number("Speed (x real time)", 1.0, min=0.1, max=100.0, step=0.1)
                self.start_at = gui.add_number("Start at segment", 0, min=0, step=1,
                                               hint="0: the beginning; N: rebuild the state at segment N and approach it")
                self.single_block = gui.add_checkbox("Single block", False,
                                                     hint="Hold at the end of every segment; Resume runs the next")
            with gui.add_folder("Job log", expand_by_default=True):
                self.log_view = gui.add_markdown("")
        self.start_button.on_click(lambda _e: self.start())
        self.hold_button.on_click(lambda _e: self.hold_or_resume())
        self.stop_button.on_click(lambda _e: self.stop())
        self.estop_button.on_click(lambda _e: self.estop())
        self.feed.on_update(lambda _e: self._override(feed=float(self.feed.value)))
        self.spindle.on_update(lambda _e: self._override(spindle=float(self.spindle.value)))
        self.rapid.on_click(lambda e: self._rapid(e.target.value))
        self.single_block.on_update(lambda _e: self._single_block())
        self._shortcuts(gui)

    def _shortcuts(self, gui: Any) -> None:
        for label, key, modifier, action in SHORTCUTS:
            command = gui.add_command(label, hotkey=key, modifier=modifier)
            command.on_trigger(lambda _e, a=action: getattr(self, a)())

    def attach_view(self, view: Any) -> None:
        """Show the running tool in ``view`` (the 3D view), and take the job's shortcuts there too: with
        the focus in the 3D view's frame, Esc must still hold the machine."""
        self.view = view
        server = getattr(view, "server", None)
        if server is not None:
            self._shortcuts(server.gui)

    # ------------------------------------------------------------------ commands
    def start(self) -> bool:
        """Start: pre-flight (run the graph as it is now), then run its jobs. False when refused."""
        with self._lock:
            if self.active:
                self._tell("error", "a job is running: stop it before starting again")
                return False
            request = self._current_run()
            if request is None:
                request = self.session.run(source="start")
                if isinstance(request, RunRefused):
                    self._tell("error", request.message)
                    return False
                self._note("pre-flight: running the graph")
            else:
                self._note("pre-flight: the last run's jobs (graph and front panel unchanged since)")
            self.active = True
            self.runners, self.runner, self._status = [], None, None
            with self.session.lock:
                self._source = SourceView(self.session.state.graph, self.session.state.base_dir)
        threading.Thread(target=self._start_after, args=(request,), name="flowmc-job-start", daemon=True).start()
        self._dirty.set()
        return True

    def _on_result(self, request: Any) -> None:
        if request.result is not None and request.plan is not None:
            self._last = (request, self.session.inputs_provider())

    def _current_run(self) -> Any:
        """The last run's request when Start may use its prepared jobs as they are: nothing runs or waits,
        the graph's plan is the one it ran, the front panel holds the values it ran with, and it has not
        been started. Start then moves exactly what the last Run showed, without computing it again."""
        if self._last is None or self.session.running:
            return None
        request, inputs = self._last
        result = request.result
        if result is not self.session.last_result or result.started or not result.ok:
            return None
        with self.session.lock:
            if self.session.state.plan() is not request.plan:
                return None
        if (request.inputs if request.inputs is not None else inputs) != self.session.inputs_provider():
            return None
        return request

    def hold(self) -> None:
        runner = self._running()
        if runner is not None and runner.state == "running":
            runner.hold()

    def resume(self) -> None:
        runner = self._running()
        if runner is not None and runner.state in ("holding", "held"):
            runner.resume()

    def hold_or_resume(self) -> None:
        runner = self._running()
        if runner is not None and runner.state in ("holding", "held"):
            runner.resume()
        else:
            self.hold()

    def _halt(self) -> Any:
        """Keep every job not yet started from starting; the running one (to stop), or None."""
        with self._lock:
            start, runner = self._start, self._running()
        if start is not None:
            start.stop()
        return runner

    def stop(self) -> None:
        """Controlled stop of the running job; no job after it starts."""
        runner = self._halt()
        if runner is not None:
            runner.stop()

    def estop(self) -> None:
        """E-stop the running job (no job after it starts); with none running, the Device tab's card."""
        runner = self._halt()
        if runner is not None:
            runner.estop()
            return
        card = getattr(self.session.devices, "card", None)
        if card is not None:
            try:
                card.estop()
                self._note("E-stop sent to the connected device")
            except FlowmcError as exc:
                self._tell("error", f"E-stop: {exc}")

    def _override(self, **values: float) -> None:
        runner = self._running()
        if runner is not None:
            try:
                runner.set_overrides(**values)
            except FlowmcError as exc:
                self._tell("error", str(exc))

    def _rapid(self, label: str) -> None:
        self.rapid_pct = float(label.split()[0])
        self.rapid_line.content = md("Rapid {}", label)
        self._override(rapid=self.rapid_pct)

    def _single_block(self) -> None:
        runner = self._running()
        if runner is not None:
            runner.set_single_block(bool(self.single_block.value))

    def _running(self) -> Any:
        runner = self.runner
        return runner if runner is not None and not runner.finished else None

    # ------------------------------------------------------------------ the run
    def options(self, jobs: dict[str, Any]) -> dict[str, Any]:
        """The Start's options from the panel: pace, speed, overrides, single block, start segment."""
        options: dict[str, Any] = {"pace": PACES[self.pace.value], "speed": float(self.speed.value),
                                   "single_block": bool(self.single_block.value), "record": self.record}
        overrides = {"feed": float(self.feed.value), "rapid": self.rapid_pct, "spindle": float(self.spindle.value)}
        options.update({k: v for k, v in overrides.items() if v != 100.0})
        segment = int(self.start_at.value or 0)
        if segment > 0:
            programs = [n for n, job in jobs.items() if getattr(job, "operation", "") == "program"]
            if len(programs) != 1:
                raise ValueError(f"start at segment {segment}: the graph has {len(programs)} program jobs"
                                 + (f" ({', '.join(programs)})" if programs else "") + "; it needs exactly one")
            options["start_at"] = {programs[0]: segment}
        return options

    def _start_after(self, request: Any) -> None:
        try:
            request.done.wait()
            result = request.result
            if result is None:
                raise ValueError(request.error or "the pre-flight run was replaced by a newer one; press Start again")
            if not result.ok:
                raise ValueError("pre-flight failed: " + "; ".join(result.errors))
            jobs = result.jobs
            if not jobs:
                raise ValueError("nothing to start: the graph has no device node")
            self._note("pre-flight passed: " + ", ".join(jobs))
            start = Start(self.options(jobs), on_job=self._on_job)
            with self._lock:
                self._start = start
            started = self.session.runtime.start(result, start)
            self.result = started
            failed = started.errors
            stopped = any(r.state in ("aborted", "faulted") for _n, r in self.runners)
            self._note("ended: " + ("; ".join(failed) if failed else "stopped" if stopped else "done"))
            if failed:
                self._tell("error", failed[0])
            self._show(started)
        except (ValueError, FlowmcError) as exc:
            self._note(f"not started: {exc}")
            self._tell("error", str(exc))
        except Exception as exc:  # noqa: BLE001 - a bug must reach the page, never leave the panel stuck
            self._note(f"failed: {type(exc).__name__}: {exc}")
            self._tell("error", f"{type(exc).__name__}: {exc}")
        finally:
            with self._lock:
                self.active, self._start = False, None
            self._dirty.set()

    def _on_job(self, node_id: str, runner: Any) -> None:
        with self._lock:
            self.runner, self.node_id, self._status = runner, node_id, runner.status
            self.runners.append((node_id, runner))
        runner.subscribe(lambda event, n=node_id: self._on_event(n, event))
        self._dirty.set()

    def _on_event(self, node_id: str, event: Any) -> None:
        with self._lock:
            self._status = event.status
            if event.kind == "state":
                self._note(f"{node_id}: {event.status.state}" + (f": {event.message}" if event.message else ""))
            elif event.kind in ("log", "fault") and event.message:
                self._note(f"{node_id}: {event.message}")
            elif event.kind == "io" and event.change is not None:
                c = event.change
                self._note(f"{node_id}: {c.kind} {c.channel} = {c.value:g}")
        self._dirty.set()

    def _show(self, result: Any) -> None:
        """The started run in the 3D view: what the devices did, beside what was planned."""
        if self.view is not None:
            try:
                self.view.show_result(result, self.session.state.graph)
            except Exception as exc:  # noqa: BLE001 - a view that cannot show it must not break the panel
                self._tell("error", f"could not show the job in the 3D view: {type(exc).__name__}: {exc}")

    # ------------------------------------------------------------------ telling
    def _note(self, text: str) -> None:
        self.log.append(f"{time.strftime('%H:%M:%S')} {text}")
        self._dirty.set()

    def _tell(self, kind: str, text: str) -> None:
        try:
            self.host.notify(kind, text)
        except Exception:  # noqa: BLE001 - a page that went away
            pass

    def _refresh_loop(self) -> None:
        while not self._closed.is_set():
            if not self._dirty.wait(0.5):
                continue
            self._dirty.clear()
            try:
                self._refresh()
            except Exception:  # noqa: BLE001 - a page mid-reload; the next event redraws
                pass
            self._closed.wait(1.0 / RATE)

    def _refresh(self) -> None:
        with self._lock:
            status, runner, active = self._status, self.runner, self.active
            log = list(self.log)[-LOG_LINES:][::-1]  # newest first: the last word is in sight
        state = status.state if status is not None else None
        moving = runner is not None and not runner.finished
        self._set("start_disabled", active, lambda v: setattr(self.start_button, "disabled", v))
        self._set("stop_disabled", not moving, lambda v: setattr(self.stop_button, "disabled", v))
        held = state in ("holding", "held")
        self._set("hold", (not moving or state == "stopping", held), self._hold_look)
        if self._set("live", live_html(status, self.node_id, active), lambda v: setattr(self.live, "content", v)):
            self.pushed += 1
        self._tool(status if moving else None)
        self._show_source(status, runner)
        self._set("log", "\n\n".join(md("{}", line) for line in log) or "",
                  lambda v: setattr(self.log_view, "content", v))

    def _show_source(self, status: Any, runner: Any) -> None:
        """The source lines around the job's segment or G-code line: sent when they change, at most
        ``SOURCE_RATE`` times a second (a change held back asks the refresher to come again)."""
        source = self._source
        if status is None or runner is None or source is None:
            return
        at = (id(runner), status.segment, status.line)
        if at == self._source_at:
            return
        now = time.monotonic()
        if now - self._source_time < 1.0 / SOURCE_RATE:
            self._dirty.set()
            return
        self._source_at, self._source_time = at, now
        names = tuple(getattr(runner.job, "segment_names", ()))
        self._set("source", source.html(names, status.segment, status.line),
                  lambda v: setattr(self.source_view, "content", v))

    def _set(self, key: str, value: Any, apply: Any) -> bool:
        """Send ``value`` to the page only when it changed (True when sent)."""
        if self._shown.get(key, object()) == value:
            return False
        self._shown[key] = value
        apply(value)
        return True

    def _hold_look(self, value: tuple[bool, bool]) -> None:
        disabled, held = value
        self.hold_button.disabled = disabled
        self.hold_button.label = "Resume" if held else "Hold"
        self.hold_button.color = "green" if held else "yellow"
        self.hold_button.icon = viser.Icon.PLAYER_PLAY if held else viser.Icon.PLAYER_PAUSE

    def _tool(self, status: Any) -> None:
        view = self.view
        show = getattr(view, "show_tool", None)
        at = None if status is None else (tuple(status.axes), tuple(round(v, 4) for v in status.commanded))
        now = time.monotonic()
        if show is None or at == self._tool_at or (at is not None and now - self._tool_time < 1.0 / TOOL_RATE):
            return
        self._tool_at, self._tool_time = at, now
        show(*(at if at is not None else ((), None)))

    # ------------------------------------------------------------------ closing
    def close(self) -> None:
        """Stop a running job (controlled) and the refresher (joined: the server stops next)."""
        self.stop()
        self._closed.set()
        self._dirty.set()
        self._refresher.join(timeout=2.0)


def _lamp(label: str, on: bool) -> str:
    color = _LAMP_ON if on else _LAMP_OFF
    return (f"<span class='flowmc-lamp' data-on='{int(on)}' style='white-space:nowrap;margin-right:8px'>"
            f"<span style='display:inline-block;width:11px;height:11px;border-radius:50%;background:{color};"
            f"vertical-align:middle;margin-right:3px'></span>{escape_html(label)}</span>")


def dro_html(status: Any) -> str:
    rows = []
    if status is not None:
        error = status.following_error
        for i, axis in enumerate(status.axes):
            actual = f"{status.actual[i]:10.3f}" if status.actual is not None else "-"
            ferr = f"{error[i]:8.4f}" if error is not None else "-"
            rows.append(f"<tr><td><b>{escape_html(axis)}</b></td><td>{status.commanded[i]:10.3f}</td>"
                        f"<td>{actual}</td><td>{ferr}</td></tr>")
    else:
        rows.append("<tr><td colspan=4 style='color:#888'>no job yet</td></tr>")
    return ("<table class='flowmc-dro' style='width:100%;font-family:monospace;font-size:15px;text-align:right;"
            "border-collapse:collapse'><tr style='color:#666;font-size:12px'><th style='text-align:left'>axis</th>"
            "<th>commanded mm</th><th>actual mm</th><th>follow. err</th></tr>" + "".join(rows) + "</table>")

def lamps_html(status: Any) -> str:
    out = status.outputs if status is not None else {}
    on = out.get("dout", out.get("outputs", []))
    if isinstance(on, dict):
        on = [int(ch) for ch, v in on.items() if v]
    on = {int(ch) for ch in on}
    lamps = [_lamp(f"OUT{ch}", ch in on) for ch in range(1, max(8, *on, 0) + 1)] if on or out else []
    rpm = float(out.get("spindle_rpm", 0.0) or 0.0)
    extra = [_lamp(f"Spindle {rpm:.0f} rpm", rpm != 0.0), _lamp("Pen/tool down", bool(out.get("tool_down")))]
    pwm = out.get("pwm")
    if pwm:
        extra.append(_lamp(f"PWM {float(pwm[1]):.0f} %", float(pwm[1]) > 0))
    if out.get("da"):
        extra.append(_lamp(f"DA {float(out['da']):.2f} V", True))
    return "<div class='flowmc-lamps' style='font-size:12px;line-height:1.9'>" + " ".join(lamps + extra) + "</div>"


_STATE_COLORS = {"running": "#2f9e44", "holding": "#e8a317", "held": "#e8a317", "stopping": "#e8590c",
                 "aborted": "#e03131", "faulted": "#e03131", "done": "#1c7ed6", "queued": "#868e96"}


def live_html(status: Any, node_id: str, active: bool) -> str:
    """What changes while a job runs, as one element (one page update a tick): state, progress with
    time left and where the job is, the DRO and the I/O lamps."""
    if status is None:
        head = ("<b>Pre-flight…</b>" if active else
                "<b>No job.</b> Run prepares the device nodes; only Start moves.")
        return f"<div class='flowmc-live' style='font-size:13px'>{head}{dro_html(None)}</div>"
    color = _STATE_COLORS.get(status.state, "#495057")
    pct = 100.0 * float(status.progress)
    left = f"{status.time_left:.1f} s left" if status.time_left is not None else "time left unknown"
    where = status.where + (f", line {status.line}" if status.line is not None else "")
    overrides = f"feed {status.feed:g} % · rapid {status.rapid:g} % · spindle {status.spindle:g} %"
    return (f"<div class='flowmc-live' data-state='{escape_html(status.state)}' style='font-size:13px'>"
            f"<div><span style='background:{color};color:white;border-radius:4px;padding:1px 6px;font-weight:600'>"
            f"{escape_html(status.state.upper())}</span> <b>{escape_html(node_id)}</b> "
            f"<span style='color:#555'>{escape_html(status.message)}</span></div>"
            f"<div style='margin:5px 0 2px;height:10px;background:#e9ecef;border-radius:5px;overflow:hidden'>"
            f"<div class='flowmc-progress' style='width:{pct:.1f}%;height:100%;background:{color}'></div></div>"
            f"<div class='flowmc-where'>{pct:.0f} % · {escape_html(left)} · {escape_html(where or '-')}</div>"
            f"<div style='color:#666;font-size:11px'>{escape_html(overrides)}</div>"
            f"{dro_html(status)}{lamps_html(status)}</div>")
