"""Closed loop: the PID position loop on a first-order motor (the DSP thesis, 001_*.txt)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from device_programs import thesis_trajectory
from flowmc.devices.sim import LoopSettings, SimCard
from flowmc.devices.sim.pid import PositionLoop
from flowmc.errors import DeviceError
from flowmc.motion.machine import Machine

#: Stated bound on the following error for the thesis pattern, each segment a trapezoid from rest to
#: rest at a = 200 mm/s^2, with the default loop (kp 150/s, ki 1000/s^2, kd 0.05, velocity feed-forward 1,
#: motor tau 10 ms). The error comes from the steps in acceleration (the motor lags by about
#: tau * a / kp per step, plus overshoot); measured 0.027-0.032 mm at feeds 20-50 mm/s, T = 1-4 ms.
FOLLOWING_ERROR_BOUND_MM = 0.05


def _direct_loop(r: np.ndarray, s: LoopSettings, T: float) -> np.ndarray:
    """The same loop stepped period by period: the reference the lfilter form must match."""
    alpha = math.exp(-T / s.tau)
    x, v, integral, e_prev = r[0], 0.0, 0.0, 0.0
    out = np.empty(len(r))
    for k in range(len(r)):
        out[k] = x
        e = r[k] - x
        integral += T * e
        r_next = r[k + 1] if k + 1 < len(r) else r[k]
        u = s.kp * e + s.ki * integral + s.kd * (e - e_prev) / T + s.kff * (r_next - r[k]) / T
        e_prev = e
        x, v = x + s.tau * (1 - alpha) * v + (T - s.tau * (1 - alpha)) * u, alpha * v + (1 - alpha) * u
    return out


@pytest.mark.parametrize("settings", [LoopSettings(), LoopSettings(kp=80, ki=0, kd=0, kff=0.5, tau=0.02)])
def test_lfilter_form_equals_the_period_by_period_loop(settings):
    T = 0.002
    t = np.arange(1500) * T
    r = 5.0 + 10 * np.sin(2 * t) * (t < 2) + np.where(t > 2.2, 3.0, 0.0)
    x = PositionLoop(settings, T).response(r[:, None])[:, 0]
    assert np.abs(x - _direct_loop(r, settings, T)).max() < 1e-9


@pytest.mark.parametrize("period,feed", [(0.001, 20.0), (0.001, 50.0), (0.004, 20.0)])
def test_following_error_on_the_thesis_pattern_stays_under_the_bound(period, feed):
    tr = thesis_trajectory(period=period, feed=feed)
    card = SimCard(Machine(period=period), closed_loop=True)
    log = card.run(tr)
    assert log.outcome == "done"
    peak = np.abs(log.following_error).max()
    assert 0.005 < peak < FOLLOWING_ERROR_BOUND_MM  # a real lag, within the bound
    assert np.abs(log.following_error[-1]).max() < 0.01 * 0.0025  # and it settles at the end
    assert log.position[-1] == pytest.approx([0, 0, 0], abs=1e-4)
    assert log.summary()["max_following_error_mm"][0] == pytest.approx(np.abs(log.following_error[:, 0]).max(),
                                                                        abs=1e-6)


def test_open_loop_has_no_following_error(machine):
    log = SimCard(machine).run(thesis_trajectory())
    assert log.following_error is None and "max_following_error_mm" not in log.summary()


def test_unstable_gains_are_refused():
    with pytest.raises(DeviceError, match="unstable"):
        SimCard(Machine(period=0.004), closed_loop=True, loop=LoopSettings(kp=2000.0, ki=0.0, tau=0.05))
