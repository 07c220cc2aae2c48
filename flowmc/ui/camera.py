"""The canvas camera: it looks straight down -z (the scene's up is +y) with a narrow field of view,
so the perspective view reads as a flat sheet; ``viser_internals`` keeps it from turning."""

from __future__ import annotations

import math
import time
import weakref
from typing import Any, Callable

import numpy as np
import viser

from flowmc.ui import viser_internals

__all__ = ["FOV", "setup", "frame", "framed_here", "resized", "view_px", "initial", "screen_rect_to_world",
           "screen_px_per_world", "world_at"]

FOV = math.radians(12.0)
LEGIBLE_STRETCH = 1.4  # how much bigger than the view a graph may be for Fit to keep its text legible
MAX_VIEW_PX = 100_000  # a page reporting a bigger view is not believed
SETTLE_S = 5.0  # the page lays out its panels after it connects: frame again while its size settles
FRAMINGS_KEPT = 4  # a camera report can lag a framing or two behind while the page docks its panels


class _View:
    """What the editor knows of one page's view (client ids restart with every server: kept by handle)."""

    def __init__(self, refit: Callable[[], None]):
        self.refit = refit  # frame again if the user has not moved the camera (see ``setup``)
        self.size: tuple[int, int] | None = None  # CSS pixels, as the page reports them
        self.framings: list[tuple[float, float, float]] = []  # the camera positions framing last set


_VIEWS: weakref.WeakKeyDictionary[viser.ClientHandle, _View] = weakref.WeakKeyDictionary()


def framed_here(client: viser.ClientHandle, position: Any) -> bool:
    """Whether ``position`` is where a recent framing put the camera (the user has not moved it). Not only
    the last framing: under load the page can report a new size with the position of the framing before
    (the answer to an in-between size of a docking panel is still on its way), and judging that a user's
    move left the graph framed for the in-between size, zoomed out."""
    view = _VIEWS.get(client)
    return view is not None and any(np.allclose(position, f, atol=1e-3 * max(f[2], 1.0)) for f in view.framings)


def view_px(cam: viser.CameraHandle) -> tuple[float, float]:
    """The view's width and height in CSS pixels, what legibility is judged in. The camera's image size is
    the drawing buffer's, which viser shrinks to 0.75 of the page's pixels on a slow GPU (and which is twice
    the CSS size on a high-density screen): framing by it zoomed a graph out to an overview under load.
    It stands in only until the page has reported its size."""
    view = _VIEWS.get(cam.client)
    if view is not None and view.size is not None:
        return float(view.size[0]), float(view.size[1])
    return float(cam.image_width), float(cam.image_height)


def resized(client: viser.ClientHandle, data: Any) -> None:
    """The page's report of its view's size, ``{"w": .., "h": ..}`` in CSS pixels: frame again when it
    changed (and the user has not moved the camera). The page is not trusted: anything else is dropped."""
    view = _VIEWS.get(client)
    try:
        size = (int(data["w"]), int(data["h"]))
    except (TypeError, KeyError, ValueError, OverflowError):
        return
    if view is None or not (0 < size[0] <= MAX_VIEW_PX and 0 < size[1] <= MAX_VIEW_PX) or size == view.size:
        return
    view.size = size
    view.refit()


def setup(client: viser.ClientHandle, frame_again: Callable[[], None]) -> None:
    """Top-down, locked camera for ``client``; ``frame_again()`` runs now and whenever the view's size
    changes during the first seconds, or later while the camera is still where framing put it (a
    docked panel opening or closing then keeps the graph framed; a view the user moved stays)."""
    deadline = time.monotonic() + SETTLE_S

    def refit() -> None:
        if time.monotonic() <= deadline or framed_here(client, client.camera.position):
            frame_again()

    view = _VIEWS[client] = _View(refit)
    size = [client.camera.image_width, client.camera.image_height]

    def drawn(camera: viser.CameraHandle) -> None:  # the drawing buffer's size, until the page reports its own
        if view.size is None and [camera.image_width, camera.image_height] != size:
            size[:] = [camera.image_width, camera.image_height]
            refit()

    client.camera.fov = FOV
    client.camera.near, client.camera.far = 0.5, 20000.0
    frame_again()
    viser_internals.lock_flat_camera(client)
    client.camera.on_update(drawn)


def frame(client: viser.ClientHandle, box: tuple[float, float, float, float], margin: float = 0.4,
          legible: float = 0.0) -> float:
    """Look straight down on the world rectangle ``box`` (xmin, ymin, xmax, ymax), all of it in view; returns
    the screen pixels per world unit of the new view (the page reports the camera back later).

    ``legible``: screen pixels per world unit below which text is hard to read. When showing all of ``box``
    would go below it, but a view at ``legible`` still shows at least 1/``LEGIBLE_STRETCH`` of the box
    each way (a docked panel opened beside a graph that just fitted), the view stays at ``legible`` and
    shows the box's left (where sources are) and top; a bigger graph is shown whole, as an overview."""
    cam = client.camera
    w, h = box[2] - box[0] + 2 * margin, box[3] - box[1] + 2 * margin
    width_px, height_px = (max(px, 200.0) for px in view_px(cam))
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
    view = _VIEWS.get(client)
    if view is not None:
        view.framings[:] = [*view.framings[1 - FRAMINGS_KEPT:], (cx, cy, dist)]
    with client.atomic():
        cam.position = (cx, cy, dist)
        cam.look_at = (cx, cy, 0.0)
    return height_px / (2 * dist * math.tan(FOV / 2))


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
    dist, height = float(cam.position[2]), view_px(cam)[1]
    if dist <= 0 or height <= 0:
        return None
    return height / (2 * dist * math.tan(cam.fov / 2))


def world_at(cam: viser.CameraHandle, u: float, v: float) -> tuple[float, float]:
    """The canvas-plane point (world x, y) under view coordinates (u, v) (0..1, y down)."""
    x0, y0, x1, y1 = screen_rect_to_world(cam, (u, v), (u, v))
    return x0, y1
