"""The only place the editor reaches past viser 1.1.1's public API (pinned in pyproject).

viser has no way to stop the camera orbiting, set the browser tab's title, place notifications,
start a download without a second click, or send page events viser does not know (a palette entry
clicked or dropped on the canvas, text pasted from the clipboard, a grid cell edited). Each is a few lines
of JavaScript sent with viser's internal ``RunJavascriptMessage`` to one client (so nothing piles
up in the broadcast buffer that new clients replay).

The camera script reads ``window.__viserMutable.cameraControl``, the camera-controls instance viser
keeps for its own browser tests: once the server's top-down pose has arrived it freezes the polar
angle at a right angle and the azimuth at the nearest quarter turn (the view stays flat on the
canvas), maps left and right drag to panning, zooms toward the cursor, and turns the view back if
anything turns it (a pan was seen to turn it by 0.24 degrees).

The page script (``install_page``) defines ``window.flowmc``: ``send(kind, data)`` posts an event to
the server as a value of one text field, the page channel (viser's own ``GuiUpdateMessage`` for
that field, so the guard below checks it like any control; the script hides its row; a counter
makes every message new), and ``download(name, text)``. It moves viser's notifications to the
top of the right-hand column, over the palette (``NOTIFICATION_CSS``), where they cover no part of the
canvas, and points ``iframe[data-flowmc-port]`` at
the other name of this machine (``127.0.0.1`` <-> ``localhost``) with the frame's token in its
address and in viser's ``websocket`` parameter (a cross-site frame gets no cookie): the browser
runs a cross-site frame in its own process, so the 3D view's work never stalls the editor's canvas.
If a future viser renames these, the camera orbits again and the extras stop; nothing else depends
on them.
Pages are served with viser's client unpacked (``flowmc.ui.viser_client``: the page, its script and its
decoder are answered here, behind the guard, before viser's own file server would answer).
viser 1.1.1 has no hook to vet connections or client messages, so ``guarded_server`` adds two
small layers (``flowmc.ui.guard`` holds the policy; docs/security.md says why):
- every HTTP request and websocket handshake passes ``Guard.check`` first. viser starts its server
  inside ``ViserServer()`` with ``websockets.asyncio.server.serve(..., process_request=...)``, looked
  up through the ``websockets`` name of ``viser.infra._infra``; while one guarded server is being
  built (under a lock) that name points at a stand-in whose ``serve`` puts the guard in front of
  viser's own ``process_request`` and delegates everything else to the real package;
- messages from clients that viser would apply to server-side GUI state are filtered before viser's
  handlers see them: a GUI update may change only ``value`` (viser would ``setattr`` any field the
  client names, ``update_cb`` included), of a control that exists, is enabled and visible, to a value
  of the control's own type and range (a dropdown's options, a number's bounds); uploads are bounded.
If a future viser moves these, ``guarded_server`` raises instead of serving unguarded.
viser runs every callback (clicks, page events, camera moves, connects) on its thread pool, and its ``stop()``
closes every message buffer at once while callbacks started before it go on: a callback still rebuilding the
side panel then queues messages no page will get (viser warns "Queued a ... on a closed connection").
``guarded_server`` counts the callbacks going (``_Callbacks``, wrapping the pool's ``submit``) so that
``quiet`` can let them end, and start no more, before the server stops.
"""

from __future__ import annotations

import json
import math
import threading
import weakref
from concurrent.futures import Future
from typing import Any, Callable

import viser
import viser.infra._infra as _infra
from viser import _messages
from websockets.datastructures import Headers
from websockets.http11 import Response

from flowmc.ui import palette_list, viser_client
from flowmc.ui.guard import REFUSED_PAGE, Guard, Verdict

__all__ = ["guarded_server", "quiet", "lock_flat_camera", "fold_narrow_controls", "set_page_title", "install_page", "download",
           "run_js", "set_tips", "set_label_colors",
           "MAX_UPLOAD_BYTES", "CHANNEL_LABEL"]

MAX_UPLOAD_BYTES = 32 * 1024 * 1024  # a graph file is far smaller; G-code files are not uploaded
MAX_TEXT_VALUE = 1_000_000  # characters a text field may be set to
_SECURITY_HEADERS = {"Referrer-Policy": "no-referrer", "X-Content-Type-Options": "nosniff", "Cache-Control": "no-store"}
_build_lock = threading.Lock()
CHANNEL_LABEL = "flowmc page events"  # the text field the page script sends through (hidden)

# Notifications sit at the top of the right-hand column (the palette's place, as wide as the column), not
# over the canvas: a refusal never hides the ports it is about. They expire (``Editor.notify``), and
# clicks go through them to the palette below, except on their close buttons.
NOTIFICATION_CSS = (".mantine-Notifications-root { top: 44px !important; bottom: auto !important; left: auto !important; "
                    "right: 14px !important; width: 296px !important; max-width: 296px !important; transform: none !important; "
                    "pointer-events: none !important; } .mantine-Notifications-root * { pointer-events: none !important; } "
                    ".mantine-Notifications-root button { pointer-events: auto !important; }")

_PAGE_JS = """
(function flowmcPage(channel) {
  if (window.flowmc) { window.flowmc.channel = channel; window.flowmc.sendView(); return; }
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
  // The view's size in CSS pixels, now and on every change (a new server-side client needs it again): the
  // camera's image size is the drawing buffer's, which viser shrinks when frames are slow.
  let watched = null;
  flowmc.sendView = () => {
    const canvas = window.__viserMutable && window.__viserMutable.canvas;
    if (!canvas || !flowmc.send("view", { w: canvas.clientWidth, h: canvas.clientHeight })) {
      setTimeout(flowmc.sendView, 100);
      return;
    }
    if (canvas !== watched) {
      watched = canvas;
      new ResizeObserver(() => canvas === watched && flowmc.send("view", { w: canvas.clientWidth, h: canvas.clientHeight }))
        .observe(canvas);
    }
  };
  flowmc.sendView();
  setInterval(() => { const m = window.__viserMutable; if (m && m.canvas && m.canvas !== watched) flowmc.sendView(); }, 1000);
  flowmc.download = (name, text) => {
    const url = URL.createObjectURL(new Blob([text], { type: "application/octet-stream" }));
    const a = document.createElement("a");
    a.href = url; a.download = name; a.style.display = "none";
    document.body.appendChild(a); a.click(); a.remove();
    setTimeout(() => URL.revokeObjectURL(url), 60000);
  };
  const style = document.createElement("style");
  style.textContent = `NOTIFICATION_CSS`;
  document.head.appendChild(style);
  const otherHost = () => {
    const h = location.hostname;
    return h === "127.0.0.1" ? "localhost" : (h === "localhost" ? "127.0.0.1" : h);
  };
  const point = (frame) => {
    const at = otherHost() + ":" + frame.dataset.flowmcPort, token = encodeURIComponent(frame.dataset.flowmcToken || "");
    const socket = encodeURIComponent((location.protocol === "https:" ? "wss://" : "ws://") + at + "/?token=" + token);
    const src = location.protocol + "//" + at + "/?token=" + token + "&websocket=" + socket;
    if (frame.getAttribute("src") !== src) frame.setAttribute("src", src);
  };
  const hide = (label) => { if (label.textContent === LABEL) { const row = label.closest(".mantine-Flex-root");
    if (row) row.style.display = "none"; } };
  const refocus = (table) => {  // a grid redrawn after an edit: back to the cell that had the focus
    const f = flowmc.gridFocus;
    if (!f || table.dataset.flowmcGrid !== f.grid || (document.activeElement && document.activeElement !== document.body)) return;
    const el = cell(table, f.r, f.c);
    if (el) el.focus();
  };
  const pin = (b) => {  // the job panel's E-STOP (not the Device tab's) stays at the top while the panel scrolls
    if (b.textContent.trim() !== "E-STOP" || b.closest('[role="tabpanel"]') || !b.parentElement) return;
    Object.assign(b.parentElement.style, { position: "sticky", top: "0", zIndex: "5",
                                           background: "var(--mantine-color-body, white)" });
    b.dataset.flowmcEstop = "1";
    // overflow:hidden between it and the panel's scroller would hold it (sticky sticks to the nearest
    // scroll container); overflow:clip clips the same and is no scroll container
    for (let e = b.parentElement.parentElement; e && !e.classList.contains("mantine-ScrollArea-viewport"); e = e.parentElement)
      if (getComputedStyle(e).overflowY === "hidden") e.style.overflow = "clip"; };
  const scan = (root) => { if (!root.querySelectorAll) return;
    root.querySelectorAll("button").forEach(pin);
    root.querySelectorAll("iframe[data-flowmc-port]").forEach(point); root.querySelectorAll("label").forEach(hide);
    root.querySelectorAll("table[data-flowmc-grid]").forEach(refocus); };
  new MutationObserver(records => records.forEach(r => r.addedNodes.forEach(scan))).observe(document.body,
                                                                                          { childList: true, subtree: true });
  scan(document);
  const inField = (t) => t && t.closest && t.closest("input, textarea, select, [contenteditable]");
  const viewPoint = (e) => { const c = window.__viserMutable && window.__viserMutable.canvas; if (!c) return null;
    const r = c.getBoundingClientRect(); const u = (e.clientX - r.left) / r.width, v = (e.clientY - r.top) / r.height;
    return (u >= 0 && u <= 1 && v >= 0 && v <= 1) ? { u: u, v: v } : null; };
  const gridOf = (el) => el && el.closest && el.closest("table[data-flowmc-grid]");
  const cell = (g, r, c) => g.querySelector(`[data-r="${r}"][data-c="${c}"]`);
  const gridSend = (el, extra) =>
    flowmc.send("grid", Object.assign({ grid: gridOf(el).dataset.flowmcGrid, row: Number(el.dataset.r) }, extra));
  document.addEventListener("change", (e) => {  // a grid cell edited
    const t = e.target;
    if (gridOf(t) && t.dataset.c !== undefined)
      gridSend(t, { op: "set", col: t.dataset.c, value: t.type === "checkbox" ? String(t.checked) : t.value });
  }, true);
  document.addEventListener("click", (e) => {
    const b = e.target.closest && e.target.closest("button[data-act]");
    if (b && gridOf(b)) gridSend(b, { op: b.dataset.act });
    const map = e.target.closest && e.target.closest("svg[data-flowmc-minimap]");
    if (map) {  // the minimap: x0, y1 (world top-left) and pixels per world unit
      const [x0, y1, scale] = map.dataset.flowmcMinimap.split(",").map(Number), r = map.getBoundingClientRect();
      flowmc.send("minimap", { x: x0 + (e.clientX - r.left - 4) / scale, y: y1 - (e.clientY - r.top - 4) / scale });
    }
  }, true);
  document.addEventListener("focusin", (e) => {
    const g = gridOf(e.target);
    if (g && e.target.dataset.c !== undefined)
      flowmc.gridFocus = { grid: g.dataset.flowmcGrid, r: e.target.dataset.r, c: e.target.dataset.c };
  }, true);
  document.addEventListener("keydown", (e) => {  // arrows and Enter move between cells
    const t = e.target, g = gridOf(t);
    if (!g || t.dataset.c === undefined) return;
    const r = Number(t.dataset.r), cols = [...g.querySelectorAll(`[data-r="${r}"][data-c]`)], k = cols.indexOf(t);
    const text = t.tagName === "INPUT" && t.type !== "checkbox";
    let next = null;
    if (e.key === "ArrowDown" || e.key === "Enter") next = cell(g, r + 1, t.dataset.c);
    else if (e.key === "ArrowUp") next = cell(g, r - 1, t.dataset.c);
    else if (e.key === "ArrowLeft" && (!text || t.selectionStart === 0)) next = cols[k - 1];
    else if (e.key === "ArrowRight" && (!text || t.selectionEnd === t.value.length)) next = cols[k + 1];
    if (t.tagName === "SELECT" && (e.key === "ArrowDown" || e.key === "ArrowUp")) return;
    if (next) { e.preventDefault(); if (t.tagName === "INPUT" && text) t.dispatchEvent(new Event("change", { bubbles: true }));
      next.focus(); if (next.select) next.select(); }
  }, true);
  document.addEventListener("paste", (e) => {  // Ctrl+V on the canvas: the server pastes this text, or its own copy
    const text0 = (e.clipboardData && e.clipboardData.getData("text/plain")) || "";
    if (gridOf(e.target) && e.target.dataset.c !== undefined) {  // cells from a spreadsheet: fill the grid from here
      if (/[\\t\\n]/.test(text0.replace(/\\s+$/, ""))) {
        e.preventDefault();
        gridSend(e.target, { op: "paste", col: e.target.dataset.c, text: text0 });
      }
      return;
    }
    if (inField(e.target)) return;
    const text = (e.clipboardData && e.clipboardData.getData("text/plain")) || "";
    flowmc.send("paste", text.length <= 900000 ? text : "");
    e.preventDefault();
  });
  // buttons in flowmc's HTML (palette_list.page_button) send their event on a click; palette entries can
  // also be dragged onto the canvas
  const sender = (t, kind) => t && t.closest
    && t.closest(kind ? `button[data-flowmc-send="${kind}"]` : "button[data-flowmc-send]");
  let drag = null, dragEnd = 0;
  const entryOf = (t) => sender(t, "ADD_EVENT");
  document.addEventListener("pointerdown", (e) => {
    const entry = e.button === 0 && entryOf(e.target);
    if (entry) drag = { key: entry.dataset.flowmcKey, label: entry.textContent, x: e.clientX, y: e.clientY, ghost: null };
  }, true);
  document.addEventListener("pointermove", (e) => {
    if (drag && !drag.ghost && Math.hypot(e.clientX - drag.x, e.clientY - drag.y) > 8) {
      const g = drag.ghost = document.createElement("div");
      g.textContent = drag.label;
      g.style.cssText = "position:fixed;z-index:10000;pointer-events:none;padding:4px 10px;border-radius:4px;" +
        "background:#228be6;color:#fff;font:13px sans-serif;box-shadow:0 2px 6px rgba(0,0,0,.3)";
      document.body.appendChild(g);
    }
    if (drag && drag.ghost) { drag.ghost.style.left = (e.clientX + 10) + "px"; drag.ghost.style.top = (e.clientY + 10) + "px"; }
    tip(e);
  }, true);
  document.addEventListener("pointerup", (e) => {
    const d = drag; drag = null;
    if (!d || !d.ghost) return;
    d.ghost.remove();
    dragEnd = performance.now();  // a drag let go over its own entry is no click
    const at = viewPoint(e);
    if (at) flowmc.send("palette-drop", { key: d.key, u: at.u, v: at.v });
  }, true);
  document.addEventListener("click", (e) => {
    const b = sender(e.target);
    if (b && performance.now() - dragEnd > 100) flowmc.send(b.dataset.flowmcSend, { key: b.dataset.flowmcKey });
  });
  flowmc.tips = [];  // [x0, y0, x1, y1, text]: canvas rectangles (world units) whose full text shows on hover
  const tip = (e) => {
    const m = window.__viserMutable, c = m && m.canvas, body = m && m.nodeRefFromName && m.nodeRefFromName["/canvas/body"];
    if (!c || !body || !body.parent || e.target !== c) return;
    const r = c.getBoundingClientRect(), V = m.camera.position.constructor;
    const screen = (x, y) => { const v = new V(x, y, 0); body.parent.localToWorld(v); v.project(m.camera);
      return [r.left + (v.x + 1) / 2 * r.width, r.top + (1 - v.y) / 2 * r.height]; };
    let text = "";
    for (const [x0, y0, x1, y1, t] of flowmc.tips) {
      const [a, b] = screen(x0, y1), [cx, cy] = screen(x1, y0);
      if (e.clientX >= a && e.clientX <= cx && e.clientY >= b && e.clientY <= cy) { text = t; break; }
    }
    if (c.title !== text) c.title = text;
  };
})(CHANNEL);
"""

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


# viser lays its controls out as a sheet over the lower part of the scene when the page is narrow (the
# 3D view docked beside the editor is): fold it to its title bar once, so the toolpath is seen whole;
# a click on the bar ("Connected", viser's status line) opens it again.
_FOLD_NARROW_JS = """
(function flowmcFold() {
  if (window.__flowmcFolded) return;
  let tries = 0;
  const go = () => {
    if (window.innerWidth >= 700) return;
    const bar = [...document.querySelectorAll("div")].find(d => d.childElementCount === 0
      && d.textContent.trim() === "Connected" && d.getBoundingClientRect().height > 0);
    if (bar) { window.__flowmcFolded = true; bar.click(); return; }
    if (++tries < 150) setTimeout(go, 100);
  };
  go();
})();
"""


def fold_narrow_controls(client: Any) -> None:
    """In a narrow page (under 700 px), fold viser's control sheet so that the scene shows whole."""
    _send(client, _FOLD_NARROW_JS)


def run_js(client: Any, source: str) -> None:
    """Run ``source`` in ``client``'s page."""
    _send(client, source)


def install_page(client: Any, channel: Any) -> None:
    """``window.flowmc`` in ``client``'s page; its events arrive as updates of the text field ``channel``
    (labelled ``CHANNEL_LABEL``, which the script hides)."""
    source = (_PAGE_JS.replace("CHANNEL", json.dumps(channel._impl.uuid)).replace("LABEL", json.dumps(CHANNEL_LABEL))
              .replace("NOTIFICATION_CSS", NOTIFICATION_CSS).replace("ADD_EVENT", palette_list.ADD_EVENT))
    _send(client, source)


def set_tips(client: Any, tips: list[tuple[float, float, float, float, str]]) -> None:
    """Hover texts for canvas rectangles (world xmin, ymin, xmax, ymax): the full titles of cut node titles."""
    _send(client, f"window.flowmc && (window.flowmc.tips = {json.dumps(tips)});")


# viser draws every label with black ink on a white, 85 % opaque backing (two fixed fragment shaders): on the dark
# canvas that is a white box on every node. This recolours those two shaders in the label materials (found by
# their source, kept in userData so a theme change can recolour again), now and for materials made later.
_LABEL_COLORS_JS = """
(function flowmcLabels(ink, back) {
  const f = window.flowmc = window.flowmc || {};
  f.labelColors = { ink: ink, back: back };
  const INK = "gl_FragColor = vec4(0.0, 0.0, 0.0, a);", BACK = "gl_FragColor = vec4(1.0, 1.0, 1.0, 0.85 * vAlpha);";
  const rgb = (c) => c.slice(0, 3).map(v => (v / 255).toFixed(4)).join(", ");
  f.paintLabels = () => {
    const m = window.__viserMutable, c = f.labelColors;
    if (!m || !m.scene || !c) return;
    let changed = false;
    m.scene.traverse(o => {
      const mat = o.material;
      if (!mat || typeof mat.fragmentShader !== "string") return;
      const orig = mat.userData.flowmcLabel || mat.fragmentShader;
      let want = null;
      if (orig.includes(INK)) want = orig.replace(INK, `gl_FragColor = vec4(${rgb(c.ink)}, a);`);
      else if (orig.includes(BACK))
        want = orig.replace(BACK, `gl_FragColor = vec4(${rgb(c.back)}, ${(c.back[3] / 255).toFixed(4)} * vAlpha);`);
      if (want === null) return;
      mat.userData.flowmcLabel = orig;
      if (mat.fragmentShader !== want) { mat.fragmentShader = want; mat.needsUpdate = true; changed = true; }
    });
    if (changed && m.requestRender) m.requestRender();
  };
  if (!f.labelTimer) f.labelTimer = setInterval(f.paintLabels, 400);  // labels made later get the colours too
  f.paintLabels();
})(INK_RGB, BACK_RGBA);
"""


def set_label_colors(client: Any, ink: tuple[int, int, int], back: tuple[int, int, int, int]) -> None:
    """Canvas labels in ``client``'s page with ``ink`` text on a ``back`` (RGBA, 0-255) backing."""
    _send(client, _LABEL_COLORS_JS.replace("INK_RGB", json.dumps(list(ink))).replace("BACK_RGBA", json.dumps(list(back))))


def download(client: Any, name: str, text: str) -> None:
    """Save ``text`` as the file ``name`` in ``client``'s browser at once (viser's own download asks twice)."""
    _send(client, f"window.flowmc && window.flowmc.download({json.dumps(name)}, {json.dumps(text)});")


# ---------------------------------------------------------------------------------------- the guard
class _Namespace:
    """Stands in for a module: ``overrides`` first, then the real module's attributes."""

    def __init__(self, real: Any, **overrides: Any):
        self._real = real
        self.__dict__.update(overrides)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._real, name)


def _set_header(headers: Headers, key: str, value: str) -> None:
    """One value for ``key`` (assigning to websockets' ``Headers`` adds a value beside those it holds)."""
    if key in headers:
        del headers[key]
    headers[key] = value


def _guarded_process_request(guard: Guard, inner: Callable[..., Any] | None) -> Callable[..., Any]:
    def process_request(connection: Any, request: Any) -> Any:
        port = connection.local_address[1]
        headers = request.headers
        if any(len(headers.get_all(name)) > 1 for name in ("Host", "Origin")):
            verdict = Verdict(False, 403, "repeated Host or Origin header")
        else:
            verdict = guard.check({k: "; ".join(headers.get_all(k)) for k in ("Host", "Origin", "Cookie")
                                   if headers.get_all(k)}, request.path, port)
        if not verdict.ok:
            response = connection.respond(verdict.status, REFUSED_PAGE.format(reason=verdict.reason))
            for key, value in _SECURITY_HEADERS.items():
                _set_header(response.headers, key, value)
            return response
        response = _client_response(guard, request)
        if response is None:
            response = inner(connection, request) if inner is not None else None
        if response is not None:  # a page or file (a websocket handshake returns None and goes on)
            kept = response.headers.get("Cache-Control") == viser_client.CACHE  # viser_client's script and decoder
            for key, value in _SECURITY_HEADERS.items():
                if not (kept and key == "Cache-Control"):
                    _set_header(response.headers, key, value)
            if verdict.set_cookie:
                response.headers["Set-Cookie"] = guard.set_cookie(port)
        return response

    return process_request


def _client_response(guard: Guard, request: Any) -> Response | None:
    """viser's client as ``viser_client`` serves it (the page, its script and decoder), or None: viser answers."""
    if request.headers.get("Upgrade") == "websocket":
        return None
    path = request.path.partition("?")[0]
    text = viser_client.page(guard.token) if path in ("/", "/index.html") else None
    asset = viser_client.Asset("text/html; charset=utf-8", text.encode("utf-8"), None) if text is not None \
        else viser_client.asset(path)
    if asset is None:
        return None
    zipped = asset.gzipped if "gzip" in request.headers.get("Accept-Encoding", "") else None
    body = zipped if zipped is not None else asset.body
    headers = Headers({"Content-Type": asset.content_type, "Vary": "Accept-Encoding"})
    if asset.digest:
        headers["ETag"], headers["Cache-Control"] = f'W/"{asset.digest}"', viser_client.CACHE  # weak: gzip or not
        if f'"{asset.digest}"' in request.headers.get("If-None-Match", ""):
            return Response(304, "Not Modified", headers, b"")
    headers["Content-Length"] = str(len(body))
    if zipped is not None:
        headers["Content-Encoding"] = "gzip"
    return Response(200, "OK", headers, body)


def guarded_server(guard: Guard, **kwargs: Any) -> viser.ViserServer:
    """``viser.ViserServer(**kwargs)`` that answers only requests passing ``guard`` and lets clients
    change only the values of enabled, visible controls."""
    real = _infra.websockets
    real_serve = real.asyncio.server.serve
    used: list[bool] = []

    def serve(handler: Any, *args: Any, process_request: Any = None, **options: Any) -> Any:
        used.append(True)
        return real_serve(handler, *args, process_request=_guarded_process_request(guard, process_request), **options)

    stand_in = _Namespace(real, asyncio=_Namespace(real.asyncio, server=_Namespace(real.asyncio.server, serve=serve)))
    with _build_lock:
        _infra.websockets = stand_in
        try:
            server = viser.ViserServer(**kwargs)
        finally:
            _infra.websockets = real
    if not used:
        server.stop()
        raise RuntimeError("viser did not start its server through websockets.asyncio.server.serve: "
                           "flowmc cannot guard this viser version")
    _filter_client_messages(server)
    _callbacks[server] = _Callbacks(server._thread_executor)
    # The served client starts with neither (viser_client); the server's state says the same to every page.
    server.scene.configure_default_lights(False)
    server.scene.configure_environment_map(None)
    threading.Thread(target=viser_client.files, name="flowmc-client-unpack", daemon=True).start()
    return server


def quiet(server: viser.ViserServer, timeout: float = 10.0) -> None:
    """Start no more callbacks on ``server`` (made by ``guarded_server``) and wait up to ``timeout`` seconds
    for those started or waiting to end (a stuck one is left behind). Called before ``server.stop()``."""
    _callbacks[server].quiet(timeout)


class _Callbacks:
    """The callbacks going on one server's thread pool (``pool.submit`` goes through ``submit``)."""

    def __init__(self, pool: Any):
        self._submit = pool.submit
        self._changed = threading.Condition()
        self._going = 0
        self._closing = False
        pool.submit = self.submit

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        with self._changed:
            if self._closing:  # the server is about to stop: the callback would talk to no page
                dropped: Future = Future()
                dropped.set_result(None)
                return dropped
            self._going += 1
        try:
            return self._submit(self._run, fn, *args, **kwargs)
        except BaseException:
            self._ended()
            raise

    def _run(self, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
        try:
            return fn(*args, **kwargs)
        finally:
            self._ended()

    def _ended(self) -> None:
        with self._changed:
            self._going -= 1
            self._changed.notify_all()

    def quiet(self, timeout: float) -> None:
        with self._changed:
            self._closing = True
            self._changed.wait_for(lambda: self._going == 0, timeout)


_callbacks: "weakref.WeakKeyDictionary[viser.ViserServer, _Callbacks]" = weakref.WeakKeyDictionary()


# ---------------------------------------------------------------------------------------- client messages
def _input_handle(gui: Any, uuid: str) -> Any:
    return gui._gui_input_handle_from_uuid.get(uuid) if gui is not None else None


def _same_kind(current: Any, new: Any) -> bool:
    """``new`` is a value of the kind ``current`` is (bool, finite number, bounded text, tuple of those)."""
    if isinstance(current, bool):
        return isinstance(new, bool)
    if isinstance(current, (int, float)):
        return isinstance(new, (int, float)) and not isinstance(new, bool) and math.isfinite(new)
    if isinstance(current, str):
        return isinstance(new, str) and len(new) <= MAX_TEXT_VALUE
    if isinstance(current, tuple):
        return (isinstance(new, (list, tuple)) and len(new) == len(current)
                and all(_same_kind(c, n) for c, n in zip(current, new)))
    return current is None and new is None


def _in_range(handle: Any, value: Any) -> bool:
    options = getattr(handle, "options", None)
    if isinstance(options, tuple) and isinstance(value, str) and value not in options:
        return False
    low, high = getattr(handle, "min", None), getattr(handle, "max", None)
    values = value if isinstance(value, (list, tuple)) else (value,)
    lows = low if isinstance(low, tuple) else (low,) * len(values)
    highs = high if isinstance(high, tuple) else (high,) * len(values)
    for v, lo, hi in zip(values, lows, highs):
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            if (isinstance(lo, (int, float)) and v < lo) or (isinstance(hi, (int, float)) and v > hi):
                return False
    return True


def update_allowed(gui: Any, message: Any) -> bool:
    """May a client's ``GuiUpdateMessage`` reach ``gui`` (the GUI that owns the control)?"""
    handle = _input_handle(gui, message.uuid)
    if handle is None:
        return True  # not this GUI's control: viser ignores it
    updates = message.updates
    if not isinstance(updates, dict) or set(updates) != {"value"}:
        return False
    if handle._impl.removed or handle.disabled or not handle.visible:
        return False
    new, current = updates["value"], handle._impl.value
    if handle._impl.is_button:  # a button sends True, a button group one of its options
        options = getattr(handle, "options", None)
        return isinstance(new, str) and new in options if isinstance(options, tuple) else new is True
    return _same_kind(current, new) and _in_range(handle, new)


def _upload_allowed(gui: Any, message: Any) -> bool:
    if isinstance(message, _messages.FileTransferStartUpload):
        handle = _input_handle(gui, message.source_component_uuid)
        if handle is None:
            return True
        return (not handle.disabled and handle.visible and 0 <= message.size_bytes <= MAX_UPLOAD_BYTES
                and 0 <= message.part_count <= max(1, message.size_bytes))
    state = gui._current_file_upload_states.get(message.transfer_uuid) if gui is not None else None
    return state is None or state["transferred_bytes"] + len(message.content) <= state["total_bytes"]


def _filter(handler: Any, gui_of: Callable[[int], Any]) -> None:
    """Wrap ``handler``'s incoming-message dispatch (a viser websocket server or client connection) so
    messages that would change server-side state they may not change are dropped."""
    dispatch = handler._handle_incoming_message

    async def filtered(client_id: Any, message: Any) -> None:
        if isinstance(message, _messages.GuiUpdateMessage):
            if not update_allowed(gui_of(client_id), message):
                return
        elif isinstance(message, (_messages.FileTransferStartUpload, _messages.FileTransferPart)):
            if not _upload_allowed(gui_of(client_id), message):
                return
        await dispatch(client_id, message)

    handler._handle_incoming_message = filtered


def _filter_client_messages(server: viser.ViserServer) -> None:
    infra_server = server._websock_server
    _filter(infra_server, lambda _cid: server.gui)

    def per_client(connection: Any) -> None:
        def client_gui(cid: Any) -> Any:
            client = server._connected_clients.get(cid)
            return client.gui if client is not None else None
        _filter(connection, client_gui)

    infra_server.on_client_connect(per_client)
