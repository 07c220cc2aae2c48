"""3D View nodes in a run: what each one was wired to, inside sub-graphs too, and a PNG of it.

``views(result, plan, runtime)`` finds every ``view.view3d`` node the run reached: in the graph itself
(key ``"view1"``) and in the sub-graphs it ran (key ``"part/view1"``: the sub-graph node's id, then
the view's), whose results their child runtimes keep (``Runtime.last_result``). A view input fed by
a sub-graph's interface is followed out to the wire that fed the sub-graph node. The editor's 3D
view shows one ``View``; ``flowmc run --snapshot DIR`` draws each as ``DIR/<key>.png``
(``snapshot``), an isometric picture with the travel box, the path (rapids orange) and the
trajectory coloured by speed, for reports and CI where no browser runs.
"""

from __future__ import annotations

import io
from dataclasses import dataclass, field
from pathlib import Path as FilePath
from typing import Any

import numpy as np

from flowmc.fileio import write_atomic
from flowmc.runtime.schedule import Plan

__all__ = ["VIEW_TYPE", "View", "views", "snapshot", "write_snapshots"]

VIEW_TYPE = "view.view3d"
_INPUTS = ("path", "trajectory", "steps", "log", "machine")


@dataclass
class View:
    """One 3D View node's values (None where nothing is wired or nothing arrived) and its params."""

    key: str
    title: str
    params: dict[str, Any] = field(default_factory=dict)
    values: dict[str, Any] = field(default_factory=dict)

    @property
    def empty(self) -> bool:
        return not any(self.values.get(k) is not None for k in ("path", "trajectory", "steps", "log"))


def _value(result: Any, plan: Any, node_id: str, port: str, outer: tuple | None) -> Any:
    """The value that arrived on input ``port`` of ``node_id``: from the wire feeding it, or through the
    interface from the graph around (``outer`` = (result, plan, sub-graph node id, its outer))."""
    bound = plan.nodes[node_id]
    src = bound.sources.get(port)
    if src is not None:
        node = result.nodes.get(src[0])
        return node.outputs.get(src[1]) if node is not None else None
    name = bound.fed.get(port)
    if name is not None and outer is not None:
        return _value(outer[0], outer[1], outer[2], name, outer[3])
    return None


def views(result: Any, plan: Any, runtime: Any = None, *, _prefix: str = "", _outer: tuple | None = None) -> list[View]:
    """Every 3D View node the run reached, in run order (sub-graphs' views where their sub-graph node ran;
    a structure's bodies run many times or not at all, and their views are not shown)."""
    found = []
    for node_id in result.order:
        bound = plan.nodes.get(node_id)
        if bound is None:
            continue
        if bound.cls.type_id == VIEW_TYPE:
            params = bound.params.model_dump() if bound.params is not None else dict(bound.raw_params)
            values = {port: _value(result, plan, node_id, port, _outer) for port in _INPUTS}
            found.append(View(_prefix + node_id, params.get("title") or node_id, params, values))
        elif isinstance(bound.binding, Plan) and runtime is not None:  # a sub-graph (not a structure's bodies)
            child = runtime.child(node_id)
            inner = getattr(child, "last_result", None)
            if inner is not None:
                found += views(inner, bound.binding, child, _prefix=f"{_prefix}{node_id}/",
                               _outer=(result, plan, node_id, _outer))
    return found


# ---------------------------------------------------------------------------------------- snapshot
_SIZE = (960, 720)
_MARGIN = 50
_MAX_SEGMENTS = 20000
_SPEED = np.array([(40, 60, 220), (0, 170, 230), (40, 190, 60), (240, 200, 0), (220, 30, 30)], dtype=float)


def _iso(points: np.ndarray) -> np.ndarray:
    """Isometric projection of (N, 3) points to (N, 2), y up."""
    x, y, z = points[:, 0], points[:, 1], points[:, 2]
    return np.column_stack([(x - y) * np.cos(np.pi / 6), (x + y) * np.sin(np.pi / 6) + z])


def _xyz(positions: np.ndarray, axes: tuple[str, ...]) -> np.ndarray:
    out = np.zeros((len(positions), 3))
    for k, name in enumerate("XYZ"):
        if name in axes:
            out[:, k] = positions[:, axes.index(name)]
    return out


def _strided(points: np.ndarray) -> np.ndarray:
    step = max(1, -(-len(points) // _MAX_SEGMENTS))
    return points[np.unique(np.r_[np.arange(0, len(points), step), len(points) - 1])] if len(points) else points


def _speed_rgb(speed: np.ndarray) -> np.ndarray:
    frac = np.clip(speed / max(float(speed.max(initial=0.0)), 1e-12), 0, 1) * (len(_SPEED) - 1)
    k = np.minimum(frac.astype(int), len(_SPEED) - 2)
    t = (frac - k)[:, None]
    return (_SPEED[k] * (1 - t) + _SPEED[k + 1] * t).round().astype(int)


def snapshot(view: View, tol: float | None = None) -> Any:
    """A PIL image of ``view``: isometric, travel box grey, path dark grey with rapids orange, the
    trajectory (or step stream) coloured blue (slow) to red (fast), a device log purple."""
    from PIL import Image, ImageDraw, ImageFont

    tol = float(tol or view.params.get("tolerance") or 0.01)
    lines: list[tuple[np.ndarray, Any, int]] = []  # (points (N, 3), colour or per-segment colours, width)
    machine = view.values.get("machine")
    if machine is not None and view.params.get("travel_box", True):
        axes = [_axis(machine, c) for c in "XYZ"]
        lo = np.array([a.min if a is not None else 0.0 for a in axes])
        hi = np.array([a.max if a is not None else 0.0 for a in axes])
        corners = np.array([[(lo, hi)[i][0], (lo, hi)[j][1], (lo, hi)[k][2]] for i in (0, 1) for j in (0, 1) for k in (0, 1)])
        for a in range(8):
            for b in range(a + 1, 8):
                if bin(a ^ b).count("1") == 1:
                    lines.append((corners[[a, b]], (185, 185, 185), 1))
    path = view.values.get("path")
    if path is not None and len(path):
        pts, seg = path.sample(tol)
        rapid = np.array([s.rapid or not s.tool_down for s in path.segments])[seg[1:]] if len(pts) > 1 else np.zeros(0, bool)
        colours = np.where(rapid[:, None], [235, 140, 40], [90, 90, 90])
        lines.append((pts, colours, 2))
    for key in ("trajectory", "steps"):
        motion = view.values.get(key)
        if motion is None:
            continue
        positions = motion.positions if key == "trajectory" else motion.positions()
        pts = _strided(_xyz(np.asarray(positions, float), tuple(motion.axes)))
        if len(pts) > 1:
            speed = np.linalg.norm(np.diff(pts, axis=0), axis=1)
            lines.append((pts, _speed_rgb(speed), 3))
    log = view.values.get("log")
    if log is not None and len(getattr(log, "t", ())):
        ok = np.all(np.isfinite(log.position), axis=1)
        lines.append((_strided(_xyz(log.position[ok], tuple(log.axes))), (120, 60, 160), 2))
    image = Image.new("RGB", _SIZE, (255, 255, 255))
    draw = ImageDraw.Draw(image)
    font = ImageFont.load_default()
    draw.text((16, 12), f"{view.title}  ({view.key})", fill=(20, 20, 20), font=font)
    flat = [_iso(p) for p, _, _ in lines if len(p)]
    if not flat:
        draw.text((16, 40), "nothing wired, or nothing arrived in this run", fill=(120, 120, 120), font=font)
        return image
    every = np.vstack(flat)
    low, high = every.min(axis=0), every.max(axis=0)
    scale = min((_SIZE[0] - 2 * _MARGIN) / max(high[0] - low[0], 1e-9), (_SIZE[1] - 2 * _MARGIN) / max(high[1] - low[1], 1e-9))
    centre = (low + high) / 2
    for points, colours, width in lines:
        if len(points) < 2:
            continue
        xy = _iso(points)
        px = np.column_stack([_SIZE[0] / 2 + (xy[:, 0] - centre[0]) * scale, _SIZE[1] / 2 - (xy[:, 1] - centre[1]) * scale])
        if isinstance(colours, tuple):
            draw.line([tuple(p) for p in px], fill=colours, width=width)
            continue
        for k in range(len(px) - 1):
            draw.line([tuple(px[k]), tuple(px[k + 1])], fill=tuple(int(c) for c in colours[k]), width=width)
    draw.text((16, _SIZE[1] - 24), "isometric; trajectory blue (slow) to red (fast), rapids orange",
              fill=(110, 110, 110), font=font)
    return image


def _axis(machine: Any, name: str) -> Any:
    return machine.axes[machine.names.index(name)] if name in machine.names else None


def write_snapshots(result: Any, plan: Any, runtime: Any, folder: str | FilePath) -> list[FilePath]:
    """``<folder>/<key>.png`` for every 3D View node of the run (``/`` in keys becomes ``__``); the files."""
    folder = FilePath(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for view in views(result, plan, runtime):
        target = folder / (view.key.replace("/", "__") + ".png")
        png = io.BytesIO()
        snapshot(view).save(png, format="PNG")
        write_atomic(target, png.getvalue(), what="snapshot")  # a snapshot is whole or not there
        written.append(target)
    return written
