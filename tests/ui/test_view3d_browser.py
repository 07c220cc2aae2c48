"""One real-browser check: headless Chromium renders the 3D view's trajectory (Debian's /usr/bin/chromium)."""

from __future__ import annotations

import io

import numpy as np
import pytest
from PIL import Image
from playwright.sync_api import sync_playwright

import flowmc
from flowmc.motion.machine import Machine
from flowmc.ui import view3d_data as data
from flowmc.ui.view3d import ToolpathView

pytestmark = pytest.mark.browser

CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--disable-features=WebUIOmniboxPopup,WebUIOmniboxAimPopup"]  # as browser_helpers.ARGS says why


def _reddish(img: np.ndarray) -> np.ndarray:
    """Pixels near the top-speed red of the speed colour scale (cruise segments are drawn in it)."""
    r, g, b = (img[..., i].astype(int) for i in range(3))
    red = data.SPEED_STOPS[-1][1]
    return (np.abs(r - red[0]) < 40) & (g < 90) & (b < 90)


def test_browser_renders_the_trajectory(tmp_path):
    g = flowmc.GraphBuilder(title="browser")
    square = g.add("path.polyline", id="square", points=[(0, 0, 0), (60, 0, 0), (60, 40, 0), (0, 40, 0)],
                   feed=50.0, closed=True)
    plan = g.add("interp.time_division", id="plan", profile="trapezoid")
    g.wire(square.path, plan.path)
    graph = g.build()
    result = flowmc.Runtime().run(graph)
    assert result.ok, result.errors
    view = ToolpathView()
    try:
        view.show([result.output("square", "path")], [result.output("plan", "trajectory")], Machine())
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path="/usr/bin/chromium", args=CHROMIUM_ARGS)
            try:
                page = browser.new_page(viewport={"width": 1000, "height": 700})
                page.goto(view.url, timeout=30_000)
                page.wait_for_function("window.__viserMutable?.nodeRefFromName['/trajectory/0'] != null",
                                       timeout=30_000)
                page.wait_for_function("window.__viserMutable?.nodeRefFromName['/machine/travel'] != null",
                                       timeout=10_000)
                for _ in range(20):  # a few frames for the lines to be drawn (more on a busy machine)
                    page.wait_for_timeout(500)
                    png = page.screenshot(path=str(tmp_path / "view3d.png"))  # kept for a look when it fails
                    shot = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))
                    if _reddish(shot[:, : shot.shape[1] // 2]).sum() > 200:
                        break
            finally:
                browser.close()
    finally:
        view.close()
    img = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))
    scene = img[:, : img.shape[1] // 2]  # the control panel is docked on the right
    assert scene.std() > 5.0, "the scene is blank"
    assert _reddish(scene).sum() > 200, "no pixels in the trajectory's top-speed colour"


def test_a_narrow_view_folds_its_controls_so_the_scene_shows_whole():
    """Docked beside the editor the view is about 460 px wide: viser then lays its controls over the lower
    scene; they start folded to their bar, and a click on the bar opens them."""
    view = ToolpathView()
    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path="/usr/bin/chromium", args=CHROMIUM_ARGS)
            try:
                page = browser.new_page(viewport={"width": 460, "height": 890})
                page.goto(view.url, timeout=30_000)
                page.wait_for_function("window.__flowmcFolded === true", timeout=30_000)
                playback = page.get_by_text("Playback", exact=True).first
                page.wait_for_timeout(1500)  # the fold's animation
                assert not playback.is_visible()
                page.get_by_text("Connected", exact=True).first.click()
                playback.wait_for(state="visible", timeout=10_000)
            finally:
                browser.close()
    finally:
        view.close()
