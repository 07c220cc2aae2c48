"""Where a program job stops for the operator: its path events (M0, M1, M60, M6, an indexing stop).

The G-code reader keeps each as a ``PathEvent`` on a zero-length dwell, and a planned program carries
them as ``ProgramEvent`` (segment, what, how many of the program's own signals come before it). A job
maps each to the first setpoint (or step) row of its segment or after it, where the planner has
already brought the motion to rest, and to its place among the signals: an M5 before an M6 switches
the spindle off before the job stops, an M3 after it waits for Resume. Extra signals (from I/O nodes)
that fall on a stop's row come after the stop. M1 stops only while the optional stop is on.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flowmc.devices.jobs.job import gcode_line
from flowmc.motion.path import describe_segment
from flowmc.motion.trajectory import ProgramEvent

__all__ = ["Pause", "program_pauses", "last_tool_before"]

@dataclass(frozen=True)
class Pause:
    """One operator stop of a job: the event, where it is (as the user counts), the G-code line."""

    event: ProgramEvent
    where: str
    line: int | None

    def stops(self, optional_stop: bool) -> bool:
        return self.event.kind != "optional_pause" or optional_stop

    def describe(self) -> str:
        said = self.event.said
        return f"{self.event.what} at {self.where}" + (f": {said}" if said else "") + "; Resume carries on"


def program_pauses(motion, seg_rows: np.ndarray, signal_rows: list[int], own_rows: np.ndarray
                   ) -> list[tuple[int, int, Pause]]:
    """``(row, place, pause)`` for each event of ``motion``: the row of ``seg_rows`` (the segment of each
    setpoint row the device runs) where it stops, and its place in the row-sorted list of all the
    job's signals (``signal_rows``; ``own_rows``: the rows of the program's own signals, in order).
    ``place`` counts the signals that come before it; pauses are listed in program order."""
    names = motion.segment_names
    out = []
    for event in getattr(motion, "events", ()):
        row = min(int(np.searchsorted(seg_rows, event.segment, side="left")), max(len(seg_rows) - 1, 0))
        before = np.asarray(own_rows[:event.signals_before])
        at_row = int(np.count_nonzero(before >= row))  # the program's signals on this row before the stop
        place = int(np.searchsorted(np.asarray(signal_rows), row, side="left")) + at_row
        name = names[event.segment] if event.segment < len(names) else ""
        out.append((row, place, Pause(event, describe_segment(event.segment, names), gcode_line(name))))
    return out


def last_tool_before(motion, segment: int) -> ProgramEvent | None:
    """The last tool change of ``motion`` before ``segment`` (what a start mid-program assumes is loaded)."""
    changes = [e for e in getattr(motion, "events", ()) if e.kind == "tool_change" and e.segment < segment]
    return changes[-1] if changes else None
