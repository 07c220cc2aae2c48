"""Curved stretches reshaped within the tolerance band for per-axis acceleration limits (flowmc.motion.reshape)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from flowmc.motion.machine import Axis, Machine
from flowmc.motion.metrics import contour_error, coverage_error, peak_ratio, programmed_polyline
from flowmc.motion.path import Arc, Path
from flowmc.motion.planner import plan_smooth

TOL = 0.05


def machine() -> Machine:
    return Machine(axes=tuple(Axis(name=n, min=-500, max=500, vmax=200, amax=200, jmax=5000.0) for n in "XYZ"),
                   period=0.001)


def full_circle(r: float = 18.0) -> Path:
    start = (r * math.cos(-0.75 * math.pi), r * math.sin(-0.75 * math.pi), 0.0)
    return Path([Arc(start, start, (0.0, 0.0, 0.0), ccw=False)]).with_feed(200.0)


def assert_within_limits_and_band(p, path: Path) -> None:
    """Per-axis velocity and acceleration from the samples at most the limits; within TOL of the path both ways."""
    limits = np.full(3, 200.0)
    assert peak_ratio(p.trajectory, limits, order=1) <= 1.0 + 1e-9
    assert peak_ratio(p.trajectory, limits, order=2) <= 1.0 + 1e-6
    programmed = programmed_polyline(path)
    assert contour_error(p.trajectory.positions, programmed) <= TOL
    assert coverage_error(p.trajectory.positions, programmed) <= TOL


def test_a_circle_is_passed_as_a_rounded_square_within_the_band_and_faster():
    # at 200 mm/s^2 per axis a circle loads one axis fully where its normal is parallel to an axis and each
    # only 1/sqrt(2) where it is diagonal; flatter at the axes and sharper at the diagonals, the curve is
    # passed faster: 2.118 s on the programmed circle (r = 18 mm, from rest to rest), under 2.10 s reshaped
    path = full_circle()
    p = plan_smooth(path, machine())
    assert p.cycle_time < 2.10
    xy = p.trajectory.positions[:, :2]
    radius = np.linalg.norm(xy, axis=1) - 18.0
    angle = np.degrees(np.arctan2(xy[:, 1], xy[:, 0]))
    for at, side in ((0.0, -1), (90.0, -1), (180.0, -1), (-90.0, -1), (45.0, 1), (135.0, 1), (-45.0, 1)):
        near = np.abs((angle - at + 180.0) % 360.0 - 180.0) < 2.0
        assert side * radius[near].mean() > 0.6 * TOL  # inside at the axes, outside at the diagonals
    assert_within_limits_and_band(p, path)
    assert p.smoothed.deviation <= TOL


def test_a_spiral_of_short_lines_is_passed_as_rounded_squares_within_the_band_and_faster():
    # three turns of 1 mm lines from r = 20 to 12 mm, fitted as one run and then reshaped as a whole (not in
    # parts held at both ends): inside at the axes and outside at the diagonals on its middle turn, within
    # the tolerance of the lines both ways; 5.476 s fitted only, under 5.45 s reshaped
    t = np.linspace(0.0, 6.0 * math.pi, 361)
    r = 20.0 - 8.0 * t / (6.0 * math.pi)
    path = Path.polyline(np.c_[r * np.cos(t), r * np.sin(t)], feed=200.0)
    p = plan_smooth(path, machine())
    assert p.smoothed.fitted == 1 and p.cycle_time < 5.45
    xy = p.trajectory.positions[:, :2]
    turned = np.unwrap(np.arctan2(xy[:, 1], xy[:, 0]))
    off = np.linalg.norm(xy, axis=1) - (20.0 - 8.0 * turned / (6.0 * math.pi))
    angle = np.degrees(turned)
    middle = (turned > 2.0 * math.pi) & (turned < 4.0 * math.pi)
    for at in range(0, 360, 45):
        near = middle & (np.abs((angle - at + 180.0) % 360.0 - 180.0) < 2.0)
        assert (1 if at % 90 else -1) * off[near].mean() > 0.6 * TOL
    assert_within_limits_and_band(p, path)


def test_jerk_limited_plans_keep_the_programmed_arc():
    # the reshaped curve joins its neighbours tangent-continuously only, so S-curve plans keep the arc
    p = plan_smooth(full_circle(), machine(), profile="scurve")
    radius = np.linalg.norm(p.trajectory.positions[:, :2], axis=1) - 18.0
    assert np.abs(radius).max() < 1e-6


def test_a_curly_run_is_not_reshaped():
    # a Gosper curve of short lines (as flowsnake.ngc) curls both ways: its fitted run nets over 1.5 pi of
    # turning, and a rounded square is nothing to it (flowsnake's linear program cost 2 s of CPU for no gain,
    # 2,401 lines 0.0143 mm long 90 s); only runs that turn nearly all one way are (reshape._ONE_WAY)
    from flowmc.motion.limits import PathLimits
    from flowmc.motion.reshape import reshape_curved
    from flowmc.motion.smoothing import fit_tolerance, raw_curve, smooth_path
    from tests.motion.test_jerk_retime import gosper

    path, lim = gosper(3, 0.03), PathLimits.of(machine())
    sm = smooth_path(path, lim, TOL)
    assert reshape_curved(sm.curve, raw_curve(path)[0], sm.stop_u, sm.seg_feed, lim, fit_tolerance(lim, TOL)) == []


@pytest.mark.linuxcnc  # spiral.ngc comes with LinuxCNC's package (a skipped linuxcnc test fails the suite)
def test_a_fitted_run_whose_curvature_passes_through_zero_is_offset_on_one_side():
    # LinuxCNC's spiral.ngc: past the plunge's corner the fit of its 4 mm lines wiggles, its curvature passing
    # through zero (the principal normal flips there); offsets along a flipping normal zigzag, and reshaped from
    # u = 106 mm the plan was 89 ms slower than not reshaped; offset on one side it is faster
    from flowmc.motion.gcode import read_gcode
    from flowmc.motion.limits import PathLimits
    from flowmc.motion.planner import _feed
    from flowmc.motion.reshape import _clock, _reshape_stretch, _splice
    from flowmc.motion.smoothing import fit_tolerance, raw_curve, smooth_path
    from flowmc.motion.timelaw import plan_time_law

    path = read_gcode("/usr/share/linuxcnc/ncfiles/spiral.ngc").with_feed(200.0)
    lim = PathLimits.of(machine())
    sm = smooth_path(path, lim, TOL)
    curve = sm.curve
    end = sm.stop_u[np.searchsorted(sm.stop_u, 106.0)]
    ka, kb = (int(k) for k in curve.interval_at(np.array([106.0, end - 1e-9])))
    inv_a = np.full(3, 1.0 / 200.0)
    got = _reshape_stretch(curve, raw_curve(path)[0], ka, kb, inv_a, fit_tolerance(lim, TOL))
    assert got is not None and got[1] <= TOL

    def planned(c):
        law = plan_time_law(c, sm.stop_u, sm.stop_dwell, sm.stop_segment, _feed(sm.seg_feed, c), lim)
        return _clock(law, [c.length])[0]

    assert planned(_splice(curve, [(ka, kb, got[0])])) < planned(curve) - 0.05


def test_the_check_says_where_a_reshaped_stretch_misses_the_tolerance():
    # a quarter circle moved out by 0.06 mm between 10 and 15 mm along it: the check finds it there only, so the
    # band is narrowed there (and the linear program solved again) instead of halving the offset all along
    from scipy.interpolate import CubicSpline
    from scipy.spatial import cKDTree

    from flowmc.motion.reshape import _deviation
    from flowmc.motion.smoothing import raw_curve

    r = 20.0
    path = Path([Arc((r, 0.0, 0.0), (0.0, r, 0.0), (0.0, 0.0, 0.0), ccw=True)]).with_feed(200.0)
    curve, _ = raw_curve(path)
    s = np.linspace(0.0, curve.length, 400)
    bump = 0.06 * np.clip(1.0 - np.abs(s - 12.5) / 2.5, 0.0, 1.0)
    points = curve.points(s) * (1.0 + bump / r)[:, None]
    spline = CubicSpline(s, points, axis=0)
    programmed = curve.points(np.linspace(0.0, curve.length, 4000))
    dev, miss = _deviation(spline, 0.0, curve.length, curve, cKDTree(programmed), programmed, TOL)
    assert 0.055 < dev < 0.061
    assert len(miss) and miss.min() > 10.0 and miss.max() < 15.0


def test_short_gaps_between_a_fitted_runs_bound_samples_are_bridged():
    # samples 0.5 mm apart: a 1 mm gap (two samples) inside a fitted run is bridged, a 2.5 mm one is not, nor
    # one with a sample not on the fitted run
    from flowmc.motion.reshape import _bridged

    bound = np.array([1, 1, 0, 0, 1, 1, 0, 0, 0, 0, 0, 1, 1, 0, 0, 1], dtype=bool)
    fitted = np.ones(len(bound), dtype=bool)
    fitted[13] = False
    assert _bridged(bound, fitted).astype(int).tolist() == [1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0, 1, 1, 0, 0, 1]
