"""The smoothing fit's runs are independent: fitted together or one by one, each run gets the same curve.

That is what lets the fit solve only the runs that still miss the tolerance (and re-parameterise only
those), so it must hold for runs next to each other in the stacked arrays whose data differ."""

import numpy as np

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
