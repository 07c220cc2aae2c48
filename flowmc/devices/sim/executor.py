"""Run a commanded count sequence on the simulated axes: stop rules, e-stop, and the closed loop.

Everything is vectorised over periods. A stop rule trips at the first period in which an axis steps
in the rule's direction and ends at or beyond the rule's threshold; ``numpy.flatnonzero`` finds
that period, and the axis is frozen from there on. In open loop the position is the step counter,
so a switch stops the axis on the very step that closed it (the card's interrupt). In closed loop
switches are judged on the motor position; the card then holds the motor where it is, and the
motor coasts to a stop through the loop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from flowmc.devices.sim.pid import PositionLoop

__all__ = ["StopRule", "Trip", "Executed", "execute"]

SETTLED = 0.01  # following error (in steps) below which a closed-loop axis counts as settled


@dataclass(frozen=True)
class StopRule:
    """Stop ``axis`` when it steps in ``direction`` (+1/-1) and ends at or beyond count ``at``.

    ``take_step``: a switch lets the closing step happen and stops there; a soft limit refuses it.
    ``on_command``: judged on the commanded counts (soft limits) rather than on the motor (switches).
    """

    axis: int
    kind: str
    direction: int
    at: float
    take_step: bool = True
    on_command: bool = False


@dataclass(frozen=True)
class Trip:
    row: int
    rule: StopRule
    count: int  # where the axis's command stopped


@dataclass(frozen=True)
class Executed:
    command: np.ndarray  # (N, n) commanded counts
    actual: np.ndarray  # (N, n) axis positions in mm (the counter in open loop, the motor in closed loop)
    trips: tuple[Trip, ...]
    estop_row: int | None


def _first_trip(col: np.ndarray, rule: StopRule) -> int | None:
    d = np.diff(col)
    hit = np.flatnonzero((rule.direction * d > 0) & (rule.direction * (col[1:] - rule.at) >= 0))
    return int(hit[0]) + 1 if len(hit) else None


def _stop_count(prev: int, rule: StopRule) -> int:
    first = math.ceil(rule.at - 1e-9) if rule.direction > 0 else math.floor(rule.at + 1e-9)
    stop = first if rule.take_step else first - rule.direction
    return max(prev, stop) if rule.direction > 0 else min(prev, stop)


def _command_trips(cmd: np.ndarray, rules, last_row: int) -> dict[int, Trip]:
    """Earliest trip per axis (ties: the rule that stops the axis soonest); freezes ``cmd`` in place."""
    best: dict[int, Trip] = {}
    for rule in rules:
        col = cmd[:, rule.axis]
        k = _first_trip(col, rule)
        if k is None or k > last_row:
            continue
        trip = Trip(k, rule, _stop_count(int(col[k - 1]), rule))
        old = best.get(rule.axis)
        if old is None or k < old.row or (k == old.row and rule.direction * (trip.count - old.count) < 0):
            best[rule.axis] = trip
    for axis, trip in best.items():
        cmd[trip.row:, axis] = trip.count
    return best


def execute(command: np.ndarray, rules, step_mm: np.ndarray, *, estop_row: int | None = None,
            loop: PositionLoop | None = None, until_trip: bool = False) -> Executed:
    """Apply stop rules and an e-stop (every axis stops at ``estop_row``, the end) to ``command`` (N, n) counts.

    ``until_trip`` ends the sequence at the first trip (homing phases). In closed loop the command
    is held at its last value until every axis has settled, so the result may be longer than given;
    with a ``LoopStream`` (a job fed a stretch at a time) it is neither padded nor settled here.
    """
    streaming = getattr(loop, "streaming", False)
    cmd = np.array(command, dtype=np.int64)
    n_rows = len(cmd)
    if estop_row is not None and estop_row >= n_rows:
        estop_row = None
    last_row = estop_row if estop_row is not None else n_rows - 1
    by_command = [r for r in rules if r.on_command or loop is None]
    trips = _command_trips(cmd, by_command, last_row)
    if estop_row is not None:  # every axis stops where it is at the end of that period; nothing follows
        cmd = cmd[:estop_row + 1]
        n_rows = len(cmd)
    if loop is None:
        if until_trip and trips:
            cmd = cmd[:min(t.row for t in trips.values()) + 1]
        return Executed(cmd, cmd * step_mm, tuple(sorted(trips.values(), key=lambda t: (t.row, t.rule.axis))),
                        estop_row)
    if not streaming:
        cmd = _padded(cmd, loop)
    actual = loop.response(cmd * step_mm)
    for rule in rules:
        if rule.on_command:
            continue
        k = _first_trip(actual[:, rule.axis] / step_mm[rule.axis], rule)
        old = trips.get(rule.axis)
        if k is None or (old is not None and old.row <= k):
            continue
        where = actual[k, rule.axis] / step_mm[rule.axis]  # hold at or past the motor, so the switch stays tripped
        hold = math.ceil(where - 1e-9) if rule.direction > 0 else math.floor(where + 1e-9)
        trips[rule.axis] = Trip(k, rule, hold)
        cmd[k:, rule.axis] = hold
        held = cmd[:, rule.axis:rule.axis + 1] * step_mm[rule.axis]
        actual[:, rule.axis] = (loop.response(held, rule.axis) if streaming else loop.response(held))[:, 0]
    base = n_rows
    if streaming:
        return Executed(cmd, actual, tuple(sorted(trips.values(), key=lambda t: (t.row, t.rule.axis))), estop_row)
    if until_trip and trips:
        base = min(t.row for t in trips.values()) + 1
        cmd = _padded(cmd[:base], loop)
        actual = loop.response(cmd * step_mm)
    unsettled = np.flatnonzero((np.abs(cmd * step_mm - actual) / step_mm).max(axis=1) > SETTLED)
    keep = max(base, int(unsettled[-1]) + 2 if len(unsettled) else 0)
    return Executed(cmd[:keep], actual[:keep], tuple(sorted(trips.values(), key=lambda t: (t.row, t.rule.axis))),
                    estop_row)


def _padded(cmd: np.ndarray, loop: PositionLoop) -> np.ndarray:
    """The command with its last row held long enough for the motors to settle."""
    return np.vstack([cmd, np.repeat(cmd[-1:], loop.settle_rows, axis=0)])
