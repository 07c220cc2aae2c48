"""What the canvas shows, as arrays and strings: batched quads, wire segments, label texts.

Kept apart from the viser calls so it stays plain data: one place decides colours and sizes.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from flowmc.ui.layout import SCALE, TITLE_H, NodeBox, PortSpot
from flowmc.ui.ports import port_color

__all__ = ["AMBIENT", "mesh_rgb", "STATUS_COLORS", "QUAD_VERTICES", "QUAD_FACES", "Quads", "node_quads", "port_quads",
           "wire_segments",
           "port_label", "status_text", "shorten", "issue_node", "node_problems"]

STATUS_COLORS: dict[str | None, tuple[int, int, int]] = {
    None: (250, 250, 250),
    "queued": (222, 228, 238),
    "running": (255, 213, 100),
    "done": (150, 220, 160),
    "cached": (175, 222, 230),
    "failed": (240, 120, 120),
    "skipped": (205, 205, 205),
}
FRAME = (95, 95, 100)
FRAME_SELECTED = (255, 140, 0)
FRAME_PROBLEM = (215, 40, 40)
TITLE_BAR = (228, 232, 240)
WIRE_SELECTED = (255, 140, 0)
WIRE_PROBLEM = (215, 40, 40)

# A unit quad hanging down-right from its position (top-left corner), facing +z.
QUAD_VERTICES = np.array([[0, 0, 0], [1, 0, 0], [1, -1, 0], [0, -1, 0]], dtype=np.float32)
QUAD_FACES = np.array([[0, 2, 1], [0, 3, 2]], dtype=np.uint32)
Z_WIRES, Z_FRAME, Z_BODY, Z_TITLE, Z_PORTS, Z_LABELS = -0.04, -0.02, 0.0, 0.01, 0.02, 0.05


@dataclass
class Quads:
    """One batched mesh's instances: top-left positions, (w, h, 1) scales, colours."""

    positions: np.ndarray
    scales: np.ndarray
    colors: np.ndarray

    def __len__(self) -> int:
        return len(self.positions)


def mesh_rgb(colors: Any) -> np.ndarray:
    """sRGB colours as the linear values viser's mesh material takes (the browser encodes them to
    sRGB again; under ``AMBIENT`` light they then show close to what was asked). Lines take sRGB as is."""
    c = np.asarray(colors, dtype=float) / 255.0
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    return (lin * 255.0).round().astype(np.uint8)


AMBIENT = 3.6  # ambient light intensity that shows mesh colours near their sRGB values (measured in Chromium)


def _quads(rects: list[tuple[float, float, float, float]], z: float, colors: list[tuple[int, int, int]]) -> Quads:
    n = len(rects)
    arr = np.asarray(rects, dtype=np.float32).reshape(n, 4)
    positions = np.column_stack([arr[:, 0], arr[:, 1], np.full(n, z, np.float32)])
    scales = np.column_stack([arr[:, 2], arr[:, 3], np.ones(n, np.float32)])
    return Quads(positions, scales, mesh_rgb(np.asarray(colors, dtype=np.uint8).reshape(n, 3)))


def node_quads(boxes: list[NodeBox], status: dict[str, Any], selected: set[str],
               problems: dict[str, list[str]]) -> dict[str, Quads]:
    """Frames (selection/problem colour), bodies (run status colour) and title bars, one per box."""
    frames, frame_colors, bodies, body_colors, bars = [], [], [], [], []
    for b in boxes:
        chosen = b.node_id in selected
        m = 0.06 if chosen else 0.025
        frames.append((b.x - m, b.y + m, b.w + 2 * m, b.h + 2 * m))
        frame_colors.append(FRAME_SELECTED if chosen else FRAME_PROBLEM if problems.get(b.node_id) else FRAME)
        bodies.append((b.x, b.y, b.w, b.h))
        body_colors.append(STATUS_COLORS.get((status.get(b.node_id) or (None,))[0], STATUS_COLORS[None]))
        bars.append((b.x, b.y, b.w, TITLE_H * SCALE))
    return {
        "frame": _quads(frames, Z_FRAME, frame_colors),
        "body": _quads(bodies, Z_BODY, body_colors),
        "title": _quads(bars, Z_TITLE, [TITLE_BAR] * len(bars)),
    }


def port_quads(boxes: list[NodeBox]) -> Quads:
    """A square per port, coloured by type; param ports smaller."""
    rects, colors = [], []
    for b in boxes:
        for spot in b.inputs + b.outputs:
            s = 0.08 if spot.info.param else 0.11
            rects.append((spot.x - s / 2, spot.y + s / 2, s, s))
            colors.append(spot.info.color)
    return _quads(rects, Z_PORTS, colors)


def wire_segments(curves: dict[Any, np.ndarray], types: dict[Any, str], selected: set,
                  broken: set) -> tuple[np.ndarray, np.ndarray]:
    """All wires as (N, 2, 3) segments and (N, 2, 3) colours: by source type, selected or broken."""
    if not curves:
        return np.zeros((0, 2, 3), np.float32), np.zeros((0, 2, 3), np.uint8)
    segs, cols = [], []
    for key, pts in curves.items():
        p = np.column_stack([pts, np.full(len(pts), Z_WIRES)])
        pair = np.stack([p[:-1], p[1:]], axis=1)
        color = WIRE_SELECTED if key in selected else WIRE_PROBLEM if key in broken else port_color(types.get(key, ""))
        segs.append(pair)
        cols.append(np.broadcast_to(np.asarray(color, np.uint8), pair.shape))
    return np.concatenate(segs).astype(np.float32), np.concatenate(cols).astype(np.uint8)


def issue_node(issue: Any, wires: list[Any]) -> str | None:
    """The node a validation issue is about: its location's node, or the node a bad wire feeds."""
    loc = issue.location
    if len(loc) >= 2 and loc[0] == "nodes":
        return str(loc[1])
    if len(loc) >= 2 and loc[0] == "wires" and isinstance(loc[1], int) and loc[1] < len(wires):
        return wires[loc[1]].to.partition(".")[0]
    return None


def node_problems(issues: list[Any], wires: list[Any]) -> tuple[dict[str, list[str]], set[tuple[str, str]]]:
    """Issue messages by node, and the wires (from, to) that issues point at."""
    problems: dict[str, list[str]] = {}
    broken: set[tuple[str, str]] = set()
    for issue in issues:
        node_id = issue_node(issue, wires)
        if node_id is not None:
            problems.setdefault(node_id, []).append(issue.message)
        loc = issue.location
        if len(loc) >= 2 and loc[0] == "wires" and isinstance(loc[1], int) and loc[1] < len(wires):
            broken.add((wires[loc[1]].from_, wires[loc[1]].to))
    return problems, broken


def shorten(text: str, limit: int) -> str:
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[: limit - 1] + "…"


def _value_text(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:g}"
    return shorten(repr(value) if isinstance(value, str) else str(value), 14)


def port_label(spot: PortSpot, params: dict[str, Any], wired: bool) -> str:
    """An input's name, with its stored value when it is an unwired scalar param."""
    info = spot.info
    if info.kind == "in" and info.param and not wired and info.name in params:
        return f"{info.name} = {_value_text(params[info.name])}"
    return info.name


def _without_node(message: str) -> str:
    """A message without its leading "node 'x': " (the label sits under that node already)."""
    return re.sub(r"^node '[^']*': ", "", message)


def status_text(entry: tuple[str, float | None, str | None] | None, problems: list[str]) -> str:
    """The line under a node: its problems before a run, else its last run status and time."""
    if problems:
        first = shorten(_without_node(problems[0]), 48)
        return f"⚠ {first}" + (f" (+{len(problems) - 1} more)" if len(problems) > 1 else "")
    if entry is None:
        return ""
    kind, duration, message = entry
    if kind == "failed":
        return "✖ " + shorten(_without_node(message or "failed"), 48)
    if kind == "done" and duration is not None:
        return f"done · {duration * 1000:.1f} ms"
    return kind
