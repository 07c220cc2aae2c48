"""The simulated card fed a stretch of periods at a time: how a job runs on it in real time.

The instant mode computes a whole program at once (``SimCard.run``). A job that can be held,
overridden and stopped cannot: its setpoints are decided as it goes. ``CardStream`` runs each
stretch through the same executor (stop rules, limit switches, the e-stop input, the closed loop
carried between stretches by a ``LoopStream``) and keeps the same log. A limit, soft limit or
e-stop stops every axis at the period it happens (a stretch is tried first to find it, then run
only up to there); the stream then refuses to move.
"""

from __future__ import annotations

import numpy as np

from flowmc.devices.log import Change, DeviceLog, Event
from flowmc.devices.sim.executor import SETTLED, execute
from flowmc.errors import DeviceError

__all__ = ["CardStream"]


class CardStream:
    """A job's program on ``card``, a stretch at a time; ``fault`` is the event that stopped it, if any."""

    def __init__(self, card):
        card._ready()
        self.card = card
        self.rules = card._motion_rules()
        self.loop = card.loop.stream(card.position()) if card.loop is not None else None
        self.fault: Event | None = None

    @property
    def clock(self) -> float:
        return self.card.clock

    def commanded(self) -> np.ndarray:
        return self.card._counts * self.card.step_mm

    def actual(self) -> np.ndarray:
        return self.card.position()

    def move(self, setpoints: np.ndarray) -> int:
        """Run these setpoints (mm, one row per period, every machine axis); returns how many ran
        (fewer when a limit or the e-stop stopped the card: ``fault`` says which)."""
        if self.fault is not None:
            raise DeviceError(f"the card stopped: {self.fault.message}", where="sim card")
        card = self.card
        counts = np.rint(np.asarray(setpoints, dtype=float) / card.step_mm).astype(np.int64)
        command = np.vstack([card._counts[None, :], counts])
        trial = execute(command, self.rules, card.step_mm, estop_row=card._estop_row(card._tick, len(command)),
                        loop=self.loop)
        stops = [t.row for t in trial.trips] + ([trial.estop_row] if trial.estop_row is not None else [])
        if stops:
            command = command[:min(stops) + 1]
        piece = card._execute(command, self.rules, loop=self.loop)
        if self.loop is not None:
            self.loop.commit()
        if piece.trips or piece.estop:
            self.fault = piece.events[0] if piece.events else Event("error", card.clock, "", "the card stopped")
        return len(command) - 1

    def output(self, kind: str, channel: int, value: float, where: str = "sim card") -> list[Change]:
        """Set one output now (at the card's clock)."""
        return self.card.output_now(kind, channel, value, where)

    def settle(self, most_rows: int | None = None) -> None:
        """Closed loop: hold the command until the motors have settled (below 0.01 step), as the card does."""
        if self.loop is None:
            return
        card = self.card
        rows = most_rows or self.loop.settle_rows
        held = np.repeat(card._counts[None, :], rows + 1, axis=0)
        actual = self.loop.response(held * card.step_mm)
        err = np.abs(held * card.step_mm - actual) / card.step_mm
        unsettled = np.flatnonzero(err.max(axis=1) > SETTLED)
        keep = int(unsettled[-1]) + 2 if len(unsettled) else 1
        if keep > 1:
            card._execute(held[:keep], [], loop=self.loop)
            self.loop.commit()

    def log(self, outcome: str | None = None, events=()) -> DeviceLog:
        """Everything since the stream opened as one log (the card's state carries on from its end)."""
        return self.card._log(outcome, events)
