"""Range minimum and maximum over many windows of one array at once (a sparse table: O(n log w), vectorised).

Only the levels the widest window needs are built (w its width), and all windows are answered by one
gather from the stacked levels, so many calls with short windows over a long array stay cheap.
"""

from __future__ import annotations

import numpy as np

__all__ = ["window_min", "window_max"]


def window_min(values: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """min(values[lo_k : hi_k + 1]) for every k; 0 <= lo_k <= hi_k < len(values)."""
    values = np.asarray(values, dtype=float)
    lo, hi = np.asarray(lo, dtype=int), np.asarray(hi, dtype=int)
    if not len(lo):
        return np.empty(0)
    level = np.floor(np.log2(np.maximum(hi - lo + 1, 1))).astype(int)
    top = int(level.max())
    table = np.full((top + 1, len(values)), np.inf)
    table[0] = values
    span = 1
    for lv in range(1, top + 1):
        np.minimum(table[lv - 1, :-span], table[lv - 1, span:], out=table[lv, :-span])
        span *= 2
    return np.minimum(table[level, lo], table[level, hi - (1 << level) + 1])


def window_max(values: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """max(values[lo_k : hi_k + 1]) for every k."""
    return -window_min(-np.asarray(values, dtype=float), lo, hi)
