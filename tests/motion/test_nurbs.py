"""NURBS evaluation, arc length and the Taylor interpolator against the shared test curve."""

import json
from pathlib import Path

import numpy as np
import pytest

from flowmc.errors import PathError
from flowmc.motion import nurbs as N

REF = Path(__file__).resolve().parents[1] / "data" / "reference" / "nurbs_test_curve.json"


@pytest.fixture(scope="module")
def spec():
    return json.loads(REF.read_text())


@pytest.fixture(scope="module")
def curve(spec):
    ctrl = spec["control_points"]
    return N.Nurbs(ctrl, spec["weights"], N.clamped_uniform_knots(len(ctrl), spec["degree"]), spec["degree"])


def _de_boor_point(ctrl, weights, knots, p, u):
    """Independent scalar reference: Cox-de Boor basis functions, rational sum."""
    n = len(ctrl)

    def basis(i, k, x):
        if k == 0:
            last = knots[i + 1] == knots[-1] and x == knots[-1] and knots[i] < knots[i + 1]
            return 1.0 if (knots[i] <= x < knots[i + 1]) or last else 0.0
        left = 0.0 if knots[i + k] == knots[i] else (x - knots[i]) / (knots[i + k] - knots[i]) * basis(i, k - 1, x)
        right = 0.0 if knots[i + k + 1] == knots[i + 1] else \
            (knots[i + k + 1] - x) / (knots[i + k + 1] - knots[i + 1]) * basis(i + 1, k - 1, x)
        return left + right

    b = np.array([basis(i, p, u) for i in range(n)]) * weights
    return (b @ ctrl) / b.sum()


def test_clamped_uniform_knots():
    k = N.clamped_uniform_knots(9, 3)
    assert len(k) == 13
    assert np.all(k[:4] == 0) and np.all(k[-4:] == 1)
    assert np.allclose(np.diff(k[3:10]), 1 / 6)


def test_evaluation_matches_de_boor_and_hits_ends(spec, curve):
    ctrl = np.array(spec["control_points"], float)
    w = np.array(spec["weights"], float)
    u = np.array([0.0, 0.05, 0.2, 0.5, 0.77, 0.999, 1.0])
    pts = curve.evaluate(u)[0]
    ref = np.array([_de_boor_point(ctrl, w, curve.knots, 3, x) for x in u])
    assert np.allclose(pts, ref, atol=1e-10)
    assert np.allclose(pts[0], ctrl[0]) and np.allclose(pts[-1], ctrl[-1])


def test_derivatives_match_finite_differences(curve):
    u = np.linspace(0.01, 0.99, 37)
    h = 1e-5
    d = curve.evaluate(u, 2)
    p_plus, p_minus = curve.evaluate(u + h)[0], curve.evaluate(u - h)[0]
    assert d.shape == (3, len(u), 2)
    assert np.allclose(d[1], (p_plus - p_minus) / (2 * h), rtol=1e-6, atol=1e-4)
    assert np.allclose(d[2], (p_plus - 2 * d[0] + p_minus) / h**2, rtol=1e-3, atol=1.0)
    # the free function gives the same numbers
    free = N.evaluate(curve.ctrl, curve.weights, curve.knots, 3, u, nderiv=2)
    assert np.array_equal(free, d)


def test_test_curve_length_and_tightest_radius(spec, curve):
    assert abs(curve.length - 409.30) < 0.01
    free = N.arc_length(curve.ctrl, curve.weights, curve.knots, 3)
    assert free == pytest.approx(curve.length, abs=1e-9)
    # polyline through a million points underestimates by ~L h^2 k^2 / 24: far below 1e-6 mm
    u = np.linspace(0, 1, 1_000_001)
    poly = np.linalg.norm(np.diff(curve.evaluate(u)[0], axis=0), axis=1).sum()
    assert curve.length == pytest.approx(poly, abs=1e-6)
    kappa = N.curvature(curve.ctrl, curve.weights, curve.knots, 3, u)
    assert 1 / kappa.max() == pytest.approx(5.44, abs=0.005)


def test_curvature_of_a_rational_quarter_circle():
    # exact circle: quadratic NURBS with middle weight sqrt(2)/2
    r = 7.0
    c = N.Nurbs([[r, 0], [r, r], [0, r]], [1, np.sqrt(0.5), 1], [0, 0, 0, 1, 1, 1], 2)
    u = np.linspace(0, 1, 50)
    assert np.allclose(np.linalg.norm(c.evaluate(u)[0], axis=1), r)
    assert np.allclose(c.curvature(u), 1 / r)
    assert c.length == pytest.approx(np.pi * r / 2, rel=1e-12)
    assert c.arc_length(0.0, 0.5) == pytest.approx(np.pi * r / 4, rel=1e-12)


def test_arc_length_inverse(curve):
    s = np.linspace(0, curve.length, 2001)
    u = N.u_at_length(curve.ctrl, curve.weights, curve.knots, 3, s)
    assert np.all(np.diff(u) > 0)
    assert np.max(np.abs(curve.table.s_at(u) - s)) < 1e-9
    # partial arc lengths add up
    assert curve.arc_length(0, u[700]) + curve.arc_length(u[700], 1) == pytest.approx(curve.length, abs=1e-9)


def test_knot_count_error_names_field_and_counts():
    with pytest.raises(PathError) as err:
        N.check_nurbs([[0, 0], [1, 1], [2, 0], [3, 1]], [1, 1, 1, 1], [0, 0, 0, 0, 1, 1, 1], 3)
    msg = str(err.value)
    assert "nurbs.knots" in msg and "4 + 3 + 1 = 8" in msg and "got 7" in msg


@pytest.mark.parametrize("ctrl, weights, knots, degree, field, text", [
    ([[0, 0], [1, 1], [2, 0]], [1, 1, 1], [0, 0, 0, 1, 1, 1], 3, "control_points", "at least 4"),
    ([[0, 0], [1, 1], [2, 0], [3, 1]], [1, 1, 1], [0, 0, 0, 0, 1, 1, 1, 1], 3, "weights", "one weight"),
    ([[0, 0], [1, 1], [2, 0], [3, 1]], [1, 0, 1, 1], [0, 0, 0, 0, 1, 1, 1, 1], 3, "weights", "weight 1 is 0"),
    ([[0, 0], [1, 1], [2, 0], [3, 1], [4, 4]], [1] * 5, [0, 0, 0, 0, 0.6, 0.4, 1, 1, 1], 3, "knots",
     "non-decreasing"),
])
def test_bad_nurbs_errors(ctrl, weights, knots, degree, field, text):
    with pytest.raises(PathError) as err:
        N.Nurbs(ctrl, weights, knots, degree, where="row 4")
    assert f"row 4.{field}" in str(err.value) and text in str(err.value)


def _sequential(curve, sched, corrector):
    """Reference: the Taylor recurrence stepped one point at a time."""
    u = [curve.u0]
    while True:
        _, du, _, final = N._taylor_step(curve, sched, np.array([u[-1]]), corrector)
        u.append(curve.u1 if final[0] else min(u[-1] + du[0], curve.u1))
        if final[0]:
            return np.array(u)


@pytest.mark.parametrize("corrector", [True, False])
def test_block_solution_equals_sequential_recurrence(curve, corrector):
    sched = N.feed_schedule(curve, 200.0, 0.004, eps=1e-3, amax=1000.0)
    steps = N.taylor_steps(curve, 200.0, 0.004, corrector=corrector, schedule=sched, block=128)
    ref = _sequential(curve, sched, corrector)
    assert len(steps.u) == len(ref)
    assert np.max(np.abs(steps.u - ref)) < 1e-11


@pytest.mark.parametrize("feed, period", [(200.0, 0.004), (100.0, 0.001)])
def test_feed_fluctuation_and_chord_error_targets(curve, feed, period):
    # eps chosen so the chord-error limit is active on the tight corner in both conditions
    eps = 1e-3 if period == 0.004 else 1e-4
    steps = N.taylor_steps(curve, feed, period, eps=eps, amax=1000.0)
    assert np.array_equal(steps.points[0], curve.evaluate([0.0])[0][0])
    assert np.array_equal(steps.points[-1], curve.evaluate([1.0])[0][0])
    fluct = N.feed_fluctuation(steps)
    assert fluct.max() < 1e-6  # 1e-4 %
    chord = N.chord_errors(curve, steps.u)
    assert chord.max() <= 1.05 * eps
    assert chord.max() > 0.9 * eps  # the limit is really what bounds it
    # without the corrector the Taylor truncation error shows
    plain = N.feed_fluctuation(N.taylor_steps(curve, feed, period, eps=eps, amax=1000.0, corrector=False))
    assert plain.max() > 100 * fluct.max()


def test_constant_feed_taylor_error_is_about_a_third_of_a_percent(curve):
    # the classical figure: 200 mm/s, T = 4 ms, no feed adaptation, predictor only
    kw = dict(eps=np.inf, amax=np.inf)
    plain = N.feed_fluctuation(N.taylor_steps(curve, 200.0, 0.004, corrector=False, **kw))
    corrected = N.feed_fluctuation(N.taylor_steps(curve, 200.0, 0.004, corrector=True, **kw))
    assert 0.001 < plain.max() < 0.006
    assert corrected.max() < 1e-6


def test_feed_follows_acceleration_limited_schedule(curve):
    amax, period = 500.0, 0.004
    steps = N.taylor_steps(curve, 200.0, period, eps=1e-2, amax=amax)
    speed = np.linalg.norm(np.diff(steps.points, axis=0), axis=1) / period
    assert speed.max() <= 200.0 * (1 + 1e-6)
    assert speed[0] < 0.01 * 200 and speed[-1] < 0.01 * 200  # starts and ends at rest
    assert np.max(np.abs(np.diff(speed))) / period <= 1.01 * amax  # tangential acceleration
    # normal acceleration V^2 kappa stays within amax
    kappa = curve.curvature(steps.u[:-1])
    assert np.max(speed**2 * kappa) <= 1.01 * amax


def test_arc_measure_shows_chord_floor(curve):
    steps = N.taylor_steps(curve, 200.0, 0.004, eps=1e-3, amax=1000.0)
    arc = N.feed_fluctuation(steps, curve, measure="arc")
    # chord-matched steps are longer in arc by about L^2 k^2 / 24 (<= eps / (3 rho) here)
    assert 1e-6 < arc.max() < 1e-3 / (3 * 5.43) * 1.1


def test_more_corrector_steps_on_a_curve_tighter_than_the_step():
    # radius ~0.07 mm against 0.4 mm steps: one Newton step leaves ~1e-4, a second ~1e-9
    c = N.Nurbs([[0, 0], [0.1, 0.1], [0.2, 0], [0.3, 0.05]], [1, 2, 1, 1], N.clamped_uniform_knots(4, 3), 3)
    worst = [N.feed_fluctuation(N.taylor_steps(c, 100.0, 0.004, corrector=k))[:-1].max() for k in (0, 1, 2)]
    assert worst[0] > 1e-2 and 1e-6 < worst[1] < 1e-3 and worst[2] < 1e-8
