"""The node canvas in the viser scene: nodes, interface terminals, comments, labels and wires drawn
from an EditorState, and clicks and drags turned back into EditorState edits.

The camera (``camera``) looks straight down -z on a flat sheet. Bodies, frames, title bars, ports,
badges and notes are batched meshes (a 120-node graph stays a handful of draw calls); wires are
one line-segments node; texts are labels (``canvas_text``). viser cannot click lines or labels,
so every click is hit-tested here: the click ray meets the plane z = 0 and ``layout.hit`` says
what is under it. Drags arrive per batched mesh with the instance under the pointer: a node body
moves the node (and the rest of the selection), a note's strip moves the note (a comment takes
the nodes inside it along), a port draws a wire (``canvas_wiring``).
"""

from __future__ import annotations

import functools
import threading
from typing import Any, Callable

import numpy as np
import viser

from flowmc.errors import GraphError
from flowmc.graph import split_ref
from flowmc.ui import camera, canvas_frames, layout, structures, viser_internals
from flowmc.ui import canvas_draw as draw
from flowmc.ui.canvas_text import Texts
from flowmc.ui.canvas_wiring import WireDrag
from flowmc.ui.forms import form_fields
from flowmc.ui.interface_edit import terminal_wires
from flowmc.ui.ports import NodePorts, PortInfo, node_ports
from flowmc.ui.state import EditorState
from flowmc.ui.text import plain

__all__ = ["Canvas"]

_BATCHES = ("comment", "notebar", "frame", "body", "title", "badge", "ports")
WIRE_CANVAS_PX = 3.5  # wire thickness in canvas px: drawn in screen px, set from the zoom (see _wire_px)
WIRE_MIN_PX, WIRE_MAX_PX = 1.5, 8.0  # readable zoomed out, not a ribbon zoomed in
LABEL_FONT = 15.0  # free labels and comment titles, canvas px
COMMENT_FONT = 14.0
MIN_TITLE_PX = 8.0  # node titles on screen at Fit, at least, when the graph is not much bigger than the view


@functools.lru_cache(maxsize=512)
def _rows_field(params: Any) -> Any:
    """A node type's first table param (its JSON schema is built once per type, not per node and redraw)."""
    return next((spec for spec in form_fields(params.model_json_schema()) if spec.kind == "rows"), None)


class Canvas:
    """Draws ``state.graph``; ``notify(kind, text)`` hears refusals ("error") and hints ("info").

    ``status`` holds each node's last run event ``(kind, duration, message)``; ``pending`` is the
    first port clicked while wiring by clicks. All edits take ``lock`` (shared with the editor)."""

    def __init__(self, server: viser.ViserServer, state: EditorState, notify: Callable[[str, str], None],
                 lock: threading.RLock | None = None, status: dict[str, tuple] | None = None):
        self.server, self.state, self.notify = server, state, notify
        self.lock = lock or threading.RLock()
        self.status: dict[str, tuple[str, float | None, str | None]] = {} if status is None else status
        self.decorations: list[Callable[["Canvas"], dict[str, tuple]]] = []  # more labels: {key: text spec}
        self.theme = draw.LIGHT
        self.pending: layout.Hit | None = None
        self.boxes: list[layout.NodeBox] = []
        self.by_id: dict[str, layout.NodeBox] = {}
        self.notes: list[layout.NoteBox] = []
        self.curves: dict[tuple[str, str], np.ndarray] = {}
        self.types: dict[tuple[str, str], str] = {}
        self.problems: dict[str, list[str]] = {}
        self.broken: set[tuple[str, str]] = set()
        self.port_index: list[tuple[str, layout.PortSpot]] = []
        self.highlight: dict[tuple[str, str, str], bool] | None = None
        self._handles: dict[str, Any] = {}
        self._drag: dict[str, Any] | None = None
        self._revision = -1  # the state revision the geometry was made for
        self._tips: list[tuple[float, float, float, float, str]] = []
        self._port_memo: tuple[tuple, draw.Quads] | None = None
        self._wire_memo: tuple[tuple, np.ndarray, np.ndarray, dict] | None = None
        self.wire_px = WIRE_CANVAS_PX  # wires' screen thickness for the current zoom
        self.frame_edge = draw.FRAME_EDGE  # node frames' width for the current zoom (at least a screen pixel)
        scene = server.scene
        scene.set_up_direction("+y")
        scene.add_light_ambient("/light", intensity=draw.AMBIENT)
        self.grid: Any = None
        self._grid_box: tuple[float, ...] | None = None
        self.texts = Texts(scene)
        self.wiring = WireDrag(self)
        self._pending_marker = scene.add_box("/canvas/pending", color=tuple(draw.mesh_rgb(draw.FRAME_SELECTED)),
                                             dimensions=(0.21, 0.21, 0.01), visible=False, cast_shadow=False,
                                             receive_shadow=False)
        self.set_theme("light")
        scene.on_click()(self._on_scene_click)
        scene.on_click(modifier="shift")(self._on_scene_click)  # shift-click adds to the selection
        scene.on_rect_select(modifier="shift")(self._on_rect_select)  # shift-drag selects a box of nodes

    # ------------------------------------------------------------------ theme and camera
    def set_theme(self, name: str) -> None:
        """Light or dark canvas: grid and node colours (the page's background follows viser's theme)."""
        self.theme = draw.THEMES[name]
        self._grid_box = None
        for client in list(self.server.get_clients().values()):
            self._paint_labels(client)
        if self.boxes:
            self.sync()

    def _paint_labels(self, client: viser.ClientHandle) -> None:
        viser_internals.set_label_colors(client, self.theme.label_ink, self.theme.label_backing)

    def _draw_grid(self) -> None:
        """A subtle grid every 100 canvas px, drawn as thin lines around the graph (a full-screen grid shader
        made every frame cost tens of milliseconds under software WebGL); redrawn when the graph outgrows it."""
        box = layout.bounds([*self.boxes, *self.notes]) or (-2.0, -2.0, 6.0, 2.0)
        if self._grid_box is not None and self._grid_box[0] <= box[0] and self._grid_box[1] <= box[1] \
                and box[2] <= self._grid_box[2] and box[3] <= self._grid_box[3]:
            return
        pad = max(box[2] - box[0], box[3] - box[1], 10.0)
        x0, y0 = np.floor(box[0] - pad), np.floor(box[1] - pad)
        x1, y1 = np.ceil(box[2] + pad), np.ceil(box[3] + pad)
        self._grid_box = (x0, y0, x1, y1)
        xs, ys = np.arange(x0, x1 + 1), np.arange(y0, y1 + 1)
        verticals = np.stack([np.column_stack([xs, np.full_like(xs, y0)]), np.column_stack([xs, np.full_like(xs, y1)])], 1)
        horizontals = np.stack([np.column_stack([np.full_like(ys, x0), ys]), np.column_stack([np.full_like(ys, x1), ys])], 1)
        segs = np.concatenate([verticals, horizontals])
        segs = np.concatenate([segs, np.full((len(segs), 2, 1), draw.Z_GRID)], axis=2).astype(np.float32)
        colors = np.broadcast_to(np.asarray(self.theme.grid, np.uint8), segs.shape).copy()
        if self.grid is not None:
            self.grid.remove()
        self.grid = self.server.scene.add_line_segments("/canvas/grid", segs, colors, thickness=1.0,
                                                        thickness_units="screen")

    def setup_client(self, client: viser.ClientHandle) -> None:
        """Top-down camera, locked flat, framing the graph; details follow the zoom."""

        def frame_again() -> None:
            with self.lock:
                self.fit([client])

        camera.setup(client, frame_again)
        canvas_frames.install(client)
        client.camera.on_update(lambda cam: self._zoomed(cam))
        self._send_tips([client])
        if self.theme is not draw.LIGHT:  # viser's own label colours are the light theme's
            self._paint_labels(client)

    def _zoomed(self, cam: Any) -> None:
        per_px = camera.screen_px_per_world(cam)
        if per_px is not None and (self.texts.zoom(per_px * layout.SCALE) | self._wire_zoom(per_px * layout.SCALE)
                                   | self._frame_zoom(per_px)):
            self.server.flush()

    def _wire_zoom(self, screen_px_per_canvas_px: float) -> bool:
        """Wires are drawn in screen pixels (a world-unit line costs two passes of a heavy shader, the largest
        item of a frame under software WebGL); their thickness follows the zoom here. True when it changed."""
        px = float(np.clip(WIRE_CANVAS_PX * screen_px_per_canvas_px, WIRE_MIN_PX, WIRE_MAX_PX))
        if abs(px - self.wire_px) < 0.25:
            return False
        self.wire_px = px
        handle = self._handles.get("wires")
        if handle is not None:
            handle.thickness = px
        return True

    def _frame_zoom(self, screen_px_per_world: float) -> bool:
        """Node frames are kept 1 to 1.5 screen pixels wide where ``FRAME_EDGE`` would be thinner: under software
        WebGL the canvas is not multisampled (``viser_client``), and a frame under a pixel wide lost whole edges
        in a zoomed-out view. True when the frames were made again."""
        low, high = max(draw.FRAME_EDGE, 1.0 / screen_px_per_world), max(draw.FRAME_EDGE, 1.5 / screen_px_per_world)
        if low <= self.frame_edge <= high:
            return False
        self.frame_edge = max(draw.FRAME_EDGE, 1.2 / screen_px_per_world)
        if "frame" in self._handles:  # drawn already (else the next drawing uses the new width)
            with self.lock, self.server.atomic():
                self._draw_shapes()
        return True

    def fit(self, clients: list[viser.ClientHandle] | None = None) -> None:
        """Frame every node and note (the middle of the sheet when there are none) in each client's view.
        A fit of every view (``clients`` None) sets the details (port names, previews) for the first one's new
        zoom at once: fitting before drawing a graph just opened, the editor makes only the labels it will show."""
        box = layout.bounds([*self.boxes, *self.notes]) or (-2.0, -2.0, 6.0, 2.0)
        zooms = []
        if clients is None:
            zooms.append(camera.initial(self.server, box))
        for client in clients if clients is not None else list(self.server.get_clients().values()):
            zooms.append(camera.frame(client, box, legible=MIN_TITLE_PX / (layout.TITLE_FONT * layout.SCALE)))
        if clients is None:  # the first page's view, else the one a page connecting next starts with
            per_px = zooms[1] if len(zooms) > 1 else zooms[0]
            self.texts.zoom(per_px * layout.SCALE)
            self._wire_zoom(per_px * layout.SCALE)
            self._frame_zoom(per_px)

    def view_centre(self) -> tuple[float, float]:
        """Canvas pixels at the middle of the first client's view (where palette nodes appear)."""
        clients = list(self.server.get_clients().values())
        if not clients:
            box = layout.bounds(self.boxes)
            return layout.to_canvas(box[2] + 1.5, (box[1] + box[3]) / 2) if box else (0.0, 0.0)
        at = clients[0].camera.look_at
        return layout.to_canvas(float(at[0]), float(at[1]))

    # ------------------------------------------------------------------ geometry
    def _title(self, node: Any) -> str:
        if node.type == "subgraph":
            return f"{node.id} · {node.params.get('file', 'sub-graph')}"
        if node.type in structures.STRUCTURES:
            return f"{node.id} · {structures.caption(self.state.graph, node.id)}"
        try:
            return f"{node.id} · {self.state.runtime.registry.lookup(node.type, self.state.base_dir).title}"
        except GraphError:
            return f"{node.id} · {node.type} (unknown type)"

    def _preview(self, node: Any) -> list[str]:
        """The first rows of the node's first table param (segment rows, machine axes)."""
        try:
            cls = self.state.runtime.registry.lookup(node.type, self.state.base_dir)
        except GraphError:
            return []
        spec = _rows_field(cls.Params)
        return draw.rows_preview(spec.name, node.params.get(spec.name, spec.default), spec.tag) if spec else []

    def geometry(self) -> None:
        """Boxes, notes, wire curves and problems from the state (no drawing)."""
        state, plan = self.state, self.state.plan()
        self._revision = state.revision
        wired = {w.to for w in state.graph.wires}
        boxes = []
        for n in state.graph.nodes:
            ports = node_ports(n, state.runtime.registry, state.base_dir, plan)
            ins = [(p, draw.port_label(p, n.params, f"{n.id}.{p.name}" in wired)) for p in ports.inputs]
            outs = [(p, p.name) for p in ports.outputs]
            boxes.append(layout.node_box(n.id, n.pos, ins, outs, self._title(n), self._preview(n)))
        boxes += self._terminals(boxes)
        self.boxes, self.by_id = boxes, {b.node_id: b for b in boxes}
        self.notes = self._note_boxes()
        self.curves, self.types = {}, {}
        lines = [(w.from_, w.to, None) for w in state.graph.wires] + terminal_wires(state.graph)
        for src, dst, kind in lines:
            a, b = self._end(src, "out"), self._end(dst, "in")
            if a is not None and b is not None:
                self.curves[(src, dst)] = layout.wire_points((a.x, a.y), (b.x, b.y))
                self.types[(src, dst)] = kind or a.info.type
        self.problems, self.broken = draw.node_problems(plan.issues, state.graph.wires)

    def _end(self, ref: str, kind: str) -> layout.PortSpot | None:
        """The port spot a wire end names: "node.port", or a terminal's one port."""
        if ref.startswith("@"):
            box = self.by_id.get(ref)
            spots = (box.outputs if kind == "out" else box.inputs) if box is not None else []
            return spots[0] if spots else None
        node_id, port = split_ref(ref)
        box = self.by_id.get(node_id)
        return box.port(kind, port) if box is not None else None

    def _terminals(self, boxes: list[layout.NodeBox]) -> list[layout.NodeBox]:
        """Input terminals left of the nodes they feed, output terminals right of their sources
        (or where they were put: ``view.terminals``)."""
        graph = self.state.graph
        if graph.interface is None:
            return []
        by_id = {b.node_id: b for b in boxes}
        left = min((b.x for b in boxes), default=0.0) / layout.SCALE - 230.0
        right = max((b.x + b.w for b in boxes), default=0.0) / layout.SCALE + 80.0
        out: list[layout.NodeBox] = []
        taken: list[tuple[str, float]] = []
        items: list[tuple[str, Any, str]] = [("in", i, i.to[0] if i.to else "") for i in graph.interface.inputs]
        items += [("out", o, o.from_) for o in graph.interface.outputs]
        for kind, item, ref in items:
            near = by_id.get(split_ref(ref)[0])
            pos = graph.view.terminals.get(f"{kind}.{item.name}")
            if pos is None:
                y = -near.y / layout.SCALE if near is not None else 0.0
                while any(abs(y - t) < 60 for k, t in taken if k == kind):
                    y += 60.0
                taken.append((kind, y))
                pos = (left if kind == "in" else right, y)
            port = PortInfo(item.name, "out" if kind == "in" else "in", (item.type,), doc=item.description)
            title = f"▶ {item.name}" if kind == "in" else f"{item.name} ▶"
            pair = [(port, item.type)]
            out.append(layout.node_box(layout.terminal_id(kind, item.name), pos, [] if kind == "in" else pair,
                                       pair if kind == "in" else [], title))
        return out

    def _note_boxes(self) -> list[layout.NoteBox]:
        view, s = self.state.graph.view, layout.SCALE
        notes = [layout.NoteBox(f"#{c.id}", "comment", c.pos[0] * s, -c.pos[1] * s, c.size[0] * s, c.size[1] * s, c.text)
                 for c in view.comments]
        for lb in view.labels:
            w = layout.text_width(lb.text or " ", LABEL_FONT) + 12
            notes.append(layout.NoteBox(f"#{lb.id}", "label", lb.pos[0] * s, -lb.pos[1] * s, w * s, 24 * s, lb.text))
        return notes

    def ports_of(self, box_id: str) -> NodePorts:
        box = self.by_id.get(box_id)
        if box is None:
            return NodePorts(known=False)
        return NodePorts(tuple(s.info for s in box.inputs), tuple(s.info for s in box.outputs))

    # ------------------------------------------------------------------ drawing
    def sync(self) -> None:
        """Redraw from the state: batches are resent only where they changed, labels only where their text did."""
        with self.lock:
            self.geometry()
            with self.server.atomic():
                self._draw_grid()
                self._draw_shapes()
                self.texts.show(self._texts())
                self._draw_pending()
            self._send_tips()
        self.server.flush()

    def _send_tips(self, clients: list[Any] | None = None) -> None:
        """Hover texts of cut titles, sent when they changed (or to a page that just connected)."""
        s = layout.SCALE
        tips = [(b.x, b.y - layout.TITLE_H * s, b.x + b.w, b.y, plain(b.full_title, 300)) for b in self.boxes if b.elided]
        if tips != self._tips or clients is not None:
            self._tips = tips
            for client in clients if clients is not None else list(self.server.get_clients().values()):
                viser_internals.set_tips(client, tips)

    def sync_selection(self) -> None:
        """After a selection change only: recolour frames, wires and notes (fast, nothing is rebuilt)."""
        with self.lock:
            if self._revision != self.state.revision:
                return self.sync()
            with self.server.atomic():
                self._draw_shapes()
        self.server.flush()

    def _draw_shapes(self) -> None:
        state, t = self.state, self.theme
        quads = draw.node_quads(self.boxes, self.status, set(state.selected_nodes), self.problems, t, self.frame_edge)
        quads["ports"] = self._ports()
        quads.update(draw.note_quads(self.notes, set(state.selected_notes), t))
        for name in _BATCHES:
            self._batch(name, quads[name])
        self._set_lines(*self._wires())

    def _ports(self) -> draw.Quads:
        """The port squares; made again only when the boxes, the theme or the drag highlight changed (a selection
        change on a 120-node graph spent half its server time remaking the same arrays)."""
        key = (self.boxes, self.theme, self.highlight)
        if self._port_memo is None or any(a is not b for a, b in zip(self._port_memo[0], key)):
            self.port_index = [(b.node_id, s) for b in self.boxes for s in b.inputs + b.outputs]
            self._port_memo = (key, draw.port_quads(self.boxes, self.highlight, self.theme))
        return self._port_memo[1]

    def _wires(self) -> tuple[np.ndarray, np.ndarray]:
        """Wire segments and colours: the geometry made once per set of curves, the selection painted over it."""
        key = (self.curves, self.theme, self.broken)
        if self._wire_memo is None or any(a is not b for a, b in zip(self._wire_memo[0], key)):
            segs, cols = draw.wire_segments(self.curves, self.types, set(), self.broken, self.theme)
            spans, at = {}, 0
            for wire, pts in self.curves.items():
                spans[wire] = (at, at + len(pts) - 1)
                at += len(pts) - 1
            self._wire_memo = (key, segs, cols, spans)
        _key, segs, cols, spans = self._wire_memo
        chosen = [spans[w] for w in self.state.selected_wires if w in spans]
        if chosen:
            cols = cols.copy()
            for a, b in chosen:
                cols[a:b] = self.theme.selected
        return segs, cols

    def _batch(self, name: str, quads: draw.Quads) -> None:
        """Update one batched mesh, sending only the arrays that changed (a new mesh when the count does)."""
        handle = self._handles.get(name)
        if handle is not None and len(handle.batched_positions) == len(quads) and len(quads):
            for prop, value in (("batched_positions", quads.positions), ("batched_scales", quads.scales),
                                ("batched_colors", quads.colors)):
                if not np.array_equal(getattr(handle, prop), value):
                    setattr(handle, prop, value)
            return
        if handle is not None:
            handle.remove()
            self._handles.pop(name)
        if not len(quads):
            return
        handle = self.server.scene.add_batched_meshes_simple(
            f"/canvas/{name}", draw.QUAD_VERTICES, draw.QUAD_FACES, np.tile([1.0, 0, 0, 0], (len(quads), 1)),
            quads.positions, batched_scales=quads.scales, batched_colors=quads.colors, lod="off", side="double",
            material="toon3", cast_shadow=False, receive_shadow=False)  # toon: same colours under ambient light, a cheaper shader
        drag = {"body": self._on_drag, "notebar": self._on_note_drag, "ports": self.wiring.on_drag}.get(name)
        if drag is not None:
            handle.on_drag("left")(drag)
        self._handles[name] = handle

    def _set_lines(self, segs: np.ndarray, cols: np.ndarray) -> None:
        handle = self._handles.get("wires")
        if handle is not None and handle.points.shape == segs.shape and np.array_equal(handle.points, segs):
            if not np.array_equal(handle.colors, cols):
                handle.colors = cols
            return
        if handle is not None:
            self._handles.pop("wires").remove()
        if len(segs):
            self._handles["wires"] = self.server.scene.add_line_segments("/canvas/wires", segs, cols, thickness=self.wire_px,
                                                                         thickness_units="screen")

    def _texts(self) -> dict[str, tuple[str, tuple[float, float], float, str, bool]]:
        """Every label: titles (always shown), and port names, previews, status lines (details)."""
        s, out = layout.SCALE, {}
        for box in self.boxes:
            key = box.node_id.replace("/", "_")
            out[f"{key}/title"] = (box.title, (box.x + layout.PAD * s, box.y - layout.TITLE_H * s / 2),
                                   layout.TITLE_FONT * s, "center-left", False)
            for spot in box.inputs:
                if spot.label:
                    out[f"{key}/in/{spot.info.name}"] = (spot.label, (spot.x + 0.09, spot.y), layout.PORT_FONT * s,
                                                        "center-left", True)
            for spot in box.outputs:
                if spot.label:
                    out[f"{key}/out/{spot.info.name}"] = (spot.label, (spot.x - 0.09, spot.y), layout.PORT_FONT * s,
                                                         "center-right", True)
            top = box.y - box.h + (len(box.preview) * layout.PREVIEW_H + layout.PAD) * s
            for k, line in enumerate(box.preview):
                out[f"{key}/row/{k}"] = (line, (box.x + layout.PAD * s, top - (k + 0.5) * layout.PREVIEW_H * s),
                                         layout.PREVIEW_FONT * s, "center-left", True)
            problems = self.problems.get(box.node_id, [])
            if draw.has_badge(box.node_id, self.status, self.problems):
                out[f"{key}/badge"] = (str(len(problems)) if len(problems) > 1 else "!",
                                       (box.x + box.w - 0.14, box.y - layout.TITLE_H * s / 2), 11 * s, "center-center", False)
            status = draw.status_text(self.status.get(box.node_id), problems)
            if status:
                out[f"{key}/status"] = (status, (box.x, box.y - box.h - 0.06), 10 * s, "top-left", True)
        for decorate in self.decorations:  # text others put on the canvas (probes' values)
            out.update(decorate(self))
        for note in self.notes:
            size = COMMENT_FONT if note.kind == "comment" else LABEL_FONT
            pos = (note.x + 0.08, note.y - (layout.COMMENT_BAR * s / 2 if note.kind == "comment" else note.h / 2))
            text = layout.fit_text(note.text or " ", size, note.w / s - 16) if note.kind == "comment" else note.text
            out[f"note/{note.note_id[1:]}"] = (text or " ", pos, size * s, "center-left", False)
        return out

    def _draw_pending(self) -> None:
        hit = self.pending
        box = self.by_id.get(hit.node_id) if hit is not None else None
        spot = box.port(hit.port.kind, hit.port.name) if box is not None and hit is not None and hit.port is not None \
            else None
        if spot is None:
            self.pending = None
            self._pending_marker.visible = False
            return
        self._pending_marker.position = (spot.x, spot.y, draw.Z_PORTS - 0.005)
        self._pending_marker.visible = True

    # ------------------------------------------------------------------ clicks
    def _on_scene_click(self, event: viser.SceneClickEvent) -> None:
        point = layout.ray_to_plane(event.ray_origin, event.ray_direction)
        if point is not None:
            self.click(point[0], point[1], toggle=event.modifier is not None and "shift" in event.modifier)

    def _on_rect_select(self, event: viser.SceneRectSelectEvent) -> None:
        self.select_box(*camera.screen_rect_to_world(event.client.camera, event.screen_min, event.screen_max))

    def select_box(self, x0: float, y0: float, x1: float, y1: float) -> list[str]:
        """Add every node and note whose centre lies in the world rectangle to the selection."""
        with self.lock:
            inside = [b.node_id for b in self.boxes if x0 <= b.centre[0] <= x1 and y0 <= b.centre[1] <= y1]
            notes = [n.note_id for n in self.notes if x0 <= n.x + n.w / 2 <= x1 and y0 <= n.y - n.h / 2 <= y1]
            new = [n for n in inside if n not in self.state.selected_nodes]
            new_notes = [n for n in notes if n not in self.state.selected_notes]
            if new or new_notes:
                self.state.select(nodes=new, notes=new_notes, toggle=True)
            return inside

    def click(self, x: float, y: float, toggle: bool = False) -> layout.Hit | None:
        """Act on a click at world point (x, y): wire ports, select nodes, notes and wires, or clear."""
        with self.lock:
            got = layout.hit(self.boxes, self.curves, x, y, notes=self.notes)
            if got is not None and got.kind == "port":
                self.wiring.port_clicked(got)
                return got
            self.pending = None
            if got is not None and got.kind == "node":
                self.state.select(nodes=[got.node_id], toggle=toggle)
            elif got is not None and got.kind == "note":
                self.state.select(notes=[got.node_id], toggle=toggle)
            elif got is not None:
                self.state.select(wires=[got.wire], toggle=toggle)
            elif not toggle and (self.state.selected_nodes or self.state.selected_wires or self.state.selected_notes):
                self.state.clear_selection()
            else:
                self._draw_pending()
                self.server.flush()
            return got

    # ------------------------------------------------------------------ drags
    def _start_move(self, grabbed: str, start: Any, selected: bool) -> None:
        state = self.state
        keys = [*state.selected_nodes, *state.selected_notes] if selected else [grabbed]
        riders = set()
        for key in keys:  # a comment carries the nodes that sit inside it
            note = next((n for n in self.notes if n.note_id == key and n.kind == "comment"), None)
            if note is not None:
                riders |= {b.node_id for b in self.boxes if note.x <= b.x and b.x + b.w <= note.x + note.w
                           and note.y - note.h <= b.y - b.h and b.y <= note.y}
        keys = list(dict.fromkeys([*keys, *sorted(riders)]))
        state.record()
        self._drag = {"grab": np.asarray(start[:2]), "from": {k: self._place(k) for k in keys}}

    def _place(self, key: str) -> tuple[float, float]:
        """Where an item's top-left is, canvas px."""
        box = self.by_id.get(key)
        if box is not None:
            return layout.to_canvas(box.x, box.y)
        note = next(n for n in self.notes if n.note_id == key)
        return layout.to_canvas(note.x, note.y)

    def _move(self, event: Any) -> None:
        if self._drag is None:
            return
        dx, dy = (np.asarray(event.end_position[:2]) - self._drag["grab"]) / layout.SCALE
        self.state.move_nodes({k: (x + dx, y - dy) for k, (x, y) in self._drag["from"].items() if self.state.has_item(k)},
                              record=False)
        if event.phase == "end":
            self._drag = None

    async def _on_drag(self, event: viser.SceneNodeDragEvent) -> None:
        """Move the grabbed node or terminal (and the rest of the selection when it is part of it)."""
        with self.lock:
            if event.phase == "start":
                k = event.instance_index
                if k is None or k >= len(self.boxes):
                    return
                key = self.boxes[k].node_id
                self._start_move(key, event.start_position, key in self.state.selected_nodes)
                return
            self._move(event)

    async def _on_note_drag(self, event: viser.SceneNodeDragEvent) -> None:
        """Move a comment (with the nodes inside it) or a label by its strip."""
        with self.lock:
            if event.phase == "start":
                k = event.instance_index  # the strips are drawn one per note, in order
                if k is None or k >= len(self.notes):
                    return
                key = self.notes[k].note_id
                self._start_move(key, event.start_position, key in self.state.selected_notes)
                return
            self._move(event)

