"""Structures, probes and indicators in a real browser (Debian's chromium driven by playwright): build a
For loop from a selection, set N on the front panel, run it and see "iteration N of N", probe a wire and
read its value in the page, and see an indicator show the cycle time."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import flowmc
from browser_helpers import EditorPage, wait_until

pytestmark = pytest.mark.browser


def _graph(folder: Path) -> Path:
    """A line, lowered by a translate (what the loop will repeat), planned: the cycle time is an output."""
    g = flowmc.GraphBuilder(title="one pass")
    line = g.add("path.polyline", id="line", points=[[0, 0, 0], [20, 0, 0]], feed=20.0, pos=(0, 0))
    move = g.add("path.translate", id="move", dz=-1.0, pos=(300, 0))
    plan = g.add("plan.lookahead", id="plan", pos=(600, 0))
    g.wire(line.path, move.path)
    g.wire(move.path, plan.path)
    g.output("cycle_time_s", "Number", plan.cycle_time, description="Planned cycle time (s)")
    path = folder / "pass.flowmc.json"
    flowmc.save(g.build(), path)
    return path


@pytest.fixture
def editor(tmp_path, open_editor):
    return open_editor(_graph(tmp_path))


def _tab(ui: EditorPage, name: str) -> None:
    ui.page.get_by_role("tab", name=name, exact=True).click()


def test_for_loop_from_a_selection_iterations_probe_and_indicator(browser, editor, tmp_path):
    ui = EditorPage(browser, editor)
    ui.open()
    ui.dismiss_toasts()
    page = ui.page
    state = editor.state

    ui.click_node("move")
    wait_until(lambda: state.selected_nodes == ["move"], what="the selection")
    page.get_by_role("button", name="Into a For loop", exact=True).click()
    wait_until(lambda: state.has_node("loop1"), what="the loop made from the selection")
    ui.wait_nodes(len(editor.canvas.boxes))
    assert state.node("loop1").type == "struct.for" and [n.id for n in state.node("loop1").bodies["body"].nodes] == ["move"]
    page.get_by_text("loop1: For loop · N = 1").first.wait_for(timeout=10000)  # the structure's kind and count
    page.get_by_label("Collect every iteration").check()
    wait_until(lambda: state.node("loop1").params.get("indexed") == ["path"], what="auto-indexing on")
    page.get_by_role("button", name="N on the front panel", exact=True).click()
    wait_until(lambda: editor.extensions.front is not None and "loop1_N" in editor.extensions.front.controls,
               what="the N control")
    page.get_by_text("loop1: For loop · N = loop1_N").first.wait_for(timeout=10000)
    assert editor.canvas._texts()["loop1/title"][0].startswith("loop1 · For loop · N = ")  # on the canvas too

    _tab(ui, "Front panel")
    n_field = ui.field("loop1_N")
    n_field.fill("4")
    n_field.press("Enter")
    wait_until(lambda: editor.last_result is not None and editor.last_result.ok
               and editor.session.status.get("loop1", ("",))[0] == "done", timeout=60, what="the run with N = 4")
    status = editor.canvas._texts()["loop1/status"][0]  # the canvas's line under the loop (drawn by WebGL)
    assert re.fullmatch(r"done · [0-9.]+ ms · iteration 4 of 4", status), status
    _tab(ui, "Node")
    ui.click_node("loop1")
    page.get_by_text("last run: iteration 4 of 4").first.wait_for(timeout=10000)  # the loop's panel says it too
    _tab(ui, "Front panel")
    one_pass = 20.0
    assert editor.last_result.nodes["loop1"].outputs["path"].length == pytest.approx(4 * one_pass + 3 * one_pass)
    cycle = editor.last_result.outputs["cycle_time_s"]
    indicator = page.get_by_text(re.compile(rf"^{cycle:.6g} s$"))
    indicator.first.wait_for(timeout=15000)  # the indicator on the front panel shows the cycle time
    page.locator("p:visible", has_text="cycle_time_s (Planned cycle time (s))").first.wait_for(timeout=5000)

    page.get_by_role("button", name="Fit", exact=True).click()
    ui.settled()
    _tab(ui, "Probes")
    page.get_by_label("Click wires to probe them").check()  # then a click on a wire probes it
    curve = editor.canvas.curves[("loop1.path", "plan.path")]
    x, y = curve[len(curve) // 2][:2]
    ui.click_world(float(x), float(y))
    wait_until(lambda: state.graph.view.probes == ["loop1.path"], what="the probe")
    page.get_by_role("button", name="Run", exact=True).click()
    page.get_by_text(re.compile(r"Path: 7 segments · length 140 mm")).first.wait_for(timeout=30000)
    wait_until(lambda: editor.canvas._texts().get("probe/loop1_path", ("",))[0] == "probe: Path · 7 seg · 140 mm",
               what="the probe's label beside the wire")
    page.screenshot(path=str(tmp_path / "structures_probe.png"))  # looked at by hand: probe text and plot
    _tab(ui, "Front panel")
    page.locator("p:visible", has_text="cycle_time_s (Planned cycle time (s))").first.scroll_into_view_if_needed()
    page.screenshot(path=str(tmp_path / "structures_indicators.png"))

    _tab(ui, "Node")
    ui.click_node("loop1")
    wait_until(lambda: state.selected_nodes == ["loop1"], what="the loop selected")
    page.get_by_role("button", name="Open body", exact=True).click()
    wait_until(lambda: state.body_place == ("loop1", "body"), what="the body opened")
    page.get_by_text("loop1 · body body").first.wait_for(timeout=10000)
    page.screenshot(path=str(tmp_path / "structures_body.png"))
    page.get_by_role("button", name="Back to the graph", exact=True).click()
    wait_until(lambda: state.body_place is None and state.has_node("loop1"), what="back in the graph")
    page.close()
