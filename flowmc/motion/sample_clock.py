"""The sample clock every planner shares: setpoints at t = kT, the last one exactly at the end.

Both the curve planners (flowmc.motion.timelaw) and the per-segment look-ahead planners
(flowmc.motion.lookahead) sample this way, and both refuse, before allocating, a motion whose
setpoints would exceed the memory budget: a feed near 0 turns a tiny program into billions of rows.
"""

import math

import numpy as np

import flowmc.budget as budget

__all__ = ["sample_count", "sample_times", "setpoint_times"]


def sample_count(total: float, period: float) -> int:
    """How many samples ``sample_times`` gives, without making them (a plan weighed by its length only)."""
    return max(1, math.ceil(total / period - 1e-9)) + 1


def sample_times(total: float, period: float) -> np.ndarray:
    """t = kT for k = 0..N, the last exactly at the end of a motion lasting ``total``."""
    ts = np.arange(sample_count(total, period)) * period
    ts[-1] = total
    return ts


def setpoint_times(total: float, period: float, axes: int) -> np.ndarray:
    """``sample_times``, after a BudgetError check on the setpoints (of ``axes`` columns) they make."""
    budget.check("setpoints", total / period + 1, axes=axes,
                 what=f"planning {total:.6g} s of motion at a {period * 1e3:g} ms period",
                 change="raise the feeds (a feed near 0 makes a move last for ever), shorten the program, "
                        "or lengthen the machine's period")
    return sample_times(total, period)
