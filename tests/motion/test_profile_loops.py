"""The time law's compiled loops against direct references on small arrays: the recursions they solve, and
the numpy expressions they replaced, to the bit (plans must not move when the loops run compiled)."""

import numpy as np
import pytest

from flowmc.motion.profile_loops import budgets, scan


def _recursion(cap, ds, up, down):
    """The fastest profile by its definition: back from the end under the slow-down budget, then forward."""
    n = len(cap)
    y = list(cap)
    for k in range(n - 2, -1, -1):
        y[k] = min(y[k], y[k + 1] + 2.0 * down[k] * ds[k])
    for k in range(1, n):
        y[k] = min(y[k], y[k - 1] + 2.0 * up[k - 1] * ds[k - 1])
    return np.array(y)


def _numpy_scan(cap, ds, up, down):
    """The running minima of cumulative sums numpy ran before (flowmc.motion.timelaw's _scan)."""
    c = np.zeros(len(ds) + 1)
    np.cumsum(2.0 * down * ds, out=c[1:])
    back = np.minimum.accumulate((cap + c)[::-1])[::-1] - c
    np.cumsum(2.0 * up * ds, out=c[1:])
    return np.minimum.accumulate(back - c) + c


def _case(seed, n=40):
    rng = np.random.default_rng(seed)
    cap = rng.uniform(10.0, 400.0, n + 1)
    cap[[0, n // 2, n]] = 0.0  # stops
    cap[5] = np.inf  # a node nothing caps
    return cap, rng.uniform(0.01, 2.0, n), rng.uniform(1.0, 50.0, n), rng.uniform(1.0, 50.0, n)


@pytest.mark.parametrize("seed", range(5))
def test_scan_is_the_recursion_and_the_numpy_passes(seed):
    cap, ds, up, down = _case(seed)
    limit = np.where(np.arange(len(cap)) % 7 == 3, 5.0, np.inf)
    for lim in (cap, limit):
        y = scan(cap, lim, ds, up, down)
        node_cap = np.minimum(cap, lim)
        assert np.array_equal(y, _numpy_scan(node_cap, ds, up, down))
        np.testing.assert_allclose(y, _recursion(node_cap, ds, up, down), rtol=1e-12, atol=1e-9)
        assert np.all(y <= node_cap * (1 + 1e-12)) and y[0] == 0.0 and y[-1] == 0.0
        dy = np.diff(y)
        assert np.all(dy <= 2.0 * up * ds * (1 + 1e-12)) and np.all(-dy <= 2.0 * down * ds * (1 + 1e-12))
        assert np.any(np.isclose(dy, 2.0 * up * ds)) and np.any(np.isclose(-dy, 2.0 * down * ds))  # budgets bind


def _terms(rng, rows, m, window):
    t = rng.uniform(0.0, 1.0, (rows, m))
    t[0, :3] = 0.0  # the first axis stands still there: no acceleration limit from it (alpha = inf)
    inv_t = np.where(t > 0, 1.0 / np.where(t > 0, t, 1.0), 0.0)
    alpha = np.where(t > 0, 200.0 * inv_t, np.inf)
    beta_up, beta_down, gamma_up, gamma_down = (rng.uniform(0.0, 0.05, (rows, m)) * inv_t for _ in range(4))
    if window > 0:
        jerk = (np.full(rows, 4950.0), t / window, 3.0 * rng.uniform(0.0, 0.1, (rows, m)),
                rng.uniform(0.0, 1e-3, (rows, m)))
    else:
        jerk = (np.zeros(rows), *(np.zeros((rows, 0)) for _ in range(3)))
    return (alpha, beta_up, beta_down, gamma_up, gamma_down, *jerk)


def _numpy_budgets(level, least, swing, terms, window):
    """Per axis, as flowmc.motion.timelaw's _Budgets worked them out in numpy before."""
    alpha, beta_up, beta_down, gamma_up, gamma_down, jmax, t_win, k3, p3 = terms
    up, down = np.full(len(level), np.inf), np.full(len(level), np.inf)
    with np.errstate(invalid="ignore", divide="ignore"):
        root = np.sqrt(level)
        for r in range(len(alpha)):
            if least is None:
                up = np.minimum(up, alpha[r] - beta_up[r] * level)
                down = np.minimum(down, alpha[r] - beta_down[r] * level)
            else:
                up = np.minimum(up, alpha[r] - beta_up[r] * level + gamma_up[r] * least)
                down = np.minimum(down, alpha[r] - beta_down[r] * level + gamma_down[r] * least)
            if window > 0:
                coeff = t_win[r] * (1.0 + swing) + k3[r] * root
                jerk = np.where(coeff > 0, (jmax[r] - p3[r] * (level * root)) / coeff, np.inf)
                up, down = np.minimum(up, jerk), np.minimum(down, jerk)
    return tuple(np.maximum(np.where(np.isfinite(b), b, 1e12), 1e-9) for b in (up, down))


@pytest.mark.parametrize("window, signed", [(0.0, False), (0.0, True), (0.08, False)])  # jerk-limited: never signed
def test_budgets_are_the_numpy_terms(window, signed):
    rng = np.random.default_rng(int(window * 100) + signed)
    m = 30
    cap = rng.uniform(0.0, 3000.0, m)
    faster, slower = rng.uniform(0.0, 4000.0, m + 1), rng.uniform(0.0, 2000.0, m + 1)
    swing = rng.random(m) < 0.3
    terms = _terms(rng, 3, m, window)
    widen = 1.0 + swing if window > 0 else np.zeros(0)
    up, down = budgets(cap, faster, slower, signed, widen, *terms, window)
    level = np.minimum(cap, np.maximum(faster[:-1], faster[1:]))
    least = np.minimum(cap, np.minimum(slower[:-1], slower[1:])) if signed else None
    ref_up, ref_down = _numpy_budgets(level, least, swing, terms, window)
    assert np.array_equal(up, ref_up) and np.array_equal(down, ref_down)
    assert not np.array_equal(up, down)  # the two sides differ where the normal terms do
    # by definition: every axis's acceleration within amax at the level (and the signed least helping)
    alpha, beta_up = terms[0], terms[1]
    free = (alpha - beta_up * level + (terms[3] * least if signed else 0.0)).min(axis=0)
    assert np.all(up <= np.maximum(free, 1e-9) * (1 + 1e-12))


def test_budgets_with_no_moving_axis_leave_the_cap_alone():
    """A machine column that never moves adds no row: with none at all the budget is the 1e12 stand-in for
    unlimited, as numpy's inf was."""
    m = 4
    empty = (np.zeros((0, m)),) * 5 + (np.zeros(0),) + (np.zeros((0, 0)),) * 3
    up, down = budgets(np.ones(m), np.ones(m + 1), np.ones(m + 1), False, np.zeros(0), *empty, 0.0)
    assert np.all(up == 1e12) and np.all(down == 1e12)
