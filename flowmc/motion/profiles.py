"""Velocity profiles for one move of length L: trapezoid, exponential and 7-segment S-curve.

Each planner returns a ``Profile``: a short list of segments in time, each either a constant-jerk
polynomial or an exponential velocity transition, so sampling any array of times is closed-form
and vectorised. Planning is scalar, closed-form where the algebra allows (trapezoid, exponential)
and a bracketed root search on a monotone distance function otherwise (S-curve short moves).

End velocities: an end velocity that cannot be reached within L (v1 above what accelerating over
the whole move gives, or above vmax) is lowered to the reachable value when ``lower_end`` is True
(the profile records it in ``v1`` and sets ``lowered``); a start velocity above vmax, or one that
cannot be brought down to v1 within L, raises PlanningError.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

import flowmc.budget as budget
from flowmc.errors import PlanningError

__all__ = ["Profile", "plan_trapezoid", "plan_exponential", "plan_scurve", "sample_profile"]


def _brentq(*args, **kwargs) -> float:
    from scipy.optimize import brentq  # scipy on first use: `flowmc validate` starts without it

    return float(brentq(*args, **kwargs))


_WHERE = "velocity profile"


@dataclass(frozen=True, eq=False)
class Profile:
    """A planned move from speed ``v0`` to ``v1`` over ``length``.

    ``t`` holds the segment break times (m+1 values, the last is the duration). Per segment: the
    start position, speed and acceleration ``seg_s, seg_v, seg_a`` and constant jerk ``seg_j``
    (polynomial segments) or, where ``seg_expo`` is set, the speed change ``seg_dv`` following
    (1 - exp(-ratio x)) / (1 - exp(-ratio)), x = time into the segment / its duration.
    ``v_peak`` is the highest speed reached; ``lowered`` says v1 is below the end speed asked for.
    """

    kind: str
    length: float
    v0: float
    v1: float
    v_peak: float
    lowered: bool
    t: np.ndarray
    seg_s: np.ndarray
    seg_v: np.ndarray
    seg_a: np.ndarray
    seg_j: np.ndarray
    seg_dv: np.ndarray
    seg_expo: np.ndarray
    ratio: float = 0.0

    @property
    def duration(self) -> float:
        return float(self.t[-1])

    def sample(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity, acceleration and jerk at times t (any shape); held at the end after ``duration``."""
        t = np.asarray(t, dtype=float)
        tc = np.clip(t, 0.0, self.t[-1])
        i = np.clip(np.searchsorted(self.t, tc, side="right") - 1, 0, len(self.seg_s) - 1)
        tau = tc - self.t[i]
        s0, v0, a0, j = self.seg_s[i], self.seg_v[i], self.seg_a[i], self.seg_j[i]
        s = s0 + tau * (v0 + tau * (0.5 * a0 + tau * j / 6.0))
        v = v0 + tau * (a0 + 0.5 * tau * j)
        a = a0 + tau * j
        jj = j.copy()
        if self.ratio > 0 and np.any(self.seg_expo[i]):
            e_seg = self.seg_expo[i]
            dur = np.where(e_seg, self.t[i + 1] - self.t[i], 1.0)
            r = self.ratio
            c = 1.0 / (1.0 - math.exp(-r))
            x = tau / dur
            e = np.exp(-r * x)
            dv = self.seg_dv[i]
            s = np.where(e_seg, s0 + v0 * tau + dv * c * dur * (x - (1.0 - e) / r), s)
            v = np.where(e_seg, v0 + dv * c * (1.0 - e), v)
            a = np.where(e_seg, dv * c * r * e / dur, a)
            jj = np.where(e_seg, -dv * c * r * r * e / (dur * dur), jj)
        done = t >= self.t[-1]
        s = np.where(done, self.length, s)
        v = np.where(done, self.v1, v)
        a = np.where(done, 0.0, a)
        jj = np.where(done, 0.0, jj)
        return s, v, a, jj


def sample_profile(profile: Profile, period: float) -> np.ndarray:
    """Positions s(kT), k = 0..n, n = ceil(duration / T): starts at 0, ends exactly at L
    (the last period is partial when the duration is not a whole number of periods)."""
    if not period > 0:
        raise PlanningError(f"period must be > 0, got {period}", where=_WHERE)
    budget.check("setpoints", profile.duration / period + 1,
                 what=f"a move of {profile.duration:.6g} s at a {period * 1e3:g} ms period",
                 change="raise the feed, shorten the move, or lengthen the machine's period")
    n = max(int(math.ceil(profile.duration / period - 1e-9)), 0)
    s = profile.sample(np.arange(n + 1) * period)[0]
    s[-1] = profile.length
    return s


# -- shared checks and assembly -----------------------------------------------------------------

def _check(length, v0, v1, vmax, amax, jmax=None):
    vals = {"L": length, "v0": v0, "v1": v1, "vmax": vmax, "amax": amax}
    if jmax is not None:
        vals["jmax"] = jmax
    bad = {k: x for k, x in vals.items() if not math.isfinite(x)}
    if bad:
        raise PlanningError(f"non-finite input {bad}", where=_WHERE)
    if length < 0 or v0 < 0 or v1 < 0:
        raise PlanningError(f"L, v0 and v1 must be >= 0, got L={length}, v0={v0}, v1={v1}", where=_WHERE)
    if vmax <= 0 or amax <= 0 or (jmax is not None and jmax <= 0):
        raise PlanningError(f"limits must be > 0, got vmax={vmax}, amax={amax}, jmax={jmax}", where=_WHERE)
    if v0 > vmax * (1 + 1e-12):
        raise PlanningError(f"start velocity v0={v0:g} exceeds vmax={vmax:g}", where=_WHERE)
    return min(v0, vmax)


def _too_short(kind, length, v0, v1, need):
    return PlanningError(
        f"{kind}: cannot slow from v0={v0:g} to v1={v1:g} within L={length:g} mm "
        f"(needs {need:g} mm); lower v0 (plan the previous move to end slower)", where=_WHERE)


def _poly_profile(kind, length, v0, v1, v_peak, lowered, durations, jerks, accels=None) -> Profile:
    """Assemble constant-jerk segments (zero-length ones dropped) and integrate their start states.

    ``accels`` gives each segment's start acceleration (trapezoid: steps); None integrates the jerk from 0.
    """
    d = np.asarray(durations, dtype=float)
    j = np.asarray(jerks, dtype=float)
    a = np.concatenate([[0.0], np.cumsum(j * d)[:-1]]) if accels is None else np.asarray(accels, dtype=float)
    keep = d > 0
    if not keep.any():
        keep[0] = True
    d, j, a = d[keep], j[keep], a[keep]
    dv = d * (a + 0.5 * d * j)
    v = v0 + np.concatenate([[0.0], np.cumsum(dv)[:-1]])
    ds = d * (v + d * (0.5 * a + d * j / 6.0))
    s = np.concatenate([[0.0], np.cumsum(ds)[:-1]])
    t = np.concatenate([[0.0], np.cumsum(d)])
    m = len(d)
    return Profile(kind, float(length), float(v0), float(v1), float(v_peak), bool(lowered), t, s, v, a, j,
                   np.zeros(m), np.zeros(m, dtype=bool))


# -- trapezoid ------------------------------------------------------------------------------------

def plan_trapezoid(length: float, v0: float, v1: float, vmax: float, amax: float, *,
                   lower_end: bool = True) -> Profile:
    """Constant acceleration amax up to the peak, cruise at vmax if the move is long enough, constant
    deceleration to v1. Short moves: peak v_p^2 = amax L + (v0^2 + v1^2) / 2 < vmax^2, no cruise."""
    v0 = _check(length, v0, v1, vmax, amax)
    lowered = False
    if v1 > vmax:
        if not lower_end:
            raise PlanningError(f"end velocity v1={v1:g} exceeds vmax={vmax:g}", where=_WHERE)
        v1, lowered = vmax, True
    if v1 > v0 and v1 * v1 - v0 * v0 > 2 * amax * length:
        reach = math.sqrt(v0 * v0 + 2 * amax * length)
        if not lower_end:
            raise PlanningError(f"trapezoid: v1={v1:g} is unreachable from v0={v0:g} within L={length:g} "
                                f"(at most {reach:g})", where=_WHERE)
        v1, lowered = reach, True
    if v0 > v1 and v0 * v0 - v1 * v1 > 2 * amax * length * (1 + 1e-12):
        raise _too_short("trapezoid", length, v0, v1, (v0 * v0 - v1 * v1) / (2 * amax))
    vp = min(vmax, math.sqrt(max(amax * length + 0.5 * (v0 * v0 + v1 * v1), max(v0, v1) ** 2)))
    ta, td = (vp - v0) / amax, (vp - v1) / amax
    cruise = max(length - (vp * vp - v0 * v0) / (2 * amax) - (vp * vp - v1 * v1) / (2 * amax), 0.0) / vp \
        if vp > 0 else 0.0
    return _poly_profile("trapezoid", length, v0, v1, vp, lowered, [ta, cruise, td], [0.0, 0.0, 0.0],
                         [amax, 0.0, -amax])


# -- exponential ----------------------------------------------------------------------------------

def plan_exponential(length: float, v0: float, v1: float, vmax: float, amax: float, *,
                     ratio: float = 4.0, lower_end: bool = True) -> Profile:
    """Exponential transitions: over a transition of duration D the velocity changes by dv following
    (1 - exp(-ratio t/D)) / (1 - exp(-ratio)), so it arrives exactly; the acceleration is largest
    (= amax) at the transition's start and decays as exp(-t/tau), tau = D / ratio =
    |dv| / (amax (1 - exp(-ratio))). ``ratio`` -> 0 tends to the trapezoid."""
    v0 = _check(length, v0, v1, vmax, amax)
    if not ratio > 0:
        raise PlanningError(f"ratio must be > 0, got {ratio}", where=_WHERE)
    c = 1.0 / (1.0 - math.exp(-ratio))
    g = c * (1.0 - (1.0 - math.exp(-ratio)) / ratio)  # mean of the normalised transition shape
    k = ratio * c / amax  # transition time per unit of velocity change

    def dist(va, vb):
        return k * abs(vb - va) * (va + g * (vb - va))

    lowered = False
    if v1 > vmax:
        if not lower_end:
            raise PlanningError(f"end velocity v1={v1:g} exceeds vmax={vmax:g}", where=_WHERE)
        v1, lowered = vmax, True
    if v1 > v0 and dist(v0, v1) > length:
        reach = v0 + (-v0 + math.sqrt(v0 * v0 + 4 * g * length / k)) / (2 * g)
        if not lower_end:
            raise PlanningError(f"exponential: v1={v1:g} is unreachable from v0={v0:g} within L={length:g} "
                                f"(at most {reach:g})", where=_WHERE)
        v1, lowered = min(reach, v1), True
    if v0 > v1 and dist(v0, v1) > length * (1 + 1e-12):
        raise _too_short("exponential", length, v0, v1, dist(v0, v1))
    if dist(v0, vmax) + dist(vmax, v1) <= length:
        vp = vmax
    else:  # k [p^2 + p (v0 - v1)(1 - 2g) + g v0^2 - g v1^2 - v0^2] = L
        b = (v0 - v1) * (1 - 2 * g)
        c0 = g * v0 * v0 - g * v1 * v1 - v0 * v0 - length / k
        vp = min(max((-b + math.sqrt(max(b * b - 4 * c0, 0.0))) / 2, v0, v1), vmax)
    da, dd = k * (vp - v0), k * (vp - v1)
    cruise = max(length - dist(v0, vp) - dist(vp, v1), 0.0) / vp if vp > 0 else 0.0
    durations = np.array([da, cruise, dd])
    dvs = np.array([vp - v0, 0.0, v1 - vp])
    expo = np.array([True, False, True])
    keep = durations > 0
    if not keep.any():
        keep[1] = True
    d, dvs, expo = durations[keep], dvs[keep], expo[keep]
    m = len(d)
    s0, vv = np.empty(m), np.empty(m)
    s, v = 0.0, v0
    for i in range(m):
        s0[i], vv[i] = s, v
        s += d[i] * (v + dvs[i] * g) if expo[i] else d[i] * v
        v += dvs[i]
    t = np.concatenate([[0.0], np.cumsum(d)])
    return Profile("exponential", float(length), float(v0), float(v1), float(vp), lowered, t, s0, vv,
                   np.zeros(m), np.zeros(m), dvs, expo, float(ratio))


# -- 7-segment S-curve ----------------------------------------------------------------------------

def _phase(dv: float, amax: float, jmax: float) -> tuple[float, float]:
    """Jerk time and constant-acceleration time of the fastest S-shaped change of speed by dv."""
    if dv <= 0:
        return 0.0, 0.0
    if dv * jmax >= amax * amax:
        return amax / jmax, dv / amax - amax / jmax
    return math.sqrt(dv / jmax), 0.0


def _phase_distance(va: float, vb: float, amax: float, jmax: float) -> float:
    tj, tc = _phase(abs(vb - va), amax, jmax)
    return 0.5 * (va + vb) * (2 * tj + tc)


def plan_scurve(length: float, v0: float, v1: float, vmax: float, amax: float, jmax: float, *,
                lower_end: bool = True) -> Profile:
    """Jerk-limited 7-segment profile (jerk +J, 0, -J; cruise; -J, 0, +J), zero acceleration at both
    ends. Each speed change takes the fastest S-shape for its size: it reaches amax only if
    |dv| >= amax^2 / jmax. Short moves lower the peak speed until the two changes fit in L."""
    v0 = _check(length, v0, v1, vmax, amax, jmax)
    lowered = False
    if v1 > vmax:
        if not lower_end:
            raise PlanningError(f"end velocity v1={v1:g} exceeds vmax={vmax:g}", where=_WHERE)
        v1, lowered = vmax, True
    if v1 > v0 and _phase_distance(v0, v1, amax, jmax) > length:
        if length <= 0:
            reach = v0
        else:
            reach = _brentq(lambda x: _phase_distance(v0, x, amax, jmax) - length, v0, v1, xtol=1e-13, rtol=1e-15)
        if not lower_end:
            raise PlanningError(f"S-curve: v1={v1:g} is unreachable from v0={v0:g} within L={length:g} "
                                f"(at most {reach:g})", where=_WHERE)
        v1, lowered = reach, True
    if v0 > v1 and _phase_distance(v0, v1, amax, jmax) > length * (1 + 1e-12):
        raise _too_short("S-curve", length, v0, v1, _phase_distance(v0, v1, amax, jmax))

    def total(vp):
        return _phase_distance(v0, vp, amax, jmax) + _phase_distance(vp, v1, amax, jmax)

    lo = max(v0, v1)
    if total(vmax) <= length:
        vp = vmax
    elif total(lo) >= length:
        vp = lo
    else:
        vp = _brentq(lambda x: total(x) - length, lo, vmax, xtol=1e-13, rtol=1e-15)
    cruise = max(length - total(vp), 0.0) / vp if vp > 0 else 0.0
    tj1, ta1 = _phase(vp - v0, amax, jmax)
    tj2, ta2 = _phase(vp - v1, amax, jmax)
    durations = [tj1, ta1, tj1, cruise, tj2, ta2, tj2]
    jerks = [jmax, 0.0, -jmax, 0.0, -jmax, 0.0, jmax]
    return _poly_profile("scurve", length, v0, v1, vp, lowered, durations, jerks)
