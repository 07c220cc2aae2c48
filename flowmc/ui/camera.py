"""The canvas camera: it looks straight down -z (the scene's up is +y) with a narrow field of view,
so the perspective view reads as a flat sheet; ``viser_internals`` keeps it from turning."""

from __future__ import annotations

import math
import time
from typing import Callable

import numpy as np
import viser

from flowmc.ui import viser_internals

__all__ = ["FOV", "setup", "frame", "initial", "screen_rect_to_world", "screen_px_per_world", "world_at"]

FOV = math.radians(12.0)
LEGIBLE_STRETCH = 1.4  # how much bigger than the view a graph may be for Fit to keep its text legible
SETTLE_S = 5.0  # the page lays out its panels after it connects: frame again while its size settles
_FRAMED: dict[int, tuple[float, float, float]] = {}  # per client: the camera position framing last set


def setup(client: viser.ClientHandle, frame_again: Callable[[], None]) -> None:
    """Top-down, locked camera for ``client``; ``frame_again()`` runs now and whenever the view's size
    changes during the first seconds, or later while the camera is still where framing put it (a
    docked panel opening or closing then keeps the graph framed; a view the user moved stays)."""
    client.camera.fov = FOV
    client.camera.near, client.camera.far = 0.5, 20000.0
    frame_again()
    viser_internals.lock_flat_camera(client)
    size = [client.camera.image_width, client.camera.image_height]
    deadline = time.monotonic() + SETTLE_S

    def refit(camera: viser.CameraHandle) -> None:
        if [camera.image_width, camera.image_height] == size:
            return
        size[:] = [camera.image_width, camera.image_height]
        framed = _FRAMED.get(client.client_id)
        untouched = framed is not None and np.allclose(camera.position, framed, atol=1e-3 * max(framed[2], 1.0))
        if time.monotonic() <= deadline or untouched:
            frame_again()

    client.camera.on_update(refit)


def frame(client: viser.ClientHandle, box: tuple[float, float, float, float], margin: float = 0.4,
          legible: float = 0.0) -> None:
    """Look straight down on the world rectangle ``box`` (xmin, ymin, xmax, ymax), all of it in view.

    ``legible``: screen pixels per world unit below which text is hard to read. When showing all of ``box``
    would go below it, but a view at ``legible`` still shows at least 1/``LEGIBLE_STRETCH`` of the box
    each way (a docked panel opened beside a graph that just fitted), the view stays at ``legible`` and
    shows the box's left (where sources are) and top; a bigger graph is shown whole, as an overview."""
    cam = client.camera
    w, h = box[2] - box[0] + 2 * margin, box[3] - box[1] + 2 * margin
    width_px, height_px = max(cam.image_width, 200), max(cam.image_height, 200)
    per_px = max(w / width_px, h / height_px)  # world units per pixel
    cx, cy = (box[0] + box[2]) / 2, (box[1] + box[3]) / 2
    if legible > 0 and 1 / legible < per_px <= LEGIBLE_STRETCH / legible:
        per_px = 1 / legible
        if w > width_px * per_px:
            cx = box[0] - margin + width_px * per_px / 2
        if h > height_px * per_px:
            cy = box[3] + margin - height_px * per_px / 2
    # FOV, not cam.fov: until the browser has applied our field of view, the camera it reports still has its
    # own (much wider), and framing with that opened about one load in fifteen zoomed in seven times.
    dist = max(per_px * height_px / (2 * math.tan(FOV / 2)), 2.0)
    _FRAMED[client.client_id] = (cx, cy, dist)
    with client.atomic():
        cam.position = (cx, cy, dist)
        cam.look_at = (cx, cy, 0.0)


def screen_rect_to_world(cam: viser.CameraHandle, screen_min: tuple[float, float],
                         screen_max: tuple[float, float]) -> tuple[float, float, float, float]:
    """A rectangle in view coordinates (0..1, y down) as (xmin, ymin, xmax, ymax) on the plane z = 0."""
    half_h = cam.position[2] * math.tan(cam.fov / 2)
    half_w = half_h * cam.aspect
    (u0, v0), (u1, v1) = screen_min, screen_max
    return (cam.position[0] + (2 * u0 - 1) * half_w, cam.position[1] - (2 * v1 - 1) * half_h,
            cam.position[0] + (2 * u1 - 1) * half_w, cam.position[1] - (2 * v0 - 1) * half_h)


def initial(server: viser.ViserServer, box: tuple[float, float, float, float], size: tuple[int, int] = (1240, 1000),
            margin: float = 0.4) -> float:
    """Where a page that connects next starts: looking straight down on ``box`` (for a view of ``size``
    pixels, refitted once the page knows its own), so it never shows a turned camera first. Returns
    the screen pixels per world unit of that view."""
    w, h = box[2] - box[0] + 2 * margin, box[3] - box[1] + 2 * margin
    dist = max(max(w / size[0], h / size[1]) * size[1] / (2 * math.tan(FOV / 2)), 2.0)
    cx, cy = (box[0] + box[2]) / 2, (box[1] + box[3]) / 2
    cam = server.initial_camera
    cam.fov, cam.up = FOV, (0.0, 1.0, 0.0)
    cam.position, cam.look_at = (cx, cy, dist), (cx, cy, 0.0)
    return size[1] / (2 * dist * math.tan(FOV / 2))


def screen_px_per_world(cam: viser.CameraHandle) -> float | None:
    """How many screen pixels one world unit on the canvas plane spans in this view (None before it is known)."""
    dist, height = float(cam.position[2]), float(cam.image_height)
    if dist <= 0 or height <= 0:
        return None
    return height / (2 * dist * math.tan(cam.fov / 2))


def world_at(cam: viser.CameraHandle, u: float, v: float) -> tuple[float, float]:
    """The canvas-plane point (world x, y) under view coordinates (u, v) (0..1, y down)."""
    x0, y0, x1, y1 = screen_rect_to_world(cam, (u, v), (u, v))
    return x0, y1
