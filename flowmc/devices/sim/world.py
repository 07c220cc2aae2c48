"""Where the simulated card's switches are, and which input each one drives (the 6050's input map).

Inputs count from 1. By default inputs 9-20 are the axis switches: axis i (0-based) has its
+limit on input 9 + 3i, its home switch on 10 + 3i and its -limit on 11 + 3i; turning an axis's
I/O off (the thesis's SetAxisIO_6050) makes those three plain inputs and disables that axis's
limit stops. Inputs 1-8 are plain inputs; one of them may be the e-stop.

Switch positions are in *world* millimetres, fixed to the machine frame. The step counter starts
at world 0; homing moves the counter's zero, so the same switch sits at a different coordinate
afterwards, as on a real machine.
"""

from __future__ import annotations

from dataclasses import dataclass

from flowmc.motion.machine import Axis

__all__ = ["AxisSwitches", "default_switches", "switch_inputs", "N_INPUTS", "N_CARD_AXES"]

N_INPUTS = 20
N_CARD_AXES = 4
LIMIT_MARGIN_MM = 5.0  # default distance of the limit switches beyond the soft limits


@dataclass(frozen=True)
class AxisSwitches:
    """One axis's switches in world mm.

    The -limit is closed at or below ``neg_limit``, the +limit at or above ``pos_limit``. The home
    switch is a cam closed at or below ``home`` (on its negative side), so an axis always finds it
    by moving in the negative direction and is clear of it on the positive side.
    """

    neg_limit: float
    pos_limit: float
    home: float

    def __post_init__(self):
        if not self.neg_limit < self.home < self.pos_limit:
            raise ValueError(f"switches must be ordered -limit < home < +limit, got {self}")


def default_switches(axis: Axis) -> AxisSwitches:
    """Limits 5 mm beyond the soft limits; home at 0 (or mid-travel if 0 is outside the travel)."""
    home = 0.0 if axis.min < 0.0 < axis.max else 0.5 * (axis.min + axis.max)
    return AxisSwitches(axis.min - LIMIT_MARGIN_MM, axis.max + LIMIT_MARGIN_MM, home)


def switch_inputs(axis_index: int) -> tuple[int, int, int]:
    """Input numbers (+limit, home, -limit) of a card axis (0-based)."""
    base = 9 + 3 * axis_index
    return base, base + 1, base + 2
