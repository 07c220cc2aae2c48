"""Time-division interpolation: exact lines, arcs within the chord bound, and the radial drift of
the second-order rotation against the exact one."""

import math

import numpy as np
import pytest

from flowmc.errors import PathError
from flowmc.motion import timediv as td
from flowmc.motion.profiles import plan_scurve, plan_trapezoid, sample_profile

T = 0.004


def test_line_points_are_on_the_line_at_the_profile_distances():
    start, end = np.array([1.0, 2.0, 3.0]), np.array([31.0, -38.0, 3.0])
    length = 50.0
    s = sample_profile(plan_trapezoid(length, 0.0, 0.0, 200.0, 200.0), T)
    pts = td.line_points(start, end, s)
    assert np.array_equal(pts[0], start) and np.array_equal(pts[-1], end)
    assert np.allclose(np.linalg.norm(pts - start, axis=1), s, atol=1e-12)
    cross = np.cross(pts - start, end - start)
    assert np.abs(cross).max() < 1e-10


def test_arc_feed_limit_formula():
    assert td.arc_feed_limit(10.0, 0.001, 0.01) == pytest.approx(2000.0 * math.sqrt(0.2 - 1e-4))
    assert td.arc_feed_limit(0.001, 0.001, 0.01) == math.inf
    with pytest.raises(PathError):
        td.arc_feed_limit(-1.0, 0.001, 0.01)


@pytest.mark.parametrize("radius, eps", [(5.0, 1e-3), (20.0, 1e-3), (50.0, 1e-4), (2.0, 0.01)])
@pytest.mark.parametrize("method", ["exact", "second_order"])
def test_arc_chord_error_within_eps_at_the_clamped_feed(radius, eps, method):
    vmax = min(300.0, td.arc_feed_limit(radius, T, eps))
    centre = np.array([3.0, -4.0])
    start = centre + radius * np.array([1.0, 0.0])
    end = centre + radius * np.array([math.cos(2.5), math.sin(2.5)])
    _, _, length = td.arc_geometry(start, end, centre)
    assert length == pytest.approx(2.5 * radius)
    profile = plan_scurve(length, 0.0, 0.0, vmax, 5000.0, 1e5)
    pts = td.arc_points(start, end, centre, sample_profile(profile, T), method=method)
    chord, radial = td.circle_errors(pts, centre, radius)
    assert chord.max() <= eps * (1 + 1e-6)
    # where the move cruises at the clamped feed, its chords sit right at eps (the bound is tight)
    if vmax < 300.0 and profile.v_peak == vmax:
        assert chord.max() > 0.99 * eps
    assert np.array_equal(pts[-1], end)


def test_chord_error_grows_past_the_clamp():
    radius, eps = 5.0, 1e-3
    vmax = 1.5 * td.arc_feed_limit(radius, T, eps)
    s = sample_profile(plan_trapezoid(math.pi * radius, 0.0, 0.0, vmax, 1e5), T)
    pts = td.arc_points((radius, 0.0), (-radius, 0.0), (0.0, 0.0), s)
    assert td.circle_errors(pts, (0.0, 0.0), radius)[0].max() > 2.0 * eps  # ~ (1.5)^2 eps


def test_exact_recurrence_has_no_drift_second_order_drifts_outward_as_derived():
    # constant step angle d for n steps: the 2nd-order factor (1 - d^2/2) + i d has modulus
    # sqrt(1 + d^4/4), so after n steps the radius is R (1 + d^4/4)^(n/2) and the angle n (d + d^3/6) + O(d^5)
    radius, d, n = 20.0, 0.05, 120
    s = np.arange(n + 1) * d * radius  # stays inside the full circle (n d < 2 pi)
    exact = td.arc_points((radius, 0.0), (radius, 0.0), (0.0, 0.0), s, method="exact")
    approx = td.arc_points((radius, 0.0), (radius, 0.0), (0.0, 0.0), s, method="second_order")
    _, rad_exact = td.circle_errors(exact, (0.0, 0.0), radius)
    _, rad_approx = td.circle_errors(approx, (0.0, 0.0), radius)
    assert np.abs(rad_exact).max() < 1e-11
    assert np.all(np.diff(rad_approx) > 0)  # monotone outward
    assert rad_approx[-1] == pytest.approx(radius * ((1 + d**4 / 4) ** (n / 2) - 1), rel=1e-9)
    assert rad_approx[-1] == pytest.approx(radius * n * d**4 / 8, rel=1e-3)  # ~ 1.9 micron here
    ang = np.unwrap(np.arctan2(approx[:, 1], approx[:, 0]))
    assert ang[-1] == pytest.approx(n * (d + d**3 / 6), rel=1e-6)
    assert ang[-1] - n * d > 0  # the approximate rotation runs ahead


def test_arc_in_zx_plane_with_helix_both_directions():
    # plane (2, 0): in-plane coordinates (Z, X) as G18 orders them; Y rises linearly (helix)
    centre = np.array([0.0, 0.0, 0.0])
    start, end = np.array([0.0, 0.0, 10.0]), np.array([10.0, 5.0, 0.0])
    radius, sweep, length = td.arc_geometry(start, end, centre, ccw=True, plane=(2, 0))
    assert radius == 10.0 and sweep == pytest.approx(math.pi / 2)  # +Z to +X is a ccw quarter in (Z, X)
    assert length == pytest.approx(math.hypot(10.0 * math.pi / 2, 5.0))
    s = np.linspace(0, length, 101)
    pts = td.arc_points(start, end, centre, s, ccw=True, plane=(2, 0))
    assert np.allclose(np.hypot(pts[:, 0], pts[:, 2]), 10.0)
    assert np.allclose(pts[:, 1], 5.0 * s / length)
    assert np.all(pts[:, 0] >= -1e-9) and np.all(pts[:, 2] >= -1e-9)  # stays in the quarter
    _, sweep_cw, length_cw = td.arc_geometry(start, end, centre, ccw=False, plane=(2, 0))
    assert sweep_cw == pytest.approx(-3 * math.pi / 2)
    cw = td.arc_points(start, end, centre, np.linspace(0, length_cw, 101), ccw=False, plane=(2, 0))
    assert np.min(cw[:, 0]) < -9.9 and np.min(cw[:, 2]) < -9.9  # the long way round
    assert np.array_equal(cw[-1], end)


def test_bad_arc_is_a_path_error():
    with pytest.raises(PathError, match="not on the circle"):
        td.arc_geometry((10.0, 0.0), (0.0, 11.0), (0.0, 0.0))
    with pytest.raises(PathError, match="coincides"):
        td.arc_geometry((0.0, 0.0), (0.0, 11.0), (0.0, 0.0))
    with pytest.raises(PathError, match="method"):
        td.arc_points((10.0, 0.0), (0.0, 10.0), (0.0, 0.0), [0.0, 1.0], method="third")
