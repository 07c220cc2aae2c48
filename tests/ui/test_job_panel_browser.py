"""The editor's job panel in Chromium on the simulated card in real-time mode, on the thesis example
graph: Start, feed hold with Esc at about 30 % and Resume, Stop, E-stop, the feed override slider, and
a front-panel change that must move nothing. Every limit and distance is checked from the raw
commanded setpoints the job runner records (``record``), not from what the page shows."""

from __future__ import annotations

import shutil
import time
from pathlib import Path

import numpy as np
import pytest

from browser_helpers import EditorPage, chromium, wait_until
from flowmc.ui.app import Editor
from tests.devices.job_helpers import distance_to_polyline, limits_ratio, moving_rows

pytestmark = pytest.mark.browser

REPO = Path(__file__).resolve().parents[2]
TOL = 1e-3  # mm: how far from the planned path a re-timed setpoint may be
SPEED = 2.0  # the card's clock runs at twice the wall clock: a 13.5 s program takes about 7 s


@pytest.fixture
def ui(tmp_path):
    shutil.copy(REPO / "graphs" / "thesis_3axis.flowmc.json", tmp_path)
    editor = Editor(tmp_path / "thesis_3axis.flowmc.json", port=0)
    panel = editor.job_panel
    panel.record, panel.speed.value = True, SPEED
    with chromium() as browser:
        page = EditorPage(browser, editor)
        page.open()
        page.dismiss_toasts()
        yield page
    editor.close()


def _responsive(ui: EditorPage, timeout: float = 120.0) -> None:
    """Wait until the page answers at once (a run's 3D drawing in software WebGL takes its main thread)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        began = time.monotonic()
        ui.page.evaluate("1")
        if time.monotonic() - began < 0.05:
            return
    raise AssertionError("the page stayed busy")


def _run_then_start(ui: EditorPage) -> None:
    """Run (the 3D view draws the plan), then Start: the panel starts the jobs that run prepared."""
    ui.page.get_by_role("button", name="Run", exact=True).click()
    ui.editor.session.wait()
    _responsive(ui)
    ui.page.get_by_text("Machine", exact=True).first.click()  # unfold the job panel
    ui.page.get_by_role("button", name="Start", exact=True).click()


def _card(ui: EditorPage, progress: float = 0.0):
    panel = ui.editor.job_panel
    wait_until(lambda: panel.node_id == "card" and panel.runner.status.progress >= progress, 60, "the card job")
    return panel.runner


def _recorded(runner):
    """(every commanded setpoint from the job's start, the log, the period, the planned positions)."""
    log, planned = runner.log, runner.job.motion.positions
    return np.vstack([planned[:1], runner.setpoints()]), log, log.period, planned


def _speed_now(runner) -> float:
    """Path speed (mm/s) over the last few recorded setpoints of a running job."""
    trace = list(runner.trace or [])
    recent = np.vstack(trace[-3:]) if trace else np.zeros((0, 3))
    if len(recent) < 6:
        return 0.0
    return float(np.linalg.norm(recent[-1] - recent[-6]) / (5 * runner.job.machine.period))


def _row(log, text: str) -> int:
    event = next(e for e in log.events if text in e.message)
    return int(round((event.t - log.t[0]) / log.period))


def _shown_state(ui: EditorPage, state: str) -> None:
    ui.page.wait_for_selector(f".flowmc-live[data-state='{state}']", timeout=30000)


def test_hold_with_esc_at_30_percent_resume_and_feed_override_50(ui, tmp_path):
    panel = ui.editor.job_panel
    _run_then_start(ui)
    runner = _card(ui, 0.3)
    ui.page.keyboard.press("Escape")  # the feed-hold shortcut
    wait_until(lambda: runner.state == "held", 20, "held")
    _shown_state(ui, "held")
    assert ui.page.get_by_role("button", name="Resume", exact=True).is_enabled()
    row = ui.page.locator(".flowmc-source[data-kind='table'] .flowmc-src-current")  # the segment table's row
    wait_until(lambda: row.count() == 1 and f"row {row.get_attribute('data-n')}"
               == runner.job.segment_names[runner.status.segment], 10, "the held row highlighted")
    time.sleep(1.0)
    ui.page.locator(".flowmc-live").scroll_into_view_if_needed()
    ui.page.screenshot(path=str(tmp_path / "held.png"))
    assert runner.state == "held"
    ui.page.get_by_role("button", name="Resume", exact=True).click()
    wait_until(lambda: runner.state == "running" and runner.status.progress > 0.5, 30, "resumed past 50 %")
    feed = ui.page.locator("label", has_text="Feed %").first.locator(
        "xpath=ancestor::div[contains(@class, 'mantine-Flex-root')][1]").locator("input:not([type='hidden'])").last
    feed.fill("50")
    feed.press("Enter")
    wait_until(lambda: runner.status.feed == 50.0, 20, "feed 50 %")
    wait_until(lambda: not panel.active, 60, "the end of the job")
    assert runner.state == "done"
    sp, log, T, planned = _recorded(runner)
    machine = runner.job.machine
    k = _row(log, "feed hold")
    assert 0.25 <= k / len(planned) <= 0.6  # held at about 30 % (the page's key latency adds a little)
    v = float(np.linalg.norm(sp[k] - sp[k - 1]) / T)
    assert v > 5.0  # it was moving
    moves = moving_rows(sp)
    stop = int(moves[moves >= k][np.argmax(np.diff(moves[moves >= k], append=10**9) > 1)]) + 1
    assert stop - k <= np.ceil(v / machine.column("amax").min() / T) + 1  # within v/amax (whole periods) + one
    resumed = _row(log, "resume")
    assert resumed - stop > 0.9 * SPEED / T and np.all(sp[stop:resumed + 1] == sp[stop])  # held, not moving
    np.testing.assert_allclose(sp[-1], planned[-1], atol=1e-12)  # ends at the programmed end point
    assert distance_to_polyline(sp, planned).max() <= TOL  # on the uninterrupted path ...
    assert distance_to_polyline(planned, sp).max() <= TOL  # ... and none of it skipped
    # Feed 50 %: the program left when the slider reached 50 % took about twice its planned time.
    last = _row(log, "feed override 50 %")
    s_done = int(np.argmin(np.linalg.norm(planned - sp[last], axis=1)))
    ratio = (len(sp) - 1 - last) / (len(planned) - 1 - s_done)
    assert 1.8 <= ratio <= 2.1, ratio
    vr, ar = limits_ratio(sp, machine, T)
    assert vr <= 1.0 + 1e-9 and ar <= 1.0
    _shown_state(ui, "done")
    assert "card: done" in panel.log_view.content.replace("\\", "")


def test_stop_button_decelerates_along_the_path_and_leaves_the_outputs_safe(ui, tmp_path):
    ui.editor.job_panel.speed.value = 1.0  # real time: the page's click latency under load stays well inside the job
    _run_then_start(ui)
    runner = _card(ui, 0.72)  # the last side: 3.2 s at 20 mm/s, room for a click that waits on a busy page
    wait_until(lambda: _speed_now(runner) > 19.0, 30, "cruising at the programmed 20 mm/s")
    assert runner.status.outputs["spindle_rpm"] > 0  # the spindle runs while it cuts
    ui.page.get_by_role("button", name="Stop", exact=True).click()
    wait_until(lambda: runner.finished, 30, "the stop")
    _shown_state(ui, "aborted")
    ui.page.locator(".flowmc-live").scroll_into_view_if_needed()
    ui.page.screenshot(path=str(tmp_path / "stopped.png"))
    sp, log, T, planned = _recorded(runner)
    k = _row(log, "stop at")
    v = float(np.linalg.norm(np.diff(sp[k - 1:], axis=0), axis=1).max() / T)  # the fastest it went from there
    assert v > 0.5  # it was moving
    stop = int(moving_rows(sp)[-1]) + 1
    assert stop - k <= np.ceil(v / runner.job.machine.column("amax").min() / T) + 1  # v/amax (whole periods) + 1
    vr, ar = limits_ratio(sp, runner.job.machine, T)
    assert vr <= 1.0 + 1e-9 and ar <= 1.0
    assert distance_to_polyline(sp[k:], planned).max() <= TOL
    state = log.state
    assert state["spindle_rpm"] == 0 and not state["tool_down"] and state["da"] == 0 and not any(state["outputs"])
    lamps = ui.page.locator(".flowmc-lamp[data-on='1']")
    assert lamps.count() == 0  # every lamp the page shows is off


def test_e_stop_button_stops_every_axis_at_once_then_a_front_panel_change_moves_nothing(ui):
    ui.editor.job_panel.speed.value = 1.0
    _run_then_start(ui)
    runner = _card(ui, 0.2)
    ui.page.get_by_role("button", name="E-STOP", exact=True).click()
    wait_until(lambda: runner.finished, 30, "the e-stop")
    sp, log, T, _planned = _recorded(runner)
    assert log.outcome == "estop" and runner.state == "aborted"
    assert len(sp) - 1 == _row(log, "software e-stop")  # nothing moved after the period it came in
    assert log.state["spindle_rpm"] == 0 and not any(log.state["outputs"])
    # Then a front-panel change: the graph runs again, the card's job is only marked stale; nothing moves.
    panel = ui.editor.job_panel
    wait_until(lambda: not panel.active, 30, "the end of the start")
    started, moved = len(panel.runners), log.digest()
    ui.page.get_by_role("tab", name="Front panel").click()
    field = ui.field("feed")
    field.fill("15")
    field.press("Enter")
    wait_until(lambda: ui.editor.session.status.get("card", ("",))[0] == "stale", 120, "the card marked stale")
    time.sleep(1.0)
    assert len(panel.runners) == started and not panel.active  # no job started
    assert runner.log.digest() == moved and ui.editor.session.last_result.nodes["card"].status == "stale"
