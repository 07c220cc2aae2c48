"""The jerk-limited (S-curve) profiles, judged from their sampled setpoints: per-axis acceleration and jerk
against the limits, on the example graphs' paths and on CAM-like programs."""

from __future__ import annotations

from pathlib import Path as FsPath

import numpy as np

import flowmc
from flowmc.motion.lookahead import plan_lookahead
from flowmc.motion.machine import Machine
from flowmc.motion.path import Path

GRAPHS = FsPath(__file__).resolve().parents[2] / "graphs"


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
