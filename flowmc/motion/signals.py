"""The I/O a path asks for, as timed Signal events: every planner and interpolator uses this one rule.

A segment's output changes (digital, analog), a spindle change and a tool (pen) change happen as
the segment starts, i.e. at the first setpoint (or step) tagged with that segment. At one start they
come in that order: outputs, analog, spindle, tool. A path's events (M0/M1/M60, M6: stops for the
operator) are placed among those signals by segment too (``program_events``), so a job knows which
signals come before a stop and which after it.
"""

from __future__ import annotations

import numpy as np

from flowmc.motion.path import Path
from flowmc.motion.path_columns import DWELL
from flowmc.motion.trajectory import ProgramEvent, Signal

__all__ = ["path_signals", "program_events", "segment_start_times", "step_start_times"]


def segment_start_times(tags: np.ndarray, period: float, n_segments: int) -> np.ndarray:
    """Time of the first setpoint of each segment, from per-setpoint segment tags (sorted)."""
    tags = np.asarray(tags)
    if len(tags) == 0:
        return np.zeros(n_segments)
    first = np.minimum(np.searchsorted(tags, np.arange(n_segments), side="left"), len(tags) - 1)
    return first * float(period)


def step_start_times(segment: np.ndarray, tick: float, n_segments: int) -> np.ndarray:
    """When each segment's first step comes, from a step stream's per-row segment tags (sorted).

    An event at row ``i`` happens just before that row's step: at ``i * tick`` s, or at ``i`` (ticks)
    when the stream is untimed (``tick == 0``), the ``Steps`` convention. A segment without steps
    starts where the next one does (``len(segment)``, after the last step, at the end).
    """
    rows = np.searchsorted(np.asarray(segment), np.arange(n_segments), side="left")
    return rows * (float(tick) if tick > 0 else 1.0)


def path_signals(path: Path, start_times) -> Signal:
    """Signal events for the path's I/O changes, each at its segment's start time.

    The spindle starts off and the tool up, so a first segment with the spindle on or the tool down
    shows as an event too. A ``tool`` event (1 down, 0 up) marks each change of ``tool_down``;
    dwells do not change the tool. Read from the path's columns, all segments at once.
    """
    t0 = np.asarray(start_times, dtype=float).reshape(-1)
    seg_all, kind, channel, value = _signal_rows(path, min(len(path.columns), len(t0)))
    return Signal(t0[seg_all], kind, channel, value)


def program_events(path: Path) -> tuple[ProgramEvent, ...]:
    """The path's events as a planned program carries them: segment, what, and how many of the
    program's signals (``path_signals`` order) come before each."""
    events = path.events()
    if not events:
        return ()
    seg_all = _signal_rows(path, len(path.columns))[0]
    before = np.searchsorted(seg_all, [i for i, _e in events], side="right")
    return tuple(ProgramEvent(int(i), e.kind, e.message, e.tool, int(n)) for (i, e), n in zip(events, before))


def _signal_rows(path: Path, m: int):
    """Segment, kind, channel and value of every I/O change of the first ``m`` segments, in signal order."""
    cols = path.columns
    seg, order, kind, channel, value = [], [], [], [], []

    def add(rows, rank: int, name: str, channels, values) -> None:
        seg.append(np.asarray(rows, dtype=np.int64))
        order.append(np.full(len(seg[-1]), rank))
        kind.append(np.full(len(seg[-1]), name, dtype="U12"))
        channel.append(np.asarray(channels, dtype=int))
        value.append(np.asarray(values, dtype=float))

    for rank, (name, sparse, kind_of) in enumerate((("dout", cols.outputs, bool), ("da", cols.analog, float))):
        changes = [(k, ch, float(kind_of(v))) for k, row in sorted(sparse.items()) if k < m for ch, v in row]
        add([c[0] for c in changes], rank, name, [c[1] for c in changes], [c[2] for c in changes])
    spindle = cols.spindle[:m]
    rows = np.flatnonzero(spindle != np.r_[0.0, spindle[:-1]])
    add(rows, 2, "spindle_rpm", np.zeros(len(rows)), spindle[rows])
    moves = np.flatnonzero(cols.kind[:m] != DWELL)
    tool = cols.tool_down[moves]
    rows = moves[tool != np.r_[False, tool[:-1]]]
    add(rows, 3, "tool", np.zeros(len(rows)), cols.tool_down[rows])
    seg_all, order_all = np.concatenate(seg), np.concatenate(order)
    sort = np.lexsort((np.arange(len(seg_all)), order_all, seg_all))
    return seg_all[sort], np.concatenate(kind)[sort], np.concatenate(channel)[sort], np.concatenate(value)[sort]
