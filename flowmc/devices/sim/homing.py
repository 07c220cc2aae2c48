"""Homing on the simulated card: the thesis's switch procedure and the XY plotter's midpoint procedure.

``switch`` (000_*.txt, 4.3): move toward the home switch at V1 until it closes, reverse at V2 until
it opens, go a set distance further, stop, zero the counter. The home switch is a cam closed on its
negative side, so the search always runs in the negative direction; an axis already on the cam
skips the first move.

``midpoint`` (004_*.txt, 4.1.2): run to the -limit, then to the +limit (both at V1), go back to
halfway between the two positions where they closed, and zero the counter there.

Each step is one phase for the card's executor, ended by the switch it waits for (``until_trip``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from flowmc.devices.sim.card import SimCard

__all__ = ["HomingSettings", "home_axis"]

_MARGIN_MM = 1.0  # search moves are planned this far past the switch they should meet


@dataclass(frozen=True)
class HomingSettings:
    """V1 (search speed), V2 (leaving speed), both mm/s, and the distance past the switch's edge (mm)."""

    v1: float = 10.0
    v2: float = 2.0
    backoff: float = 1.0

    def __post_init__(self):
        if not (self.v1 > 0 and self.v2 > 0 and self.backoff > 0):
            raise ValueError(f"homing speeds and back-off must be > 0, got {self}")


def home_axis(card: "SimCard", axis: int, method: str) -> str | None:
    """Home one axis through ``card``'s phases; returns None when done, else why it failed."""
    return _switch(card, axis) if method == "switch" else _midpoint(card, axis)


def _switch(card: "SimCard", axis: int) -> str | None:
    s, sw = card.homing, card.switches[axis]
    name = card.machine.names[axis]
    if card.world_position(axis) > sw.home:
        trip = card.phase(axis, -1, s.v1, card.world_position(axis) - sw.neg_limit + _MARGIN_MM,
                          [card.rule(axis, "home_closed", -1, sw.home), card.limit_rule(axis, -1)])
        if trip is None or trip.rule.kind != "home_closed":
            return f"{name}: home switch not found before the -limit"
    trip = card.phase(axis, +1, s.v2, sw.home - card.world_position(axis) + _MARGIN_MM,
                      [card.rule(axis, "home_open", +1, sw.home, strict=True), card.limit_rule(axis, +1)])
    if trip is None or trip.rule.kind != "home_open":
        return f"{name}: the home switch did not open"
    trip = card.phase(axis, +1, s.v2, s.backoff, [card.limit_rule(axis, +1)])
    if trip is not None:
        return f"{name}: the +limit closed while backing off the home switch"
    return None


def _midpoint(card: "SimCard", axis: int) -> str | None:
    s, sw = card.homing, card.switches[axis]
    name = card.machine.names[axis]
    trip = card.phase(axis, -1, s.v1, card.world_position(axis) - sw.neg_limit + _MARGIN_MM,
                      [card.rule(axis, "find_-limit", -1, sw.neg_limit)])
    if trip is None:
        return f"{name}: -limit not found"
    low = card.count(axis)
    trip = card.phase(axis, +1, s.v1, sw.pos_limit - card.world_position(axis) + _MARGIN_MM,
                      [card.rule(axis, "find_+limit", +1, sw.pos_limit)])
    if trip is None:
        return f"{name}: +limit not found"
    high = card.count(axis)
    middle = (low + high) // 2
    card.phase(axis, -1, s.v1, (card.count(axis) - middle) * card.step_mm[axis], [])
    return None
