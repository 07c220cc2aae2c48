"""The structure example graphs (loops, case, wait) run headless and check their key numbers."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import flowmc

GRAPHS = Path(__file__).resolve().parents[2] / "graphs"


def run(name: str, start: bool = True, **inputs):
    return flowmc.run(flowmc.load(GRAPHS / f"{name}.flowmc.json"), inputs=inputs, start=start)


def _cuts(path):
    return [s for s in path.segments if not s.rapid]


def test_multipass_cuts_five_passes_one_mm_deeper_each():
    result = run("multipass_depth")
    assert result.ok, result.errors
    rows = result.outputs["pass_z"].to_rows()
    assert [r["z"] for r in rows] == [-1.0, -2.0, -3.0, -4.0, -5.0]
    path = result.nodes["passes"].outputs["pass"]
    cuts = _cuts(path)
    assert len(cuts) == 5 * 6
    for k in range(5):  # every segment of pass k lies at its Z
        z = np.array([[s.start[2], s.end[2]] for s in cuts[6 * k:6 * k + 6]])
        np.testing.assert_allclose(z, -(k + 1))
    one_pass = flowmc.run(flowmc.load(GRAPHS / "multipass_depth.flowmc.json"), inputs={"passes": 1.0})
    single = one_pass.outputs["total_length_mm"]
    # five passes, and four 1 mm tool-up moves down between them
    assert result.outputs["total_length_mm"] == pytest.approx(5 * single + 4 * 1.0, rel=1e-9)
    quarter = np.pi * 20 / 2  # the thesis's table: lines of 32.01562, 15, 25 and 75 mm, two R20 quarter arcs
    assert single == pytest.approx(32.01562 + quarter + 15 + quarter + 25 + 75, abs=1e-4)
    log = result.outputs["log"]
    assert log.outcome == "done"
    np.testing.assert_allclose(log.position[-1], [0, 0, -5], atol=0.003)
    assert log.position[:, 2].min() == pytest.approx(-5.0, abs=0.003)


def test_grid_places_twelve_parts_with_tool_up_rapids_between():
    result = run("grid_3x4")
    assert result.ok, result.errors
    path = result.outputs["parts"]
    rapids = [s for s in path.segments if s.rapid]
    assert len(rapids) == 11 and not any(s.tool_down for s in rapids)
    starts = [tuple(np.round(rapid.end[:2], 6)) for rapid in rapids]
    expected = [(20.0 * c, 18.0 * r) for r in range(3) for c in range(4)][1:]
    assert starts == expected  # row by row, column by column
    assert len(_cuts(path)) == 12 * 5
    assert result.outputs["log"].outcome == "done"
    np.testing.assert_allclose(result.outputs["log"].position[-1], [60, 36, 0], atol=0.003)


@pytest.mark.parametrize("holes", [6, 8])
def test_bolt_circle_places_n_holes_on_the_circle(holes):
    result = run("bolt_circle", start=False, holes=float(holes), radius=25.0)
    assert result.ok, result.errors
    path = result.outputs["path"]
    plunges = [s for s in path.segments if not s.rapid and s.end[2] < s.start[2]]
    assert len(plunges) == holes
    angles = np.radians(360.0 / holes * np.arange(holes))
    centres = np.array([s.start[:2] for s in plunges])
    np.testing.assert_allclose(centres, 25.0 * np.c_[np.cos(angles), np.sin(angles)], atol=1e-9)
    assert all(s.end[2] == pytest.approx(-3.0) for s in plunges)
    assert [r["angle"] for r in result.outputs["angles"].to_rows()] == pytest.approx(np.degrees(angles))


def test_wait_for_clamp_waits_then_cuts_and_times_out_cleanly():
    result = run("wait_for_clamp", clamp_after=1.2)
    assert result.ok, result.errors
    assert result.outputs["waited_s"] == pytest.approx(1.2, abs=0.004)
    log = result.outputs["log"]
    assert log.t[0] == pytest.approx(1.2, abs=0.004) and log.outcome == "done"
    late = run("wait_for_clamp", clamp_after=9.0, timeout=1.0)
    assert not late.ok
    assert "input 3 (clamp) on ended with timeout" in late.nodes["clamp"].error
    assert late.nodes["card"].status == "skipped"  # nothing cut


def test_probe_branch_takes_the_other_path_when_the_probe_is_high():
    high = run("probe_branch", probe_after=0.1)
    assert high.ok, high.errors
    assert high.outputs["probe_high"] is True and len(high.outputs["path"]) == 3
    assert high.outputs["log"].position[:, 1].max() == pytest.approx(20.0, abs=0.003)
    low = run("probe_branch", probe_after=5.0)
    assert low.ok, low.errors
    assert low.outputs["probe_high"] is False and len(low.outputs["path"]) == 1
    assert abs(low.outputs["log"].position[:, 1]).max() < 0.003
    prepared = run("probe_branch", start=False)  # before Start nothing waits: the case waits for the probe
    assert prepared.nodes["probe"].status == "ready" and prepared.nodes["which_path"].status == "waiting"


def test_case_picks_the_planner_from_the_selector():
    trapezoid = run("case_planner", profile="trapezoid")
    scurve = run("case_planner", profile="scurve")
    other = run("case_planner", profile="anything else")  # the default case
    assert trapezoid.ok and scurve.ok and other.ok
    assert scurve.outputs["cycle_time_s"] > trapezoid.outputs["cycle_time_s"]  # jerk-limited takes longer
    assert other.outputs["cycle_time_s"] == scurve.outputs["cycle_time_s"]
    assert "case 'trapezoid'" in trapezoid.nodes["planner"].logs
