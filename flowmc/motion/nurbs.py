"""NURBS curves: checking, vectorised evaluation, curvature, arc length and its inverse.

Evaluation runs scipy's B-spline on homogeneous coordinates (w*P, w) and recovers the rational
curve and its derivatives by the quotient rule, so a whole array of parameters costs one call.
The interpolator (Taylor parameter update with a chord corrector) lives in the second half.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import comb
from typing import TYPE_CHECKING

import numpy as np

import flowmc.budget as budget
from flowmc.errors import PathError, PlanningError

if TYPE_CHECKING:
    from scipy.interpolate import PPoly

__all__ = [
    "clamped_uniform_knots",
    "check_nurbs",
    "Nurbs",
    "evaluate",
    "curvature",
    "arc_length",
    "u_at_length",
    "ArcLengthTable",
    "FeedSchedule",
    "feed_schedule",
    "TaylorSteps",
    "taylor_steps",
    "interpolate",
    "feed_fluctuation",
    "chord_errors",
]

_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)
_SUB_PER_SPAN = 32  # sub-intervals per knot span in the arc-length table


def clamped_uniform_knots(n_ctrl: int, degree: int) -> np.ndarray:
    """Clamped uniform knot vector on [0, 1]: degree+1 zeros, uniform interior, degree+1 ones."""
    if degree < 1 or n_ctrl < degree + 1:
        raise PathError(f"need at least degree+1 = {degree + 1} control points, got {n_ctrl}",
                        where="nurbs.control_points")
    n_inner = n_ctrl - degree - 1
    inner = np.arange(1, n_inner + 1) / (n_inner + 1)
    return np.concatenate([np.zeros(degree + 1), inner, np.ones(degree + 1)])


def check_nurbs(ctrl, weights, knots, degree, where: str = "nurbs"):
    """Validate a NURBS definition; return (ctrl (n, dim), weights (n,), knots (n+degree+1,)) as float arrays.

    Raises PathError naming the offending field (``<where>.knots`` ...) with expected and actual values.
    """
    if int(degree) != degree or degree < 1:
        raise PathError(f"degree must be an integer >= 1, got {degree!r}", where=f"{where}.degree")
    degree = int(degree)
    try:
        ctrl = np.array(ctrl, dtype=float)
        weights = np.array(weights, dtype=float).reshape(-1)
        knots = np.array(knots, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise PathError(f"not numeric: {exc}", where=where) from None
    if ctrl.ndim != 2 or ctrl.shape[1] < 1:
        raise PathError(f"control points must be a list of points (n, dim), got shape {ctrl.shape}",
                        where=f"{where}.control_points")
    n = len(ctrl)
    if n < degree + 1:
        raise PathError(f"degree {degree} needs at least {degree + 1} control points, got {n}",
                        where=f"{where}.control_points")
    if not np.all(np.isfinite(ctrl)):
        raise PathError("control points must be finite", where=f"{where}.control_points")
    if len(weights) != n:
        raise PathError(f"expected one weight per control point ({n}), got {len(weights)}",
                        where=f"{where}.weights")
    if not np.all(np.isfinite(weights)) or np.any(weights <= 0):
        bad = int(np.flatnonzero(~(weights > 0) | ~np.isfinite(weights))[0])
        raise PathError(f"weights must be > 0, weight {bad} is {weights[bad]}", where=f"{where}.weights")
    expected = n + degree + 1
    if len(knots) != expected:
        raise PathError(
            f"knot count must be len(control_points) + degree + 1 = {n} + {degree} + 1 = {expected}, "
            f"got {len(knots)}", where=f"{where}.knots")
    if not np.all(np.isfinite(knots)):
        raise PathError("knots must be finite", where=f"{where}.knots")
    drops = np.flatnonzero(np.diff(knots) < 0)
    if len(drops):
        i = int(drops[0])
        raise PathError(f"knots must be non-decreasing: knot {i + 1} ({knots[i + 1]}) < knot {i} ({knots[i]})",
                        where=f"{where}.knots")
    if not knots[n] > knots[degree]:
        raise PathError(f"empty parameter domain [{knots[degree]}, {knots[n]}]", where=f"{where}.knots")
    return ctrl, weights, knots


class Nurbs:
    """A checked NURBS curve with its homogeneous B-spline and a lazily built arc-length table.

    Build once and reuse when evaluating many times; the free functions below build one per call.
    """

    __slots__ = ("ctrl", "weights", "knots", "degree", "dim", "u0", "u1", "_hom", "_table")

    def __init__(self, ctrl, weights, knots, degree, where: str = "nurbs"):
        self.ctrl, self.weights, self.knots = check_nurbs(ctrl, weights, knots, degree, where)
        self.degree = int(degree)
        self.dim = self.ctrl.shape[1]
        self.u0 = float(self.knots[self.degree])
        self.u1 = float(self.knots[len(self.ctrl)])
        from scipy.interpolate import BSpline  # scipy on first use: `flowmc validate` starts without it

        hom = np.hstack([self.ctrl * self.weights[:, None], self.weights[:, None]])
        self._hom = BSpline(self.knots, hom, self.degree, extrapolate=True)
        self._table = None
        for a in (self.ctrl, self.weights, self.knots):
            a.flags.writeable = False

    # -- evaluation -------------------------------------------------------------------------
    def evaluate(self, u, nderiv: int = 0) -> np.ndarray:
        """Points and derivatives d^k C/du^k, k = 0..nderiv: array (nderiv+1, len(u), dim).

        u is clipped to the parameter domain [u0, u1] (a clamped curve's ends are exact there).
        """
        u = np.minimum(np.maximum(np.asarray(u, dtype=float).reshape(-1), self.u0), self.u1)
        d = self.dim
        hom = [self._hom(u, nu=k) for k in range(nderiv + 1)]  # each (len(u), dim+1)
        w = hom[0][:, d:]
        out = np.empty((nderiv + 1, len(u), d))
        np.divide(hom[0][:, :d], w, out=out[0])
        for k in range(1, nderiv + 1):  # quotient rule: A^(k) = sum_i C(k,i) w^(i) C^(k-i)
            acc = hom[k][:, :d]
            for i in range(1, k + 1):
                acc = acc - comb(k, i) * hom[i][:, d:] * out[k - i]
            np.divide(acc, w, out=out[k])
        return out

    def curvature(self, u) -> np.ndarray:
        """Curvature kappa(u) = |C' x C''| / |C'|^3 (1/mm), vectorised."""
        _, d1, d2 = self.evaluate(u, 2)
        return _curvature(d1, d2)

    # -- arc length -------------------------------------------------------------------------
    def _speed_integral(self, a, b) -> np.ndarray:
        """Integral of |C'| over each [a_i, b_i] by 8-point Gauss-Legendre (intervals must be short)."""
        a = np.asarray(a, dtype=float)
        b = np.asarray(b, dtype=float)
        half = 0.5 * (b - a)
        x = (0.5 * (a + b))[:, None] + half[:, None] * _GL_X[None, :]
        sp = np.linalg.norm(self.evaluate(x.ravel(), 1)[1], axis=1).reshape(x.shape)
        return half * (sp @ _GL_W)

    @property
    def table(self) -> "ArcLengthTable":
        if self._table is None:
            self._table = ArcLengthTable(self)
        return self._table

    @property
    def length(self) -> float:
        return self.table.length

    def arc_length(self, u0=None, u1=None) -> float:
        """Arc length between parameters u0 and u1 (defaults: the whole curve)."""
        u0 = self.u0 if u0 is None else float(u0)
        u1 = self.u1 if u1 is None else float(u1)
        sign = 1.0
        if u1 < u0:
            u0, u1, sign = u1, u0, -1.0
        return sign * float(self.table.s_at(np.array([u1]))[0] - self.table.s_at(np.array([u0]))[0])

    def u_at(self, s) -> np.ndarray:
        """Parameters at arc lengths s from the start (vectorised): table, Hermite interpolation, Newton polish."""
        return self.table.u_at(s)


def _curvature(d1: np.ndarray, d2: np.ndarray) -> np.ndarray:
    dim = d1.shape[-1]
    if dim == 2:
        cross = np.abs(d1[..., 0] * d2[..., 1] - d1[..., 1] * d2[..., 0])
    elif dim == 3:
        cross = np.linalg.norm(np.cross(d1, d2), axis=-1)
    else:
        n1 = np.einsum("...i,...i", d1, d1)
        cross = np.sqrt(np.maximum(n1 * np.einsum("...i,...i", d2, d2) - np.einsum("...i,...i", d1, d2) ** 2, 0))
    speed = np.linalg.norm(d1, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        kappa = cross / speed**3
    return np.where(speed > 0, kappa, np.inf)  # a cusp (speed 0): unbounded curvature


class ArcLengthTable:
    """s(u) on a dense grid (8-point Gauss-Legendre per sub-interval of each knot span) and its inverse.

    Between grid nodes both s(u) and u(s) are quintic Hermite interpolants built from the exact
    first and second derivatives (s' = |C'|, s'' = C'.C''/|C'|), good to about 1e-8 mm on the
    test curve; ``u_at`` polishes with Newton steps on the quadrature to reach ~1e-12 mm.
    """

    __slots__ = ("curve", "u", "s", "length", "_fwd", "_inv")

    def __init__(self, curve: Nurbs):
        self.curve = curve
        breaks = np.unique(curve.knots[curve.degree:len(curve.ctrl) + 1])
        frac = np.linspace(0.0, 1.0, _SUB_PER_SPAN + 1)[:-1]
        u = (breaks[:-1, None] + np.diff(breaks)[:, None] * frac[None, :]).ravel()
        u = np.append(u, breaks[-1])
        seg = curve._speed_integral(u[:-1], u[1:])
        self.u = u
        self.s = np.concatenate([[0.0], np.cumsum(seg)])
        self.length = float(self.s[-1])
        _, d1, d2 = curve.evaluate(u, 2)
        speed = np.linalg.norm(d1, axis=1)
        if not np.all(speed > 1e-12 * max(float(speed.max()), 1e-300)):
            bad = float(u[np.argmin(speed)])
            raise PathError(f"the curve stops (zero speed) near u = {bad:.6g}: repeated control points?",
                            where="nurbs.control_points")
        accel = np.einsum("ij,ij->i", d1, d2) / speed
        self._fwd = _quintic_hermite(u, self.s, speed, accel)
        self._inv = _quintic_hermite(self.s, u, 1.0 / speed, -accel / speed**3)

    def s_at(self, u, exact: bool = True) -> np.ndarray:
        """Arc length from the start to each parameter u: by quadrature, or (exact=False) by the interpolant."""
        u = np.clip(np.asarray(u, dtype=float), self.u[0], self.u[-1])
        if not exact:
            return np.clip(self._fwd(u), 0.0, self.length)
        i = np.clip(np.searchsorted(self.u, u, side="right") - 1, 0, len(self.u) - 2)
        return self.s[i] + self.curve._speed_integral(self.u[i], u)

    def u_at(self, s, polish: int = 1) -> np.ndarray:
        """Inverse of s_at: interpolant guess, then ``polish`` Newton steps on the quadrature."""
        s = np.clip(np.asarray(s, dtype=float), 0.0, self.length)
        u = np.clip(self._inv(s), self.u[0], self.u[-1])
        for _ in range(polish):
            speed = np.linalg.norm(self.curve.evaluate(u, 1)[1], axis=1)
            u = np.clip(u - (self.s_at(u) - s) / speed, self.u[0], self.u[-1])
        return u


def _quintic_hermite(x, y, dy, ddy) -> PPoly:
    """Piecewise quintic matching value, first and second derivative at every node (vectorised build)."""
    from scipy.interpolate import PPoly  # scipy on first use: `flowmc validate` starts without it

    h = np.diff(x)
    a = y[1:] - (y[:-1] + dy[:-1] * h + 0.5 * ddy[:-1] * h * h)
    b = (dy[1:] - dy[:-1] - ddy[:-1] * h) * h
    c = (ddy[1:] - ddy[:-1]) * h * h
    coef = np.array([
        (6.0 * a - 3.0 * b + 0.5 * c) / h**5,
        (-15.0 * a + 7.0 * b - c) / h**4,
        (10.0 * a - 4.0 * b + 0.5 * c) / h**3,
        0.5 * ddy[:-1],
        dy[:-1],
        y[:-1],
    ])
    return PPoly(coef, x, extrapolate=True)


# -- free functions over plain arrays (build a Nurbs per call; use Nurbs directly in loops) ----

def evaluate(ctrl, weights, knots, degree, u, nderiv: int = 0) -> np.ndarray:
    """Points and derivatives of the rational curve at parameters u: array (nderiv+1, len(u), dim)."""
    return Nurbs(ctrl, weights, knots, degree).evaluate(u, nderiv)


def curvature(ctrl, weights, knots, degree, u) -> np.ndarray:
    """Curvature (1/mm) at parameters u."""
    return Nurbs(ctrl, weights, knots, degree).curvature(u)


def arc_length(ctrl, weights, knots, degree, u0: float | None = None, u1: float | None = None) -> float:
    """Arc length between u0 and u1 (defaults: whole curve), Gauss-Legendre per knot-span sub-interval."""
    return Nurbs(ctrl, weights, knots, degree).arc_length(u0, u1)


def u_at_length(ctrl, weights, knots, degree, s) -> np.ndarray:
    """Parameters at arc lengths s measured from the curve start (vectorised)."""
    return Nurbs(ctrl, weights, knots, degree).u_at(s)


# == interpolation: second-order Taylor parameter update with a chord corrector ================

@dataclass(frozen=True, eq=False)
class FeedSchedule:
    """The curvature- and acceleration-limited feed along the curve, and its time law.

    On a uniform arc-length grid ``s``: the cap ``v_cap`` (feed, chord error and normal
    acceleration over the tightest radius within one step either side), the speed ``v`` after the
    forward/backward acceleration passes, and the time ``t`` each node is reached (constant
    acceleration between nodes).
    """

    s: np.ndarray
    v_cap: np.ndarray
    v: np.ndarray
    t: np.ndarray
    period: float

    @property
    def duration(self) -> float:
        return float(self.t[-1])

    def _accel(self, i):
        ds = self.s[i + 1] - self.s[i]
        return (self.v[i + 1] ** 2 - self.v[i] ** 2) / (2.0 * ds)

    def s_at_time(self, t) -> np.ndarray:
        """Planned arc length at times t."""
        t = np.clip(np.asarray(t, dtype=float), 0.0, self.t[-1])
        i = np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, len(self.t) - 2)
        tau = t - self.t[i]
        return np.minimum(self.s[i] + self.v[i] * tau + 0.5 * self._accel(i) * tau * tau, self.s[-1])

    def time_at_s(self, s) -> np.ndarray:
        """Planned time at arc lengths s (exact inverse of s_at_time)."""
        s = np.clip(np.asarray(s, dtype=float), 0.0, self.s[-1])
        i = np.clip(np.searchsorted(self.s, s, side="right") - 1, 0, len(self.s) - 2)
        d = s - self.s[i]
        root = np.sqrt(np.maximum(self.v[i] ** 2 + 2.0 * self._accel(i) * d, 0.0))
        return self.t[i] + 2.0 * d / np.maximum(self.v[i] + root, 1e-300)

    def step_feed(self, s) -> tuple[np.ndarray, np.ndarray]:
        """Feed of a step starting at arc length s (distance planned for the next period / T),
        and whether that step reaches the end."""
        t = self.time_at_s(s)
        final = t + self.period >= self.t[-1] * (1.0 - 1e-12)
        return (self.s_at_time(t + self.period) - s) / self.period, final


def _limited_passes(s: np.ndarray, cap: np.ndarray, amax: float) -> np.ndarray:
    """Largest v <= cap with |d(v^2)/ds| <= 2 amax: forward and backward passes, vectorised.

    v^2 may grow by 2 amax ds, so the forward pass is v_i^2 = min_{j<=i} (cap_j^2 + 2 amax (s_i - s_j)):
    a running minimum of cap_j^2 - 2 amax s_j. The backward pass is its mirror image.
    """
    if not np.isfinite(amax):
        return cap.copy()
    c2 = cap * cap
    fwd = np.minimum.accumulate(c2 - 2.0 * amax * s) + 2.0 * amax * s
    back = (np.minimum.accumulate((c2 + 2.0 * amax * s)[::-1]))[::-1] - 2.0 * amax * s
    return np.sqrt(np.clip(np.minimum(fwd, back), 0.0, None))


def feed_schedule(curve: Nurbs, feed: float, period: float, *, eps: float = 1e-3,
                  amax: float = np.inf, v_start: float = 0.0, v_end: float = 0.0) -> FeedSchedule:
    """Feed along the curve: min(feed, chord-error limit, normal-acceleration limit), then
    acceleration-limited transitions (forward/backward passes) and the resulting time law.

    Chord error: a chord c on radius rho deviates rho - sqrt(rho^2 - c^2/4); keeping that <= eps gives
    c <= 2 sqrt(2 rho eps - eps^2) (~ sqrt(8 rho eps)), so V <= c / T. Normal acceleration: V <= sqrt(amax rho).
    The radius used at each point is the tightest within one full-feed step either side. With
    amax = inf the feed jumps and v_start / v_end are ignored.
    """
    if not (feed > 0 and period > 0 and eps > 0 and amax > 0 and v_start >= 0 and v_end >= 0):
        raise PlanningError(f"feed, period, eps, amax must be > 0 and end speeds >= 0, got feed={feed}, "
                            f"period={period}, eps={eps}, amax={amax}, v_start={v_start}, v_end={v_end}",
                            where="nurbs interpolation")
    length = curve.length
    step_max = feed * period
    n = int(min(max(np.ceil(length / (0.25 * step_max)), 64), 2_000_000))
    s = np.linspace(0.0, length, n + 1)
    kappa = curve.curvature(curve.table.u_at(s, polish=0))
    half = int(np.ceil(step_max / (length / n))) + 1
    from scipy.ndimage import maximum_filter1d  # scipy on first use: `flowmc validate` starts without it

    kappa = maximum_filter1d(kappa, 2 * half + 1, mode="nearest")
    with np.errstate(divide="ignore", invalid="ignore"):
        rho = np.where(kappa > 0, 1.0 / kappa, np.inf)
        chord = np.where(rho > 0.5 * eps, 2.0 * np.sqrt(np.maximum(2.0 * rho * eps - eps * eps, 0.0)), np.inf)
        cap = np.minimum(np.minimum(feed, chord / period), np.sqrt(amax * rho))
    if np.isfinite(amax):
        cap[0] = min(cap[0], v_start)
        cap[-1] = min(cap[-1], v_end)
    v = _limited_passes(s, cap, amax)
    vsum = v[1:] + v[:-1]
    if np.any(vsum <= 0):
        raise PlanningError("feed schedule stalls (zero speed over a grid interval)", where="nurbs interpolation")
    t = np.concatenate([[0.0], np.cumsum(2.0 * np.diff(s) / vsum)])
    return FeedSchedule(s, cap, v, t, float(period))


@dataclass(frozen=True, eq=False)
class TaylorSteps:
    """Setpoints of the Taylor interpolator: points (N, dim), parameters u (N,), the feed ``feed[k]``
    commanded for the step from point k to k+1 (N-1,), and the fixed-point sweeps it took."""

    points: np.ndarray
    u: np.ndarray
    feed: np.ndarray
    period: float
    sweeps: int


def _taylor_step(curve: Nurbs, sched: FeedSchedule, u: np.ndarray, corrector: int):
    """One step from each u (vectorised): Taylor predictor, then ``corrector`` Newton steps on the chord.

    A step the schedule says reaches the end goes to the curve's end, its feed = chord / T.
    Returns (points at u, parameter increments, commanded feeds).
    """
    pts, d1, d2 = curve.evaluate(u, 2)
    feed, final = sched.step_feed(curve.table.s_at(u, exact=False))
    ds = feed * sched.period
    sp2 = np.einsum("ij,ij->i", d1, d1)
    du = ds / np.sqrt(sp2) - ds * ds * np.einsum("ij,ij->i", d1, d2) / (2.0 * sp2 * sp2)
    for _ in range(int(corrector)):
        q, q1 = curve.evaluate(u + du, 1)
        diff = q - pts
        chord = np.sqrt(np.einsum("ij,ij->i", diff, diff))
        slope = np.einsum("ij,ij->i", diff, q1) / np.where(chord > 0, chord, 1.0)
        ok = slope > 0
        du = du - np.where(ok, (chord - ds) / np.where(ok, slope, 1.0), 0.0)
    if final.any():
        du = np.where(final, curve.u1 - u, du)
        end = curve.evaluate([curve.u1])[0][0]
        feed = np.where(final, np.linalg.norm(end - pts, axis=1) / sched.period, feed)
    return pts, du, feed, final


def _newton_update(u: np.ndarray, du: np.ndarray, resid: np.ndarray, u_end: float) -> np.ndarray:
    """One Newton step on the block's equations u_{k+1} = u_k + step(u_k) (u_0 fixed).

    The correction e solves e_{k+1} = (1 + step'(u_k)) e_k + r_k, r_k the residuals, step' by finite
    differences along the block; the recurrence's solution is a cumulative product and sum.
    """
    x = u[:-1]
    gap = np.gradient(x) if len(x) > 1 else np.ones(1)
    slope = np.where(gap > 0, np.gradient(du) / np.where(gap > 0, gap, 1.0), 0.0) if len(x) > 1 else np.zeros(1)
    m = np.clip(1.0 + slope, 0.5, 2.0)
    g = np.concatenate([[1.0], np.cumprod(m)])  # g_k = prod_{j<k} m_j
    e = g[1:] * np.cumsum(resid / g[1:])
    return np.concatenate([[u[0]], np.minimum(u[1:] + e, u_end)])


def taylor_steps(curve: Nurbs, feed: float, period: float, *, eps: float = 1e-3, amax: float = np.inf,
                 corrector: int = 1, v_start: float = 0.0, v_end: float = 0.0,
                 block: int = 1024, schedule: FeedSchedule | None = None) -> TaylorSteps:
    """Interpolate a NURBS at period T by the second-order Taylor update with a chord corrector.

    Step k from u_k with feed V_k (the schedule's distance for the next period, at u_k's arc length):
        u* = u_k + V T/|C'| - (V T)^2 (C'.C'')/(2 |C'|^4)                   (predictor)
        u_{k+1} = u* - (|C(u*) - C(u_k)| - V T) / (d/du |C(u) - C(u_k)|)(u*)  (corrector: one Newton step)
    ``corrector`` is the number of Newton steps (True = 1, False = 0: predictor only); one brings the
    test curve below 1e-6 relative, a second helps on curves whose radius is near the step length.
    The recurrence is sequential. It is solved block by block as the fixed point of
    u_{k+1} = u_b + sum_{b<=j<=k} step(u_j), starting from the planned time law and sweeping the whole
    block at once (two batched curve evaluations per sweep) until no parameter moves by more than
    1e-14 of the domain: the result is the sequential recurrence's, to rounding. The last step lands
    exactly on the curve's end.
    """
    sched = schedule or feed_schedule(curve, feed, period, eps=eps, amax=amax, v_start=v_start, v_end=v_end)
    budget.check("setpoints", sched.duration / period + 1,
                 what=f"a NURBS curve of {sched.duration:.6g} s at a {period * 1e3:g} ms period",
                 change="raise the feed, or lengthen the machine's period")
    tol = 1e-14 * (curve.u1 - curve.u0)
    us, feeds = [np.array([curve.u0])], []
    u_cur, t_cur, sweeps = curve.u0, 0.0, 0
    while True:
        # starting guess: where the time law puts the next block of setpoints
        n = int(min(block, np.ceil((sched.duration - t_cur) / period) + 8))
        t_next = t_cur + period * np.arange(1, n + 1)
        u = np.concatenate([[u_cur], curve.table.u_at(sched.s_at_time(t_next), polish=0)])
        for _ in range(100):
            _, du, f, final = _taylor_step(curve, sched, u[:-1], corrector)
            sweeps += 1
            new = np.minimum(u[:-1] + du, curve.u1)
            if float(np.max(np.abs(new - u[1:]))) <= tol:
                break
            u = _newton_update(u, du, new - u[1:], curve.u1)
        else:
            raise PlanningError("Taylor interpolation did not converge", where="nurbs interpolation")
        stop = np.flatnonzero(final)
        if len(stop):
            k = int(stop[0]) + 1
            u = u[:k + 1]
            u[-1] = curve.u1
            us.append(u[1:])
            feeds.append(f[:k])
            break
        us.append(u[1:])
        feeds.append(f)
        u_cur = float(u[-1])
        t_cur = float(sched.time_at_s(curve.table.s_at(np.array([u_cur]), exact=False))[0])
    u_all = np.concatenate(us)
    points = curve.evaluate(u_all, 0)[0]
    return TaylorSteps(points, u_all, np.concatenate(feeds), float(period), sweeps)


def interpolate(curve: Nurbs, feed: float, period: float, **options) -> np.ndarray:
    """Setpoints (N, dim) at period T from the curve's start to exactly its end (see ``taylor_steps``)."""
    return taylor_steps(curve, feed, period, **options).points


def feed_fluctuation(steps: TaylorSteps, curve: Nurbs | None = None, measure: str = "chord") -> np.ndarray:
    """|L_k/T - V_k| / V_k per step, L_k the chord (``measure="chord"``) or the arc length (``"arc"``) of step k."""
    if measure == "chord":
        lk = np.linalg.norm(np.diff(steps.points, axis=0), axis=1)
    elif measure == "arc":
        if curve is None:
            raise ValueError("measure='arc' needs the curve")
        lk = curve._speed_integral(steps.u[:-1], steps.u[1:])
    else:
        raise ValueError(f"measure must be 'chord' or 'arc', got {measure!r}")
    return np.abs(lk / steps.period - steps.feed) / steps.feed


def chord_errors(curve: Nurbs, u: np.ndarray, samples: int = 16) -> np.ndarray:
    """Per step: largest distance from the curve between u_k and u_k+1 to the chord [C(u_k), C(u_k+1)].

    The curve piece is sampled at ``samples`` parameters and the largest distance refined by a
    parabola through the best sample and its neighbours.
    """
    u = np.asarray(u, dtype=float)
    a, b = u[:-1], u[1:]
    frac = np.linspace(0.0, 1.0, samples + 1)
    uu = a[:, None] + (b - a)[:, None] * frac[None, :]
    q = curve.evaluate(uu.ravel(), 0)[0].reshape(len(a), samples + 1, -1)
    p0 = q[:, :1, :]
    axis = q[:, -1:, :] - p0
    rel = q - p0
    len2 = np.maximum(np.sum(axis * axis, axis=-1, keepdims=True), 1e-300)
    along = np.clip(np.sum(rel * axis, axis=-1, keepdims=True) / len2, 0.0, 1.0)
    dist = np.linalg.norm(rel - along * axis, axis=-1)
    i = np.clip(np.argmax(dist, axis=1), 1, samples - 1)
    r = np.arange(len(a))
    y0, y1, y2 = dist[r, i - 1], dist[r, i], dist[r, i + 1]
    den = y0 - 2.0 * y1 + y2
    peak = np.where(den < 0, y1 - 0.125 * (y2 - y0) ** 2 / np.where(den < 0, den, -1.0), y1)
    return np.maximum(peak, dist.max(axis=1))
