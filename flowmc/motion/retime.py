"""Play a planned trajectory at a variable rate: feed hold, resume, stop and overrides, re-timed live.

A device runs a trajectory q(tau) planned at period T. Running it at rate r = dtau/dt (tau counted in
samples, so r = 1 is the plan) keeps every commanded point on the planned path; only the timing
changes. Per axis the commanded velocity is q' r and the acceleration q'' r^2 + q' r_dot, so:

- **Hold and stop** drive r to 0 with the most negative r_dot every axis's amax allows, period by
  period (the bounds on r_dot are exact per axis, taking the plan's own acceleration into account):
  the tool decelerates along the path at the machine's limit and stops on it.
- **Overrides** set the wanted rate: feed 10-200 % on feed moves, rapid 25/50/100 % on rapids. Below
  100 % the plan is feasible as it is (slower means smaller velocity and acceleration). Above 100 %
  the rate is capped where a velocity (q' r <= vmax) or acceleration (q'' r^2 <= half amax, the other
  half kept for braking) limit would be passed, and a braking envelope over the path ahead (a
  reverse cumulative minimum of ``v^2 + 2 A s``, vectorised) brings the speed down in time for
  each cap.
- **Single block** stops at a chosen point of the path (a segment's end) by the same envelope.

Transitions run a short Python loop (a few scalars per period); steady stretches (the plan as it
is, or a constant override) are vectorised slices and interpolations.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["Retimer"]

_EPS = 1e-12
ACCEL_MARGIN = 0.01
_STOP_TOL = 1e-5  # mm: closer than this to a stop point, the clamp at the point itself stops the job
_RHO_MAX = 1e6  # 1/s: a rate change this fast is immediate (where nothing moves)


class Retimer:
    """The setpoint generator of a running job over ``positions`` (N, n) planned at ``period``.

    ``vmax``/``amax`` per axis (mm/s, mm/s^2). ``rapid`` marks rapid samples (rapid override) or is
    None. ``quantised``: the plan is a step stream (positions move in whole steps), so its velocity
    is taken over a window and its sampled acceleration (pulse noise) is ignored.
    ``start``: the sample to start from; ``rate``: the starting rate (0: from rest).
    """

    def __init__(self, positions, period: float, vmax, amax, *, rapid=None, quantised: bool = False,
                 start: float = 0.0, rate: float = 1.0, horizon_s: float = 30.0, cap_share: float = 0.5):
        q = np.asarray(positions, dtype=float)
        if q.ndim != 2 or len(q) < 1:
            raise ValueError("positions must be (N, n) with N >= 1")
        if len(q) == 1:
            q = np.vstack([q, q])
        self.q = q
        self.period = float(period)
        self.vmax = np.asarray(vmax, dtype=float)
        # 1 % kept back: the sampled second difference of a re-timed stretch runs a little over the
        # continuous value the bounds are computed from (measured up to 0.5 %)
        self.amax = np.asarray(amax, dtype=float) * (1.0 - ACCEL_MARGIN)
        self.n = len(q)
        self.quantised = bool(quantised)
        self.end = float(self.n - 1)
        T = self.period
        if quantised:
            w = 8
            pad = np.vstack([np.repeat(q[:1], w, axis=0), q, np.repeat(q[-1:], w, axis=0)])
            self.dq = (pad[2 * w:] - pad[:-2 * w]) / (2 * w * T)
            self.ddq = np.zeros_like(q)
        else:
            pad = np.vstack([q[:1], q, q[-1:]])
            self.dq = (pad[2:] - pad[:-2]) / (2 * T)
            self.ddq = (pad[2:] - 2 * pad[1:-1] + pad[:-2]) / (T * T)
        self.speed = np.linalg.norm(self.dq, axis=1)
        self.s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(q, axis=0), axis=1))])
        self.rapid = None if rapid is None else np.asarray(rapid, dtype=bool)
        if self.rapid is not None and len(self.rapid) != len(positions):
            raise ValueError("rapid needs one flag per sample")
        if self.rapid is not None and len(self.rapid) == 1:
            self.rapid = np.repeat(self.rapid, 2)
        n_rapid = np.concatenate([[0], np.cumsum(self.rapid[1:])]) if self.rapid is not None else np.zeros(self.n)
        self._rapid_after = n_rapid[-1] - n_rapid  # rapid samples still to run after sample k
        self.brake = 0.5 * float(self.amax.min())  # path deceleration a single-block stop plans with
        self.cap_share = float(cap_share)
        self.horizon = max(int(round(horizon_s / T)), 64)
        self.tau = float(min(max(start, 0.0), self.end))
        self.r = float(rate)
        self.feed = 1.0
        self.rapid_rate = 1.0
        self.hold = False
        self.stop_tau: float | None = None
        self._window: tuple[int, int] | None = None
        self._goal = np.empty(0)

    # ------------------------------------------------------------------ controls
    def set_overrides(self, feed: float | None = None, rapid: float | None = None) -> None:
        """Feed and rapid override as fractions (1.0 = 100 %); applied from the next period on."""
        if feed is not None:
            self.feed = float(feed)
        if rapid is not None:
            self.rapid_rate = float(rapid)
        self._window = None

    def stop_at(self, tau: float | None) -> None:
        """Come to rest exactly at sample ``tau`` (single block), or run on (None)."""
        self.stop_tau = None if tau is None else float(min(max(tau, self.tau), self.end))

    @property
    def done(self) -> bool:
        return self.tau >= self.end - 1e-9

    @property
    def at_rest(self) -> bool:
        return self.r <= 0.0

    def position(self, tau: float | None = None) -> np.ndarray:
        return self._point(self.tau if tau is None else tau)

    def velocity(self) -> np.ndarray:
        return self._at(self.dq, self.tau) * self.r

    def time_left(self) -> float:
        """Seconds the rest takes at the current overrides (holds not counted)."""
        k = min(int(math.ceil(self.tau - 1e-9)), self.n - 1)
        left = self.end - self.tau
        rapid_left = float(self._rapid_after[k]) if self.rapid is not None else 0.0
        feed_left = max(left - rapid_left, 0.0)
        return (feed_left / max(self.feed, _EPS) + rapid_left / max(self.rapid_rate, _EPS)) * self.period

    # ------------------------------------------------------------------ stepping
    def advance(self, periods: int) -> tuple[np.ndarray, np.ndarray]:
        """The next setpoints (up to ``periods`` rows, n) and their tau; fewer when the end comes first."""
        out = np.empty((periods, self.q.shape[1]))
        taus = np.empty(periods)
        j = 0
        while j < periods:
            if self.done:
                self.tau, self.r = self.end, 0.0
                return out[:j], taus[:j]
            m = self._steady(periods - j)
            if m:
                taus[j:j + m] = self.tau + self.r * np.arange(1, m + 1)
                np.minimum(taus[j:j + m], self.end, out=taus[j:j + m])
                out[j:j + m] = self._point(taus[j:j + m])
                self.tau = float(taus[j + m - 1])
                j += m
                continue
            self._step()
            taus[j] = self.tau
            out[j] = self._point(self.tau)
            j += 1
        return out, taus

    def _steady(self, most: int) -> int:
        """How many of the next periods run at the current rate unchanged (0: take one careful step)."""
        if self.hold or self.stop_tau is not None or self.r <= 0.0:
            return 0
        k = int(self.tau)
        span = int(math.ceil(self.r * most)) + 2
        goal = self._goals(k, min(k + span, self.n))
        if not np.all(np.abs(goal - self.r) <= 1e-12 * max(1.0, self.r)):
            return 0
        return max(min(most, math.ceil((self.end - self.tau) / self.r - 1e-9)), 1)

    def _goals(self, k0: int, k1: int) -> np.ndarray:
        """The wanted rate at samples k0..k1-1 (recomputed over a window ahead when needed)."""
        w = self._window
        if w is None or k0 < w[0] or k1 > w[1]:
            lo = k0
            hi = min(self.n, max(k1, k0 + self.horizon))
            self._goal = self._goal_window(lo, hi)
            self._window = (lo, hi)
            w = self._window
        return self._goal[k0 - w[0]:k1 - w[0]]

    def _goal_window(self, lo: int, hi: int) -> np.ndarray:
        """Wanted rate per sample: the override, capped above 100 % by velocity and (half the) acceleration
        limits, with a braking envelope in rate so each cap is reached in time. Braking lowers r^2 by at
        most 2 rho T per sample, rho being the rate deceleration the other half of amax gives there
        (amax / |q'| per axis): a reverse cumulative minimum of ``cap^2 + P`` (P the running sum of
        2 rho T) minus P is the highest rate from which every cap ahead can still be met."""
        want = np.full(hi - lo, self.feed)
        if self.rapid is not None:
            want[self.rapid[lo:hi]] = self.rapid_rate
        if want.max() <= 1.0:
            return want  # slower than planned is always feasible
        dq, ddq = np.abs(self.dq[lo:hi]), np.abs(self.ddq[lo:hi])
        with np.errstate(divide="ignore", invalid="ignore"):
            cap_v = np.min(np.where(dq > _EPS, self.vmax / dq, np.inf), axis=1)
            cap_a = np.min(np.where(ddq > _EPS, np.sqrt(self.cap_share * self.amax / ddq), np.inf), axis=1)
            rho = (1.0 - self.cap_share) * np.min(np.where(dq > _EPS, self.amax / dq, np.inf), axis=1)
        cap = np.minimum(want, np.maximum(1.0, np.minimum(cap_v, cap_a)))
        if hi < self.n:  # beyond the window: at most the plan's own rate
            cap[-1] = min(cap[-1], 1.0)
        drop = 2.0 * np.minimum(rho, _RHO_MAX) * self.period
        p = np.concatenate([[0.0], np.cumsum(drop[:-1])])
        env2 = np.minimum.accumulate((cap * cap + p)[::-1])[::-1] - p
        return np.minimum(cap, np.maximum(1.0, np.sqrt(np.maximum(env2, 0.0))))

    def _step(self) -> None:
        """One period with the rate moving toward its goal as fast as every axis's amax allows."""
        T, tau, r = self.period, self.tau, self.r
        k = min(int(tau), self.n - 2)
        f = tau - k
        dq = self.dq[k] + f * (self.dq[k + 1] - self.dq[k])
        ddq = self.ddq[k] + f * (self.ddq[k + 1] - self.ddq[k])
        if self.hold:
            goal = 0.0
        else:
            g = self._goals(k, min(k + int(math.ceil(r)) + 2, self.n))
            goal = float(g.min())
            if self.stop_tau is not None:
                left = float(np.interp(self.stop_tau, np.arange(self.n), self.s)) - float(
                    np.interp(tau, np.arange(self.n), self.s))
                speed = float(np.linalg.norm(dq))
                if speed > _EPS and left > _STOP_TOL:  # within a micrometre (or standing still, a dwell)
                    goal = min(goal, math.sqrt(2 * self.brake * left) / speed)  # the clamp below stops it
        lo, hi = -math.inf, math.inf
        # The period spans samples k..k+2 at most: bound r_dot with the plan's acceleration at each of them.
        # The velocity direction turns within the period too: the bounds from the plan's velocity at the
        # next samples tighten these where keeping the rate (r_dot = 0) is within them; where the plan itself
        # runs at the limit there, its own timing is kept.
        k2 = min(k + 2, self.n - 1)
        for vel_rows, acc_rows in (((dq,) * 3, (ddq, self.ddq[k + 1], self.ddq[k2])),
                                   ((self.dq[k + 1], self.dq[k2]), (self.ddq[k + 1], self.ddq[k2]))):
            b_lo, b_hi = _rate_bounds(vel_rows, acc_rows, r, self.amax)
            if lo == -math.inf or b_lo <= 0.0 <= b_hi:
                lo, hi = max(lo, b_lo), min(hi, b_hi)
        want = (goal - r) / T
        r_dot = min(max(want, lo), hi) if lo <= hi else 0.5 * (lo + hi)
        r_new = max(r + r_dot * T, 0.0)
        if r_dot > 0.0:  # never past the goal: where the bounds contradict (a reversal, q' ~ 0) r_dot is their middle
            r_new = min(r_new, max(goal, r))
        new_tau = min(tau + 0.5 * (r + r_new), self.end)
        if self.stop_tau is not None and new_tau >= self.stop_tau - 1e-9:
            new_tau, r_new = max(self.stop_tau, tau), 0.0
        self.tau, self.r = new_tau, r_new

    def _point(self, tau) -> np.ndarray:
        """The path at (fractional) sample ``tau``: cubic Hermite between samples with the sampled velocity,
        so the acceleration of a re-timed stretch is the plan's (q'' r^2 + q' r_dot), not the kinks of a
        polyline; step streams (whole steps) are interpolated linearly."""
        if self.quantised:
            return self._at(self.q, tau)
        t = np.asarray(tau, dtype=float)
        k = np.minimum(np.floor(t).astype(np.int64), self.n - 2)
        f = t - k
        if t.ndim:
            f = f[:, None]
        f2, f3 = f * f, f * f * f
        T = self.period
        return ((2 * f3 - 3 * f2 + 1) * self.q[k] + (f3 - 2 * f2 + f) * T * self.dq[k]
                + (3 * f2 - 2 * f3) * self.q[k + 1] + (f3 - f2) * T * self.dq[k + 1])

    @staticmethod
    def _at(values: np.ndarray, tau) -> np.ndarray:
        """Linear interpolation of per-sample ``values`` at (fractional) sample ``tau``."""
        t = np.asarray(tau, dtype=float)
        k = np.minimum(np.floor(t).astype(np.int64), len(values) - 2)
        f = (t - k)[..., None] if t.ndim else t - k
        return values[k] + f * (values[k + 1] - values[k])


def _rate_bounds(vel_rows, acc_rows, r: float, amax: np.ndarray) -> tuple[float, float]:
    """The r_dot interval keeping q'' r^2 + q' r_dot within +-amax on every axis, for each (q', q'') pair."""
    lo, hi = -math.inf, math.inf
    for vel, acc_row in zip(vel_rows, acc_rows):
        acc = acc_row * (r * r)
        for i in range(len(vel)):
            b = float(vel[i])
            if abs(b) > _EPS:
                a_lo = (-amax[i] - acc[i]) / b
                a_hi = (amax[i] - acc[i]) / b
                if b < 0:
                    a_lo, a_hi = a_hi, a_lo
                lo, hi = max(lo, a_lo), min(hi, a_hi)
    return lo, hi
