"""Programmed arcs reshaped within the tolerance band so that per-axis acceleration limits allow more speed.

Why: on an arc the speed is held near v = sqrt(1 / (kappa max_i |N_i| / A_i)): the normal acceleration
v^2 kappa loads the axis the normal N points along. A circle loads one axis fully wherever its normal is
parallel to an axis and each only 1/sqrt(2) where the normal is diagonal, so its time law slows down four times
a turn. A curve flatter where the normal is parallel to an axis and sharper where it is diagonal (a rounded
square) is passed at a steadier, higher speed: up to 1/sqrt(0.900) = 1.054 times the circle's at constant speed
when the band allows it (about r/190 each way); a 0.05 mm band gives about half of that at r = 18 mm, and the
time law on the circle already takes part of it by speeding up at the diagonals (3dtest's circles: 1.2 %).

How: along each curvature-bound stretch of a programmed arc, the curve p(s) is offset along its principal
normal N by d(s), within the band the programmed path allows (both ways: each point of the new curve within
the tolerance of the path near it, each point of the path within it of the curve point nearest it). N is
kept on one side all along, the curvature kappa signed to match: a fitted run's curvature may pass through
zero, where the principal normal flips and offsets along it would zigzag (the spiral's first turn, whose fit
wiggles: reshaped from there, the plan was 89 ms slower). To first order the new curvature is kappa + kappa^2 d
+ d''. A linear program (scipy's HiGHS) chooses d to lower the
per-axis load kappa max_i |N_i| / A_i by a share g below its largest value within pi/8 of turning, g weighted by
the time spent there and changing slowly along the stretch, with a small price on |d''| (without it the program
picks any d the constraints at its points allow, rippling between them) and a share of the time a shorter path
saves (inward, the length falls by kappa d per mm); d and d' are zero at the stretch's
ends, so it joins its neighbours with the same position and tangent. The offset curve is a clamped cubic spline
through the offset points on the curve's own parameter, checked both ways against the programmed path (where it
misses the tolerance, the band is halved there and the program solved again, up to _NARROWINGS times; then the
offset is halved all along, then the stretch left as it was: one miss 10 mm from a spiral's end had halved a
1,600 mm stretch). ``faster_reshaped`` keeps the stretches the time law passes faster, and only if the whole
plan is faster.

Literature: the axis limits, not the programmed shape, choose the curve within the tolerance, as in Tajima and
Sencer, "Kinematic corner smoothing for high speed machine tools", Int. J. Machine Tools and Manufacture 108
(2016), and in the racing line of minimum-time vehicle manoeuvring (Kapania, Subosits and Gerdes, J. Dynamic
Systems, Measurement and Control 138 (2016) 091005); per-axis rather than path limits as in Beudaert,
Lavernhe and Tournier, "Feedrate interpolation with axis jerk constraints on 5-axis NURBS and G1 tool path",
Int. J. Machine Tools and Manufacture 57 (2012). Fitted runs of short lines (flowmc.motion.smoothing) whose net
turning is 1.5 pi or more are reshaped too, each stretch whole: held at both ends every _PART mm, a spiral's
rounded squares (a quarter turn each, 75 mm at r = 48 mm) had no room. Their band both ways is the lines', so
where the chords sag it is narrower (4 mm lines at r = 48 mm: about 0.03 mm either side of the curve through
their middle). Near a fitted run's ends its curvature swings with the lines: there the program works from the
load's mean over about a line (``_line_mean``), so it flattens the swings, and short gaps between bound samples
are bridged (``_bridged``; spiral.ngc past its plunge: reshaped from 106.8 mm, not 118.8, 21.613 -> 21.603 s).

Only for acceleration-limited (trapezoid) plans: the joins are tangent-continuous, not curvature-continuous.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING, Callable

import numpy as np

from flowmc.motion.curve import ARC, PlannedCurve
from flowmc.motion.limits import PathLimits
from flowmc.motion.ranges import window_max
from flowmc.motion.smoothing import Smoothed, fit_tolerance
from flowmc.motion.timelaw import TimeLaw

if TYPE_CHECKING:
    from scipy.interpolate import CubicSpline
    from scipy.spatial import cKDTree

__all__ = ["reshape_curved", "faster_reshaped"]

_SCAN = 0.5  # mm between the samples that find curvature-bound stretches
_BOUND = 0.95  # a sample is curvature-bound where sqrt(A / load) is below this share of the speed cap
_BRIDGE = 1.5  # mm: gaps this short between a fitted run's curvature-bound samples are bridged (``_bridged``)
_MIN_LEN = 2.0  # mm: shorter stretches are left alone
_MIN_TURN = 1.5 * math.pi  # and so are arcs turning less: with both ends held (d = d' = 0) too little is left
# to reshape (the half-turns of benchmarks/planning.py's lines+arcs gained nothing, at 6 s of CPU for 100 of them)
_PART = 40.0  # mm: longer ones are reshaped in parts about this long
_TURN_STEP = 0.08  # radians of turning between the linear program's points at most
_STEP_MAX = 0.5  # mm between them at most
_STEP_MIN = 0.02  # and at least (the step their spacing is worked out at)
_REACH_TURN = math.pi / 8  # the load is lowered below its largest value within this much turning either way
_WINDOW_MAX = 40.0  # mm: and at most this far either way
_GAIN_MAX = 0.3  # most share the load is lowered by
_GAIN_SLOPE = 0.05  # most change of that share per 2 _REACH_TURN of turning (so the speed can follow it)
_BENDING = 0.05  # the price of bending the offset, as a share of the load it may lower
_SHORTER = 0.35  # share of the time a shorter path saves (to first order) that the linear program counts: the
# speed follows the largest load near a point, not its own (spiral: 0.25-0.5 alike, 21.622 -> 21.613 s; 1.0 slower)
_MEAN_LEN = 4.0  # mm either way of a point that a fitted run's load is averaged over (spiral.ngc's lines are 4 mm)
_MEAN_TURN = 0.12  # and radians of turning at most (so at a small radius, a little more than a line's 4.5 degrees)
_BAND_SHARE = 0.96  # of the tolerance the linear program plans for; the check holds the whole tolerance
_CHECK_STEP = 0.01  # mm between the points the band and the deviation are worked out from
_MARGIN = 1.0  # mm of path either side of a stretch that its check takes in
_NARROWINGS = 3  # times a stretch's band is halved where its check fails, before its offset is halved all along
_NARROW_REACH = 2.0  # mm either side of each point that fails the check where the band is halved
_ONE_WAY = 0.9  # a fitted run is reshaped only if its net turning is this share of its total or more: a Gosper
# curve's curls (flowsnake) net 1.5 pi and more, a rounded square is nothing to them, and their linear program took
# 2 s (flowsnake.ngc) to 90 s (2,401 lines 0.0143 mm long) for no gain; a spiral's is about 1
_LEAST_SHARE = 0.05  # of the curve's length the stretches must make up to be reshaped at all: every trial law plans
# the whole curve (3D_Chips' fitted full turns, 1.2 % of it, gained 14 ms of 146 s for about 5 s of CPU)


def faster_reshaped(sm: Smoothed, raw: PlannedCurve, limits: PathLimits, tolerance: float,
                    laws_of: Callable[[PlannedCurve], Callable[[None], TimeLaw]]
                    ) -> tuple[Smoothed, tuple[TimeLaw, Callable] | None]:
    """``sm`` with the stretches ``reshape_curved`` reshapes that its time law (``laws_of(curve)(None)``) passes
    faster than before, if the whole is faster too; ``sm`` itself otherwise (``raw``: the programmed path as
    a curve, ``raw_curve``). With it, the time law of the curve returned and its ``laws_of`` where they were
    worked out (None where nothing was found to reshape), so the caller need not lay them out again."""
    tol_fit = fit_tolerance(limits, tolerance)
    found = reshape_curved(sm.curve, raw, sm.stop_u, sm.seg_feed, limits, tol_fit)
    if not found:
        return sm, None
    laws = laws_of(sm.curve)
    law = laws(None)
    before = _clock(law, [sm.curve.length])[0]
    for _ in range(3):  # all found, then those that gained (a stretch's neighbours change speed too), then again
        curve = _splice(sm.curve, found)
        new_laws = laws_of(curve)
        new = new_laws(None)
        faster = [f for f in found if np.diff(_clock(new, f[3]))[0] < np.diff(_clock(law, f[3]))[0]]
        if len(faster) == len(found):
            if _clock(new, [curve.length])[0] < before:
                return replace(sm, curve=curve, deviation=max(sm.deviation, max(f[4] for f in found))), (new, new_laws)
            break
        if not faster:
            break
        found = faster
    return sm, (law, laws)


def _clock(law: TimeLaw, u) -> np.ndarray:
    """The time law's time (waits left out) at curve parameters u."""
    v = np.sqrt(np.maximum(law.y, 0.0))
    t = np.r_[0.0, np.cumsum(2.0 * np.diff(law.s) / np.maximum(v[1:] + v[:-1], 1e-300))]
    return np.interp(np.asarray(u, dtype=float), law.u, t)


def reshape_curved(curve: PlannedCurve, raw: PlannedCurve, stop_u: np.ndarray, seg_feed: np.ndarray,
                   limits: PathLimits, tol: float) -> list:
    """Curvature-bound stretches of ``curve`` reshaped within ``tol`` of the programmed path ``raw``
    (parameterised by programmed arc length); ``seg_feed``: each programmed segment's path-speed cap.
    Returns (ka, kb, spline, (ua, ub), deviation) per stretch reshaped: the spline, on the curve's own
    parameter from ua, replaces intervals ka .. kb."""
    cols = list(limits.cols)
    inv_a = np.zeros(3)
    inv_a[cols] = 1.0 / limits.amax[cols]
    n_scan = max(2, int(math.ceil(curve.length / _SCAN)) + 1)
    u = np.linspace(0.0, curve.length, n_scan)
    k = curve.interval_at(u)
    tangent, d2 = curve.evaluate(u, 2, index=k, lowest=1)
    kappa, normal = _curvature_of(tangent, d2)
    load = kappa * np.max(np.abs(normal) * inv_a, axis=1)
    cap = np.minimum(seg_feed[curve.segment_at(u)], limits.along(tangent)[0])
    bound = np.sqrt(1.0 / np.maximum(load, 1e-300)) < _BOUND * cap
    on_arc = curve.kind[k] == ARC
    stops = np.unique(np.asarray(stop_u, dtype=float))

    def arc_turn(ka: int, kb: int) -> float:
        return float(np.sum(np.abs(curve.dphi[ka:kb + 1]) * (curve.u1[ka:kb + 1] - curve.u0[ka:kb + 1])))

    # fitted runs by their net turning (the integral of kappa t x N): a wave of short lines turns both ways and
    # has no rounded square to become
    unit = tangent / np.maximum(np.linalg.norm(tangent, axis=1), 1e-300)[:, None]
    bend = np.cross(unit, kappa[:, None] * normal)

    def fitted_turn(ka: int, kb: int) -> float:  # 0 unless nearly all of it turns one way (_ONE_WAY)
        inside = bend[np.searchsorted(u, curve.u0[ka]):np.searchsorted(u, curve.u1[kb])]  # u ascends: a slice
        net = float(np.linalg.norm(np.sum(inside, axis=0)))
        return net * (u[1] - u[0]) if net >= _ONE_WAY * float(np.sum(np.linalg.norm(inside, axis=1))) else 0.0

    # arcs in parts of about _PART mm; fitted runs whole (a spiral's rounded squares reach over a quarter turn)
    pieces = sorted([(ka, kb, False) for ka, kb in _pieces(curve, u, bound & on_arc, stops, arc_turn, _PART)]
                    + [(ka, kb, True) for ka, kb in _pieces(curve, u, _bridged(bound, ~on_arc), stops, fitted_turn, math.inf)])
    if sum(curve.u1[kb] - curve.u0[ka] for ka, kb, _ in pieces) < _LEAST_SHARE * curve.length:
        return []
    found = []
    for ka, kb, fitted in pieces:  # in order: _splice needs it
        got = _reshape_stretch(curve, raw, ka, kb, inv_a, tol, fitted)
        if got is not None:
            found.append((ka, kb, got[0], (float(curve.u0[ka]), float(curve.u1[kb])), got[1]))
    return found


def _bridged(bound: np.ndarray, fitted: np.ndarray) -> np.ndarray:
    """``bound & fitted`` with gaps of at most _BRIDGE mm between its runs filled where ``fitted``: a fitted run's
    curvature swings with the lines near its ends, so its bound samples flicker there (spiral.ngc's first turn
    past the plunge: bound from 107 mm, 1 mm gaps at 110, 114 and 118 mm, and reshaped from 118.8 mm only)."""
    mask = bound & fitted
    edges = np.flatnonzero(np.diff(np.r_[0, mask.astype(int), 0]))
    gap_a, gap_b = edges[1:-1:2], edges[2::2]  # each gap: samples gap_a .. gap_b - 1
    other = np.r_[0, np.cumsum(~fitted)]
    short = (gap_b - gap_a <= round(_BRIDGE / _SCAN)) & (other[gap_b] == other[gap_a])  # and all on fitted runs
    fill = np.zeros(len(mask) + 1, dtype=int)
    np.add.at(fill, gap_a[short], 1)
    np.add.at(fill, gap_b[short], -1)
    return mask | (np.cumsum(fill)[:-1] > 0)


def _pieces(curve: PlannedCurve, u: np.ndarray, bound: np.ndarray, stops: np.ndarray,
            turned: Callable[[int, int], float], part: float) -> list[tuple[int, int]]:
    """Intervals (ka, kb) to reshape: runs of ``bound`` samples u, cut at stops, snapped to the curve's interval
    boundaries, at least _MIN_LEN long and turning (``turned``) _MIN_TURN or more, in parts about ``part`` mm
    long (each kept or not on its own), cut between intervals."""
    edges = np.flatnonzero(np.diff(np.r_[0, bound.astype(int), 0]))
    ends: list[tuple[float, float]] = []
    for ua, ub in zip(u[edges[::2]].tolist(), u[edges[1::2] - 1].tolist()):
        cuts = stops[(stops > ua) & (stops < ub)].tolist()
        ends += zip([ua, *cuts], [*cuts, ub])
    if not ends:
        return []
    lo, hi = np.array(ends).T
    ka, kb = curve.interval_at(lo), curve.interval_at(hi)  # every stretch's at once: a lookup per stretch costs more
    ka += curve.u0[ka] < lo - _SCAN  # intervals that reach well past the bound samples stay
    kb -= curve.u1[kb] > hi + _SCAN
    keep = kb >= ka
    ka, kb = ka[keep], kb[keep]
    long = curve.u1[kb] - curve.u0[ka] >= _MIN_LEN
    pieces = []
    for a, b in zip(ka[long].tolist(), kb[long].tolist()):
        if turned(a, b) < _MIN_TURN:
            continue
        parts = max(1, int(round((curve.u1[b] - curve.u0[a]) / part)))
        cut = np.searchsorted(curve.u0[a:b + 1], np.linspace(curve.u0[a], curve.u1[b], parts + 1)[1:-1]) + a
        bounds = np.unique(np.r_[a, cut, b + 1])
        pieces += [(int(x), int(y) - 1) for x, y in zip(bounds[:-1], bounds[1:])]
    return pieces


def _curvature(curve: PlannedCurve, u: np.ndarray, within=None) -> tuple[np.ndarray, np.ndarray]:
    """Curvature and unit principal normal at curve parameters u (normal 0 where the curve is straight);
    ``within``: (ka, kb), the intervals u lies in (so a stretch's last point is evaluated on its last interval)."""
    return _curvature_of(*_evaluate(curve, u, 2, within)[1:])


def _curvature_of(d1: np.ndarray, d2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``_curvature`` from the first and second derivatives."""
    speed = np.linalg.norm(d1, axis=1)
    t = d1 / speed[:, None]
    kvec = (d2 - np.einsum("ij,ij->i", d2, t)[:, None] * t) / speed[:, None] ** 2
    kappa = np.linalg.norm(kvec, axis=1)
    return kappa, kvec / np.maximum(kappa, 1e-300)[:, None]


def _evaluate(curve: PlannedCurve, u: np.ndarray, order: int, within=None) -> list[np.ndarray]:
    index = None if within is None else np.clip(curve.interval_at(u), *within)
    return curve.evaluate(u, order, index=index)


def _grid(curve: PlannedCurve, ka: int, kb: int) -> np.ndarray:
    """Parameters over [ua, ub] at most _TURN_STEP of turning and _STEP_MAX mm apart."""
    ua, ub = curve.u0[ka], curve.u1[kb]
    fine = np.linspace(ua, ub, max(3, int(math.ceil((ub - ua) / _STEP_MIN)) + 1))
    kappa, _ = _curvature(curve, fine, (ka, kb))
    density = np.maximum(kappa / _TURN_STEP, 1.0 / _STEP_MAX)
    count = np.r_[0.0, np.cumsum(0.5 * (density[1:] + density[:-1]) * np.diff(fine))]
    n = max(8, int(math.ceil(count[-1])))
    return np.interp(np.linspace(0.0, count[-1], n + 1), count, fine)


def _reshape_stretch(curve: PlannedCurve, raw: PlannedCurve, ka: int, kb: int, inv_a: np.ndarray,
                     tol: float, fitted: bool = False):
    """(spline, deviation) of the stretch over intervals ka .. kb reshaped, or None where nothing is gained or the
    check fails. ``fitted``: a fitted run of short lines, whose load is taken as its mean over about a line
    (``_line_mean``)."""
    from scipy.interpolate import CubicSpline  # on first use, as jerk_retime: a plan without such arcs needs none
    from scipy.optimize import linprog
    from scipy.sparse import coo_matrix
    from scipy.spatial import cKDTree

    ua, ub = float(curve.u0[ka]), float(curve.u1[kb])
    u = _grid(curve, ka, kb)
    p, d1 = _evaluate(curve, u, 1, (ka, kb))
    kappa, normal = _curvature(curve, u, (ka, kb))
    speed = np.linalg.norm(d1, axis=1)
    # the normal on one side all along (a fitted run's curvature may pass through zero, where the principal
    # normal flips), with the curvature signed to match
    tangent = d1 / speed[:, None]
    side = np.cross(np.sum(np.cross(tangent, kappa[:, None] * normal), axis=0), tangent)
    flip = np.einsum("ij,ij->i", normal, side) < 0.0
    normal[flip] *= -1.0
    signed = np.where(flip, -kappa, kappa)
    s = np.r_[0.0, np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(u))]
    n = len(u)
    m = np.max(np.abs(normal) * inv_a, axis=1)
    load = kappa * m
    # the band: where along N the programmed path lies from each point, and how far either way d may go
    pu = curve.programmed_u(np.array([ua, ub]))
    programmed = _dense(raw.points, pu[0], pu[1])  # the path the stretch stands for
    around = _dense(raw.points, max(0.0, pu[0] - _MARGIN), min(raw.length, pu[1] + _MARGIN))
    near = cKDTree(around)
    lo, hi = _band(p, normal, d1 / speed[:, None], around, near, programmed, _BAND_SHARE * tol)
    lo[:2] = hi[:2] = lo[-2:] = hi[-2:] = 0.0
    turn = np.r_[0.0, np.cumsum(0.5 * (kappa[1:] + kappa[:-1]) * np.diff(s))]
    lo_w = np.maximum(np.searchsorted(turn, turn - _REACH_TURN), np.searchsorted(s, s - _WINDOW_MAX))
    hi_w = np.minimum(np.searchsorted(turn, turn + _REACH_TURN, side="right"),
                      np.searchsorted(s, s + _WINDOW_MAX, side="right")) - 1
    ref = window_max(_line_mean(load, s, turn) if fitted else load, lo_w, np.maximum(hi_w, lo_w))
    # variables: d_0 .. d_n-1, g_0 .. g_n-1, e_0 .. e_n-1; rows: load_k + m_k (kappa_k^2 d_k + (D2 d)_k) <= (1 - g_k) ref_k
    hm, hp = np.diff(s)[:-1], np.diff(s)[1:]
    k = np.arange(1, n - 1)
    c_lo, c_hi = 2.0 / (hm * (hm + hp)), 2.0 / (hp * (hm + hp))
    rows = np.concatenate([k - 1, k - 1, k - 1, k - 1, k - 1])
    cols = np.concatenate([k - 1, k, k + 1, k, n + k])
    vals = np.concatenate([m[k] * c_lo, -m[k] * (c_lo + c_hi), m[k] * c_hi, m[k] * kappa[k] ** 2, ref[k]])
    rhs = ref[k] - m[k] * signed[k]
    # the share changes slowly: |g_k+1 - g_k| <= slope * turning between them (and a little per mm)
    step = _GAIN_SLOPE * (np.diff(turn) / (2 * _REACH_TURN) + np.diff(s) / (4 * _WINDOW_MAX))
    j = np.arange(n - 1)
    r0 = n - 2
    rows = np.concatenate([rows, r0 + j, r0 + j, r0 + n - 1 + j, r0 + n - 1 + j])
    cols = np.concatenate([cols, n + j + 1, n + j, n + j, n + j + 1])
    vals = np.concatenate([vals, np.ones(n - 1), -np.ones(n - 1), np.ones(n - 1), -np.ones(n - 1)])
    rhs = np.concatenate([rhs, step, step])
    # e_k >= |(D2 d)_k|, priced at _BENDING of what lowering the load by that much would gain: d bends only
    # where that pays (a linear program would otherwise pick any d, rippling between its points)
    r1 = r0 + 2 * (n - 1)
    e_at = 2 * n + k
    for sign, r in ((1.0, r1), (-1.0, r1 + n - 2)):
        rows = np.concatenate([rows, *[r + k - 1] * 4])
        cols = np.concatenate([cols, k - 1, k, k + 1, e_at])
        vals = np.concatenate([vals, sign * c_lo, -sign * (c_lo + c_hi), sign * c_hi, -np.ones(n - 2)])
    rhs = np.concatenate([rhs, np.zeros(2 * (n - 2))])
    a_ub = coo_matrix((vals, (rows, cols)), shape=(len(rhs), 3 * n)).tocsr()
    weight = np.gradient(s) * np.sqrt(np.maximum(ref, 1e-300))  # time ~ ds sqrt(load)
    # moved inward by d the path is shorter by kappa d per mm: with time ~ ds sqrt(load), worth 2 kappa d in g's units
    cost = np.r_[-_SHORTER * 2.0 * weight * signed, -weight, _BENDING * weight * m / np.maximum(ref, 1e-300)]
    bounds = np.c_[np.r_[lo, np.zeros(2 * n)], np.r_[hi, np.full(n, _GAIN_MAX), np.full(n, np.inf)]]
    bounds[n:n + 2, 1] = bounds[2 * n - 2:2 * n, 1] = 0.0
    if fitted:  # where the load is above its mean, the share may be negative: those points are not flattened
        bounds[n:2 * n, 0] = -_GAIN_MAX

    def offset(d):  # the stretch moved by d along the normal, with its own tangents kept at both ends
        return CubicSpline(u - ua, p + d[:, None] * normal, axis=0, bc_type=((1, d1[0]), (1, d1[-1])))

    for _ in range(_NARROWINGS + 1):  # where the check fails, the band is narrowed there and the program solved again
        res = linprog(cost, A_ub=a_ub, b_ub=rhs, bounds=bounds, method="highs")
        if res.status != 0 or float(weight @ res.x[n:2 * n]) < 1e-3 * float(weight.sum()) * _GAIN_SLOPE:
            return None
        d = res.x[:n]
        spline = offset(d)
        dev, miss = _deviation(spline, ua, ub, curve, near, programmed, tol)
        if dev <= tol:
            return spline, dev
        miss = np.sort(np.r_[miss, np.inf])
        bounds[:n][miss[np.searchsorted(miss, u - ua - _NARROW_REACH)] <= u - ua + _NARROW_REACH] *= 0.5
    spline = offset(0.5 * d)
    dev = _deviation(spline, ua, ub, curve, near, programmed, tol)[0]
    return (spline, dev) if dev <= tol else None


def _line_mean(load: np.ndarray, s: np.ndarray, turn: np.ndarray) -> np.ndarray:
    """The load's mean over _MEAN_LEN mm and _MEAN_TURN of turning either way of each point. Near a fitted run's
    ends, where its smoothing is cut, its curvature swings with the programmed lines (past spiral.ngc's plunge
    0.0004-0.044 /mm about 0.0197); taken from the load itself, the largest value near a point counts those swings
    as room to spare, and the linear program leaves them; from the mean, it flattens them."""
    area = np.r_[0.0, np.cumsum(0.5 * (load[1:] + load[:-1]) * np.diff(s))]
    lo = np.maximum(np.searchsorted(s, s - _MEAN_LEN), np.searchsorted(turn, turn - _MEAN_TURN))
    hi = np.minimum(np.searchsorted(s, s + _MEAN_LEN, side="right"), np.searchsorted(turn, turn + _MEAN_TURN, side="right")) - 1
    wide = s[hi] - s[lo] > 0.0
    return np.where(wide, (area[hi] - area[lo]) / np.where(wide, s[hi] - s[lo], 1.0), load)


def _band(p: np.ndarray, normal: np.ndarray, tangent: np.ndarray, around: np.ndarray, near: cKDTree,
          programmed: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi): how far along the normal each point may move. Both ways: the point stays within ``tol`` of the
    programmed point nearest it (of ``around``, the path near the stretch), and every programmed point stays
    within ``tol`` of the curve point nearest it (each taken as lying on a line along the curve's tangent)."""
    from scipy.spatial import cKDTree

    _, j = near.query(p)
    lo, hi = _room(around[j] - p, normal, tangent, tol)
    _, k = cKDTree(p).query(programmed)
    lo_r, hi_r = _room(programmed - p[k], normal[k], tangent[k], tol)
    np.maximum.at(lo, k, lo_r)
    np.minimum.at(hi, k, hi_r)
    return np.minimum(lo, 0.0), np.maximum(hi, 0.0)


def _room(r: np.ndarray, normal: np.ndarray, tangent: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Interval of d for which |p + d N - q| <= tol, r = q - p, q's line taken along the tangent."""
    along = np.einsum("ij,ij->i", r, normal)
    side = r - along[:, None] * normal
    side -= np.einsum("ij,ij->i", side, tangent)[:, None] * tangent
    room = np.sqrt(np.maximum(tol * tol - np.einsum("ij,ij->i", side, side), 0.0))
    return along - room, along + room


def _dense(points_of, a: float, b: float) -> np.ndarray:
    return points_of(np.linspace(a, b, _count(b - a)))


def _deviation(spline: CubicSpline, ua: float, ub: float, curve: PlannedCurve, near: cKDTree,
               programmed: np.ndarray, tol: float) -> tuple[float, np.ndarray]:
    """Largest distance, both ways, between the reshaped stretch (with a little of the curve either side) and
    the programmed path it stands for, both as points _CHECK_STEP apart: distances to the nearest point, each
    at most sqrt(d^2 + (step/2)^2) over the distance to the polyline through them (3e-4 mm at 0.05 mm). With it,
    the spline's parameters (from ua) where either distance exceeds ``tol``."""
    from scipy.spatial import cKDTree

    x = np.r_[np.linspace(-min(_MARGIN, ua), 0.0, _count(min(_MARGIN, ua))), np.linspace(0.0, ub - ua, _count(ub - ua)),
              np.linspace(ub - ua, min(curve.length, ub + _MARGIN) - ua, _count(min(curve.length - ub, _MARGIN)))]
    inside = (x >= 0.0) & (x <= ub - ua)
    pts = np.empty((len(x), 3))
    pts[inside] = spline(x[inside])
    pts[~inside] = curve.points(ua + x[~inside])
    out = near.query(pts)[0]
    back, foot = cKDTree(pts).query(programmed)
    miss = np.clip(np.r_[x[out > tol], x[foot[back > tol]]], 0.0, ub - ua)
    return max(float(out.max()), float(back.max())), miss


def _count(length: float) -> int:
    return max(3, int(math.ceil(length / _CHECK_STEP)) + 1)


_FIELDS = ("kind", "coef", "centre", "e1", "e2", "w", "radius", "phi0", "dphi", "rise")


def _splice(curve: PlannedCurve, replaced) -> PlannedCurve:
    """The curve with intervals ka .. kb of each (ka, kb, spline) replaced by the spline's cubics (on the same
    parameter, so nothing else moves)."""
    parts: dict[str, list] = {name: [] for name in (*_FIELDS, "u0", "u1", "pu0", "prate")}
    prev = 0
    for ka, kb, spline, *_ in replaced:
        for name in parts:
            parts[name].append(getattr(curve, name)[prev:ka])
        ua = float(curve.u0[ka])
        u0, u1 = ua + spline.x[:-1], ua + spline.x[1:]
        u1[-1] = curve.u1[kb]
        n = len(u0)
        pu0, pu1 = curve.programmed_u(u0), curve.programmed_u(u1)
        pu1[-1] = curve.pu0[kb] + curve.prate[kb] * (curve.u1[kb] - curve.u0[kb])
        new = {"u0": u0, "u1": u1, "pu0": pu0, "prate": (pu1 - pu0) / (u1 - u0), "kind": np.zeros(n, dtype=np.int8),
               "coef": np.transpose(spline.c[::-1], (1, 0, 2)), "radius": np.zeros(n), "phi0": np.zeros(n),
               "dphi": np.zeros(n), "rise": np.zeros(n)}
        new |= {name: np.zeros((n, 3)) for name in ("centre", "e1", "e2", "w")}
        for name in parts:
            parts[name].append(new[name].astype(getattr(curve, name).dtype))
        prev = kb + 1
    for name in parts:
        parts[name].append(getattr(curve, name)[prev:])
    return PlannedCurve(seg_u0=curve.seg_u0, **{name: np.concatenate(v) for name, v in parts.items()})
