"""Programs for device tests: the thesis pattern as a trajectory and straight moves (the fixtures are
in conftest.py)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from flowmc.motion.profiles import plan_trapezoid, sample_profile
from flowmc.motion.segment_table import path_from_rows
from flowmc.motion.trajectory import Trajectory

PATTERN = Path(__file__).resolve().parents[1] / "data" / "reference" / "thesis_pattern.json"


def thesis_path(feed: float = 20.0):
    return path_from_rows(json.loads(PATTERN.read_text())["segments"], feed=feed)


def thesis_trajectory(period: float = 0.001, feed: float = 20.0, amax: float = 200.0) -> Trajectory:
    """The six-segment pattern, each segment a trapezoid from rest to rest (the thesis card's way)."""
    path = thesis_path(feed)
    pts, seg = [np.zeros((1, 3))], [np.zeros(1, dtype=int)]
    for i, s in enumerate(path.segments):
        along = sample_profile(plan_trapezoid(s.length, 0.0, 0.0, feed, amax), period)
        pts.append(s.point_at(along[1:]))
        seg.append(np.full(len(along) - 1, i))
    return Trajectory(np.vstack(pts), period, np.concatenate(seg), segment_names=path.segment_names())


def line_trajectory(start, end, period: float = 0.001, feed: float = 50.0, amax: float = 200.0,
                    axes=("X", "Y", "Z")) -> Trajectory:
    """A straight move from rest to rest."""
    start, end = np.asarray(start, float), np.asarray(end, float)
    length = float(np.linalg.norm(end - start))
    s = sample_profile(plan_trapezoid(length, 0.0, 0.0, feed, amax), period)
    return Trajectory(start + np.outer(s / length, end - start), period, axes=axes)
