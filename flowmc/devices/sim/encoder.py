"""Incremental encoder with x4 quadrature decoding, as the 6050's FPGA counts it (thesis 4.1.8).

The A/B lines step through 00 -> 10 -> 11 -> 01 when A leads B (count up) and the reverse when B
leads A (count down); every transition counts, so one line period gives four counts. A jump
between opposite states (00 <-> 11, 10 <-> 01) skips a state: the direction is unknown, the
counter does not move and the sample is flagged as illegal.

Example
-------
>>> a, b = ab_levels([0, 1, 2, 3, 4, 3, 2])
>>> decode(a, b).counts.tolist()
[0, 1, 2, 3, 4, 3, 2]
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["ab_levels", "line_samples", "decode", "Decoded"]

# phase index 0..3 of each (A, B) pair along the count-up sequence 00, 10, 11, 01
_PHASE = np.array([[0, 3], [1, 2]], dtype=np.int8)  # _PHASE[a, b]
_LEVELS = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=np.int8)  # (a, b) of each phase


class Decoded(NamedTuple):
    counts: np.ndarray  # counter value after each sample
    illegal: np.ndarray  # indices of samples that jumped two states


def ab_levels(counts) -> tuple[np.ndarray, np.ndarray]:
    """The A and B line levels (0/1) an encoder shows at each count."""
    levels = _LEVELS[np.mod(np.asarray(counts, dtype=np.int64), 4)]
    return levels[:, 0], levels[:, 1]


def line_samples(counts) -> np.ndarray:
    """Every count the lines pass through between position samples (what a fast sampler sees)."""
    counts = np.asarray(counts, dtype=np.int64)
    if len(counts) < 2:
        return counts.copy()
    d = np.diff(counts)
    n = np.abs(d)
    sign = np.repeat(np.sign(d), n)
    base = np.repeat(counts[:-1], n)
    within = np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n) + 1
    return np.concatenate([counts[:1], base + sign * within])


def decode(a, b, start: int = 0) -> Decoded:
    """x4 decoding of sampled A/B levels: +1 per forward transition, -1 per backward, 0 and a flag per jump."""
    phase = _PHASE[np.asarray(a, dtype=np.int8), np.asarray(b, dtype=np.int8)]
    d = np.mod(np.diff(phase.astype(np.int64)), 4)
    step = np.where(d == 1, 1, np.where(d == 3, -1, 0))
    counts = start + np.concatenate([[0], np.cumsum(step)])
    return Decoded(counts, np.flatnonzero(d == 2) + 1)
