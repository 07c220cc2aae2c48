"""The I/O a path asks for, as timed Signal events: every planner and interpolator uses this one rule.

A segment's output changes (digital, analog) and a spindle change happen as the segment starts,
i.e. at the first setpoint tagged with that segment.
"""

from __future__ import annotations

import numpy as np

from flowmc.motion.path import Path
from flowmc.motion.trajectory import Signal

__all__ = ["path_signals", "segment_start_times"]


def segment_start_times(tags: np.ndarray, period: float, n_segments: int) -> np.ndarray:
    """Time of the first setpoint of each segment, from per-setpoint segment tags (sorted)."""
    tags = np.asarray(tags)
    if len(tags) == 0:
        return np.zeros(n_segments)
    first = np.minimum(np.searchsorted(tags, np.arange(n_segments), side="left"), len(tags) - 1)
    return first * float(period)


def path_signals(path: Path, start_times) -> Signal:
    """Signal events for the path's I/O changes, each at its segment's start time.

    The spindle starts off, so a first segment with the spindle on shows as an event too.
    """
    t, kind, channel, value = [], [], [], []
    spindle = 0.0
    for seg, t0 in zip(path.segments, np.asarray(start_times, dtype=float)):
        changes = [("dout", ch, float(bool(on))) for ch, on in seg.outputs]
        changes += [("da", ch, float(volts)) for ch, volts in seg.analog]
        if seg.spindle != spindle:
            spindle = seg.spindle
            changes.append(("spindle_rpm", 0, float(spindle)))
        for kd, ch, val in changes:
            t.append(t0)
            kind.append(kd)
            channel.append(ch)
            value.append(val)
    return Signal(t, kind, channel, value)
