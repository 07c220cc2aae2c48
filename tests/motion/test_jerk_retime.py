"""The jerk-limited retiming of curvature-bound stretches (flowmc.motion.jerk_retime), judged from sampled
setpoints: every axis within its jerk, acceleration and velocity limit, and faster than the time law alone."""

from __future__ import annotations

import json
from pathlib import Path as FsPath

import numpy as np

from flowmc.motion import jerk_retime
from flowmc.motion.limits import PathLimits
from flowmc.motion.machine import Axis, Machine
from flowmc.motion.path import Dwell, Line, Path
from flowmc.motion.planner import plan_smooth
from flowmc.motion.timelaw import sample_time_law

REF = FsPath(__file__).resolve().parents[1] / "data" / "reference" / "paths"


def cam_machine() -> Machine:
    """The CAM benchmark's machine: per-axis 200 mm/s, 200 mm/s^2, 5000 mm/s^3, T = 1 ms."""
    return Machine(axes=tuple(Axis(name=n, min=-500, max=500, vmax=200, amax=200, jmax=5000.0) for n in "XYZ"),
                   period=0.001)


def gosper(order: int, step: float) -> Path:
    """A Gosper curve (flowsnake, like LinuxCNC's flowsnake.ngc): 7^order lines ``step`` mm long turning by
    60 and 120 degrees."""
    rules = {"A": "A-B--B+A++AA+B-", "B": "+A-AA++A+B--B-A"}
    word = "A"
    for _ in range(order):
        word = "".join(rules.get(ch, ch) for ch in word)
    heading = np.cumsum([{"+": 1, "-": -1}.get(ch, 0) for ch in word])[[i for i, ch in enumerate(word) if ch in "AB"]]
    angle = np.radians(60.0) * heading
    pts = np.vstack([[0.0, 0.0], np.cumsum(step * np.c_[np.cos(angle), np.sin(angle)], axis=0)])
    return Path.polyline(np.c_[pts, np.zeros(len(pts))], feed=200.0)


def peaks(positions: np.ndarray, period: float) -> tuple[float, float, float]:
    """Largest per-axis sampled velocity, acceleration and jerk (finite differences of the setpoints)."""
    return tuple(float(np.abs(np.diff(positions, k, axis=0)).max()) / period**k for k in (1, 2, 3))


def test_a_curvature_bound_stretch_is_retimed_faster_within_every_per_axis_limit(monkeypatch):
    # 343 lines 0.03 mm long: the time law holds the speed so that |P3_i| v^3 fits alone, point by point
    # (2.83 s); planned jointly along the curve, the tangential terms cancel it and the plan takes 2.50 s.
    # Its stretches have |P3_i| v^3 over half of jmax on 10-28 % of their samples, flowsnake's on over half:
    # the gate is lowered to a tenth here to keep the test small
    monkeypatch.setattr(jerk_retime, "_BOUND_SHARE", 0.1)
    machine = cam_machine()
    plan = plan_smooth(gosper(3, 0.03), machine, tolerance=0.05, profile="scurve")
    law_alone, _ = sample_time_law(plan.law, plan.smoothed.curve, machine.period)
    assert plan.cycle_time < 0.92 * (len(law_alone) - 1) * machine.period
    v, a, j = peaks(plan.trajectory.positions, machine.period)
    # positions are exact to about 1e-13 mm: sampling noise in the jerk stays below 1e-3 mm/s^3
    assert j <= 5000.0 and a <= 200.0 and v <= 200.0
    # every setpoint is on the planned curve, in order, and the plan ends where the path does
    assert np.all(np.diff(plan.u) >= 0.0)
    assert np.allclose(plan.smoothed.curve.points(plan.u), plan.trajectory.positions, atol=1e-9)
    assert np.allclose(plan.trajectory.positions[-1], gosper(3, 0.03).end)


def test_a_stretch_whose_samples_would_break_a_limit_is_left_as_planned(monkeypatch):
    # programs aiming at 1.5 x jmax give stretches whose samples break the jerk limit: those are dropped,
    # and what is kept (if anything) still holds every limit
    machine = cam_machine()
    monkeypatch.setattr(jerk_retime, "_BOUND_SHARE", 0.1)
    monkeypatch.setattr(jerk_retime, "_JERK_SHARE", 1.5)
    plan = plan_smooth(gosper(3, 0.03), machine, tolerance=0.05, profile="scurve")
    v, a, j = peaks(plan.trajectory.positions, machine.period)
    assert j <= 5000.0 and a <= 200.0 and v <= 200.0


def test_straight_code_has_no_curvature_bound_stretch():
    # zigzag40's 5 mm lines: the curvature-change term never holds the speed, so nothing is retimed (and no
    # linear program is solved)
    data = json.loads((REF / "zigzag40.json").read_text())
    machine = cam_machine()
    plan = plan_smooth(Path.polyline(data["points"], feed=200.0), machine, tolerance=0.05, profile="scurve")
    curve = plan.smoothed.curve
    assert jerk_retime.retime_curvature_bound(plan.law, curve, PathLimits.of(machine),
                                              lambda u: plan.smoothed.seg_feed[curve.segment_at(u)],
                                              machine.period) is None


def test_stretches_that_are_a_sliver_of_the_plan_are_not_retimed(monkeypatch):
    # the Gosper curve, a dwell, then a 1000 mm line: the curve's curvature-bound stretch is about a quarter
    # of the plan's 9.8 s, retimed by default and left alone where 40 % of the plan is asked for
    monkeypatch.setattr(jerk_retime, "_BOUND_SHARE", 0.1)
    machine = cam_machine()
    snake = gosper(3, 0.03)
    end = snake.segments[-1].end
    path = Path([*snake.segments, Dwell(end, 0.1), Line(end, end - [1000.0, 0.0, 0.0], feed=200.0)])
    plan = plan_smooth(path, machine, tolerance=0.05, profile="scurve")
    curve = plan.smoothed.curve

    def retimed():
        return jerk_retime.retime_curvature_bound(plan.law, curve, PathLimits.of(machine),
                                                  lambda u: plan.smoothed.seg_feed[curve.segment_at(u)],
                                                  machine.period)

    assert retimed() is not None
    monkeypatch.setattr(jerk_retime, "_MIN_SHARE", 0.4)
    assert retimed() is None


def test_more_effort_retimes_the_same_curve_no_slower_within_every_per_axis_limit(monkeypatch):
    # the planner's effort against more rounds with control points two periods apart, on the same time law and
    # curve: the linear programs start from the same profile and keep their fastest, so more effort never loses
    monkeypatch.setattr(jerk_retime, "_BOUND_SHARE", 0.1)
    machine = cam_machine()
    plan = plan_smooth(gosper(3, 0.03), machine, tolerance=0.05, profile="scurve")
    curve, lim = plan.smoothed.curve, PathLimits.of(machine)

    def retimed(effort):
        return jerk_retime.retime_curvature_bound(plan.law, curve, lim,
                                                  lambda u: plan.smoothed.seg_feed[curve.segment_at(u)],
                                                  machine.period, effort=effort)

    planned = retimed(jerk_retime.PLANNED)
    harder = retimed(jerk_retime.Effort(step_periods=2.0, rounds=4, gain=0.0))
    assert planned is not None and harder is not None
    assert len(harder[0]) < len(planned[0])
    v, a, j = peaks(harder[2], machine.period)
    assert j <= 5000.0 and a <= 200.0 and v <= 200.0


def test_a_retimed_stretch_that_breaks_a_limit_is_retimed_again_without_that_part(monkeypatch):
    # the first stitched samples are made to break a limit in the middle of a stretch: the stretch is not
    # dropped whole, its parts either side are retimed again and kept (faster than the time law alone)
    monkeypatch.setattr(jerk_retime, "_BOUND_SHARE", 0.1)
    machine = cam_machine()
    plan = plan_smooth(gosper(3, 0.03), machine, tolerance=0.05, profile="scurve")
    curve, lim = plan.smoothed.curve, PathLimits.of(machine)
    real_over, real_split, real_stitch = jerk_retime._over_limits, jerk_retime._split, jerk_retime._stitch
    calls, parts, spans = [], [], []

    def stitch(*args):
        out = real_stitch(*args)
        spans.append(out[2])
        return out

    def over_once(positions, lim_):  # first: a break in the middle of the longest retimed window
        calls.append(len(positions))
        a, b = max(spans[0], key=lambda ab: ab[1] - ab[0])
        return np.array([int(0.5 * (a + b) / machine.period)]) if len(calls) == 1 else real_over(positions, lim_)

    def split(k0, k1, at):
        parts.append(real_split(k0, k1, at))
        return parts[-1]

    monkeypatch.setattr(jerk_retime, "_over_limits", over_once)
    monkeypatch.setattr(jerk_retime, "_split", split)
    monkeypatch.setattr(jerk_retime, "_stitch", stitch)
    out = jerk_retime.retime_curvature_bound(plan.law, curve, lim, lambda u: plan.smoothed.seg_feed[curve.segment_at(u)],
                                             machine.period)
    assert out is not None
    (a0, a1), (b0, b1) = parts[0]  # the first split: two parts, 2 _SPLIT_GAP samples apart
    assert a1 < b0 and b0 - a1 == 2 * jerk_retime._SPLIT_GAP
    law_alone, _ = sample_time_law(plan.law, curve, machine.period)
    assert len(out[0]) < len(law_alone)
    v, a, j = peaks(out[2][:, :2], machine.period)
    assert j <= 5000.0 and a <= 200.0 and v <= 200.0
