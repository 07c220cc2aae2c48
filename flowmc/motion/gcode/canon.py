"""What an interpretation makes: moves, dwells and path events in machine coordinates, kept as columns
while the program runs and handed on as path columns (no Segment objects) at the end.

Output changes follow LinuxCNC's timing. M62/M63/M67 (synchronised with motion) ride on the next
move's ``outputs``/``analog``. M64/M65/M68 and coolant (M7/M8/M9) happen when reached, after the
moves before them: they ride on the next dwell if one comes before the next move, or else on a
zero-second dwell placed just before that move. Pauses (M0/M1/M60) and tool changes (M6) are
zero-second dwells carrying a ``PathEvent``. Whatever is left at the end (changes, a spindle stop)
goes on a final zero-second dwell, so nothing is lost.
"""

from __future__ import annotations

from array import array

import numpy as np

import flowmc.budget as budget
from flowmc.errors import GcodeError
from flowmc.motion.path import MAX_COORD_MM, NurbsCurve, PathEvent
from flowmc.motion.path_columns import ARC, CURVE, DWELL, LINE, PathColumns

__all__ = ["Canon"]

NURBS = CURVE  # a G5/G5.1 spline row


class Canon:
    """Collects segments as columns. Coordinates are machine coordinates in mm, feeds mm/s.

    Rows made one at a time (``line_to``, ``arc_to``, ``dwell``) gather in short Python lists, the
    tail; ``extend_moves`` (many rows from the plain-line reader) first seals the tail into a numpy
    chunk, then appends its own arrays as a chunk: a large program is a few hundred arrays, not
    millions of list items. ``columns`` joins the chunks once at the end."""

    def __init__(self, rapid_feed: float):
        self.rapid_feed = rapid_feed
        self.chunks: list[tuple] = []  # sealed rows: (kind, ends, rapid, feed, spindle, file, line) arrays
        self.arc_chunks: list[tuple] = []  # arcs of those chunks: (rows, centres, normals, ccw, turns) arrays
        self.sealed = 0  # rows in the chunks
        # Numbers go in typed arrays (stored unboxed, side by side: sealing copies them at once); kinds,
        # flags and file indices are a few shared Python objects, kept in lists.
        self.kind: list[int] = []
        self.x = array("d")
        self.y = array("d")
        self.z = array("d")
        self.rapid: list[bool] = []
        self.feed = array("d")
        self.spindle = array("d")
        self.file: list[int] = []
        self.line = array("q")
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
        return self.sealed + len(self.kind)

    def last_end(self) -> tuple[float, float, float] | None:
        """Where the last row ends (None before any row)."""
        if self.kind:
            return self.x[-1], self.y[-1], self.z[-1]
        if self.chunks:
            x, y, z = self.chunks[-1][1][-1].tolist()
            return x, y, z
        return None

    def last_spindle(self) -> float | None:
        if self.kind:
            return self.spindle[-1]
        if self.chunks:
            return float(self.chunks[-1][4][-1])
        return None

    def _seal(self) -> None:
        """The tail's rows into a chunk of arrays (its arcs with them)."""
        if not self.kind:
            return
        ends = np.empty((len(self.kind), 3))
        ends[:, 0] = np.frombuffer(self.x, dtype=float)
        ends[:, 1] = np.frombuffer(self.y, dtype=float)
        ends[:, 2] = np.frombuffer(self.z, dtype=float)
        self.chunks.append((np.array(self.kind, dtype=np.int8), ends, np.array(self.rapid, dtype=bool),
                            np.frombuffer(self.feed, dtype=float).copy(), np.frombuffer(self.spindle, dtype=float).copy(),
                            np.array(self.file, dtype=np.int32), np.frombuffer(self.line, dtype=np.int64).copy()))
        self.sealed += len(self.kind)
        for column in (self.kind, self.rapid, self.file):
            column.clear()
        for numbers in (self.x, self.y, self.z, self.feed, self.spindle, self.line):
            del numbers[:]
        if self.arcs:
            table = np.array(list(self.arcs.values()), dtype=float)
            self.arc_chunks.append((np.fromiter(self.arcs, dtype=np.int64, count=len(self.arcs)), table[:, :3],
                                    table[:, 3].astype(np.int8), table[:, 4] != 0, table[:, 5].astype(np.int64)))
            self.arcs = {}

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
        return self.last_end() or self.start

    def dwell(self, seconds: float, feed: float, spindle: float, file: int, line: int,
              event: PathEvent | None = None) -> None:
        k = len(self)
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
        k = len(self)
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
        k = len(self)
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
        self._seal()
        k0 = self.sealed
        kind = np.zeros(m, dtype=np.int8)
        kind[arcs] = ARC
        rapid = np.asarray(rapid, dtype=bool)
        self.chunks.append((kind, np.array(ends, dtype=float), rapid.copy(),
                            np.where(rapid, self.rapid_feed, feed).astype(float),
                            np.array(spindle, dtype=float), np.full(m, file, dtype=np.int32),
                            np.array(lines, dtype=np.int64)))
        self.sealed += m
        if len(arcs):
            self.arc_chunks.append((np.asarray(arcs, dtype=np.int64) + k0, np.array(centres, dtype=float),
                                    np.array(normals, dtype=np.int8), np.array(ccw, dtype=bool),
                                    np.array(turns, dtype=np.int64)))

    def nurbs_to(self, points: list, degree: int, feed: float, spindle: float, file: int, line: int) -> None:
        """A NURBS (G5/G5.1 spline) through machine-coordinate control points; it ends on the last."""
        if self.now_out or self.now_an or self.sync_out or self.sync_an:
            self._before_move(feed, spindle)
        k = len(self)
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
        last = self.last_spindle()
        changed = last is not None and last != spindle
        if pending or changed:
            self.dwell(0.0, feed, spindle, file, line)

    # Assembly ----------------------------------------------------------------------------------
    def _joined(self) -> tuple:
        """All rows as arrays (kind, ends, rapid, feed, spindle, file, line), and all arcs as
        (rows, centres, normals, ccw, turns)."""
        self._seal()
        rows = tuple(np.concatenate(parts) for parts in zip(*self.chunks))
        self.chunks = [rows]
        if self.arc_chunks:
            arcs = tuple(np.concatenate(parts) for parts in zip(*self.arc_chunks))
            self.arc_chunks = [arcs]
        else:
            arcs = (np.zeros(0, dtype=np.int64), np.zeros((0, 3)), np.zeros(0, dtype=np.int8), np.zeros(0, dtype=bool),
                    np.zeros(0, dtype=np.int64))
        return rows, arcs

    def _check_sizes(self, files: list[str], rows: tuple, arcs: tuple) -> None:
        """Refuse coordinates beyond any machine (whose lengths would overflow) and arcs of more turns
        than the budget, naming the line, before any segment is made."""
        file, line = rows[5], rows[6]

        def where(k: int) -> str:
            return f"{files[file[k]]}:{line[k]}"

        ends = rows[1]
        k = _first_bad(~(np.abs(ends) <= MAX_COORD_MM).all(axis=1))
        if k is not None:
            raise GcodeError(f"the move ends at {ends[k].tolist()} mm, out of range: coordinates must be within "
                             f"+-{MAX_COORD_MM:g} mm", where=where(k))
        index, centres, _, _, turns = arcs
        if index.size:
            k = _first_bad(~(np.abs(centres) <= MAX_COORD_MM).all(axis=1))
            if k is not None:
                raise GcodeError(f"the arc's centre {centres[k].tolist()} mm is out of range: coordinates "
                                 f"must be within +-{MAX_COORD_MM:g} mm", where=where(int(index[k])))
            limit = budget.cap("turns")
            k = _first_bad(turns > limit)
            if k is not None:
                raise GcodeError(f"the arc makes {turns[k] + 1:,} turns (P), over the arc-turns budget of "
                                 f"{limit:,}: use fewer turns (FLOWMC_BUDGET_TURNS raises the budget)",
                                 where=where(int(index[k])))

    def columns(self, files: list[str]) -> PathColumns | None:
        """The program as path columns (None when it made no segment); ``files`` names each file
        index in the sources. The interpreter checked every row, so no Segment is built here."""
        n = len(self)
        if n == 0:
            return None
        rows, arcs = self._joined()
        self._check_sizes(files, rows, arcs)
        kind, ends, rapid, feed, spindle, file, line = rows
        starts = np.empty((n, 3))
        starts[0] = self.start
        starts[1:] = ends[:-1]
        # A dwell keeps the tool as the last move left it (down before any move).
        moves = kind != DWELL
        last_move = np.maximum.accumulate(np.where(moves, np.arange(n), -1))
        tool_down = np.where(moves, ~rapid, np.where(last_move < 0, True, ~rapid[np.maximum(last_move, 0)]))
        center = np.zeros((n, 3))
        normal = np.full(n, 2, dtype=np.int8)
        ccw = np.ones(n, dtype=bool)
        turns = np.zeros(n, dtype=np.int64)
        index = arcs[0]
        if index.size:
            normal[index] = arcs[2]
            center[index] = arcs[1]
            center[index, normal[index]] = starts[index, normal[index]]
            ccw[index] = arcs[3]
            turns[index] = arcs[4]
        seconds = np.zeros(n)
        if self.dwells:
            seconds[np.fromiter(self.dwells, dtype=np.int64, count=len(self.dwells))] = list(self.dwells.values())
        curves = {}
        for k, (points, degree) in self.curves.items():
            points = [starts[k]] + [np.asarray(p, dtype=float) for p in points[1:]]
            curves[k] = NurbsCurve(points, degree=degree, feed=float(feed[k]), rapid=False, tool_down=True,
                                   spindle=float(spindle[k]), source=f"{files[file[k]]}:{line[k]}")
        return PathColumns(
            kind=kind, start=starts, end=ends, feed=feed, rapid=rapid, tool_down=tool_down,
            spindle=spindle, center=center, normal_axis=normal, ccw=ccw, turns=turns,
            seconds=seconds, files=tuple(files), file=file, line=line, events=dict(self.events),
            outputs={k: tuple(changes.items()) for k, changes in self.outputs.items()},
            analog={k: tuple(changes.items()) for k, changes in self.analog.items()}, curves=curves)


def _first_bad(mask: np.ndarray) -> int | None:
    hit = np.flatnonzero(mask)
    return int(hit[0]) if hit.size else None
