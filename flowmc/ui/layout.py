"""Canvas geometry in plain numbers: node boxes sized to their text, port spots, wire curves,
comments and labels, and hit-testing.

Graph files store node positions in canvas pixels (x right, y down). The scene is in world
units with y up: ``world = (x, -y) * SCALE``. Clicks arrive as a ray; the canvas intersects it
with the plane z = 0 and asks ``hit`` what lies under the point (ports first, then nodes, then
labels, comment title bars and wires), because viser cannot report clicks on lines or labels.

A node is as wide as its title and its port rows need (``MIN_W`` to ``MAX_W``); a title that does
not fit even then is cut with an ellipsis and ``full_title`` keeps it whole for the tooltip.
Text widths are estimated from the character count (``text_width``), generously, so text never
runs past the box. Interface terminals of a sub-graph are boxes too, with ids ``@in:<name>`` and
``@out:<name>`` (no node id can start with ``@``).
"""

from __future__ import annotations

import unicodedata
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from flowmc.ui.ports import PortInfo

__all__ = ["SCALE", "TITLE_H", "ROW_H", "PREVIEW_H", "PAD", "TITLE_FONT", "PORT_FONT", "PREVIEW_FONT", "MIN_W", "MAX_W",
           "COMMENT_BAR", "PortSpot", "NodeBox", "NoteBox", "Hit", "to_world", "to_canvas", "text_width", "fit_text",
           "node_box", "wire_points", "bounds", "ray_to_plane", "hit", "terminal_id", "terminal_of"]

SCALE = 0.01  # world units per canvas pixel
TITLE_H = 28.0  # px
ROW_H = 18.0
PREVIEW_H = 14.0
PAD = 8.0
TITLE_FONT = 13.0
PORT_FONT = 10.5
PREVIEW_FONT = 10.0
MIN_W = 130.0
MAX_W = 250.0
BADGE_W = 22.0  # room kept right of the title for the problem badge
COMMENT_BAR = 26.0  # the draggable title strip of a comment box
CHAR_W = 0.56  # a character's width as a share of the font size (measured 0.51 in Chromium's label font; kept generous)


def text_width(text: str, font: float) -> float:
    """An upper estimate of ``text``'s width in pixels at font size ``font`` (wide characters count double)."""
    units = sum(2.0 if unicodedata.east_asian_width(c) in "WF" else 1.0 for c in text)
    return units * font * CHAR_W


def fit_text(text: str, font: float, width: float) -> str:
    """``text``, or its start and an ellipsis, so that it fits ``width`` pixels."""
    if text_width(text, font) <= width:
        return text
    keep = max(1, int(width / (font * CHAR_W)) - 1)
    while keep > 1 and text_width(text[:keep] + "…", font) > width:
        keep -= 1
    return text[:keep].rstrip() + "…"


def terminal_id(kind: str, name: str) -> str:
    """The box id of an interface terminal: ``@in:feed``, ``@out:path``."""
    return f"@{kind}:{name}"


def terminal_of(box_id: str) -> tuple[str, str] | None:
    """("in" | "out", name) for a terminal box id, None for a node id."""
    if not box_id.startswith("@"):
        return None
    kind, _, name = box_id[1:].partition(":")
    return kind, name


@dataclass(frozen=True)
class PortSpot:
    info: PortInfo
    x: float  # world
    y: float
    label: str = ""  # the text drawn beside it (name, or "name = value")


@dataclass
class NodeBox:
    """A node's (or interface terminal's) rectangle in world units: top-left (x, y), width w, height h (y up)."""

    node_id: str
    x: float
    y: float
    w: float
    h: float
    inputs: list[PortSpot] = field(default_factory=list)
    outputs: list[PortSpot] = field(default_factory=list)
    title: str = ""
    full_title: str = ""
    preview: list[str] = field(default_factory=list)

    @property
    def terminal(self) -> tuple[str, str] | None:
        return terminal_of(self.node_id)

    @property
    def elided(self) -> bool:
        return self.title != self.full_title

    def contains(self, px: float, py: float, margin: float = 0.0) -> bool:
        return self.x - margin <= px <= self.x + self.w + margin and self.y - self.h - margin <= py <= self.y + margin

    def port(self, kind: str, name: str) -> PortSpot | None:
        spots = self.inputs if kind == "in" else self.outputs
        return next((s for s in spots if s.info.name == name), None)

    @property
    def centre(self) -> tuple[float, float]:
        return self.x + self.w / 2, self.y - self.h / 2

    @property
    def rect(self) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) in world units."""
        return self.x, self.y - self.h, self.x + self.w, self.y


@dataclass(frozen=True)
class NoteBox:
    """A comment (``comment``: a frame with a title strip) or a free label, in world units."""

    note_id: str
    kind: str  # "comment" | "label"
    x: float
    y: float
    w: float
    h: float
    text: str

    def grab(self, px: float, py: float) -> bool:
        """Whether a click here picks the note: a label anywhere on it, a comment on its title strip."""
        top = self.h if self.kind == "label" else COMMENT_BAR * SCALE
        return self.x <= px <= self.x + self.w and self.y - top <= py <= self.y


@dataclass(frozen=True)
class Hit:
    """What a click landed on: kind "port" (with ``port``), "node", "note" (``node_id`` is the note's id)
    or "wire" (with ``wire``)."""

    kind: str
    node_id: str = ""
    port: PortInfo | None = None
    wire: Any = None


def to_world(pos: tuple[float, float]) -> tuple[float, float]:
    return pos[0] * SCALE, -pos[1] * SCALE


def to_canvas(x: float, y: float) -> tuple[float, float]:
    return x / SCALE, -y / SCALE


def node_box(node_id: str, pos: tuple[float, float], inputs: list[tuple[PortInfo, str]],
             outputs: list[tuple[PortInfo, str]], title: str, preview: Sequence[str] = ()) -> NodeBox:
    """A box at ``pos`` (canvas px) wide enough for ``title`` and each row's input and output label
    (``(port, label text)`` pairs), with ``preview`` lines under the port rows (cut to the box)."""
    rows = max(len(inputs), len(outputs), 1)
    need = text_width(title, TITLE_FONT) + 2 * PAD + BADGE_W
    for k in range(rows):
        left = text_width(inputs[k][1], PORT_FONT) + 14 if k < len(inputs) else 0.0
        right = text_width(outputs[k][1], PORT_FONT) + 14 if k < len(outputs) else 0.0
        need = max(need, left + right + 3 * PAD)
    w_px = min(max(MIN_W, np.ceil(need / 10.0) * 10.0), MAX_W)
    shown = fit_text(title, TITLE_FONT, w_px - 2 * PAD - BADGE_W)
    x, y = to_world(pos)
    h_px = TITLE_H + rows * ROW_H + (len(preview) * PREVIEW_H + 4 if preview else 0) + PAD
    lines = [fit_text(line, PREVIEW_FONT, w_px - 2 * PAD) for line in preview]
    box = NodeBox(node_id, x, y, w_px * SCALE, h_px * SCALE, title=shown, full_title=title, preview=lines)
    for k, (info, label) in enumerate(inputs):
        box.inputs.append(PortSpot(info, x, y - (TITLE_H + (k + 0.5) * ROW_H) * SCALE, label))
    for k, (info, label) in enumerate(outputs):
        box.outputs.append(PortSpot(info, x + box.w, y - (TITLE_H + (k + 0.5) * ROW_H) * SCALE, label))
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


def bounds(boxes: list[Any]) -> tuple[float, float, float, float] | None:
    """(xmin, ymin, xmax, ymax) around every box (nodes or notes), None when there are none."""
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


def hit(boxes: list[NodeBox], wires: dict[Any, np.ndarray], x: float, y: float, tol: float = 0.08,
        notes: Sequence[NoteBox] = ()) -> Hit | None:
    """The topmost thing at world point (x, y): a port (within ``tol``), a node, a label or a comment's
    title strip, or a wire (within ``tol``). Later boxes are drawn on top, so they are tried first."""
    port_reach = max(tol, 11.0 * SCALE)
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
    for note in sorted(notes, key=lambda n: n.kind != "label"):  # labels sit above comments
        if note.grab(x, y):
            return Hit("note", note.note_id)
    p = np.array([x, y])
    near = [(_distance_to_polyline(pts, p), key) for key, pts in wires.items() if len(pts) > 1]
    near = [(d, key) for d, key in near if d <= tol]
    if near:
        return Hit("wire", wire=min(near, key=lambda item: item[0])[1])
    return None
