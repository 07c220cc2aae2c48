"""Canvas geometry in plain numbers: node boxes, port spots, wire curves and hit-testing.

Graph files store node positions in canvas pixels (x right, y down). The scene is in world
units with y up: ``world = (x, -y) * SCALE``. Clicks arrive as a ray; the canvas intersects it
with the plane z = 0 and asks ``hit`` what lies under the point (ports first, then nodes, then
wires), because viser cannot report clicks on lines or labels.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from flowmc.ui.ports import NodePorts, PortInfo

__all__ = ["SCALE", "NODE_W", "TITLE_H", "ROW_H", "PortSpot", "NodeBox", "Hit", "to_world", "to_canvas", "node_box",
           "wire_points",
           "bounds", "ray_to_plane", "hit"]

SCALE = 0.01  # world units per canvas pixel
NODE_W = 200.0  # px
TITLE_H = 26.0
ROW_H = 18.0
PAD = 6.0
PORT_PX = 11.0


@dataclass(frozen=True)
class PortSpot:
    info: PortInfo
    x: float  # world
    y: float


@dataclass
class NodeBox:
    """A node's rectangle in world units: top-left (x, y), width w, height h (y grows up)."""

    node_id: str
    x: float
    y: float
    w: float
    h: float
    inputs: list[PortSpot] = field(default_factory=list)
    outputs: list[PortSpot] = field(default_factory=list)

    def contains(self, px: float, py: float, margin: float = 0.0) -> bool:
        return self.x - margin <= px <= self.x + self.w + margin and self.y - self.h - margin <= py <= self.y + margin

    def port(self, kind: str, name: str) -> PortSpot | None:
        spots = self.inputs if kind == "in" else self.outputs
        return next((s for s in spots if s.info.name == name), None)

    @property
    def centre(self) -> tuple[float, float]:
        return self.x + self.w / 2, self.y - self.h / 2


@dataclass(frozen=True)
class Hit:
    """What a click landed on: kind "port" (with ``port``), "node" or "wire" (with ``wire``)."""

    kind: str
    node_id: str | None = None
    port: PortInfo | None = None
    wire: Any = None


def to_world(pos: tuple[float, float]) -> tuple[float, float]:
    return pos[0] * SCALE, -pos[1] * SCALE


def to_canvas(x: float, y: float) -> tuple[float, float]:
    return x / SCALE, -y / SCALE


def node_box(node_id: str, pos: tuple[float, float], ports: NodePorts) -> NodeBox:
    x, y = to_world(pos)
    rows = max(len(ports.inputs), len(ports.outputs), 1)
    w, h = NODE_W * SCALE, (TITLE_H + rows * ROW_H + PAD) * SCALE
    box = NodeBox(node_id, x, y, w, h)
    for k, info in enumerate(ports.inputs):
        box.inputs.append(PortSpot(info, x, y - (TITLE_H + (k + 0.5) * ROW_H) * SCALE))
    for k, info in enumerate(ports.outputs):
        box.outputs.append(PortSpot(info, x + w, y - (TITLE_H + (k + 0.5) * ROW_H) * SCALE))
    return box


def wire_points(a: tuple[float, float], b: tuple[float, float], n: int = 16) -> np.ndarray:
    """A wire from output spot ``a`` to input spot ``b``: a cubic Bezier leaving and entering
    horizontally, as (n + 1, 2) world points."""
    (x0, y0), (x1, y1) = a, b
    reach = max(0.4, abs(x1 - x0) * 0.5)
    ctrl = np.array([[x0, y0], [x0 + reach, y0], [x1 - reach, y1], [x1, y1]])
    t = np.linspace(0.0, 1.0, n + 1)[:, None]
    basis = np.hstack([(1 - t) ** 3, 3 * (1 - t) ** 2 * t, 3 * (1 - t) * t ** 2, t ** 3])
    return basis @ ctrl


def bounds(boxes: list[NodeBox]) -> tuple[float, float, float, float] | None:
    """(xmin, ymin, xmax, ymax) around every box, None when there are none."""
    if not boxes:
        return None
    return (min(b.x for b in boxes), min(b.y - b.h for b in boxes),
            max(b.x + b.w for b in boxes), max(b.y for b in boxes))


def ray_to_plane(origin: tuple[float, float, float], direction: tuple[float, float, float]) -> tuple[float, float] | None:
    """Where a click ray meets the canvas plane z = 0 (None when it runs parallel to it or away)."""
    oz, dz = origin[2], direction[2]
    if abs(dz) < 1e-12:
        return None
    t = -oz / dz
    if t < 0:
        return None
    return origin[0] + t * direction[0], origin[1] + t * direction[1]


def _distance_to_polyline(points: np.ndarray, p: np.ndarray) -> float:
    a, b = points[:-1], points[1:]
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-18), 0.0, 1.0)
    nearest = a + t[:, None] * ab
    return float(np.min(np.linalg.norm(nearest - p, axis=1)))


def hit(boxes: list[NodeBox], wires: dict[Any, np.ndarray], x: float, y: float, tol: float = 0.08) -> Hit | None:
    """The topmost thing at world point (x, y): a port (within ``tol``), a node, or a wire (within ``tol``).
    Later boxes are drawn on top, so they are tried first."""
    port_reach = max(tol, PORT_PX * SCALE)
    best: tuple[float, Hit] | None = None
    for box in reversed(boxes):
        if not box.contains(x, y, margin=port_reach):
            continue
        for spot in box.inputs + box.outputs:
            d = float(np.hypot(spot.x - x, spot.y - y))
            if d <= port_reach and (best is None or d < best[0]):
                best = (d, Hit("port", box.node_id, spot.info))
    if best is not None:
        return best[1]
    for box in reversed(boxes):
        if box.contains(x, y):
            return Hit("node", box.node_id)
    p = np.array([x, y])
    near = [(_distance_to_polyline(pts, p), key) for key, pts in wires.items() if len(pts) > 1]
    near = [(d, key) for d, key in near if d <= tol]
    if near:
        return Hit("wire", wire=min(near, key=lambda item: item[0])[1])
    return None
