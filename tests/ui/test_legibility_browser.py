"""What a person reads on the canvas, in a real browser (Debian's chromium via playwright): node titles stay
legible when the docked 3D view opens after the first Run, and the dark theme's labels are light on dark."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from browser_helpers import EditorPage, chromium, wait_until
from editor_graphs import example_file
from flowmc.ui import camera, canvas, canvas_draw, layout
from flowmc.ui.app import Editor

pytestmark = pytest.mark.browser

ROOT = Path(__file__).resolve().parents[2]
BRIGHT_MAX = 0.05


@pytest.fixture(scope="module")
def browser():
    with chromium() as b:
        yield b


def _title_px(editor: Editor) -> float:
    client = next(iter(editor.server.get_clients().values()))
    return layout.TITLE_FONT * layout.SCALE * (camera.screen_px_per_world(client.camera) or 0.0)


@pytest.mark.parametrize("query", ["", "fixedDpr=0.75"], ids=["adaptive", "slow-gpu"])
def test_titles_stay_legible_when_the_3d_view_opens(browser, tmp_path, query):
    """``slow-gpu``: the drawing buffer at 0.75 of the page's pixels, where viser's adaptive resolution goes
    when frames are slow (software WebGL under load); framing by its size zoomed the graph out."""
    editor = Editor(ROOT / "graphs" / "thesis_3axis.flowmc.json", port=0, folder=tmp_path)
    ui = EditorPage(browser, editor)
    try:
        ui.open(timeout=90, query=query)
        ui.dismiss_toasts()
        width = ui.page.evaluate("window.__viserMutable.canvas.clientWidth")
        ui.page.get_by_role("button", name="Run", exact=True).click()
        wait_until(lambda: editor.last_result is not None and editor.extensions.view_open, 90, "the run and the 3D view")
        ui.page.wait_for_function(f"window.__viserMutable.canvas.clientWidth < {width - 200}", timeout=30000)
        ui.settled(30)
        ui.framed(30)
        assert _title_px(editor) >= canvas.MIN_TITLE_PX - 0.05
        first = min(editor.canvas.boxes, key=lambda b: b.x)  # the sources stay in view
        x, y = ui.screen(first.x, first.y)
        assert 0 <= x <= ui.page.evaluate("window.__viserMutable.canvas.getBoundingClientRect().right") and y >= 0
    finally:
        ui.page.close()
        editor.close()


def test_dark_theme_labels_are_light_on_a_dark_backing(browser, tmp_path):
    editor = Editor(example_file(tmp_path), port=0)
    ui = EditorPage(browser, editor)
    try:
        ui.open(timeout=60)
        ui.dismiss_toasts()
        box = ui.box("table")
        (x0, y0), (x1, y1) = ui.screen(box.x, box.y), ui.screen(box.x + box.w, box.y - box.h)

        def bright_share() -> float:  # light pixels on the node: glyphs only, or whole white label backings
            shot = np.asarray(Image.open(io.BytesIO(ui.page.screenshot())).convert("RGB")).astype(int)
            region = shot[int(y0) + 2:int(y1) - 2, int(x0) + 2:int(x1) - 2]
            return float((region.min(axis=2) > 200).mean())

        editor.dark.value = True
        ink = ", ".join(f"{v / 255:.4f}" for v in canvas_draw.DARK.label_ink)
        ui.page.wait_for_function(f"""() => {{ let n = 0; window.__viserMutable.scene.traverse(o => {{
            if (o.material && o.material.userData.flowmcLabel && o.material.fragmentShader.includes({ink!r})) n += 1; }});
            return n > 0; }}""", timeout=15000)
        ui.page.wait_for_timeout(1500)
        dark = bright_share()
        assert dark < BRIGHT_MAX, dark
        ui.page.screenshot(path=str(tmp_path / "dark.png"))
    finally:
        ui.page.close()
        editor.close()
