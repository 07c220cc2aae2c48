"""Editing as a person does it, in a real browser (Debian's chromium via playwright): drag to wire, copy
and paste, comments through save and reload, auto-layout of a big graph, the examples browser, a grid
filled by pasting spreadsheet cells, an interface input drawn as a terminal, a palette entry dropped
on the canvas, and the first view framing the whole graph every time."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from browser_helpers import EditorPage, expected, wait_until
from editor_graphs import chain_file, example_file
from flowmc.ui import arrange, canvas_draw, layout
from flowmc.ui.app import Editor
from flowmc.ui.examples import examples_dir

pytestmark = pytest.mark.browser


@pytest.fixture
def page_on(browser, tmp_path):
    """An editor on the example graph and a page open on it (closed after the test)."""
    made = []

    def make(path=None, **options):
        editor = Editor(path or example_file(tmp_path), port=0, **options)
        ui = EditorPage(browser, editor)
        made.append((editor, ui))
        ui.open(timeout=60)
        ui.dismiss_toasts()
        return editor, ui

    yield make
    for editor, ui in made:
        ui.page.close()
        editor.close()


def wires(editor):
    return {(w.from_, w.to) for w in editor.state.graph.wires}


def drag(ui, a, b, steps=8):
    page = ui.page
    page.mouse.move(*a)
    page.mouse.down()
    for k in range(1, steps + 1):
        page.mouse.move(a[0] + (b[0] - a[0]) * k / steps, a[1] + (b[1] - a[1]) * k / steps)
        page.wait_for_timeout(50)
    page.wait_for_timeout(120)
    page.mouse.up()


def select_table_and_shift(ui):
    """Click 'table', shift-click 'shift', as a person selects two nodes."""
    ui.click_node("table")
    ui.page.keyboard.down("Shift")
    ui.click_node("shift")
    ui.page.keyboard.up("Shift")
    wait_until(lambda: sorted(ui.editor.state.selected_nodes) == ["shift", "table"], what="two selected")


def scene_boxes(ui):
    """Every body's world rectangle as the browser's scene holds it."""
    return ui.page.evaluate("""() => { const o = window.__viserMutable.nodeRefFromName['/canvas/body']; let m = null;
      o.traverse(c => { if (c.isInstancedMesh && !m) m = c; }); const M = m.matrix.constructor; const out = [];
      for (let i = 0; i < m.instancesCount; i++) { const t = new M(); m.getMatrixAt(i, t); const e = t.elements;
        out.push([e[12], e[13], e[0], e[5]]); } return out; }""")


def test_drag_from_a_port_to_a_port_wires_them(page_on):
    editor, ui = page_on()
    editor.state.delete(wires=[("shift.path", "both.path1")])
    ui.page.wait_for_timeout(400)
    a, b = ui.box("shift").port("out", "path"), ui.box("both").port("in", "path1")
    drag(ui, ui.screen(a.x, a.y), ui.screen(b.x, b.y))
    wait_until(lambda: ("shift.path", "both.path1") in wires(editor), what="the dragged wire")
    n = len(wires(editor))
    c = ui.box("both").port("in", "rapid_feed")  # a Path cannot feed a Number: dropped, nothing wired
    drag(ui, ui.screen(a.x, a.y), ui.screen(c.x, c.y))
    ui.page.wait_for_timeout(800)
    assert len(wires(editor)) == n


def test_copy_and_paste_a_group_brings_its_inner_wire(page_on, browser):
    editor, ui = page_on()
    page = ui.page
    select_table_and_shift(ui)
    page.keyboard.press("Control+c")
    page.wait_for_timeout(300)
    page.keyboard.press("Control+v")
    wait_until(lambda: len(editor.state.graph.nodes) == 6, what="the paste")
    new = {editor.state.node(n).type: n for n in editor.state.selected_nodes}
    assert (f"{new['path.segment_table']}.path", f"{new['path.translate']}.path") in wires(editor)
    assert editor.state.node(new["path.segment_table"]).params == editor.state.node("table").params
    ui.wait_nodes(len(editor.canvas.boxes))
    placed = editor.actions.rects()
    assert arrange.overlaps({k: placed[k] for k in placed if not k.startswith("@")}) == []  # pasted at a free spot


def test_a_comment_survives_save_and_reload(page_on, tmp_path):
    editor, ui = page_on()
    page = ui.page
    ui.click_node("table")
    page.get_by_role("button", name="Comment", exact=True).click()
    wait_until(lambda: editor.state.graph.view.comments, what="the comment")
    ui.field("Text").fill("Where the path comes from")
    ui.field("Text").press("Tab")
    wait_until(lambda: editor.state.graph.view.comments[0].text == "Where the path comes from", what="its text")
    page.keyboard.press("Control+s")
    wait_until(lambda: not editor.state.dirty, what="the save")
    saved = json.loads((tmp_path / "example.flowmc.json").read_text())
    assert saved["view"]["comments"][0]["text"] == "Where the path comes from"
    page.reload()
    ui.wait_nodes(len(editor.canvas.boxes))
    page.wait_for_function("""() => { const o = window.__viserMutable.nodeRefFromName['/canvas/comment'];
      let m = null; if (!o) return false; o.traverse(c => { if (c.isInstancedMesh && !m) m = c; });
      return m && m.instancesCount === 1; }""", timeout=15000)
    again = Editor(tmp_path / "example.flowmc.json", port=0, extensions=False)
    try:
        assert again.state.graph.view.comments[0].text == "Where the path comes from"
        comment = again.state.graph.view.comments[0]
        table = again.state.node("table")
        assert comment.pos[0] < table.pos[0] and comment.pos[1] < table.pos[1]  # drawn around the table
    finally:
        again.close()


def test_auto_layout_of_120_nodes_leaves_no_overlap_in_the_scene(page_on, tmp_path):
    editor, ui = page_on(chain_file(tmp_path, 120))
    ui.page.get_by_role("button", name="Layout", exact=True).click()
    wait_until(lambda: not arrange.overlaps(editor.actions.rects()), 30, "the layout")
    ui.page.wait_for_timeout(1500)
    rects = {str(k): arrange.Rect(x, -y, w, h) for k, (x, y, w, h) in enumerate(scene_boxes(ui))}
    assert len(rects) == 120 and arrange.overlaps(rects) == []
    assert editor.minimap.panel.visible  # a big graph gets a minimap


def test_open_an_example_from_the_browser(page_on):
    editor, ui = page_on()
    page = ui.page
    page.get_by_role("tab", name="Examples").click()
    page.get_by_role("button", name="Open thesis_3axis", exact=True).click()
    wait_until(lambda: editor.state.path is not None and editor.state.path.name == "thesis_3axis.flowmc.json",
               what="the example to open")
    assert editor.state.path.parent == examples_dir() and editor.state.folder != examples_dir()
    ui.wait_nodes(len(editor.canvas.boxes))
    assert not editor.files.save()  # the example is not overwritten: Save as keeps a copy
    assert "outside the editor's folder" in editor.messages[-1][1]


def test_paste_twenty_segment_rows_from_tab_separated_text(page_on):
    editor, ui = page_on()
    page = ui.page
    ui.click_node("table")
    first = page.locator('table[data-flowmc-grid] [data-r="0"][data-c="type"]')
    first.wait_for(timeout=15000)
    text = "\n".join(f"line\t{10 * k}\t{5 * k}\t0" for k in range(20))
    first.focus()
    page.evaluate("""(text) => { const el = document.activeElement; const dt = new DataTransfer();
      dt.setData('text/plain', text); el.dispatchEvent(new ClipboardEvent('paste', { clipboardData: dt, bubbles: true,
      cancelable: true })); }""", text)
    wait_until(lambda: len(editor.state.node("table").params["rows"]) == 20, what="20 rows")
    rows = editor.state.node("table").params["rows"]
    assert rows[13] == {"type": "line", "end": [130.0, 65.0, 0.0]} and editor.state.issues() == []
    page.locator('table[data-flowmc-grid] [data-r="19"][data-c="end.0"]').wait_for(timeout=10000)
    cell = page.locator('table[data-flowmc-grid] [data-r="2"][data-c="end.1"]')
    cell.fill("7")
    cell.press("ArrowDown")  # the edit goes in, and the focus moves down a row
    wait_until(lambda: editor.state.node("table").params["rows"][2]["end"][1] == 7.0, what="the cell edit")
    wait_until(lambda: page.evaluate("document.activeElement && document.activeElement.dataset.r") == "3",
               what="the focus on the next row")


def test_an_added_interface_input_is_drawn_as_a_terminal(page_on):
    editor, ui = page_on()
    page = ui.page
    page.get_by_text("Interface", exact=True).first.click()
    ui.field("Input name").fill("offset")
    ui.field("Input name").press("Tab")
    page.get_by_role("button", name="Add input", exact=True).click()
    wait_until(lambda: any(i.name == "offset" for i in editor.state.graph.interface.inputs), what="the input")
    wait_until(lambda: any(b.node_id == "@in:offset" for b in editor.canvas.boxes), what="its terminal laid out")
    ui.wait_nodes(len(editor.canvas.boxes))  # and drawn in the page before it is dragged from
    ui.wait_ports()
    term = ui.box("@in:offset")
    assert term.x < min(b.x for b in editor.canvas.boxes if not b.node_id.startswith("@"))  # left of the nodes
    spot, dx = term.outputs[0], ui.box("shift").port("in", "dx")
    drag(ui, ui.screen(spot.x, spot.y), ui.screen(dx.x, dx.y))
    wait_until(lambda: "shift.dx" in editor.state.graph.interface.inputs[-1].to, what="the terminal wired")
    ui.wait_nodes(len(editor.canvas.boxes))
    wait_until(lambda: ("@in:offset", "shift.dx") in editor.canvas.curves, what="its wire drawn")


def test_a_palette_entry_dragged_onto_the_canvas_lands_there(page_on):
    editor, ui = page_on()
    page = ui.page
    button = page.get_by_role("button", name="Scale", exact=True)
    button.scroll_into_view_if_needed()
    box = button.bounding_box()
    target = ui.screen(2.0, -4.5)  # a free place on the canvas, in world units
    drag(ui, (box["x"] + 30, box["y"] + 10), target, steps=12)
    wait_until(lambda: any(n.type == "path.scale" for n in editor.state.graph.nodes), what="the drop")
    node = next(n for n in editor.state.graph.nodes if n.type == "path.scale")
    centre = np.add(node.pos, [65, 40])
    assert np.hypot(*(centre - np.asarray(layout.to_canvas(2.0, -4.5)))) < 120  # about where it was let go


def test_the_first_view_frames_the_whole_graph_every_time(browser, tmp_path):
    editor = Editor(example_file(tmp_path), port=0, extensions=False)
    try:
        for _ in range(5):
            ui = EditorPage(browser, editor)
            ui.open()
            ui.settled()
            r = ui.page.evaluate("(() => { const r = window.__viserMutable.canvas.getBoundingClientRect(); "
                                 "return [r.left, r.top, r.right, r.bottom]; })()")
            for b in editor.canvas.boxes:
                for x, y in ((b.x, b.y), (b.x + b.w, b.y - b.h)):
                    sx, sy = ui.screen(x, y)
                    assert r[0] <= sx <= r[2] and r[1] <= sy <= r[3], (b.node_id, sx, sy, r)
            ui.page.close()
    finally:
        editor.close()


def test_notifications_stay_off_the_canvas_never_pile_up_and_expire(page_on):
    editor, ui = page_on()
    page = ui.page
    ui.wire("table.path", "shift.dx")  # refused: a Path cannot feed a Number
    toasts = page.locator(".mantine-Notification-root", has_text="cannot wire")
    toasts.first.wait_for(timeout=10000)
    canvas = page.evaluate("(() => { const r = window.__viserMutable.canvas.getBoundingClientRect(); "
                           "return [r.left, r.top, r.right, r.bottom]; })()")
    boxes = [toasts.first.bounding_box()]

    def still() -> bool:  # a notification slides in from the right: judge where it comes to rest
        page.wait_for_timeout(100)
        boxes.append(toasts.first.bounding_box())
        return boxes[-1] == boxes[-2]
    wait_until(still, 10, "the notification to come to rest")
    box = boxes[-1]
    assert box["x"] >= canvas[2] - 1, (box, canvas)  # beside the canvas, over the right-hand column
    for k in range(6):  # a burst of messages: the oldest go
        editor.notify("info", f"message {k}")
    page.locator(".mantine-Notification-root", has_text="message 5").wait_for(timeout=10000)
    page.wait_for_timeout(500)
    assert page.locator(".mantine-Notification-root", has_text=re.compile("message|cannot wire")).count() <= 3
    wait_until(lambda: page.locator(".mantine-Notification-root", has_text="message").count() == 0, 15,
               "the messages to expire")


def test_the_palette_is_open_on_load_grouped_and_finds_nodes_by_port_type(page_on):
    editor, ui = page_on()
    page = ui.page
    assert page.get_by_role("tab", name="Nodes").get_attribute("aria-selected") == "true"
    everything = len(editor.palette.items)
    page.get_by_text(f"{everything} entries", exact=True).wait_for(timeout=10000)
    for category in {i.category for i in editor.palette.items}:
        page.get_by_text(category, exact=True).first.wait_for(state="attached", timeout=10000)
    ui.field("Search").fill("Trajectory")
    ui.field("Search").press("Tab")
    wait_until(lambda: editor.palette.search.value == "Trajectory", what="the search")
    found = page.get_by_text(re.compile(r"^\d+ of \d+ entries match$"))
    found.wait_for(timeout=10000)
    assert int(found.inner_text().split()[0]) >= 8  # every node that takes or gives a Trajectory
    page.get_by_role("button", name="Look-ahead planner", exact=True).wait_for(timeout=10000)


def test_align_the_selection_from_the_side_panel(page_on):
    editor, ui = page_on()
    page = ui.page
    select_table_and_shift(ui)
    editor.state.move_node("shift", (320.0, 90.0))
    ui.field("Align").click()
    page.get_by_role("option", name="top", exact=True).click()
    wait_until(lambda: editor.state.node("shift").pos[1] == editor.state.node("table").pos[1], what="the alignment")


def test_one_click_downloads_the_graph(page_on):
    editor, ui = page_on()
    page = ui.page
    page.get_by_role("tab", name="Files").click()
    with page.expect_download(timeout=15000) as got:
        page.get_by_role("button", name="Download the graph", exact=True).click()
    saved = json.loads(open(got.value.path()).read())
    assert got.value.suggested_filename == "example.flowmc.json"
    assert {n["id"] for n in saved["nodes"]} == {n.id for n in editor.state.graph.nodes}


def test_the_dark_theme_darkens_the_page_and_the_canvas(page_on):
    editor, ui = page_on()
    page = ui.page
    page.get_by_role("tab", name="Files").click()
    page.get_by_text("Dark theme", exact=True).click()
    page.wait_for_function("document.documentElement.dataset.mantineColorScheme === 'dark'", timeout=10000)
    dark = expected(canvas_draw.DARK.status[None])
    wait_until(lambda: np.allclose(ui.body_colors()[0], dark, atol=0.02), what="dark node bodies")


def test_a_failed_node_gets_a_badge_and_its_error_is_in_the_problems_list(page_on):
    editor, ui = page_on()
    page = ui.page
    badges = "(() => { const o = window.__viserMutable.nodeRefFromName['/canvas/badge']; let m = null; if (!o) return 0;" \
             " o.traverse(c => { if (c.isInstancedMesh && !m) m = c; }); return m ? m.instancesCount : 0; })()"
    editor.state.set_param("table", "rows", [{"type": "arc", "direction": "ccw", "radius": 5.0, "start_angle": 0.0,
                                              "end_angle": 0.0}])  # valid fields, but the arc sweeps nothing
    page.get_by_role("button", name="Run", exact=True).click()
    wait_until(lambda: editor.session.run_errors(), 30, "the failed run")
    page.wait_for_function(f"{badges} >= 1", timeout=15000)
    page.get_by_role("tab", name="Problems").click()
    message = next(iter(editor.session.run_errors().values()))
    page.get_by_role("button", name=re.compile(re.escape(message[:30]))).first.wait_for(timeout=10000)

