"""How every planner is measured: from the sampled setpoints alone, as the reference README defines.

p_k = p(kT); v_k = (p_{k+1} - p_k)/T, a_k and j_k likewise. Cycle time is N*T to the last setpoint.
Peak ratios are per axis, against each axis's own limit. The corner spike (the velocity change at a
sharp corner a junction rule passes at speed) is reported apart from the acceleration along the path.
Contour error is the largest distance from any chord [p_k, p_k+1] to the programmed path. Planners
here and external ones (LinuxCNC) go through the same functions, so no planner can hide a corner.
"""

from __future__ import annotations

import math

import numpy as np

import flowmc.budget as budget
from flowmc.motion.limits import AxisLimits
from flowmc.motion.machine import Machine
from flowmc.motion.path import Path
from flowmc.motion.trajectory import Trajectory

__all__ = [
    "cycle_time",
    "time_ratio",
    "peak_ratio",
    "corner_spike_ratio",
    "programmed_polyline",
    "contour_error",
    "feed_fluctuation",
    "trajectory_report",
]


def cycle_time(traj: Trajectory) -> float:
    """N*T to the last setpoint."""
    return traj.duration


def time_ratio(traj: Trajectory, bound: float) -> float:
    """R_T = cycle time / the path's time-optimal bound."""
    return traj.duration / bound


def _corner_rows(traj: Trajectory, corner_times, n_rows: int) -> np.ndarray:
    """Rows of the sampled acceleration (np.diff order) that see the turn at each corner time."""
    k = np.floor(np.asarray(corner_times, dtype=float) / traj.period + 1e-9).astype(int)
    rows = np.concatenate([k - 1, k]) if len(k) else np.zeros(0, dtype=int)
    return np.unique(rows[(rows >= 0) & (rows < n_rows)])


def peak_ratio(traj: Trajectory, limits, order: int = 2, exclude_times=()) -> float:
    """max over samples and axes of |d^order p / dt^order| / limit (order 1 velocity, 2 acceleration,
    3 jerk), leaving out the acceleration rows at ``exclude_times`` (corner spikes) when order is 2."""
    values = traj.derivatives()[order - 1]
    if len(values) == 0:
        return 0.0
    ratio = np.abs(values) / np.asarray(limits, dtype=float)
    if order == 2 and len(exclude_times):
        keep = np.ones(len(ratio), dtype=bool)
        keep[_corner_rows(traj, exclude_times, len(ratio))] = False
        ratio = ratio[keep]
    return float(ratio.max()) if ratio.size else 0.0


def corner_spike_ratio(traj: Trajectory, amax, corner_times) -> float:
    """The sampled acceleration at the given corner times over the per-axis limit (0 without corners)."""
    _, a, _ = traj.derivatives()
    rows = _corner_rows(traj, corner_times, len(a))
    if len(rows) == 0:
        return 0.0
    return float((np.abs(a[rows]) / np.asarray(amax, dtype=float)).max())


def programmed_polyline(path: Path, axes=("X", "Y", "Z"), tol: float = 1e-4) -> np.ndarray:
    """The programmed path as points within ``tol`` of it (exact for lines), in the given axes."""
    pts, _ = path.sample(tol)
    return pts[:, ["XYZ".index(a.upper()) for a in axes]]


def _segment_distance(q: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance from points q to segments [a, b], all row-aligned (..., d)."""
    ab = b - a
    denom = np.einsum("...i,...i->...", ab, ab)
    t = np.einsum("...i,...i->...", q - a, ab) / np.where(denom > 0, denom, 1.0)
    t = np.clip(t, 0.0, 1.0)
    return np.linalg.norm(q - (a + t[..., None] * ab), axis=-1)


class _PolylineDistance:
    """Exact distance to a polyline, and which of its segments is nearest.

    The polyline is split into pieces no longer than h; candidate pieces come from a k-d tree of
    their midpoints (a piece at distance d has its midpoint within d + h/2), and a point whose k
    candidates might miss the nearest piece is checked by a radius query.
    """

    _K = 8

    def __init__(self, polyline: np.ndarray):
        pts = np.asarray(polyline, dtype=float)
        diff = np.diff(pts, axis=0)
        seg_len = np.linalg.norm(diff, axis=1)
        h = min(max(float(np.median(seg_len)) if len(seg_len) else 1.0, 1e-6), 0.5)
        budget.check("points", float(np.sum(seg_len)) / h + len(seg_len), what="indexing the path for distances",
                     change="sample the path more evenly")
        splits = np.maximum(1, np.ceil(seg_len / h)).astype(int)
        frac = np.concatenate([np.arange(n) / n for n in splits]) if len(splits) else np.zeros(0)
        self.owner = np.repeat(np.arange(len(seg_len)), splits)
        self.a = pts[self.owner] + frac[:, None] * diff[self.owner]
        self.b = self.a + diff[self.owner] / splits[self.owner, None]
        self.h = float(np.linalg.norm(self.b - self.a, axis=1).max()) if len(self.a) else 0.0
        from scipy.spatial import cKDTree  # scipy on first use: `flowmc validate` starts without it

        self.tree = cKDTree(0.5 * (self.a + self.b)) if len(self.a) else None
        self.point = pts[0] if len(pts) else None

    def __call__(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if self.tree is None:  # a single point
            return np.linalg.norm(q - self.point, axis=1), np.zeros(len(q), dtype=int)
        k = min(self._K, len(self.a))
        mid_d, idx = self.tree.query(q, k=k)
        mid_d, idx = mid_d.reshape(len(q), k), idx.reshape(len(q), k)
        all_d = _segment_distance(q[:, None, :], self.a[idx], self.b[idx])
        best = all_d.argmin(axis=1)
        d = all_d[np.arange(len(q)), best]
        near_piece = idx[np.arange(len(q)), best]
        unsure = np.flatnonzero(mid_d[:, -1] <= d + 0.5 * self.h) if k < len(self.a) else []
        for i in unsure:
            near = np.asarray(self.tree.query_ball_point(q[i], d[i] + 0.5 * self.h + 1e-12), dtype=int)
            dd = _segment_distance(q[i], self.a[near], self.b[near])
            d[i], near_piece[i] = dd.min(), near[dd.argmin()]
        return d, self.owner[near_piece]


def contour_error(positions: np.ndarray, polyline: np.ndarray) -> float:
    """Largest distance from any chord [p_k, p_k+1] to the polyline (same columns).

    The distance to one straight segment is convex along a chord, so a chord whose two ends have the
    same nearest segment has its largest distance at an end. Only chords whose ends see different
    segments (around corners) are split, recursively, until each part is resolved that way or is
    too short to matter (1e-6 of the chord).
    """
    p = np.asarray(positions, dtype=float)
    dist = _PolylineDistance(polyline)
    if len(p) == 0:
        return 0.0
    d, owner = dist(p)
    best = float(d.max())
    a, b, da, db, oa, ob = p[:-1], p[1:], d[:-1], d[1:], owner[:-1], owner[1:]
    n = 8
    for _ in range(7):
        length = np.linalg.norm(b - a, axis=1)
        open_ = (oa != ob) & (np.maximum(da, db) + 0.5 * length > best)
        if not np.any(open_):
            break
        a, b, da, db, oa, ob = a[open_], b[open_], da[open_], db[open_], oa[open_], ob[open_]
        f = (np.arange(1, n) / n)[None, :, None]
        inner = a[:, None, :] + f * (b - a)[:, None, :]
        di, oi = dist(inner.reshape(-1, p.shape[1]))
        di, oi = di.reshape(len(a), n - 1), oi.reshape(len(a), n - 1)
        best = max(best, float(di.max()))
        pts = np.concatenate([a[:, None, :], inner, b[:, None, :]], axis=1)
        dd = np.concatenate([da[:, None], di, db[:, None]], axis=1)
        oo = np.concatenate([oa[:, None], oi, ob[:, None]], axis=1)
        dim = p.shape[1]
        a, b = pts[:, :-1].reshape(-1, dim), pts[:, 1:].reshape(-1, dim)
        da, db, oa, ob = dd[:, :-1].ravel(), dd[:, 1:].ravel(), oo[:, :-1].ravel(), oo[:, 1:].ravel()
    return best


def feed_fluctuation(positions: np.ndarray, period: float, feed, lengths=None) -> dict:
    """|L_k/T - V_k| / V_k over the chords with V_k > 0: max, mean and RMS.

    ``L_k`` is the chord length by default (which alone has a floor of about L^2 kappa^2 / 24 on a
    curve) or the arc length covered in period k when the caller passes ``lengths``.
    """
    p = np.asarray(positions, dtype=float)
    step = np.linalg.norm(np.diff(p, axis=0), axis=1) if lengths is None else np.asarray(lengths, dtype=float)
    target = np.broadcast_to(np.asarray(feed, dtype=float), step.shape)
    moving = target > 0
    rel = np.abs(step[moving] / period - target[moving]) / target[moving]
    if rel.size == 0:
        return {"max": 0.0, "mean": 0.0, "rms": 0.0, "measure": "chord" if lengths is None else "arc"}
    return {"max": float(rel.max()), "mean": float(rel.mean()), "rms": float(math.sqrt(np.mean(rel**2))),
            "measure": "chord" if lengths is None else "arc"}


def trajectory_report(traj: Trajectory, path: Path, machine: Machine, bound: float | None = None,
                      corner_times=()) -> dict:
    """Cycle time, ratio to ``bound``, peak per-axis velocity and acceleration over their limits
    (corners apart), the corner spike, and the contour error against the programmed path."""
    lim = AxisLimits.of(machine, traj.axes)
    amax = lim.amax
    out = {
        "cycle_time": cycle_time(traj),
        "time_ratio": time_ratio(traj, bound) if bound else float("nan"),
        "peak_velocity": peak_ratio(traj, lim.vmax, order=1),
        "peak_accel": peak_ratio(traj, amax, order=2, exclude_times=corner_times),
        "corner_spike": corner_spike_ratio(traj, amax, corner_times),
        "contour_error": contour_error(traj.positions, programmed_polyline(path, traj.axes)),
    }
    return out
