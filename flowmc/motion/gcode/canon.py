"""What an interpretation makes: moves, dwells and path events in machine coordinates, kept as columns
while the program runs and turned into Path segments once at the end.

Output changes follow LinuxCNC's timing. M62/M63/M67 (synchronised with motion) ride on the next
move's ``outputs``/``analog``. M64/M65/M68 and coolant (M7/M8/M9) happen when reached, after the
moves before them: they ride on the next dwell if one comes before the next move, or else on a
zero-second dwell placed just before that move. Pauses (M0/M1/M60) and tool changes (M6) are
zero-second dwells carrying a ``PathEvent``. Whatever is left at the end (changes, a spindle stop)
goes on a final zero-second dwell, so nothing is lost.
"""

from __future__ import annotations

import contextlib
import gc

import numpy as np

import flowmc.budget as budget
from flowmc.errors import GcodeError
from flowmc.motion.path import MAX_COORD_MM, Arc, Dwell, Line, NurbsCurve, PathEvent

__all__ = ["Canon"]

LINE, ARC, DWELL, NURBS = 0, 1, 2, 3


class Canon:
    """Collects segments as columns. Coordinates are machine coordinates in mm, feeds mm/s."""

    def __init__(self, rapid_feed: float):
        self.rapid_feed = rapid_feed
        self.kind: list[int] = []
        self.x: list[float] = []
        self.y: list[float] = []
        self.z: list[float] = []
        self.rapid: list[bool] = []
        self.feed: list[float] = []
        self.spindle: list[float] = []
        self.file: list[int] = []
        self.line: list[int] = []
        self.arcs: dict[int, tuple] = {}  # index -> (cx, cy, cz, normal_axis, ccw, turns)
        self.dwells: dict[int, float] = {}  # index -> seconds
        self.curves: dict[int, tuple] = {}  # index -> (control points, degree)
        self.events: dict[int, PathEvent] = {}
        self.outputs: dict[int, dict] = {}
        self.analog: dict[int, dict] = {}
        self.sync_out: dict = {}
        self.sync_an: dict = {}
        self.now_out: dict = {}
        self.now_an: dict = {}
        self.now_src: tuple[int, int] | None = None
        self.start = (0.0, 0.0, 0.0)
        self.last_move_rapid = None

    def __len__(self) -> int:
        return len(self.kind)

    # Output changes ------------------------------------------------------------------------------
    def set_output(self, channel: int, on: bool, synced: bool, file: int, line: int) -> None:
        if synced:
            self.sync_out[channel] = on
        else:
            self.now_out[channel] = on
            self.now_src = self.now_src or (file, line)

    def set_analog(self, channel: int, volts: float, synced: bool, file: int, line: int) -> None:
        if synced:
            self.sync_an[channel] = volts
        else:
            self.now_an[channel] = volts
            self.now_src = self.now_src or (file, line)

    def _flush_now(self, index: int) -> None:
        if self.now_out:
            self.outputs[index] = self.now_out
            self.now_out = {}
        if self.now_an:
            self.analog[index] = self.now_an
            self.now_an = {}
        self.now_src = None

    # Segments ----------------------------------------------------------------------------------
    def _here(self) -> tuple[float, float, float]:
        if self.kind:
            return self.x[-1], self.y[-1], self.z[-1]
        return self.start

    def dwell(self, seconds: float, feed: float, spindle: float, file: int, line: int,
              event: PathEvent | None = None) -> None:
        k = len(self.kind)
        x, y, z = self._here()
        self.kind.append(DWELL)
        self.x.append(x)
        self.y.append(y)
        self.z.append(z)
        self.rapid.append(False)
        self.feed.append(feed if feed > 0 else self.rapid_feed)
        self.spindle.append(spindle)
        self.file.append(file)
        self.line.append(line)
        self.dwells[k] = seconds
        if event is not None:
            self.events[k] = event
        self._flush_now(k)

    def _before_move(self, feed: float, spindle: float) -> int:
        if self.now_out or self.now_an:
            file, line = self.now_src
            self.dwell(0.0, feed, spindle, file, line)
        k = len(self.kind)
        if self.sync_out:
            self.outputs[k] = self.sync_out
            self.sync_out = {}
        if self.sync_an:
            self.analog[k] = self.sync_an
            self.sync_an = {}
        return k

    def line_to(self, x: float, y: float, z: float, rapid: bool, feed: float, spindle: float, file: int,
                line: int) -> None:
        if self.now_out or self.now_an or self.sync_out or self.sync_an:
            self._before_move(feed, spindle)
        self.kind.append(LINE)
        self.x.append(x)
        self.y.append(y)
        self.z.append(z)
        self.rapid.append(rapid)
        self.feed.append(self.rapid_feed if rapid else feed)
        self.spindle.append(spindle)
        self.file.append(file)
        self.line.append(line)

    def arc_to(self, x: float, y: float, z: float, centre: tuple, normal_axis: int, ccw: bool, turns: int,
               feed: float, spindle: float, file: int, line: int) -> None:
        if self.now_out or self.now_an or self.sync_out or self.sync_an:
            self._before_move(feed, spindle)
        k = len(self.kind)
        self.kind.append(ARC)
        self.x.append(x)
        self.y.append(y)
        self.z.append(z)
        self.rapid.append(False)
        self.feed.append(feed)
        self.spindle.append(spindle)
        self.file.append(file)
        self.line.append(line)
        self.arcs[k] = (centre[0], centre[1], centre[2], normal_axis, ccw, turns)

    def extend_moves(self, ends, rapid, feed, spindle, file: int, lines, arcs, centres, normals, ccw,
                     turns) -> None:
        """Many lines and arcs at once (numpy arrays, one row per move): rows ``arcs`` are arcs about
        ``centres``. Pending output changes go with the first, as ``line_to`` does."""
        m = len(ends)
        if m == 0:
            return
        if self.now_out or self.now_an or self.sync_out or self.sync_an:
            self._before_move(float(feed[0]), float(spindle[0]))
        k0 = len(self.kind)
        kind = np.zeros(m, dtype=np.int64)
        kind[arcs] = ARC
        self.kind.extend(kind.tolist())
        self.x.extend(ends[:, 0].tolist())
        self.y.extend(ends[:, 1].tolist())
        self.z.extend(ends[:, 2].tolist())
        self.rapid.extend(np.asarray(rapid).tolist())
        feed = np.where(rapid, self.rapid_feed, feed)
        self.feed.extend(feed.tolist())
        self.spindle.extend(np.asarray(spindle, dtype=float).tolist())
        self.file.extend([file] * m)
        self.line.extend(np.asarray(lines).tolist())
        arc_rows = (np.asarray(arcs) + k0).tolist()
        for k, c, nrm, cc, t in zip(arc_rows, centres.tolist(), np.asarray(normals).tolist(),
                                    np.asarray(ccw).tolist(), np.asarray(turns).tolist()):
            self.arcs[k] = (c[0], c[1], c[2], nrm, cc, t)

    def nurbs_to(self, points: list, degree: int, feed: float, spindle: float, file: int, line: int) -> None:
        """A NURBS (G5/G5.1 spline) through machine-coordinate control points; it ends on the last."""
        if self.now_out or self.now_an or self.sync_out or self.sync_an:
            self._before_move(feed, spindle)
        k = len(self.kind)
        x, y, z = points[-1]
        self.kind.append(NURBS)
        self.x.append(x)
        self.y.append(y)
        self.z.append(z)
        self.rapid.append(False)
        self.feed.append(feed)
        self.spindle.append(spindle)
        self.file.append(file)
        self.line.append(line)
        self.curves[k] = (points, degree)

    def finish(self, feed: float, spindle: float, file: int, line: int) -> None:
        """At the program's end: leftover changes, and a spindle change after the last segment."""
        pending = self.now_out or self.now_an or self.sync_out or self.sync_an
        if self.sync_out:
            self.now_out = {**self.sync_out, **self.now_out}
            self.sync_out = {}
        if self.sync_an:
            self.now_an = {**self.sync_an, **self.now_an}
            self.sync_an = {}
        changed = bool(self.kind) and self.spindle[-1] != spindle
        if pending or changed:
            self.dwell(0.0, feed, spindle, file, line)

    # Assembly ----------------------------------------------------------------------------------
    def _check_sizes(self, files: list[str]) -> None:
        """Refuse coordinates beyond any machine (whose lengths would overflow) and arcs of more turns
        than the budget, naming the line, before any segment is made."""
        def where(k: int) -> str:
            return f"{files[self.file[k]]}:{self.line[k]}"

        ends = np.column_stack([self.x, self.y, self.z])
        k = _first_bad(~(np.abs(ends) <= MAX_COORD_MM).all(axis=1))
        if k is not None:
            raise GcodeError(f"the move ends at {ends[k].tolist()} mm, out of range: coordinates must be within "
                             f"+-{MAX_COORD_MM:g} mm", where=where(k))
        if self.arcs:
            index = np.fromiter(self.arcs, dtype=np.int64, count=len(self.arcs))
            table = np.array(list(self.arcs.values()), dtype=float)
            k = _first_bad(~(np.abs(table[:, :3]) <= MAX_COORD_MM).all(axis=1))
            if k is not None:
                raise GcodeError(f"the arc's centre {table[k, :3].tolist()} mm is out of range: coordinates "
                                 f"must be within +-{MAX_COORD_MM:g} mm", where=where(int(index[k])))
            limit = budget.cap("turns")
            k = _first_bad(table[:, 5] > limit)
            if k is not None:
                raise GcodeError(f"the arc makes {table[k, 5] + 1:,.0f} turns (P), over the arc-turns budget of "
                                 f"{limit:,}: use fewer turns (FLOWMC_BUDGET_TURNS raises the budget)",
                                 where=where(int(index[k])))


    def segments(self, files: list[str]) -> list:
        """The Segment objects, built without re-running their constructors' checks (the
        interpreter checked everything); ``files`` names each file index in ``source``."""
        n = len(self.kind)
        if n == 0:
            return []
        self._check_sizes(files)
        with _gc_paused():
            ends = np.empty((n, 3))
            ends[:, 0] = self.x
            ends[:, 1] = self.y
            ends[:, 2] = self.z
            ends.setflags(write=False)
            end_rows = list(ends)
            start = np.array(self.start, dtype=float)
            start.setflags(write=False)
            start_rows = [start] + end_rows[:-1]
            if len(files) == 1:
                prefix = files[0] + ":"
                sources = [prefix + str(line) for line in self.line]
            else:
                sources = [f"{files[f]}:{line}" for f, line in zip(self.file, self.line)]
            new = object.__new__
            out = [None] * n
            arc_index = list(self.arcs)
            if arc_index:
                table = np.array(list(self.arcs.values()), dtype=float)
                centres = table[:, :3].copy()
                normals = table[:, 3].astype(np.int64)
                starts_at = ends[np.maximum(np.array(arc_index) - 1, 0)]
                starts_at[np.array(arc_index) == 0] = start
                rows_a = np.arange(len(arc_index))
                centres[rows_a, normals] = starts_at[rows_a, normals]
                centres.setflags(write=False)
                arc_row = dict(zip(arc_index, range(len(arc_index))))
                centre_rows = list(centres)
            kinds, rapids, feeds, spindles = self.kind, self.rapid, self.feed, self.spindle
            arcs, dwells, events = self.arcs, self.dwells, self.events
            prev_rapid = None
            for k in range(n):
                kind = kinds[k]
                if kind == LINE:
                    seg = new(Line)
                    rapid = rapids[k]
                    seg.__dict__.update(start=start_rows[k], end=end_rows[k], feed=feeds[k], rapid=rapid,
                                        tool_down=not rapid, spindle=spindles[k], outputs=(), analog=(),
                                        source=sources[k])
                    prev_rapid = rapid
                elif kind == ARC:
                    _, _, _, normal, ccw, turns = arcs[k]
                    seg = new(Arc)
                    seg.__dict__.update(start=start_rows[k], end=end_rows[k], center=centre_rows[arc_row[k]],
                                        normal_axis=normal,
                                        ccw=ccw, turns=turns, feed=feeds[k], rapid=False, tool_down=True,
                                        spindle=spindles[k], outputs=(), analog=(), source=sources[k])
                    prev_rapid = False
                elif kind == NURBS:
                    points, degree = self.curves[k]
                    points = [start_rows[k]] + [np.asarray(p, dtype=float) for p in points[1:]]
                    seg = NurbsCurve(points, degree=degree, feed=feeds[k], rapid=False, tool_down=True,
                                     spindle=spindles[k], source=sources[k])
                    seg.__dict__.update(start=start_rows[k], end=end_rows[k])
                    prev_rapid = False
                else:
                    seg = new(Dwell)
                    seg.__dict__.update(start=start_rows[k], end=start_rows[k],
                                        seconds=dwells[k], event=events.get(k), feed=feeds[k], rapid=False,
                                        tool_down=True if prev_rapid is None else not prev_rapid,
                                        spindle=spindles[k], outputs=(), analog=(), source=sources[k])
                out[k] = seg
            for k, changes in self.outputs.items():
                out[k].__dict__["outputs"] = tuple(changes.items())
            for k, changes in self.analog.items():
                out[k].__dict__["analog"] = tuple(changes.items())
        return out


def _first_bad(mask: np.ndarray) -> int | None:
    hit = np.flatnonzero(mask)
    return int(hit[0]) if hit.size else None


@contextlib.contextmanager
def _gc_paused():
    """Pause the cyclic garbage collector while segments are made: they hold no cycles, and the
    collector's passes over 100k new objects would otherwise cost more than making them."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()
