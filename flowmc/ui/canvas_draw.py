"""What the canvas shows, as arrays and strings: colours (light and dark), batched quads, wire
segments and the texts of titles, port labels, table previews, badges and status lines.

Kept apart from the viser calls so it stays plain data: one place decides colours and sizes.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from flowmc.ui.layout import COMMENT_BAR, SCALE, TITLE_H, NodeBox, NoteBox
from flowmc.ui.ports import PortInfo, port_color

__all__ = ["AMBIENT", "Theme", "LIGHT", "DARK", "THEMES", "mesh_rgb", "QUAD_VERTICES", "QUAD_FACES", "Quads",
           "FRAME_EDGE", "node_quads", "port_quads", "note_quads", "wire_segments", "port_label", "status_text", "shorten",
           "issue_node", "node_problems", "rows_preview", "STATUS_COLORS", "FRAME_SELECTED"]


@dataclass(frozen=True)
class Theme:
    name: str
    grid: tuple[int, int, int]
    status: dict[str | None, tuple[int, int, int]]
    frame: tuple[int, int, int]
    selected: tuple[int, int, int]
    problem: tuple[int, int, int]
    title_bar: tuple[int, int, int]
    terminal: tuple[int, int, int]
    comment: tuple[int, int, int]
    comment_bar: tuple[int, int, int]
    label_back: tuple[int, int, int]
    dim_port: tuple[int, int, int]
    label_ink: tuple[int, int, int] = (0, 0, 0)  # text labels: ink on a backing (RGBA) that lets the node show through
    label_backing: tuple[int, int, int, int] = (255, 255, 255, 217)


LIGHT = Theme(
    "light", grid=(228, 231, 236),
    status={None: (252, 252, 252), "queued": (222, 228, 238), "running": (255, 213, 100), "done": (170, 226, 178),
            "cached": (186, 226, 234), "failed": (244, 140, 140), "skipped": (210, 210, 210),
            "ready": (150, 190, 250), "stale": (250, 195, 95), "waiting": (222, 214, 242)},
    frame=(120, 124, 132), selected=(255, 140, 0), problem=(215, 40, 40), title_bar=(226, 231, 240),
    terminal=(214, 226, 246), comment=(255, 244, 196), comment_bar=(248, 226, 140), label_back=(236, 236, 236),
    dim_port=(200, 200, 200))
DARK = Theme(
    "dark", grid=(52, 56, 64),
    status={None: (58, 62, 71), "queued": (62, 70, 88), "running": (150, 118, 30), "done": (46, 104, 62),
            "cached": (40, 92, 104), "failed": (136, 44, 44), "skipped": (70, 70, 74),
            "ready": (44, 80, 140), "stale": (140, 96, 30), "waiting": (80, 70, 110)},
    frame=(100, 106, 118), selected=(255, 150, 20), problem=(240, 70, 70), title_bar=(78, 84, 98),
    terminal=(48, 70, 110), comment=(70, 64, 40), comment_bar=(112, 100, 50), label_back=(60, 60, 66),
    dim_port=(84, 86, 92), label_ink=(232, 235, 240), label_backing=(30, 33, 40, 200))
THEMES = {"light": LIGHT, "dark": DARK}
STATUS_COLORS = LIGHT.status
FRAME_SELECTED = LIGHT.selected

# A unit quad hanging down-right from its position (top-left corner), facing +z.
QUAD_VERTICES = np.array([[0, 0, 0], [1, 0, 0], [1, -1, 0], [0, -1, 0]], dtype=np.float32)
QUAD_FACES = np.array([[0, 2, 1], [0, 3, 2]], dtype=np.uint32)
Z_GRID, Z_COMMENT, Z_WIRES, Z_FRAME, Z_BODY, Z_TITLE, Z_PORTS, Z_LABELS = -0.08, -0.06, -0.04, -0.02, 0.0, 0.01, 0.02, 0.05


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


FRAME_EDGE = 0.02  # a node frame's width beyond its body (world units); 0.05 when selected


def node_quads(boxes: list[NodeBox], status: dict[str, Any], selected: set[str], problems: dict[str, list[str]],
               theme: Theme = LIGHT, edge: float = FRAME_EDGE) -> dict[str, Quads]:
    """Frames (selection/problem colour), bodies (run status colour), title bars and problem badges (a node
    with problems, or whose last run failed, gets one; the text is in the Problems list). ``edge``: the
    narrowest frame (the canvas passes one screen pixel when that is wider than ``FRAME_EDGE``)."""
    frames, frame_colors, bodies, body_colors, bars, bar_colors, badges = [], [], [], [], [], [], []
    for b in boxes:
        chosen = b.node_id in selected
        m = max(0.05 if chosen else FRAME_EDGE, edge)
        frames.append((b.x - m, b.y + m, b.w + 2 * m, b.h + 2 * m))
        flagged = has_badge(b.node_id, status, problems)
        frame_colors.append(theme.selected if chosen else theme.problem if flagged else theme.frame)
        bodies.append((b.x, b.y, b.w, b.h))
        body_colors.append(theme.status.get((status.get(b.node_id) or (None,))[0], theme.status[None]))
        bars.append((b.x, b.y, b.w, TITLE_H * SCALE))
        bar_colors.append(theme.terminal if b.terminal else theme.title_bar)
        if flagged:
            s = 0.18
            badges.append((b.x + b.w - s - 0.05, b.y - (TITLE_H * SCALE - s) / 2, s, s))
    return {
        "frame": _quads(frames, Z_FRAME, frame_colors),
        "body": _quads(bodies, Z_BODY, body_colors),
        "title": _quads(bars, Z_TITLE, bar_colors),
        "badge": _quads(badges, Z_PORTS, [theme.problem] * len(badges)),
    }


def port_quads(boxes: list[NodeBox], highlight: dict[tuple[str, str, str], bool] | None = None,
               theme: Theme = LIGHT) -> Quads:
    """A square per port, coloured by type; param ports smaller. ``highlight`` (while a wire is dragged):
    ``(node, kind, port) -> compatible`` grows compatible ports and greys the rest."""
    rects, colors = [], []
    for b in boxes:
        for spot in b.inputs + b.outputs:
            s = 0.08 if spot.info.param else 0.11
            color = spot.info.color
            if highlight is not None:
                ok = highlight.get((b.node_id, spot.info.kind, spot.info.name), False)
                s, color = (0.17, color) if ok else (s * 0.8, theme.dim_port)
            rects.append((spot.x - s / 2, spot.y + s / 2, s, s))
            colors.append(color)
    return _quads(rects, Z_PORTS, colors)


def note_quads(notes: list[NoteBox], selected: set[str], theme: Theme = LIGHT) -> dict[str, Quads]:
    """Comment frames (a body and a title strip) and label backgrounds; selected ones edged in the selection colour."""
    bodies, body_colors, bars, bar_colors = [], [], [], []
    for n in notes:
        if n.kind == "comment":
            bodies.append((n.x, n.y, n.w, n.h))
            body_colors.append(theme.comment)
            bars.append((n.x, n.y, n.w, COMMENT_BAR * SCALE))
            bar_colors.append(theme.selected if n.note_id in selected else theme.comment_bar)
        else:
            bars.append((n.x, n.y, n.w, n.h))
            bar_colors.append(theme.selected if n.note_id in selected else theme.label_back)
    return {"comment": _quads(bodies, Z_COMMENT, body_colors), "notebar": _quads(bars, Z_COMMENT + 0.005, bar_colors)}


def wire_segments(curves: dict[Any, np.ndarray], types: dict[Any, str], highlight: set, broken: set,
                  theme: Theme = LIGHT) -> tuple[np.ndarray, np.ndarray]:
    """Wires as (N, 2, 3) segments and (N, 2, 3) colours: by source type, selected or broken (``highlight``
    and ``broken`` hold wire keys)."""
    if not curves:
        return np.zeros((0, 2, 3), np.float32), np.zeros((0, 2, 3), np.uint8)
    segs, cols = [], []
    for key, pts in curves.items():
        p = np.column_stack([pts, np.full(len(pts), Z_WIRES)])
        pair = np.stack([p[:-1], p[1:]], axis=1)
        color = theme.selected if key in highlight else theme.problem if key in broken else port_color(types.get(key, ""))
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
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, (list, tuple)) and len(value) <= 4 and all(isinstance(v, (int, float)) for v in value):
        return ", ".join(f"{v:g}" for v in value)
    return shorten(str(value), 16)


def port_label(info: PortInfo, params: dict[str, Any], wired: bool) -> str:
    """An input's name, with its stored value when it is an unwired scalar param."""
    if info.kind == "in" and info.param and not wired and info.name in params:
        return f"{info.name} = {_value_text(params[info.name])}"
    return info.name


def rows_preview(name: str, rows: Any, tag: str | None, limit: int = 3) -> list[str]:
    """The first rows of a table param as short lines for the node (``1 line · end 40, 0, 0``), and how many more."""
    if not isinstance(rows, list) or not rows:
        return []
    lines = []
    for k, row in enumerate(rows[:limit]):
        if not isinstance(row, dict):
            lines.append(f"{k + 1} {_value_text(row)}")
            continue
        head = f"{k + 1} {row.get(tag, '')}".rstrip() if tag else f"{k + 1}"
        fields = [f"{key} {_value_text(v)}" for key, v in row.items() if key != tag][:3]
        lines.append(" · ".join([head, *fields]))
    if len(rows) > limit:
        lines.append(f"… {len(rows) - limit} more {name}")
    return lines


def has_badge(node_id: str, status: dict[str, Any], problems: dict[str, list[str]]) -> bool:
    """A node shows the problem badge when it has problems or its last run failed."""
    return bool(problems.get(node_id)) or (status.get(node_id) or (None,))[0] == "failed"


def status_text(entry: tuple[str, float | None, str | None] | None, problems: list[str]) -> str:
    """The short line under a node: how many problems it has, else its last run status and time.
    The problems' text is in the Problems list and in the side panel when the node is selected."""
    if problems:
        return f"{len(problems)} problem{'s' if len(problems) > 1 else ''}: see Problems"
    if entry is None:
        return ""
    kind, duration, message = entry
    if kind == "failed":
        return "failed: see Problems"
    loop = f" · {message}" if message and message.startswith("iteration") else ""  # a loop's last iteration
    if kind == "done" and duration is not None:
        return f"done · {duration * 1000:.1f} ms{loop}"
    return kind + loop
