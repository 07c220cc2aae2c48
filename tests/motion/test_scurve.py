"""The jerk-limited (S-curve) profiles, judged from their sampled setpoints: per-axis acceleration and jerk
against the limits, on the example graphs' paths and on CAM-like programs."""

from __future__ import annotations

import json
from pathlib import Path as FsPath

import numpy as np

import flowmc
from flowmc.motion import timelaw
from flowmc.motion.limits import PathLimits
from flowmc.motion.lookahead import plan_lookahead
from flowmc.motion.machine import Axis, Machine
from flowmc.motion.path import Path
from flowmc.motion.planner import plan_smooth
from flowmc.motion.smoothing import smooth_path

GRAPHS = FsPath(__file__).resolve().parents[2] / "graphs"
REF = FsPath(__file__).resolve().parents[1] / "data" / "reference" / "paths"


def arm_lookahead_path() -> Path:
    """The path of the ARM look-ahead example graph (the 'mixed' reference path), as the graph builds it."""
    graph = flowmc.load(GRAPHS / "arm_lookahead.flowmc.json")
    node = next(n for n in graph.nodes if n.id == "path")
    return Path.polyline(node.params["points"], feed=node.params["feed"])


def sampled_accel(positions: np.ndarray, period: float) -> np.ndarray:
    """Per-axis acceleration by second differences of the setpoints (N-2, axes)."""
    return np.diff(positions, 2, axis=0) / period**2


def test_junction_deviation_scurve_keeps_every_axis_within_its_acceleration_limit():
    # An S-curve promises bounded acceleration: a corner passed at speed may turn the velocity only by
    # what a*T allows within one period (per axis), whatever the junction rule lets through.
    machine = Machine(period=0.004)
    plan = plan_lookahead(arm_lookahead_path(), machine, rule="junction_deviation", tolerance=0.05,
                          profile="scurve")
    amax = np.array([ax.amax for ax in machine.axes])
    acc = np.abs(sampled_accel(plan.trajectory.positions, machine.period))
    assert np.max(acc / amax) <= 1.01  # 1 % for rounding of the corner's sample phase
    assert len(plan.corner_times) > 0  # corners are still passed at speed, not stopped at


def cam_machine(jerk: float = 5000.0, period: float = 0.001) -> Machine:
    """The CAM benchmark's machine: per-axis 200 mm/s, 200 mm/s^2 and ``jerk`` mm/s^3."""
    return Machine(axes=tuple(Axis(name=n, min=-500, max=500, vmax=200, amax=200, jmax=jerk) for n in "XYZ"),
                   period=period)


def wiggle() -> Path:
    """Dense, tightly curved code (like flowsnake): 500 chords along a sine of 0.5 mm amplitude, 1.6 mm period."""
    x = np.linspace(0.0, 10.0, 501)
    return Path.polyline(np.c_[x, 0.5 * np.sin(4.0 * x), np.zeros_like(x)], feed=200.0)


def test_dense_curved_code_takes_the_short_filter_and_keeps_every_limit(monkeypatch):
    # the curvature terms hold the tangential acceleration far below amax here, so a filter half as long
    # (half the reach, half the rests) is faster; the per-axis limits hold from the sampled setpoints
    # (positions exact to about 1e-13 mm: sampling noise in the jerk stays below 1e-3 mm/s^3)
    machine = cam_machine()
    plan = plan_smooth(wiggle(), machine, tolerance=0.05, profile="scurve")
    assert plan.jerk_window == 0.5 * 200.0 / 5000.0
    q, T = plan.trajectory.positions, machine.period
    assert np.abs(np.diff(q, 3, axis=0)).max() / T**3 <= 5000.0
    assert np.abs(np.diff(q, 2, axis=0)).max() / T**2 <= 200.0
    assert np.abs(np.diff(q, axis=0)).max() / T <= 200.0
    monkeypatch.setattr(timelaw, "_WINDOWS", (1.0,))
    full = plan_smooth(wiggle(), machine, tolerance=0.05, profile="scurve")

    def law_time(p):  # the time law's own motion (flowmc.motion.jerk_retime then retimes both)
        return (len(timelaw.sample_time_law(p.law, p.smoothed.curve, T)[0]) - 1) * T
    assert full.jerk_window == 200.0 / 5000.0 and law_time(plan) < law_time(full)


def test_straight_code_keeps_the_full_filter():
    # zigzag40's 5 mm lines accelerate at the limit most of the time: the full window, one plan
    data = json.loads((REF / "zigzag40.json").read_text())
    plan = plan_smooth(Path.polyline(data["points"], feed=200.0), cam_machine(), tolerance=0.05, profile="scurve")
    assert plan.jerk_window == 200.0 / 5000.0
    q, T = plan.trajectory.positions, 0.001
    assert np.abs(np.diff(q, 3, axis=0)).max() / T**3 <= 5000.0


#: A random walk of 32 lines (10-50 mm, turns of about 0.3 rad; numpy's default_rng(18)) on which a jerk-limited
#: law planned without mending the swings of its acceleration breaks the jerk limit (1.027 x at j = 500 mm/s^3,
#: T = 1 ms): a margin the last bits of another numpy, scipy or CPU do not erase (the walk used before broke it by
#: 1.004 x on one machine and kept it, 0.995 x, on another).
SWINGING = [[-400.0, -200.0], [-374.070, -201.487], [-336.244, -193.326], [-317.039, -184.269], [-305.012, -178.570],
            [-258.561, -163.642], [-237.514, -138.803], [-219.085, -108.143], [-193.484, -87.201],
            [-171.003, -68.859], [-159.150, -59.837], [-144.565, -42.647], [-117.059, -14.370], [-78.269, 10.901],
            [-52.858, 48.697], [-8.364, 66.526], [2.642, 66.051], [41.376, 58.201], [75.988, 45.399],
            [108.335, 32.011], [141.093, 18.319], [156.074, 16.868], [185.906, -1.525], [224.979, 12.410],
            [233.884, 17.579], [278.715, 31.156], [293.826, 33.019], [318.848, 32.462], [343.515, 12.033],
            [372.390, -6.534], [392.147, -31.678], [404.451, -54.024], [412.302, -98.549]]


def _law_jerk(path: Path, machine: Machine, mend_swings: bool) -> tuple[float, float]:
    """Duration and sampled per-axis jerk over the limit of the jerk-limited law alone, swings mended or not."""
    lim = PathLimits.of(machine)
    sm = smooth_path(path, lim, 0.05, continuity=2)
    law = timelaw.plan_time_law(sm.curve, sm.stop_u, sm.stop_dwell, sm.stop_segment,
                                lambda u: sm.seg_feed[sm.curve.segment_at(u)], lim, jerk=True, mend_swings=mend_swings)
    u, _ = timelaw.sample_time_law(law, sm.curve, machine.period)
    return (len(u) - 1) * machine.period, timelaw.sampled_jerk(sm.curve.points(u)[:, list(lim.cols)], lim)


def test_a_law_whose_samples_break_the_jerk_limit_is_planned_again_with_its_swings_mended():
    path = Path.polyline(np.c_[np.array(SWINGING), np.zeros(len(SWINGING))], feed=200.0)
    machine = cam_machine(jerk=500.0)
    assert _law_jerk(path, machine, mend_swings=False)[1] > 1.0  # the first try breaks it
    plan = plan_smooth(path, machine, tolerance=0.05, profile="scurve")
    q, T = plan.trajectory.positions, machine.period
    assert np.abs(np.diff(q, 3, axis=0)).max() / T**3 <= 500.0


def test_plan_jerk_limited_gives_the_laws_plan_time_law_gives_unmended_and_mended():
    path = Path.polyline(np.c_[np.array(SWINGING), np.zeros(len(SWINGING))], feed=200.0)
    lim = PathLimits.of(cam_machine(jerk=500.0))
    sm = smooth_path(path, lim, 0.05, continuity=2)
    args = (sm.curve, sm.stop_u, sm.stop_dwell, sm.stop_segment, lambda u: sm.seg_feed[sm.curve.segment_at(u)], lim)
    first, mended = timelaw.plan_jerk_limited(*args)
    again = mended()
    for law, fresh in ((first, timelaw.plan_time_law(*args, jerk=True, mend_swings=False)),
                       (again, timelaw.plan_time_law(*args, jerk=True, mend_swings=True))):
        assert law.window == fresh.window
        assert np.array_equal(law.y, fresh.y) and np.array_equal(law.u, fresh.u)
    assert not np.array_equal(again.y, first.y)  # this walk's swings needed mending


def test_samples_of_counts_the_samples_of_a_law_without_sampling_it():
    path = Path.polyline(np.c_[np.array(SWINGING), np.zeros(len(SWINGING))], feed=200.0)
    machine = cam_machine(jerk=500.0)
    lim = PathLimits.of(machine)
    sm = smooth_path(path, lim, 0.05, continuity=2)
    args = (sm.curve, sm.stop_u, sm.stop_dwell, sm.stop_segment, lambda u: sm.seg_feed[sm.curve.segment_at(u)], lim)
    first, mended = timelaw.plan_jerk_limited(*args)
    for law in (first, mended()):
        u, _ = timelaw.sample_time_law(law, sm.curve, machine.period)
        assert timelaw.samples_of(law, machine.period) == len(u)


def test_a_law_within_the_jerk_limit_keeps_its_swings_unmended_and_is_faster():
    # mixed at j = 500: mending the swings everywhere costs 2 % and was not needed (sampled jerk 0.99 x)
    data = json.loads((REF / "mixed.json").read_text())
    path = Path.polyline(data["points"], feed=200.0)
    machine = cam_machine(jerk=500.0, period=0.004)
    plan = plan_smooth(path, machine, tolerance=0.05, profile="scurve")
    mended, _ = _law_jerk(path, machine, mend_swings=True)
    assert plan.cycle_time < 0.99 * mended
    q, T = plan.trajectory.positions, machine.period
    assert np.abs(np.diff(q, 3, axis=0)).max() / T**3 <= 500.0


def test_a_short_move_between_two_stops_is_planned_not_left_at_rest():
    # 11 lines of 0.4-2 mm, most corners sharp (stops): a move between two stops used to get one grid node
    # inside, so its speed peak could only be cut flat to rest (1e299 s of motion, refused by the budget)
    pts = [[0.0, 0.0], [0.069, -1.478], [-0.032, -0.988], [-0.133, 0.749], [-0.814, -1.083], [-2.361, -1.882],
           [-2.072, -2.181], [-1.807, -3.307], [-0.731, -2.504], [1.08, -2.316], [-0.121, -2.233], [-0.532, -1.908]]
    machine = cam_machine(jerk=500.0, period=0.004)
    plan = plan_smooth(Path.polyline(np.c_[np.array(pts), np.zeros(len(pts))], feed=200.0), machine,
                       tolerance=0.05, profile="scurve")
    assert plan.cycle_time < 10.0  # 11 rests of Tj = 0.4 s and the moves between them
    q, T = plan.trajectory.positions, machine.period
    assert np.abs(np.diff(q, 3, axis=0)).max() / T**3 <= 500.0
