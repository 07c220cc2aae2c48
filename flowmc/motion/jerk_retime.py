"""Jerk-limited retiming where the point-by-point caps of the S-curve time law bind: sequential linear programs.

flowmc.motion.timelaw leaves room for each term of an axis's jerk, T_i da/dt + 3 K_i v a + P3_i v^3, at
its worst, point by point: the speed so that |P3_i| v^3 fits alone. On dense, tightly curved code
(flowsnake) that term holds the speed far down, while a motion whose path speed swings within each wiggle
lets the tangential terms cancel it. This pass treats the terms jointly along the curve, on every moving
stretch (between rests) where the curvature-change term is what holds the speed.

With u = v^2 as a function of the arc length s, a = u'/2 and da/dt = v u''/2, so axis i's jerk is
    J_i = sqrt(u) L_i(u),   L_i(u) = T_i u''/2 + 3/2 K_i u' + P3_i u,   L_i linear in u.
|J_i| <= jmax_i reads +-L_i(u) <= jmax_i / sqrt(u): a linear function below a convex one. Replacing the
convex side by its tangent at the current profile u0 (which lies below it) gives a linear constraint
whose every solution keeps the true one: the convex-concave procedure, each iterate feasible, as in
Debrouwere, Van Loock, Pipeleers, Dinh, Diehl, De Schutter and Swevers, "Time-optimal path following
for robots with convex-concave constraints using sequential convex programming" (IEEE T-RO 29, 2013),
which treats jerk this way in b = ds/dt^2. Per-axis acceleration T_i u'/2 + K_i u and velocity are
linear in u already. The time, the sum of ds / sqrt(u), is linearised at u0 within a trust region
(u within a share of u0), and every round is one sparse linear program (scipy's HiGHS).

u(s) is a uniform quadratic B-spline (a continuous, u'' piecewise constant), its control points the
unknowns, spaced about three sampling periods' travel; the constraints are held at several points of
each piece, with the geometry evaluated there. The stretch starts and ends on the S-curve plan's own
motion (three control points fixed to it at each end), and the samples before and after are the plan's,
shifted in time. The result is kept only if its sampled setpoints keep every axis within its jerk,
acceleration and velocity limits (checked here, from the samples) and it is faster; where they break one, the
stretch is retimed again without the part about the break, which runs as planned. Around the jerk-limited
corner blends of flowmc.motion.smoothing the time law holds the speed at its lowest over the whole blend;
there the stretches run from the top speed before a blend to the top speed after it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flowmc.motion.curve import PlannedCurve
from flowmc.motion.limits import PathLimits
from flowmc.motion.ranges import ranks
from flowmc.motion.sample_clock import sample_times
from flowmc.motion.timelaw import TimeLaw, _phases, _phases_of, arc_length_at, frame, speed_at

__all__ = ["Effort", "PLANNED", "retime_curvature_bound"]

_JERK_SHARE = 0.985  # the programs aim at this share of jmax at their points (the samples are checked against 1)
_ACCEL_SHARE = 0.999
_SUB = np.arange(4) / 3  # where in each piece of the spline the constraints are held (with three, a stretch of the
# small Gosper curve of the tests broke the jerk limit between them and was left as planned)
_FINE, _FINE_MAX = 8, 512  # constant-acceleration steps per piece when sampling the result
_BLEND_REACH = 4.0  # windows around corner blends reach this many filter lengths Tj either side, at most
_CHUNK = 800  # control points per linear program
_P3_BOUND, _BOUND_SHARE = 0.5, 0.5  # a stretch is retimed where |P3_i| v^3 is over _P3_BOUND of jmax on at
# least _BOUND_SHARE of its samples: flowsnake's do; 3D_Chips's 100-odd stretches with a tenth or more
# would gain 2.6 % (1.266 -> 1.233 of the trapezoid) for ten times the planning time
_MIN_SAMPLES = 50
_MIN_SHARE = 0.01  # the stretches retimed make up at least this share of the plan's time
_SETTLED = 0.5  # the retimed part runs where the speed is over this share of the stretch's median
_SPLIT_GAP = 25  # samples either side of where a retimed stretch broke a limit that are left as planned
_END_FIT = 3  # samples each side of a stretch's ends the boundary state (u, u', u'') is fitted on


@dataclass(frozen=True)
class Effort:
    """How hard the linear programs work: control points ``step_periods`` sampling periods' travel apart, at most
    ``rounds`` rounds, a further one only while the last gained ``gain`` of the stretch's (linearised) time or
    more, each keeping u within ``trust`` of the last. The planner's (PLANNED) is what dense code affords;
    benchmarks/retime_bound.py asks for more, to see how far a plan is from the best retiming of its curve."""

    step_periods: float = 3.0
    rounds: int = 2
    gain: float = 0.005
    trust: float = 0.5


# flowsnake: 5.829 s of motion; more rounds or a wider trust region gain at most 0.2 %, controls two periods apart
# 0.7 % for about twice the planning time, one period apart 1.2 % for ten times (benchmarks/retime_bound.py)
PLANNED = Effort()


def retime_curvature_bound(law: TimeLaw, curve: PlannedCurve, lim: PathLimits, feed_of_u,
                           period: float, blend_u: np.ndarray | None = None, effort: Effort = PLANNED
                           ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Curve parameter, dwell segment (-1 elsewhere) and position at t = kT of ``law``'s motion with every
    stretch where the curvature-change term holds the speed retimed (module docstring), and every corner
    blend (``blend_u``: curve parameter ranges (n, 2)) from the top speed before it to the top speed after
    it; None if no stretch is, they are under _MIN_SHARE of the plan's time, or none gains.
    Every sample keeps each axis's velocity, acceleration and jerk (finite differences) within its limit:
    a stretch whose samples would not is left as planned."""
    cols = list(lim.cols)
    blend_u = np.zeros((0, 2)) if blend_u is None else blend_u
    # first, on the time law's own grid (far fewer points than samples): does the term hold the speed anywhere?
    _, _, p3, _ = frame(curve, law.u, curve.interval_at(law.u))
    p3_share = np.max(np.abs(p3[:, cols]) / lim.jmax[cols], axis=1)
    if not len(blend_u) and not np.any(p3_share * np.maximum(law.y, 0.0) ** 1.5 > _P3_BOUND):
        return None
    ph = _phases(law)
    total = float(ph.start[-1] + ph.dur[-1]) + law.window
    ts = sample_times(total, period)
    n = len(ts) - 1
    s, seg = arc_length_at(law, ph, ts)
    v = speed_at(law, ph, ts)
    moving = (v > 1e-9 * max(float(v.max()), 1.0)) & (seg < 0)
    edges = np.flatnonzero(np.diff(np.r_[0, moving.astype(np.int8), 0]))
    stretches = [(a + k0, a + k1) for a, b in zip(edges[::2], edges[1::2]) if b - a >= _MIN_SAMPLES
                 for k0, k1 in _settled(v[a:b])]
    # the term at every sample, its geometry interpolated on the time law's grid (about as dense as the samples
    # where the speed is low; on 3D_Chips, evaluating the curve at every sample of its 140 stretches cost 0.25 s)
    over = np.interp(s, law.s, p3_share) * v ** 3 > _P3_BOUND
    bound_stretches = []
    for k0, k1 in stretches:
        bound = np.flatnonzero(over[k0:k1 + 1])
        if len(bound) < _BOUND_SHARE * (k1 - k0 + 1):
            continue
        # starting and ending where the term holds the speed keeps the joins off stretches the plan runs
        # at the jerk limit with its own (tangential) motion
        k0, k1 = k0 + int(bound[0]), k0 + int(bound[-1])
        if k1 - k0 >= _MIN_SAMPLES:
            bound_stretches.append((k0, k1))
    at_blends = _around_blends(law, s, v, moving, blend_u)
    bound_stretches = _merged(bound_stretches + at_blends)
    # a retimed stretch gains a share of its own time: where they are all a sliver of the plan, the programs
    # are not worth their cost (3D_Chips: two of 0.29 s gained 14 ms of 188 s for 0.2 s of CPU)
    if sum(k1 - k0 for k0, k1 in bound_stretches) < _MIN_SHARE * n:
        return None

    def retimed(spans: list[tuple[int, int]]) -> list[tuple]:
        out = []
        for k0, k1 in spans:
            strict = any(k0 <= a and b <= k1 for a, b in at_blends)
            win = _retime_stretch(law, curve, lim, feed_of_u, s, v, k0, k1, period, strict, effort)
            if win is not None and win[1] < (k1 - k0) * period * (1.0 - 1e-6):
                out.append((k0, k1, *win))
        return out

    windows = retimed(bound_stretches)
    # a window whose samples (or the joins to the plan's) break a limit is retimed again without the part about
    # them, which is left as planned
    while windows:
        s_new, seg_new, spans = _stitch(law, ph, windows, total, period)
        u = law.u_sampled(s_new, curve)
        pos = curve.points(u)
        bad = _over_limits(pos[:, cols], lim)
        if not len(bad):
            return u, seg_new, pos
        t_bad = bad * period
        keep, split = [], []
        for w, (a, b) in zip(windows, spans):
            hit = (t_bad >= a - 4 * period) & (t_bad <= b + period)
            if hit.any():
                split += _split(w[0], w[1], np.searchsorted(s, s_new[bad[hit]]))
            else:
                keep.append(w)
        if len(keep) == len(windows):
            return None
        windows = sorted(keep + retimed(split), key=lambda w: w[0])
    return None


def _split(k0: int, k1: int, at: np.ndarray) -> list[tuple[int, int]]:
    """The parts of sample range [k0, k1] more than _SPLIT_GAP samples from every sample ``at`` (plan samples
    where its retimed motion broke a limit), each at least _MIN_SAMPLES long."""
    cut = np.sort(np.clip(at, k0, k1))
    lo, hi = np.r_[k0, cut + _SPLIT_GAP], np.r_[cut - _SPLIT_GAP, k1]
    return [(int(a), int(b)) for a, b in zip(lo, hi) if b - a >= _MIN_SAMPLES]


def _around_blends(law: TimeLaw, s: np.ndarray, v: np.ndarray, moving: np.ndarray,
                   blend_u: np.ndarray) -> list[tuple[int, int]]:
    """Sample ranges from the last top of the speed before each corner blend to the first after it (no further
    than _BLEND_REACH filter windows from the blend), within its moving run and clear of the run's ends (the
    boundary state is fitted on samples either side): the time law holds the speed at its lowest over the
    whole blend and half its filter's reach each side, the linear programs let it dip at the blend's middle."""
    if not len(blend_u):
        return []
    top = np.flatnonzero((v[1:-1] >= v[:-2]) & (v[1:-1] > v[2:])) + 1
    reach = int(round(_BLEND_REACH * law.window / law.period))
    edges = np.flatnonzero(np.diff(np.r_[0, moving.astype(np.int8), 0]))
    run_a, run_b = edges[::2] + _END_FIT, edges[1::2] - 1 - _END_FIT
    ka, kb = np.searchsorted(s, np.interp(blend_u, law.u, law.s).T)
    out = []
    for a, b in zip(ka, kb):
        r = np.searchsorted(run_a, a, side="right") - 1
        if r < 0 or b > run_b[r]:
            continue
        before, after = top[top <= a], top[top >= b]
        k0 = max(int(before[-1]) if len(before) else run_a[r], run_a[r], a - reach)
        k1 = min(int(after[0]) if len(after) else run_b[r], run_b[r], b + reach)
        if k1 - k0 >= _MIN_SAMPLES:
            out.append((k0, k1))
    return out


def _merged(spans: list[tuple[int, int]]) -> list[tuple[int, int]]:
    """Sample ranges merged where they overlap or touch, in order."""
    out: list[tuple[int, int]] = []
    for a, b in sorted(spans):
        if out and a <= out[-1][1] + 1:
            out[-1] = (out[-1][0], max(out[-1][1], b))
        else:
            out.append((a, b))
    return out


def _settled(v: np.ndarray) -> list[tuple[int, int]]:
    """First and last sample of every stretch of a moving run at over _SETTLED of the run's median speed
    (where the speed dips towards rest the plan's own motion is kept), clear of the run's ends so the
    boundary state can be fitted on samples either side."""
    fast = np.r_[False, v[1:-1] > _SETTLED * np.median(v), False]
    edges = np.flatnonzero(np.diff(fast.astype(np.int8)))
    out = []
    for a, b in zip(edges[::2] + 1, edges[1::2]):
        a, b = max(int(a), _END_FIT), min(int(b), len(v) - 1 - _END_FIT)
        if b - a >= _MIN_SAMPLES:
            out.append((a, b))
    return out


def _end_state(s: np.ndarray, v: np.ndarray, k: int) -> np.ndarray:
    """u, du/ds and d2u/ds2 of the sampled motion at sample k (a quadratic fitted on the samples around it)."""
    at = slice(k - _END_FIT, k + _END_FIT + 1)
    c = np.polyfit(s[at] - s[k], v[at] ** 2, 2)
    return np.array([c[2], c[1], 2.0 * c[0]])


def _retime_stretch(law, curve, lim, feed_of_u, s, v, k0, k1, period, strict=False, effort=PLANNED):
    """The fastest u(s) found between samples k0 and k1 (a quadratic B-spline, see the module docstring),
    as constant-acceleration phases from s[k0], and how long it takes; None if a program fails. ``strict``:
    each program holds the limits themselves where it can (around corner blends, where the starting profile
    fitted to the plan's samples is over them at points, by up to 6.7 % on zigzag40), else never worse than
    the current profile."""
    d0, d1 = float(s[k0]), float(s[k1])
    pieces = max(8, int(round((d1 - d0) / (effort.step_periods * period * float(np.median(v[k0:k1 + 1]))))))
    h = (d1 - d0) / pieces
    m = pieces + 2  # control points: piece j (1..m-2) is [node_j - h/2, node_j + h/2], node_j = d0 + (j - 1/2) h
    nodes = d0 + (np.arange(m) - 0.5) * h
    c = np.interp(nodes, s[k0 - _END_FIT:k1 + _END_FIT + 1], v[k0 - _END_FIT:k1 + _END_FIT + 1] ** 2)
    # three control points at each end carry the plan's u, u' and u'' there (jerk continuous at the joins)
    ends = []
    for k, sign in ((k0, 1.0), (k1, -1.0)):
        u0, u1, u2 = _end_state(s, v, k)
        inner, outer = u0 + sign * 0.5 * h * u1, u0 - sign * 0.5 * h * u1  # (c_a + c_b)/2 = u0, (c_b - c_a) = h u1
        third = 2.0 * inner - outer + h * h * u2
        ends.append((outer, inner, third))
    c[[0, 1, 2]] = ends[0]
    c[[m - 1, m - 2, m - 3]] = ends[1]
    fixed = np.r_[0, 1, 2, m - 3, m - 2, m - 1]
    # the constraint points: each piece at _SUB (both ends included: u'' steps between pieces), and both sides
    # of every joint of the curve's intervals inside (its third derivative steps there)
    j = np.repeat(np.arange(1, m - 1), len(_SUB))
    x = np.tile(_SUB, m - 2)
    pts = nodes[j] + (x - 0.5) * h
    u = law.u_at(pts, curve)
    index = curve.interval_at(u)
    u_ends = law.u_at(np.array([d0, d1]), curve)
    joint = curve.u0[(curve.u0 > u_ends[0]) & (curve.u0 < u_ends[1])]
    if len(joint):
        k = curve.interval_at(joint)
        at = np.interp(joint, law.u, law.s)
        jj = np.clip(np.floor((at - d0) / h).astype(int) + 1, 1, m - 2)
        u, index = np.r_[u, joint, joint], np.r_[index, k - 1, k]
        j, x = np.r_[j, jj, jj], np.r_[x, np.tile(np.clip((at - d0) / h - (jj - 1), 0.0, 1.0), 2)]
    tan, kv, p3, _ = frame(curve, u, index)
    feed = feed_of_u(u)
    weight = np.r_[np.full((m - 2) * len(_SUB), 1.0 / len(_SUB)), np.zeros(len(x) - (m - 2) * len(_SUB))]
    basis = np.stack([0.5 * (1 - x) ** 2, 0.5 * (1 + 2 * x - 2 * x * x), 0.5 * x * x], axis=1)
    slope = np.stack([-(1 - x), 1 - 2 * x, x], axis=1) / h
    curv = np.tile(np.array([1.0, -2.0, 1.0]) / h**2, (len(x), 1))
    cols3 = j[:, None] + np.arange(-1, 2)[None, :]
    axes = [i for i in lim.cols if np.max(np.abs(tan[:, i])) > 1e-9 or np.max(np.abs(kv[:, i])) > 1e-9]
    lo_c = np.full(m, 1e-12)
    with np.errstate(divide="ignore"):
        vel = np.min([np.where(tan[:, i] != 0, (_ACCEL_SHARE * lim.vmax[i] / np.abs(tan[:, i])) ** 2, np.inf)
                      for i in axes], axis=0)
    vel = np.minimum(vel, feed ** 2)
    import scipy.sparse as sparse  # on first use: scipy.optimize alone costs a fresh process about 0.5 s of CPU
    from scipy.optimize import linprog
    best, best_time = c, np.inf
    for rnd in range(effort.rounds + 1):
        up = (basis * c[cols3]).sum(axis=1)
        if np.any(up <= 0):
            break
        took = h * float(np.sum(weight / np.sqrt(up)))  # the linearised time is not the time: keep the fastest
        gained = best_time - took
        if took < best_time:
            best, best_time = c, took
        if rnd == effort.rounds or gained < effort.gain * best_time:
            break
        lo, hi = np.maximum(c * (1.0 - effort.trust), lo_c), c * (1.0 + effort.trust)
        lo[fixed] = hi[fixed] = c[fixed]
        blocks = []
        for i in axes:
            jmax = _JERK_SHARE * lim.jmax[i]
            lin = 0.5 * jmax * up ** -1.5
            jerk = 0.5 * tan[:, i, None] * curv + 1.5 * kv[:, i, None] * slope + p3[:, i, None] * basis
            acc = 0.5 * tan[:, i, None] * slope + kv[:, i, None] * basis
            for sign in (1.0, -1.0):
                blocks.append((sign * jerk + lin[:, None] * basis, 1.5 * jmax * up ** -0.5))
                blocks.append((sign * acc, np.full(len(x), _ACCEL_SHARE * lim.amax[i])))
        blocks.append((basis, vel))
        vals = np.concatenate([blk for blk, _ in blocks])
        b = np.concatenate([r for _, r in blocks])
        cols_all = np.tile(cols3, (len(blocks), 1))
        # rows no point of the trust region can break are left out (a third of the jerk rows, most others):
        # the program is the same, and HiGHS's time grows with its rows
        reach = np.maximum(vals * lo[cols_all], vals * hi[cols_all]).sum(axis=1) >= b
        vals, b, cols_all = vals[reach], b[reach], cols_all[reach]
        obj = np.zeros(m)
        np.add.at(obj, cols3.ravel(), (-0.5 * up ** -1.5 * weight)[:, None].repeat(3, axis=1).ravel()
                  * basis.ravel())
        # one program per chunk of control points, the others held (a program's cost grows faster than its
        # size); the chunks' joins move by half a chunk every round
        order = np.argsort(cols_all[:, 0], kind="stable")
        vals, b, cols_all = vals[order], b[order], cols_all[order]
        first = cols_all[:, 0]
        shift = (_CHUNK // 2) * (rnd % 2)
        for a in range(-shift, m, _CHUNK):
            a, z = max(a, 0), min(a + _CHUNK, m)
            if z <= a:
                continue
            r0, r1 = np.searchsorted(first, a - 2), np.searchsorted(first, z)
            v_, c_ = vals[r0:r1], cols_all[r0:r1]
            free = (c_ >= a) & (c_ < z)
            held = np.where(free, 0.0, v_ * c[c_]).sum(axis=1)
            rr, cc = np.nonzero(free)
            a_ub = sparse.csr_matrix((v_[rr, cc], (rr, c_[rr, cc] - a)), shape=(r1 - r0, z - a))
            # never worse than the current profile (it may be a hair over where it was interpolated)
            current = np.maximum(b[r0:r1], (v_ * c[c_]).sum(axis=1)) - held
            for rhs_ in ((b[r0:r1] - held, current) if strict else (current,)):
                res = linprog(obj[a:z], A_ub=a_ub, b_ub=rhs_, bounds=np.c_[lo[a:z], hi[a:z]], method="highs-ds",
                              options={"presolve": False})  # presolve finds little in these rows, took half the time
                if res.status == 0:
                    break
            if res.status == 0:
                c = c.copy()
                c[a:z] = np.maximum(res.x, lo_c[a:z])
    c = best
    # each step at most an eighth of a period long (an acceleration step of a longer one would show in the samples)
    slow = np.sqrt(np.maximum(np.minimum(np.minimum(c[:-2], c[1:-1]), c[2:]), 1e-300))
    steps = np.clip(np.ceil(8.0 * h / (period * slow)), _FINE, _FINE_MAX).astype(int)
    fj = np.repeat(np.arange(1, m - 1), steps)
    fine_x = (ranks(steps) - 1) / np.repeat(steps, steps)
    fb = np.stack([0.5 * (1 - fine_x) ** 2, 0.5 * (1 + 2 * fine_x - 2 * fine_x ** 2), 0.5 * fine_x ** 2], axis=1)
    fu = np.r_[(fb * c[fj[:, None] + np.arange(-1, 2)[None, :]]).sum(axis=1), 0.5 * (c[-2] + c[-1])]
    fs = np.r_[nodes[fj] - 0.5 * h + fine_x * h, d1]
    fs[0] = d0
    ph = _phases_of(fs, fu, np.diff(fu) / (2.0 * np.diff(fs)), np.zeros(len(fs)), np.full(len(fs), -1))
    return ph, float(ph.start[-1] + ph.dur[-1])


def _stitch(law, ph, windows, total, period):
    """Samples at t = kT of the plan with each window [k0, k1] (in the plan's samples) replaced by its
    retimed phases; the plan's motion after a window runs later (or earlier) by what the window gained."""
    k0 = np.array([w[0] for w in windows])
    k1 = np.array([w[1] for w in windows])
    dur = np.array([w[3] for w in windows])
    shift = np.cumsum(dur - (k1 - k0) * period)  # after window w
    before = np.r_[0.0, shift[:-1]]
    new_start = k0 * period + before
    new_end = new_start + dur
    ts = sample_times(total + shift[-1], period)
    w = np.searchsorted(new_start, ts, side="right") - 1
    inside = (w >= 0) & (ts <= new_end[np.maximum(w, 0)])
    old_t = ts - np.where(w >= 0, shift[np.maximum(w, 0)], 0.0)
    s, seg = arc_length_at(law, ph, np.clip(old_t, 0.0, total))
    for i in np.unique(w[inside]):
        at = np.flatnonzero(inside & (w == i))
        s[at] = windows[i][2].s(ts[at] - new_start[i])
        seg[at] = -1
    return s, seg, list(zip(new_start, new_end))


def _over_limits(positions: np.ndarray, lim: PathLimits) -> np.ndarray:
    """First samples of every finite difference (velocity, acceleration, jerk) over an axis's limit."""
    cols = list(lim.cols)
    d, over = positions, []
    for limit in (lim.vmax, lim.amax, lim.jmax):
        d = np.diff(d, axis=0) / lim.period
        over.append(np.flatnonzero(np.any(np.abs(d) > limit[cols] * (1.0 + 1e-9), axis=1)))
    return np.unique(np.concatenate(over))
