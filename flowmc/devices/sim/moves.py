"""Moves the card makes by itself (jog, homing, the approach to a program's start), sampled at period T."""

from __future__ import annotations

import math

import numpy as np

import flowmc.budget as budget

__all__ = ["line_move", "ramp"]


def line_move(start, end, vmax, amax, period: float, speed: float | None = None) -> np.ndarray:
    """A straight move from ``start`` to ``end`` (mm, one value per axis) with a trapezoidal speed profile.

    The path speed and acceleration are the largest that keep every axis within its ``vmax`` and
    ``amax`` (and within ``speed`` if given). The profile is stretched slightly so that it ends
    exactly on a period; row 0 is ``start`` and the last row is ``end``.
    """
    start = np.asarray(start, dtype=float)
    end = np.asarray(end, dtype=float)
    delta = end - start
    length = float(np.linalg.norm(delta))
    if length == 0.0:
        return start[None, :].copy()
    unit = np.abs(delta) / length
    moving = unit > 0
    v = float(np.min(np.asarray(vmax, float)[moving] / unit[moving]))
    a = float(np.min(np.asarray(amax, float)[moving] / unit[moving]))
    if speed is not None:
        v = min(v, float(speed))
    t_acc = v / a
    if a * t_acc * t_acc > length:  # no cruise: a triangle
        t_acc = math.sqrt(length / a)
        v = a * t_acc
    t_total = 2 * t_acc + (length - a * t_acc * t_acc) / v
    budget.check("setpoints", t_total / period + 1, axes=len(delta), what=f"a move of {t_total:.6g} s",
                 change="move a shorter distance or faster")
    rows = max(math.ceil(t_total / period - 1e-9), 1)
    t = np.arange(rows + 1) * (t_total / rows)  # stretched onto whole periods
    s = np.where(t < t_acc, 0.5 * a * t * t,
                 np.where(t > t_total - t_acc, length - 0.5 * a * (t_total - t) ** 2, a * t_acc * (t - 0.5 * t_acc)))
    s[-1] = length
    return start + np.outer(s / length, delta)


def ramp(start: float, direction: int, speed: float, distance: float, period: float) -> np.ndarray:
    """One axis at constant ``speed`` for ``distance`` mm in ``direction`` (+1/-1): positions per period.

    Homing moves at a set speed without ramps (the thesis's V1 and V2, slow enough for a stepper
    to start and stop at once).
    """
    budget.check("setpoints", distance / (speed * period) + 1, axes=1,
                 what=f"{distance:g} mm at {speed:g} mm/s", change="move a shorter distance or faster")
    rows = max(math.ceil(distance / (speed * period) - 1e-9), 1)
    travel = np.minimum(np.arange(rows + 1) * speed * period, distance)
    return start + direction * travel
