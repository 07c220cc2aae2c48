"""Range minimum and maximum over many windows of one array at once (a sparse table: O(n log w), vectorised).

Only the levels the widest window needs are built (w its width), and all windows are answered by one
gather from the stacked levels, so many calls with short windows over a long array stay cheap. The time
law takes minima over the same windows again and again (every round of a profile): ``Windows`` works out
the levels and where to gather once.
"""

from __future__ import annotations

import numpy as np

__all__ = ["CHUNK", "CHUNKED", "Windows", "window_min", "window_max", "moving_means", "MovingMeans", "range_medians",
           "search_right", "ranks"]

CHUNK = 16384  # elements a long pass works out together (the curve's points, the time law's intervals) ...
CHUNKED = 4 * CHUNK  # ... where there are more than this: every temporary then stays in cache


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


def search_right(keys: np.ndarray, t: np.ndarray) -> np.ndarray:
    """np.searchsorted(keys, t, side="right"). Sampled times, arc lengths and curve parameters ascend and
    outnumber the keys between their first and last several times over: then each of those keys is looked up
    among them instead, and the counts of keys at or below every t summed up (the same integers; a third of the
    time for 338k samples over 63k phases, a tenth over 1,800 curve intervals). Only the keys between matter, so
    a run of samples (a chunk of a long sampling) takes the short cut too."""
    t = np.asarray(t)
    if t.ndim == 1 and len(t) > 1 and np.all(t[1:] >= t[:-1]):
        below, upto = np.searchsorted(keys, t[[0, -1]], side="right")  # keys at or below the first t, the last
        if len(t) > 2 * (upto - below):
            at = np.searchsorted(t, keys[below:upto], side="left")
            return below + np.cumsum(np.bincount(at, minlength=len(t) + 1)[:len(t)])
    return np.searchsorted(keys, t, side="right")


def range_medians(values: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """np.median(values[lo_k:hi_k]) for every k (0 <= lo_k < hi_k <= len(values)), the same numbers, all ranges
    sorted at once (one np.median per range is Python work for each of hundreds of runs)."""
    values = np.asarray(values, dtype=float)
    lo, hi = np.asarray(lo, dtype=int), np.asarray(hi, dtype=int)
    n = hi - lo
    if np.any(n <= 0):
        raise ValueError("every range needs a value")
    start = np.cumsum(n) - n
    at = np.arange(int(n.sum())) - np.repeat(start - lo, n)  # every range's indices, range after range
    owner = np.repeat(np.arange(len(n)), n)
    ranked = values[at][np.lexsort((values[at], owner))]
    # np.median: the middle value, or the mean of the two middle ones (their sum halved)
    return (ranked[start + (n - 1) // 2] + ranked[start + n // 2]) / 2.0


def moving_means(values: np.ndarray, lengths: np.ndarray, size: int) -> np.ndarray:
    """Mean over the ``size`` (odd) values centred on each, within consecutive segments of ``lengths`` values
    that cover the array, each segment's ends mirrored (d c b a | a b c d | d c b a, repeated if it is short).

    Why per segment: the smoothing fit stacks many independent runs in one array; a mean across two runs
    would tie a run's smoothing to its neighbour's, so a run could not be refitted on its own. Why not
    scipy.ndimage.uniform_filter1d (mode "reflect"), which gives the same values: one call per segment is
    slow for hundreds of short runs, and importing scipy.ndimage costs about 0.2 s of CPU in a fresh process.
    """
    return MovingMeans(lengths, size)(values)


class MovingMeans:
    """``moving_means`` over one layout of segments, where each mean's values come from worked out once: the
    smoothing fit takes the means of new values over the same runs every iteration, and laying the mirrored
    segments out is most of the work on arrays of a thousand values."""

    def __init__(self, lengths: np.ndarray, size: int):
        if size % 2 != 1:
            raise ValueError(f"moving_means needs an odd window, got {size}")
        lengths = np.asarray(lengths, dtype=int)
        if np.any(lengths <= 0):
            raise ValueError("segment lengths must be positive")
        half = size // 2
        seg = np.repeat(np.arange(len(lengths)), lengths + 2 * half)
        ext_start = np.r_[0, np.cumsum(lengths + 2 * half)[:-1]]
        local = np.arange(len(seg)) - ext_start[seg] - half  # -half .. length + half - 1 in each segment
        n, start = lengths[seg], np.r_[0, np.cumsum(lengths)[:-1]][seg]
        m = np.mod(local, 2 * n)
        self.size, self.n = size, int(lengths.sum())
        self.src = start + np.where(m < n, m, 2 * n - 1 - m)  # each mirrored segment's values, where they come from
        self.at = np.arange(self.n) - np.repeat(np.r_[0, np.cumsum(lengths)[:-1]], lengths) + np.repeat(ext_start, lengths)
        self.end = self.at + size

    def __call__(self, values: np.ndarray) -> np.ndarray:
        values = np.asarray(values, dtype=float)
        if len(values) != self.n:
            raise ValueError(f"segment lengths must be positive and sum to {len(values)}")
        total = np.empty(len(self.src) + 1)  # the sums from the first value, 0 before it
        total[0] = 0.0
        np.cumsum(values[self.src], out=total[1:])
        return (total[self.end] - total[self.at]) / self.size


def ranks(sizes: np.ndarray) -> np.ndarray:
    """1..r for each r in ``sizes``, concatenated: the offsets of many runs laid end to end."""
    return np.arange(int(sizes.sum())) - np.repeat(np.cumsum(sizes) - sizes, sizes) + 1
