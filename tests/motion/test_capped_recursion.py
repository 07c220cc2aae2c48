import numpy as np
import pytest

from flowmc.motion.capped_recursion import descend, descend_again


def _step_by_step(cap, a, b):
    y = np.empty(len(cap))
    y[-1] = cap[-1]
    for k in range(len(cap) - 2, -1, -1):
        y[k] = min([cap[k]] + [ai[k] * y[k + 1] + bi[k] for ai, bi in zip(a, b)])
    return y


@pytest.mark.parametrize("n, axes", [(7, 2), (200, 1), (5000, 3), (20011, 2)])
def test_descend_is_the_recursion_step_by_step(n, axes):
    # long uncapped stretches (the cap only now and then) carry the solution across many blocks; slopes above
    # and below 1 (normal terms that help or hurt), axes that do not move (b = inf) and rests (cap 0)
    rng = np.random.default_rng(n)
    cap = np.where(rng.random(n + 1) < 0.01, rng.uniform(0.0, 1e4, n + 1), np.inf)
    cap[rng.integers(0, n + 1, 3)] = 0.0
    cap[-1] = 0.0
    a = [np.exp(rng.normal(0.0, 0.02, n)) for _ in range(axes)]
    b = [np.where(rng.random(n) < 0.05, np.inf, rng.uniform(1.0, 50.0, n)) for _ in range(axes)]
    expected = _step_by_step(cap, a, b)
    got = descend(cap, a, b)
    assert np.allclose(got, expected, rtol=1e-12, atol=0.0)
    upper = np.maximum(expected * 1.5, expected + 10.0)
    assert np.allclose(descend(cap, a, b, guess=np.minimum(cap, upper)), expected, rtol=1e-12, atol=0.0)


@pytest.mark.parametrize("n, changes", [(5000, 3), (20011, 12), (20011, 0), (300, 40)])
def test_descend_again_after_caps_change_is_the_recursion(n, changes):
    # caps lowered (and a few raised) at a few nodes, as a tight range lowers them: the stretches solved again
    # and the old values kept elsewhere give the recursion's values for the new caps, however far a change
    # reaches back (long uncapped stretches), and past a quarter of the nodes descend itself
    rng = np.random.default_rng(n + changes)
    cap = np.where(rng.random(n + 1) < 0.01, rng.uniform(0.0, 1e4, n + 1), np.inf)
    cap[-1] = 0.0
    a = [np.exp(rng.normal(0.0, 0.02, n)) for _ in range(2)]
    b = [rng.uniform(1.0, 50.0, n) for _ in range(2)]
    old = descend(cap, a, b)
    new_cap = cap.copy()
    at = rng.integers(0, n, changes)
    new_cap[at] = np.minimum(new_cap[at], old[at] * rng.uniform(0.1, 1.2, changes))
    got = descend_again(new_cap, cap, old, a, b)
    assert np.allclose(got, _step_by_step(new_cap, a, b), rtol=1e-12, atol=0.0)
