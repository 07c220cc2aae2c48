"""flowmc.motion.ranges: window minima and maxima equal a brute-force scan, reused windows included."""

import numpy as np

from flowmc.motion.ranges import Windows, window_max, window_min


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
