"""End to end in a real browser (Debian's chromium driven by playwright): the editor page on an
example graph, used the way a person would: palette, wiring clicks, Run, Save, reload."""

from __future__ import annotations

import io
import re

import numpy as np
import pytest
from PIL import Image

import flowmc
from browser_helpers import EditorPage, expected, wait_until
from editor_graphs import example_file
from flowmc.ui import camera, canvas_draw
from flowmc.ui.app import Editor

pytestmark = pytest.mark.browser

DONE = expected(canvas_draw.STATUS_COLORS["done"])


@pytest.fixture
def editor(tmp_path, open_editor):
    return open_editor(example_file(tmp_path))


def add_from_palette(ui: EditorPage, query: str, button: str) -> str:
    page, before = ui.page, len(ui.editor.canvas.boxes)
    ui.field("Search").fill(query)
    page.get_by_role("button", name=button, exact=True).click()
    ui.wait_nodes(before + 1)
    return ui.editor.state.graph.nodes[-1].id


def not_blank(image: np.ndarray) -> float:
    """Share of pixels that differ clearly from the background (the most common colour)."""
    rgb = np.asarray(image)[..., :3].astype(int)
    colours, counts = np.unique(rgb.reshape(-1, 3), axis=0, return_counts=True)
    background = colours[np.argmax(counts)]
    return float(np.mean(np.abs(rgb - background).max(axis=-1) > 40))


def test_palette_wire_run_3d_view_save_and_reload(browser, editor, tmp_path):
    ui = EditorPage(browser, editor)
    ui.open()
    ui.dismiss_toasts()
    page = ui.page
    assert page.get_by_role("button", name="Translate", exact=True).is_visible()  # the palette shows on load
    shift2 = add_from_palette(ui, "translate", "Translate")
    line = add_from_palette(ui, "polyline", "Polyline")
    join = add_from_palette(ui, "join", "Join")
    assert [editor.state.node(n).type for n in (shift2, line, join)] == ["path.translate", "path.polyline", "path.join"]
    page.get_by_role("button", name="Fit", exact=True).click()
    ui.settled()

    for src, dst in ((f"{line}.path", f"{shift2}.path"), (f"{shift2}.path", f"{join}.path1"), ("both.path", f"{join}.path2")):
        ui.wire(src, dst)
        wait_until(lambda: (src, dst) in {(w.from_, w.to) for w in editor.state.graph.wires}, what=f"wire {src} -> {dst}")

    before = len(editor.state.graph.wires)
    ui.wire(f"{line}.path", f"{shift2}.dx")  # a Path into a Number param: refused
    page.get_by_text(re.compile(r"is a Path, but input 'dx'.*takes Number")).filter(visible=True).first.wait_for(timeout=10000)
    assert len(editor.state.graph.wires) == before

    page.get_by_role("button", name="Run", exact=True).click()
    page.wait_for_function(
        f"""() => {{ const o = window.__viserMutable.nodeRefFromName['/canvas/body']; let m = null;
        o.traverse(c => {{ if (c.isInstancedMesh && !m) m = c; }}); const C = m.material.color.constructor;
        for (let i = 0; i < m.instancesCount; i++) {{ const c = new C(); m.getColorAt(i, c);
          if (i < 7 && (Math.abs(c.r - {DONE[0]}) > 0.01 || Math.abs(c.g - {DONE[1]}) > 0.01)) return false; }}
        return m.instancesCount === 8; }}""",
        timeout=30000)
    assert np.allclose(ui.body_colors()[:7], DONE, atol=0.01)  # the 8th body is the interface output's terminal
    assert editor.last_result.ok and set(editor.last_result.nodes) == {n.id for n in editor.state.graph.nodes}

    view = editor.extensions.view  # the 3D view: a second viser server, shown in the page's docked panel
    wait_until(lambda: view.server.get_clients() and "/path/0" in view.nodes, what="the 3D view to show the path")
    page.wait_for_timeout(800)
    client = next(iter(view.server.get_clients().values()))
    render = client.get_render(height=360, width=480)
    shown = not_blank(render)
    assert shown > 0.002, f"the 3D view render is blank ({shown:.4%} coloured pixels)"
    canvas = next(iter(editor.server.get_clients().values())).get_render(height=400, width=600)
    assert not_blank(canvas) > 0.002

    page.get_by_role("tab", name="Files").click()
    page.get_by_role("button", name="Save", exact=True).click()
    wait_until(lambda: not editor.state.dirty, what="the save")
    saved = flowmc.load(tmp_path / "example.flowmc.json")
    assert flowmc.dumps(saved) == flowmc.dumps(editor.state.graph)
    positions = ui.body_positions()

    page.reload()
    ui.wait_nodes(8)
    assert np.allclose(ui.body_positions(), positions, atol=1e-4)
    on_file = [saved.node(n.id).pos for n in editor.state.graph.nodes]
    assert np.allclose(ui.body_positions()[:7], [(x * 0.01, -y * 0.01) for x, y in on_file], atol=1e-4)
    again = Editor(tmp_path / "example.flowmc.json", port=0, extensions=False)
    try:
        assert flowmc.dumps(again.state.graph) == flowmc.dumps(editor.state.graph)
    finally:
        again.close()
    page.close()


def test_click_selects_drag_moves_and_the_camera_stays_flat(browser, editor):
    ui = EditorPage(browser, editor)
    ui.open()
    ui.dismiss_toasts()
    page = ui.page
    ui.click_node("shift")
    wait_until(lambda: editor.state.selected_nodes == ["shift"], what="selection")
    index = [n.id for n in editor.state.graph.nodes].index("shift")
    page.wait_for_function(f"""() => {{ const o = window.__viserMutable.nodeRefFromName['/canvas/frame']; let m = null;
        o.traverse(c => {{ if (c.isInstancedMesh && !m) m = c; }}); const c = new (m.material.color.constructor)();
        m.getColorAt({index}, c); return Math.abs(c.r - {expected(canvas_draw.FRAME_SELECTED)[0]}) < 0.01; }}""", timeout=10000)
    page.get_by_text("path.translate").first.wait_for(timeout=10000)  # the inspector shows the node
    ui.field("dx (mm)").wait_for(timeout=10000)  # and its params, with units

    page.keyboard.down("Shift")
    ui.click_node("edge")  # shift-click adds to the selection
    page.keyboard.up("Shift")
    wait_until(lambda: editor.state.selected_nodes == ["shift", "edge"], what="shift-click")
    editor.state.clear_selection()
    a, b = ui.box("table"), ui.box("shift")
    (x0, y0), (x1, y1) = ui.screen(a.x - 0.3, a.y + 0.3), ui.screen(b.x + b.w + 0.3, b.y - b.h - 0.3)
    left = page.evaluate("() => window.__viserMutable.canvas.getBoundingClientRect().left")
    x0 = max(x0, left + 25)  # not on the docked panel's edge
    page.keyboard.down("Shift")  # shift-drag on the background selects the nodes in the box
    page.mouse.move(x0, y0)
    page.mouse.down()
    for k in range(1, 9):
        page.mouse.move(x0 + (x1 - x0) * k / 8, y0 + (y1 - y0) * k / 8)
        page.wait_for_timeout(30)
    page.mouse.up()
    page.keyboard.up("Shift")
    wait_until(lambda: sorted(editor.state.selected_nodes) == ["shift", "table"], what="box selection")
    editor.state.clear_selection()

    box = ui.box("shift")
    x0, y0 = ui.screen(box.x + box.w / 2, box.y - box.h / 2)
    old = editor.state.node("shift").pos
    page.mouse.move(x0, y0)
    page.mouse.down()
    for k in range(1, 9):
        page.mouse.move(x0 + 12 * k, y0 + 6 * k)
        page.wait_for_timeout(40)
    page.mouse.up()
    wait_until(lambda: editor.state.node("shift").pos[0] > old[0] + 20, what="the drag to move the node")
    assert editor.state.node("shift").pos[1] > old[1]  # dragged down the screen: y grows down on the canvas

    cam = "() => [window.__viserMutable.cameraControl.polarAngle, window.__viserMutable.cameraControl.azimuthAngle, window.__viserMutable.camera.position.toArray()]"
    polar, azimuth, before = page.evaluate(cam)
    page.mouse.move(700, 900)
    page.mouse.down()
    for k in range(1, 8):
        page.mouse.move(700 + 20 * k, 900 - 10 * k)
        page.wait_for_timeout(40)
    page.mouse.up()
    page.mouse.wheel(0, 300)
    page.wait_for_timeout(600)
    polar2, azimuth2, after = page.evaluate(cam)
    assert polar2 == pytest.approx(polar, abs=1e-6)  # panned and zoomed, never tilted or turned
    assert (np.cos(azimuth2), np.sin(azimuth2)) == pytest.approx((np.cos(azimuth), np.sin(azimuth)), abs=1e-6)
    assert not np.allclose(before, after)
    page.close()


_WIRE_LOOK = """() => { const o = window.__viserMutable.nodeRefFromName['/canvas/wires']; const out = [];
  o.traverse(c => { if (c.material && c.material.type === 'LineMaterial') out.push([c.material.worldUnits, c.material.linewidth]); });
  const m = window.__viserMutable, mat = m.backgroundMaterial, quad = m.scene.children.find(c => c.isMesh && c.material === mat);
  return [out, quad ? quad.visible : null]; }"""


def test_frames_skip_unseen_work_and_wires_follow_the_zoom(browser, editor):
    """One cheap pass per wire (screen pixels, thickness set from the zoom) and no background-image quad
    while no image is set: the two largest items of a frame under software WebGL."""
    ui = EditorPage(browser, editor)
    ui.open()
    ui.dismiss_toasts()
    page = ui.page
    page.wait_for_function(f"({_WIRE_LOOK})()[1] === false", timeout=10000)  # the page script hid the quad
    lines, _quad = page.evaluate(_WIRE_LOOK)
    assert lines == [[False, pytest.approx(editor.canvas.wire_px)]]  # one pass, screen units
    before = editor.canvas.wire_px
    ui.settled()
    x, y = ui.screen(*ui.box("shift").centre)
    page.mouse.move(x, y)
    for _ in range(4):
        page.mouse.wheel(0, -400)  # zoom in
        page.wait_for_timeout(150)
    ui.settled()
    wait_until(lambda: editor.canvas.wire_px > before + 0.5, what="thicker wires zoomed in")
    page.wait_for_function(f"({_WIRE_LOOK})()[0][0][1] === {editor.canvas.wire_px}", timeout=10000)
    page.close()


def test_node_frames_stay_a_screen_pixel_wide_zoomed_out(browser, editor):
    """The canvas is not multisampled under software WebGL: zoomed out, a node's frame is widened to at least
    a screen pixel each side (thinner, whole edges dropped out), and back to its own width zoomed in."""
    ui = EditorPage(browser, editor)
    ui.open()
    ui.settled()
    page, canvas = ui.page, editor.canvas

    def edge_px() -> float:
        per_px = camera.screen_px_per_world(next(iter(editor.server.get_clients().values())).camera)
        frame, body = canvas._handles["frame"].batched_scales, canvas._handles["body"].batched_scales
        return float(np.min(frame[:, :2] - body[:, :2]) / 2 * per_px)

    x, y = ui.screen(*ui.box("shift").centre)
    page.mouse.move(x, y)
    for _ in range(6):
        page.mouse.wheel(0, 400)  # zoom out
        page.wait_for_timeout(150)
    ui.settled()
    wait_until(lambda: canvas.frame_edge > canvas_draw.FRAME_EDGE, what="frames widened zoomed out")
    wait_until(lambda: 1.0 <= edge_px() <= 1.5, what="frames a screen pixel wide")
    for _ in range(10):
        page.mouse.wheel(0, -400)  # zoom in
        page.wait_for_timeout(150)
    ui.settled()
    wait_until(lambda: canvas.frame_edge == canvas_draw.FRAME_EDGE, what="frames back to their width zoomed in")
    assert edge_px() > 1.0
    page.close()


def test_frames_held_for_a_click_are_drawn_with_its_answer(browser, editor):
    """A press holds the page's frames until the editor answers; the answer's frame then shows the selection
    (the pixels, not only the scene's colour), and a press with no answer lets its frames go after the hold."""
    ui = EditorPage(browser, editor)
    ui.open()
    ui.dismiss_toasts()
    page = ui.page
    assert page.evaluate("window.__flowmcFrames.until") == 0
    box = ui.box("shift")
    edge = ui.screen(box.x + box.w / 2, box.y + 0.03)  # inside the selection frame's top margin, above the body
    ui.click_node("shift")
    page.get_by_text("Selected: node shift").wait_for(timeout=10000)

    def drawn_orange() -> bool:
        shot = np.asarray(Image.open(io.BytesIO(page.screenshot())).convert("RGB")).astype(int)
        r, g, b = shot[int(round(edge[1])), int(round(edge[0]))]
        return r > 200 and 90 < g < 190 and b < 90

    wait_until(drawn_orange, 10, "the selection frame drawn")
    page.mouse.click(*ui.screen(box.x + box.w * 0.6, box.y - box.h * 0.6))  # the same node again: no change, no answer
    page.wait_for_function("window.__flowmcFrames.until === 0", timeout=5000)
    page.close()
