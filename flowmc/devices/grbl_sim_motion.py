"""The GRBL simulator's motion model (``GrblSimulator(motion=True)``): moves take time.

Each accepted G0/G1 move becomes a block in a 15-block planner queue (``ok`` is sent when the block is
queued, as GRBL does); a full queue holds back line processing, so the host's stream really waits on
the machine. Blocks run one after another, each from rest to rest with a trapezoidal speed profile
at ``accel`` (mm/s^2) along the move and its feed (G1, times the feed override) or the rapid rate
(G0, times the rapid override). Feed hold (``!``) decelerates along the move at ``accel`` (state
``Hold:1``) and stops on it (``Hold:0``); resume (``~``) accelerates again; no position is lost.
Overrides (the real-time bytes 0x90-0x9D) change the speed of the running block at once, within
``accel``. A soft reset while moving loses the position on a real board: here it raises ``ALARM:3``
and locks, as GRBL does. G4 dwells take their time in the queue.

Not modelled: junction speeds between blocks (GRBL's planner carries speed through corners; here
every block ends at rest, so a streamed polyline takes longer than on a board), per-axis limits
(one acceleration along the move), step timing, arcs (G2/G3 move straight to their end point).
"""

from __future__ import annotations

import collections
import math
from dataclasses import dataclass

__all__ = ["MotionModel", "PLANNER_BLOCKS", "OVERRIDE_BYTES"]

PLANNER_BLOCKS = 15
_SUBSTEP = 0.001  # s: the model integrates in steps of a millisecond
#: GRBL 1.1's real-time override bytes.
OVERRIDE_BYTES: dict[int, tuple[str, int | str]] = {
    0x90: ("feed", "reset"), 0x91: ("feed", 10), 0x92: ("feed", -10), 0x93: ("feed", 1), 0x94: ("feed", -1),
    0x95: ("rapid", 100), 0x96: ("rapid", 50), 0x97: ("rapid", 25),
    0x99: ("spindle", "reset"), 0x9A: ("spindle", 10), 0x9B: ("spindle", -10), 0x9C: ("spindle", 1),
    0x9D: ("spindle", -1)}


@dataclass
class _Block:
    start: list[float]
    target: list[float]
    length: float  # mm (0 for a dwell)
    speed: float  # mm/s at 100 % (feed, or the rapid rate)
    rapid: bool
    dwell: float = 0.0  # s


class MotionModel:
    def __init__(self, position: list[float], *, accel: float = 200.0, rapid_rate: float = 6000.0):
        self.position = list(position)
        self.accel = float(accel)
        self.rapid_rate = float(rapid_rate) / 60.0  # mm/s
        self.queue: collections.deque[_Block] = collections.deque()
        self.block: _Block | None = None
        self.done_s = 0.0  # mm (or s of a dwell) of the running block done
        self.speed = 0.0  # mm/s now
        self.hold = False
        self.overrides = {"feed": 100, "rapid": 100, "spindle": 100}
        self.ends: list[list[float]] = []  # where blocks ended since the simulator last took them

    # ------------------------------------------------------------ queue
    @property
    def room(self) -> bool:
        return len(self.queue) < PLANNER_BLOCKS

    @property
    def busy(self) -> bool:
        return self.block is not None or bool(self.queue)

    @property
    def moving(self) -> bool:
        return self.speed > 0.0

    def planned_end(self) -> list[float]:
        """Where the last queued block ends (where the next move starts)."""
        return list(self.queue[-1].target if self.queue else self.block.target if self.block else self.position)

    def move(self, target: list[float], feed_mm_min: float, rapid: bool) -> None:
        start = self.planned_end()
        length = math.dist(start, target)
        if length > 1e-9:
            self.queue.append(_Block(start, list(target), length, self.rapid_rate if rapid else feed_mm_min / 60.0, rapid))

    def dwell(self, seconds: float) -> None:
        here = self.planned_end()
        self.queue.append(_Block(here, here, 0.0, 0.0, False, max(float(seconds), 0.0)))

    def clear(self) -> None:
        """A soft reset: the queue and the running block are gone; the position stays where it is."""
        self.queue.clear()
        self.block, self.done_s, self.speed, self.hold = None, 0.0, 0.0, False
        self.overrides = {"feed": 100, "rapid": 100, "spindle": 100}

    def override(self, byte: int) -> None:
        kind, step = OVERRIDE_BYTES[byte]
        low, high = (10, 200)
        if kind == "rapid":
            self.overrides["rapid"] = int(step)
            return
        value = 100 if step == "reset" else self.overrides[kind] + int(step)
        self.overrides[kind] = min(max(value, low), high)

    # ------------------------------------------------------------ time
    def state(self) -> str:
        if self.hold:
            return "Hold:1" if self.moving else "Hold:0"
        return "Run" if self.busy else "Idle"

    def advance(self, dt: float) -> None:
        while dt > 1e-12:
            h = min(dt, _SUBSTEP)
            dt -= h
            if self.block is None:
                if not self.queue or self.hold:
                    self.speed = 0.0
                    return
                self.block, self.done_s = self.queue.popleft(), 0.0
            b = self.block
            if b.length == 0.0:  # a dwell
                if not self.hold:
                    self.done_s += h
                if self.done_s >= b.dwell:
                    self.block = None
                continue
            left = b.length - self.done_s
            pct = self.overrides["rapid" if b.rapid else "feed"] / 100.0
            goal = 0.0 if self.hold else min(b.speed * pct, math.sqrt(2.0 * self.accel * max(left, 0.0)))
            if self.speed < goal:
                self.speed = min(self.speed + self.accel * h, goal)
            else:
                self.speed = max(self.speed - self.accel * h, goal)
            self.done_s = min(self.done_s + self.speed * h, b.length)
            f = self.done_s / b.length
            self.position = [s + (t - s) * f for s, t in zip(b.start, b.target)]
            if b.length - self.done_s <= 1e-6:
                self.position, self.block, self.speed = list(b.target), None, 0.0
                self.ends.append(list(b.target))
