"""The only place the editor reaches past viser 1.1.1's public API (pinned in pyproject).

viser has no way to stop the camera orbiting, set the browser tab's title, place notifications,
start a download without a second click, or send page events viser does not know (a palette entry
dropped on the canvas, text pasted from the clipboard, a grid cell edited). Each is a few lines
of JavaScript sent with viser's internal ``RunJavascriptMessage`` to one client (so nothing piles
up in the broadcast buffer that new clients replay).

The camera script reads ``window.__viserMutable.cameraControl``, the camera-controls instance viser
keeps for its own browser tests: once the server's top-down pose has arrived it freezes the polar
angle at a right angle and the azimuth at the nearest quarter turn (the view stays flat on the
canvas), maps left and right drag to panning, zooms toward the cursor, and turns the view back if
anything turns it (a pan was seen to turn it by 0.24 degrees).

The page script (``install_page``) defines ``window.flowmc``: ``send(kind, data)`` posts an event to
the server through a hidden text field (``channel``: viser's own ``GuiUpdateMessage`` for that
field, so the server hears it as that field's update; a counter makes every message new), and
``download(name, text)``. It moves viser's notifications to the bottom right corner, over the foot
of the side panel, and points ``iframe[data-flowmc-port]`` at the other name of this machine
(``127.0.0.1`` <-> ``localhost``): a cross-site frame runs in its own browser process, so the 3D
view's work never stalls the editor's canvas. If a future viser renames these, the camera
orbits again and the extras stop; nothing else depends on them.
"""

from __future__ import annotations

import json
from typing import Any

from viser import _messages

__all__ = ["lock_flat_camera", "set_page_title", "install_page", "download", "run_js"]

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

_PAGE_JS = """
(function flowmcPage(channel) {
  if (window.flowmc) { window.flowmc.channel = channel; return; }
  let counter = 0;
  const flowmc = window.flowmc = { channel: channel, handlers: [] };
  flowmc.send = (kind, data) => {
    const m = window.__viserMutable;
    if (!m || !m.sendMessage) return false;
    counter += 1;
    m.sendMessage({ type: "GuiUpdateMessage", uuid: flowmc.channel,
                    updates: { value: JSON.stringify({ kind: kind, n: counter, t: Date.now(), data: data }) } });
    return true;
  };
  flowmc.download = (name, text) => {
    const url = URL.createObjectURL(new Blob([text], { type: "application/octet-stream" }));
    const a = document.createElement("a");
    a.href = url; a.download = name; a.style.display = "none";
    document.body.appendChild(a); a.click(); a.remove();
    setTimeout(() => URL.revokeObjectURL(url), 60000);
  };
  const style = document.createElement("style");
  style.textContent = `.mantine-Notifications-root { position: fixed !important; top: auto !important;
      left: auto !important; right: 12px !important; bottom: 12px !important; width: 340px !important; }`;
  document.head.appendChild(style);
  const otherHost = () => {
    const h = location.hostname;
    return h === "127.0.0.1" ? "localhost" : (h === "localhost" ? "127.0.0.1" : h);
  };
  const point = (frame) => {
    const src = location.protocol + "//" + otherHost() + ":" + frame.dataset.flowmcPort + (frame.dataset.flowmcPath || "/");
    if (frame.getAttribute("src") !== src) frame.setAttribute("src", src);
  };
  const scan = (root) => root.querySelectorAll && root.querySelectorAll("iframe[data-flowmc-port]").forEach(point);
  new MutationObserver(records => records.forEach(r => r.addedNodes.forEach(scan))).observe(document.body,
                                                                                          { childList: true, subtree: true });
  scan(document);
})(CHANNEL);
"""


def run_js(client: Any, source: str) -> None:
    """Run ``source`` in ``client``'s page."""
    client.gui._websock_interface.queue_message(_messages.RunJavascriptMessage(source=source))


def lock_flat_camera(client: Any) -> None:
    """Keep ``client``'s camera looking straight down -z (the scene's up is +y): pan and zoom only."""
    run_js(client, _LOCK_JS)


def set_page_title(client: Any, title: str) -> None:
    """The browser tab's title (the editor puts the file name and the unsaved-changes mark there)."""
    run_js(client, f"document.title = {json.dumps(title)};")


def install_page(client: Any, channel: Any) -> None:
    """``window.flowmc`` in ``client``'s page; its events arrive as updates of the hidden text ``channel``."""
    run_js(client, _PAGE_JS.replace("CHANNEL", json.dumps(channel._impl.uuid)))


def download(client: Any, name: str, text: str) -> None:
    """Save ``text`` as the file ``name`` in ``client``'s browser at once (viser's own download asks twice)."""
    run_js(client, f"window.flowmc && window.flowmc.download({json.dumps(name)}, {json.dumps(text)});")
