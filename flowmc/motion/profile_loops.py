"""The time law's sequential passes as compiled loops (numba): a profile's backward and forward scans, and
the tangential budgets every round of a profile asks for.

Why compiled: a scan is a running minimum of a cumulative sum, each step depending on the one before, and
numpy runs such a pass one dependent step at a time through four separate whole-array passes; the budgets
are a dozen whole-array passes per machine axis. A plan makes about fifty scans and budget rounds over
arrays of 1e5 intervals (3D_Chips), which in numpy were most of the time law. Each loop does the very
arithmetic, in the same order, that the numpy expressions it replaces did (additions of the same terms in
sequence, no fused multiply-adds: numba's default keeps IEEE order), so plans are the same to the bit.

Compiled code is kept in numba's on-disk cache (``cache=True``: next to this file, or in the user's cache
directory where that is read-only), so only the first plan after installing pays for compiling. Importing
this module imports numba (about 0.3 s): flowmc.motion.timelaw imports it when it first plans.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["scan", "budgets"]


@njit(cache=True, inline="always", error_model="numpy")
def _lesser(m: float, x: float) -> float:
    """np.minimum(m, x): the smaller, NaN if either is NaN."""
    return x if (x < m or x != x) and m == m else m


@njit(cache=True, error_model="numpy")
def scan(cap: np.ndarray, limit: np.ndarray, ds: np.ndarray, up: np.ndarray, down: np.ndarray) -> np.ndarray:
    """The fastest y at the nodes with y <= min(cap, limit), y_{k+1} - y_k <= 2 up_k ds_k and
    y_k - y_{k+1} <= 2 down_k ds_k: the backward pass min over j >= k of (cap_j + C_j) - C_k with C the
    cumulative sum of 2 down ds, then the forward pass the same with 2 up ds, every sum taken in order as
    np.cumsum takes it. All three passes work in the one array returned (on a virtual machine a fresh
    array's page faults can cost as much as a pass)."""
    n = len(cap)
    out = np.empty(n)
    total = 0.0
    out[0] = 0.0
    for i in range(n - 1):
        total = total + 2.0 * down[i] * ds[i]
        out[i + 1] = total
    low = np.inf
    for i in range(n - 1, -1, -1):
        c = out[i]
        low = _lesser(low, _lesser(cap[i], limit[i]) + c)
        out[i] = low - c
    total = 0.0
    low = np.inf
    for i in range(n):
        if i > 0:
            total = total + 2.0 * up[i - 1] * ds[i - 1]
        low = _lesser(low, out[i] - total)
        out[i] = low + total
    return out


@njit(cache=True, error_model="numpy")
def budgets(cap: np.ndarray, faster: np.ndarray, slower: np.ndarray, signed: bool, widen: np.ndarray,
            alpha: np.ndarray, beta_up: np.ndarray, beta_down: np.ndarray, gamma_up: np.ndarray,
            gamma_down: np.ndarray, jmax: np.ndarray, t_win: np.ndarray, k3: np.ndarray, p3: np.ndarray,
            window: float) -> tuple[np.ndarray, np.ndarray]:
    """Largest path acceleration and deceleration (up, down) on every interval k for speed^2 up to
    y = min(cap_k, max(faster_k, faster_k+1)) (flowmc.motion.timelaw's _Budgets; ``faster`` a profile at the
    nodes): per machine axis (rows of the 2-D terms) alpha - beta y, plus gamma min(cap_k, min(slower_k,
    slower_k+1)) where ``signed``; with ``window`` > 0 also the jerk term
    (jmax - p3 y^1.5) / (t_win widen + k3 sqrt(y)) where that divisor is positive. The smallest over the
    axes, a non-finite one taken as 1e12 and every one at least 1e-9. Axis by axis, so each loop is a plain
    pass the compiler vectorises; both results are rows of one array."""
    n = len(cap)
    out = np.empty((2, n))
    up, down = out[0], out[1]
    level = np.empty(n)
    for k in range(n):
        a, b = faster[k], faster[k + 1]
        level[k] = _lesser(cap[k], a if a > b or a != a else b)
    least = np.empty(n if signed else 0)
    if signed:
        for k in range(n):
            least[k] = _lesser(cap[k], _lesser(slower[k], slower[k + 1]))
    up[:] = np.inf
    down[:] = np.inf
    for r in range(alpha.shape[0]):
        al, bu, bd, gu, gd = alpha[r], beta_up[r], beta_down[r], gamma_up[r], gamma_down[r]
        if signed:
            for k in range(n):
                up[k] = _lesser(up[k], al[k] - bu[k] * level[k] + gu[k] * least[k])
                down[k] = _lesser(down[k], al[k] - bd[k] * level[k] + gd[k] * least[k])
        else:
            for k in range(n):
                up[k] = _lesser(up[k], al[k] - bu[k] * level[k])
                down[k] = _lesser(down[k], al[k] - bd[k] * level[k])
        if window > 0:
            tw, k3r, p3r, jm = t_win[r], k3[r], p3[r], jmax[r]
            for k in range(n):
                y = level[k]
                root = np.sqrt(y)
                coeff = tw[k] * widen[k] + k3r[k] * root
                jerk = (jm - p3r[k] * (y * root)) / coeff
                jerk = jerk if coeff > 0 else np.inf
                up[k] = _lesser(up[k], jerk)
                down[k] = _lesser(down[k], jerk)
    for k in range(n):
        u, d = up[k], down[k]
        up[k] = max(u if np.isfinite(u) else 1e12, 1e-9)
        down[k] = max(d if np.isfinite(d) else 1e12, 1e-9)
    return up, down
