"""What the 3D view draws, as plain numpy: motions in time, speed colours, plot series, I/O timelines.

Kept apart from ``view3d.py`` so the numbers can be checked without a viser server, and so the
view module holds only scene and GUI code. Everything here is vectorised over samples.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from flowmc.motion.machine import Machine
from flowmc.motion.path import Path
from flowmc.motion.trajectory import Signal, Steps, Trajectory

__all__ = ["Motion", "Shown", "collect", "xyz", "speed_colors", "linear_rgb", "pairs", "path_lines", "travel_edges",
           "motion_series", "io_timelines", "signal_events", "log_events", "envelope", "SPEED_STOPS"]

#: Speed colour map stops (fraction of the top speed -> RGB): blue, cyan, green, yellow, red.
SPEED_STOPS = (
    (0.0, (40, 60, 220)),
    (0.25, (0, 170, 230)),
    (0.5, (40, 190, 60)),
    (0.75, (240, 200, 0)),
    (1.0, (220, 30, 30)),
)
FEED_RGB = (90, 90, 90)
RAPID_RGB = (235, 140, 40)
_TIMELINE_TITLES = {"dout": "Digital outputs", "din": "Digital inputs", "pwm_duty": "PWM duty (%)",
                    "pwm_freq": "PWM frequency (Hz)", "da": "DA (V)", "spindle_rpm": "Spindle (rpm)",
                    "tool": "Tool/pen (1 = down)"}


def xyz(positions: np.ndarray, axes: tuple[str, ...]) -> np.ndarray:
    """Columns X, Y, Z of per-axis positions as (N, 3); an axis the motion lacks is 0 (A is not drawn)."""
    positions = np.asarray(positions, dtype=float)
    out = np.zeros((len(positions), 3))
    for k, name in enumerate("XYZ"):
        if name in axes:
            out[:, k] = positions[:, axes.index(name)]
    return out


@dataclass(frozen=True, eq=False)
class Motion:
    """Positions against time, whatever produced them (a trajectory, a step stream, a device log).

    ``t`` rises; ``timed`` is False for an untimed step stream, whose "time" is the tick index.
    """

    name: str
    t: np.ndarray
    positions: np.ndarray  # (N, n_axes), in ``axes`` order
    axes: tuple[str, ...]
    signals: Signal = field(default_factory=Signal)
    timed: bool = True
    segment: np.ndarray | None = None  # path segment index of each sample, where known
    segment_names: tuple[str, ...] = ()  # where each path segment came from (for describe_segment)

    @cached_property
    def points(self) -> np.ndarray:
        """Positions as X, Y, Z scene points (N, 3)."""
        return xyz(self.positions, self.axes)

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0]) if len(self.t) else 0.0

    @cached_property
    def speed(self) -> np.ndarray:
        """Path speed over each interval (N-1 values)."""
        return np.linalg.norm(np.diff(self.positions, axis=0), axis=1) / np.diff(self.t)

    def index_at(self, t: float) -> int:
        """The sample nearest time ``t`` (clamped to the motion)."""
        k = int(np.searchsorted(self.t, t))
        if k >= len(self.t):
            return len(self.t) - 1
        if k > 0 and t - self.t[k - 1] <= self.t[k] - t:
            return k - 1
        return k

    @classmethod
    def of(cls, value: Any, name: str) -> "Motion":
        """A Trajectory, a Steps stream or a device log (``t``, ``position``, ``axes``) as a Motion."""
        if isinstance(value, Trajectory):
            return cls(name, value.times, value.positions, value.axes, value.signals, segment=value.segment,
                       segment_names=value.segment_names)
        if isinstance(value, Steps):
            pos = value.positions()
            timed = value.tick > 0
            t = np.arange(len(pos)) * (value.tick if timed else 1.0)
            segment = np.concatenate([value.segment[:1], value.segment])  # row 0 is the origin
            return cls(name, t, pos, value.axes, value.signals, timed, segment, value.segment_names)
        if is_log(value):
            ok = np.all(np.isfinite(value.position), axis=1)  # GRBL logs hold NaN when no report came
            t, first = np.unique(value.t[ok], return_index=True)  # status reports may repeat a time
            return cls(name, t, value.position[ok][first], value.axes)
        raise TypeError(f"not a motion: {type(value).__name__}")


@dataclass
class Shown:
    """The values one view shows (what ``collect`` finds in a run result)."""

    paths: list[Path] = field(default_factory=list)
    trajectories: list[Trajectory | Steps] = field(default_factory=list)
    machine: Machine | None = None
    logs: list[Any] = field(default_factory=list)  # device logs
    names: dict[int, str] = field(default_factory=dict)  # id(value) -> "node.port"


def is_log(value: Any) -> bool:
    """A device log (the ``Log`` port type): a time column, positions per axis and I/O changes. Told by
    its shape, because the editor does not import the device package that defines it."""
    return all(hasattr(value, a) for a in ("t", "position", "axes", "changes", "outcome"))


SHOWN_TYPES = ("Path", "Trajectory", "Steps", "Machine", "Log")  # the port types a view shows


def _kind(value: Any) -> str | None:
    if isinstance(value, Path):
        return "path"
    if isinstance(value, (Trajectory, Steps)):
        return "motion"
    if isinstance(value, Machine):
        return "machine"
    if is_log(value):
        return "log"
    return None


def _superseded(result: Any, graph: Any) -> set[str]:
    """'node.port' outputs wired into a node that itself outputs the same kind of value (a Path into a
    Translate): the downstream value replaces them. A Path into an interpolator is not superseded."""
    if graph is None:
        return set()
    out = set()
    for wire in graph.wires:
        src_node, _, src_port = wire.from_.partition(".")
        dst_node = wire.to.partition(".")[0]
        src, dst = result.nodes.get(src_node), result.nodes.get(dst_node)
        if src is None or dst is None or src_port not in src.outputs:
            continue
        if _kind(src.outputs[src_port]) in {_kind(v) for v in dst.outputs.values()}:
            out.add(wire.from_)
    return out


def collect(result: Any, graph: Any = None, limit: int = 4) -> Shown:
    """Paths, trajectories/step streams, the machine and device logs among a run's node outputs.

    Most downstream first. With the graph: every value not replaced by a downstream value of the
    same kind (the ends of chains), up to ``limit`` of each kind; without it: the last of each kind
    in run order. Equal values (same digest) are shown once; the machine is the last one found.
    """
    dropped = _superseded(result, graph)
    found: dict[str, list[tuple[str, Any]]] = {"path": [], "motion": [], "machine": [], "log": []}
    seen: set[str] = set()
    downstream_first = {node_id: -i for i, node_id in enumerate(result.order)}
    for node_id, port, value in sorted(result.values_of(*SHOWN_TYPES), key=lambda v: downstream_first[v[0]]):
        kind, ref = _kind(value), f"{node_id}.{port}"
        if kind is None or ref in dropped or value.digest() in seen:
            continue
        seen.add(value.digest())
        found[kind].append((ref, value))
    keep = {k: v[: limit if graph is not None else 1] for k, v in found.items()}
    shown = Shown(paths=[v for _, v in keep["path"]][::-1], trajectories=[v for _, v in keep["motion"]][::-1],
                  machine=keep["machine"][0][1] if keep["machine"] else None, logs=[v for _, v in keep["log"]][::-1])
    shown.names = {id(v): ref for group in keep.values() for ref, v in group}
    return shown


def speed_colors(speed: np.ndarray, top: float) -> np.ndarray:
    """RGB (uint8) for each speed on the blue (0) to red (``top``) scale."""
    frac = np.clip(np.asarray(speed, dtype=float) / (top if top > 0 else 1.0), 0.0, 1.0)
    stops = np.array([s for s, _ in SPEED_STOPS])
    rgb = np.array([c for _, c in SPEED_STOPS], dtype=float)
    return np.stack([np.interp(frac, stops, rgb[:, i]) for i in range(3)], axis=-1).round().astype(np.uint8)


def linear_rgb(rgb: np.ndarray) -> np.ndarray:
    """sRGB colours as the linear values viser's line material takes (the browser encodes them to sRGB
    again: measured in headless Chromium, red (220, 30, 30) sent as is shows as (236, 113, 107), washed out;
    converted, as (229, 7, 27))."""
    c = np.asarray(rgb, dtype=float) / 255.0
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    return (lin * 255.0).round().astype(np.uint8)


def pairs(points: np.ndarray) -> np.ndarray:
    """Consecutive points as line segments, shape (N-1, 2, 3)."""
    return np.stack([points[:-1], points[1:]], axis=1)


def path_lines(path: Path, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """The programmed path as segments (M, 2, 3) and colours (M, 2, 3): feed moves grey, rapids orange."""
    pts, seg = path.sample(tol)
    if len(pts) < 2:
        return np.zeros((0, 2, 3)), np.zeros((0, 2, 3), dtype=np.uint8)
    cols = path.columns
    rapid = (cols.rapid | ~cols.tool_down)[seg[1:]]
    colors = np.where(rapid[:, None], np.array(RAPID_RGB), np.array(FEED_RGB)).astype(np.uint8)
    return pairs(pts), np.repeat(colors[:, None, :], 2, axis=1)


def travel_edges(machine: Machine) -> tuple[np.ndarray, np.ndarray]:
    """The 12 edges (12, 2, 3) of the machine's X/Y/Z travel box, and its (low, high) corners.

    An axis the machine lacks spans 0..0.
    """
    lo = np.zeros(3)
    hi = np.zeros(3)
    for k, name in enumerate("XYZ"):
        if name in machine.names:
            ax = machine.axes[machine.names.index(name)]
            lo[k], hi[k] = ax.min, ax.max
    corners = np.array([[(lo, hi)[i][0], (lo, hi)[j][1], (lo, hi)[k][2]] for i in (0, 1) for j in (0, 1)
                        for k in (0, 1)])
    edges = [(a, b) for a in range(8) for b in range(a + 1, 8) if bin(a ^ b).count("1") == 1]
    return corners[np.array(edges)], np.stack([lo, hi])


def envelope(x: np.ndarray, ys: list[np.ndarray], max_points: int) -> tuple[np.ndarray, list[np.ndarray]]:
    """At most ``max_points`` samples: each bucket of samples becomes its min and its max, so peaks survive."""
    n = len(x)
    if n <= max_points:
        return x, ys
    size = -(-n // (max_points // 2))
    count = n // size
    cut = count * size
    xb = x[:cut].reshape(count, size)
    xo = np.stack([xb[:, 0], xb[:, -1]], axis=1).ravel()
    out = [np.stack([y[:cut].reshape(count, size).min(1), y[:cut].reshape(count, size).max(1)], 1).ravel()
           for y in ys]
    return xo, out


def motion_series(motion: Motion) -> dict[str, tuple[np.ndarray, list[tuple[str, np.ndarray]]]]:
    """Velocity (with |v|), acceleration and jerk per axis against time, by finite differences.

    Each difference is placed at the middle of the samples it spans, so on a trajectory these
    are exactly ``Trajectory.derivatives()`` at times (k + 1/2)T, (k + 1)T and (k + 3/2)T.
    """
    t, p = motion.t, motion.positions
    unit = "mm/s" if motion.timed else "mm/tick"
    out: dict[str, tuple[np.ndarray, list[tuple[str, np.ndarray]]]] = {}
    if len(t) < 2:
        return out
    tv = 0.5 * (t[1:] + t[:-1])
    v = np.diff(p, axis=0) / np.diff(t)[:, None]
    per_axis = [(a, v[:, i]) for i, a in enumerate(motion.axes)]
    out[f"Velocity ({unit})"] = (tv, [("|v|", np.linalg.norm(v, axis=1))] + per_axis)
    if len(t) >= 3:
        ta = 0.5 * (tv[1:] + tv[:-1])
        acc = np.diff(v, axis=0) / np.diff(tv)[:, None]
        out[f"Acceleration ({unit}²)"] = (ta, [(a, acc[:, i]) for i, a in enumerate(motion.axes)])
        if len(t) >= 4:
            tj = 0.5 * (ta[1:] + ta[:-1])
            jerk = np.diff(acc, axis=0) / np.diff(ta)[:, None]
            out[f"Jerk ({unit}³)"] = (tj, [(a, jerk[:, i]) for i, a in enumerate(motion.axes)])
    return out


def _steps(times: np.ndarray, values: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """A right-continuous step function (0 before the first event; the last event at a time wins) on ``grid``."""
    k = np.searchsorted(times, grid, side="right") - 1
    return np.where(k >= 0, values[np.maximum(k, 0)], 0.0)


def io_timelines(events: list[tuple[str, np.ndarray, np.ndarray, np.ndarray, np.ndarray]], t_end: float
                 ) -> dict[str, tuple[np.ndarray, list[tuple[str, np.ndarray]]]]:
    """Step plots of I/O over time, one plot per kind (digital outputs, PWM duty, ...).

    ``events``: ``(source, t, kind, channel, value)`` column groups (a program's Signal, a log's
    changes). Every value starts at 0 at t = 0. Digital channels are stacked: channel i of a plot is
    drawn at ``i + 0.8 * level`` so the bits do not overlap.
    """
    series: dict[str, list[tuple[str, np.ndarray, np.ndarray]]] = {}
    for source, t, kind, channel, value in events:
        for key in sorted(set(zip(kind.tolist(), channel.tolist()))):
            sel = (kind == key[0]) & (channel == key[1])
            prefix = {"dout": "DO", "din": "DI"}.get(key[0], key[0])
            label = f"{prefix}{key[1]}" + (f" ({source})" if source else "")
            series.setdefault(key[0], []).append((label, t[sel], value[sel]))
    plots = {}
    for kind in (k for k in _TIMELINE_TITLES if k in series):
        grid = np.unique(np.concatenate([[0.0, t_end]] + [t for _, t, _ in series[kind]]))
        x = np.stack([grid[:-1], grid[1:]], axis=1).ravel() if len(grid) > 1 else grid
        lines = []
        for i, (label, t, value) in enumerate(series[kind]):
            level = _steps(t, value, grid)
            y = np.repeat(level[:-1], 2) if len(grid) > 1 else level
            lines.append((label, i + 0.8 * (y != 0) if kind in ("dout", "din") else y))
        plots[_TIMELINE_TITLES[kind]] = (x, lines)
    return plots


def signal_events(signals: Signal, source: str = ""):
    """A Signal as an ``io_timelines`` event group."""
    return (source, signals.t, signals.kind, signals.channel, signals.value)


def log_events(log: Any, source: str = "device"):
    """A device log's I/O changes as an ``io_timelines`` event group (times from the log's start)."""
    c = log.changes
    t0 = float(log.t[0]) if len(log.t) else 0.0
    return (source, np.array([x.t for x in c], dtype=float) - t0, np.array([x.kind for x in c], dtype="U12"),
            np.array([x.channel for x in c], dtype=int), np.array([x.value for x in c], dtype=float))
