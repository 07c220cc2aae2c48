"""Range minimum and maximum over many windows of one array at once (a sparse table: O(n log w), vectorised).

Only the levels the widest window needs are built (w its width), and all windows are answered by one
gather from the stacked levels, so many calls with short windows over a long array stay cheap. The time
law takes minima over the same windows again and again (every round of a profile): ``Windows`` works out
the levels and where to gather once.
"""

from __future__ import annotations

import numpy as np

__all__ = ["Windows", "window_min", "window_max", "moving_mean"]


class Windows:
    """Windows [lo_k, hi_k] (0 <= lo_k <= hi_k < n) over arrays of length n."""

    def __init__(self, lo: np.ndarray, hi: np.ndarray, n: int):
        lo, hi = np.asarray(lo, dtype=int), np.asarray(hi, dtype=int)
        level = np.floor(np.log2(np.maximum(hi - lo + 1, 1))).astype(int)
        self.n = n
        self.top = int(level.max()) if len(lo) else 0
        # where each window's two overlapping blocks of 2^level sit in the stacked levels
        self.first = level * n + lo
        self.second = level * n + hi - (1 << level) + 1

    def min(self, values: np.ndarray) -> np.ndarray:
        """min(values[lo_k : hi_k + 1]) for every k."""
        values = np.asarray(values, dtype=float)
        if not len(self.first):
            return np.empty(0)
        # level l holds the minimum of 2^l values from each index; its last 2^(l-1) entries are never read
        table = np.empty((self.top + 1, self.n))
        table[0] = values
        span = 1
        for lv in range(1, self.top + 1):
            np.minimum(table[lv - 1, :-span], table[lv - 1, span:], out=table[lv, :-span])
            span *= 2
        flat = table.reshape(-1)
        return np.minimum(flat[self.first], flat[self.second])


def window_min(values: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """min(values[lo_k : hi_k + 1]) for every k; 0 <= lo_k <= hi_k < len(values)."""
    return Windows(lo, hi, len(values)).min(values)


def window_max(values: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """max(values[lo_k : hi_k + 1]) for every k."""
    return -window_min(-np.asarray(values, dtype=float), lo, hi)


def moving_mean(values: np.ndarray, size: int) -> np.ndarray:
    """Mean over the ``size`` (odd) values centred on each, the ends mirrored (d c b a | a b c d | d c b a).

    Why here and not scipy.ndimage.uniform_filter1d (mode "reflect"): it is all the smoothing needs from
    scipy.ndimage, whose import costs about 0.2 s of CPU in a fresh process. The sum runs along the array
    (the first window added in order, then each step adds the value entering and subtracts the one leaving)
    and is divided at the end, which gives uniform_filter1d's values to the last bit.
    """
    if size % 2 != 1:
        raise ValueError(f"moving_mean needs an odd window, got {size}")
    values = np.asarray(values, dtype=float)
    if not len(values):
        return values.copy()
    ext = np.pad(values, size // 2, mode="symmetric")
    steps = np.empty(len(values))
    steps[0] = np.cumsum(ext[:size])[-1]
    steps[1:] = ext[size:] - ext[:-size]
    return np.cumsum(steps) / size
