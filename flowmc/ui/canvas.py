"""The node canvas in the viser scene: boxes, ports, wires and labels drawn from an EditorState,
and clicks and drags turned back into EditorState edits.

The camera (``camera``) looks straight down -z on a flat sheet. Bodies, frames, title bars and
ports are four batched meshes (a 100-node graph stays a handful of draw calls); wires are one
line-segments node. viser cannot click lines or labels, so every click is hit-tested here: the
click ray meets the plane z = 0 and ``layout.hit`` says what is under it.
"""

from __future__ import annotations

import threading
from typing import Any, Callable

import numpy as np
import viser

from flowmc.errors import GraphError
from flowmc.graph import split_ref
from flowmc.ui import camera, layout
from flowmc.ui import canvas_draw as draw
from flowmc.ui.ports import node_ports
from flowmc.ui.state import EditorState

__all__ = ["Canvas"]

_BATCHES = ("frame", "body", "title", "ports")


class Canvas:
    """Draws ``state.graph``; ``notify(kind, text)`` hears refusals ("error") and hints ("info").

    ``status`` holds each node's last run event ``(kind, duration, message)``; ``pending`` is the
    first port clicked while wiring. All edits take ``lock`` (shared with the rest of the editor)."""

    def __init__(self, server: viser.ViserServer, state: EditorState, notify: Callable[[str, str], None],
                 lock: threading.RLock | None = None, status: dict[str, tuple] | None = None):
        self.server, self.state, self.notify = server, state, notify
        self.lock = lock or threading.RLock()
        self.status: dict[str, tuple[str, float | None, str | None]] = {} if status is None else status
        self.pending: layout.Hit | None = None
        self.boxes: list[layout.NodeBox] = []
        self.curves: dict[tuple[str, str], np.ndarray] = {}
        self._handles: dict[str, Any] = {}
        self._labels: dict[str, tuple[Any, str, tuple[float, float]]] = {}
        self._drag: dict[str, Any] | None = None
        scene = server.scene
        scene.set_up_direction("+y")
        scene.configure_default_lights(False)
        scene.configure_environment_map(None)
        scene.add_light_ambient("/light", intensity=draw.AMBIENT)
        self._pending_marker = scene.add_box("/canvas/pending", color=tuple(draw.mesh_rgb(draw.FRAME_SELECTED)),
                                             dimensions=(0.21, 0.21, 0.01),
                                             visible=False, cast_shadow=False, receive_shadow=False)
        scene.on_click()(self._on_scene_click)
        scene.on_click(modifier="shift")(self._on_scene_click)  # shift-click adds to the selection
        scene.on_rect_select(modifier="shift")(self._on_rect_select)  # shift-drag selects a box of nodes

    # ------------------------------------------------------------------ camera
    def setup_client(self, client: viser.ClientHandle) -> None:
        """Top-down camera, locked flat, framing the graph."""

        def frame_again() -> None:
            with self.lock:
                self.fit([client])

        camera.setup(client, frame_again)

    def fit(self, clients: list[viser.ClientHandle] | None = None) -> None:
        """Frame every node (the middle of the sheet when there are none) in each client's view."""
        box = layout.bounds(self.boxes) or (-2.0, -2.0, 6.0, 2.0)
        for client in clients if clients is not None else list(self.server.get_clients().values()):
            camera.frame(client, box)

    def view_centre(self) -> tuple[float, float]:
        """Canvas pixels at the middle of the first client's view (where palette nodes appear)."""
        clients = list(self.server.get_clients().values())
        if not clients:
            box = layout.bounds(self.boxes)
            return layout.to_canvas(box[2] + 0.5, box[3]) if box else (0.0, 0.0)
        at = clients[0].camera.look_at
        return layout.to_canvas(float(at[0]), float(at[1]))

    # ------------------------------------------------------------------ drawing
    def sync(self) -> None:
        """Redraw from the state: batches are resent whole, labels only where their text or place changed."""
        with self.lock:
            state, plan = self.state, self.state.plan()
            self.boxes = [layout.node_box(n.id, n.pos, node_ports(n, state.runtime.registry, state.base_dir, plan))
                          for n in state.graph.nodes]
            by_id = {b.node_id: b for b in self.boxes}
            self.curves, types = {}, {}
            for w in state.graph.wires:
                (sn, sp), (dn, dp) = split_ref(w.from_), split_ref(w.to)
                a = by_id[sn].port("out", sp) if sn in by_id else None
                b = by_id[dn].port("in", dp) if dn in by_id else None
                if a is not None and b is not None:
                    self.curves[(w.from_, w.to)] = layout.wire_points((a.x, a.y), (b.x, b.y))
                    types[(w.from_, w.to)] = a.info.type
            problems, broken = draw.node_problems(plan.issues, state.graph.wires)
            with self.server.atomic():
                quads = draw.node_quads(self.boxes, self.status, set(state.selected_nodes), problems)
                quads["ports"] = draw.port_quads(self.boxes)
                for name in _BATCHES:
                    self._batch(name, quads[name])
                segs, cols = draw.wire_segments(self.curves, types, set(state.selected_wires), broken)
                self._set_lines(segs, cols)
                self._draw_labels(by_id, problems)
                self._draw_pending(by_id)
        self.server.flush()

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
            cast_shadow=False, receive_shadow=False)
        if name == "body":
            handle.on_drag("left")(self._on_drag)
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
            self._handles["wires"] = self.server.scene.add_line_segments("/canvas/wires", segs, cols, thickness=0.025)

    def _label(self, key: str, text: str, pos: tuple[float, float], size: float, anchor: str) -> None:
        old = self._labels.get(key)
        if old is not None and old[1] == text and old[2] == pos:
            return
        if old is not None and old[1] == text:
            old[0].position = (pos[0], pos[1], draw.Z_LABELS)
        else:
            if old is not None:
                old[0].remove()
            handle = self.server.scene.add_label(f"/canvas/labels/{key}", text, position=(pos[0], pos[1], draw.Z_LABELS),
                                                 font_size_mode="scene", font_scene_height=size, anchor=anchor)
            old = (handle, text, pos)
        self._labels[key] = (old[0], text, pos)

    def _draw_labels(self, by_id: dict[str, layout.NodeBox], problems: dict[str, list[str]]) -> None:
        seen: set[str] = set()
        wired = {w.to for w in self.state.graph.wires}

        def put(key: str, text: str, pos: tuple[float, float], size: float, anchor: str) -> None:
            if text:
                seen.add(key)
                self._label(key, text, (round(pos[0], 4), round(pos[1], 4)), size, anchor)

        for node in self.state.graph.nodes:
            box = by_id[node.id]
            put(f"{node.id}/title", draw.shorten(f"{node.id} · {self._type_title(node)}", 30),
                (box.x + 0.07, box.y - layout.TITLE_H * layout.SCALE / 2), 0.125, "center-left")
            for spot in box.inputs:
                text = draw.port_label(spot, node.params, f"{node.id}.{spot.info.name}" in wired)
                put(f"{node.id}/in/{spot.info.name}", text, (spot.x + 0.1, spot.y), 0.095, "center-left")
            for spot in box.outputs:
                put(f"{node.id}/out/{spot.info.name}", spot.info.name, (spot.x - 0.1, spot.y), 0.095, "center-right")
            put(f"{node.id}/status", draw.status_text(self.status.get(node.id), problems.get(node.id, [])),
                (box.x, box.y - box.h - 0.08), 0.1, "top-left")
        for key in [k for k in self._labels if k not in seen]:
            self._labels.pop(key)[0].remove()

    def _type_title(self, node: Any) -> str:
        if node.type == "subgraph":
            return str(node.params.get("file", "sub-graph"))
        try:
            return self.state.runtime.registry.lookup(node.type, self.state.base_dir).title
        except GraphError:
            return f"{node.type} (unknown type)"

    def _draw_pending(self, by_id: dict[str, layout.NodeBox]) -> None:
        hit = self.pending
        spot = by_id[hit.node_id].port(hit.port.kind, hit.port.name) if hit is not None and hit.node_id in by_id else None
        if spot is None:
            self.pending = None
            self._pending_marker.visible = False
            return
        self._pending_marker.position = (spot.x, spot.y, draw.Z_PORTS - 0.005)
        self._pending_marker.visible = True

    # ------------------------------------------------------------------ interaction
    def _on_scene_click(self, event: viser.SceneClickEvent) -> None:
        point = layout.ray_to_plane(event.ray_origin, event.ray_direction)
        if point is not None:
            self.click(point[0], point[1], toggle=event.modifier is not None and "shift" in event.modifier)

    def _on_rect_select(self, event: viser.SceneRectSelectEvent) -> None:
        self.select_box(*camera.screen_rect_to_world(event.client.camera, event.screen_min, event.screen_max))

    def select_box(self, x0: float, y0: float, x1: float, y1: float) -> list[str]:
        """Add every node whose centre lies in the world rectangle to the selection."""
        with self.lock:
            inside = [b.node_id for b in self.boxes if x0 <= b.centre[0] <= x1 and y0 <= b.centre[1] <= y1]
            new = [n for n in inside if n not in self.state.selected_nodes]
            if new:
                self.state.select(nodes=new, toggle=True)
            return inside

    def click(self, x: float, y: float, toggle: bool = False) -> layout.Hit | None:
        """Act on a click at world point (x, y): wire ports, select nodes and wires, or clear."""
        with self.lock:
            got = layout.hit(self.boxes, self.curves, x, y)
            if got is not None and got.kind == "port":
                self._port_clicked(got)
            elif got is not None and got.kind == "node":
                self.pending = None
                self.state.select(nodes=[got.node_id], toggle=toggle)
            elif got is not None:
                self.pending = None
                self.state.select(wires=[got.wire], toggle=toggle)
            else:
                self.pending = None
                if not toggle:
                    self.state.clear_selection()
                self.sync()
            return got

    def _port_clicked(self, got: layout.Hit) -> None:
        first, self.pending = self.pending, None
        if first is None:
            self.pending = got
            other = "an input" if got.port.kind == "out" else "an output"
            self.notify("info", f"{got.node_id}.{got.port.name} picked: now click {other} to wire it")
            self.sync()
            return
        if (first.node_id, first.port.name, first.port.kind) == (got.node_id, got.port.name, got.port.kind):
            self.sync()
            return
        if first.port.kind == got.port.kind:
            both = "outputs" if got.port.kind == "out" else "inputs"
            self.notify("error", f"{first.node_id}.{first.port.name} and {got.node_id}.{got.port.name} are both "
                                 f"{both}: wire an output to an input")
            self.sync()
            return
        src, dst = (first, got) if first.port.kind == "out" else (got, first)
        reason = self.state.connect(f"{src.node_id}.{src.port.name}", f"{dst.node_id}.{dst.port.name}")
        if reason is not None:
            self.notify("error", reason)
        self.sync()

    async def _on_drag(self, event: viser.SceneNodeDragEvent) -> None:
        """Move the grabbed node (and the rest of the selection when it is part of it)."""
        with self.lock:
            if event.phase == "start":
                node_id = self.boxes[event.instance_index].node_id if event.instance_index < len(self.boxes) else None
                if node_id is None:
                    return
                moving = list(self.state.selected_nodes) if node_id in self.state.selected_nodes else [node_id]
                self.state.record()
                self._drag = {"grab": np.asarray(event.start_position[:2]),
                              "from": {n: self.state.node(n).pos for n in moving if self.state.has_node(n)}}
                return
            if self._drag is None:
                return
            dx, dy = (np.asarray(event.end_position[:2]) - self._drag["grab"]) / layout.SCALE
            self.state.move_nodes({n: (x + dx, y - dy) for n, (x, y) in self._drag["from"].items()
                                   if self.state.has_node(n)}, record=False)
            if event.phase == "end":
                self._drag = None
