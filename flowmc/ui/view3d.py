"""The 3D toolpath view: programmed path, planned trajectory coloured by speed, travel box, playback, plots.

It runs on its own ``viser.ViserServer`` (one scene per browser tab), which the editor shows in a
docked panel through ``embed_html(view.url)``. Scene units are millimetres, Z up.

Scene nodes: ``/machine/travel`` (box edges), ``/path/<i>`` (programmed paths), ``/trajectory/<i>``
(setpoints, coloured by speed), ``/device/<i>`` (positions a device log recorded), ``/tool`` (the
marker the playback slider moves along the followed motion).

Everything is drawn with line segments, the marker too: the first Run used to freeze the page for
2.6-6.3 s under software WebGL while the browser compiled the lit material of a sphere marker.
The editor shows the view in a frame at the other name of this machine (``embed_html``), so the
browser runs it in its own process.
"""

from __future__ import annotations

import html
import socket
import threading
import time
from typing import Any, Sequence

import numpy as np
import viser
import viser.uplot as uplot

from flowmc.motion.machine import Machine
from flowmc.motion.path import Path, describe_segment
from flowmc.motion.trajectory import Steps, Trajectory
from flowmc.ui import view3d_data as data
from flowmc.ui import viser_internals
from flowmc.ui.guard import Guard
from flowmc.ui.text import md

__all__ = ["ToolpathView", "embed_html"]

MAX_SEGMENTS = 200_000  # line segments per motion sent to the browser (longer motions are strided)
_AXIS_COLORS = {"|v|": "#222222", "X": "#d62728", "Y": "#2ca02c", "Z": "#1f77b4", "A": "#9467bd"}
_PALETTE = ("#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf")
_MARKER_RGB = (30, 30, 30)
_JOB_TOOL_RGB = (225, 0, 225)  # the running job's tool (live): magenta, a colour no speed or path takes
_LOG_RGB = (120, 60, 160)


def embed_html(view: "ToolpathView", height: str = "calc(100vh - 128px)") -> str:
    """The ``<iframe>`` the editor puts in a docked panel. The page script (``viser_internals``) sets its
    address from ``data-flowmc-port`` and ``data-flowmc-token``: this machine under its other name, so
    the frame is cross-site."""
    href = html.escape(view.url, quote=True)
    token = html.escape(view.guard.token, quote=True)
    style = html.escape(f"width:100%;height:{height};border:0;display:block", quote=True)
    return (f'<iframe data-flowmc-port="{int(view.server.get_port())}" data-flowmc-token="{token}" '
            f'title="flowmc 3D view" style="{style}"></iframe>'
            f'<div style="font-size:12px;opacity:.75">Playback and plots: click the bar at the bottom of the view.</div>'
            f'<a href="{href}" target="_blank" rel="noopener">Open the 3D view in its own tab</a>')


def _marker_lines(size: float) -> np.ndarray:
    """Three axis-aligned strokes through the origin, ``size`` long each side: the playback marker."""
    return np.array([[[-size, 0, 0], [size, 0, 0]], [[0, -size, 0], [0, size, 0]], [[0, 0, -size], [0, 0, size]]],
                    dtype=np.float32)


class ToolpathView:
    """A second viser server showing paths and trajectories; ``show()`` replaces what it shows.

    ``show``/``set_time``/``close`` may be called from any thread. Handles are public for tests and
    for the editor: ``nodes`` (scene handles by name), ``plots`` (uplot handles by title),
    ``time_slider``, ``play_button``, ``marker``, ``info``.
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 0, *, tol: float = 0.01, max_plot_points: int = 4000,
                 guard: Guard | None = None):
        self.host = host
        self.guard = guard or Guard(host)
        self.tol = tol
        self.max_plot_points = max_plot_points
        self.server = viser_internals.guarded_server(self.guard, host=host, port=port, verbose=False)
        # Docked beside the editor the view is narrow: medium-width controls that fold away (the ">>" button).
        self.server.gui.configure_theme(show_share_button=False, control_width="medium")
        self.server.gui.main_panel.dock_right()  # beside the scene, not over it
        self.server.on_client_connect(viser_internals.fold_narrow_controls)  # docked narrow: the scene first
        self.server.scene.set_up_direction("+z")
        self.nodes: dict[str, Any] = {}
        self.plots: dict[str, Any] = {}
        self.motions: list[data.Motion] = []
        self.logs: list[Any] = []  # device logs
        self.motion: data.Motion | None = None
        self.speed_top = 0.0
        self._framed: tuple[np.ndarray, float] | None = None  # (centre, radius) the camera was last set for
        self._lock = threading.RLock()
        self._playing = threading.Event()
        self._closed = threading.Event()
        self._build_gui()
        self.marker = self.server.scene.add_line_segments(
            "/tool", _marker_lines(1.0), data.linear_rgb(np.full((3, 2, 3), _MARKER_RGB, np.uint8)), thickness=4.0,
            thickness_units="screen", visible=False)
        # Lines like the paths', not a mesh: a browser without a GPU compiles no new shader when it first shows.
        self.job_tool = self.server.scene.add_line_segments(
            "/job/tool", _marker_lines(1.0), data.linear_rgb(np.full((3, 2, 3), _JOB_TOOL_RGB, np.uint8)),
            thickness=7.0, thickness_units="screen", visible=False)
        self._player = threading.Thread(target=self._play_loop, name="flowmc-view3d-player", daemon=True)
        self._player.start()

    @property
    def url(self) -> str:
        """Where a browser finds the view: on all interfaces (``--host 0.0.0.0``), by this machine's
        name, so the editor's iframe works from other machines too."""
        host = socket.gethostname() if self.host in ("0.0.0.0", "::", "") else self.host
        return self.guard.url(host, self.server.get_port())

    # ------------------------------------------------------------------ GUI
    def _build_gui(self) -> None:
        gui = self.server.gui
        self.info = gui.add_markdown("Nothing to show yet: run a graph with a path or a trajectory.")
        with gui.add_folder("Playback"):
            self.follow = gui.add_dropdown("Follow", ("(none)",), disabled=True)
            self.time_slider = gui.add_slider("Time (s)", min=0.0, max=1.0, step=0.001, initial_value=0.0,
                                              disabled=True)
            self.play_button = gui.add_button("Play", icon=viser.Icon.PLAYER_PLAY, disabled=True)
            self.rate = gui.add_number("Playback speed (x)", 1.0, min=0.01, max=100.0, step=0.01)
            self.readout = gui.add_markdown("")
        self._plot_folder = gui.add_folder("Motion plots", expand_by_default=True)
        self._io_folder = gui.add_folder("Outputs over time", expand_by_default=False)
        self.time_slider.on_update(lambda _: self._on_time())
        self.follow.on_update(lambda _: self._on_follow())
        self.play_button.on_click(lambda _: self.pause() if self._playing.is_set() else self.play())

    # ------------------------------------------------------------------ showing
    def show(self, paths: Sequence[Path] = (), trajectories: Sequence[Trajectory | Steps] = (),
             machine: Machine | None = None, logs: Sequence[Any] = (),
             names: Sequence[str] | None = None) -> None:
        """Show programmed paths, trajectories/step streams (the last one is followed), the machine's
        travel box and device logs, replacing what was shown."""
        traj_names = list(names or [])
        traj_names += [f"motion {i + 1}" for i in range(len(traj_names), len(trajectories))]
        planned = [m for m in map(data.Motion.of, trajectories, traj_names) if len(m.t)]
        done = [m for m in (data.Motion.of(log, f"device log {i + 1}") for i, log in enumerate(logs)) if len(m.t)]
        with self._lock:
            self.pause()
            self.motions, self.logs = planned + done, list(logs)
            speeds = [m.speed for m in self.motions if len(m.t) > 1]
            self.speed_top = max((float(s.max()) for s in speeds), default=0.0)
            with self.server.atomic():
                bounds = self._draw_scene(list(paths), planned, machine, done)
                self._frame_camera(bounds)
            self._set_info(list(paths), self.motions, machine)
            self.follow.options = tuple(m.name for m in self.motions) or ("(none)",)
            self.follow.disabled = len(self.motions) < 2
            chosen = (planned or done or [None])[-1]
            if chosen is not None and self.follow.value != chosen.name:
                self.follow.value = chosen.name  # fires _on_follow
            else:
                self._select(chosen)

    def show_view(self, view: Any) -> None:
        """Show what one 3D View node (a ``flowmc.runtime.views.View``) was wired to."""
        values, params = view.values, view.params
        self.tol = float(params.get("tolerance") or self.tol)
        motions = [(values[k], f"{view.key}.{k}") for k in ("trajectory", "steps") if values.get(k) is not None]
        self.show([values["path"]] if values.get("path") is not None else [], [m for m, _ in motions],
                  values.get("machine") if params.get("travel_box", True) else None,
                  [values["log"]] if values.get("log") is not None else [], names=[n for _, n in motions])
        if view.empty:
            self.info.content = md("**{}**: nothing wired into it arrived in this run.", view.title)
        else:
            self.info.content = md("**{}**  \n", view.title) + self.info.content

    def show_result(self, result: Any, graph: Any = None) -> data.Shown:
        """Show what a ``RunResult`` produced (see ``view3d_data.collect``); returns what was picked."""
        shown = data.collect(result, graph)
        names = [shown.names.get(id(v), "") or f"motion {i + 1}" for i, v in enumerate(shown.trajectories)]
        self.show(shown.paths, shown.trajectories, shown.machine, shown.logs, names=names)
        return shown

    def _add_lines(self, name: str, segments: np.ndarray, colors: np.ndarray, px: float) -> None:
        if len(segments):
            self.nodes[name] = self.server.scene.add_line_segments(
                name, segments.astype(np.float32), data.linear_rgb(colors), thickness=px, thickness_units="screen")

    def _draw_scene(self, paths: list[Path], planned: list[data.Motion], machine: Machine | None,
                    done: list[data.Motion]) -> np.ndarray | None:
        """Replace the scene nodes; returns the (low, high) corners of the toolpaths (else of the travel box)."""
        for handle in self.nodes.values():
            handle.remove()
        self.nodes = {}
        drawn, box = [], None
        if machine is not None:
            edges, box = data.travel_edges(machine)
            self._add_lines("/machine/travel", edges, np.full((12, 2, 3), 150, np.uint8), 1.0)
        for i, path in enumerate(paths):
            segments, colors = data.path_lines(path, self.tol)
            self._add_lines(f"/path/{i}", segments, colors, 1.5)
            drawn.append(segments.reshape(-1, 3))
        for i, m in enumerate(planned + done):
            if len(m.t) < 2:
                continue
            k = np.unique(np.r_[np.arange(0, len(m.t), -(-len(m.t) // MAX_SEGMENTS)), len(m.t) - 1])
            pts = m.points[k]
            if i < len(planned):
                speed = np.linalg.norm(np.diff(m.positions[k], axis=0), axis=1) / np.diff(m.t[k])
                colors = np.repeat(data.speed_colors(speed, self.speed_top)[:, None, :], 2, axis=1)
                self._add_lines(f"/trajectory/{i}", data.pairs(pts), colors, 3.0)
            else:
                self._add_lines(f"/device/{i - len(planned)}", data.pairs(pts),
                                np.full((len(pts) - 1, 2, 3), _LOG_RGB, np.uint8), 1.5)
            drawn.append(pts)
        everything = np.vstack(drawn) if drawn else np.zeros((0, 3))
        return np.stack([everything.min(axis=0), everything.max(axis=0)]) if len(everything) else box

    def _frame_camera(self, bounds: np.ndarray | None) -> None:
        """Look at the toolpaths from the front-right, above, and size the marker to them. A re-run that
        draws about the same place keeps the camera where the user put it."""
        if bounds is None:
            return
        centre = bounds.mean(axis=0)
        radius = max(float(np.linalg.norm(bounds[1] - bounds[0])) / 2.0, 5.0)
        if self._framed is not None:
            old_centre, old_radius = self._framed
            if np.linalg.norm(centre - old_centre) < 0.25 * old_radius and 0.67 < radius / old_radius < 1.5:
                return
        self._framed = (centre, radius)
        eye = centre + radius * np.array([1.2, -2.2, 1.8])
        init = self.server.initial_camera
        init.near, init.far, init.up = radius / 200.0, radius * 50.0, (0.0, 0.0, 1.0)
        init.position, init.look_at = tuple(eye), tuple(centre)
        for client in self.server.get_clients().values():
            cam = client.camera
            cam.near, cam.far, cam.up_direction = radius / 200.0, radius * 50.0, (0.0, 0.0, 1.0)
            cam.position, cam.look_at = tuple(eye), tuple(centre)
        self.marker.points = _marker_lines(radius * 0.05)
        self.job_tool.points = _marker_lines(radius * 0.08)

    def _set_info(self, paths: list[Path], motions: list[data.Motion], machine: Machine | None) -> None:
        if not paths and not motions:
            self.info.content = "Nothing to show: the run produced no path or trajectory."
            return
        lines = []
        for p in paths:
            lines.append(f"- path: {len(p)} segments, {p.length:.3f} mm")
        for m in motions:
            unit = "s" if m.timed else "ticks (untimed)"
            top = float(m.speed.max()) if len(m.t) > 1 else 0.0
            lines.append(md("- {}: {} samples, {:.4g} {}, peak speed {:.4g}", m.name, len(m.t), m.duration, unit, top))
        if machine is None:
            lines.append("- no machine wired: no travel box")
        if self.speed_top > 0:
            lines.append(f"\nSpeed colours: blue 0 → green → red {self.speed_top:.4g} mm/s")
        self.info.content = "\n".join(lines)

    # ------------------------------------------------------------------ playback and plots
    def _on_follow(self) -> None:
        with self._lock:
            self._select(next((m for m in self.motions if m.name == self.follow.value), None))

    def _select(self, motion: data.Motion | None) -> None:
        """Follow ``motion``: slider range, marker, plots and I/O timeline."""
        self.pause()
        self.motion = motion
        live = motion is not None and len(motion.t) > 0
        self.time_slider.disabled = self.play_button.disabled = not live
        self.marker.visible = live
        if live:
            step = float(np.median(np.diff(motion.t))) if len(motion.t) > 1 else 0.001
            self.time_slider.min = float(motion.t[0])
            self.time_slider.max = float(max(motion.t[-1], motion.t[0] + step))
            self.time_slider.step = step
            self.time_slider.value = float(motion.t[0])
            self._on_time()  # also when the value did not change (then no update fires)
        self._draw_plots(motion)

    def _draw_plots(self, motion: data.Motion | None) -> None:
        for handle in self.plots.values():
            handle.remove()
        self.plots = {}
        if motion is None:
            return
        with self._plot_folder:
            for title, (x, lines) in data.motion_series(motion).items():
                self._add_plot(title, x, lines, "t (s)" if motion.timed else "tick")
        events = [data.signal_events(motion.signals, "program")] if len(motion.signals) else []
        events += [data.log_events(log, f"device {i + 1}") for i, log in enumerate(self.logs) if log.changes]
        t_end = max([motion.duration] + [log.duration for log in self.logs])
        with self._io_folder:
            for title, (x, lines) in data.io_timelines(events, t_end).items():
                self._add_plot(title, x, lines, "t (s)")

    def _add_plot(self, title: str, x: np.ndarray, lines: list[tuple[str, np.ndarray]], xlabel: str) -> None:
        x, ys = data.envelope(x, [y for _, y in lines], self.max_plot_points)
        series = [uplot.Series(label=xlabel)] + [
            uplot.Series(label=label, stroke=_AXIS_COLORS.get(label, _PALETTE[i % len(_PALETTE)]), width=1.5)
            for i, (label, _) in enumerate(lines)]
        self.plots[title] = self.server.gui.add_uplot(
            (x, *ys), tuple(series), title=title, scales={"x": uplot.Scale(time=False, auto=True)}, aspect=2.0)

    def _on_time(self) -> None:
        """Move the marker to the followed motion's sample nearest the slider's time."""
        with self._lock:
            m = self.motion
            if m is None or not len(m.t):
                return
            k = m.index_at(float(self.time_slider.value))
            p = m.points[k]
            self.marker.position = tuple(float(c) for c in p)
            v = float(m.speed[min(k, len(m.speed) - 1)]) if len(m.speed) else 0.0
            where = (f" · {describe_segment(int(m.segment[k]), m.segment_names)}"
                     if m.segment is not None and k < len(m.segment) else "")
            coords = " ".join(f"{a} {m.positions[k, i]:.3f}" for i, a in enumerate(m.axes))
            unit = "mm/s" if m.timed else "mm/tick"
            self.readout.content = md("t = {:.4f} · {} mm · speed {:.3f} {}{}", m.t[k], coords, v, unit, where)

    def show_tool(self, axes: tuple[str, ...], position: Any) -> None:
        """Where a running job's tool is now (machine axes, mm), live; ``position`` None hides it."""
        with self._lock:
            if position is None:
                self.job_tool.visible = False
                return
            point = data.xyz(np.asarray(position, dtype=float)[None, :], tuple(axes))[0]
            self.job_tool.position = (float(point[0]), float(point[1]), float(point[2]))
            self.job_tool.visible = True

    def set_time(self, t: float) -> None:
        """Put the playback at time ``t`` (clamped): moves the slider and the marker."""
        with self._lock:
            if self.motion is not None:
                self.time_slider.value = float(np.clip(t, self.time_slider.min, self.time_slider.max))

    def play(self) -> None:
        if self.motion is None or self._closed.is_set():
            return
        if self.time_slider.value >= self.time_slider.max:
            self.set_time(self.time_slider.min)
        self.play_button.label, self.play_button.icon = "Pause", viser.Icon.PLAYER_PAUSE
        self._playing.set()

    def pause(self) -> None:
        if self._playing.is_set():
            self._playing.clear()
            self.play_button.label, self.play_button.icon = "Play", viser.Icon.PLAYER_PLAY

    def _play_loop(self) -> None:
        """Advance the slider in real time (times the playback speed) while playing, 25 times a second."""
        last = time.monotonic()
        while not self._closed.is_set():
            if not self._playing.wait(0.1):
                last = time.monotonic()
                continue
            time.sleep(0.04)
            now = time.monotonic()
            with self._lock:
                if not self._playing.is_set() or self.motion is None:
                    continue
                t = float(self.time_slider.value) + (now - last) * float(self.rate.value)
                self.set_time(t)
                if t >= self.time_slider.max:
                    self.pause()
            last = now

    def close(self) -> None:
        """Stop playback and the server (safe to call twice)."""
        if self._closed.is_set():
            return
        self._closed.set()
        self._playing.clear()
        self._player.join(timeout=2.0)
        viser_internals.quiet(self.server)
        self.server.stop()

    def __enter__(self) -> "ToolpathView":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
