"""Tolerance-bounded smoothing of a program: corners and runs of short segments, within the tolerance.

Why: a controller that rounds each corner on its own, using at most half of each short segment,
crawls through CAM code made of thousands of short lines; LinuxCNC's G64 P Q merges and smooths
across many segments. Here the smoothing works on *runs*, not corners:

1. Every junction that is not smooth enough for the profile gets a zone: how far along the path,
   on each side, a curve within the tolerance would need to turn (the tangent-arc trim
   ``R tan(alpha/2)`` with ``R (1/cos(alpha/2) - 1) = tol``; longer for curvature-continuous joins,
   and ``sqrt(3 tol / dkappa)`` for a curvature jump alone).
2. Zones that overlap (a segment shorter than the two zones at its ends) merge into one run, so a
   run spans as many short segments as it needs, across corners and arcs alike.
3. A lone corner between two lines, when tangent continuity is enough (trapezoid profiles), is
   rounded by the per-axis time-optimal blend, a parabola (``_corner_parabolas``): with every axis
   held to its own acceleration limit it passes a right angle about 1.5 times as fast as the
   tangent arc within the same tolerance (LinuxCNC 2.7+ blends by tangent arcs, Ellenberg). Its corner is
   moved out first (``_outside_corners``: the racing line, outside the band before and after the corner,
   inside at it), so the parabola may be longer and is passed faster; where the turn leaves an axis spare
   and it is quicker, two parabolas, slowing along that axis into the corner. Every other run is replaced
   by a cubic B-spline fitted to the programmed path over the run, with the position, tangent and
   curvature of the path at both ends of the run fixed, so the result is curvature-continuous (G2)
   where it joins the rest of the path and inside. For jerk-limited profiles a lone corner between two
   lines gets the jerk-limited analogue of the parabola instead (``_corner_jerk_blends``: two cubics,
   curvature-continuous), and ``Smoothed.stopped`` carries the same smoothing with those corners stopped at.

The fit is a penalised least-squares B-spline (a P-spline: Eilers and Marx, "Flexible smoothing with
B-splines and penalties", Statistical Science 11, 1996) with a penalty on the second differences of the
control points (about the integral of |p''|^2, the bending: what acceleration limits pay for) or, for
jerk-limited plans, on the third (about the integral of |p'''|^2, the rate of change of curvature: what
per-axis jerk pays for), and on both where a jerk-limited run's waves or zigzags are finer than the
tolerance (flowsnake's Koch curls: bending is the detail to smooth away there). The tolerance is held as
an L-infinity bound by iteratively re-weighting the data points that stray (the approach to
approximation within a given tolerance of Piegl and Tiller, The NURBS Book, 2nd ed. 1997, section 9.4,
with a smoothing penalty instead of knot insertion); it follows the global micro-segment smoothing of
CNC tool paths by curvature-continuous splines, as in Erkorkmaz and Altintas, "High speed CNC system
design. Part I", Int. J. Machine Tools & Manufacture 41 (2001), and Yang and Yau / Bi et al. on G01
fitting within a chord tolerance.

The spline is parameterised by the programmed path's arc length over the run, and every data point
q(u) of the path is held within the tolerance of the curve point p(u) at the same u. That bound
works both ways: every point of the curve is within the tolerance of the path (of q at its u) and
every point of the path within the tolerance of the curve. Between data points the bound grows by
at most |p''| du^2 / 8, which the data spacing keeps negligible. Fits with the bending penalty (fine waves
and zigzags of jerk-limited plans) hold each way on its own, so the curve may slide along the path and use
the band on both sides: each data point within the tolerance of the curve point one Newton step along the
tangent from its u (or of p(u)), and each p(u) within the tolerance of one of the data points _NEAR either
side (flowsnake: the curve comes within 0.035 mm of the path, was 0.030, the path within 0.049 mm of it;
S-curve 5.527 -> 5.488 s of feed).

A run whose fit does not meet the tolerance within the iteration budget is not smoothed: the
planner stops at its corners (reported in ``Smoothed.failed``; none of the benchmark programs needs it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from functools import cached_property

import numpy as np
from scipy.linalg import LinAlgError, get_lapack_funcs

from flowmc.errors import PlanningError
from flowmc.motion.bsplines import RunKnots
from flowmc.motion.curve import POLY, CurveBuilder, PlannedCurve
from flowmc.motion.limits import PathLimits
from flowmc.motion.path import Path
from flowmc.motion.path_columns import CURVE, DWELL, LINE, PathColumns
from flowmc.motion.pieces import REVERSAL, checked_feeds, corner_angle
from flowmc.motion.ranges import MovingMeans, Windows, moving_means, range_medians

__all__ = ["Smoothed", "fit_tolerance", "smooth_path", "raw_curve"]

_EPS_LEN = 1e-9  # mm: shorter segments are dropped
_CURVE_STEP = 1.0  # mm: tabulated curves (ellipse, NURBS) become cubic splines with knots this far apart at most
_G2_STRETCH = 2.0  # a curvature-continuous corner needs this many times the tangent arc's trim
_FLAT = 0.002  # a curve whose normal acceleration at full speed is this share of amax counts as straight
_SPLIT_MOST = 0.6  # two-parabola corner blends slow down along the spare axis by at most this share
_SPLIT_GAIN = 1.0  # ... where their time, by _corner_time, is below this share of one parabola's (at 0.99, 3dtest's
# lettering kept one parabola at a corner where two are 2 ms quicker under the exact time law)
_SHARP = math.radians(30.0)  # corners turning more than this are fitted on their own, with finer knots
_FIT_ITER = 16
_FIT_SETTLE = 6  # iterations that may also smooth more where the tolerance is met with room to spare
_SPARE = 0.6
_RELAX = 1.6
_MIN_SPANS = 10  # a run, however short, has room to turn: six of its control points are held by its ends
_END_FIT = 2.0  # mm of programmed path a free run end takes its direction from
_END_BENT = 0.5 * math.pi  # rad: where that path turns more than this (a tight spiral's centre) a quadratic
_END_TURN = 0.6  # misjudges the end's direction: the span is shortened until it turns at most this
_TOL_SHARE = 0.99  # of the tolerance left for smoothing, after the sampled chords sagitta
_KNOT_TOL = 2.0  # least knot spacing, in tolerances
_KNOT_TOL_FINE = 0.8  # ... for fits with the bending penalty (flowsnake: 5.488 s at 2, 5.406 at 1; with the reach below
# 5.251 at 1, 5.239 at 0.8, 5.289 at 0.6, and the retimed stretch breaks no limit, so it is retimed once)
_KNOT_SEGMENT = 0.4  # knot spacing in a run's typical programmed segment lengths
_KNOT_MAX = 10.0  # most knot spacing, in tolerances
_REFINE_KNOTS = 2  # times a run that misses the tolerance is fitted again with knots twice as dense
_PARAM_PASSES = 3  # refits with the data re-parameterised by arc length along the fitted curve
#: The penalty's difference stencils: second differences ~ the integral of |p''|^2 (bending; for
#: acceleration limits), third ~ of |p'''|^2 (the rate of change of curvature; for jerk limits).
_STENCILS = {2: np.array([1.0, -2.0, 1.0]), 3: np.array([1.0, -3.0, 3.0, -1.0])}
#: Their products s_p s_q (p = 0 .. q) as columns, by stencil length and q: what d^T d adds to the band's column q.
_PRODUCTS = {len(s): [(s[:q + 1] * s[q])[:, None] for q in range(len(s))] for s in _STENCILS.values()}
_ELL = 100.0  # longest smoothing length in knot spans
_ELL_SEGMENTS = 1.5  # initial smoothing length in programmed segment lengths
_ELL_SEGMENTS_JERK = 2.2  # ... for jerk-limited fits: chord ripple in the curvature's slope costs speed as v^3
_STEADY = 0.5  # a trapezoid run whose net turning is at least this share of its total turning is fitted with the
# third-difference penalty (its curvature is steady: bending is not what there is to smooth away; see _steady)
_BEND = 50.0  # jerk-limited fits of waves and zigzags of fine detail also penalise bending, at this share of
# l^4 (an order-2 smoothing length 2.7 times l): flowsnake's S-curve 5.829 -> 5.527 s of feed (1 -> 5.785, 10 -> 5.701,
# 30 -> 5.617, 40-60 5.527-5.536; at 100 a retimed stretch broke a limit and was dropped)
_FINE_DETAIL = 1.0  # ... where the run's typical programmed segment is shorter than this many tolerances (flowsnake's
# 0.014 mm lines; raster's 0.25 mm waves are its geometry, and their S-curve took 27.171 -> 27.679 s with the bending)
_NEAR = 3  # data points either side whose distance to the curve at a data point's parameter bounds the curve's
# distance to the path, in fits that let the curve slide along the path (those with the bending penalty)
_ELL_TOL = 20.0  # and at least this many tolerances: details below the tolerance are smoothed away
_BLUR = 41  # control points over which the smoothing's local scale is evened out
_REACH = 2.0  # smoothing lengths either side of a stray point over which smoothing is reduced
_REACH_FINE = 0.35  # ... in fits with the bending penalty: the Koch curls' tips that bind are short, and smoothing
# kept about them keeps their change of curvature low (flowsnake's S-curve: 5.406 s at 2, 5.357 at 1, 5.251 at 0.35)


@dataclass(frozen=True, eq=False)
class Smoothed:
    """The curve to plan along and what the time law needs besides it.

    ``stop_u``: where the tool must be at rest (program start and end, tool or spindle changes,
    dwells, reversals, corners of runs that could not be fitted), with ``stop_dwell`` seconds to wait
    and ``stop_segment`` the dwell segment that owns the wait (-1 for none). ``seg_feed``: each
    programmed segment's path-speed cap. Counts: ``blends`` corner blends, ``fitted`` spline
    runs, ``failed`` runs left unsmoothed; ``deviation`` the largest distance between a fitted curve
    and the programmed path (both ways, see the module docstring); ``blend_u`` the curve parameter
    range (n, 2) of every lone corner's blend; ``stopped`` (jerk-limited smoothing with blends only) the same
    smoothing with those corners stopped at instead.
    """

    curve: PlannedCurve
    stop_u: np.ndarray
    stop_dwell: np.ndarray
    stop_segment: np.ndarray
    seg_feed: np.ndarray
    blends: int
    fitted: int
    failed: int
    deviation: float
    blend_u: np.ndarray
    stopped: Smoothed | None = None


_PBSV = get_lapack_funcs("pbsv", dtype=np.float64)


def _solved(band: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """x with A x = rhs, A symmetric positive definite in upper band form ``band``: LAPACK's pbsv, as
    scipy.linalg.solveh_banded calls it (the same numbers), without its argument checks (about 5 us of each
    solve, of which a fit makes one an iteration)."""
    _, x, info = _PBSV(band, rhs, lower=0, overwrite_ab=1, overwrite_b=1)
    if info:
        raise LinAlgError(f"pbsv failed (info {info}): not positive definite")
    return x


# ---------------------------------------------------------------- the programmed path as a curve

@dataclass
class _Elements:
    """The path's moving segments as curve stretches, in order: segment index, u range, and the unit tangent
    and curvature vector at each end."""

    seg: np.ndarray
    u0: np.ndarray
    u1: np.ndarray
    is_line: np.ndarray
    t0: np.ndarray
    t1: np.ndarray
    k0: np.ndarray
    k1: np.ndarray


def _turning(chords: np.ndarray) -> float:
    """Net angle, in radians, between the first and last of ``chords``: a steady curve's turning (a zigzag's
    corners, which a quadratic averages out, cancel)."""
    u = chords[np.linalg.norm(chords, axis=1) > 1e-12]
    u = u / np.linalg.norm(u, axis=1, keepdims=True)
    return float(np.arccos(np.clip(u[0] @ u[-1], -1.0, 1.0))) if len(u) > 1 else 0.0


def _unit_and_curvature(d1: np.ndarray, d2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    speed = np.linalg.norm(d1, axis=1, keepdims=True)
    t = d1 / np.maximum(speed, 1e-300)
    normal = d2 - np.einsum("ij,ij->i", d2, t)[:, None] * t
    return t, normal / np.maximum(speed, 1e-300) ** 2


def raw_curve(path: Path) -> tuple[PlannedCurve, _Elements]:
    """The programmed path as a PlannedCurve (lines, arcs, tabulated curves as cubic splines), unsmoothed.

    Read from the path's columns: lines and arcs all at once, tabulated curves one by one."""
    cols = path.columns
    lengths = np.array(cols.lengths, dtype=float)
    lengths[lengths <= _EPS_LEN] = 0.0
    seg_u0 = np.concatenate([[0.0], np.cumsum(lengths)[:-1]])
    moving = np.flatnonzero(lengths > 0)
    if not len(moving):
        raise PlanningError("the path does not move (every segment has zero length)", where="path")
    kind = cols.kind[moving]
    rows_of = np.ones(len(moving), dtype=int)  # curve intervals each moving segment becomes
    b = CurveBuilder()
    lines = moving[kind == LINE]
    if len(lines):
        coef = np.zeros((len(lines), 4, 3))
        coef[:, 0] = cols.start[lines]
        coef[:, 1] = (cols.end[lines] - cols.start[lines]) / lengths[lines, None]
        b.polys(np.c_[seg_u0[lines], seg_u0[lines] + lengths[lines]], coef)
    geo = cols.arcs
    arc = np.flatnonzero(lengths[geo.rows] > 0)
    if len(arc):
        rows, length = geo.rows[arc], lengths[geo.rows[arc]]
        eye = np.eye(3)
        b.arcs(seg_u0[rows], seg_u0[rows] + length, length, cols.center[rows], eye[geo.iu[arc]], eye[geo.iv[arc]],
               eye[geo.normal[arc]], geo.r0[arc], geo.angle0[arc], geo.sweep[arc] / length, geo.rise[arc] / length)
    for k in moving[kind == CURVE]:  # ellipses and NURBS, tabulated as cubic splines
        from scipy.interpolate import CubicSpline  # here: scipy.interpolate costs a fresh process about 0.3 s of CPU
        seg, u0, length = cols.curves[k], float(seg_u0[k]), float(lengths[k])
        n = int(max(4, math.ceil(length / min(_CURVE_STEP, 0.25 * seg.min_radius))))
        s = np.linspace(0.0, length, n + 1)
        tan = seg.tangent_at(np.array([0.0, length]))
        cs = CubicSpline(s, seg.point_at(s), axis=0, bc_type=((1, tan[0]), (1, tan[1])))
        b.polys(u0 + s, np.transpose(cs.c[::-1], (1, 0, 2)))
        rows_of[np.searchsorted(moving, k)] = n
    curve = b.build(seg_u0)
    first = np.cumsum(rows_of) - rows_of
    last = np.r_[first[1:] - 1, len(curve) - 1]
    el_u0, el_u1 = seg_u0[moving], seg_u0[moving] + lengths[moving]
    d_start = curve.evaluate(el_u0, 2, index=first)
    d_end = curve.evaluate(el_u1, 2, index=last)
    t0, k0 = _unit_and_curvature(d_start[1], d_start[2])
    t1, k1 = _unit_and_curvature(d_end[1], d_end[2])
    return curve, _Elements(moving, el_u0, el_u1, kind == LINE, t0, t1, k0, k1)


# ---------------------------------------------------------------- zones and runs

def _stops_between(cols: PathColumns, seg: np.ndarray) -> np.ndarray:
    """Whether the tool must rest between consecutive moving segments ``seg``: a dwell between them, or the
    tool or spindle changing on the way."""
    change = np.r_[False, (cols.tool_down[1:] != cols.tool_down[:-1]) | (cols.spindle[1:] != cols.spindle[:-1])]
    marks = np.cumsum(change | (cols.kind == DWELL))
    return marks[seg[1:]] > marks[seg[:-1]]


def _zone_wants(alpha, dkappa, tol: float, r_cap: float, g2: bool) -> tuple[np.ndarray, np.ndarray]:
    """Half-width of the zone each junction needs (0: none): for a tangent arc, and for a fitted spline
    (curvature-continuous, so it needs more room; curvature jumps count when ``g2``)."""
    half = 0.5 * alpha
    one_minus_cos = 2.0 * np.sin(0.5 * half) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        radius = np.minimum(np.where(one_minus_cos > 0, tol * np.cos(half) / one_minus_cos, np.inf), r_cap)
        arc = np.where(np.isfinite(radius), radius * np.tan(half), 0.0)
        fit = _G2_STRETCH * arc
        if g2:
            jump = np.where(dkappa > 0, np.sqrt(3.0 * tol / np.where(dkappa > 0, dkappa, 1.0)), 0.0)
            fit = np.maximum(fit, np.minimum(jump, r_cap * 0.05))
    return arc, fit


@dataclass
class _Runs:
    """Runs to smooth: u range, the junctions they cover, whether each is a lone line-line tangent arc."""

    ua: np.ndarray
    ub: np.ndarray
    first: np.ndarray  # first junction (index into junction arrays)
    last: np.ndarray
    arc: np.ndarray
    free_a: np.ndarray  # the run starts at a stop: only its position is held there
    free_b: np.ndarray


def _merge_zones(lo: np.ndarray, hi: np.ndarray, want: np.ndarray, barrier_before: np.ndarray):
    """Group consecutive zones [lo, hi] that overlap (or nearly: a stub shorter than a quarter of the zone
    next to it is not worth keeping) unless a barrier (a stop, or another run) lies between them.
    Returns the index of each group's first and last zone."""
    reach = np.maximum.accumulate(hi)  # how far the zones so far reach
    ahead = np.minimum.accumulate(lo[::-1])[::-1]  # how far back the zones to come reach
    new = np.r_[True, ahead[1:] >= reach[:-1] + 0.25 * want[1:]]
    new[1:] |= barrier_before[1:] >= reach[:-1]
    starts = np.flatnonzero(new)
    return starts, np.r_[starts[1:] - 1, len(lo) - 1]


def _find_runs(el: _Elements, need: np.ndarray, want: np.ndarray, alpha: np.ndarray, stop: np.ndarray,
               g2: bool) -> _Runs:
    """Group the junctions that need a zone (junction j is between elements j and j+1) into runs.

    Each zone is the stretch of programmed path within ``want`` of its junction, through as many
    segments as that takes, never across a stop. Sharp corners (turning more than _SHARP) are fitted
    on their own, with finer knots: their zones merge only with each other's, take in any gentler
    junction inside them and cut back the zones of gentler junctions around them. Gentle zones that
    overlap merge into one run, however many segments that spans. A run that reaches a stop is free
    there: the tool is at rest, nothing to join smoothly.
    """
    jn = np.flatnonzero(need)
    if not len(jn):
        z = np.zeros(0)
        return _Runs(z, z, z.astype(int), z.astype(int), z.astype(bool), z.astype(bool), z.astype(bool))
    at = el.u1[jn]  # where each junction is, in programmed arc length
    stops = np.unique(np.r_[el.u0[0], el.u1[:-1][stop], el.u1[-1]])
    prev_stop = stops[np.searchsorted(stops, at, side="right") - 1]
    next_stop = stops[np.searchsorted(stops, at, side="left")]
    lo = np.maximum(at - want[jn], prev_stop)
    hi = np.minimum(at + want[jn], next_stop)
    sharp = alpha[jn] >= _SHARP
    runs = []  # (ua, ub, first junction, last junction, free_a, free_b)
    sa = sb = np.zeros(0)
    if sharp.any():
        k = np.flatnonzero(sharp)
        first, last = _merge_zones(lo[k], hi[k], want[jn[k]], prev_stop[k])
        sa, sb = np.minimum.reduceat(lo[k], first), np.maximum.reduceat(hi[k], first)
        runs += [(sa, sb, jn[k[first]], jn[k[last]], sa <= prev_stop[k[first]], sb >= next_stop[k[last]])]
    gentle = np.flatnonzero(~sharp)
    if len(sa):  # gentle junctions inside a sharp run are its; the others stop short of sharp runs
        i = np.searchsorted(sa, at[gentle], side="right") - 1
        inside = (i >= 0) & (at[gentle] < sb[np.maximum(i, 0)])
        gentle = gentle[~inside]
        i = np.searchsorted(sa, at[gentle], side="right") - 1
        lo[gentle] = np.maximum(lo[gentle], np.where(i >= 0, sb[np.maximum(i, 0)], -np.inf))
        hi[gentle] = np.minimum(hi[gentle], np.r_[sa, np.inf][i + 1])
    if len(gentle):
        barrier = prev_stop[gentle].copy()
        if len(sa):
            i = np.searchsorted(sb, at[gentle], side="right") - 1
            barrier = np.maximum(barrier, np.where(i >= 0, sb[np.maximum(i, 0)], -np.inf))
        first, last = _merge_zones(lo[gentle], hi[gentle], want[jn[gentle]], barrier)
        ga, gb = np.minimum.reduceat(lo[gentle], first), np.maximum.reduceat(hi[gentle], first)
        runs += [(ga, gb, jn[gentle[first]], jn[gentle[last]], ga <= prev_stop[gentle[first]],
                  gb >= next_stop[gentle[last]])]
    ua, ub, first, last, free_a, free_b = (np.concatenate(col) for col in zip(*runs))
    order = np.argsort(ua, kind="stable")
    ua, ub, first, last, free_a, free_b = ua[order], ub[order], first[order], last[order], free_a[order], free_b[order]
    # a lone corner between two lines whose zone stays on them: a tangent arc will do (when G1 is enough)
    lone_arc = ((first == last) & el.is_line[first] & el.is_line[first + 1] & (not g2) & ~free_a & ~free_b
                & (ua >= el.u0[first]) & (ub <= el.u1[first + 1]))
    return _Runs(ua, ub, first, last, lone_arc, free_a, free_b)


# ---------------------------------------------------------------- fitting runs

@dataclass
class _Fit:
    """Fitted runs: knots, control points (all runs stacked, run r from ``offset[r]``), whether each met the
    tolerance, its largest deviation, and for each knot the programmed arc length it stands for."""

    knots: list
    coef: np.ndarray
    offset: np.ndarray
    ok: np.ndarray
    deviation: np.ndarray
    knot_pu: list


class _Selection:
    """The runs a fitter still solves, as index arrays into its stacked arrays (control points, penalty rows,
    data, spans), and what its iterations look up in them and gather by them. They change only when a run is
    done, so the iterations take them from here rather than work them out again (on ellipse200's one run of
    972 control points about a tenth of a millisecond an iteration)."""

    def __init__(self, fit: _RunFitter, active: np.ndarray):
        self.fit, self.active = fit, active.copy()
        self.runs = np.flatnonzero(active)
        self.cps, self.rows, self.data = (np.flatnonzero(active[of]) for of in (fit.cp_run, fit.diff_run, fit.run_of))

    @cached_property
    def run_data(self) -> np.ndarray:
        """Where each run's data start among ``data``."""
        return np.r_[0, np.cumsum(np.diff(self.fit.bounds)[self.runs])[:-1]]

    @cached_property
    def run_rows(self) -> np.ndarray:
        """Where each run's penalty rows start among ``rows``."""
        return np.r_[0, np.cumsum((self.fit.ncp - self.fit.order)[self.active])[:-1]]

    @cached_property
    def cp_runs(self) -> np.ndarray:
        """Each control point's run, as its place among ``runs``."""
        return np.searchsorted(self.runs, self.fit.cp_run[self.cps])

    @cached_property
    def spans(self) -> tuple[np.ndarray, np.ndarray]:
        """Each span's control point among ``cps`` and where its data start among ``data`` (spans with data)."""
        first, span = self.fit.span_runs
        at = np.flatnonzero(self.active[self.fit.run_of[first]])
        return np.searchsorted(self.cps, span[at]), np.searchsorted(self.data, first[at])

    @cached_property
    def reach(self) -> Windows:
        """Each penalty row's reach, as windows over ``cps``."""
        lo, hi = (np.searchsorted(self.cps, end[self.rows]) for end in (self.fit.reach_lo, self.fit.reach_hi))
        return Windows(lo, hi, len(self.cps))

    @cached_property
    def blur(self) -> MovingMeans:
        """Moving means over _BLUR penalty rows within each run."""
        return MovingMeans((self.fit.ncp - self.fit.order)[self.active], _BLUR)

    @cached_property
    def row_cp(self) -> np.ndarray:
        """Each penalty row's first control point among ``cps``."""
        return np.searchsorted(self.cps, self.fit.diff_start[self.rows])

    @cached_property
    def fixed(self) -> np.ndarray:
        return self.fit.fixed[self.cps]

    @cached_property
    def fixed_x(self) -> np.ndarray:
        return self.fit.fixed_x[self.cps]

    @cached_property
    def fixed_values(self) -> np.ndarray:
        return self.fit.c_fixed[self.cps][self.fixed]

    @cached_property
    def rhs_data(self) -> np.ndarray:
        return self.fit.rhs_data[self.cps]

    @cached_property
    def data_band(self) -> np.ndarray:
        """The data part of the normal equations in upper band form (4, cps): entry (i, i + k) in row 3 - k,
        column i + k; nothing left of the band (every iteration adds its penalty to a copy)."""
        total = len(self.cps)
        band = np.zeros((4, total))
        for k, d in enumerate(self.fit.data_diag):
            band[3 - k, k:] = d[self.cps[:total - k]]
        return band

    @cached_property
    def fixed_terms(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """What moving the fixed control points to the right-hand side changes: only the free control points
        within the band of a fixed one (every other term is 0 times an entry, which leaves it as it is). Those
        rows, their terms' band entries (flat indices into the band, term by row) and fixed positions (term, row,
        axis), each row's terms in the order the whole product subtracts them (k = 1, 2, 3, above the diagonal
        first; a row with fewer ends on the empty corner band[0, 0] times 0), and their right-hand sides."""
        fixed, total = self.fixed, len(self.cps)
        found = []  # (row, band entry, fixed neighbour) of every such term, in order
        for k in range(1, 4):
            for way in (k, -k):
                i = np.arange(max(0, -way), min(total, total - way))
                i = i[~fixed[i] & fixed[i + way]]
                found.append((i, (3 - k) * total + np.maximum(i, i + way), i + way))
        row, entry, nb = (np.concatenate(col) for col in zip(*found))
        order = np.argsort(row, kind="stable")  # each row's terms stay in order
        row, entry, nb = row[order], entry[order], nb[order]
        rows, first, count = np.unique(row, return_index=True, return_counts=True)
        slot = np.arange(len(row)) - np.repeat(first, count)
        place = np.repeat(np.arange(len(rows)), count)
        at = np.zeros((int(count.max(initial=0)), len(rows)), dtype=np.intp)
        x = np.zeros((*at.shape, 3))
        at[slot, place], x[slot, place] = entry, self.fixed_x[nb]
        return rows, at, x, self.rhs_data[rows]

    @cached_property
    def band_free(self) -> np.ndarray:
        """Whether both control points of each entry of the band are free, as the band's 1.0 and 0.0."""
        free, total = ~self.fixed, len(self.cps)
        band = np.zeros((4, total))
        for k in range(4):
            band[3 - k, k:] = free[:total - k] & free[k:]
        return band


class _RunFitter:
    """Penalised least-squares cubic B-splines for many runs at once (one block-diagonal banded system).

    Data: the programmed path over each run, sampled at a quarter of the knot spacing, plus its vertices.
    Each data point has a fitting parameter t (first the programmed arc length; after a parameter
    pass, the arc length along the fitted curve to the point's foot) and the curve is held within
    the tolerance of it at that t.
    """

    def __init__(self, raw: PlannedCurve, ua, ub, free_a, free_b, tol: float, h: np.ndarray, order: int = 2,
                 ell_segments: float = _ELL_SEGMENTS, bend: float = 0.0):
        self.raw, self.ua, self.ub, self.tol, self.h = raw, ua, ub, tol, np.broadcast_to(h, ua.shape)
        self.order, self.stencil, self.ell_segments, self.bend = order, _STENCILS[order], ell_segments, bend
        self.free_a, self.free_b = free_a, free_b
        n_runs = len(ua)
        length = ub - ua
        self.spans = np.maximum(_MIN_SPANS, np.ceil(length / np.broadcast_to(h, length.shape)).astype(int))
        self.ncp = self.spans + 3
        self.offset = np.r_[0, np.cumsum(self.ncp)[:-1]]
        self.total = int(self.ncp.sum())
        self.cp_run = np.repeat(np.arange(n_runs), self.ncp)  # each control point's run
        per = 4 * self.spans
        run_of = np.repeat(np.arange(n_runs), per + 1)
        frac = np.concatenate([np.arange(p + 1) / p for p in per])
        u = ua[run_of] + frac * length[run_of]
        inner = raw.u0[(raw.u0 > ua.min()) & (raw.u0 < ub.max())]
        r_in = np.searchsorted(ua, inner, side="right") - 1
        keep = (r_in >= 0) & (inner < ub[np.clip(r_in, 0, None)])
        u = np.concatenate([u, inner[keep]])
        run_of = np.concatenate([run_of, r_in[keep]])
        sort = np.lexsort((u, run_of))
        self.pu, self.run_of = u[sort], run_of[sort]
        self.q = raw.points(self.pu)
        self.bounds = np.searchsorted(self.run_of, np.arange(n_runs + 1))
        self.d_a = raw.evaluate(ua, 2, index=raw.interval_at(ua))
        self.d_b = raw.evaluate(ub, 2, index=np.clip(raw.interval_at(ub - 1e-12), 0, None))
        self.end_tangent = (self._data_tangent(ua, ub - ua, free_a, 1.0), self._data_tangent(ub, ub - ua, free_b, -1.0))
        # smoothing length per data point: a few programmed segment lengths, enough to even out the
        # kinks between them without reshaping the curve they describe
        k_raw = raw.interval_at(self.pu)
        self.seg_len = raw.u1[k_raw] - raw.u0[k_raw]
        self.scale = np.zeros(0)  # per penalty row, set at the first setup (a part's fitter is given its own)

    def _data_tangent(self, at: np.ndarray, length: np.ndarray, free: np.ndarray, way: float) -> np.ndarray:
        """Unit tangent of the programmed path at run ends ``at`` (going into the run): the slope at the end of
        a least-squares quadratic through the path over its first _END_FIT mm (or a quarter of the run)."""
        out = np.zeros((len(at), 3))
        x = np.linspace(0.0, 1.0, 17)
        for r in np.flatnonzero(free):
            span = min(_END_FIT, 0.25 * length[r])
            pts = self.raw.points(at[r] + way * span * x)
            turn = _turning(np.diff(pts, axis=0))
            for _ in range(3 if turn > _END_BENT else 0):
                span *= _END_TURN / turn
                pts = self.raw.points(at[r] + way * span * x)
                turn = _turning(np.diff(pts, axis=0))
                if turn <= _END_TURN * 1.05:
                    break
            coef = np.polynomial.polynomial.polyfit(span * x, pts, 2)
            slope = way * coef[1]
            out[r] = slope / max(float(np.linalg.norm(slope)), 1e-300)
        return out

    def _setup(self, t: np.ndarray, width: np.ndarray) -> None:
        """Basis, fixed end control points and penalty for fitting parameters t over [ua, ua + width]."""
        ua, spans, ncp, offset, total, run_of = self.ua, self.spans, self.ncp, self.offset, self.total, self.run_of
        n_runs = len(ua)
        hr = width / spans
        self.hr, self.t = hr, t
        self.basis = RunKnots(ua, width, spans, offset)
        self.knots = self.basis.knots
        x = np.clip(t, ua[run_of], (ua + width)[run_of])
        self.x_data, self.width = x, width
        span = self.basis.span(run_of, x)
        first = self.basis.first_cp(run_of, span)
        # the design matrix, row i: basis values b[:, i] on control points first[i] .. first[i] + 3
        self.design_b, self.design_cp = self.basis.bases(span, x, (3,))[3], first + np.arange(4)[:, None]
        # fixed control points: position, tangent and curvature of the path at both ends of each run
        fixed = np.zeros(total, dtype=bool)
        c_fixed = np.zeros((total, 3))
        o, e = offset, offset + ncp - 1
        h_r = hr[:, None]
        d_a, d_b = self.d_a, self.d_b
        c_fixed[o], c_fixed[o + 1], c_fixed[o + 2] = (d_a[0], d_a[0] + h_r * d_a[1] / 3.0,
                                                      d_a[0] + h_r * d_a[1] + h_r**2 * d_a[2] / 3.0)
        c_fixed[e], c_fixed[e - 1], c_fixed[e - 2] = (d_b[0], d_b[0] - h_r * d_b[1] / 3.0,
                                                      d_b[0] - h_r * d_b[1] + h_r**2 * d_b[2] / 3.0)
        # at a free end (a stop) the direction is the data's own there, from a quadratic through its first
        # few millimetres: a spline left free to turn at its end strays there
        c_fixed[o + 1] = np.where(self.free_a[:, None], d_a[0] + h_r * self.end_tangent[0] / 3.0, c_fixed[o + 1])
        c_fixed[e - 1] = np.where(self.free_b[:, None], d_b[0] - h_r * self.end_tangent[1] / 3.0, c_fixed[e - 1])
        fixed[np.concatenate([o, e, o + 1, e - 1, (o + 2)[~self.free_a], (e - 2)[~self.free_b]])] = True
        self.fixed, self.c_fixed = fixed, c_fixed
        # second-difference penalty rows: sum |D2 c|^2 ~ h^3 * integral |p''|^2, so mu = l^4 / (delta h^3)
        # makes the objective (1/delta) (integral r^2 + l^4 integral |p''|^2)
        self.diff_start = np.concatenate([offset[r] + np.arange(ncp[r] - self.order) for r in range(n_runs)])
        self.diff_run = np.repeat(np.arange(n_runs), ncp - self.order)
        self.span_of = np.clip(np.floor((t - ua[run_of]) / hr[run_of]).astype(int), 0, spans[run_of] - 1) + offset[run_of]
        per_cp: np.ndarray = np.bincount(self.span_of, weights=np.minimum(self.seg_len, _ELL * hr[run_of]), minlength=total)
        per_cp = per_cp / np.maximum(np.bincount(self.span_of, minlength=total), 1)
        per_cp = moving_means(per_cp, ncp, 41)
        hd = hr[self.diff_run]
        ell = np.clip(np.maximum(self.ell_segments * per_cp[self.diff_start + 1], _ELL_TOL * self.tol), hd, _ELL * hd)
        self.mu = ell**(2 * self.order) / (0.25 * hd * hd**(2 * self.order - 1))
        self.mu_bend = self.bend * ell**4 / (0.25 * hd**4)
        self.floor = (hd / ell) ** (2 * self.order)
        reach = np.ceil((_REACH_FINE if self.bend else _REACH) * ell / hd).astype(int)
        first_cp, last_cp = offset[self.diff_run], offset[self.diff_run] + ncp[self.diff_run] - 1
        self.reach_lo = np.maximum(self.diff_start + 1 - reach, first_cp)
        self.reach_hi = np.minimum(self.diff_start + 1 + reach, last_cp)
        if not len(self.scale):
            self.scale = np.ones(len(self.diff_start))
        # where each span's data start: the data run along the spans (sorted by run and parameter, and the
        # parameters rise within a run), so each span's data are one stretch
        first = np.r_[0, np.flatnonzero(np.diff(self.span_of)) + 1]
        self.span_runs = (first, self.span_of[first])
        self.data_diag, self.rhs_data = self._normal_data()
        self.fixed_x = self.c_fixed * fixed[:, None]
        self.q_rows = np.ascontiguousarray(self.q.T)

    def _normal_data(self) -> tuple[list[np.ndarray], np.ndarray]:
        """The data part of the normal equations, B^T B (its four upper diagonals) and B^T q, B the design
        matrix: each entry summed over the data rows in order, from zero, as a sparse product sums it. The
        rows' first control points rise with the rows, so an entry's terms come in the rows' order also when
        taken a (the row's place) by a, last a first: each a's terms are whole rows of b (no transposed copy)."""
        b, cp, total = self.design_b, self.design_cp, self.total
        diag = []
        for k in range(4):  # row i adds b[a, i] b[a + k, i] to diagonal k at cp[a, i], a = 0 .. 3 - k
            w = (b[:4 - k] * b[k:])[::-1].ravel()
            diag.append(np.bincount(cp[:4 - k][::-1].ravel(), weights=w, minlength=total)[:total - k])
        at = cp[::-1].ravel()
        rhs = np.stack([np.bincount(at, weights=(b * self.q[:, j])[::-1].ravel(), minlength=total)
                        for j in range(3)], axis=1)
        return diag, rhs

    def _residual(self, coef: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """|B coef - q| at data points ``rows``, B the design matrix (summed over a row's four control points in
        order). Most of them are worked out at every point and picked from there (gathering a row's data costs
        more than its arithmetic)."""
        if len(self.pu) > len(rows) > 0.5 * len(self.pu):
            return self._residual(coef, np.arange(len(self.pu)))[rows]
        every = len(rows) == len(self.pu)  # all of them: no copy
        b, cp, q = ((self.design_b, self.design_cp, self.q_rows) if every else
                    (self.design_b[:, rows], self.design_cp[:, rows], self.q_rows[:, rows]))
        by_axis = np.ascontiguousarray(coef.T)
        val = np.take(by_axis, cp[0], axis=1) * b[0]
        for a in range(1, 4):
            val += np.take(by_axis, cp[a], axis=1) * b[a]
        d = val - q
        dist = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        if self.bend:  # the curve may slide along the path: each way bounded on its own, both below dist
            dist = np.maximum(self._from_path(coef, rows, d, dist), self._to_path(val, rows, dist))
        return dist

    def _from_path(self, coef: np.ndarray, rows: np.ndarray, d: np.ndarray, dist: np.ndarray) -> np.ndarray:
        """Distance from data points ``rows`` to the curve, bounded from above by the curve point one Newton step
        along the tangent from their parameter (or the one at it, ``dist``, where nearer)."""
        run, x = self.run_of[rows], self.x_data[rows]
        p1 = self.basis.evaluate(coef, run, x, 1, only=(1,))[0].T
        lo, hi = self.ua[run], self.ua[run] + self.width[run]
        x2 = np.clip(x - (d * p1).sum(axis=0) / np.maximum((p1 * p1).sum(axis=0), 1e-300), lo, hi)
        e = self.basis.evaluate(coef, run, x2, 0)[0].T - self.q_rows[:, rows]
        return np.minimum(dist, np.sqrt((e * e).sum(axis=0)))

    def _to_path(self, val: np.ndarray, rows: np.ndarray, dist: np.ndarray) -> np.ndarray:
        """Distance from the curve at data points ``rows``' parameters to the path, bounded from above by the
        nearest of the data points _NEAR either side (all on the path)."""
        out = dist
        for k in range(-_NEAR, _NEAR + 1):
            e = val - self.q_rows[:, np.clip(rows + k, 0, len(self.pu) - 1)]
            out = np.minimum(out, np.sqrt((e * e).sum(axis=0)))
        return out

    def _solve(self, sel: _Selection) -> np.ndarray:
        """The banded normal equations (upper band form, LAPACK's pbsv) of the runs ``sel`` (their control points
        ``sel.cps``, whole runs, ascending, and penalty rows ``sel.rows``), assembled directly: the data part
        plus each penalty row's w * d^T d, d its difference stencil on its control points. Runs share no entry
        (their end control points are fixed), so any set of them is solved on its own."""
        fixed = sel.fixed
        band = sel.data_band.copy()
        self._add_penalty(band, self.stencil, self.mu, sel)
        if self.bend:
            self._add_penalty(band, _STENCILS[2], self.mu_bend, sel)
        # move the fixed control points to the right-hand side: rhs -= A[:, fixed] c_fixed (``fixed_terms``)
        rows, at, x, rhs_rows = sel.fixed_terms
        moved = rhs_rows.copy()
        for entry, x_term in zip(band.ravel().take(at), x):
            moved -= entry[:, None] * x_term
        rhs = sel.rhs_data.copy()
        rhs[rows] = moved
        band *= sel.band_free
        band[3, fixed] = 1.0
        rhs[fixed] = sel.fixed_values
        return _solved(band, rhs)

    def _add_penalty(self, band: np.ndarray, stencil: np.ndarray, mu: np.ndarray, sel: _Selection) -> None:
        """Add each penalty row's weight mu * scale times d^T d (d ``stencil`` on the row's control points) to
        ``band``: entry (c + p, c + q) gets s_p s_q w_c, all entries of the stencil's column q at once, so each
        entry's terms come in order of p. The weights sit at each row's first control point, zero between runs."""
        w = np.zeros(band.shape[1])
        w[sel.row_cp] = mu[sel.rows] * self.scale[sel.rows]
        for q, products in enumerate(_PRODUCTS[len(stencil)]):  # entries (c + p, c + q), p = 0 .. q: rows 3 - q .. 3
            band[3 - q:, q:] += products * w[:len(w) - q]

    def _iterate(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Solve, then smooth less wherever the tolerance is not met and more wherever it is met with room to
        spare, so the fit settles where it just keeps the tolerance. Each run keeps its last fit that met
        it (or its last, if none did). Runs are independent: a run is solved again only while it may still
        change, that is until it meets the tolerance after the settling iterations, or until its smoothing
        stops changing."""
        n_runs = len(self.ua)
        coef = np.zeros((self.total, 3))
        best = np.zeros((self.total, 3))
        resid = np.zeros(len(self.pu))
        ok_any = np.zeros(n_runs, dtype=bool)
        dev_best = np.full(n_runs, np.inf)
        active = np.ones(n_runs, dtype=bool)
        sel = _Selection(self, active)
        for it in range(_FIT_ITER):
            runs, cps, data = sel.runs, sel.cps, sel.data
            coef[cps] = self._solve(sel)
            resid[data] = r_act = self._residual(coef, data)
            dev = np.maximum.reduceat(r_act, sel.run_data)
            ok = dev <= self.tol
            keep = ok | ~ok_any[runs]
            take = cps[keep[sel.cp_runs]]
            best[take] = coef[take]
            dev_best[runs] = np.where(keep, dev, dev_best[runs])
            ok_any[runs] |= ok
            if it >= _FIT_SETTLE and ok.any():
                active[runs[ok]] = False
                if not active.any():
                    break
                sel = _Selection(self, active)
            # the largest ratio per span, then onto its four control points (of the runs still fitted)
            cps, data = sel.cps, sel.data
            worst = np.zeros(len(cps))
            span_cp, span_data = sel.spans
            worst[span_cp] = np.maximum.reduceat(resid[data] / self.tol, span_data)
            over = worst.copy()
            for j in range(1, 4):
                np.maximum(over[j:], worst[:-j], out=over[j:])
            rows = sel.rows
            row_over = -sel.reach.min(-over)
            prev = self.scale[rows]
            scale = np.where(row_over > 1.0, prev / (1.2 * row_over**2), prev)
            if it < _FIT_SETTLE:  # room to spare: smooth more again (up to where it started)
                scale = np.where(row_over < _SPARE, np.minimum(scale * _RELAX, 1.0), scale)
            # changed gently along the run: a step in smoothing makes a kink in the curve's parameter
            log_scale = np.log(scale)
            scale = np.exp(np.minimum(sel.blur(log_scale), log_scale))
            # never below the smoothing of one knot span: less only lets the parameter wander along the path
            scale = np.maximum(np.minimum(scale, np.where(row_over > 1.0, prev, np.inf)), self.floor[rows])
            self.scale[rows] = scale
            # a run whose smoothing did not change would be solved to the same fit again
            changed = np.add.reduceat((scale != prev).astype(int), sel.run_rows) > 0
            if not changed.all():
                active[sel.runs[~changed]] = False
                if not active.any():
                    break
                sel = _Selection(self, active)
        return best, ok_any, dev_best

    def _arc_length_params(self, coef: np.ndarray, width: np.ndarray):
        """Foot of each data point on the fitted curves (two Newton steps from its parameter), as arc length
        along its curve; and each curve's length. None where the feet do not run forwards."""
        run, a = self.run_of, self.ua[self.run_of]
        t, q = self.t.copy(), self.q
        for _ in range(2):
            p, p1, p2 = self.basis.evaluate(coef, run, t, 2)
            diff = p - q
            den = np.einsum("ij,ij->i", p1, p1) + np.einsum("ij,ij->i", diff, p2)
            t = np.clip(t - np.einsum("ij,ij->i", diff, p1) / np.where(den > 1e-12, den, 1.0), a, a + width[run])
        lo, hi = self.bounds[:-1], self.bounds[1:] - 1
        t[lo], t[hi] = self.ua, self.ua + width
        step = np.diff(t)
        inside = run[1:] == run[:-1]  # stretches between consecutive feet of one run
        if np.any(step[inside] < 0):
            return None
        # arc length at the feet: Gauss-Legendre on every stretch between consecutive feet
        gl_x, gl_w = np.polynomial.legendre.leggauss(5)
        mid, half = np.where(inside, 0.5 * (t[1:] + t[:-1]), t[1:]), np.where(inside, 0.5 * step, 0.0)
        nodes = mid[:, None] + half[:, None] * gl_x[None, :]
        d1 = self.basis.evaluate(coef, np.repeat(run[1:], len(gl_x)), nodes.ravel(), 1, only=(1,))[0]
        d = d1.T  # |d1| summed as np.linalg.norm sums it, along the points
        part = half * (np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).reshape(nodes.shape) @ gl_w)
        t_new = np.empty_like(self.t)
        lengths = np.empty(len(self.ua))
        for r in range(len(self.ua)):  # per run, so each sum runs as it always has
            s = np.concatenate([[0.0], np.cumsum(part[lo[r]:hi[r]])])
            t_new[lo[r]:hi[r] + 1] = self.ua[r] + s
            lengths[r] = s[-1]
        return t_new, lengths

    def _only(self, keep: np.ndarray, t: np.ndarray, width: np.ndarray):
        """A fitter for runs ``keep`` (a mask) alone, with their data's parameters ``t``, their widths and
        their smoothing so far: the same data, so it goes on fitting them as this one would."""
        sub = _RunFitter(self.raw, self.ua[keep], self.ub[keep], self.free_a[keep], self.free_b[keep], self.tol,
                         self.h[keep], self.order, self.ell_segments, self.bend)
        sub.scale = self.scale[keep[self.diff_run]]
        return sub, t[keep[self.run_of]], width[keep]

    def fit(self) -> _Fit:
        """Fit, re-parameterise the data by arc length along the fit (the programmed arc length drifts from the
        curve's wherever the fit cuts corners), fit again; each run keeps its last fit that met the
        tolerance (or its first, when none did). Only the runs that have not met the tolerance yet are
        re-parameterised and fitted again."""
        n_runs = len(self.ua)
        knots: list[np.ndarray] = [np.empty(0)] * n_runs
        coefs: list[np.ndarray] = [np.empty((0, 3))] * n_runs
        knot_pu: list[np.ndarray] = [np.empty(0)] * n_runs
        ok_any = np.zeros(n_runs, dtype=bool)
        dev_best = np.full(n_runs, np.inf)
        fitter, runs, t, width = self, np.arange(n_runs), self.pu.copy(), self.ub - self.ua
        for attempt in range(_PARAM_PASSES + 1):
            fitter._setup(t, width)
            coef, ok, dev = fitter._iterate()
            take = ok | (~ok_any[runs] & (dev < dev_best[runs]))
            for i in np.flatnonzero(take):
                r, lo, hi = runs[i], fitter.bounds[i], fitter.bounds[i + 1]
                knots[r] = fitter.knots[i]
                coefs[r] = coef[fitter.offset[i]:fitter.offset[i] + fitter.ncp[i]]
                knot_pu[r] = np.interp(fitter.knots[i][3:-3], t[lo:hi], fitter.pu[lo:hi])
                dev_best[r] = dev[i]
            ok_any[runs] |= ok
            if attempt == _PARAM_PASSES or ok_any.all():
                break
            keep = ~ok_any[runs]
            sub, t, width = fitter._only(keep, t, width)
            sub._setup(t, width)
            moved = sub._arc_length_params(coef[np.repeat(keep, fitter.ncp)], width)
            if moved is None:
                break
            fitter, runs, (t, width) = sub, runs[keep], moved
        offset = np.r_[0, np.cumsum([len(c) for c in coefs])[:-1]]
        return _Fit(knots, np.concatenate(coefs), offset, ok_any, dev_best, knot_pu)


def _runs_polys(fit: _Fit, runs: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Knots, programmed arc length at each knot, and ascending power coefficients (n, 4, 3) of fitted runs
    ``runs``: the derivatives at each span's first knot, all runs at once."""
    knots = [fit.knots[r] for r in runs]
    ncp = np.array([len(k) - 4 for k in knots], dtype=int)
    coef = np.concatenate([fit.coef[fit.offset[r]:fit.offset[r] + n] for r, n in zip(runs, ncp)])
    basis = RunKnots.of(knots, np.r_[0, np.cumsum(ncp)[:-1]])
    d = basis.evaluate(coef, np.repeat(np.arange(len(runs)), ncp - 3), np.concatenate([k[3:-4] for k in knots]), 3)
    polys = np.split(np.stack([d[m] / math.factorial(m) for m in range(4)], axis=1), np.cumsum(ncp - 3)[:-1])
    return [(k[3:-3], fit.knot_pu[r], p) for k, r, p in zip(knots, runs, polys)]


# ---------------------------------------------------------------- corners between two lines

def _corner_parabolas(corner, u_in, u_out, room, v_full, apex, limits: PathLimits):
    """Round lone line-line corners by the per-axis time-optimal blend: a parabola, or two.

    Through a corner at speed v, the velocity must change by v (u_out - u_in); with each axis held to
    its own amax, the fastest way is one constant acceleration vector, each axis at most at its limit,
    for tau = v max_i |u_out_i - u_in_i| / amax_i: the path is then a parabola from v tau / 2 before the
    corner to v tau / 2 after it (LinuxCNC's old parabolic blend, here sized per axis and by the
    tolerance). Its point nearest the corner is v tau sin(alpha/2) / 4 from it, and no point of either
    is further from the other, so the trim d = v tau / 2 may grow to 2 apex / sin(alpha/2) (``apex``: how far
    its middle may pass from the corner: the tolerance, more where the corner is moved out); no larger
    than what passing at full speed needs (v_full^2 m / 2, m = max_i |u_out_i - u_in_i| / amax_i), nor
    than ``room``. For a right angle between two axes it passes about 1.5 times as fast as the tangent
    arc within the same tolerance.

    Where the turn leaves an axis spare (a 60 degree zigzag along X: only Y turns), the tool may also slow
    down along w = u_in + u_out for the first half and speed up again for the second, with lambda w taken from
    and added to the acceleration, lambda as large as every axis allows: two parabolas, whose middle
    cuts in (1 - f) times as far at the same entry speed (f = lambda m, at most _SPLIT_MOST; the
    zigzag: f = 0.58, entered 1.54 times as fast within the same apex). Their trim is
    v^2 m (1 - f / 2) / 2. They are laid in where they let the corner be entered faster (the apex or the
    room binds, not the feed) and ``_corner_time`` finds them _SPLIT_GAIN as quick; the time law counts the
    normal term helping the slowing axis (flowmc.motion.timelaw). Returns the trims, the coefficients
    (n, 2, 4, 3) of each blend's pieces in the curve parameter x from each piece's start (the first piece
    p = start + u_in x + c2 x^2 over the whole blend where it is one parabola), whether it is split at its
    middle, and its length W = v^2 m in curve parameter (each piece W / 2 where split).
    """
    du = u_out - u_in
    mean = u_in + u_out
    half_sin = 0.5 * np.linalg.norm(du, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        m = np.max(np.where(np.abs(du) > 0, np.abs(du) / limits.amax, 0.0), axis=1)
        spare = np.min(np.where(np.abs(mean) > 1e-9, (limits.amax - np.abs(du) / m[:, None]) / np.abs(mean), np.inf),
                       axis=1)
        f = np.clip(np.where(np.isfinite(spare), spare * m, 0.0), 0.0, _SPLIT_MOST)
        one = np.minimum(np.minimum(4.0 * apex / np.maximum(half_sin, 1e-300), v_full**2 * m), 2.0 * room)
        two = np.minimum(np.minimum(4.0 * apex / np.maximum(half_sin * (1.0 - f), 1e-300), v_full**2 * m),
                         2.0 * room / (1.0 - 0.5 * f))
    a_line = np.minimum(limits.along(u_in)[1], limits.along(u_out)[1])
    split = (f > 0) & (two > one * (1.0 + 1e-6))
    one_time = _corner_time(one, 0.0, m, room, v_full, a_line)
    split &= _corner_time(two, f, m, room, v_full, a_line) < _SPLIT_GAIN * one_time
    f = np.where(split, f, 0.0)
    width = np.where(split, two, one)  # v^2 m: the blend's length in curve parameter
    d = 0.5 * width * (1.0 - 0.5 * f)
    first = 0.5 * (du - f[:, None] * mean) / width[:, None]
    coef = np.zeros((len(d), 2, 4, 3))
    coef[:, 0, 0] = corner - u_in * d[:, None]
    coef[:, 0, 1] = u_in
    coef[:, 0, 2] = first
    half = 0.5 * width[:, None]
    coef[:, 1, 0] = coef[:, 0, 0] + half * (u_in + half * first)
    coef[:, 1, 1] = u_in + 2.0 * half * first
    coef[:, 1, 2] = 0.5 * (du + f[:, None] * mean) / width[:, None]
    return d, coef, split, width


def _corner_time(width, f, m, room, v_full, a_line):
    """About how long a blend of ``width`` (v^2 m) and split ``f`` takes from ``room`` before its corner to ``room``
    after it: its own time v m at entry speed v, and each line's rest from v, speeding up at ``a_line`` to
    ``v_full`` at most (a model to choose between one parabola and two, not a plan)."""
    v = np.sqrt(width / np.maximum(m, 1e-300))
    rest = np.maximum(room - 0.5 * width * (1.0 - 0.5 * f), 0.0)
    reach = np.maximum(v_full**2 - v**2, 0.0) / (2.0 * a_line)  # distance to full speed
    short = rest <= reach
    line = np.where(short, (np.sqrt(v**2 + 2.0 * a_line * rest) - v) / a_line,
                    (v_full - v) / a_line + (rest - reach) / v_full)
    return v * m + 2.0 * line


def _corner_jerk_blends(corner, u_in, u_out, room, v_full, apex, limits: PathLimits):
    """Round lone line-line corners for jerk-limited profiles by the per-axis jerk-limited blend: two cubics.

    The jerk-limited analogue of ``_corner_parabolas``: through a corner the velocity changes direction
    by (u_out - u_in) per unit of path parameter rate w, here with one constant jerk vector over the first
    half of the blend and the opposite one over the second (the bang-bang jerk of an S-curve, applied to the
    velocity's change of direction; with an axis the turn leaves alone, as X on a zigzag, that axis moves at
    constant speed through it). With x in [0, 2d], p = start + u_in x + (u_out - u_in) 2d G(x / 2d), g = G'
    rising as 2 z^2 to 1/2 at z = 1/2 and as 1 - 2 (1 - z)^2 after: two cubics, whose curvature is zero at
    both ends, so the blend joins its lines curvature-continuously (G2) and its curvature rises and falls
    linearly in x, as the clothoid pairs and curvature-optimal corner blends of CNC corner smoothing do
    (Sencer, Ishizaki and Shamoto, "A curvature optimal sharp corner smoothing algorithm for high-speed
    feed motion generation of NC systems along linear tool paths", Int. J. Adv. Manuf. Technol. 76, 2015),
    here sized per axis. Passed at rate w it takes w^2 |du_i| / d <= amax_i and w^3 |du_i| / d^2 <= jmax_i;
    its middle passes d |du| / 6 = d sin(alpha/2) / 3 from the corner (the parabola's: d sin(alpha/2) / 2),
    which ``apex`` bounds, so d may grow to 3 apex / sin(alpha/2), no more than ``room`` nor than passing
    at ``v_full`` needs. Returns d, the pieces' breaks (n, 3) in shares of 2d, and their coefficients
    (n, 2, 4, 3) in each piece's own parameter.
    """
    du = u_out - u_in
    half_sin = 0.5 * np.linalg.norm(du, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        m_a = np.max(np.where(np.abs(du) > 0, np.abs(du) / limits.amax, 0.0), axis=1)
        m_j = np.max(np.where(np.abs(du) > 0, np.abs(du) / limits.jmax, 0.0), axis=1)
        need = np.maximum(v_full**2 * m_a, np.sqrt(v_full**3 * m_j))
        d = np.minimum(np.minimum(3.0 * apex / np.maximum(half_sin, 1e-300), need), room)
    start = (corner - u_in * d[:, None])[:, None]
    coef = np.zeros((len(d), 2, 4, 3))
    # per half: its start at x = 0 and x = d; G, g and g' there (g' = 2 at the middle), g'' = +-4 on it
    coef[:, :, 0] = start + np.stack([np.zeros_like(u_in), u_in + du / 6.0], axis=1) * d[:, None, None]
    coef[:, :, 1] = u_in[:, None] + du[:, None] * np.array([0.0, 0.5])[None, :, None]
    coef[:, :, 2] = du[:, None] * np.array([0.0, 0.5])[None, :, None] / d[:, None, None]
    coef[:, :, 3] = du[:, None] * np.array([1.0, -1.0])[None, :, None] / (6.0 * d[:, None, None] ** 2)
    return d, np.tile([0.0, 0.5, 1.0], (len(d), 1)), coef


@dataclass
class _Outside:
    """Lone corners moved out (``_outside_corners``): per blend the (moved) corner, the lines' directions into
    and out of it, how far its parabola's middle may pass from it, its room, and how far each end of the blend
    lies past the programmed corner along a line left as programmed (``past_in``, ``past_out``; 0 on a
    redrawn line); and the lines redrawn between moved ends, with their new ends."""

    corner: np.ndarray
    u_in: np.ndarray
    u_out: np.ndarray
    apex: np.ndarray
    room: np.ndarray
    past_in: np.ndarray
    past_out: np.ndarray
    redrawn_in: np.ndarray
    redrawn_out: np.ndarray
    line: np.ndarray
    start: np.ndarray
    end: np.ndarray


def _outside_corners(el: _Elements, raw: PlannedCurve, j: np.ndarray, stop: np.ndarray, short: np.ndarray,
                     room_in: np.ndarray, room_out: np.ndarray, tol: float, still: np.ndarray) -> _Outside:
    """Move lone line-line corners out, so their blends use the tolerance band on both sides of the path.

    A fast way through a corner within a band keeps to the outside of the band before and after it and cuts
    to the inside at the corner (the racing line of minimum-time vehicle manoeuvring, e.g. Kapania, Subosits
    and Gerdes, J. Dynamic Systems, Measurement and Control 138 (2016) 091005). CNC corner blends (e.g.
    Sencer and Shamoto's curvature-continuous corner smoothing, with the cornering error set analytically)
    stay on the inner side of both lines; here the tolerance is used on both sides.
    Each corner C is moved out to C' so the lines into it stay within the tolerance of the programmed
    ones, and the parabola of ``_corner_parabolas`` is laid in the moved corner with its middle still
    within the tolerance of C (the path both ways): it may pass up to about tol + |C' - C| from C', so
    it is longer and passed faster. A line whose other end is a stop, the path's end or another blend is
    redrawn between its (moved) ends, within the tolerance of its programmed line since both ends are.
    Where both lines can be redrawn, C moves along its bisector by tol / cos(alpha/2) (the lines' ends
    then lie on the band's outer edge; a 60 degree zigzag: the parabola 2.15 times as long, passed 1.47
    times as fast); where only one can, along the other line's extension by tol tan(alpha/2) (which lets the
    parabola's middle pass tol / cos(alpha/2) from C'; at most tol / sin(alpha), which keeps the redrawn
    line within the band), leaving that line as programmed; where neither can (or ``still``: a blend too
    short to reach back past the slide), C stays. Lines next to anything else (a fitted run, an arc) keep
    their direction, so nothing else changes. Moves are at most 2 tol. The deviation both ways is checked
    on sampled plans over turns of 20-150 degrees, with both kinds of move (tests/motion/test_planner.py).
    A reversal between two redrawn lines (``short``: the tool stops there anyway) moves back along them by up
    to tol (a quarter of the shorter line at most): the tool stops short of the apex, which stays within tol
    of where it stops (3dtest's six reversals: 8 ms).
    """
    nj = len(el.seg) - 1
    cand = np.zeros(nj, dtype=bool)
    cand[j] = True
    end_free = np.r_[True, stop | cand, True]  # element boundaries (starts, then the path's end)
    redrawn = el.is_line & end_free[:-1] & end_free[1:]  # per element
    r_in, r_out = redrawn[j], redrawn[j + 1]
    u_in, u_out = el.t1[j].copy(), el.t0[j + 1].copy()
    corner = raw.points(el.u1[j])
    cos_a = np.einsum("ij,ij->i", u_in, u_out)
    sin_a = np.sqrt(np.clip(1.0 - cos_a**2, 0.0, 1.0))
    outward = u_in - u_out
    outward /= np.maximum(np.linalg.norm(outward, axis=1, keepdims=True), 1e-300)
    cos_half = np.sqrt(np.clip(0.5 * (1.0 + cos_a), 0.0, 1.0))
    with np.errstate(divide="ignore"):
        lift = np.minimum(tol / cos_half, 2.0 * tol)
        # sliding C by x along one line puts the parabola's middle within tol of C while it is at most
        # x sin(alpha/2) + sqrt(tol^2 - x^2 cos^2(alpha/2)) from C': most (tol / cos(alpha/2)) at x = tol tan(alpha/2)
        slide = np.minimum(np.minimum(tol * np.sqrt(np.clip(1.0 - cos_a, 0, 2) / np.clip(1.0 + cos_a, 1e-300, 2)),
                                      tol / sin_a), 2.0 * tol)
    shift = np.where(still[:, None], 0.0, np.where((r_in & r_out)[:, None], lift[:, None] * outward,
                     np.where((r_in & ~r_out)[:, None], -slide[:, None] * u_out,
                              np.where((~r_in & r_out)[:, None], slide[:, None] * u_in, 0.0))))
    s_at = np.zeros((nj + 2, 3))  # per element boundary
    s_at[j + 1] = shift
    # a reversal between two redrawn lines (``short``) is stopped at up to tol before it, on both lines at once
    k = np.flatnonzero(short & redrawn[:-1] & redrawn[1:])
    span = el.u1 - el.u0
    s_at[k + 1] = -np.minimum(tol, 0.25 * np.minimum(span[k], span[k + 1]))[:, None] * el.t1[k]
    line = np.flatnonzero(redrawn)
    start = raw.points(el.u0[line]) + s_at[line]
    end = raw.points(el.u1[line]) + s_at[line + 1]
    length = np.linalg.norm(end - start, axis=1)
    new_dir = (end - start) / length[:, None]
    at_in, at_out = np.searchsorted(line, j), np.searchsorted(line, j + 1)
    u_in[r_in], u_out[r_out] = new_dir[at_in[r_in]], new_dir[at_out[r_out]]
    corner += shift
    past_in = np.where(r_in, 0.0, np.einsum("ij,ij->i", shift, u_in))
    past_out = np.where(r_out, 0.0, -np.einsum("ij,ij->i", shift, u_out))
    # on a redrawn line a blend may take half of it; on a programmed one what its zone left, and the slide
    room = np.minimum(np.where(r_in, 0.5 * length[np.minimum(at_in, len(line) - 1)] if len(line) else 0.0,
                               room_in + past_in),
                      np.where(r_out, 0.5 * length[np.minimum(at_out, len(line) - 1)] if len(line) else 0.0,
                               room_out + past_out))
    # the parabola's middle lies on its own bisector b, h from C': keep it within tol of C, |shift - h b| <= tol
    bis = u_in - u_out
    bis /= np.maximum(np.linalg.norm(bis, axis=1, keepdims=True), 1e-300)
    along = np.einsum("ij,ij->i", bis, shift)
    apex = along + np.sqrt(np.maximum(tol**2 - np.einsum("ij,ij->i", shift, shift) + along**2, 0.0))
    return _Outside(corner, u_in, u_out, apex, room, past_in, past_out, r_in, r_out, line, start, end)


# ---------------------------------------------------------------- assembling the curve

def _shift_poly(coef: np.ndarray, du: np.ndarray) -> np.ndarray:
    """Coefficients of the same cubics re-expanded about u0 + du (rows of (n, 4, 3))."""
    c0, c1, c2, c3 = (coef[:, m] for m in range(4))
    d = du[:, None]
    return np.stack([c0 + d * (c1 + d * (c2 + d * c3)), c1 + d * (2 * c2 + 3 * d * c3), c2 + 3 * d * c3, c3], axis=1)


def _copy_outside(raw: PlannedCurve, b: CurveBuilder, cut_a: np.ndarray, cut_b: np.ndarray) -> None:
    """Copy the raw curve's intervals outside the cut stretches [cut_a, cut_b) (sorted, disjoint), trimmed."""
    # pieces of every raw interval that lie outside all cuts
    edges = np.unique(np.r_[raw.u0, raw.u1[-1:], cut_a, cut_b])
    lo, hi = edges[:-1], edges[1:]
    mid = 0.5 * (lo + hi)
    inside = np.searchsorted(cut_a, mid, side="right") - 1
    in_cut = (inside >= 0) & (mid < np.r_[cut_b, -np.inf][np.where(inside >= 0, inside, len(cut_b))])
    keep = ~in_cut & (hi > lo)
    lo, hi = lo[keep], hi[keep]
    k = raw.interval_at(0.5 * (lo + hi))
    du = lo - raw.u0[k]
    poly = raw.kind[k] == POLY
    if poly.any():
        kk = k[poly]
        b.polys(np.c_[lo[poly], hi[poly]], _shift_poly(raw.coef[kk], du[poly]))
    arc = ~poly
    if arc.any():
        kk = k[arc]
        d = du[arc]
        centre = raw.centre[kk] + (raw.rise[kk] * d)[:, None] * raw.w[kk]
        b.arcs(lo[arc], hi[arc], hi[arc] - lo[arc], centre, raw.e1[kk], raw.e2[kk],
               raw.w[kk], raw.radius[kk], raw.phi0[kk] + raw.dphi[kk] * d, raw.dphi[kk], raw.rise[kk])


def fit_tolerance(limits: PathLimits, tolerance: float) -> float:
    """The share of ``tolerance`` (mm) a fitted or reshaped curve may use: the sampled chords' sagitta at the
    largest acceleration comes on top of the curve's own deviation. Raises PlanningError if nothing is left."""
    a_big = float(np.max(limits.amax[list(limits.cols)]))
    left = tolerance - a_big * limits.period**2 / 8.0
    if left <= 0:
        raise PlanningError(f"tolerance {tolerance} mm is below the sampled chords' sagitta at this period",
                            where="planner")
    return _TOL_SHARE * left


def smooth_path(path: Path, limits: PathLimits, tolerance: float, *, continuity: int = 1,
                as_curve: tuple[PlannedCurve, _Elements] | None = None) -> Smoothed:
    """Smooth ``path`` within ``tolerance`` (mm): tangent-continuous joins (``continuity=1``, enough for
    acceleration-limited profiles) or curvature-continuous ones (``continuity=2``, for jerk limits; lone
    sharp line-line corners then get ``_corner_jerk_blends``, and ``Smoothed.stopped`` stops at them).
    ``as_curve``: ``raw_curve(path)``, where the caller needs it too.

    Raises PlanningError naming the segment for gaps, bad feeds, or motion on axes the machine lacks.
    """
    if not (math.isfinite(tolerance) and tolerance > 0):
        raise PlanningError(f"tolerance must be > 0 mm, got {tolerance}", where="planner")
    seg_feed = checked_feeds(path)
    raw, el = raw_curve(path) if as_curve is None else as_curve
    g2 = continuity >= 2
    period = limits.period
    v_big = float(np.max(limits.vmax[list(limits.cols)]))
    tol_fit = fit_tolerance(limits, tolerance)

    # junctions between consecutive elements
    nj = len(el.seg) - 1
    gap_stop = _stops_between(path.columns, el.seg)
    alpha = corner_angle(el.t1[:-1], el.t0[1:]) if nj > 0 else np.zeros(0)
    dkappa = np.linalg.norm(el.k0[1:] - el.k1[:-1], axis=1) if nj > 0 else np.zeros(0)
    stop = gap_stop | (alpha >= REVERSAL)
    a_min = float(np.min(limits.amax[list(limits.cols)]))
    if g2:
        j_min = float(np.min(limits.jmax[list(limits.cols)]))
        need = (alpha > 2e-3 * j_min * period**2 / v_big) | (dkappa > 2e-3 * j_min * period / v_big**2)
    else:
        need = alpha > 2e-3 * a_min * period / v_big
    need &= ~stop
    r_cap = v_big**2 / (_FLAT * a_min)  # flatter than this costs nothing worth smoothing for
    want_arc, want = _zone_wants(alpha, dkappa, tol_fit, r_cap, g2)
    runs = _find_runs(el, need, want, alpha, stop, g2)
    stop_extra = []
    if g2:
        # a lone sharp corner is cheaper to stop at than to pass on a curvature-continuous curve within the
        # tolerance (whose curvature must rise and fall within a fraction of a millimetre: the jerk limit
        # holds the speed there near zero anyway), so the jerk-limited profile stops there
        lone = ((runs.first == runs.last) & (alpha[runs.first] >= _SHARP) & (runs.ua >= el.u0[runs.first])
                & (runs.ub <= el.u1[runs.first + 1]))
        runs.arc = (lone & el.is_line[runs.first] & el.is_line[runs.first + 1] & ~runs.free_a & ~runs.free_b)
        lone &= ~runs.arc
        stop_extra.append(el.u1[runs.first[lone]])
        runs = _Runs(*(getattr(runs, f.name)[~lone] for f in fields(_Runs)))

    blend_parts: list[tuple] = []  # (programmed stretches, coefficients, widths) of blends and their redrawn lines
    fit_parts: list[tuple] = []
    line_a = line_b = np.zeros(0)
    blends = np.flatnonzero(runs.arc)
    if len(blends):
        j = runs.first[blends]
        v_full = np.minimum(np.minimum(seg_feed[el.seg[j]], seg_feed[el.seg[j + 1]]),
                            np.minimum(limits.along(el.t1[j])[0], limits.along(el.t0[j + 1])[0]))
        room_in, room_out = el.u1[j] - runs.ua[blends], runs.ub[blends] - el.u0[j + 1]
        still = np.zeros(len(j), dtype=bool)
        while True:  # a blend too short to reach back past a slid corner (no room) keeps its corner where it is
            out = _outside_corners(el, raw, j, stop, (alpha >= REVERSAL) & ~gap_stop, room_in, room_out, tol_fit,
                                   still)
            if g2:
                d, breaks, coef = _corner_jerk_blends(out.corner, out.u_in, out.u_out, out.room, v_full, out.apex,
                                                      limits)
                widths = 2.0 * d[:, None] * np.diff(breaks, axis=1)
            else:  # one parabola, or two (split at the middle) where the turn leaves an axis spare
                d, coef, split, width = _corner_parabolas(out.corner, out.u_in, out.u_out, out.room, v_full, out.apex,
                                                          limits)
                breaks = np.where(split[:, None], [0.0, 0.5, 1.0], [0.0, 1.0, 1.0])
                widths = np.where(split[:, None], 0.5 * width[:, None], [[1.0, 0.0]] * width[:, None])
            short = ~still & (d <= np.maximum(out.past_in, out.past_out))
            if not short.any():
                break
            still |= short
        # a blend ends on a programmed line past its corner's slide, or on a redrawn line d from its moved end
        runs.ua[blends], runs.ub[blends] = el.u1[j] - d + out.past_in, el.u0[j + 1] + d - out.past_out
        for ua, ub, c, w, x in zip(runs.ua[blends], runs.ub[blends], coef, widths, breaks):
            pieces = 2 if x[1] < 1.0 else 1
            blend_parts.append((ua + (ub - ua) * x[:pieces + 1], c[:pieces], w[:pieces]))
        if len(out.line):  # the redrawn lines, between the blends' ends
            redrawn = out.line
            trim = np.zeros(len(el.seg) + 1)
            trim[j + 1] = d
            lead, tail = trim[redrawn], trim[redrawn + 1]
            span = out.end - out.start
            full = np.linalg.norm(span, axis=1)
            coef = np.zeros((len(redrawn), 4, 3))
            coef[:, 0] = out.start + (lead / full)[:, None] * span
            coef[:, 1] = span / full[:, None]
            line_a, line_b = el.u0[redrawn] + lead, el.u1[redrawn] - tail
            blend_parts.append((np.c_[line_a, line_b], coef, full - lead - tail))
    fits = np.flatnonzero(~runs.arc)
    failed = 0
    deviation = 0.0
    if len(fits):
        # knots a fraction of the run's typical segment apart (chords of a gentle curve need fewer), no
        # closer than _KNOT_TOL tolerances and no further apart than _KNOT_MAX
        widths = raw.u1 - raw.u0
        lo_i = np.searchsorted(raw.u1, runs.ua[fits], side="right")
        hi_i = np.searchsorted(raw.u0, runs.ub[fits], side="left")
        typical = range_medians(widths, lo_i, np.maximum(hi_i, lo_i + 1))
        # the penalty: second differences (kind 0), third for jerk-limited plans and for steadily turning runs (1),
        # both on jerk-limited runs of waves and zigzags finer than the tolerance (2)
        steady = _steady(el, runs.first[fits], runs.last[fits])
        kind = np.where(g2, np.where(steady | (typical > _FINE_DETAIL * tolerance), 1, 2), steady.astype(int))
        h = np.clip(_KNOT_SEGMENT * typical, np.where(kind == 2, _KNOT_TOL_FINE, _KNOT_TOL) * tolerance,
                    _KNOT_MAX * tolerance)
        pending = fits
        devs: list[float] = []
        for _attempt in range(_REFINE_KNOTS + 1):  # runs that miss the tolerance are fitted again with finer knots
            missed = []
            for k in range(3):
                these = pending[kind[np.searchsorted(fits, pending)] == k]
                if not len(these):
                    continue
                fit = _RunFitter(raw, runs.ua[these], runs.ub[these], runs.free_a[these], runs.free_b[these], tol_fit,
                                 h[np.searchsorted(fits, these)], order=2 if k == 0 else 3,
                                 ell_segments=_ELL_SEGMENTS_JERK if g2 else _ELL_SEGMENTS,
                                 bend=_BEND if k == 2 else 0.0).fit()
                done = np.flatnonzero(fit.ok)
                for x, pu, coef in _runs_polys(fit, done) if len(done) else []:
                    fit_parts.append((pu, coef, np.diff(x)))
                devs.extend(fit.deviation[done].tolist())
                missed.append(these[~fit.ok])
            pending = np.sort(np.concatenate(missed))
            h *= 0.5
            if not len(pending):
                break
        for r in pending:  # left as programmed: the tool stops at every corner inside
            failed += 1
            inside = (el.u1[:-1] > runs.ua[r]) & (el.u1[:-1] < runs.ub[r])
            stop_extra.append(el.u1[:-1][inside])
            runs.ua[r] = runs.ub[r] = np.nan
        deviation = float(max(devs)) if devs else 0.0
    stops = [np.array([0.0, raw.length]), el.u1[:-1][stop],
             el.u1[:-1][~need & ~stop & (alpha > 0) & _unsmoothable(alpha, period, a_min, v_big)], *stop_extra]

    def assemble(with_blends: bool, stopped: Smoothed | None = None) -> Smoothed:
        b = CurveBuilder()
        for pu, coef, widths in (blend_parts if with_blends else []) + fit_parts:
            b.polys(pu, coef, widths=widths)
        keep = np.isfinite(runs.ua) & (with_blends | ~runs.arc)
        cut_a = np.r_[runs.ua[keep], line_a if with_blends else []]
        cut_b = np.r_[runs.ub[keep], line_b if with_blends else []]
        order = np.argsort(cut_a, kind="stable")
        _copy_outside(raw, b, cut_a[order], cut_b[order])
        curve = b.build(raw.seg_u0)
        # stops: start, end, stop junctions, unsmoothed corners (and lone corners not blended); dwells wait
        # where they are
        stop_u = stops if with_blends else stops + [el.u1[runs.first[blends]]]
        cols = path.columns
        dwell_idx = np.flatnonzero(cols.kind == DWELL)
        su = curve.curve_u(np.concatenate(stop_u + [raw.seg_u0[dwell_idx]]))
        sd = np.concatenate([np.zeros(len(su) - len(dwell_idx)), cols.seconds[dwell_idx]])
        ss = np.concatenate([np.full(len(su) - len(dwell_idx), -1), dwell_idx])
        order = np.lexsort((ss, su))
        n = len(blends) if with_blends else 0
        blend_u = curve.curve_u(np.c_[runs.ua[blends], runs.ub[blends]]) if n else np.zeros((0, 2))
        return Smoothed(curve, su[order], sd[order], ss[order], seg_feed, n, len(fits) - failed, failed,
                        deviation, blend_u, stopped)

    # jerk-limited: the same smoothing with the lone corners stopped at, for the planner to weigh
    return assemble(True, assemble(False) if g2 and len(blends) else None)


def _steady(el: _Elements, first: np.ndarray, last: np.ndarray) -> np.ndarray:
    """Per run (junctions first .. last): whether its net turning is at least _STEADY of its total turning, each
    junction's and each inner element's turning taken as t_a x t_b of its unit tangents (a spiral or an arc of
    short lines: 1; a raster's waves or a Koch curve's zigzags: 0.2-0.4).

    Why: the second-difference penalty (the integral of |p''|^2) pulls against curvature itself, so on a run
    that keeps turning one way it straightens the curve wherever its smoothing is cut (at a run's end held
    straight, where the tolerance is missed), about kappa l^2 off for a smoothing length l, and the cuts
    spread along the run: left with the smoothing of a knot span there, the fit follows the chords and its
    curvature swings with them (a spiral of 4 mm lines, r = 48 mm: kappa r 0.85-1.4). The third-difference
    penalty (the integral of |p'''|^2) does not pull against steady curvature; on waves and zigzags, bending
    is what there is to smooth away, and the second-difference penalty does that better."""
    turn_j = np.cross(el.t1[:-1], el.t0[1:])  # junction j: between elements j and j + 1
    turn_e = np.cross(el.t0, el.t1)
    at_j = np.r_[[np.zeros(3)], np.cumsum(turn_j, axis=0)]
    at_e = np.r_[[np.zeros(3)], np.cumsum(turn_e, axis=0)]
    size_j = np.r_[0.0, np.cumsum(np.linalg.norm(turn_j, axis=1))]
    size_e = np.r_[0.0, np.cumsum(np.linalg.norm(turn_e, axis=1))]
    net = (at_j[last + 1] - at_j[first]) + (at_e[last + 1] - at_e[first + 1])
    total = (size_j[last + 1] - size_j[first]) + (size_e[last + 1] - size_e[first + 1])
    return np.linalg.norm(net, axis=1) >= _STEADY * total


def _unsmoothable(alpha, period, a_min, v_big) -> np.ndarray:
    """Junctions left sharp because their turn is negligible at full speed still pass at speed; none stop."""
    return np.zeros_like(alpha, dtype=bool)
