"""Which camera reports count as "the user has not moved the view": a docked panel's resize is framed
again only then, and under load a report can carry the position of the framing before the last."""

from __future__ import annotations

import contextlib
from types import SimpleNamespace

from flowmc.ui import camera

BOX = (0.0, -2.0, 30.0, 2.0)


class _Client:
    """What ``camera`` reads and writes of a viser client: its camera and view size (its page is not here;
    the browser tests drive the real one)."""

    def __init__(self, width: int, height: int = 1000):
        self.camera = SimpleNamespace(image_width=width, image_height=height, position=(0.0, 0.0, 10.0),
                                      look_at=(0.0, 0.0, 0.0), fov=camera.FOV, client=self, on_update=lambda _f: None)
        self.atomic = contextlib.nullcontext
        self.gui = SimpleNamespace(_websock_interface=SimpleNamespace(queue_message=lambda _message: None))
        camera.setup(self, lambda: camera.frame(self, BOX))  # type: ignore[arg-type]


def test_a_report_lagging_one_framing_behind_still_counts_as_framed():
    client = _Client(1236)
    before = client.camera.position
    camera.resized(client, {"w": 500, "h": 1000})  # an in-between width while a panel docks
    assert client.camera.position != before
    assert camera.framed_here(client, before)  # the page's report, sent before the second framing reached it
    assert camera.framed_here(client, client.camera.position)


def test_a_view_the_user_moved_is_not_framed_and_old_framings_expire():
    client = _Client(1236)
    first = client.camera.position
    assert not camera.framed_here(client, (first[0] + 3.0, first[1], first[2]))
    assert not camera.framed_here(_Client(700), first)  # framed for another page, not this one
    for width in range(400, 400 + 100 * camera.FRAMINGS_KEPT, 100):
        camera.resized(client, {"w": width, "h": 1000})
    assert not camera.framed_here(client, first)


def test_legibility_is_judged_in_the_pages_pixels_not_the_drawing_buffers():
    client = _Client(1236)
    camera.resized(client, {"w": 1236, "h": 1000})
    framed, per_px = client.camera.position, camera.screen_px_per_world(client.camera)
    client.camera.image_width, client.camera.image_height = 927, 750  # viser's adaptive resolution at 0.75
    assert camera.view_px(client.camera) == (1236.0, 1000.0)
    assert camera.screen_px_per_world(client.camera) == per_px
    camera.frame(client, BOX)
    assert client.camera.position == framed


def test_a_page_size_that_is_not_two_sane_numbers_is_dropped():
    client = _Client(1236)
    framed = client.camera.position
    for bad in (None, {"w": "x", "h": 1}, {"w": 0, "h": 1000}, {"w": 10**9, "h": 1000}, {"w": 1e400, "h": 5}, [1, 2]):
        camera.resized(client, bad)
    assert camera.view_px(client.camera) == (1236.0, 1000.0) and client.camera.position == framed
