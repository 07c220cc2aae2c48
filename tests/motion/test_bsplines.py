"""flowmc.motion.bsplines: many runs' cubic B-splines at once give what scipy's BSpline gives run by run."""

import numpy as np
from scipy.interpolate import BSpline

from flowmc.motion.bsplines import RunKnots


def _runs(overlap: bool):
    rng = np.random.default_rng(7)
    a = np.array([0.0, 5.0, 9.0]) if not overlap else np.array([0.0, 3.0, 4.0])
    width, spans = np.array([5.0, 3.0, 7.5]), np.array([10, 12, 17])
    offset = np.r_[0, np.cumsum(spans + 3)[:-1]]
    coef = rng.normal(size=(int((spans + 3).sum()), 3))
    x = [np.r_[np.sort(rng.uniform(lo, lo + w, 97)), lo, lo + w, lo + w * np.arange(1, s) / s]
         for lo, w, s in zip(a, width, spans)]
    run = np.concatenate([np.full(len(xs), r) for r, xs in enumerate(x)])
    return RunKnots(a, width, spans, offset), coef, run, np.concatenate(x)


def test_knots_are_numpy_linspace_clamped():
    rng = np.random.default_rng(3)
    a, w, s = rng.uniform(0, 100, 50), rng.uniform(0.01, 50, 50), rng.integers(10, 300, 50)
    rk = RunKnots(a, w, s, np.r_[0, np.cumsum(s + 3)[:-1]])
    for k, lo, ww, ss in zip(rk.knots, a, w, s):
        np.testing.assert_array_equal(k, np.r_[[lo] * 3, np.linspace(lo, lo + ww, ss + 1), [lo + ww] * 3])


def test_design_rows_and_derivatives_match_scipy_run_by_run():
    for overlap in (False, True):  # runs whose stretches overlap still search their own knots
        rk, coef, run, x = _runs(overlap)
        span = rk.span(run, x)
        basis = rk.basis(span, x)
        values = rk.evaluate(coef, run, x, 3)
        np.testing.assert_array_equal(rk.evaluate(coef, run, x, 3, only=(2, 1))[0], values[2])  # just some
        for r in range(3):
            sel = run == r
            design = BSpline.design_matrix(x[sel], rk.knots[r], 3).toarray()
            mine = np.zeros_like(design)
            first = rk.first_cp(run[sel], span[sel]) - rk.offset[r]
            for j in range(4):
                mine[np.arange(sel.sum()), first + j] = basis[sel, j]
            np.testing.assert_allclose(mine, design, rtol=0, atol=1e-15)
            spl = BSpline(rk.knots[r], coef[rk.offset[r]:rk.offset[r] + rk.spans[r] + 3], 3)
            for m in range(4):
                np.testing.assert_allclose(values[m][sel], spl(x[sel], nu=m), rtol=1e-12, atol=1e-12)


def test_runs_of_given_knots_evaluate_as_the_runs_that_made_them():
    """RunKnots.of (a fit's knots, kept run by run) gives the same values as the equal-span runs they came from,
    at the spans' first knots too (where the smoothing takes each span's power coefficients)."""
    rk, coef, run, x = _runs(False)
    again = RunKnots.of(rk.knots, rk.offset)
    np.testing.assert_array_equal(again.flat, rk.flat)
    at_knots = np.concatenate([k[3:-4] for k in rk.knots])
    knot_run = np.repeat(np.arange(3), rk.spans)
    for r, xs in ((run, x), (knot_run, at_knots)):
        for mine, theirs in zip(again.evaluate(coef, r, xs, 3), rk.evaluate(coef, r, xs, 3)):
            np.testing.assert_array_equal(mine, theirs)
