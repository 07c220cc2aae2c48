"""Closed position loop of the simulated card: a PID on each axis driving a first-order motor.

After the DSP thesis (001_*.txt): a positional PID, u_k = Kp e_k + Ki T sum(e) + Kd (e_k - e_{k-1}) / T,
computed once per period T. Here u is the velocity command to the axis drive, plus velocity feed-
forward Kff (r_{k+1} - r_k) / T. The drive and motor are a first-order velocity lag with time constant
tau (v' = (u - v) / tau), integrated to position; u is held over each period (zero-order hold).

The loop is linear, so instead of stepping it period by period in Python it is written as one
discrete state-space system (states: x, v, the integral, the last error, the last setpoint), turned
into a transfer function from setpoint to position and run with ``scipy.signal.lfilter`` over all
axes at once. Not modelled: drive saturation and encoder quantisation inside the loop (the loop
sees the exact motor position; at the default gains the following error is many counts).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import signal

from flowmc.errors import DeviceError

__all__ = ["LoopSettings", "PositionLoop", "LoopStream"]


@dataclass(frozen=True)
class LoopSettings:
    """PID gains (kp 1/s, ki 1/s^2, kd dimensionless), velocity feed-forward and the motor's time constant (s)."""

    kp: float = 150.0
    ki: float = 1000.0
    kd: float = 0.05
    kff: float = 1.0
    tau: float = 0.01


class PositionLoop:
    """The closed loop at period T: ``response(setpoints)`` gives the motor positions."""

    def __init__(self, settings: LoopSettings, period: float):
        s, T = settings, float(period)
        if not (s.tau > 0 and T > 0):
            raise DeviceError("motor time constant and period must be > 0", where="closed loop")
        alpha = math.exp(-T / s.tau)
        bx = T - s.tau * (1 - alpha)  # position gain of a held u over one period
        # state z = [x, v, I (integral before this period), e_prev, r]; input w_k = r_{k+1}
        # e = r - x; u = ce . z + cw * w
        kd_t, kff_t = s.kd / T, s.kff / T
        ce = np.array([-(s.kp + s.ki * T + kd_t), 0.0, s.ki, -kd_t, s.kp + s.ki * T + kd_t - kff_t])
        cw = kff_t
        e_row = np.array([-1.0, 0.0, 0.0, 0.0, 1.0])
        a = np.zeros((5, 5))
        a[0] = [1.0, s.tau * (1 - alpha), 0, 0, 0] + bx * ce
        a[1] = [0.0, alpha, 0, 0, 0] + (1 - alpha) * ce
        a[2] = [0, 0, 1.0, 0, 0] + T * e_row
        a[3] = e_row
        b = np.array([[bx * cw], [(1 - alpha) * cw], [0.0], [0.0], [1.0]])
        c = np.array([[1.0, 0, 0, 0, 0]])
        if s.ki == 0:  # without integral action the integral state is inert: drop it
            keep = [0, 1, 3, 4]
            a, b, c = a[np.ix_(keep, keep)], b[keep], c[:, keep]
        poles = np.linalg.eigvals(a)
        radius = float(np.max(np.abs(poles)))
        if radius >= 1.0 - 1e-9:
            raise DeviceError(f"the position loop is unstable at T = {T} s with {settings} "
                              f"(largest pole |z| = {radius:.4f}); lower kp/ki or raise tau", where="closed loop")
        num, den = signal.ss2tf(a, b, c, np.zeros((1, 1)))
        self.settings = settings
        self.period = T
        self.pole_radius = radius
        self._b, self._a = num[0], den
        #: at most this many periods for an error to shrink a million-fold once the setpoint stops
        self.settle_rows = int(min(math.ceil(math.log(1e-6) / math.log(radius)) if radius > 0 else 1, round(5.0 / T)))

    def response(self, setpoints: np.ndarray) -> np.ndarray:
        """Motor positions (N, n) for setpoints (N, n) in mm, starting at rest at ``setpoints[0]``."""
        r = np.asarray(setpoints, dtype=float)
        if len(r) < 2:
            return r.copy()
        r0 = r[0]
        w = np.vstack([r[1:], r[-1:]]) - r0  # w_k = r_{k+1}: the card knows the next setpoint
        return signal.lfilter(self._b, self._a, w, axis=0) + r0

    def stream(self, start_mm: np.ndarray) -> "LoopStream":
        """The loop fed a stretch of setpoints at a time, from rest at ``start_mm`` (the real-time mode)."""
        return LoopStream(self, start_mm)


class LoopStream:
    """The closed loop carried from one stretch of setpoints to the next (``lfilter`` state kept).

    ``response(setpoints)``: row 0 is the setpoint already reached (its motor position is the current
    one), rows 1.. continue from the kept state; the state moves on only at ``commit()``, so a
    stretch can be redone (a switch that trips mid-stretch holds an axis, and the stretch is rerun).
    The motor position after a setpoint does not depend on the next one (no direct feed-through), so
    every row's position is known when the row is given.
    """

    streaming = True

    def __init__(self, loop: PositionLoop, start_mm: np.ndarray):
        self.loop = loop
        self.settle_rows = loop.settle_rows
        self.r0 = np.asarray(start_mm, dtype=float).copy()
        order = max(len(loop._a), len(loop._b)) - 1
        self.zi = np.zeros((order, len(self.r0)))
        self._next = self.zi.copy()

    def response(self, setpoints: np.ndarray, column: int | None = None) -> np.ndarray:
        cols = slice(None) if column is None else slice(column, column + 1)
        sp = np.asarray(setpoints, dtype=float) - self.r0[cols]
        b, a = self.loop._b, self.loop._a
        y, zf = signal.lfilter(b, a, sp[1:], axis=0, zi=self.zi[:, cols])
        last, _ = signal.lfilter(b, a, np.zeros((1, sp.shape[1])), axis=0, zi=zf)
        self._next[:, cols] = zf
        return np.vstack([y, last]) + self.r0[cols] if len(sp) > 1 else last + self.r0[cols]

    def commit(self) -> None:
        self.zi = self._next.copy()
