"""Velocity profiles: limits respected when sampled, exact ends, short-move and infeasible cases."""

import math

import numpy as np
import pytest

from flowmc.errors import PlanningError
from flowmc.motion.profiles import plan_exponential, plan_scurve, plan_trapezoid, sample_profile

VMAX, AMAX, JMAX = 200.0, 200.0, 500.0


def plan(kind, length, v0, v1, **kw):
    if kind == "trapezoid":
        return plan_trapezoid(length, v0, v1, VMAX, AMAX, **kw)
    if kind == "exponential":
        return plan_exponential(length, v0, v1, VMAX, AMAX, **kw)
    return plan_scurve(length, v0, v1, VMAX, AMAX, JMAX, **kw)


KINDS = ["trapezoid", "exponential", "scurve"]
MOVES = [
    (1500.0, 0.0, 0.0),    # long: cruise at vmax
    (10.0, 0.0, 0.0),      # short: no cruise
    (0.5, 0.0, 0.0),       # very short: S-curve does not reach amax
    (60.0, 50.0, 20.0),    # unequal end speeds
    (200.0, 150.0, 180.0),
    (3.0, 30.0, 30.0),     # short with equal nonzero ends
    (30.0, 40.0, 60.0),
]


def _check_sampled(p, length, v1):
    t = np.linspace(0.0, p.duration, 20001)
    s, v, a, j = p.sample(t)
    assert v.max() <= VMAX * 1.01
    assert np.abs(a).max() <= AMAX * 1.01
    if p.kind == "scurve":
        assert np.abs(j).max() <= JMAX * 1.01
    assert np.all(np.diff(s) >= -1e-12)  # never runs backwards
    assert s[-1] == length and v[-1] == p.v1
    # the closed-form state is self-consistent: s' = v, v' = a (finite differences, inside segments)
    h = 1e-6
    tm = np.linspace(0.01, 0.99, 97) * p.duration
    sp, vp, _, _ = p.sample(tm + h)
    sm, vm, _, _ = p.sample(tm - h)
    _, v_mid, a_mid, _ = p.sample(tm)
    assert np.allclose((sp - sm) / (2 * h), v_mid, atol=1e-4 * VMAX)
    inside = ~np.any(np.abs(tm[:, None] - p.t[None, :]) < 2 * h, axis=1)
    assert np.allclose(((vp - vm) / (2 * h))[inside], a_mid[inside], atol=1e-3 * AMAX)
    # position is continuous across segment joins and lands on L at the duration
    left = p.sample(p.t[1:-1] - 1e-12)[0]
    right = p.sample(p.t[1:-1])[0]
    assert np.allclose(left, right, atol=1e-9)
    assert p.sample(p.duration * (1 - 1e-12))[0] == pytest.approx(length, abs=1e-8)
    assert p.sample(p.duration * (1 - 1e-12))[1] == pytest.approx(v1, abs=1e-6 * VMAX)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("length, v0, v1", MOVES)
def test_limits_and_exact_end(kind, length, v0, v1):
    p = plan(kind, length, v0, v1)
    assert not p.lowered and p.v1 == v1 and p.v0 == v0
    _check_sampled(p, length, v1)
    s = sample_profile(p, 0.004)
    assert s[0] == 0.0 and s[-1] == length
    assert len(s) == math.ceil(p.duration / 0.004 - 1e-9) + 1


@pytest.mark.parametrize("kind", KINDS)
def test_long_move_cruises_at_vmax_short_move_does_not(kind):
    long_move = plan(kind, 1500.0, 0.0, 0.0)  # the exponential needs ~630 mm to reach vmax
    assert long_move.v_peak == VMAX
    t = np.linspace(0, long_move.duration, 10001)
    assert np.sum(np.isclose(long_move.sample(t)[1], VMAX)) > 100
    short = plan(kind, 10.0, 0.0, 0.0)
    assert short.v_peak < VMAX
    assert short.sample(np.linspace(0, short.duration, 10001))[1].max() == pytest.approx(short.v_peak, rel=1e-3)


def test_trapezoid_closed_forms():
    p = plan_trapezoid(10.0, 0.0, 0.0, VMAX, AMAX)
    assert p.v_peak == pytest.approx(math.sqrt(AMAX * 10.0))
    assert p.duration == pytest.approx(2 * math.sqrt(10.0 / AMAX))
    p = plan_trapezoid(400.0, 0.0, 0.0, VMAX, AMAX)
    assert p.duration == pytest.approx(400.0 / VMAX + VMAX / AMAX)


def test_scurve_reaches_amax_only_on_large_speed_changes():
    big = plan_scurve(400.0, 0.0, 0.0, VMAX, AMAX, JMAX)  # dv = 200 >= amax^2/jmax = 80
    assert np.abs(big.sample(np.linspace(0, big.duration, 20001))[2]).max() == pytest.approx(AMAX, rel=1e-6)
    small = plan_scurve(0.5, 0.0, 0.0, VMAX, AMAX, JMAX)  # peak speed far below 80
    a = np.abs(small.sample(np.linspace(0, small.duration, 20001))[2]).max()
    assert a < 0.9 * AMAX
    assert a == pytest.approx(math.sqrt(JMAX * small.v_peak), rel=1e-3)  # triangular acceleration


def test_scurve_long_move_duration():
    # dv = 200 with amax reached: each change takes amax/jmax + dv/amax = 0.4 + 1.0 s and covers vmax/2 * that
    p = plan_scurve(400.0, 0.0, 0.0, VMAX, AMAX, JMAX)
    change = AMAX / JMAX + VMAX / AMAX
    assert p.duration == pytest.approx(2 * change + (400.0 - VMAX * change) / VMAX)


def test_exponential_shape():
    p = plan_exponential(400.0, 0.0, 0.0, VMAX, AMAX, ratio=4.0)
    d = p.t[1]  # first transition
    # acceleration is amax at the start and decays by exp(-ratio) over the transition
    a = p.sample(np.array([0.0, 0.5 * d, d * (1 - 1e-9)]))[2]
    assert a[0] == pytest.approx(AMAX)
    assert a[1] == pytest.approx(AMAX * math.exp(-2.0), rel=1e-6)
    assert a[2] == pytest.approx(AMAX * math.exp(-4.0), rel=1e-6)
    # slower to reach vmax than a trapezoid with the same peak acceleration
    assert p.duration > plan_trapezoid(400.0, 0.0, 0.0, VMAX, AMAX).duration


@pytest.mark.parametrize("kind", KINDS)
def test_unreachable_end_velocity_is_lowered(kind):
    p = plan(kind, 1.0, 0.0, 100.0)
    assert p.lowered and 0 < p.v1 < 100.0
    _check_sampled(p, 1.0, p.v1)
    # it is the most the move allows: asking for it exactly is not lowered
    again = plan(kind, 1.0, 0.0, p.v1 * (1 - 1e-9))
    assert not again.lowered
    with pytest.raises(PlanningError, match="unreachable"):
        plan(kind, 1.0, 0.0, 100.0, lower_end=False)


@pytest.mark.parametrize("kind", KINDS)
def test_end_velocity_above_vmax_is_lowered(kind):
    p = plan(kind, 1500.0, 0.0, 300.0)
    assert p.lowered and p.v1 == VMAX


@pytest.mark.parametrize("kind", KINDS)
def test_cannot_slow_down_in_time(kind):
    with pytest.raises(PlanningError) as err:
        plan(kind, 50.0, 150.0, 0.0)
    assert "cannot slow from v0=150 to v1=0 within L=50" in str(err.value)
    assert str(err.value).startswith("velocity profile:")


@pytest.mark.parametrize("kind", KINDS)
def test_bad_inputs(kind):
    with pytest.raises(PlanningError, match="exceeds vmax"):
        plan(kind, 10.0, 250.0, 0.0)
    with pytest.raises(PlanningError, match=">= 0"):
        plan(kind, -1.0, 0.0, 0.0)
    with pytest.raises(PlanningError, match="non-finite"):
        plan(kind, float("nan"), 0.0, 0.0)


@pytest.mark.parametrize("kind", KINDS)
def test_zero_length_move(kind):
    p = plan(kind, 0.0, 0.0, 0.0)
    assert p.duration == 0.0
    assert list(sample_profile(p, 0.004)) == [0.0]


def test_sampling_is_vectorised_over_any_shape():
    p = plan_scurve(100.0, 0.0, 10.0, VMAX, AMAX, JMAX)
    t = np.linspace(-1.0, p.duration + 1.0, 24).reshape(4, 6)
    s, v, a, j = p.sample(t)
    assert s.shape == v.shape == a.shape == j.shape == (4, 6)
    assert s[0, 0] == 0.0 and s[-1, -1] == 100.0 and v[-1, -1] == 10.0
