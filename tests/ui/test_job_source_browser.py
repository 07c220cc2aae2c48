"""The job panel in Chromium while a real-time job runs on the simulated card: the E-STOP is in sight
from the page's load (no folder to unfold), and the G-code line the job is on is highlighted in its
source, with the text of every line shown literally (a hostile comment stays text)."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest

from browser_helpers import VIEWPORT, EditorPage, chromium, wait_until
from flowmc.ui.app import Editor

pytestmark = pytest.mark.browser

REPO = Path(__file__).resolve().parents[2]
HOSTILE = "(<img src=x onerror=window.__pwned=1>)"


@pytest.fixture
def ui(tmp_path):
    """The teaching-machine G-code example on the simulated card (its GRBL node set to ``sim``), a
    hostile comment on two of its lines, real time."""
    graph = json.loads((REPO / "graphs" / "teaching_machine.flowmc.json").read_text())
    gcode = next(n for n in graph["nodes"] if n["id"] == "gcode")
    lines = gcode["params"]["text"].splitlines()
    lines[4] += " " + HOSTILE  # line 5: G1 X40 Y20
    lines[6] += " " + HOSTILE  # line 7: G1 X0 Y30
    gcode["params"]["text"] = "\n".join(lines) + "\n"
    next(n for n in graph["nodes"] if n["id"] == "grbl")["params"]["device"] = "sim"
    path = tmp_path / "teaching.flowmc.json"
    path.write_text(json.dumps(graph))
    editor = Editor(path, port=0)
    with chromium() as browser:
        page = EditorPage(browser, editor)
        page.open()
        yield page, lines
    editor.close()


def _in_viewport(locator) -> bool:
    """Inside the viewport, and what the page shows at its centre (not scrolled away or covered)."""
    box = locator.bounding_box()
    inside = (box is not None and box["width"] > 0 and box["x"] >= 0 and box["y"] >= 0
              and box["x"] + box["width"] <= VIEWPORT["width"] and box["y"] + box["height"] <= VIEWPORT["height"])
    return inside and locator.evaluate(
        "(b) => { const r = b.getBoundingClientRect(); const at = document.elementFromPoint(r.left + r.width / 2, "
        "r.top + r.height / 2); return !!at && b.contains(at); }")


def _estop(ui: EditorPage):
    return ui.page.get_by_role("button", name="E-STOP", exact=True)


def test_e_stop_in_sight_on_load_and_the_running_line_highlighted_in_the_gcode(ui, tmp_path):
    ui, lines = ui
    assert _in_viewport(_estop(ui))  # on load, nothing clicked or unfolded
    assert ui.page.locator(".flowmc-source").count() == 0 or not ui.page.locator(".flowmc-src-line").count()
    ui.page.get_by_role("button", name="Run", exact=True).click()
    ui.editor.session.wait()
    ui.page.get_by_text("Machine", exact=True).first.click()
    ui.page.get_by_role("button", name="Start", exact=True).click()
    panel = ui.editor.job_panel
    wait_until(lambda: panel.node_id == "grbl" and panel.runner is not None, 60, "the job")
    runner = panel.runner
    wait_until(lambda: (runner.status.line or 0) >= 4, 60, "the job past a few lines")
    ui.page.screenshot(path=str(tmp_path / "running.png"))
    assert runner.state == "running" and _in_viewport(_estop(ui))  # still in sight while it runs
    current = ui.page.locator(".flowmc-source[data-kind='gcode'] .flowmc-src-current")
    seen: set[int] = set()

    def agrees() -> bool:  # the page's highlighted line is the job's current line (it moves on)
        line, shown = runner.status.line, current.get_attribute("data-n", timeout=5000)
        seen.add(int(shown))
        return shown is not None and int(shown) == line

    wait_until(agrees, 20, "the highlighted line to be the job's")
    ui.page.locator(".flowmc-source").scroll_into_view_if_needed()
    ui.page.screenshot(path=str(tmp_path / "source.png"))
    assert _in_viewport(_estop(ui))  # the side panel scrolled down to the source: the E-STOP stays at its top
    ui.page.keyboard.press("Escape")  # feed hold: the line stays put, page and job must agree exactly
    wait_until(lambda: runner.state == "held", 20, "held")
    time.sleep(1.0)
    line = runner.status.line
    assert int(current.get_attribute("data-n")) == line
    text = current.inner_text()
    assert text.split(None, 1)[1].strip() == lines[line - 1].strip()  # the line's own text, literally
    window = ui.page.locator(".flowmc-source .flowmc-src-line")
    numbers = [int(window.nth(k).get_attribute("data-n")) for k in range(window.count())]
    assert numbers == list(range(max(1, line - 2), min(len(lines), line + 4) + 1))  # 2 before, 4 after
    source = ui.page.locator(".flowmc-source")
    if any(HOSTILE in lines[n - 1] for n in numbers):
        assert HOSTILE in source.inner_text()
    assert source.locator("img").count() == 0 and ui.page.evaluate("window.__pwned") is None
    ui.page.get_by_role("button", name="Resume", exact=True).click()
    wait_until(lambda: runner.state == "running", 20, "resumed")
    assert _in_viewport(_estop(ui))
    _estop(ui).click()  # the E-STOP in sight stops the running job; outputs safe
    wait_until(lambda: runner.finished, 30, "the e-stop")
    assert runner.log.outcome == "estop" and runner.state == "aborted"
    state = runner.log.state
    assert state["spindle_rpm"] == 0 and not state["tool_down"] and not any(state["outputs"])
    assert len(seen) >= 1
