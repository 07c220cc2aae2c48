"""Feed planning over a whole program: look-ahead junction speeds, and the stop-and-go baseline.

Look-ahead (the ARM paper, 003): every junction gets a speed limit from a selectable rule, a
backward and a forward pass make the junction speeds reachable under the acceleration (and jerk)
limits, and a trapezoid or S-curve profile joins consecutive junctions. The rules:

- ``arm_weighted``: v <= w*a*T / (2 sin(alpha/2)), w from the paper's angle table, so the velocity
  change at a corner within one period stays within w*a.
- ``junction_deviation`` (GRBL): v^2 <= a*delta*cos(alpha/2) / (1 - cos(alpha/2)), the speed of a
  circle of deviation delta tangent to both moves; the sampled path still turns sharply (with the
  trapezoid the turn's velocity change may exceed a*T; S-curves cap it at amax_i*T per axis).
- ``blend``: handed to flowmc.motion.planner: corners and runs of short segments smoothed within the
  tolerance (G64 P Q style, across many segments), then the fastest per-axis time law; jerk-limited
  per axis with ``profile="scurve"``.

At a rule corner passed at speed the profile holds its speed for two periods on each side, so the
sampled acceleration there is the pure direction change the rule bounds (the paper's "first period
only changes the velocity's direction"). Profiles run in continuous time across pieces; setpoints
are taken at t = kT over the whole plan, never rounded per piece.

Stop-and-go: every segment starts and ends at rest, with a trapezoid, exponential or S-curve profile.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np

from flowmc.errors import PlanningError
from flowmc.motion.limits import PathLimits
from flowmc.motion.machine import Machine
from flowmc.motion.path import Path
from flowmc.motion.pieces import DWELL, REVERSAL, Pieces, build_pieces, corner_angle
from flowmc.motion.profiles import Profile, plan_exponential, plan_scurve, plan_trapezoid
from flowmc.motion.sample_clock import setpoint_times
from flowmc.motion.signals import path_signals, program_events, segment_start_times
from flowmc.motion.trajectory import Trajectory

if TYPE_CHECKING:  # the smoothing planner (scipy) loads on first use: `flowmc validate` starts without it
    from flowmc.motion.planner import SmoothPlan

__all__ = [
    "ARM_WEIGHT_TABLE",
    "RULES",
    "LOOKAHEAD_PROFILES",
    "STOP_PROFILES",
    "Plan",
    "arm_weight",
    "arm_junction_speed",
    "junction_deviation_speed",
    "blend_radius",
    "plan_lookahead",
    "plan_stop_and_go",
]

#: The ARM paper's table 1: (upper bound of the direction change in degrees, weight w). A change
#: on a bound (within _EDGE_TOL_DEG, so coordinates rounded by CAM still count) takes the smaller weight.
ARM_WEIGHT_TABLE = ((5.0, 1.0), (15.0, 0.9), (30.0, 0.8), (60.0, 0.7), (90.0, 0.5), (120.0, 0.2), (180.0, 0.0))
_EDGE_TOL_DEG = 1e-4
RULES = ("arm_weighted", "junction_deviation", "blend")
LOOKAHEAD_PROFILES = ("trapezoid", "scurve")
STOP_PROFILES = ("trapezoid", "exponential", "scurve")

_RHO_TRAPEZOID = 0.98  # curved pieces: top speed uses at most this share of A as normal acceleration
_RHO_FIXED = 0.8  # S-curve / exponential: fixed normal share; the tangential budget is the rest
_MERGE = 0.3  # S-curve runs merge tangent pieces whose speed limits are within 30 %
_TINY = 1e-3  # mm: pieces this short never split an S-curve run
_CORNER_SPIKE = 0.01  # a junction is a corner when its turn at speed costs > 1 % of the accel limit


# ---------------------------------------------------------------- junction rules

def arm_weight(alpha) -> np.ndarray:
    """The ARM paper's weight w for a direction change ``alpha`` (radians), vectorised."""
    deg = np.degrees(np.asarray(alpha, dtype=float))
    edges = np.array([edge for edge, _ in ARM_WEIGHT_TABLE[:-1]])
    weights = np.array([w for _, w in ARM_WEIGHT_TABLE])
    return weights[np.searchsorted(edges, deg + _EDGE_TOL_DEG, side="right")]


def arm_junction_speed(alpha, accel, period) -> np.ndarray:
    """v = w(alpha) * a * T / (2 sin(alpha/2)): the speed whose turn changes velocity by w*a*T."""
    alpha = np.asarray(alpha, dtype=float)
    half_sin = np.sin(0.5 * alpha)
    with np.errstate(divide="ignore", invalid="ignore"):
        v = arm_weight(alpha) * np.asarray(accel, dtype=float) * period / (2.0 * half_sin)
    return np.where(half_sin > 0, v, np.inf)


def blend_radius(alpha, tol) -> np.ndarray:
    """Radius of the arc tangent to both moves whose distance from the corner point is ``tol``."""
    half = 0.5 * np.asarray(alpha, dtype=float)
    one_minus_cos = 2.0 * np.sin(0.5 * half) ** 2
    with np.errstate(divide="ignore"):
        return np.where(one_minus_cos > 0, tol * np.cos(half) / one_minus_cos, np.inf)


def junction_deviation_speed(alpha, accel, deviation) -> np.ndarray:
    """GRBL's junction speed: sqrt(a * R) with R the blend radius of deviation ``deviation``."""
    r = np.clip(blend_radius(alpha, deviation), 0.0, None)
    return np.sqrt(np.asarray(accel, dtype=float) * r)


# ---------------------------------------------------------------- the plan value

@dataclass(frozen=True, eq=False)
class Plan:
    """A planned program: the setpoints and what a check needs to judge them.

    ``s[k]`` is the arc length along the planned geometry at setpoint k and ``run[k]`` the profile
    run it lies in (a run is what one profile covers: a piece, a merged chain of pieces for
    S-curves, a segment for stop-and-go). Per run: ``run_vmax`` its speed cap, ``run_accel`` the
    tangential acceleration its profile uses (0 where its speed does not change), ``run_jerk`` its
    jerk limit; ``junction_speed`` the speeds where runs meet; ``corner_times`` the times at which
    the path turns a sharp corner at speed (rule junctions; none when corners are blended).
    """

    trajectory: Trajectory
    s: np.ndarray
    run: np.ndarray
    run_vmax: np.ndarray
    run_accel: np.ndarray
    run_jerk: np.ndarray
    junction_speed: np.ndarray
    corner_times: np.ndarray

    @property
    def cycle_time(self) -> float:
        return self.trajectory.duration


# ---------------------------------------------------------------- runs: what one profile covers

@dataclass
class _Runs:
    first: np.ndarray  # first piece of each run
    last: np.ndarray  # last piece
    length: np.ndarray
    s0: np.ndarray
    vmax: np.ndarray
    accel: np.ndarray  # norm budget A (or tangential limit when kappa == 0)
    kappa: np.ndarray  # 0 unless the tangential budget depends on speed
    jerk: np.ndarray
    dwell: np.ndarray
    vlim: np.ndarray  # junction limits, len(runs) + 1
    corner: np.ndarray  # junction is a rule corner passed at speed: hold 2T each side


def _piece_caps(pieces: Pieces, rho: float) -> tuple[np.ndarray, np.ndarray]:
    """Speed cap per piece with at most ``rho`` of A spent as normal acceleration, and the tangential
    budget left at that cap."""
    curved = pieces.kappa > 0
    cap = pieces.vmax.copy()
    with np.errstate(divide="ignore"):
        cap[curved] = np.minimum(cap[curved], np.sqrt(rho * pieces.accel[curved] / pieces.kappa[curved]))
    a_t = pieces.accel.copy()
    a_t[curved] = np.sqrt(np.maximum(pieces.accel[curved] ** 2 - (cap[curved] ** 2 * pieces.kappa[curved]) ** 2, 0.0))
    return cap, a_t


def _junctions(pieces: Pieces, cap: np.ndarray, rule: str, tol: float, period: float,
               amax: np.ndarray, sampled_turn: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Speed limit and corner flag at each junction between consecutive pieces (len(pieces) - 1).

    ``sampled_turn`` (S-curves, which promise bounded acceleration): every rule's speed is also capped so
    that the turn, made within one period, changes each axis's velocity by at most amax_i T."""
    t_in, t_out = pieces.t_end[:-1], pieces.t_start[1:]
    alpha = corner_angle(t_in, t_out)
    du = t_out - t_in
    norm = np.linalg.norm(du, axis=1, keepdims=True)
    unit = np.abs(du / np.where(norm > 0, norm, 1.0))
    with np.errstate(divide="ignore"):
        a_j = np.min(np.where(unit > 1e-12, amax / np.where(unit > 1e-12, unit, 1.0), np.inf), axis=1)
    a_j = np.where(np.isfinite(a_j), a_j, np.min(amax))
    if rule == "junction_deviation":
        v = junction_deviation_speed(alpha, a_j, tol)
        if sampled_turn:
            with np.errstate(divide="ignore", invalid="ignore"):
                v = np.minimum(v, np.where(alpha > 0, a_j * period / (2.0 * np.sin(0.5 * alpha)), np.inf))
    else:  # arm_weighted, and blend mode's corners that could not be rounded (arcs, curves)
        v = arm_junction_speed(alpha, a_j, period)
        if rule == "blend":
            cut = arm_weight(alpha) * a_j * period**2 / 4.0
            v = np.where(cut <= tol, v, 0.0)
    v = np.minimum(v, np.minimum(cap[:-1], cap[1:]))
    v = np.where((alpha >= REVERSAL) | pieces.stop_after[:-1], 0.0, v)
    corner = (2.0 * np.sin(0.5 * alpha) * v / period > _CORNER_SPIKE * a_j) & (v > 0)
    return v, corner


def _make_runs(pieces: Pieces, groups: list[int], cap, accel, kappa, jv, jcorner) -> _Runs:
    """Runs from group start indices (each group a consecutive stretch of pieces)."""
    first = np.asarray(groups, dtype=int)
    last = np.r_[first[1:] - 1, len(pieces) - 1]
    length = np.add.reduceat(pieces.length, first)
    vmax = np.minimum.reduceat(cap, first)
    acc = np.minimum.reduceat(accel, first)
    jerk = np.minimum.reduceat(pieces.jerk, first)
    kap = np.maximum.reduceat(kappa, first)
    dwell = np.add.reduceat(pieces.dwell, first)
    inner = first[1:] - 1  # junction index between piece first-1 and first
    vlim = np.r_[0.0, jv[inner], 0.0]
    corner = np.r_[False, jcorner[inner], False]
    return _Runs(first, last, length, pieces.s0[first], vmax, acc, kap, jerk, dwell, vlim, corner)


def _group_scurve(pieces: Pieces, cap: np.ndarray, jv: np.ndarray, jcorner: np.ndarray) -> list[int]:
    """Merge tangent pieces with similar speed limits into runs, so one S-curve spans a chain of
    short pieces instead of stopping its acceleration at every chord. Pieces shorter than a micron
    (what is left of a chord between two blends) do not count towards the similarity."""
    groups = [0]
    lo = hi = cap[0]
    kind, tiny = pieces.kind, pieces.length < _TINY
    for p in range(len(pieces) - 1):
        nxt = cap[p + 1]
        new_lo, new_hi = (lo, hi) if tiny[p + 1] else (min(lo, nxt), max(hi, nxt))
        join = (not pieces.stop_after[p] and not jcorner[p] and kind[p] != DWELL and kind[p + 1] != DWELL
                and (tiny[p] or tiny[p + 1] or jv[p] >= min(cap[p], nxt) * (1.0 - 1e-9))
                and new_hi <= (1.0 + _MERGE) * new_lo)
        if join:
            lo, hi = new_lo, new_hi
        else:
            groups.append(p + 1)
            lo = hi = nxt
    return groups


# ---------------------------------------------------------------- backward and forward passes

def _reach_trapezoid(v_known: float, length: float, accel: float, kappa: float) -> float:
    """Largest speed at the other end of a run from which ``v_known`` is reachable, when the
    tangential budget is sqrt(A^2 - (v^2 kappa)^2) at the run's higher speed."""
    c = v_known * v_known
    if kappa == 0.0:
        return math.sqrt(c + 2.0 * length * accel)
    k2 = kappa * kappa
    disc = accel * accel - k2 * c * c + 4.0 * length * length * k2 * accel * accel
    x = (c + 2.0 * length * math.sqrt(max(disc, 0.0))) / (1.0 + 4.0 * length * length * k2)
    return math.sqrt(max(x, c))


def _reach_scurve(v_known: float, length: float, accel: float, jerk: float) -> float:
    """Largest speed whose jerk-limited change to ``v_known`` fits in ``length``."""
    if length <= 0.0:
        return v_known
    p, q = 2.0 * v_known, length * math.sqrt(jerk)
    w = (0.5 * q + math.sqrt(0.25 * q * q + p**3 / 27.0)) ** (1.0 / 3.0)
    u = w - p / (3.0 * w)
    u -= (u**3 + p * u - q) / (3.0 * u * u + p)  # one Newton step against cancellation
    dv = u * u
    if dv > accel * accel / jerk:  # the change needs a constant-acceleration phase
        b = 2.0 * v_known / accel + accel / jerk
        c = 2.0 * v_known * accel / jerk - 2.0 * length
        dv = (-b + math.sqrt(b * b - 4.0 * c / accel)) / (2.0 / accel)
    return v_known + dv


def _reach_with_holds(reach, v_known: float, length: float, hold_known: float, hold_other: float) -> float:
    """``reach`` (speed at the other end of a run, given its free length) when holds at the run's
    corners take ``hold * v`` of its length at their actual speeds. Constant speed always fits."""
    free = length - hold_known * v_known
    if free <= 0.0:
        return v_known
    hi = reach(v_known, free)
    if hold_other == 0.0:
        return hi
    # g(v) = reach(free - hold_other * v) falls with v; g(hi) is feasible, bisect towards v = g(v).
    lo = reach(v_known, max(free - hold_other * hi, 0.0))
    for _ in range(6):
        mid = 0.5 * (lo + hi)
        if reach(v_known, max(free - hold_other * mid, 0.0)) >= mid:
            lo = mid
        else:
            hi = mid
    return max(v_known, lo)


def _passes(runs: _Runs, profile: str, period: float) -> np.ndarray:
    """Junction speeds: limits, then backward (can still slow down) and forward (can get there) passes."""
    v = runs.vlim.tolist()
    cap = runs.vmax.tolist()
    hold = (2.0 * period * runs.corner).tolist()
    lengths, accel, kappa, jerk = (x.tolist() for x in (runs.length, runs.accel, runs.kappa, runs.jerk))
    n = len(lengths)
    for r in range(n):
        v[r + 1] = min(v[r + 1], cap[r], cap[r + 1] if r + 1 < n else 0.0)
    v[0] = 0.0
    if profile == "scurve":
        fns = [lambda vk, free, a=accel[r], j=jerk[r]: _reach_scurve(vk, free, a, j) for r in range(n)]
    else:
        fns = [lambda vk, free, a=accel[r], k=kappa[r]: _reach_trapezoid(vk, free, a, k) for r in range(n)]
    for r in range(n - 1, -1, -1):
        reach = _reach_with_holds(fns[r], v[r + 1], lengths[r], hold[r + 1], hold[r])
        v[r] = min(v[r], reach)
    for r in range(n):
        reach = _reach_with_holds(fns[r], v[r], lengths[r], hold[r], hold[r + 1])
        v[r + 1] = min(v[r + 1], reach)
    return np.asarray(v)


# ---------------------------------------------------------------- profiles as phase tables

@dataclass
class _Phases:
    """Phases of all runs in time order. A polynomial phase starts at speed ``v0`` and acceleration
    ``a0`` with constant ``jerk``; an exponential one (``ratio`` > 0, profiles.plan_exponential's
    shape) changes speed by ``dv`` as (1 - exp(-ratio x)) / (1 - exp(-ratio)), x = time / duration."""

    dur: np.ndarray
    v0: np.ndarray
    a0: np.ndarray
    jerk: np.ndarray
    dv: np.ndarray
    ratio: np.ndarray
    run: np.ndarray
    s_start: np.ndarray | None = None

    def distance(self, tau: np.ndarray, idx: np.ndarray) -> np.ndarray:
        """Distance covered ``tau`` seconds into phases ``idx``."""
        d = tau * (self.v0[idx] + tau * (0.5 * self.a0[idx] + tau * self.jerk[idx] / 6.0))
        expo = np.flatnonzero(self.ratio[idx] > 0)
        if len(expo):
            k = idx[expo]
            r, dur, t = self.ratio[k], self.dur[k], tau[expo]
            x = t / dur
            c = 1.0 / (1.0 - np.exp(-r))
            d[expo] = self.v0[k] * t + self.dv[k] * c * dur * (x - (1.0 - np.exp(-r * x)) / r)
        return d


def _stack(columns: list[tuple], runs_n: int) -> _Phases:
    """Polynomial phases from per-run columns (dur, v0, a0, jerk), each an array over the runs;
    the phases of run r come out consecutively."""
    def col(i):
        return np.stack([np.broadcast_to(c[i], (runs_n,)) for c in columns], axis=1).ravel()

    zero = np.zeros(runs_n * len(columns))
    return _Phases(col(0), col(1), col(2), col(3), zero, zero.copy(), np.repeat(np.arange(runs_n), len(columns)))


def _profile_phases(profiles: list[Profile]) -> _Phases:
    """Phases from profiles.py profiles, one per run."""
    cols: dict[str, list[np.ndarray]] = {name: [] for name in ("dur", "v0", "a0", "jerk", "dv", "ratio", "run")}
    for r, prof in enumerate(profiles):
        m = len(prof.seg_v)
        cols["dur"].append(np.diff(prof.t))
        cols["v0"].append(prof.seg_v)
        cols["a0"].append(prof.seg_a)
        cols["jerk"].append(prof.seg_j)
        cols["dv"].append(prof.seg_dv)
        cols["ratio"].append(np.where(prof.seg_expo, prof.ratio, 0.0))
        cols["run"].append(np.full(m, r))
    return _Phases(*(np.concatenate(cols[name]) for name in ("dur", "v0", "a0", "jerk", "dv", "ratio", "run")))


def _trapezoid_phases(runs: _Runs, v: np.ndarray, period: float) -> tuple[_Phases, np.ndarray]:
    v0, v1 = v[:-1], v[1:]
    h0, h1 = 2.0 * period * runs.corner[:-1], 2.0 * period * runs.corner[1:]
    free = runs.length - h0 * v0 - h1 * v1
    tight = free < 0  # holds overlap: the run keeps its (equal) end speeds throughout
    h0, h1 = np.where(tight, 0.0, h0), np.where(tight, 0.0, h1)
    free = np.where(tight, runs.length, free)
    lo = np.maximum(v0, v1)
    big_a, k = runs.accel, runs.kappa
    ssum = v0**2 + v1**2
    disc = 4 * big_a**2 - k**2 * ssum**2 + 4 * free**2 * k**2 * big_a**2
    x = (ssum + free * np.sqrt(np.maximum(disc, 0.0))) / (2.0 * (1.0 + free**2 * k**2))
    vp = np.clip(np.sqrt(x), lo, np.where(tight, lo, np.maximum(runs.vmax, lo)))
    a = np.sqrt(np.maximum(big_a**2 - (vp**2 * k) ** 2, 0.0))
    a = np.where(a > 0, a, 1.0)  # only when vp == v0 == v1: no speed change, the value is unused
    t_acc, t_dec = (vp - v0) / a, (vp - v1) / a
    cruise_d = free - (2 * vp**2 - ssum) / (2 * a)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_cruise = np.where(vp > 0, np.maximum(cruise_d, 0.0) / vp, 0.0)
    zero = np.zeros_like(v0)
    phases = _stack([(h0, v0, zero, zero), (t_acc, v0, a, zero), (t_cruise, vp, zero, zero),
                     (t_dec, vp, -a, zero), (h1, v1, zero, zero)], len(v0))
    return phases, np.where(vp > np.minimum(v0, v1), a, 0.0)


def _scurve_times(dv, accel, jerk):
    """Jerk-ramp and constant-acceleration times of a symmetric S-curve speed change dv >= 0."""
    short = dv <= accel**2 / jerk
    tj = np.where(short, np.sqrt(np.maximum(dv, 0.0) / jerk), accel / jerk)
    ta = np.where(short, 0.0, dv / accel - accel / jerk)
    return tj, ta


def _scurve_distance(v_from, v_to, accel, jerk):
    tj, ta = _scurve_times(np.abs(v_to - v_from), accel, jerk)
    return 0.5 * (v_from + v_to) * (2.0 * tj + ta)


def _scurve_phases(runs: _Runs, v: np.ndarray, period: float) -> tuple[_Phases, np.ndarray]:
    v0, v1, a, j = v[:-1], v[1:], runs.accel, runs.jerk
    h0, h1 = 2.0 * period * runs.corner[:-1], 2.0 * period * runs.corner[1:]
    free = runs.length - h0 * v0 - h1 * v1
    tight = free < 0
    h0, h1 = np.where(tight, 0.0, h0), np.where(tight, 0.0, h1)
    free = np.where(tight, runs.length, free)
    lo = np.maximum(v0, v1)
    hi = np.where(tight, lo, np.maximum(runs.vmax, lo))

    def need(vp):
        return _scurve_distance(v0, vp, a, j) + _scurve_distance(vp, v1, a, j)

    vp = hi.copy()
    short = need(hi) > free
    if np.any(short):
        lo_b, hi_b = lo[short].copy(), hi[short].copy()
        sub = lambda x: _scurve_distance(v0[short], x, a[short], j[short]) + _scurve_distance(  # noqa: E731
            x, v1[short], a[short], j[short])
        for _ in range(60):
            mid = 0.5 * (lo_b + hi_b)
            fits = sub(mid) <= free[short]
            lo_b, hi_b = np.where(fits, mid, lo_b), np.where(fits, hi_b, mid)
        vp[short] = lo_b
    tj1, ta1 = _scurve_times(vp - v0, a, j)
    tj2, ta2 = _scurve_times(vp - v1, a, j)
    ap1, ap2 = j * tj1, j * tj2
    cruise_d = free - need(vp)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_cruise = np.where(vp > 0, np.maximum(cruise_d, 0.0) / vp, 0.0)
    # Speeds at phase starts (acceleration side, then deceleration side).
    va1 = v0 + 0.5 * j * tj1**2
    va2 = va1 + ap1 * ta1
    vd1 = vp - 0.5 * j * tj2**2
    vd2 = vd1 - ap2 * ta2
    zero = np.zeros_like(v0)
    phases = _stack([
        (h0, v0, zero, zero),
        (tj1, v0, zero, j), (ta1, va1, ap1, zero), (tj1, va2, ap1, -j),
        (t_cruise, vp, zero, zero),
        (tj2, vp, zero, -j), (ta2, vd1, -ap2, zero), (tj2, vd2, -ap2, j),
        (h1, v1, zero, zero),
    ], len(v0))
    return phases, np.maximum(ap1, ap2)


# ---------------------------------------------------------------- sampling at t = kT

def _sample(pieces: Pieces, runs: _Runs, phases: _Phases, path: Path, machine: Machine, cols: list[int],
            v: np.ndarray, accel_used: np.ndarray) -> Plan:
    period = machine.period
    # Dwells are phases of their own (speed 0 for the dwell time) inside their zero-length run.
    dwell_runs = np.flatnonzero(runs.dwell > 0)
    if len(dwell_runs):
        first_phase = np.searchsorted(phases.run, dwell_runs)
        phases.dur[first_phase] += runs.dwell[dwell_runs]
    starts = np.cumsum(np.r_[0.0, phases.dur])
    total = float(starts[-1])
    seg_d = phases.distance(phases.dur, np.arange(len(phases.dur)))
    # s at each phase start: the run's s0 plus what earlier phases of the run covered.
    cum = np.cumsum(seg_d)
    run_first = np.searchsorted(phases.run, phases.run)
    run_dist = cum - seg_d - (cum[run_first] - seg_d[run_first])
    phases.s_start = runs.s0[phases.run] + run_dist

    t = setpoint_times(total, period, len(cols))
    idx = np.clip(np.searchsorted(starts[:-1], t, side="right") - 1, 0, len(phases.dur) - 1)
    tau_t = np.clip(t - starts[idx], 0.0, phases.dur[idx])
    run = phases.run[idx]
    s = phases.s_start[idx] + phases.distance(tau_t, idx)
    s = np.clip(s, runs.s0[run], runs.s0[run] + runs.length[run])
    piece = np.searchsorted(pieces.s0, s, side="right") - 1
    piece = np.clip(piece, runs.first[run], runs.last[run])
    local = np.clip(s - pieces.s0[piece], 0.0, pieces.length[piece])
    pos = pieces.point_at(piece, local)
    pos[0], pos[-1] = path.start, path.end
    s[-1] = pieces.total_length
    tags = pieces.seg[piece]
    traj = Trajectory(pos[:, cols], period, tags, axes=tuple("XYZ"[c] for c in cols),
                      signals=path_signals(path, segment_start_times(tags, period, len(path))),
                      segment_names=path.segment_names(), segment_rapid=path.segment_rapid(), events=program_events(path))
    corner_times = starts[np.searchsorted(phases.run, np.flatnonzero(runs.corner[1:-1]) + 1)]
    return Plan(traj, s, run, runs.vmax, accel_used, runs.jerk, v, corner_times)


# ---------------------------------------------------------------- planners

def plan_lookahead(path: Path, machine: Machine, rule: Literal["arm_weighted", "junction_deviation", "blend"] = "blend",
                   tolerance: float = 0.05, profile: Literal["trapezoid", "scurve"] = "trapezoid") -> Plan | SmoothPlan:
    """Plan the whole program with look-ahead.

    ``blend`` (the default) smooths corners and runs of short segments within the tolerance and plans the
    fastest per-axis time law along the result (flowmc.motion.planner: a SmoothPlan). The paper's rules
    plan segment by segment with junction speeds, as below (a Plan).

    ``tolerance`` (mm) is the corner tolerance for ``blend`` and GRBL's junction deviation for
    ``junction_deviation``; ``arm_weighted`` needs none. Raises PlanningError for unknown options
    and for paths that cannot be planned (the error names the segment).
    """
    if rule not in RULES:
        raise PlanningError(f"unknown junction rule {rule!r}; choose one of {', '.join(RULES)}", where="planner")
    if profile not in LOOKAHEAD_PROFILES:
        raise PlanningError(f"unknown profile {profile!r}; choose one of {', '.join(LOOKAHEAD_PROFILES)}",
                            where="planner")
    if not (math.isfinite(tolerance) and tolerance > 0):
        raise PlanningError(f"tolerance must be > 0 mm, got {tolerance}", where="planner")
    if rule == "blend":
        from flowmc.motion.planner import plan_smooth

        return plan_smooth(path, machine, tolerance=tolerance, profile=profile)
    lim = PathLimits.of(machine)
    cols, amax = list(lim.cols), lim.amax
    pieces = build_pieces(path, machine, blend_tol=tolerance if rule == "blend" else None)
    period = machine.period
    if profile == "trapezoid":
        cap, _ = _piece_caps(pieces, _RHO_TRAPEZOID)
        accel, kappa = pieces.accel, pieces.kappa
        jv, jcorner = _junctions(pieces, cap, rule, tolerance, period, amax)
        groups = list(range(len(pieces)))
    else:
        cap, accel = _piece_caps(pieces, _RHO_FIXED)
        kappa = np.zeros(len(pieces))
        jv, jcorner = _junctions(pieces, cap, rule, tolerance, period, amax, sampled_turn=True)
        groups = _group_scurve(pieces, cap, jv, jcorner)
    runs = _make_runs(pieces, groups, cap, accel, kappa, jv, jcorner)
    v = _passes(runs, profile, period)
    runs.corner &= v > 0
    if profile == "trapezoid":
        phases, used = _trapezoid_phases(runs, v, period)
    else:
        phases, used = _scurve_phases(runs, v, period)
    return _sample(pieces, runs, phases, path, machine, cols, v, used)


def plan_stop_and_go(path: Path, machine: Machine,
                     profile: Literal["trapezoid", "exponential", "scurve"] = "trapezoid") -> Plan:
    """Plan every segment on its own, from rest to rest (the baseline look-ahead is measured against)."""
    if profile not in STOP_PROFILES:
        raise PlanningError(f"unknown profile {profile!r}; choose one of {', '.join(STOP_PROFILES)}",
                            where="planner")
    cols = list(PathLimits.of(machine).cols)
    pieces = build_pieces(path, machine)
    cap, accel = _piece_caps(pieces, _RHO_FIXED)
    groups = np.flatnonzero(np.r_[True, pieces.seg[1:] != pieces.seg[:-1]]).tolist()
    n_j = len(pieces) - 1
    runs = _make_runs(pieces, groups, cap, accel, np.zeros(len(pieces)), np.zeros(n_j), np.zeros(n_j, bool))
    profiles = []
    for length, vmax, a, j in zip(runs.length.tolist(), runs.vmax.tolist(), runs.accel.tolist(), runs.jerk.tolist()):
        if length == 0.0:  # a dwell: its time is added by the sampler
            profiles.append(plan_trapezoid(0.0, 0.0, 0.0, 1.0, 1.0))
        elif profile == "trapezoid":
            profiles.append(plan_trapezoid(length, 0.0, 0.0, vmax, a))
        elif profile == "exponential":
            profiles.append(plan_exponential(length, 0.0, 0.0, vmax, a))
        else:
            profiles.append(plan_scurve(length, 0.0, 0.0, vmax, a, j))
    used = np.array([0.0 if p.length == 0 else (a if p.v_peak > 0 else 0.0) for p, a in zip(profiles, runs.accel)])
    return _sample(pieces, runs, _profile_phases(profiles), path, machine, cols, np.zeros(len(groups) + 1), used)
