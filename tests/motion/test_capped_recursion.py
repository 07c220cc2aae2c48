import numpy as np
import pytest

from flowmc.motion.capped_recursion import descend


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
