"""The jerk-limited (S-curve) profiles, judged from their sampled setpoints: per-axis acceleration and jerk
against the limits, on the example graphs' paths and on CAM-like programs."""

from __future__ import annotations

import json
from pathlib import Path as FsPath

import numpy as np

import flowmc
from flowmc.motion import timelaw
from flowmc.motion.lookahead import plan_lookahead
from flowmc.motion.machine import Axis, Machine
from flowmc.motion.path import Path
from flowmc.motion.planner import plan_smooth

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
    assert full.jerk_window == 200.0 / 5000.0 and plan.cycle_time < full.cycle_time


def test_straight_code_keeps_the_full_filter():
    # zigzag40's 5 mm lines accelerate at the limit most of the time: the full window, one plan
    data = json.loads((REF / "zigzag40.json").read_text())
    plan = plan_smooth(Path.polyline(data["points"], feed=200.0), cam_machine(), tolerance=0.05, profile="scurve")
    assert plan.jerk_window == 200.0 / 5000.0
    q, T = plan.trajectory.positions, 0.001
    assert np.abs(np.diff(q, 3, axis=0)).max() / T**3 <= 5000.0
