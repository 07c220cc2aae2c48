"""The time law along a planned curve: how fast to go where, under per-axis limits, sampled at t = kT.

Everything is geometric, so how the curve happens to be parameterised does not matter: with s the
arc length, T = dp/ds the unit tangent, K = d2p/ds2 the curvature vector and P3 = d3p/ds3, axis i
moves with
    velocity T_i v,   acceleration T_i a + K_i v^2,   jerk T_i da/dt + 3 K_i v a + P3_i v^3,
where v = ds/dt is the path speed and a = dv/dt.

Phase plane. On a grid s_0 < s_1 < ... the state is y = v^2 and the path acceleration is constant on
each interval, so y is linear in s there (y_{k+1} = y_k + 2 a_k (s_{k+1} - s_k)): the discretisation
of time-optimal path parameterisation in Verscheure et al., "Time-optimal path tracking for robots:
a convex optimization approach" (IEEE TAC 54, 2009) and Pham and Pham's TOPP-RA (IEEE T-RO 34, 2018).
Sampled at t = kT it is exact: every setpoint is on the curve.

Limits are kept per axis. The coupling of the normal and the tangential parts (K_i v^2 and T_i a)
is split per interval: a speed cap Y_k leaves the tangential budget
    |a| <= A_k = min_i (amax_i - |K_i| Y_k) / |T_i|
whatever the speed below the cap. With caps and budgets fixed, the fastest profile is a backward pass
(y_k <= y_{k+1} + 2 A_k ds_k) and a forward pass (y_{k+1} <= y_k + 2 A_k ds_k), each a running minimum
of a cumulative sum: fully vectorised. Which cap to use where is settled by iteration: the scans
with budgets taken at the speed of a given profile form an antitone map, so its iterates alternate
around its fixed point; every second iterate used budgets taken at a faster profile and is
therefore feasible, and they increase towards the fixed point. That is how the jerk-limited law is
planned. Without a jerk limit no iteration is needed: each axis's budget on an interval is linear in the
speeds^2 at its ends (at the interval's start and end each point's own terms at that end's speed, at its
middle the normal term that hurts taken at the larger, one that helps at the smaller: T_i a and K_i v^2 of
opposite signs, the tool slowing into a turn on the axis the turn speeds up; TOPP-RA's per-interval
constraints, linear in (a, v^2)), so the largest speed^2 a node may have given the next one's is an affine
map per axis and point, and the fastest profile that keeps every interval's budgets at its own speeds
is one backward and one forward pass of y_k = min(cap_k, min_i(a_ik y_{k+1} + b_ik)), solved exactly
(``_greatest``, flowmc.motion.capped_recursion). Its cap is not the normal terms' own (min_i amax_i / |K_i|,
where the tool may still hold its speed) but the largest speed^2 at which some path acceleration keeps every
axis within its limit (``_tangent_cap``): a corner parabola is passed with both axes at their limits all
through it, above the normal terms' own cap at its quarter points. The budgets hold at three points of each
interval; where a sample breaks a limit between them, flowmc.motion.planner plans the law again with the
normal terms' own cap about it (``tight``). Any profile the iteration gives keeps those budgets too,
so this one is at least as fast at every node; so is it than any planned with the caps lower (a profile
under lower caps keeps the same budgets under these).

Jerk (``jerk=True``). The profile above, with its budget shared with the jerk terms, is filtered by
a moving average of length Tj = 2 max_i(amax_i / jmax_i) over the arc length: s_f(t) = (1/Tj) times
the integral of s over [t - Tj, t] (the FIR jerk limitation of Biagiotti and Melchiorri, "FIR filters
for online trajectory planning with time- and frequency-domain specifications", Control Eng.
Practice 20, 2012; applied to the arc length, so the tool stays exactly on the curve). Then
d3s_f/dt3 = (a(t) - a(t - Tj)) / Tj, at most 2 A / Tj. The curvature terms are capped ahead of the
filter: the speed so that |K_i| v^2 and |P3_i| v^3 leave room, and A so that 3 |K_i| v A fits too;
because the filter averages over a window, every cap is taken as the smallest over the filtered positions
whose window holds that stretch (about half a window's travel each side, from a profile at least as
fast), and the tool rests for Tj wherever the profile stops, so it comes to rest exactly there. Where the
curvature terms keep the acceleration well below amax anyway, a window half as long is planned too and
kept if faster. The curve must be curvature-continuous for this
(flowmc.motion.smoothing's continuity=2). Every claim is checked from sampled setpoints in the tests.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from flowmc.errors import PlanningError
from flowmc.motion.capped_recursion import descend, descend_again
from flowmc.motion.curve import ARC, POLY, PlannedCurve
from flowmc.motion.limits import PathLimits
from flowmc.motion.ranges import CHUNK, CHUNKED, Windows, ranks, search_right, window_max, window_min
from flowmc.motion.sample_clock import sample_count, setpoint_times

__all__ = ["TimeLaw", "plan_time_law", "trapezoid_laws", "plan_jerk_limited", "sample_time_law", "samples_of",
           "sampled_accel", "sampled_jerk", "arc_length_at", "speed_at", "frame"]

_ACCEL_SLACK = 1e-7  # sampled accelerations this share over amax are rounding (the plans before: up to 5e-8)
_RHO = 0.999  # caps start at this share of what the normal acceleration (and jerk) alone allow
_ROUNDS = 20
_REACH_PROFILE_ROUNDS = 4
_CONVERGED = 2e-3  # stop when the feasible profile is within this share of the top speed^2 of the one above
_LINE_STEP = 0.5  # mm of u between grid nodes on lines (a peak between nodes is cut flat)
_LINE_STEP_JERK = 0.25  # finer for jerk-limited profiles: their plateaus start and end at nodes
_ARC_STEP_RAD = math.radians(3.0)
_POLY_SUB = 2  # grid intervals per spline interval
_REFINE = 6  # rounds of halving grid intervals where the curve turns more than the turn step (rad) ...
_TURN_STEP = math.radians(2.0)
_TURN_STEP_TRAPEZOID = math.radians(0.2)  # finer without a jerk limit: each interval's budget holds its middle at
# the worse end's speed, and in a tight fitted turn a coarse interval holds the speed at the turn's sharpest point for
# longer (3D_Chips 0.4 %, flowsnake 1.2 % quicker at 0.5 degrees than at 2, then 0.07 % and 0.3 % at 0.35; at 0.2
# with each point's own budget, 3D_Chips 145.442 -> 145.376 s and 3dtest 15.114 -> 15.112 s of feed for about 20 %
# more of 3D_Chips' planning CPU; the jerk-limited law keeps the coarser grid its filter is tuned on; refined only where a
# 2-degree plan nears its caps or loads an axis by its normal terms, 3dtest and spiral miss 0.90x: docs/planning.md, grid18)
_KAPPA_CHANGE = 0.25  # ... or its curvature changes by more than this share
_SWING_ROUNDS = 3
_PLATEAU_ROUNDS = 8
_REACH_ROUNDS = 2
_WINDOWS = (1.0, 0.5)  # filter lengths tried, in shares of max(amax / jmax): the fastest is kept
_SHORT_WINDOW_USE = 0.2  # ... a shorter one only where the motion uses over half the budget less than this
_JERK_SHARE = 0.99  # jerk-limited profiles aim at this share of jmax (sampling and rounding margin)
_NEWTON_CHUNK = 2048  # samples a Newton pass on arc length works on together (12 values a sample in its temporaries)
_GL3_X, _GL3_W = np.polynomial.legendre.leggauss(3)
_NEWTON_NODES = np.r_[0.5 * (1.0 + _GL3_X), 1.0][:, None]  # the Gauss-Legendre nodes on [0, 1], and 1 itself
_PART = 32768  # intervals the budgets work out together (temporaries in cache; 3D_Chips' budgets 56 ms, at 16384
# 61, at 4096 81: each part's numpy calls cost more than the cache saves)
_FLOOR = np.full((2, _PART), 1e-9)  # the least budget


@dataclass(frozen=True, eq=False)
class TimeLaw:
    """The profile at the grid nodes (curve parameter ``u``, arc length ``s``, path speed squared ``y``),
    the path acceleration on each interval, stops (node, wait, dwell segment) and the filter length."""

    u: np.ndarray
    s: np.ndarray
    y: np.ndarray
    accel: np.ndarray
    speed_u: np.ndarray  # ds/du at the nodes, for mapping arc length back to u
    stop_node: np.ndarray
    stop_wait: np.ndarray
    stop_segment: np.ndarray
    window: float  # Tj of the moving average; 0 for none
    period: float  # the sampling period T

    def u_sampled(self, s: np.ndarray, curve: PlannedCurve) -> np.ndarray:
        """``u_at`` for sampled arc lengths ending at the motion's end: the last sample is the law's end exactly
        (rounding in s would leave the tool a hair short of it)."""
        u = self.u_at(s, curve)
        u[-1] = self.u[-1]
        return u

    def u_at(self, s: np.ndarray, curve: PlannedCurve) -> np.ndarray:
        """Curve parameter at arc lengths s: cubic Hermite on each grid interval (ds/du matched at both ends;
        exact on lines and arcs, where ds/du is constant), then, on the other intervals only, two Newton steps
        on the arc length from the interval's start (3-point Gauss-Legendre, exact to rounding over intervals
        this short). Worked out CHUNK samples at a time past CHUNKED, and the Newton steps _NEWTON_CHUNK at a
        time: the same numbers, with every temporary in cache (a third quicker for 369k samples) and none so
        large that it takes fresh memory from the system (ellipse200: 470 page faults a plan, none now; 1.2 -> 0.5 ms)."""
        s = np.asarray(s, dtype=float).reshape(-1)
        if len(s) > CHUNKED:
            return np.concatenate([self.u_at(s[i:i + CHUNK], curve) for i in range(0, len(s), CHUNK)])
        s = np.clip(s, self.s[0], self.s[-1])
        if not len(s):
            return s
        k = np.clip(search_right(self.s, s) - 1, 0, len(self.s) - 2)
        h = self.s[k + 1] - self.s[k]
        x = np.where(h > 0, (s - self.s[k]) / np.where(h > 0, h, 1.0), 0.0)
        u0, u1 = self.u[k], self.u[k + 1]
        m0, m1 = h / self.speed_u[k], h / self.speed_u[k + 1]  # du/dx at the ends
        x2, x3 = x**2, x**3
        h00, h10, h01, h11 = 2 * x3 - 3 * x2 + 1, x3 - 2 * x2 + x, -2 * x3 + 3 * x2, x3 - x2
        u = np.clip(h00 * u0 + h10 * m0 + h01 * u1 + h11 * m1, u0, u1)
        if len(s) > len(self.u):  # more samples than grid intervals: each interval's curve interval looked up once
            index = curve.interval_at(0.5 * (self.u[:-1] + self.u[1:]))[k]
        else:
            index = curve.interval_at(0.5 * (u0 + u1))
        # lines and arcs have a constant ds/du, where the Hermite cubic is the exact (linear) map already
        curved = np.flatnonzero(~curve.constant_speed()[index])
        for i in range(0, len(curved), _NEWTON_CHUNK):
            c = curved[i:i + _NEWTON_CHUNK]
            u[c] = self._newton(s[c], u[c], k[c], index[c], curve)
        return u

    def _newton(self, s: np.ndarray, u: np.ndarray, k: np.ndarray, index: np.ndarray,
                curve: PlannedCurve) -> np.ndarray:
        """Newton steps on polynomial intervals (the only ones with a varying ds/du): |p'| from each row's
        coefficients, gathered once, worked as (axis, node, sample) so numpy's inner loops run along the samples."""
        u0, u1 = self.u[k], self.u[k + 1]
        by_power = curve.by_power
        c1, c2, c3 = (f * np.take(by_power[m], index, axis=1)[:, None, :] for m, f in ((1, 1.0), (2, 2.0), (3, 3.0)))
        start = curve.u0[index]
        for _ in range(2):
            x = (u0 - start) + (u - u0) * _NEWTON_NODES  # (4, n) from the row's start
            d1 = x * c3  # c1 + x (c2 + x c3), in place: one (3, 4, n) array
            d1 += c2
            d1 *= x
            d1 += c1
            speed = np.sqrt(np.einsum("ijk,ijk->jk", d1, d1))
            err = self.s[k] + 0.5 * (u - u0) * (_GL3_W @ speed[:-1]) - s
            u = np.clip(u - err / np.maximum(speed[-1], 1e-12), u0, u1)
        return u


def _grid(curve: PlannedCurve, stop_u: np.ndarray, line_step: float, turn_step: float) -> np.ndarray:
    """Nodes: every interval boundary and stop, lines every _LINE_STEP, arcs every few degrees, splines
    halved; and at least three intervals between any two stops, so no interval starts and ends at rest
    and a jerk-limited move between them has a middle interval to hold its top speed on (_flatten_peaks
    cuts a peak flat from node to node: with one node between two stops it could only cut it to rest)."""
    parts = [curve.u0, curve.u1[-1:], stop_u]
    width = curve.u1 - curve.u0
    line = (curve.kind == POLY) & np.all(curve.coef[:, 2:] == 0.0, axis=(1, 2))
    arc = curve.kind == ARC
    n = np.where(line, np.ceil(width / line_step),
                 np.where(arc, np.ceil(np.abs(curve.dphi) * width / _ARC_STEP_RAD), _POLY_SUB)).astype(int)
    n = np.maximum(n, 1)
    sub = np.flatnonzero(n > 1)
    if len(sub):
        reps = n[sub] - 1
        k = np.repeat(sub, reps)
        parts.append(curve.u0[k] + width[k] * ranks(reps) / n[k])
    u = np.unique(np.concatenate(parts))
    # where the curve turns or its curvature changes quickly, halve the intervals until it does not; lines
    # never need it, and an interval that passed keeps passing, so each round checks only the new halves,
    # whose ends but the middle were evaluated already (a half lies in its parent's curve interval k): ``ends``
    # holds u, curvature and unit tangent (5 rows) at the start and end of each interval checked
    at = np.flatnonzero(~line[curve.interval_at(0.5 * (u[:-1] + u[1:]))])
    k = curve.interval_at(0.5 * (u[at] + u[at + 1]))
    ab = np.r_[u[at], u[at + 1]]
    tan, kap = _turning(curve, ab, np.r_[k, k])
    ends = np.concatenate([ab[None], kap[None], tan]).reshape(5, 2, len(at)).transpose(1, 0, 2)
    mids = [u]  # every middle lies between two nodes: sorted in once at the end
    for _ in range(_REFINE):
        (a, b), (kap_a, kap_b), d = ends[:, 0], ends[:, 1], ends[1, 2:] - ends[0, 2:]
        turn = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        change = np.abs(kap_b - kap_a) > _KAPPA_CHANGE * np.maximum(kap_b, kap_a)
        # arcs (even curvature) keep the coarse step: fitted cubics and lone corners' parabolas take the fine one
        step = np.where(arc[k], _TURN_STEP, turn_step)
        split = np.flatnonzero(((turn > step) | change) & (b - a > 1e-4))
        if not len(split):
            break
        mid, k = 0.5 * (a[split] + b[split]), np.repeat(k[split], 2)
        tan_m, kap_m = _turning(curve, mid, k[::2])
        mids.append(mid)
        ends = _halved(ends[:, :, split], np.concatenate([mid[None], kap_m[None], tan_m]))
    u = np.sort(np.concatenate(mids))
    at = np.unique(np.searchsorted(u, stop_u))  # the stops' nodes (every stop is one)
    few = np.flatnonzero(np.diff(at) < 3)
    if len(few):
        a, b = u[at[few]], u[at[few + 1]]
        u = np.unique(np.r_[u, a + (b - a) / 3.0, a + 2.0 * (b - a) / 3.0])
    return u


def _turning(curve: PlannedCurve, u: np.ndarray, index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit tangent rows (3, n) and curvature at u on intervals ``index``, worked along the points (sums as
    np.linalg.norm and np.cross take them)."""
    d1, d2 = (d.T for d in curve.evaluate(u, 2, index=index, lowest=1))
    sp = np.maximum(np.sqrt(d1[0] * d1[0] + d1[1] * d1[1] + d1[2] * d1[2]), 1e-300)
    c = (d1[1] * d2[2] - d1[2] * d2[1], d1[2] * d2[0] - d1[0] * d2[2], d1[0] * d2[1] - d1[1] * d2[0])
    return d1 / sp, np.sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]) / sp**3


def _halved(ends: np.ndarray, mids: np.ndarray) -> np.ndarray:
    """Values at the ends of intervals (start and end, quantity, interval) split at their middles, where they are
    ``mids`` (quantity, interval): at the halves' ends, in order along the intervals (each interval's ends
    twice, then the middle's in between, in one array rather than one pair of them a quantity)."""
    out = np.repeat(ends, 2, axis=2)
    out[1, :, 0::2] = mids  # the first half ends at the middle
    out[0, :, 1::2] = mids  # the second starts there
    return out


def _scan(cap_node: np.ndarray, ds: np.ndarray, budget: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Fastest y at the nodes with y <= cap_node, y_{k+1} - y_k <= 2 up_k ds_k and y_k - y_{k+1} <= 2 down_k ds_k
    (``budget`` = (up, down)).

    The running minima take np.fmin, 14 % quicker than np.minimum, where no cap is NaN: the two differ only at
    NaNs and in which of two equal zeros they give, and no -0 arises (the sums are finite and >= +0, and x - y is
    -0 only for x = -0)."""
    up, down = budget
    least = np.minimum if np.isnan(cap_node).any() else np.fmin
    c = np.zeros(len(ds) + 1)  # the sums from the first node, every step worked out in place (no temporaries)
    step = c[1:]
    np.cumsum(np.multiply(np.multiply(2.0, down, out=step), ds, out=step), out=step)
    back = np.add(cap_node, c)[::-1]
    least.accumulate(back, out=back)
    back = back[::-1]
    back -= c
    if not (up is down or np.array_equal(up, down)):  # the same sums otherwise (lines+arcs: every scan)
        np.cumsum(np.multiply(np.multiply(2.0, up, out=step), ds, out=step), out=step)
    back -= c
    least.accumulate(back, out=back)
    return np.add(back, c, out=back)


@dataclass
class _Geometry:
    """|T_i|, |K_i|, |P3_i| per evaluation point (m, 3): the tangent, curvature and third derivative by arc
    length, on the machine's columns; ``kt`` = sign(T_i) K_i (how the normal part adds to a speed-up)."""

    t: np.ndarray
    k: np.ndarray
    p3: np.ndarray | None  # None for laws without a jerk limit, which do not need it
    kt: np.ndarray


def frame(curve: PlannedCurve, u: np.ndarray, index: np.ndarray, third: bool = True) -> tuple:
    """Tangent T, curvature vector K and P3 = d3p/ds3 by arc length at u (each (n, 3); P3 None unless
    ``third``), and ds/du there."""
    d = curve.evaluate(u, 3 if third else 2, index=index, lowest=1)
    d1, d2 = d[0], d[1]
    sp = np.maximum(np.linalg.norm(d1, axis=1), 1e-300)
    tan = d1 / sp[:, None]
    sp1 = np.einsum("ij,ij->i", d1, d2) / sp  # d|p'|/du
    kv = (d2 - sp1[:, None] * tan) / sp[:, None] ** 2
    if not third:
        return tan, kv, None, sp
    d3 = d[2]
    sp2 = (np.einsum("ij,ij->i", d2, d2) + np.einsum("ij,ij->i", d1, d3)) / sp - sp1**2 / sp
    p3 = (d3 - 3.0 * (sp * sp1)[:, None] * kv - sp2[:, None] * tan) / sp[:, None] ** 3
    return tan, kv, p3, sp


def _interval_frame(curve: PlannedCurve, u: np.ndarray, k_iv: np.ndarray, third: bool) -> tuple:
    """``frame`` at every grid interval's start, middle and end (rows in that order), on its curve interval
    ``k_iv``; an end is the next interval's start where both lie on one curve interval, so it is taken from
    there rather than worked out again (the same arithmetic on the same numbers)."""
    m = len(k_iv)
    own = np.flatnonzero(np.r_[k_iv[1:] != k_iv[:-1], True])  # ends that are no start on the same interval
    pts = np.concatenate([u[:-1], 0.5 * (u[:-1] + u[1:]), u[1:][own]])
    index = np.concatenate([k_iv, k_iv, k_iv[own]])
    step = CHUNK if len(pts) > CHUNKED else len(pts)  # in cache
    chunks = [frame(curve, pts[i:i + step], index[i:i + step], third) for i in range(0, len(pts), step)]
    out: list[np.ndarray | None] = []
    for p in zip(*chunks):
        if p[0] is None:
            out.append(None)
            continue
        # the chunks written straight into place (no concatenated copy of them first)
        whole = np.empty_like(p[0], shape=(3 * m, *p[0].shape[1:]))  # in frame's layout: by axis
        ends = np.empty_like(p[0], shape=(len(own), *p[0].shape[1:]))
        start = 0
        for part in p:
            stop = start + len(part)
            if start < 2 * m:
                whole[start:min(stop, 2 * m)] = part[:2 * m - start]
            if stop > 2 * m:
                ends[max(start - 2 * m, 0):stop - 2 * m] = part[max(2 * m - start, 0):]
            start = stop
        whole[2 * m:3 * m - 1] = whole[1:m]
        whole[2 * m + own] = ends
        out.append(whole)
    return tuple(out)


def _geometry(curve: PlannedCurve, u: np.ndarray, k_iv: np.ndarray, cols, third: bool) -> tuple[_Geometry, np.ndarray]:
    """Geometric derivatives at every grid interval's start, middle and end (``_interval_frame``), and ds/du
    there; P3 only if ``third``."""
    tan, kv, p3, sp = _interval_frame(curve, u, k_iv, third)
    mask = np.zeros(3)
    mask[list(cols)] = 1.0
    # in place: every fresh array of 3 x 3 values per interval costs page faults as well as a pass
    kt = np.sign(tan)
    kt *= kv
    kt *= mask
    for a in (tan, kv, p3):
        if a is not None:
            np.abs(a, out=a)
            a *= mask
    return _Geometry(tan, kv, p3, kt), sp


def _caps(g: _Geometry, feed: np.ndarray, lim: PathLimits, jerk: bool) -> tuple[np.ndarray, np.ndarray]:
    """Speed^2 cap from velocity and feed, and the largest speed^2 the normal terms alone allow. Worked out
    CHUNK points at a time past CHUNKED, so the temporaries (3 values a point each) stay in cache and are not
    fresh memory (page faults) every time."""
    if len(feed) > CHUNKED:
        parts = [_caps(_Geometry(g.t[i:i + CHUNK], g.k[i:i + CHUNK], None if g.p3 is None else g.p3[i:i + CHUNK],
                                 g.kt[i:i + CHUNK]), feed[i:i + CHUNK], lim, jerk) for i in range(0, len(feed), CHUNK)]
        return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])
    with np.errstate(divide="ignore"):
        y_vel = _least_of_columns(np.where(g.t > 0, (lim.vmax / np.where(g.t > 0, g.t, 1.0)) ** 2, np.inf))
        y_vel = np.minimum(y_vel, feed**2)
        y_acc = _least_of_columns(np.where(g.k > 0, lim.amax / np.where(g.k > 0, g.k, 1.0), np.inf))
        if jerk:
            j, p3 = _JERK_SHARE * lim.jmax, g.p3
            assert p3 is not None, "jerk-limited geometry has P3"
            y_jerk = _least_of_columns(np.where(p3 > 0, (j / np.where(p3 > 0, p3, 1.0)) ** (2.0 / 3.0), np.inf))
            y_acc = np.minimum(y_acc, y_jerk)
    return y_vel, y_acc


def _tangent_cap(g: _Geometry, lim: PathLimits) -> np.ndarray:
    """Largest speed^2 at each point for which some path acceleration keeps every axis within its limit
    (-amax_i <= T_i a + K_i y <= amax_i): on a moving axis a lies in [-alpha_i - c_i y, alpha_i - c_i y],
    alpha_i = amax_i / |T_i|, c_i = sign(T_i) K_i / |T_i|, and these meet while (c_j - c_i) y <= alpha_i + alpha_j
    for every pair; an axis that does not move caps y at amax_i / |K_i|. Above the normal terms' own cap
    amax_i / |K_i| the tool must speed up or slow down there (a parabola's corner blend entered at the speed
    it was sized for: both axes at their limits all through it, the speed below that cap nowhere). Worked out
    CHUNK points at a time past CHUNKED, as ``_caps``."""
    if len(g.t) > CHUNKED:
        return np.concatenate([_tangent_cap(_Geometry(g.t[i:i + CHUNK], g.k[i:i + CHUNK], None, g.kt[i:i + CHUNK]), lim)
                               for i in range(0, len(g.t), CHUNK)])
    moving = g.t > 1e-9
    with np.errstate(divide="ignore", invalid="ignore"):
        alpha = np.where(moving, lim.amax / np.where(moving, g.t, 1.0), np.inf).T  # by axis: contiguous rows
        c = np.where(moving, g.kt / np.where(moving, g.t, 1.0), 0.0).T
        y = _least_of_columns(np.where(~moving & (g.k > 0), lim.amax / np.where(g.k > 0, g.k, 1.0), np.inf))
        moving = moving.T
        for i, j in ((0, 1), (0, 2), (1, 2)):  # c_j - c_i is exactly -(c_i - c_j): one of each pair binds
            d = np.abs(c[j] - c[i])
            ok = moving[i] & moving[j] & (d > 0)
            y = np.minimum(y, np.where(ok, (alpha[i] + alpha[j]) / np.where(ok, d, 1.0), np.inf))
    return y


def _least_of_columns(v: np.ndarray) -> np.ndarray:
    """np.min(v, axis=1) of an (n, 3) array, as two elementwise minima (a reduction along rows of three is
    several times slower)."""
    return np.minimum(np.minimum(v[:, 0], v[:, 1]), v[:, 2])


def _within(u: np.ndarray, ranges: np.ndarray | None) -> np.ndarray:
    """Per grid interval of nodes ``u``: whether it overlaps any of ``ranges`` ((n, 2): lo, hi)."""
    mark = np.zeros(len(u), dtype=int)
    if ranges is not None and len(ranges):
        np.add.at(mark, np.maximum(np.searchsorted(u, ranges[:, 0], side="right") - 1, 0), 1)
        np.add.at(mark, np.minimum(np.searchsorted(u, ranges[:, 1]), len(u) - 1), -1)
    return np.cumsum(mark)[:-1] > 0


class _Budgets:
    """Largest path acceleration and deceleration on every grid interval for any speed^2 up to a level Y.

    Acceleration, per axis: -amax_i <= T_i a + K_i y <= amax_i, so a speed-up may use
    (amax_i - sign(T_i) K_i y) / |T_i| and a slow-down (amax_i + sign(T_i) K_i y) / |T_i|, at their worst
    over 0 <= y <= Y (``__call__``), or over the speeds^2 at the interval's ends (``maps``). Jerk, when filtered over
    Tj: |T_i| J/Tj + 3 |K_i| sqrt(Y) A + |P3_i| Y^1.5 <= share * jmax_i, with J the largest jump of the
    acceleration within Tj (the budget, or twice it). For ``__call__`` each axis takes the worst of every term
    over the interval's three points (conservative, and three columns instead of nine); ``maps`` keeps each
    point's own terms.
    """

    def __init__(self, g: _Geometry, m: int, lim: PathLimits, window: float):
        self.geo, self.lim, self.m = g, lim, m
        self.window = window
        self._maps: tuple[np.ndarray, tuple] | None = None  # (ds, maps(ds)): the planner asks again per tight range

    @cached_property
    def terms(self) -> _Terms | None:
        """The terms of every axis that moves or turns anywhere (a column the machine lacks is all zeros), each at
        its worst over an interval's three points; worked out on the first call (trapezoid laws take ``maps``)."""
        g, m, lim = self.geo, self.m, self.lim

        def worst(a):  # (3m, 3) -> per axis, the largest over the interval's three points (m,), column by column
            return [np.max(a[:, i].reshape(3, m), axis=0) for i in range(3)]

        t, k = worst(g.t), worst(g.k)
        p3 = None if g.p3 is None else worst(g.p3)
        kt_up, kt_down = worst(np.maximum(g.kt, 0.0)), worst(np.maximum(-g.kt, 0.0))
        rows = [i for i in range(3) if t[i].any() or k[i].any() or (p3 is not None and p3[i].any())]
        return _Terms.of([t[i] for i in rows], [kt_up[i] for i in rows], [kt_down[i] for i in rows],
                         lim.amax[rows], None if self.window <= 0 or p3 is None else
                         (_JERK_SHARE * lim.jmax[rows], [k[i] for i in rows], [p3[i] for i in rows], self.window))

    def __call__(self, level: np.ndarray, swing: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Budgets at speed^2 ``level`` (normal terms that help counted as at rest); where ``swing``, safe for
        any swing of the acceleration (a jump of up to twice the budget within Tj), elsewhere for jumps of up
        to the budget. Worked out _PART intervals at a time (``_parts``)."""
        n = len(level)
        out = np.empty((2, n))
        if self.terms is None:
            out.fill(1e12)
        elif n <= _PART:
            self.terms.budgets(level, swing, out)
        else:
            for part, at in self._parts:
                part.budgets(level[at], None if swing is None else swing[at], out[:, at])
        return out[0], out[1]

    def maps(self, ds: np.ndarray) -> tuple[tuple[list, list], tuple[list, list]]:
        """Without a jerk limit: per axis and per point of the interval (its start, middle and end, each with its
        own tangent and normal terms), the largest speed^2 y one end of each interval may have given the
        speed^2 x at its other end, y <= a x + b, for slowing down (x the later end's) and for speeding up (x the
        earlier end's). On axis i that takes y - x <= 2 ds (alpha + c y_p), c = -+ sign(T_i) K_i / |T_i| (the
        normal term helps where c > 0) and y_p = w y + (1 - w) x the speed^2 at the point: at the interval's
        ends their own (w = 1 at y's end, 0 at x's: exact at the grid's nodes), at its middle the larger where
        the term hurts and the smaller where it helps (w = 1 or 0: safe whatever y does in between); solved for
        y, a = (1 + 2 ds c (1 - w)) / (1 - 2 ds c w), b = 2 ds alpha / (1 - 2 ds c w). An end whose term would
        make a map steep or fall (2 ds |c| over 1/2: a coarse interval in a tight turn) takes the middle's w.
        An axis that does not move has b = inf. Each point's own terms at its own speed rather than the worst
        of each over the three at the larger end's: round a turn the tangent and the normal load an axis most
        at different points, and speeding up from rest the speed^2 at one end is far from the other's
        (3dtest: 15.1235 -> 15.1141 s of feed motion by the law)."""
        if self._maps is not None and self._maps[0] is ds:
            return self._maps[1]
        h = 2.0 * ds
        m = len(ds)
        down: tuple[list[np.ndarray], list[np.ndarray]] = ([], [])
        up: tuple[list[np.ndarray], list[np.ndarray]] = ([], [])
        for i in range(3):
            t, kt = self.geo.t[:, i].reshape(3, m), self.geo.kt[:, i].reshape(3, m)
            if not (t.any() or kt.any()):
                continue
            moving = t > 0
            inv_t = np.where(moving, 1.0 / np.where(moving, t, 1.0), 0.0)
            alpha = np.where(moving, self.lim.amax[i] * inv_t, np.inf)
            # each point's h c and h alpha once for both ways (speeding up's h c is slowing down's negated: the
            # same products, rounded alike)
            hc_down = [h * kt[q] * inv_t[q] for q in range(3)]
            h_alpha = [h * alpha[q] for q in range(3)]
            # slowing down y is the earlier end's speed^2 and kt > 0 helps; speeding up y is the later end's
            for (a, b), hcs, ends in ((down, hc_down, (1.0, 0.0)), (up, [-hc for hc in hc_down], (0.0, 1.0))):
                for q, hc in enumerate(hcs):
                    w = (hc < 0).astype(float)  # the middle's: hurting at the larger speed, helping at the smaller
                    if q != 1:
                        own = ends[q // 2]
                        w = np.where((hc * own < 0.5) & (hc * (own - 1.0) < 0.5), own, w)
                    den = 1.0 - hc * w
                    a.append((1.0 + hc * (1.0 - w)) / den)
                    b.append(h_alpha[q] / den)
        self._maps = ds, (down, up)
        return down, up

    @cached_property
    def _parts(self) -> list[tuple[_Terms, slice]]:
        """These budgets' terms over every _PART intervals: the same terms (views), so the same numbers, while every
        temporary of a part stays in the processor's cache (one pass over the whole arrays per term is
        bound by memory: about a third slower for 3D_Chips' 152,000 intervals)."""
        assert self.terms is not None
        return [(self.terms.part(slice(start, start + _PART)), slice(start, start + _PART))
                for start in range(0, self.terms.alpha.shape[1], _PART)]


@dataclass
class _Terms:
    """``_Budgets``' terms, one row per axis that moves or turns, stacked (axis, interval): each step of the
    budgets is one numpy call for every axis (a third of the calls, on parts of _PART intervals about as costly
    as their arithmetic)."""

    alpha: np.ndarray  # (r, m): amax_i / |T_i|, inf where the axis does not move
    beta: np.ndarray  # (2, r, m): what the normal term takes per speed^2 from a speed-up, from a slow-down
    jerk: tuple | None  # filtered: (share * jmax_i (r, 1), |T_i| / Tj, 3 |K_i|, |P3_i| (r, m) each)

    @classmethod
    def of(cls, t: list, kt_up: list, kt_down: list, amax: np.ndarray, jerk: tuple | None) -> _Terms | None:
        """The terms from each axis's worst |T_i|, sign(T_i) K_i either way, amax_i and, filtered, (jmax_i, |K_i|,
        |P3_i|, Tj); None without an axis."""
        if not t:
            return None
        rows = np.array(t)
        moving = rows > 0
        inv_t = np.where(moving, 1.0 / np.where(moving, rows, 1.0), 0.0)
        alpha = np.where(moving, amax[:, None] * inv_t, np.inf)
        beta = np.array([kt_up, kt_down]) * inv_t
        if jerk is not None:
            jmax, k, p3, window = jerk
            jerk = (jmax[:, None], rows / window, 3.0 * np.array(k), np.array(p3))
        return cls(alpha, beta, jerk)

    def part(self, at: slice) -> _Terms:
        return _Terms(self.alpha[:, at], self.beta[:, :, at],
                      None if self.jerk is None else (self.jerk[0], *(v[:, at] for v in self.jerk[1:])))

    def budgets(self, y: np.ndarray, swing: np.ndarray | None, out: np.ndarray) -> None:
        """The budgets' arithmetic into ``out`` (2, n): up and down, each the least of every axis's terms (a
        minimum is exact, so in any order the same numbers)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            terms = np.multiply(self.beta, y)
            np.minimum.reduce(np.subtract(self.alpha, terms, out=terms), axis=1, out=out)
            if self.jerk is not None:
                jmax, t_win, k3, p3 = self.jerk
                root = np.sqrt(y)
                coeff = np.multiply(k3, root)
                np.add(t_win if swing is None else t_win * (1.0 + swing), coeff, out=coeff)
                term = np.multiply(p3, np.multiply(y, root, out=root))
                np.subtract(jmax, term, out=term)
                jerk = np.divide(term, coeff, out=term)
                np.copyto(jerk, np.inf, where=~(coeff > 0))  # as dividing only where coeff > 0, twice as fast
                np.minimum(out, np.minimum.reduce(jerk, axis=0), out=out)
            out[~np.isfinite(out)] = 1e12
            np.maximum(out, _FLOOR[:, :out.shape[1]], out=out)  # an array: three times as fast as the scalar


def _converged(high: np.ndarray, low: np.ndarray) -> bool:
    """The profiles from above and from below agree within _CONVERGED of the speed^2 at every node."""
    return bool(np.all(high - low <= _CONVERGED * high + 1e-9 * float(np.max(high))))


def _profile(cap: np.ndarray, stops: np.ndarray, ds: np.ndarray, budget_of,
             node_limit: np.ndarray | None = None, rounds: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """The fastest profile whose tangential budget on each interval is taken at its own speed there.

    T(y) = the scans with budgets taken at the profile y is antitone, so from y = 0 the iterates alternate
    around the fixed point: odd ones from above, even ones from below. An even iterate used budgets taken
    at a faster profile, so it is feasible; they increase towards the fixed point. Returns the last
    feasible profile and its budgets.
    """
    node_cap = np.minimum(np.r_[cap, np.inf], np.r_[np.inf, cap])
    if node_limit is not None:
        node_cap = np.minimum(node_cap, node_limit)
    node_cap[stops] = 0.0
    high = _scan(node_cap, ds, budget_of(np.zeros_like(cap)))
    low = budget = None
    for r in range(rounds):
        budget = budget_of(np.minimum(cap, np.maximum(high[:-1], high[1:])))
        low = _scan(node_cap, ds, budget)
        if r == rounds - 1 or _converged(high, low):  # the last round's profile from above would go unused
            break
        high = _scan(node_cap, ds, budget_of(np.minimum(cap, np.maximum(low[:-1], low[1:]))))
    assert low is not None and budget is not None, "at least one round"
    return low, budget


def _greatest(cap: np.ndarray, stops: np.ndarray, ds: np.ndarray, budgets: _Budgets, known: list | None = None) -> np.ndarray:
    """Without a jerk limit: the fastest profile each interval of which keeps its budgets at its own speeds,
    the normal terms that help counted at the smaller end's speed (``_Budgets.maps``): one backward pass for
    the largest speed^2 from which the tool can still slow down to every cap ahead, one forward pass for the
    largest it can speed up to, each solved exactly (flowmc.motion.capped_recursion). ``known``: the node caps
    and both passes of the last profile on this grid and these budgets (replaced by this one's), from which
    each pass is solved again only about the nodes whose cap changed (``descend_again``)."""
    node_cap = np.minimum(np.r_[cap, np.inf], np.r_[np.inf, cap])
    node_cap[stops] = 0.0
    down, up = budgets.maps(ds)
    up_back = [a[::-1] for a in up[0]], [b[::-1] for b in up[1]]
    if known:
        old_cap, old_reach, old_y = known
        reach = descend_again(node_cap, old_cap, old_reach, *down)
        y = descend_again(reach[::-1], old_reach[::-1], old_y[::-1], *up_back)[::-1]
    else:
        reach = descend(node_cap, *down)
        y = descend(reach[::-1], *up_back, guess=reach[::-1])[::-1]
    if known is not None:
        known[:] = node_cap, reach, y
    return y


def plan_time_law(curve: PlannedCurve, stop_u: np.ndarray, stop_dwell: np.ndarray, stop_segment: np.ndarray,
                  feed_of_u, lim: PathLimits, *, jerk: bool = False, mend_swings: bool = True,
                  tight: np.ndarray | None = None) -> TimeLaw:
    """The fastest time law on ``curve`` under ``lim`` (see the module docstring).

    ``feed_of_u(u)`` gives the path-speed cap at curve parameters u; ``stop_u`` are parameters where the
    tool rests (with ``stop_dwell`` seconds, owned by dwell segment ``stop_segment`` or -1).
    ``mend_swings=False`` (jerk-limited laws only) skips step 2 of ``_filterable``, whose bound stacks every
    term at its worst: faster, and usually within the jerk limit anyway, which the caller then checks from
    the samples (``sampled_jerk``; ``plan_jerk_limited`` mends only then). Without a jerk limit the speed
    may pass the normal terms' own cap where a path acceleration keeps every axis within its limit
    (``_tangent_cap``), except over the curve parameter ranges ``tight`` ((n, 2): lo, hi), where the caller
    found its samples over a limit (``sampled_accel``).
    """
    if jerk:
        law, mended = plan_jerk_limited(curve, stop_u, stop_dwell, stop_segment, feed_of_u, lim)
        return mended() if mend_swings else law
    return trapezoid_laws(curve, stop_u, stop_dwell, stop_segment, feed_of_u, lim)(tight)


def trapezoid_laws(curve: PlannedCurve, stop_u: np.ndarray, stop_dwell: np.ndarray, stop_segment: np.ndarray,
                   feed_of_u, lim: PathLimits) -> Callable[[np.ndarray | None], TimeLaw]:
    """``plan_time_law`` without a jerk limit as a function of ``tight``: the grid, its geometry, caps and
    budget maps are laid out once for all the ranges a caller tries (the planner: up to three per curve)."""
    u, s, ds, speed_u, stops, geo, cap_of = _laid_out(curve, stop_u, feed_of_u, lim, jerk=False)
    budgets = _Budgets(geo, len(ds), lim, 0.0)
    known: list = []  # the last law's caps and passes: a range made tight plans each pass again only about it

    def law(tight: np.ndarray | None = None) -> TimeLaw:
        y = _greatest(cap_of(tight), stops, ds, budgets, known)
        return TimeLaw(u, s, y, np.diff(y) / (2.0 * ds), speed_u, stops, stop_dwell, stop_segment, 0.0, lim.period)
    return law


def plan_jerk_limited(curve: PlannedCurve, stop_u: np.ndarray, stop_dwell: np.ndarray, stop_segment: np.ndarray,
                      feed_of_u, lim: PathLimits):
    """The jerk-limited law with its swings unmended, and a function that gives it mended: that one goes on
    from where the unmended one stopped (grid, geometry, profiles and the first round of ``_filterable`` are
    the same), and is the unmended law itself where no swing needed mending."""
    u, s, ds, speed_u, stops, geo, cap = _laid_out(curve, stop_u, feed_of_u, lim, jerk=True)
    tries = _JerkLimited(cap, stops, stop_dwell, stop_segment, ds, geo, lim)

    def law_of(mend_swings: bool) -> TimeLaw:
        y, window = tries.best(mend_swings)
        return TimeLaw(u, s, y, np.diff(y) / (2.0 * ds), speed_u, stops, stop_dwell, stop_segment, window,
                       lim.period)

    first = law_of(False)

    def mended() -> TimeLaw:
        law = law_of(True)
        return first if law.y is first.y and law.window == first.window else law
    return first, mended


def _laid_out(curve: PlannedCurve, stop_u: np.ndarray, feed_of_u, lim: PathLimits, jerk: bool):
    """The grid (u, s, ds, ds/du at the nodes, stop nodes), its geometry and its speed^2 caps; without a jerk
    limit a function of ``tight`` (as in ``plan_time_law``) that gives them."""
    u = _grid(curve, stop_u, _LINE_STEP_JERK if jerk else _LINE_STEP, _TURN_STEP if jerk else _TURN_STEP_TRAPEZOID)
    du = np.diff(u)
    if np.any(du <= 0):
        raise PlanningError("the planned curve has an empty interval", where="planner")
    k_iv = curve.interval_at(0.5 * (u[:-1] + u[1:]))
    m = len(du)
    # arc length of every grid interval (Gauss-Legendre), and the geometry at both ends and the middle
    gl_u = 0.5 * (u[:-1] + u[1:])[:, None] + 0.5 * du[:, None] * _GL3_X[None, :]
    d1 = curve.evaluate(gl_u.ravel(), 1, index=np.repeat(k_iv, len(_GL3_X)), lowest=1)[0]
    ds = 0.5 * du * (np.sqrt(np.einsum("ij,ij->i", d1, d1)).reshape(m, -1) @ _GL3_W)
    s = np.concatenate([[0.0], np.cumsum(ds)])
    geo, sp = _geometry(curve, u, k_iv, lim.cols, third=jerk)
    feed = np.tile(feed_of_u(0.5 * (u[:-1] + u[1:])), 3)
    y_vel, y_acc = _caps(geo, feed, lim, jerk)
    y_vel, y_acc = np.min(y_vel.reshape(3, m), axis=0), np.min(y_acc.reshape(3, m), axis=0)
    grid = u, s, ds, np.r_[sp[:m], sp[-1]], np.searchsorted(u, stop_u), geo
    if jerk:
        return *grid, np.minimum(y_vel, _RHO * y_acc)
    y_tangent = np.min(_tangent_cap(geo, lim).reshape(3, m), axis=0)

    def cap_of(tight: np.ndarray | None) -> np.ndarray:
        return np.minimum(y_vel, _RHO * np.where(_within(u, tight), y_acc, y_tangent))
    return *grid, cap_of


class _JerkLimited:
    """The jerk-limited profile and its filter length Tj, swings mended or not.

    The filter allows an acceleration jump of jmax Tj within Tj, so Tj = amax / jmax lets the tangential
    acceleration reach amax on straight stretches. Where curvature terms hold the tangential budget far
    below that anyway (dense, tightly curved code: the motion spends less than _SHORT_WINDOW_USE of its
    time above half of it), a window half as long costs little acceleration and halves every reach (caps
    are taken over the stretch the window spans) and every rest at a stop; both are planned then, and the
    one with the shorter motion (rests included) is kept. Each window's rounds of ``_filterable`` are
    planned once, as far as asked: the unmended profile is the mended one's first round."""

    def __init__(self, cap: np.ndarray, stops: np.ndarray, stop_dwell: np.ndarray, stop_segment: np.ndarray,
                 ds: np.ndarray, geo: _Geometry, lim: PathLimits):
        self.cap, self.stops, self.stop_dwell, self.stop_segment = cap, stops, stop_dwell, stop_segment
        self.ds, self.geo, self.lim = ds, geo, lim
        self.base = float(np.max((lim.amax / lim.jmax)[list(lim.cols)]))
        self.rounds: dict[float, tuple] = {}  # share -> (window, rest, its rounds, their profiles so far)

    def _filtered(self, share: float, mend_swings: bool) -> tuple[float, np.ndarray, np.ndarray]:
        if share not in self.rounds:
            window = share * self.base
            budget_of = _Budgets(self.geo, len(self.ds), self.lim, window)
            rest = _stop_waits(len(self.ds) + 1, self.stops, self.stop_dwell, self.stop_segment, window, self.lim.period)
            y, _ = _profile(self.cap, self.stops, self.ds, budget_of)
            rounds = _filterable(y, self.cap, budget_of, self.stops, self.ds, window, rest)
            self.rounds[share] = (window, rest, rounds, [next(rounds)])
        window, rest, rounds, ys = self.rounds[share]
        if mend_swings:
            ys.extend(rounds)
        return window, rest, ys[-1] if mend_swings else ys[0]

    def best(self, mend_swings: bool) -> tuple[np.ndarray, float]:
        ds, lim = self.ds, self.lim
        best: tuple[float, np.ndarray, float] | None = None
        for share in _WINDOWS:
            window, rest, y = self._filtered(share, mend_swings)
            dt = np.diff(_node_times(y, ds))
            total = float(dt.sum() + rest.sum()) + window
            if best is None or total < best[0]:
                best = (total, y, window)
            full = _JERK_SHARE * float(np.min(lim.jmax[list(lim.cols)])) * window  # the straight-line budget
            if float(dt[np.abs(np.diff(y) / (2.0 * ds)) > 0.5 * full].sum()) >= _SHORT_WINDOW_USE * dt.sum():
                break
        assert best is not None
        return best[1], best[2]


def _filterable(y: np.ndarray, cap: np.ndarray, budget_of, stops: np.ndarray, ds: np.ndarray,
                window: float, rest: np.ndarray):
    """The profile made fit for the moving average over Tj: yields it after every round (the first is the
    unmended profile; the last, mended), each worked out only when asked for.

    1. The filtered motion at time t averages the unfiltered one over [t - Tj, t], so wherever it is,
       the unfiltered motion it averages lies within Tj of the time that motion passed there: every cap
       and budget becomes the smallest within that reach, taken from a profile at least as fast as the
       result (the reach of a faster profile is the wider). Planning within a profile's reach is
       antitone in that profile, so the two alternate: every second result, capped by the faster one it
       came from, is safe, and they increase.
    2. The jerk of the filtered motion is (a(t) - a(t - Tj)) / Tj. The budgets allow a jump of one
       budget within Tj. A swing further than that (speeding up within Tj of slowing down) is mostly a
       peak: those are cut flat for Tj (``_flatten_peaks``). Wherever a swing remains, the intervals
       involved get budgets safe for a swing of twice the budget, and it is planned again (mending;
       flowmc.motion.planner checks the samples of a law planned without).
    """
    m = len(ds)
    swing = np.zeros(m, dtype=bool)
    fastest, own = y, _reach(y, cap, ds, window, rest)
    for r in range(_SWING_ROUNDS):
        y, budget_e, reach = _within_reach(fastest, cap, budget_of, swing, stops, ds, window, rest, own)
        # peaks (speeding up, then slowing down) cut flat for Tj: the usual swing, mended cheaply
        node_cap = np.full(m + 1, np.inf)
        node_cap[stops] = 0.0
        for _ in range(_PLATEAU_ROUNDS):
            lowered = _flatten_peaks(y, ds, window)
            if lowered is None:
                break
            node_cap = np.minimum(node_cap, lowered)
            y = _scan(np.minimum(node_cap, y), ds, budget_e)
        yield y
        if r == _SWING_ROUNDS - 1:  # no round left to mend what the check below would find
            return
        depart = _node_times(y, ds) + np.cumsum(rest)  # the rests at stops (sample_time_law) separate too
        arrive = depart - rest
        a = np.diff(y) / (2.0 * ds)
        # partners of interval k: the intervals the motion was on Tj earlier, during its time on k
        p_lo = np.searchsorted(arrive[1:], depart[:-1] - window, side="right")
        p_hi = np.searchsorted(depart[:-1], arrive[1:] - window, side="left") - 1
        has = p_hi >= p_lo
        p_lo, p_hi = np.clip(p_lo, 0, m - 1), np.clip(np.maximum(p_hi, p_lo), 0, m - 1)
        allowed = np.minimum(*budget_of(np.minimum(cap, np.maximum(y[:-1], y[1:])), None))
        allowed = window_min(allowed, *reach)
        over = ((window_max(a, p_lo, p_hi) - a > allowed * (1 + 1e-9))
                | (a - window_min(a, p_lo, p_hi) > allowed * (1 + 1e-9)))
        over &= ~swing & has
        if not over.any():
            return
        # mark each offending interval and its partners (a difference array over the ranges)
        k = np.flatnonzero(over)
        mark = np.zeros(m + 1, dtype=int)
        np.add.at(mark, p_lo[k], 1)
        np.add.at(mark, p_hi[k] + 1, -1)
        swing |= (np.cumsum(mark)[:m] > 0) | over


def _within_reach(fastest: np.ndarray, cap: np.ndarray, budget_of, swing: np.ndarray, stops: np.ndarray,
                  ds: np.ndarray, window: float, rest: np.ndarray, own: tuple):
    """1. of _filterable: the safe profile, its budgets, and its reach (lo, hi per interval). ``own``: ``_reach``
    of ``fastest``, the same in every round of _filterable."""
    at_rest: list[tuple[np.ndarray, np.ndarray]] = []  # the budgets at speed 0, where every profile below starts: worked out once
    swung = swing if swing.any() else None  # no swing: the same budgets without widening by 1

    def budgets(level: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if level.any():
            return budget_of(level, swung)
        if not at_rest:
            at_rest.append(budget_of(level, swung))
        return at_rest[0]

    def planned(faster: np.ndarray, limit: np.ndarray | None, known: tuple | None = None):
        lo, hi, windows, capped = known if known is not None else _reach(faster, cap, ds, window, rest)

        def reach_budget(level):
            up, down = budgets(level)
            least = windows.min(up)
            # on straight stretches the two budgets are the same numbers: their minima too
            return least, least if np.array_equal(up, down) else windows.min(down)

        y, budget = _profile(capped, stops, ds, reach_budget, node_limit=limit, rounds=_REACH_PROFILE_ROUNDS)
        return y, budget, (lo, hi)

    high = fastest
    known: tuple | None = own
    for r in range(_REACH_ROUNDS):
        y, budget, reach = planned(high, high, known)
        if r == _REACH_ROUNDS - 1 or _converged(high, y):  # the last round's faster profile would go unused
            break
        high, known = np.maximum(planned(y, None)[0], y), None
    return y, budget, reach


def _reach(faster: np.ndarray, cap: np.ndarray, ds: np.ndarray, window: float, rest: np.ndarray) -> tuple:
    """The reach of every interval under profile ``faster`` (lo, hi), its ``Windows`` (every round of a profile
    takes minima over them) and the cap's minima over them.

    The reach of interval k: every interval the filtered motion is on while its window holds some of the
    time spent on k. The window holds it from the time the motion leaves node k until Tj after it reaches
    node k + 1, and the filtered position only grows, so the filtered motion is between s_f(leave k) and
    s_f(reach k+1, plus Tj): about half a window's travel each side, since s_f lags by about Tj / 2. A faster
    profile (faster at every s) gives a wider reach: the window's average lies further back and ahead."""
    m = len(ds)
    s_nodes = np.concatenate([[0.0], np.cumsum(ds)])
    ph = _phases_of(s_nodes, faster, np.diff(faster) / (2.0 * ds), rest, None)
    depart = ph.start[0::2] + ph.dur[0::2]  # leaving each node (after its rest)
    arrive = ph.start[0::2]
    times = np.concatenate([depart[:-1], arrive[1:] + window])
    lo, hi = _intervals_reached(ph, times, m, window, s_nodes)
    k = np.arange(m)
    lo, hi = np.minimum(lo, k), np.maximum(hi, k)
    windows = Windows(lo, hi, m)
    return lo, hi, windows, windows.min(cap)


def _intervals_reached(ph: _Phases, times: np.ndarray, m: int, window: float, s_nodes: np.ndarray) -> tuple:
    """The intervals the filtered motion is on at ``times`` (the first m from the left, the rest from the right).

    The filtered positions are averages of two long double integrals (``_filtered``), but only the nodes they
    fall between matter: worked out in doubles, they are within ``delta`` of the long doubles' (each double
    rounds the integrals, at most ``scale``, by 2^-53 of them, and the average by 2^-53 of it: a few times
    that, taken 100 times over), so only those within ``delta`` of a node are worked out again as before.
    Long double arithmetic over 3m times (3D_Chips: 15 MB of fresh arrays a reach) is most of a reach."""
    rounded = ph.cumulative.astype(float)
    back, ahead = ph.integral(times - window, cumulative=rounded), ph.integral(times[m:], cumulative=rounded)
    f = np.concatenate([rounded[1:2 * m:2], ahead])  # leaving node k: the whole phases before it
    f -= back
    f /= window
    scale = max(float(np.max(np.abs(rounded))), float(np.max(np.abs(back))), float(np.max(np.abs(ahead))))
    delta = 2.0**-46 * (4.0 * scale / window + float(np.max(np.abs(f)))) + 1e-300
    pad = np.concatenate([[-np.inf], s_nodes, [np.inf]])
    at = np.concatenate([np.searchsorted(s_nodes, f[:m], side="left"), np.searchsorted(s_nodes, f[m:], side="right")])
    near = np.flatnonzero(~((pad[at] < f - delta) & (f + delta < pad[at + 1])))  # NaN counts as near
    if len(near):
        exact = _filtered(ph, times, m, window, near)
        first = near < m
        at[near] = np.where(first, np.searchsorted(s_nodes, exact, side="left"),
                            np.searchsorted(s_nodes, exact, side="right"))
    return np.clip(at[:m] - 1, 0, m - 1), np.clip(at[m:] - 1, 0, m - 1)


def _filtered(ph: _Phases, times: np.ndarray, m: int, window: float, idx: np.ndarray) -> np.ndarray:
    """The filtered positions at times[idx] as the long doubles give them (see ``_intervals_reached``)."""
    return ((_integral_leaving_first(ph, times, m, idx) - ph.integral(times[idx] - window)).astype(float)
            / window)


def _integral_leaving_first(ph: _Phases, times: np.ndarray, m: int, idx: np.ndarray) -> np.ndarray:
    """``ph.integral(times[idx])``, the first m of ``times`` the times the motion leaves nodes 0..m-1: the starts of
    phases 1, 3, ..., where no phase after one of them lasts no time at all. There the integral is the whole phases'
    before, found without a search and with nothing of the phase's own to add (that part is 0)."""
    leaving = np.arange(1, 2 * m, 2)
    if not (np.array_equal(times[:m], ph.start[leaving]) and np.all(ph.start[leaving + 1] > ph.start[leaving])):
        return ph.integral(times[idx])
    first = idx < m
    out = np.empty(len(idx), dtype=np.longdouble)
    out[first] = ph.cumulative[leaving[idx[first]]]
    out[~first] = ph.integral(times[idx[~first]])
    return out


def _flatten_peaks(y: np.ndarray, ds: np.ndarray, window: float) -> np.ndarray | None:
    """Node caps that cut every peak of the profile flat for at least ``window`` seconds; None if all are.

    A peak is a stretch of constant speed (possibly a single node) with speeding up before it and slowing
    down after. Cut at level L, its plateau runs between the nodes where the rising and the falling side
    reach L, and lasts that distance over sqrt(L); the level is
    found by bisection, for all peaks at once. The plateau counts from node to node only: the grid
    intervals where the sides cross the level still change speed a little.
    """
    dy = np.diff(y)
    tiny = 1e-9 * max(float(np.max(y)), 1.0)
    sign = np.where(dy > tiny, 1, np.where(dy < -tiny, -1, 0))
    v = np.sqrt(np.maximum(y, 0.0))
    dt = 2.0 * ds / np.maximum(v[:-1] + v[1:], 1e-300)
    moving = np.flatnonzero(sign != 0)
    if len(moving) < 2:
        return None
    turn = (sign[moving[:-1]] > 0) & (sign[moving[1:]] < 0)
    rise, fall = moving[:-1][turn], moving[1:][turn]  # last rising interval, first falling one
    flat_time = np.cumsum(np.r_[0.0, np.where(sign == 0, dt, 0.0)])
    short = flat_time[fall] - flat_time[rise + 1] < window * (1.0 - 1e-6)
    if not short.any():
        return None
    rise, fall = rise[short], fall[short]
    s = np.r_[0.0, np.cumsum(ds)]
    # each peak's sides: the run of rising intervals ending at its last rise, the falling run from its first fall
    run_start = np.r_[True, sign[1:] != sign[:-1]]
    run_id = np.cumsum(run_start) - 1
    first_of_run = np.flatnonzero(run_start)
    last_of_run = np.r_[first_of_run[1:] - 1, len(sign) - 1]
    left0 = first_of_run[run_id[rise]]
    right1 = last_of_run[run_id[fall]] + 1
    top = y[rise + 1]
    lo, hi = np.maximum(y[left0], y[right1]), top.copy()
    # one sorted key array per side, peaks kept apart by multiples of a big offset
    big = 2.0 * float(np.max(y)) + 1.0
    idx = np.arange(len(rise))
    l_len, r_len = rise + 2 - left0, right1 - fall + 1
    l_nodes = np.repeat(left0 - 1, l_len) + ranks(l_len)  # left0 .. rise + 1 for each peak
    r_nodes = np.repeat(right1 + 1, r_len) - ranks(r_len)  # right1 down to fall
    l_key = y[l_nodes] + np.repeat(idx, l_len) * big
    r_key = y[r_nodes] + np.repeat(idx, r_len) * big
    shift = idx * big

    def crossing(key, nodes, length):
        """Where the side is first at or above a level, at a node (the plateau starts and ends at nodes), given the
        side's sorted keys, its nodes and lengths: the bisection's 40 rounds look up only what changes."""
        off = np.r_[0, np.cumsum(length)[:-1]]
        last, at = off + length - 1, s[nodes]

        def where(level):
            return at[np.minimum(np.maximum(np.searchsorted(key, level + shift), off), last)]
        return where

    right, left = crossing(r_key, r_nodes, r_len), crossing(l_key, l_nodes, l_len)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        width = right(mid) - left(mid)
        wide = width >= window * np.sqrt(mid)
        lo, hi = np.where(wide, mid, lo), np.where(wide, hi, mid)
    level = np.minimum(lo, top * (1.0 - 1e-6))
    # every node of a peak above its level is capped there: both sides and the top between them
    caps = np.full(len(y), np.inf)
    t_len = fall - rise
    t_nodes = np.repeat(rise, t_len) + ranks(t_len)  # rise + 1 .. fall
    for nodes, length in ((l_nodes, l_len), (r_nodes, r_len), (t_nodes, t_len)):
        lv = np.repeat(level, length)
        above = y[nodes] > lv
        np.minimum.at(caps, nodes[above], lv[above])
    return caps


def _node_times(y: np.ndarray, ds: np.ndarray) -> np.ndarray:
    v = np.sqrt(np.maximum(y, 0.0))
    return np.concatenate([[0.0], np.cumsum(2.0 * ds / np.maximum(v[:-1] + v[1:], 1e-300))])


@dataclass
class _Phases:
    """The unfiltered motion as phases in time order: each starts at ``start`` (s) at arc length ``s0`` with
    speed ``v0`` and constant acceleration ``a`` for ``dur`` seconds (waits have v0 = a = 0)."""

    start: np.ndarray
    dur: np.ndarray
    s0: np.ndarray
    v0: np.ndarray
    a: np.ndarray
    owner: np.ndarray | None  # dwell segment a wait belongs to, -1 otherwise; None where no one asks (``_reach``)

    def at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        k = np.clip(search_right(self.start, t) - 1, 0, len(self.start) - 1)
        return k, np.clip(t - self.start[k], 0.0, self.dur[k])

    def s(self, t: np.ndarray, where: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """Arc length at times t; ``where``: ``at(t)``, if known."""
        k, tau = self.at(t) if where is None else where
        return self.s0[k] + tau * (self.v0[k] + 0.5 * self.a[k] * tau)

    @cached_property
    def cumulative(self) -> np.ndarray:
        """The integral of s over every whole phase before each, as long doubles (summed in place: one array)."""
        part = self.dur * (self.s0 + self.dur * (0.5 * self.v0 + self.dur * self.a / 6.0))
        cum = np.empty(len(part) + 1, dtype=np.longdouble)
        cum[0] = 0.0
        cum[1:] = part
        np.cumsum(cum[1:], out=cum[1:])
        return cum

    def integral(self, t: np.ndarray, where: tuple[np.ndarray, np.ndarray] | None = None,
                 cumulative: np.ndarray | None = None) -> np.ndarray:
        """Running integral of s over [0, t] (s is s0 before 0 and its end value after the last phase), as
        long doubles: the moving average subtracts two of them. ``where``: ``at(t)``, if known. ``cumulative``:
        ``self.cumulative`` rounded to doubles, for the integral in doubles (each of its two or three additions
        rounds once more than the long doubles', by at most 2^-53 of the larger sum)."""
        k, tau = self.at(t) if where is None else where
        total = (self.cumulative if cumulative is None else cumulative)[k]
        # the phase's own part, widened exactly and added as long doubles (in doubles from ``cumulative``)
        total += tau * (self.s0[k] + tau * (0.5 * self.v0[k] + tau * self.a[k] / 6.0))
        # the parts after the end and before 0, added only where they are not zero (adding a zero changes nothing)
        end_t = self.start[-1] + self.dur[-1]
        late, early = np.flatnonzero(t > end_t), np.flatnonzero(t < 0.0)
        if len(late):
            s_end = self.s0[-1] + self.dur[-1] * (self.v0[-1] + 0.5 * self.a[-1] * self.dur[-1])
            total[late] += ((t[late] - end_t) * s_end).astype(total.dtype)
        if len(early):
            total[early] += (t[early] * self.s0[0]).astype(total.dtype)
        return total


def _stop_waits(n: int, stop_node: np.ndarray, dwell: np.ndarray, owner: np.ndarray, window: float,
                period: float) -> np.ndarray:
    """How long the unfiltered motion waits at each node: at every stop its dwell, plus Tj inside the program
    when filtered, so that the filtered motion rests there that long too. Unfiltered, a stop of the path's
    shape (no dwell, no segment of its own) is passed at rest in an instant: a sampled acceleration that sees
    both the arrival and the departure (which may go another way) is an average of the two, each within the
    per-axis limits, so it is too (a second difference is the acceleration weighed over two periods). A stop
    the program asks for (its own segment: M0, M1, M6, M60, a dwell) rests at least a period, so a setpoint
    is there at rest: a job holds at it, and LinuxCNC's program and single-block ends are cut there."""
    wait = np.zeros(n)
    np.add.at(wait, stop_node, dwell)
    inner = np.zeros(n, dtype=bool)
    inner[stop_node] = True
    inner[[0, -1]] = False
    if window > 0:
        wait[inner] += window
    else:
        asked = stop_node[(owner >= 0) & inner[stop_node]]
        wait[asked] = np.maximum(wait[asked], period)
    return wait


def _phases(law: TimeLaw) -> _Phases:
    wait = _stop_waits(len(law.s), law.stop_node, law.stop_wait, law.stop_segment, law.window, law.period)
    owner = np.full(len(law.s), -1)
    owner[law.stop_node] = law.stop_segment
    return _phases_of(law.s, law.y, law.accel, wait, owner)


def _phases_of(s: np.ndarray, y: np.ndarray, accel: np.ndarray, wait: np.ndarray, owner: np.ndarray | None) -> _Phases:
    """Phases of a profile y at nodes s, waiting ``wait`` at each node (dwell segment ``owner`` or -1; None: not
    needed)."""
    v = np.sqrt(np.maximum(y, 0.0))
    dt = 2.0 * np.diff(s) / np.maximum(v[:-1] + v[1:], 1e-300)
    n = len(s)
    dur, s0, v0, acc = np.empty(2 * n - 1), np.empty(2 * n - 1), np.zeros(2 * n - 1), np.zeros(2 * n - 1)
    dur[0::2], dur[1::2] = wait, dt
    s0[0::2], s0[1::2] = s, s[:-1]
    v0[1::2] = v[:-1]
    acc[1::2] = accel
    own = None
    if owner is not None:
        own = np.full(2 * n - 1, -1)
        own[0::2] = owner
    start = np.empty(2 * n - 1)
    start[0] = 0.0
    np.cumsum(dur[:-1], out=start[1:])
    return _Phases(start, dur, s0, v0, acc, own)


def sample_time_law(law: TimeLaw, curve: PlannedCurve, period: float,
                    axes: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Curve parameter u at t = kT (k = 0..N, the last sample exactly at the end of the motion) and, per
    sample, the dwell segment it waits in (-1 elsewhere). Dwells (and, when filtered, a rest of Tj at
    every stop) are inserted at the stop nodes. BudgetError before allocating more setpoints (of ``axes``
    columns) than the budget allows."""
    ph = _phases(law)
    s, seg = arc_length_at(law, ph, setpoint_times(_duration(law, ph), period, axes))
    return law.u_sampled(s, curve), seg


def samples_of(law: TimeLaw, period: float) -> int:
    """How many samples ``sample_time_law`` gives, without sampling."""
    return sample_count(_duration(law, _phases(law)), period)


def _duration(law: TimeLaw, ph: _Phases) -> float:
    """The motion's length in time, rests and the filter's lag included."""
    return float(ph.start[-1] + ph.dur[-1]) + law.window


def arc_length_at(law: TimeLaw, ph: _Phases, ts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Arc length of the (filtered) motion at times ts, and the dwell segment each waits in (-1 elsewhere). Worked
    out CHUNK times at a time past CHUNKED, as ``TimeLaw.u_at``."""
    if len(ts) > CHUNKED:
        parts = [arc_length_at(law, ph, ts[i:i + CHUNK]) for i in range(0, len(ts), CHUNK)]
        return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])
    owner = ph.owner
    assert owner is not None, "a law's phases (``_phases``)"
    if law.window <= 0:
        where = ph.at(ts)
        return ph.s(ts, where), owner[where[0]]
    tj = law.window
    back = ts - tj
    at0, at1 = ph.at(back), ph.at(ts)
    s = ((ph.integral(ts, at1) - ph.integral(back, at0)) / np.longdouble(tj)).astype(float)
    k0, k1 = at0[0], at1[0]
    resting = (k0 == k1) & (ph.v0[k1] == 0.0) & (ph.a[k1] == 0.0)  # the whole window rests in one wait
    s = np.where(resting, ph.s0[k1], s)
    seg = np.where(resting & (owner[k1] >= 0), owner[k1], -1)
    return s, seg


def speed_at(law: TimeLaw, ph: _Phases, ts: np.ndarray) -> np.ndarray:
    """Path speed of the (filtered) motion at times ts."""
    def unfiltered(t):
        k, tau = ph.at(t)
        return ph.v0[k] + ph.a[k] * tau
    if law.window <= 0:
        return unfiltered(ts)
    return (ph.s(ts) - ph.s(ts - law.window)) / law.window


def sampled_accel(positions: np.ndarray, lim: PathLimits) -> np.ndarray:
    """Setpoints (indices of ``positions``, the machine's columns, period ``lim.period``) whose per-axis
    acceleration by second differences, as a device sees it, is over amax by more than rounding."""
    cols = list(lim.cols)
    if len(positions) < 3:
        return np.zeros(0, dtype=int)
    over = np.abs(np.diff(positions, 2, axis=0)) > lim.amax[cols] * lim.period**2 * (1.0 + _ACCEL_SLACK)
    return np.flatnonzero(np.any(over, axis=1)) + 1


def sampled_jerk(positions: np.ndarray, lim: PathLimits) -> float:
    """The largest per-axis jerk of setpoints ``positions`` (the machine's columns, period ``lim.period``),
    by third differences as a device sees it, over that axis's jmax."""
    cols = list(lim.cols)
    if len(positions) < 4:
        return 0.0
    return float(np.max(np.abs(np.diff(positions, 3, axis=0)) / lim.period**3 / lim.jmax[cols]))
