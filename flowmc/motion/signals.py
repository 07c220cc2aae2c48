"""The I/O a path asks for, as timed Signal events: every planner and interpolator uses this one rule.

A segment's output changes (digital, analog), a spindle change and a tool (pen) change happen as
the segment starts, i.e. at the first setpoint (or step) tagged with that segment. At one start they
come in that order: outputs, analog, spindle, tool.
"""

from __future__ import annotations

import numpy as np

from flowmc.motion.path import Dwell, Path
from flowmc.motion.trajectory import Signal

__all__ = ["path_signals", "segment_start_times", "step_start_times"]


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
    dwells do not change the tool.
    """
    t, kind, channel, value = [], [], [], []
    spindle = 0.0
    tool = False
    for seg, t0 in zip(path.segments, np.asarray(start_times, dtype=float)):
        changes = [("dout", ch, float(bool(on))) for ch, on in seg.outputs]
        changes += [("da", ch, float(volts)) for ch, volts in seg.analog]
        if seg.spindle != spindle:
            spindle = seg.spindle
            changes.append(("spindle_rpm", 0, float(spindle)))
        if not isinstance(seg, Dwell) and bool(seg.tool_down) != tool:
            tool = bool(seg.tool_down)
            changes.append(("tool", 0, float(tool)))
        for kd, ch, val in changes:
            t.append(t0)
            kind.append(kd)
            channel.append(ch)
            value.append(val)
    return Signal(t, kind, channel, value)
