"""The smoothing fit's runs are independent: fitted together or one by one, each run gets the same curve.

That is what lets the fit solve only the runs that still miss the tolerance (and re-parameterise only
those), so it must hold for runs next to each other in the stacked arrays whose data differ. And a fit that
bounds each way of the deviation on its own (the bending fits of fine zigzags) keeps the tolerance both ways."""

import numpy as np
from scipy.interpolate import BSpline

from flowmc.motion.metrics import contour_error, farthest_from, programmed_polyline
from flowmc.motion.path import Path
from flowmc.motion.smoothing import _RunFitter, raw_curve


def _wavy_path() -> Path:
    # a wave drawn with fine chords (0.05 mm) on its first half and coarse ones (0.6 mm) on the second
    x = np.r_[np.arange(0.0, 30.0, 0.05), np.arange(30.0, 60.0001, 0.6)]
    return Path.polyline(np.c_[x, 1.5 * np.sin(x / 2.0)], feed=200.0)


def test_runs_fitted_together_get_the_curves_they_get_alone():
    raw, _ = raw_curve(_wavy_path())
    ua, ub = np.array([5.0, 32.0]), np.array([29.0, 58.0])  # one run in each half
    free = np.zeros(2, dtype=bool)
    h = np.array([0.02, 0.24])
    tol = 0.01
    both = _RunFitter(raw, ua, ub, free, free, tol, h).fit()
    assert both.ok[0] and both.deviation[0] <= tol  # the fine run holds the tolerance at once
    for r in range(2):
        alone = _RunFitter(raw, ua[r:r + 1], ub[r:r + 1], free[:1], free[:1], tol, h[r:r + 1]).fit()
        n = len(alone.coef)
        np.testing.assert_allclose(both.coef[both.offset[r]:both.offset[r] + n], alone.coef, rtol=0, atol=1e-9)
        np.testing.assert_array_equal(both.knots[r], alone.knots[0])
        assert both.ok[r] == alone.ok[0] and abs(both.deviation[r] - alone.deviation[0]) <= 1e-9


def test_free_end_at_a_tight_spiral_centre_takes_the_direction_it_arrives_in():
    # LinuxCNC's spiral.ngc in mm, its last 2.5 turns: 4.5 degree steps, 0.0635 mm nearer the centre each,
    # ending there; the last 2 mm turn about 2.6 rad, so a quadratic over them points about 39 degrees off
    k = np.arange(161)
    r, th = 0.0635 * (160 - k), np.radians(4.5) * k
    pts = np.c_[r * np.cos(th), r * np.sin(th)]
    raw, _ = raw_curve(Path.polyline(pts, feed=200.0))
    fit = _RunFitter(raw, np.array([1.0]), np.array([raw.u1[-1]]), np.array([False]), np.array([True]), 0.05,
                     np.array([0.1]))
    last = (pts[-1] - pts[-2]) / np.linalg.norm(pts[-1] - pts[-2])
    assert np.degrees(np.arccos(fit.end_tangent[1][0, :2] @ last)) < 10.0


def test_a_bending_fit_that_slides_along_a_koch_curve_keeps_the_tolerance_both_ways():
    # a Gosper curve of 0.02 mm lines (finer than the tolerance): with the bending penalty the curve may slide
    # along the path, each way of the deviation bounded on its own; measured densely, both ways hold
    rules = {"A": "A-B--B+A++AA+B-", "B": "+A-AA++A+B--B-A"}
    word = "A"
    for _ in range(3):
        word = "".join(rules.get(ch, ch) for ch in word)
    turn = np.pi / 3 * np.cumsum([{"+": 1, "-": -1}.get(ch, 0) for ch in word])[[i for i, ch in enumerate(word) if ch in "AB"]]
    pts = np.vstack([[0.0, 0.0], np.cumsum(0.02 * np.c_[np.cos(turn), np.sin(turn)], axis=0)])
    path = Path.polyline(np.c_[pts, np.zeros(len(pts))], feed=200.0)
    raw, _ = raw_curve(path)
    tol, ua, ub, free = 0.049, np.array([0.3]), np.array([raw.u1[-1] - 0.3]), np.zeros(1, dtype=bool)
    fit = _RunFitter(raw, ua, ub, free, free, tol, np.array([0.05]), order=3, ell_segments=2.2, bend=50.0).fit()
    assert fit.ok[0]
    knots = fit.knots[0]
    curve = BSpline(knots, fit.coef[:len(knots) - 4], 3)(np.linspace(knots[0], knots[-1], 40001))
    programmed = raw.points(np.linspace(ua[0], ub[0], 40001))
    assert contour_error(curve, programmed_polyline(path)) <= tol + 1e-4  # the curve to the path
    assert farthest_from(curve, programmed) <= tol + 1e-4  # the path to the curve
