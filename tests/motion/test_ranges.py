"""flowmc.motion.ranges: window minima and maxima equal a brute-force scan, reused windows included; the moving
mean equals scipy.ndimage.uniform_filter1d to the last bit."""

import numpy as np
import pytest
from scipy.ndimage import uniform_filter1d

from flowmc.motion.ranges import Windows, moving_mean, window_max, window_min


def test_windows_match_a_scan_of_every_window():
    rng = np.random.default_rng(5)
    n = 300
    lo = rng.integers(0, n, 500)
    hi = np.minimum(lo + rng.integers(0, 70, 500), n - 1)
    lo[:3], hi[:3] = [0, 0, n - 1], [n - 1, 0, n - 1]  # the whole array, and one-element windows at both ends
    windows = Windows(lo, hi, n)
    for _ in range(3):  # the same windows over other values
        values = rng.normal(size=n)
        brute_min = np.array([values[a:b + 1].min() for a, b in zip(lo, hi)])
        brute_max = np.array([values[a:b + 1].max() for a, b in zip(lo, hi)])
        np.testing.assert_array_equal(windows.min(values), brute_min)
        np.testing.assert_array_equal(window_min(values, lo, hi), brute_min)
        np.testing.assert_array_equal(window_max(values, lo, hi), brute_max)
    assert len(Windows(np.zeros(0), np.zeros(0), n).min(rng.normal(size=n))) == 0


def test_moving_mean_is_uniform_filter1d_bit_for_bit():
    # the smoothing fit's plans stay bit-identical only if every value is summed exactly as scipy sums it
    rng = np.random.default_rng(7)
    for n in [1, 2, 5, 19, 20, 21, 40, 41, 42, 100, 1000, 5000]:
        values = np.log(rng.random(n)) * 10.0 ** rng.integers(-3, 4)  # mixed magnitudes show any reordering
        for size in (1, 3, 41):
            np.testing.assert_array_equal(moving_mean(values, size), uniform_filter1d(values, size=size))
            assert moving_mean(values, size).tobytes() == uniform_filter1d(values, size=size).tobytes()
    assert len(moving_mean(np.zeros(0), 41)) == 0
    with pytest.raises(ValueError, match="odd window"):
        moving_mean(np.ones(10), 40)
