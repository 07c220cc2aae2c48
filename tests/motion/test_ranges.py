"""flowmc.motion.ranges: window minima and maxima equal a brute-force scan, reused windows included; the moving
means equal scipy.ndimage.uniform_filter1d segment by segment; search_right is np.searchsorted."""

import numpy as np
import pytest
from scipy.ndimage import uniform_filter1d

from flowmc.motion.ranges import Windows, moving_means, range_medians, search_right, window_max, window_min


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


def test_moving_means_are_uniform_filter1d_within_each_segment():
    # each segment on its own, ends mirrored as scipy mirrors them, however short the segment
    rng = np.random.default_rng(7)
    lengths = np.array([1, 2, 5, 19, 20, 21, 40, 41, 42, 100, 1000, 5000, 3])
    values = np.log(rng.random(lengths.sum())) * 10.0 ** rng.integers(-3, 4, lengths.sum())
    starts = np.r_[0, np.cumsum(lengths)]
    for size in (1, 3, 41):
        out = moving_means(values, lengths, size)
        for a, b in zip(starts[:-1], starts[1:]):
            np.testing.assert_allclose(out[a:b], uniform_filter1d(values[a:b], size=size), rtol=1e-9, atol=1e-9)
    # one segment is the plain moving mean; a value in one segment does not reach the next
    np.testing.assert_allclose(moving_means(values, [len(values)], 41), uniform_filter1d(values, size=41), atol=1e-9)
    step = np.r_[np.zeros(30), np.ones(30)]
    np.testing.assert_array_equal(moving_means(step, [30, 30], 41), step)
    with pytest.raises(ValueError, match="odd window"):
        moving_means(np.ones(10), [10], 40)
    with pytest.raises(ValueError, match="sum to 10"):
        moving_means(np.ones(10), [4, 5], 41)


def test_range_medians_are_numpy_medians():
    # odd and even counts, one-value ranges, overlapping ranges and ties: the very numbers np.median gives
    rng = np.random.default_rng(11)
    values = np.round(rng.normal(size=400), 2) * 10.0 ** rng.integers(-3, 3, 400)
    lo = rng.integers(0, 399, 300)
    hi = np.minimum(lo + 1 + rng.integers(0, 60, 300), 400)
    lo[:2], hi[:2] = [0, 399], [400, 400]
    out = range_medians(values, lo, hi)
    np.testing.assert_array_equal(out, [np.median(values[a:b]) for a, b in zip(lo, hi)])
    with pytest.raises(ValueError, match="needs a value"):
        range_medians(values, [3], [3])


def test_search_right_is_searchsorted_ties_and_both_ends_included():
    rng = np.random.default_rng(7)
    keys = np.sort(np.r_[rng.integers(0, 50, 40).astype(float), [3.0, 3.0, 3.0]])  # repeated keys
    ascending = np.sort(np.r_[rng.uniform(-5, 55, 300), keys[:10], [-10.0, 60.0]])  # needles on keys and outside
    for t in (ascending, rng.permutation(ascending), ascending[:20], np.repeat(keys[5], 200)):
        assert np.array_equal(search_right(keys, t), np.searchsorted(keys, t, side="right"))


def test_search_right_on_a_run_of_samples_within_many_keys():
    """A chunk of a long sampling: many keys in all, few between its first and last sample, some on them."""
    keys = np.sort(np.r_[np.arange(0.0, 1000.0, 0.7), [400.0, 400.0, 400.0]])
    t = np.sort(np.r_[np.linspace(398.6, 410.0, 300), [400.0, 400.0]])
    for run in (t, t[5:], np.r_[t, 410.2]):
        assert np.array_equal(search_right(keys, run), np.searchsorted(keys, run, side="right"))
