"""Can any jerk-limited trajectory within the 0.05 mm band run flowsnake in 1.3x the trapezoid's time?

Issue 14 asks S-curve plans (per-axis 5,000 mm/s^3, 200 mm/s^2, 200 mm/s, tolerance 0.05 mm) for at
most 1.3x the trapezoid plan's time on every program; flowsnake (LinuxCNC's sample program: a Koch
curve of 3,072 lines 0.0144 mm long, turning 60 and 120 degrees) is at 1.83x. This answers whether
the target is reachable at all, with the geometry free: a discretised optimal-control problem in
which the positions at every sample are the unknowns, so the curve and the time law are found
together.

For a given duration D = factor x (the trapezoid plan's time on the same lines), on a grid of
period dt: per axis, |first, second, third differences| <= vmax dt, amax dt^2, jmax dt^3 (exactly
the sampled peaks the benchmarks report), rest (zero velocity and acceleration) at both ends; every
sample inside the tolerance capsule of the programmed line nearest to it in the previous iterate
(a 16-sided polygon inscribed in the capsule), and every point of the programmed lines (at most 6 um
apart) within the tolerance of the nearest chord of the samples, at the point of it nearest in the
previous iterate (an inscribed 16-gon; every fifth of the points within 0.015 mm of losing it held, and
any the last round lost, the rest checked after). Band violations carry an L1
penalty; each round is one linear program (scipy's HiGHS), and the nearest lines are re-assigned
between rounds (sequential convex programming) until the samples keep the tolerance both ways,
measured exactly as benchmarks/cam_programs.py measures plans (flowmc.motion.metrics: every chord
to the programmed path, every programmed point to the sampled path). The first duration starts
from the trapezoid plan's setpoints (or ``--init``) stretched uniformly to D, each later one from the
last trajectory found.

A ``yes`` is a proof by construction: the samples printed keep every limit and the tolerance both
ways. A ``no`` only says this local method found none from that start.

With ``--no-jerk`` it asks the trapezoid question of issue 14 (0.90 x LinuxCNC) on 3dtest's three circles
(``annulus_trajectory``: each rest to rest, joined to the plan's samples either side) and on spiral turn by
turn (``convex_band_trajectory``: windows of the plan's 1 ms samples, their first and last two kept, so the
periods each saves add up); both print the whole program measured as cam_programs.py measures plans.

    python3 benchmarks/scurve_bound.py [--dt 0.002] [--factors 1.3 1.25] [--rounds 12] [--save X.npy]
    python3 benchmarks/scurve_bound.py --dt 0.001 --init X.npy   # at 1 ms, from the 2 ms trajectory
    python3 benchmarks/scurve_bound.py 3dtest --no-jerk --dt 0.001 --factors 0.995 0.9942 --rounds 6
    python3 benchmarks/scurve_bound.py spiral --no-jerk --dt 0.001 --saves 4 8 12 16 --rounds 6
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path as FsPath

import numpy as np
import scipy.sparse as sp
from scipy.optimize import linprog
from scipy.spatial import cKDTree

sys.path.insert(0, str(FsPath(__file__).parent))
import cam_programs as cam  # noqa: E402

from flowmc.devices.linuxcnc.compare import flowmc_feed_time  # noqa: E402
from flowmc.motion.metrics import contour_error, farthest_from  # noqa: E402
from flowmc.motion.path import Path  # noqa: E402
from flowmc.motion.planner import plan_smooth  # noqa: E402

VMAX, AMAX, JMAX, TOL = 200.0, 200.0, cam.JERK, cam.TOL
_UM = 1000.0  # the linear programs are posed in micrometres


def _polygon(sides: int) -> tuple[np.ndarray, float]:
    """Face normals of a ``sides``-gon and the face distance that keeps it inside the tolerance circle."""
    ang = 2 * np.pi * (np.arange(sides) + 0.5) / sides
    return np.c_[np.cos(ang), np.sin(ang)], TOL * np.cos(np.pi / sides) * 0.995


class Band:
    """The programmed lines (XY) and nearest-line look-ups."""

    def __init__(self, vertices: np.ndarray):
        self.v = vertices
        self.a, self.b = vertices[:-1], vertices[1:]
        n = np.maximum(1, np.ceil(np.linalg.norm(self.b - self.a, axis=1) / 0.002).astype(int))
        frac = np.concatenate([np.arange(k) / k for k in n])
        self.owner = np.repeat(np.arange(len(self.a)), n)
        self.dense = np.vstack([self.a[self.owner] + frac[:, None] * (self.b - self.a)[self.owner], vertices[-1:]])
        self.owner = np.r_[self.owner, len(self.a) - 1]
        self.tree = cKDTree(self.dense)
        self.check = np.vstack([self.a[self.owner[:-1]] + frac[:, None] * (self.b - self.a)[self.owner[:-1]],
                                vertices[-1:]])[::3]  # 6 um apart: the points that must stay covered

    def hold_cover_between(self, first: np.ndarray, last: np.ndarray) -> None:
        """Only the programmed points between the points nearest ``first`` and ``last`` are this band's to
        cover (a window of a longer trajectory: the samples outside it cover the rest)."""
        (j0, j1) = self.tree.query(np.vstack([first, last]))[1]
        idx = np.r_[np.arange(0, len(self.dense) - 1, 3), len(self.dense) - 1][:len(self.check)]
        self.check = self.check[(idx >= j0) & (idx <= j1)]

    def _dist(self, x, i):
        a, d = self.a[i], self.b[i] - self.a[i]
        t = np.clip(((x - a) * d).sum(1) / np.maximum((d * d).sum(1), 1e-30), 0.0, 1.0)
        return np.linalg.norm(x - (a + t[:, None] * d), axis=1)

    def nearest_line(self, x: np.ndarray) -> np.ndarray:
        _, j = self.tree.query(x)
        cand = np.clip(self.owner[j][:, None] + np.arange(-3, 4)[None, :], 0, len(self.a) - 1)
        d = np.stack([self._dist(x, cand[:, m]) for m in range(cand.shape[1])], axis=1)
        return cand[np.arange(len(x)), d.argmin(1)]

    def deviation(self, x: np.ndarray) -> tuple[float, float]:
        """(samples' chords to the lines, the lines to the sampled path), as the benchmarks measure plans."""
        x3, v3 = np.c_[x, np.zeros(len(x))], np.c_[self.v, np.zeros(len(self.v))]
        return contour_error(x3, v3), farthest_from(x3, np.c_[self.check, np.zeros(len(self.check))])


def _differences(n: int, dt: float, jerk: bool):
    rows, rhs = [], []
    for k, lim in ((1, VMAX * dt), (2, AMAX * dt**2)) + (((3, JMAX * dt**3),) if jerk else ()):
        d = sp.eye(n, format="csr")
        for _ in range(k):
            d = d[1:] - d[:-1]
        for axis in range(2):
            da = sp.kron(d, sp.csr_matrix(np.eye(2)[axis:axis + 1]))
            rows += [da, -da]
            rhs += [np.full(d.shape[0], lim)] * 2
    return sp.vstack(rows).tocsr(), np.concatenate(rhs)


def _polygon_rows(normals: np.ndarray, k: np.ndarray, lam: np.ndarray, nvar: int, slack0: int, slack_of: np.ndarray):
    """Rows n_m . ((1 - lam) x_k + lam x_k+1) - e <= h for every face m of the polygon and every i (k = k[i])."""
    n, sides = len(k), len(normals)
    r = np.repeat(np.arange(n * sides), 4)
    cols = np.c_[2 * k, 2 * k + 1, 2 * k + 2, 2 * k + 3]
    cols = np.repeat(np.minimum(cols, nvar - 1), sides, axis=0).ravel()
    nm = np.tile(normals, (n, 1))
    w = np.repeat(np.c_[1 - lam, 1 - lam, lam, lam], sides, axis=0)
    vals = (np.c_[nm, nm] * w).ravel()
    pos = sp.csr_matrix((vals, (r, cols)), shape=(n * sides, nvar))
    pos.eliminate_zeros()
    slack = sp.csr_matrix((np.ones(n * sides), (np.arange(n * sides), slack0 + np.repeat(slack_of, sides))),
                          shape=(n * sides, nvar))
    return pos - slack


def _nearest_chord(x: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For each point, the chord (its first sample k) of the sampled path nearest it, where along it (lam)
    and how far: the programmed points are held within the tolerance of the tool path, as measured."""
    _, j = cKDTree(x).query(points)
    best = None
    for k in (np.clip(j - 1, 0, len(x) - 2), np.clip(j, 0, len(x) - 2)):
        d = x[k + 1] - x[k]
        lam = np.clip(((points - x[k]) * d).sum(1) / np.maximum((d * d).sum(1), 1e-30), 0.0, 1.0)
        dist = np.linalg.norm(points - (x[k] + lam[:, None] * d), axis=1)
        if best is None:
            best = (k, lam, dist)
        else:
            pick = dist < best[2]
            best = tuple(np.where(pick, new, old) for new, old in zip((k, lam, dist), best))
    return best


def band_trajectory(band: Band, x0: np.ndarray, dt: float, *, jerk: bool = True, rounds: int = 12, hold: int = 3,
                    sides: int = 16, reach: float = 0.3, log=print) -> tuple[np.ndarray, int]:
    """Sequential linear programs from ``x0`` (samples, dt apart) with its first and last ``hold`` samples kept
    (3 at rest: velocity and acceleration zero; 2 for a trapezoid), each sample moving at most ``reach`` (mm, per
    axis) in a round; the last samples and the rounds used."""
    n, x = len(x0), x0.copy()
    nx = 2 * n
    normals, inscribed = _polygon(sides)
    dyn, dyn_rhs = _differences(n, dt, jerk)
    for rnd in range(1, rounds + 1):
        t0 = time.perf_counter()
        line = band.nearest_line(x)
        chord, lam, dist = _nearest_chord(x, band.check)
        # the programmed points the samples may lose: every fifth of them (30 um apart) and any the last round lost
        cover = np.flatnonzero((dist > 0.7 * TOL) & ((np.arange(len(dist)) % 5 == 0) | (dist > inscribed)))
        nvar = nx + n + len(cover)
        tube = _polygon_rows(normals, np.arange(n), np.zeros(n), nvar, nx, np.arange(n))
        tube_rhs = np.maximum(band.a[line] @ normals.T, band.b[line] @ normals.T).ravel() + inscribed
        # the polygon's faces alone bound a larger set than the line swept by the polygon: add the line's own
        # normal (both ways) at the polygon's support along it, so each sample is in the Minkowski sum
        d = band.b[line] - band.a[line]
        u = np.c_[-d[:, 1], d[:, 0]] / np.maximum(np.linalg.norm(d, axis=1), 1e-30)[:, None]
        u = np.vstack([u, -u])
        ks = np.r_[np.arange(n), np.arange(n)]
        side = sp.csr_matrix((u.ravel(), (np.repeat(np.arange(2 * n), 2), np.c_[2 * ks, 2 * ks + 1].ravel())),
                             shape=(2 * n, nvar)) - sp.csr_matrix((np.ones(2 * n), (np.arange(2 * n), nx + ks)),
                                                                  shape=(2 * n, nvar))
        vertices = inscribed / np.cos(np.pi / sides) * np.c_[np.cos(2 * np.pi * np.arange(sides) / sides),
                                                             np.sin(2 * np.pi * np.arange(sides) / sides)]
        side_rhs = (u * np.r_[band.a[line], band.a[line]]).sum(1) + (u @ vertices.T).max(1)
        tube, tube_rhs = sp.vstack([tube, side]), np.r_[tube_rhs, side_rhs]
        cov = _polygon_rows(normals, chord[cover], lam[cover], nvar, nx + n, np.arange(len(cover)))
        cov_rhs = (band.check[cover] @ normals.T).ravel() + inscribed
        a_ub = sp.vstack([sp.hstack([dyn, sp.csr_matrix((dyn.shape[0], nvar - nx))]), tube, cov]).tocsc()
        lo = np.r_[x.ravel() - reach, np.zeros(nvar - nx)]
        hi = np.r_[x.ravel() + reach, np.full(nvar - nx, np.inf)]
        lo[:2 * hold] = hi[:2 * hold] = x0[:hold].ravel()  # the state at both ends is kept
        lo[nx - 2 * hold:nx] = hi[nx - 2 * hold:nx] = x0[n - hold:].ravel()
        # solved in um, so HiGHS's 1e-7 feasibility tolerance is 1e-10 mm, not 2 % of jmax dt^3 at 1 ms
        res = linprog(np.r_[np.zeros(nx), np.ones(nvar - nx)], A_ub=a_ub,
                      b_ub=_UM * np.r_[dyn_rhs, tube_rhs, cov_rhs], bounds=_UM * np.c_[lo, hi], method="highs")
        if res.status != 0:
            log(f"    round {rnd}: {res.message}")
            return x, rnd
        x = res.x[:nx].reshape(-1, 2) / _UM
        to_path, from_path = band.deviation(x)
        log(f"    round {rnd}: band violation {res.fun / _UM:.2e} mm, deviation {to_path:.4f} / {from_path:.4f} mm, "
            f"{len(cover)} points held, {time.perf_counter() - t0:.0f} s")
        if max(to_path, from_path) <= TOL:
            return x, rnd
    return x, rounds


def annulus_trajectory(center: np.ndarray, radius: float, x0: np.ndarray, dt: float, *, rounds: int = 12,
                       hold: int = 2, faces: int = 720, log=print) -> tuple[np.ndarray, int]:
    """``band_trajectory`` for a full circle, trapezoid limits: every sample within ``radius`` +- (TOL less the
    programmed chords' 1e-4 mm and 3e-4 mm for the samples' chords), which, the samples going round once, keeps
    the tolerance both ways. The outer bound is the nearest ``faces``-gon's faces (each sample's own and 8 each
    side), the inner one the tangent at the last round's angle; so samples may slide along the circle by mm in a
    round, where the capsules of the programmed 0.12 mm chords pin them."""
    n, x = len(x0), x0.copy()
    nx = 2 * n
    inner, outer = radius - TOL + 4e-4, (radius + TOL - 4e-4) * np.cos(np.pi / faces)
    dyn, dyn_rhs = _differences(n, dt, False)
    for rnd in range(1, rounds + 1):
        t0 = time.perf_counter()
        rel = x - center
        ang = np.arctan2(rel[:, 1], rel[:, 0])
        u = rel / np.linalg.norm(rel, axis=1)[:, None]
        near = np.round(ang / (2 * np.pi / faces)).astype(int)[:, None] + np.arange(-8, 9)[None, :]
        fa = near.ravel() * 2 * np.pi / faces
        k = np.repeat(np.arange(n), near.shape[1])
        m = len(k)
        rows = [sp.csr_matrix((np.c_[np.cos(fa), np.sin(fa)].ravel(), (np.repeat(np.arange(m), 2),
                                                                      np.c_[2 * k, 2 * k + 1].ravel())),
                              shape=(m, nx + n)) - sp.csr_matrix((np.ones(m), (np.arange(m), nx + k)), shape=(m, nx + n)),
                -sp.csr_matrix((u.ravel(), (np.repeat(np.arange(n), 2), np.arange(nx))), shape=(n, nx + n))
                - sp.csr_matrix((np.ones(n), (np.arange(n), nx + np.arange(n))), shape=(n, nx + n))]
        rhs = [outer + np.c_[np.cos(fa), np.sin(fa)] @ center, -(inner + u @ center)]
        a_ub = sp.vstack([sp.hstack([dyn, sp.csr_matrix((dyn.shape[0], n))]), *rows]).tocsc()
        lo = np.r_[x.ravel() - 3.0, np.zeros(n)]
        hi = np.r_[x.ravel() + 3.0, np.full(n, np.inf)]
        lo[:2 * hold] = hi[:2 * hold] = x0[:hold].ravel()
        lo[nx - 2 * hold:nx] = hi[nx - 2 * hold:nx] = x0[n - hold:].ravel()
        res = linprog(np.r_[np.zeros(nx), np.ones(n)], A_ub=a_ub, b_ub=_UM * np.r_[dyn_rhs, *rhs],
                      bounds=_UM * np.c_[lo, hi], method="highs")
        if res.status != 0:
            log(f"    round {rnd}: {res.message}")
            return x, rnd
        x = res.x[:nx].reshape(-1, 2) / _UM
        r = np.linalg.norm(x - center, axis=1)
        log(f"    round {rnd}: band violation {res.fun / _UM:.2e} mm, radius {r[hold:-hold].min() - radius:+.4f} "
            f"to {r.max() - radius:+.4f} mm, {time.perf_counter() - t0:.0f} s")
        if res.fun / _UM < 1e-9:
            return x, rnd
    return x, rounds


def convex_band_trajectory(band: Band, centre: np.ndarray, x0: np.ndarray, dt: float, *, rounds: int = 12,
                           hold: int = 2, reach: float = 1.5, log=print) -> tuple[np.ndarray, int]:
    """``band_trajectory`` for lines that turn one way round ``centre`` (a spiral; trapezoid limits): each sample
    inside the outer offsets of its nearest line and the two either side (the outside of a convex polygon's band
    is convex) and outside the inner offsets of its and its neighbours' nearest lines (re-linearised every
    round), all 2e-4 mm inside
    the tolerance; going round once in the band, the samples then keep the tolerance both ways. No row pins a
    sample to a short stretch of the lines, so samples slide along them as a shorter duration asks."""
    n, x = len(x0), x0.copy()
    nx = 2 * n
    d = band.b - band.a
    u = np.c_[d[:, 1], -d[:, 0]] / np.maximum(np.linalg.norm(d, axis=1), 1e-30)[:, None]
    u *= np.sign(np.einsum("ij,ij->i", (band.a + band.b) / 2 - centre, u))[:, None]  # outward
    off = np.einsum("ij,ij->i", u, band.a)
    room = TOL - 2e-4
    dyn, dyn_rhs = _differences(n, dt, False)
    for rnd in range(1, rounds + 1):
        t0 = time.perf_counter()
        line = band.nearest_line(x)
        near = np.clip(line[:, None] + np.arange(-2, 3)[None, :], 0, len(u) - 1)
        # inside: each sample beyond the inner offsets of its own and its neighbours' nearest lines, so both ends
        # of a chord are on one side of each (the band's inside edge is not convex: a chord may cut its corners)
        inside = np.c_[line, np.r_[line[:1], line[:-1]], np.r_[line[1:], line[-1:]]]
        k = np.r_[np.repeat(np.arange(n), near.shape[1]), np.repeat(np.arange(n), 3)]
        j = np.r_[near.ravel(), inside.ravel()]
        sign = np.r_[np.ones(near.size), -np.ones(inside.size)]
        m = len(k)
        rows = sp.csr_matrix(((sign[:, None] * u[j]).ravel(), (np.repeat(np.arange(m), 2),
                                                               np.c_[2 * k, 2 * k + 1].ravel())), shape=(m, nx + n)) \
            - sp.csr_matrix((np.ones(m), (np.arange(m), nx + k)), shape=(m, nx + n))
        rhs = sign * off[j] + room
        a_ub = sp.vstack([sp.hstack([dyn, sp.csr_matrix((dyn.shape[0], n))]), rows]).tocsc()
        lo = np.r_[x.ravel() - reach, np.zeros(n)]
        hi = np.r_[x.ravel() + reach, np.full(n, np.inf)]
        lo[:2 * hold] = hi[:2 * hold] = x0[:hold].ravel()
        lo[nx - 2 * hold:nx] = hi[nx - 2 * hold:nx] = x0[n - hold:].ravel()
        res = linprog(np.r_[np.zeros(nx), np.ones(n)], A_ub=a_ub, b_ub=_UM * np.r_[dyn_rhs, rhs],
                      bounds=_UM * np.c_[lo, hi], method="highs")
        if res.status != 0:
            log(f"    round {rnd}: {res.message}")
            return x, rnd
        x = res.x[:nx].reshape(-1, 2) / _UM
        dev = band.deviation(x)
        log(f"    round {rnd}: band violation {res.fun / _UM:.2e} mm, deviation {dev[0]:.4f} / {dev[1]:.4f} mm, "
            f"{time.perf_counter() - t0:.0f} s")
        if res.fun / _UM < 1e-9 and max(dev) <= TOL:
            return x, rnd
    return x, rounds


def stretched(points: np.ndarray, duration: float, dt: float) -> np.ndarray:
    t_old = np.linspace(0.0, 1.0, len(points))
    t_new = np.linspace(0.0, 1.0, int(round(duration / dt)) + 1)
    return np.stack([np.interp(t_new, t_old, points[:, i]) for i in range(points.shape[1])], axis=1)


def peaks(x: np.ndarray, dt: float) -> tuple[float, float, float]:
    d, out = x, []
    for lim in (VMAX, AMAX, JMAX):
        d = np.diff(d, axis=0) / dt
        out.append(float(np.abs(d).max()) / lim)
    return tuple(out)


def steady_jerk(x: np.ndarray, dt: float) -> np.ndarray:
    """max_i |P3_i| v^3 / jmax at every sample where the tool moves (v > 0.5 mm/s): the part of each axis's jerk
    that curvature change alone asks at the speed held (jerk = T_i da/dt + 3 K_i v a + P3_i v^3), from
    central differences of the samples."""
    v_ = (x[2:] - x[:-2]) / (2 * dt)
    a_ = (x[2:] - 2 * x[1:-1] + x[:-2]) / dt**2
    j3 = (x[3:] - 3 * x[2:-1] + 3 * x[1:-2] - x[:-3]) / dt**3
    j_, v_, a_ = 0.5 * (j3[1:] + j3[:-1]), v_[1:-1], a_[1:-1]
    speed = np.linalg.norm(v_, axis=1)
    keep = speed > 0.5
    t = v_[keep] / speed[keep, None]
    at = (a_[keep] * t).sum(1)
    k = (a_[keep] - t * at[:, None]) / speed[keep, None] ** 2
    p3v3 = j_[keep] - t * np.gradient(at, dt)[:, None] - 3 * k * (speed[keep] * at)[:, None]
    return np.abs(p3v3).max(axis=1) / JMAX


def flowmc_on_curve(x: np.ndarray, m) -> tuple[float, float]:
    """flowmc's trapezoid and S-curve cycle times along the curve through the samples ``x``."""
    x = x[np.r_[True, np.linalg.norm(np.diff(x, axis=0), axis=1) > 1e-6]]
    curve = Path.polyline(np.c_[x, np.zeros(len(x))], feed=cam.FEED)
    return tuple(plan_smooth(curve, m, tolerance=0.005, profile=p).cycle_time for p in ("trapezoid", "scurve"))


def at_rest(x: np.ndarray, first: np.ndarray, last: np.ndarray, hold: int) -> np.ndarray:
    """``x`` with its first and last ``hold`` samples at the path's ends (at rest there)."""
    x = x.copy()
    x[:hold], x[len(x) - hold:] = first, last
    return x


def flowsnake(args) -> None:
    path, m = cam.program_path("flowsnake"), cam.machine()
    first, last = 3, len(path) - 3  # the Koch curve's lines, after the plunge and before the retract
    assert all(s.kind == "line" and not s.rapid and s.start[2] == 0 == s.end[2] for s in path.segments[first:last + 1])
    band = Band(np.array([s.start[:2] for s in path.segments[first:last + 1]] + [path.segments[last].end[:2]]))
    plans = {prof: plan_smooth(path, m, tolerance=TOL, profile=prof) for prof in ("trapezoid", "scurve")}
    on_lines = {k: (p.trajectory.segment >= first) & (p.trajectory.segment <= last) for k, p in plans.items()}
    times = {k: on_lines[k].sum() * m.period for k in plans}
    trap_xy = plans["trapezoid"].trajectory.positions[on_lines["trapezoid"], :2]
    feed = {k: flowmc_feed_time(p.trajectory, path) for k, p in plans.items()}
    rest = feed["scurve"] - times["scurve"]  # the plunge, as flowmc's S-curve plans it
    print(f"flowsnake's {last - first + 1} Koch lines (XY, the plunge and retract left out), 1 ms setpoints: "
          f"trapezoid plan {times['trapezoid']:.3f} s, S-curve plan {times['scurve']:.3f} s "
          f"({times['scurve'] / times['trapezoid']:.3f} x)", flush=True)
    rows = []
    start = np.load(args.init) if args.init else trap_xy
    for factor in args.factors:
        duration = factor * times["trapezoid"]
        print(f"\n  {factor:.2f} x trapezoid = {duration:.3f} s, dt = {args.dt * 1e3:g} ms", flush=True)
        t0 = time.perf_counter()
        x0 = at_rest(stretched(start, duration, args.dt), band.v[0], band.v[-1], 3)
        x, used = band_trajectory(band, x0, args.dt, rounds=args.rounds, sides=args.sides,
                                  log=lambda s: print(s, flush=True))
        dev = band.deviation(x)
        pk = peaks(x, args.dt)
        ok = max(dev) <= TOL and max(pk) <= 1.0 + 1e-4  # the LP's own rounding: 1e-7 um in jmax dt^3 >= 5e-3 um
        wall = time.perf_counter() - t0
        laws = flowmc_on_curve(x, m) if ok else (float("nan"), float("nan"))
        steady = steady_jerk(x, args.dt)
        print(f"    P3 v^3 over jmax on {np.mean(steady > 1) * 100:.0f} % of the samples; median, 90th, 99th "
              f"percentile {np.percentile(steady, 50):.2f}, {np.percentile(steady, 90):.2f}, "
              f"{np.percentile(steady, 99):.2f} x jmax", flush=True)
        rows.append((factor, (len(x) - 1) * args.dt, ok, dev, pk, used, wall, laws))
        if ok:
            start = x  # the next duration starts from this trajectory, stretched
            if args.save:
                np.save(args.save, x)
    print(f"\nJerk-limited trajectories within {TOL} mm of flowsnake's lines, per axis {VMAX:g} mm/s, "
          f"{AMAX:g} mm/s^2, {JMAX:g} mm/s^3, dt = {args.dt * 1e3:g} ms\n")
    head = (f"{'/ trap':>7}{'time s':>9}{'found':>7}{'dev->':>8}{'dev<-':>8}{'v/vmax':>8}{'a/amax':>8}{'j/jmax':>8}"
            f"{'rounds':>7}{'solve s':>9}{'program':>9}{'flowmc trap':>12}{'flowmc S':>10}{'S/trap':>8}")
    print(head)
    print("-" * len(head))
    for factor, dur, ok, dev, pk, used, wall, laws in rows:
        print(f"{factor:>7.2f}{dur:>9.3f}{'yes' if ok else 'no':>7}{dev[0]:>8.4f}{dev[1]:>8.4f}{pk[0]:>8.3f}"
              f"{pk[1]:>8.3f}{pk[2]:>8.3f}{used:>7}{wall:>9.0f}{(dur + rest) / feed['trapezoid']:>9.3f}"
              f"{laws[0]:>12.3f}{laws[1]:>10.3f}{laws[1] / laws[0]:>8.3f}")
    print(f"\nprogram: the whole program's feed time over the trapezoid plan's ({feed['trapezoid']:.3f} s) with the "
          f"plunge as flowmc's S-curve plans it ({rest:.3f} s)")
    print("flowmc trap / flowmc S: flowmc's own time laws (plan_smooth) on the curve found, its samples taken as a "
          "polyline\nand re-fitted within 0.005 mm, so the curve is (nearly) the same: what the time law, not the "
          "geometry, costs.")
    print(f"\nflowmc's S-curve plan on the same lines: {times['scurve'] / times['trapezoid']:.3f} x the trapezoid")

def _arc_vertices(path: Path, index: int) -> np.ndarray:
    """Segment ``index`` as the benchmark's programmed polyline has it (chords within 1e-4 mm)."""
    pts, seg = path.sample(1e-4)
    return np.vstack([path.segments[index].start, pts[1:][seg[1:] == index]])


def _program_check(path: Path, positions: np.ndarray, segment: np.ndarray, m) -> str:
    """The whole program's trajectory measured as benchmarks/cam_programs.py measures plans."""
    moved = np.any(np.diff(positions, axis=0) != 0, axis=1)
    feed = np.array([not (s.rapid or s.kind == "dwell") for s in path.segments])
    cut = feed[segment[1:]]
    got = cam.measure(positions, m.period, path, cut)
    speed = np.linalg.norm(np.diff(positions, axis=0), axis=1).max() / m.period
    return (f"feed {np.count_nonzero(cut & moved) * m.period:.3f} s, deviation {got['dev_to_path']:.4f} / "
            f"{got['dev_from_path']:.4f} mm, v/vmax {got['v'] / VMAX:.4f}, a/amax {got['a'] / AMAX:.6f}, "
            f"path speed {speed:.1f} mm/s")


def circle(args) -> None:
    """3dtest's three full circles (r = 17.96 mm, in XY, XZ and YZ, each from rest to rest: a rapid before and
    after), each on its own: the plan's boundary samples differ between them by up to 0.07 mm."""
    path, m = cam.program_path("3dtest"), cam.machine()
    circles = [i for i, s in enumerate(path.segments) if s.kind == "arc"]
    traj = plan_smooth(path, m, tolerance=TOL).trajectory
    times = [np.count_nonzero(traj.segment == i) * m.period for i in circles]
    feed = flowmc_feed_time(traj, path)
    print(f"3dtest: circles {circles} take {', '.join(f'{t:.3f}' for t in times)} s of the plan's {feed:.3f} s "
          f"of feed; 0.90 x LinuxCNC (16.796 s) needs {0.9 * 16.796:.3f} s, so each circle "
          f"{(0.9 * 16.796 - feed + sum(times)) / 3:.4f} s", flush=True)
    pos, seg, last = [], [], 0
    for n_circle, (i, t_plan) in enumerate(zip(circles, times)):
        if args.turns is not None and n_circle not in args.turns:
            continue
        arc = _arc_vertices(path, i)
        plane = np.flatnonzero(np.ptp(arc, axis=0) > 0)
        band = Band(arc[:, plane])
        centre = path.segments[i].center[plane]
        radius = float(np.linalg.norm(band.v[0] - centre))
        on = np.flatnonzero(traj.segment == i)
        # the plan's samples tagged with the circle and one either side: the rapid's last step before the start
        # and its first after the end; the first two and last two are kept, so the circle joins them
        plan_xy = traj.positions[on[0] - 1:on[-1] + 2][:, plane]
        start = np.load(args.init) if args.init else plan_xy
        best = None
        for factor in args.factors:
            chords = int(round(factor * t_plan / args.dt))
            x0 = stretched(start, (chords + 1) * args.dt, args.dt)  # chords + 2 samples: chords as the plan counts
            x0[:2], x0[-2:] = plan_xy[:2], plan_xy[-2:]
            print(f"\n  circle {i} (plane {'XYZ'[plane[0]]}{'XYZ'[plane[1]]}): {factor:.4f} x the plan's = "
                  f"{chords * args.dt:.3f} s, dt = {args.dt * 1e3:g} ms", flush=True)
            x, used = annulus_trajectory(centre, radius, x0, args.dt, rounds=args.rounds,
                                         log=lambda s: print(s, flush=True))
            dev, pk = band.deviation(x), peaks(x, args.dt)
            ok = max(dev) <= TOL and max(pk[:2]) <= 1.0 + 1e-4
            print(f"    {'found' if ok else 'none found'}: deviation {dev[0]:.4f} / {dev[1]:.4f} mm, v/vmax "
                  f"{pk[0]:.4f}, a/amax {pk[1]:.6f}, {used} rounds", flush=True)
            if not ok:
                break
            start, best = x, x
            if args.save:
                np.save(f"{args.save}.{n_circle}.npy", x)
        if best is None or args.dt != m.period:
            continue
        full = np.repeat(traj.positions[on[0]:on[0] + 1], len(best) - 4, axis=0)  # the normal axis as planned
        full[:, plane] = best[2:-2]
        pos += [traj.positions[last:on[0] + 1], full]
        seg += [traj.segment[last:on[0] + 1], np.full(len(full), i)]
        last = on[-1]
    if pos:
        pos.append(traj.positions[last:])
        seg.append(traj.segment[last:])
        print(f"\n3dtest with the circles so: {_program_check(path, np.vstack(pos), np.concatenate(seg), m)}")
        print(f"3dtest as planned:          {_program_check(path, traj.positions, traj.segment, m)}")


def spiral(args) -> None:
    """LinuxCNC's spiral (800 lines of 4.5 degrees, r = 51 mm down to 0, at rest at the centre), turn by turn:
    each turn's samples of the plan are a window whose first and last two samples are kept (the plan's
    state at each cut), so every window's trajectory joins the plan's and the windows' periods saved add up."""
    path, m = cam.program_path("spiral"), cam.machine()
    if args.dt != m.period:
        raise SystemExit("spiral: the windows are joined to the plan's samples, so --dt must be its period (0.001)")
    lines = np.array([i for i, s in enumerate(path.segments)
                      if s.kind == "line" and not s.rapid and s.start[2] == s.end[2] and s.length > 0])
    plan = plan_smooth(path, m, tolerance=TOL)
    traj = plan.trajectory
    z = path.segments[lines[0]].start[2]
    on = np.flatnonzero(np.isin(traj.segment, lines))
    first = on[np.flatnonzero(np.abs(traj.positions[on, 2] - z) > 1e-6)[-1] + 1]  # past the plunge's blend
    per_turn = int(round(2 * np.pi / np.radians(4.5)))
    cuts = [first] + [on[np.searchsorted(traj.segment[on], lines[0] + t * per_turn)]
                      for t in range(1, len(lines) // per_turn)] + [on[-1]]
    cuts = sorted(set(c for c in cuts if c >= first))
    feed = flowmc_feed_time(traj, path)
    print(f"spiral: plan {feed:.3f} s of feed; 0.90 x LinuxCNC (23.987 s) needs {0.9 * 23.987:.3f} s; "
          f"{len(cuts) - 1} windows from sample {first} (the plunge's blend left as planned)", flush=True)
    pos, seg = traj.positions.copy(), traj.segment.copy()
    parts, rows = [], []
    turns = range(len(cuts) - 1) if args.turns is None else args.turns
    for t in range(len(cuts) - 1):
        a, b = cuts[t], cuts[t + 1]
        xw = pos[a:b + 1, :2]
        if t not in turns:
            parts.append((a, b, None, None))
            continue
        lo, hi = max(int(seg[a]) - 1, lines[0]), min(int(seg[b]) + 1, lines[-1])
        band = Band(np.array([path.segments[i].start[:2] for i in range(lo, hi + 1)] + [path.segments[hi].end[:2]]))
        band.hold_cover_between(xw[0], xw[-1])
        found, start, used_all = None, xw, []
        for k in args.saves:
            x0 = stretched(start, (len(xw) - 1 - k) * args.dt, args.dt)
            x0[:2], x0[-2:] = xw[:2], xw[-2:]
            print(f"  turn {t}: samples {a}-{b} ({(b - a) * args.dt:.3f} s), {k} periods off", flush=True)
            x, used = convex_band_trajectory(band, np.zeros(2), x0, args.dt, rounds=args.rounds,
                                             log=lambda s: print(s, flush=True))
            dev, pk = band.deviation(x), peaks(x, args.dt)
            ok = max(dev) <= TOL and max(pk[:2]) <= 1.0 + 1e-4
            used_all.append(used)
            if not ok:
                break
            found, start = (k, x, band, dev), x
        rows.append((t, b - a, found[0] if found else 0, found[3] if found else (float("nan"),) * 2, used_all))
        parts.append((a, b, None if found is None else found[1], None if found is None else found[2]))
        print(f"  turn {t}: {found[0] if found else 0} periods saved", flush=True)
    out_p, out_s, last = [], [], 0
    for a, b, x, band in parts:  # each window's x replaces the plan's samples a..b-1 (b: the next one's first)
        if x is None:
            continue
        out_p += [pos[last:a], np.c_[x[:-1], np.linspace(pos[a, 2], pos[b, 2], len(x))[:-1]]]  # z: the plan's
        out_s += [seg[last:a], lo_index(path, band.a[band.nearest_line(x[:-1])], lines)]
        last = b
    out_p.append(pos[last:])
    out_s.append(seg[last:])
    print("\nturn  plan s  periods saved  deviation mm (window)  rounds")
    for t, n, k, dev, used in rows:
        print(f"{t:>4}{n * args.dt:>8.3f}{k:>15}{dev[0]:>12.4f} / {dev[1]:.4f}  {used}")
    print(f"\nspiral with the turns so: {_program_check(path, np.vstack(out_p), np.concatenate(out_s), m)}")
    print(f"spiral as planned:       {_program_check(path, traj.positions, traj.segment, m)}")


def lo_index(path: Path, starts: np.ndarray, lines: np.ndarray) -> np.ndarray:
    """The programmed line (its index in ``path``) that starts at each of ``starts``."""
    first = np.array([path.segments[i].start[:2] for i in lines])
    return lines[cKDTree(first).query(starts)[1]]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("program", nargs="?", default="flowsnake", choices=("flowsnake", "3dtest", "spiral"))
    ap.add_argument("--dt", type=float, default=0.002)
    ap.add_argument("--factors", type=float, nargs="+", default=[1.3, 1.25])
    ap.add_argument("--rounds", type=int, default=12)
    ap.add_argument("--sides", type=int, default=16, help="sides of the polygons inscribed in the tolerance circle")
    ap.add_argument("--save", help="save the samples of each trajectory found here (.npy; the last one stays)")
    ap.add_argument("--init", help="start from these samples (.npy, any period; stretched to the first duration) "
                                   "instead of the trapezoid plan's")
    ap.add_argument("--turns", type=int, nargs="+", help="only these turns of spiral, circles of 3dtest (from 0)")
    ap.add_argument("--saves", type=int, nargs="+", default=[4, 8, 12],
                    help="spiral: periods to take off each turn, tried in turn while they succeed")
    ap.add_argument("--no-jerk", dest="jerk", action="store_false",
                    help="trapezoid limits only (velocity and acceleration), as LinuxCNC plans")
    args = ap.parse_args()
    if (args.program == "flowsnake") != args.jerk:
        ap.error("flowsnake's question is the S-curve's, 3dtest's and spiral's the trapezoid's (--no-jerk)")
    {"flowsnake": flowsnake, "3dtest": circle, "spiral": spiral}[args.program](args)


if __name__ == "__main__":
    main()
