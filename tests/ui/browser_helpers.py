"""Driving the editor page in Debian's chromium with playwright (shared by the browser tests and
benchmarks/editor.py). Scene facts come from ``window.__viserMutable``, which viser keeps in its
production build for its own browser tests: ``nodeRefFromName`` (three.js objects by scene name),
``camera`` and ``canvas`` (to turn world points into page pixels). Batched meshes are three.ez
``InstancedMesh2``: ``instancesCount`` is how many there are (``count`` is how many are on screen)."""

from __future__ import annotations

import contextlib
import re
import time
from typing import Any, Iterator

import numpy as np
from playwright.sync_api import Browser, BrowserContext, Page, sync_playwright

from flowmc.ui import camera, canvas_draw

CHROMIUM = "/usr/bin/chromium"
# Chromium 156's headless mode builds the address bar's suggestion popup (a WebUI page in a renderer of its own)
# for every new window: about 1.3 s of CPU while the editor's page loads beside it on this 2-core machine, work a
# person's browser did once when its window opened. Puppeteer turns the two features off by default for the same reason.
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync",
        "--disable-features=WebUIOmniboxPopup,WebUIOmniboxAimPopup"]
VIEWPORT = {"width": 1600, "height": 1000}


@contextlib.contextmanager
def chromium() -> Iterator[Browser]:
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        try:
            yield browser
        finally:
            browser.close()


_INSTANCES = """(name) => { const o = window.__viserMutable?.nodeRefFromName?.[name]; if (!o) return -1;
  let m = null; o.traverse(c => { if (c.isInstancedMesh && !m) m = c; }); return m ? (m.instancesCount ?? m.count) : -1; }"""

def opened(count: int) -> str:
    """The page holds ``count`` node bodies and its camera is locked: an open is done at the frame where both hold
    (one condition, so that its polling adds no frame of its own: with two waits in turn, each polled on the
    page's frames, one open ended up to two frames after the drawing)."""
    return f"() => ({_INSTANCES})('/canvas/body') === {count} && window.__flowmcCameraLocked === true"


# The frame after: by its start the frame in which a condition held has been drawn.
NEXT_FRAME = "() => new Promise(resolve => requestAnimationFrame(() => resolve()))"

_COLORS = """(name) => { const o = window.__viserMutable.nodeRefFromName[name]; let m = null;
  o.traverse(c => { if (c.isInstancedMesh && !m) m = c; }); const C = m.material.color.constructor; const out = [];
  for (let i = 0; i < (m.instancesCount ?? m.count); i++) { const c = new C(); m.getColorAt(i, c); out.push([c.r, c.g, c.b]); } return out; }"""

_POSITIONS = """(name) => { const o = window.__viserMutable.nodeRefFromName[name]; let m = null;
  o.traverse(c => { if (c.isInstancedMesh && !m) m = c; }); const M = m.matrix.constructor; const out = [];
  for (let i = 0; i < (m.instancesCount ?? m.count); i++) { const t = new M(); m.getMatrixAt(i, t); out.push([t.elements[12], t.elements[13]]); }
  return out; }"""

_PROJECT = """([x, y]) => { const m = window.__viserMutable; const o = m.nodeRefFromName['/canvas/body'];
  const V = m.camera.position.constructor; const v = new V(x, y, 0); o.parent.localToWorld(v); v.project(m.camera);
  const r = m.canvas.getBoundingClientRect(); return [r.left + (v.x + 1) / 2 * r.width, r.top + (1 - v.y) / 2 * r.height]; }"""


_STILL = """() => new Promise(resolve => {
  const m = window.__viserMutable, key = () => { const r = m.canvas.getBoundingClientRect();
    return JSON.stringify([Math.round(r.left), Math.round(r.width), Math.round(r.height), m.camera.position.toArray().map(v => v.toFixed(4))]); };
  let last = key(), same = 0;
  const check = () => { const now = key(); same = now === last ? same + 1 : 0; last = now;
    if (same >= 6) resolve(true); else setTimeout(check, 60); };
  setTimeout(check, 60);
})"""


class EditorPage:
    """One browser tab on an Editor running in this process."""

    def __init__(self, browser: Browser | BrowserContext, editor: Any):
        """A new tab: in a fresh context of its own (``browser``), or beside others in ``BrowserContext``, whose
        cache it shares (made with ``viewport=VIEWPORT``)."""
        self.editor = editor
        self.page: Page = browser.new_page(viewport=VIEWPORT) if isinstance(browser, Browser) else browser.new_page()

    def open(self, timeout: float = 30.0, query: str = "") -> float:
        """Load the page (``query``: more URL parameters, e.g. viser's ``fixedDpr=0.75``); returns seconds
        until the frame in which every node is in the scene and the camera is locked has been drawn."""
        start = time.perf_counter()
        self.page.goto(self.editor.url + (f"&{query}" if query else ""))
        self.page.wait_for_function(opened(len(self.editor.canvas.boxes)), timeout=timeout * 1000)
        self.page.evaluate(NEXT_FRAME)
        return time.perf_counter() - start

    def settled(self, timeout: float = 15.0) -> None:
        """Wait until the page's layout and the camera stop moving (panels dock and the view is framed
        again while the page settles): clicks aimed from the scene's geometry then land where meant."""
        self.page.wait_for_function(_STILL, timeout=timeout * 1000)

    def framed(self, timeout: float = 30.0) -> None:
        """Wait until the server has the view's present size and the camera is where its framing put it,
        then until the page settles: a resize is answered by the server, which under load can lag."""
        seen: list[Any] = []

        def answered() -> bool:
            size = self.page.evaluate("[window.__viserMutable.canvas.clientWidth, window.__viserMutable.canvas.clientHeight]")
            cam = next(iter(self.editor.server.get_clients().values())).camera
            seen[:] = [size, list(camera.view_px(cam)), np.round(cam.position, 3)]
            return seen[0] == seen[1] and camera.framed_here(cam.client, cam.position)
        try:
            wait_until(answered, timeout, "the server framing the view's present size")
        except AssertionError as err:
            raise AssertionError(f"{err}: page size, server size, server camera = {seen}") from None
        self.settled(timeout)

    def wait_nodes(self, count: int, timeout: float = 30.0) -> None:
        """Wait until the scene holds ``count`` node bodies (nodes and interface terminals)."""
        self.page.wait_for_function(f"({_INSTANCES})('/canvas/body') === {count}", timeout=timeout * 1000)

    def wait_ports(self, timeout: float = 30.0) -> None:
        """Wait until the scene's port squares are those of the editor's current boxes (they follow the bodies,
        so a drag that starts at a new port right after ``wait_nodes`` could still meet the old ones)."""
        count = sum(len(b.inputs) + len(b.outputs) for b in self.editor.canvas.boxes)
        self.page.wait_for_function(f"({_INSTANCES})('/canvas/ports') === {count}", timeout=timeout * 1000)
        self.settled()

    def dismiss_toasts(self) -> None:
        """Close the 'Software WebGL' notice (it covers the top left of the canvas), then wait for the page to settle."""
        for frame in self.page.frames:
            toast = frame.locator(".mantine-Notification-root", has_text="Software WebGL")
            for k in range(toast.count()):
                with contextlib.suppress(Exception):
                    toast.nth(k).locator("button").first.click(timeout=2000)
        self.settled()

    def field(self, label: str) -> Any:
        """The input beside a side-panel label (viser puts them in one row; its label's ``for`` misses)."""
        target = self.page.locator("label", has_text=re.compile(f"^{re.escape(label)}$")).first
        target.wait_for(timeout=10000)
        row = target.locator("xpath=ancestor::div[contains(@class, 'mantine-Flex-root')][1]")
        return row.locator("input, textarea").first

    def settle(self, frames: int = 2) -> None:
        self.page.evaluate(f"() => new Promise(r => {{ let n = {frames}; const f = () => --n ? requestAnimationFrame(f) : r(); requestAnimationFrame(f); }})")

    def body_colors(self) -> np.ndarray:
        """Each node body's colour as the scene holds it (0..1, linear, in graph order)."""
        return np.asarray(self.page.evaluate(_COLORS, "/canvas/body"))

    def body_positions(self) -> np.ndarray:
        """Each node body's top-left corner (world x, y) as the scene holds it."""
        return np.asarray(self.page.evaluate(_POSITIONS, "/canvas/body"))

    def frame_colors(self) -> np.ndarray:
        return np.asarray(self.page.evaluate(_COLORS, "/canvas/frame"))

    def screen(self, x: float, y: float) -> tuple[float, float]:
        sx, sy = self.page.evaluate(_PROJECT, [float(x), float(y)])
        return sx, sy

    def box(self, node_id: str) -> Any:
        return next(b for b in self.editor.canvas.boxes if b.node_id == node_id)

    def click_world(self, x: float, y: float) -> None:
        self.page.mouse.click(*self.screen(x, y))

    def click_node(self, node_id: str) -> None:
        box = self.box(node_id)
        self.click_world(box.x + box.w * 0.6, box.y - box.h * 0.6)

    def click_port(self, node_id: str, kind: str, port: str) -> None:
        spot = self.box(node_id).port(kind, port)
        self.click_world(spot.x, spot.y)

    def wire(self, src: str, dst: str) -> None:
        """Click the output ``src``, then the input ``dst`` ("node.port"), as a person would: the second click
        only once the editor has the first port picked. Under load a click can go unanswered (CI saw one wire
        of three missing, its two clicks 10 ms apart); one more click then, as a person would, and a clear
        failure if that is lost too."""
        (sn, sp), (dn, dp) = src.split("."), dst.split(".")
        canvas = self.editor.canvas

        def picked() -> bool:
            hit = canvas.pending
            return hit is not None and hit.port is not None and (hit.node_id, hit.port.name, hit.port.kind) == (sn, sp, "out")
        self.settled()
        for attempt in range(2):
            self.click_port(sn, "out", sp)
            try:
                wait_until(picked, 5.0 if attempt == 0 else 15.0, f"the editor to pick {src} (a click on it)")
                break
            except AssertionError:
                if attempt:
                    raise
        self.click_port(dn, "in", dp)


def expected(color: tuple[int, int, int]) -> np.ndarray:
    """What the scene holds for a colour the canvas asked for (it sends linear values)."""
    return canvas_draw.mesh_rgb(color) / 255.0


def wait_until(check: Any, timeout: float = 20.0, what: str = "condition") -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if check():
            return
        time.sleep(0.03)
    raise AssertionError(f"timed out waiting for {what}")
