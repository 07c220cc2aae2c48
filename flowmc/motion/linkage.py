"""Two-axis linkage pulse table (the LabVIEW + Arduino teaching machine's interpolation).

Each straight move (arcs and curves are cut into chords first) becomes one row: how many pulses each
axis sends, in which direction, and at what frequency, so that both axes start and stop together
at the programmed feed: ``f_i = feed * |d_i| / L / step_i`` with L the move's length. A controller
that plays the rows in order draws the path as a chain of straight moves.

Rounding: a row's pulse count is the difference of the rounded absolute positions of its ends.
That is the same as carrying each row's rounding residual into the next, so the position never
drifts more than half a step from the programmed one, the end point is exact, and the pulses of
all rows add up to the end point in steps. Frequencies use the rounded counts, so
``pulses / frequency`` is the same duration for both axes.
"""

from __future__ import annotations

import numpy as np

from flowmc.errors import PathError
from flowmc.motion.path import Dwell, Line, Path
from flowmc.motion.table import Table

__all__ = ["linkage_table", "path_linkage_table", "COLUMNS"]

#: Column order of every linkage table.
COLUMNS = ("segment", "x_pulses", "y_pulses", "x_dir", "y_dir", "x_freq_hz", "y_freq_hz", "duration_s",
           "feed_mm_s", "rate_limited")


def _per_row(value, n: int, name: str, unit: str) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    if arr.shape != (n,):
        raise PathError(f"{name} must be one number or one per move ({n}), got shape {arr.shape}")
    if not np.all(np.isfinite(arr) & (arr > 0)):
        bad = int(np.flatnonzero(~(np.isfinite(arr) & (arr > 0)))[0])
        raise PathError(f"{name} must be > 0 {unit}, got {arr[bad]} for move {bad + 1}")
    return arr


def _pair(value, name: str, unit: str) -> np.ndarray:
    arr = np.broadcast_to(np.asarray(value, dtype=float), (2,)).copy()
    if not np.all(np.isfinite(arr) & (arr > 0)):
        raise PathError(f"{name} must be > 0 {unit} for X and Y, got {value!r}")
    return arr


def linkage_table(points, step_mm, feed, max_step_rate=None, segment=None) -> Table:
    """Pulse table for the moves joining ``points`` (M+1, 2 or 3) in mm.

    ``feed`` (mm/s) is one number or one per move; ``step_mm`` is the X and Y pulse equivalent.
    A third column (Z) counts towards each move's length and time but sends no pulses here.
    Where a move would need more than ``max_step_rate`` (Hz, one number or X and Y) on an axis, its
    feed is scaled down for that move; ``feed_mm_s`` and ``rate_limited`` report it.
    ``segment`` labels the rows with segment numbers as users count them (default 1..M: the moves).
    """
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] not in (2, 3) or len(pts) < 2:
        raise PathError(f"a pulse table needs at least two points of 2 or 3 coordinates, got shape {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise PathError(f"point {int(np.flatnonzero(~np.isfinite(pts).all(axis=1))[0]) + 1} is not finite")
    n = len(pts) - 1
    labels = np.arange(1, n + 1) if segment is None else np.asarray(segment, dtype=np.int64)
    if labels.shape != (n,):
        raise PathError(f"segment labels must be one per move ({n}), got shape {labels.shape}")
    step = _pair(step_mm, "step_mm", "mm")
    feeds = _per_row(feed, n, "feed", "mm/s")
    lengths = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    if np.any(lengths == 0):
        i = int(np.flatnonzero(lengths == 0)[0])
        raise PathError(f"zero-length move: points {i + 1} and {i + 2} are both {pts[i].tolist()}",
                        where=f"segment {labels[i]}")
    target = np.rint(pts[:, :2] / step).astype(np.int64)
    pulses = np.diff(target, axis=0)
    duration = lengths / feeds
    freq = np.abs(pulses) / duration[:, None]
    scale = np.ones(n)
    if max_step_rate is not None:
        rate = _pair(max_step_rate, "max_step_rate", "Hz")
        with np.errstate(divide="ignore"):
            scale = np.minimum(1.0, np.min(np.where(freq > 0, rate / freq, np.inf), axis=1))
    limited = scale < 1.0
    feeds = feeds * scale
    duration = lengths / feeds
    freq = np.abs(pulses) / duration[:, None]
    return Table({
        "segment": labels,
        "x_pulses": np.abs(pulses[:, 0]),
        "y_pulses": np.abs(pulses[:, 1]),
        "x_dir": np.sign(pulses[:, 0]),
        "y_dir": np.sign(pulses[:, 1]),
        "x_freq_hz": freq[:, 0],
        "y_freq_hz": freq[:, 1],
        "duration_s": duration,
        "feed_mm_s": feeds,
        "rate_limited": limited,
    })


def path_linkage_table(path: Path, step_mm, max_step_rate=None, chord_tol: float | None = None) -> Table:
    """Pulse table for a path: lines as they are, arcs and curves as chords within ``chord_tol`` mm.

    Rows carry the path's segment number (1-based, as Measure path and messages count). Each
    segment runs at its own feed; a dwell is a row with no pulses that lasts its seconds; segments
    that do not move are left out. ``chord_tol`` defaults to half the smaller step.
    """
    step = _pair(step_mm, "step_mm", "mm")
    tol = 0.5 * float(step.min()) if chord_tol is None else float(chord_tol)
    if not tol > 0:
        raise PathError(f"chord tolerance must be > 0 mm, got {chord_tol!r}")
    points, feeds, labels, dwells = [], [], [], []
    last = None
    for i, seg in enumerate(path):
        if isinstance(seg, Dwell):
            dwells.append((len(labels), i + 1, seg.seconds))
            continue
        if seg.length == 0.0:
            continue
        pts = np.vstack([seg.start, seg.end]) if isinstance(seg, Line) else seg.sample(tol)
        if last is None:
            points.append(pts[:1])
        elif not np.array_equal(pts[0], last):
            pts = np.vstack([last, pts])  # a gap in the path: the first row closes it
        pts = pts[np.r_[True, np.any(np.diff(pts, axis=0) != 0, axis=1)]]
        points.append(pts[1:])
        feeds.append(np.full(len(pts) - 1, seg.feed))
        labels.append(np.full(len(pts) - 1, i + 1))
        last = pts[-1]
    if labels:
        table = linkage_table(np.vstack(points), step, np.concatenate(feeds), max_step_rate,
                              np.concatenate(labels)).columns
        table = {k: list(v) for k, v in table.items()}
    else:
        table = {k: [] for k in COLUMNS}
    moves_before = np.cumsum([0] + [len(x) for x in labels])
    for row_at, i, seconds in reversed(dwells):
        at = int(moves_before[row_at])
        row = dict(segment=i, x_pulses=0, y_pulses=0, x_dir=0, y_dir=0, x_freq_hz=0.0, y_freq_hz=0.0,
                   duration_s=seconds, feed_mm_s=0.0, rate_limited=False)
        for k in COLUMNS:
            table[k].insert(at, row[k])
    dtypes = dict(segment=np.int64, x_pulses=np.int64, y_pulses=np.int64, x_dir=np.int64, y_dir=np.int64,
                  rate_limited=bool)
    return Table({k: np.asarray(table[k], dtype=dtypes.get(k, float)) for k in COLUMNS})
