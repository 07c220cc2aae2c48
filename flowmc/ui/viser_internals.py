"""The only place the editor reaches past viser 1.1.1's public API (pinned in pyproject).

viser has no way to stop the camera orbiting, and none to set the browser tab's title. Both are
a few lines of JavaScript sent with viser's internal ``RunJavascriptMessage`` to one client (so
nothing piles up in the broadcast buffer that new clients replay). The script reads
``window.__viserMutable.cameraControl``, the camera-controls instance viser keeps for its own
browser tests: once the server's top-down pose has arrived it freezes the polar angle at a
right angle and the azimuth at the nearest quarter turn (the view stays flat on the canvas),
maps left and right drag to panning, zooms toward the cursor, and turns the view back if anything
turns it (a pan was seen to turn it by 0.24 degrees). If a future viser renames
these, the camera simply orbits again; nothing else depends on them.
"""

from __future__ import annotations

import json
from typing import Any

from viser import _messages

__all__ = ["lock_flat_camera", "set_page_title"]

# camera-controls ACTION codes (v2): TRUCK pans, DOLLY zooms; TOUCH_TRUCK pans with one finger.
_LOCK_JS = """
(function flowmcLockCamera(tries) {
  const m = window.__viserMutable;
  const c = m && m.cameraControl;
  const flat = c && Math.abs(c.polarAngle - Math.PI / 2) < 1e-3;
  if (!flat) { if (tries < 600) setTimeout(() => flowmcLockCamera(tries + 1), 50); return; }
  const quarter = Math.PI / 2;  // top-down: the azimuth is a whole number of quarter turns (may be mid-transition)
  const azimuth = Math.round(c.azimuthAngle / quarter) * quarter;
  c.minPolarAngle = c.maxPolarAngle = quarter;
  c.minAzimuthAngle = c.maxAzimuthAngle = azimuth;
  c.rotateTo(azimuth, quarter, false);
  const turned = () => Math.abs(Math.sin(c.azimuthAngle - azimuth)) > 1e-9 || Math.cos(c.azimuthAngle - azimuth) < 0
    || Math.abs(c.polarAngle - quarter) > 1e-9;
  c.addEventListener("update", () => { if (turned()) c.rotateTo(azimuth, quarter, false); });  // a pan may drift
  c.mouseButtons.left = 2; c.mouseButtons.right = 2; c.mouseButtons.wheel = 16;
  c.touches.one = 128;
  c.dollyToCursor = true;
  window.__flowmcCameraLocked = true;
})(0);
"""


def _send(client: Any, source: str) -> None:
    client.gui._websock_interface.queue_message(_messages.RunJavascriptMessage(source=source))


def lock_flat_camera(client: Any) -> None:
    """Keep ``client``'s camera looking straight down -z (the scene's up is +y): pan and zoom only."""
    _send(client, _LOCK_JS)


def set_page_title(client: Any, title: str) -> None:
    """The browser tab's title (the editor puts the file name and the unsaved-changes mark there)."""
    _send(client, f"document.title = {json.dumps(title)};")
