"""Range minimum and maximum over many windows of one array at once (a sparse table: O(n log n), vectorised)."""

from __future__ import annotations

import numpy as np

__all__ = ["window_min", "window_max"]


def window_min(values: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """min(values[lo_k : hi_k + 1]) for every k; 0 <= lo_k <= hi_k < len(values)."""
    values = np.asarray(values, dtype=float)
    lo, hi = np.asarray(lo, dtype=int), np.asarray(hi, dtype=int)
    table = [values]
    span = 1
    while 2 * span <= len(values):
        prev = table[-1]
        table.append(np.minimum(prev[:-span], prev[span:]))
        span *= 2
    level = np.floor(np.log2(np.maximum(hi - lo + 1, 1))).astype(int)
    out = np.empty(len(lo))
    for lv in np.unique(level):
        sel = np.flatnonzero(level == lv)
        t = table[lv]
        out[sel] = np.minimum(t[lo[sel]], t[hi[sel] - (1 << lv) + 1])
    return out


def window_max(values: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """max(values[lo_k : hi_k + 1]) for every k."""
    return -window_min(-np.asarray(values, dtype=float), lo, hi)
