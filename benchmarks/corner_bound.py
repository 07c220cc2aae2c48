"""A lower bound on ANY plan's time through the reference polylines star10 and zigzag40, and its ratio to LinuxCNC.

Not TOPP-RA on one chosen curve (that bounds the time along that curve only): this bounds every sequence of
setpoints the benchmarks would accept, whatever curve it follows. What a plan is, exactly as
benchmarks/cam_programs.py measures it (per-axis finite differences of the raw samples):

- setpoints p_0 .. p_N, period T = 1 ms, at rest before and after (p_-1 = p_0 = start, p_N+1 = p_N = end);
- per axis |p_k+1 - p_k| <= vmax T and |p_k+1 - 2 p_k + p_k-1| <= amax T^2 (200 mm/s, 200 mm/s^2);
- path speed |p_k+1 - p_k| <= F T (F = 200 mm/s, the program's feed);
- every setpoint within the tolerance (0.05 mm) of the polyline;
- (assumption A) the plan follows the program in order: each setpoint is within the tolerance of a segment
  j(k) that never decreases with k (both flowmc's and LinuxCNC's plans do; the script checks it on flowmc's).

Everything else the benchmark asks (chords between setpoints within the tolerance, the path within the
tolerance of the setpoints, z motion) is dropped: fewer constraints, so still a lower bound.

How. Cut the plan where it crosses the middle of each line: g_j is the first setpoint assigned to line j at
or past the line's midpoint. Between two cuts the plan is near line j or line j+1 only, switching once, so
N = g_1 + sum_j (g_j+1 - g_j) + (N - g_m) and each term is at least the least number of periods of its own
piece, with the state at the cuts left free (any position in the strip, any velocity): a relaxation of the
coupling between pieces, so the sum is a lower bound. Each piece is a mixed-integer feasibility problem
(HiGHS through scipy.optimize.milp): positions are continuous, one binary per setpoint says which of the two
lines it is assigned to (non-decreasing), the tolerance band of a segment is relaxed to its bounding strip
and the Euclidean feed limit to 16 directions (both outer approximations). A piece of c periods
infeasible means no plan spends c periods there (the binaries relaxed first, which proves infeasibility
cheaply when it can, then exactly). A setpoint that switches lines is within r of the corner (r from the
geometry, checked below) and so never at a cut: the setpoints at a cut belong to that cut's line. Pieces are stepped every h
periods (fewer setpoints, still implied by the 1 ms constraints); where a cut falls between two kept
setpoints, only how far one period's travel can reach is kept. Finding the least c by bisection ASSUMES
that a piece feasible in c steps is feasible in c + 1; every c tested is decided exactly.

Free cut states are nearly tight here: each line is symmetric, the optimum speeds up to its middle and
slows down after, and the speed a piece would like at a cut is the speed the piece before can reach.

    python3 benchmarks/corner_bound.py [--linuxcnc] [--jobs N] [--step H] [NAME ...]

LinuxCNC's feed times below are cached from one run of benchmarks/cam_programs.py (docs/planning.md, real
simulator through flowmc's backend, G64 P0.05, default Q, 1 ms); ``--linuxcnc`` measures them again.
``--jobs N`` solves the distinct pieces in N processes (star10 has 7: start, end and five corners, alike
only in pairs under the limits' symmetry and time reversal).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path as FsPath

import numpy as np
from scipy.optimize import Bounds, LinearConstraint, milp
from scipy.sparse import coo_matrix

ROOT = FsPath(__file__).resolve().parents[1]
TOL, VMAX, AMAX, FEED, T = 0.05, 200.0, 200.0, 200.0, 0.001
STEP = {"star10": 5, "zigzag40": 2}  # periods per step: fewer setpoints per piece, still a relaxation
LINUXCNC_FEED_S = {"star10": 11.890, "zigzag40": 10.952}  # docs/planning.md, one run of benchmarks/cam_programs.py
_DIRS = 16


@dataclass(frozen=True)
class Line:
    a: np.ndarray
    b: np.ndarray

    @property
    def length(self) -> float:
        return float(np.linalg.norm(self.b - self.a))

    @property
    def d(self) -> np.ndarray:
        return (self.b - self.a) / self.length

    @property
    def n(self) -> np.ndarray:
        return np.array([-self.d[1], self.d[0]])

    @property
    def mid(self) -> np.ndarray:
        return (self.a + self.b) / 2


class _Rows:
    """Sparse rows lo <= A x <= hi, added in blocks of equal shape (one row per entry of ``lo``)."""

    def __init__(self):
        self.r, self.c, self.v, self.lo, self.hi = [], [], [], [], []
        self.n = 0

    def add(self, cols, vals, lo, hi):
        """``cols``, ``vals``: (rows, terms); ``lo``, ``hi``: (rows,) or scalars."""
        cols, vals = np.atleast_2d(cols), np.atleast_2d(vals)
        rows = len(cols)
        self.r.append(np.repeat(np.arange(self.n, self.n + rows), cols.shape[1]))
        self.c.append(cols.ravel())
        self.v.append(np.broadcast_to(vals, cols.shape).ravel())
        self.lo.append(np.broadcast_to(np.asarray(lo, float), (rows,)))
        self.hi.append(np.broadcast_to(np.asarray(hi, float), (rows,)))
        self.n += rows

    def constraint(self, nvar):
        a = coo_matrix((np.concatenate(self.v), (np.concatenate(self.r), np.concatenate(self.c))),
                       shape=(self.n, nvar)).tocsr()
        return LinearConstraint(a, np.concatenate(self.lo), np.concatenate(self.hi))


def switch_radius(a: Line, b: Line) -> float:
    """How far from the corner a setpoint on ``a`` can be while the next (one period on) is on ``b``."""
    step = np.hypot(VMAX, VMAX) * T
    s = abs(float(a.d[0] * b.d[1] - a.d[1] * b.d[0]))
    return (step + 2 * TOL) / max(s, 1e-9) + TOL


def _piece_feasible(c: int, entry: Line, exit_: Line | None, *, h: int = 1, start=None, end=None,
                    exact: bool = True) -> bool:
    """Is there a piece of ``c`` steps of ``h`` periods (every h-th setpoint of the plan)?

    Corner piece: q_0 is the cut's setpoint (on ``entry``, 0 to F T past its midpoint), then each setpoint on
    ``entry`` and then on ``exit_`` (one switch, binaries z_k, relaxed to [0, 1] with ``exact=False``), those
    on ``exit_`` short of its midpoint, and q_c within h F T of it (on ``exit_``). Start piece (``start``):
    q_-1 = q_0 = start (at rest), every setpoint on ``entry`` short of its midpoint and q_c at the cut. End
    piece (``end``): q_0 at the cut, every setpoint on ``entry``, q_c within the h - 1 periods of slowing to
    rest at ``end`` (per axis h(h-1)/2 amax T^2 from it, its last step at most h(3h-1)/2 amax T^2 long).
    Steps of h periods keep what the plan's setpoints imply: |q_k+1 - q_k| <= h vmax T per axis (h F T along
    the path), |q_k+1 - 2 q_k + q_k-1| <= h^2 amax T^2.
    """
    two = exit_ is not None
    m = c + 1 + (start is not None)  # setpoints (the start piece has the rest before it)
    nx = 2 * m
    nvar = nx + (m if two else 0)
    lines = [entry] + ([exit_] if two else [])
    pts = np.vstack([ln.a for ln in lines] + [ln.b for ln in lines])
    lo_box, hi_box = pts.min(0) - 1.0, pts.max(0) + 1.0
    big = 2.0 * float(np.linalg.norm(hi_box - lo_box)) + 1.0
    rows = _Rows()
    k = np.arange(m)
    vt, at2, ft = h * VMAX * T, h * h * AMAX * T * T, h * FEED * T
    for i in range(2):  # per-axis velocity and acceleration
        rows.add(np.c_[2 * k[1:] + i, 2 * k[:-1] + i], [1.0, -1.0], -vt, vt)
        rows.add(np.c_[2 * k[2:] + i, 2 * k[1:-1] + i, 2 * k[:-2] + i], [1.0, -2.0, 1.0], -at2, at2)
    for t in np.linspace(0, np.pi, _DIRS, endpoint=False):  # path speed, 16 directions
        u = [np.cos(t), np.sin(t)]
        rows.add(np.c_[2 * k[1:], 2 * k[1:] + 1, 2 * k[:-1], 2 * k[:-1] + 1], [u[0], u[1], -u[0], -u[1]], -ft, ft)

    def on(ks, ln: Line, z_off=None):
        """q_k within ``ln``'s strip; ``z_off`` = +1: rows off when z_k = 1, -1: off when z_k = 0."""
        ks = np.asarray(ks)
        for vec, lo, hi in ((ln.n, -TOL, TOL), (ln.d, -TOL, ln.length + TOL)):
            base = float(vec @ ln.a)
            cols = np.c_[2 * ks, 2 * ks + 1]
            if z_off is None:
                rows.add(cols, vec, lo + base, hi + base)
            else:
                zc = np.c_[cols, nx + ks]
                off = 0.0 if z_off == 1 else big
                rows.add(zc, [vec[0], vec[1], -big * z_off], -np.inf, hi + base + off)
                rows.add(zc, [vec[0], vec[1], big * z_off], lo + base - off, np.inf)

    def sigma(ks, ln: Line, lo, hi):
        """How far q_k is past ``ln``'s midpoint, along it."""
        base = float(ln.d @ ln.mid)
        rows.add(np.c_[2 * np.asarray(ks), 2 * np.asarray(ks) + 1], ln.d, lo + base, hi + base)

    def cut(k, ln: Line, first: bool):
        """q_k at a cut through ``ln``'s midpoint: the cut's setpoint (``first``), or the last setpoint of the
        steps, the cut within the h - 1 periods after it. A period's travel along the line is within the
        acceleration's reach (``slack``) of the mean x of the step beside it; q_k is past the midpoint by at
        most one period's travel and short of it by at most h - 1 (of at most (x + F T)/2 + ..., the secant of
        max(x, 0) over |x| <= F T: a travel backwards brings nothing)."""
        d, base = ln.d, float(ln.d @ ln.mid)
        slack = float(np.abs(d).sum()) * AMAX * T * T
        nb = k + 1 if first else k - 1  # the setpoint that makes the step with q_k
        # x: the mean travel along the line per period over the step between q_k and q_nb
        cols = np.array([[2 * k, 2 * k + 1, 2 * nb, 2 * nb + 1]])
        if first:  # d.q_k - base <= x + slack (h+1)/2 (the period before it brought q_k past), and >= 0
            rows.add(cols, [d[0] + d[0] / h, d[1] + d[1] / h, -d[0] / h, -d[1] / h], -np.inf,
                     base + slack * (h + 1) / 2)
            sigma([k], ln, 0.0, np.inf)
            return
        # short of the midpoint, or past it by the last period's travel: d.q_k - base <= (x + F T)/2 + slack (h+1)/2
        v = 1 / (2 * h)
        rows.add(cols, [d[0] - v * d[0], d[1] - v * d[1], v * d[0], v * d[1]], -np.inf,
                 base + FEED * T / 2 + slack * (h + 1) / 2)
        # d.q_k - base >= -(h-1) ((x + F T)/2 + slack (2h-1)/2)
        w = (h - 1) / (2 * h)
        rows.add(cols, [d[0] + w * d[0], d[1] + w * d[1], -w * d[0], -w * d[1]],
                 base - (h - 1) * (FEED * T / 2 + slack * (2 * h - 1) / 2), np.inf)

    lb, ub = np.full(nvar, -np.inf), np.full(nvar, np.inf)
    lb[:nx], ub[:nx] = np.tile(lo_box, m), np.tile(hi_box, m)
    integrality = np.zeros(nvar)
    if end is not None:
        on(k, entry)
        cut(0, entry, first=True)
        near, step = h * (h - 1) / 2 * AMAX * T * T, h * (3 * h - 1) / 2 * AMAX * T * T
        lb[nx - 2:nx], ub[nx - 2:nx] = np.asarray(end) - near, np.asarray(end) + near
        for i in range(2):
            rows.add([[2 * (m - 1) + i, 2 * (m - 2) + i]], [1.0, -1.0], -step, step)
    elif not two:
        lb[:4] = ub[:4] = np.tile(start, 2)
        on(k[2:], entry)
        sigma(k[2:-1], entry, -np.inf, 0.0)
        cut(m - 1, entry, first=False)
    else:
        on([0], entry)
        cut(0, entry, first=True)
        on([m - 1], exit_)
        cut(m - 1, exit_, first=False)
        inner = k[1:-1]
        lb[nx:], ub[nx:] = 0.0, 1.0
        ub[nx] = 0.0
        on(inner, entry, z_off=1)
        on(inner, exit_, z_off=-1)
        # on the exit line, short of its midpoint (the cut is the first setpoint past it): off when z = 0
        base = float(exit_.d @ exit_.mid)
        rows.add(np.c_[2 * inner, 2 * inner + 1, nx + inner], [exit_.d[0], exit_.d[1], big], -np.inf, base + big)
        rows.add(np.c_[nx + k[1:], nx + k[:-1]], [1.0, -1.0], 0.0, np.inf)  # one switch
        if exact:
            integrality[nx:] = 1
    res = milp(np.zeros(nvar), constraints=rows.constraint(nvar), integrality=integrality,
               bounds=Bounds(lb, ub), options={"presolve": True, "time_limit": 900})
    if res.status == 0:
        return True
    if res.status == 2:
        return False
    raise RuntimeError(f"HiGHS gave no answer for a piece of {c} steps: {res.message}")


def least_steps(entry: Line, exit_: Line | None, hi: int, **kw) -> tuple[int, list]:
    """The least c for which the piece is feasible, by bisection below ``hi`` (known feasible). ASSUMES feasibility
    is monotone in c (not proven; every c tested is decided exactly). Returns c and the (c, feasible) tested."""
    lo, tested = 0, [(hi, True)]  # lo: infeasible
    while hi - lo > 1:
        mid = (lo + hi) // 2
        ok = _piece_feasible(mid, entry, exit_, exact=False, **kw) and (
            exit_ is None or _piece_feasible(mid, entry, exit_, **kw))
        tested.append((mid, ok))
        print(f"  piece {entry.a.round(2)}->{exit_.b.round(2) if exit_ else '(start)'}: {mid} steps "
              f"{'feasible' if ok else 'infeasible'}", file=sys.stderr, flush=True)
        lo, hi = (lo, mid) if ok else (mid, hi)
    return hi, tested


def _canonical(*vecs: np.ndarray) -> tuple:
    """Directions up to the symmetries of per-axis limits (axis swaps and sign flips), to 1e-4."""
    best = None
    for swap in (False, True):
        for sx in (1, -1):
            for sy in (1, -1):
                key = tuple(round(float(v), 4) for w in vecs
                            for v in ((sx * w[1], sy * w[0]) if swap else (sx * w[0], sy * w[1])))
                best = key if best is None or key < best else best
    return best


def _kind(a: Line, b: Line | None) -> tuple:
    """Pieces alike up to those symmetries and to playing them backwards (the limits are symmetric in time)
    cost alike; lengths and directions to 1e-4 (the reference points are given to 1e-6 mm)."""
    if b is None:
        return _canonical(a.d) + (round(a.length, 4),)
    return min(_canonical(a.d, b.d) + (round(a.length, 4), round(b.length, 4)),
               _canonical(-b.d, -a.d) + (round(b.length, 4), round(a.length, 4)))


def _least(args) -> int:
    a, b, start, end, h = args
    span = a.length + (b.length if b else 0.0)
    est = int(3.0 * np.sqrt(span / AMAX) / (h * T)) + 10  # feasible, or doubled until it is
    while not _piece_feasible(est, a, b, h=h, start=start, end=end):
        est *= 2
    return least_steps(a, b, est, h=h, start=start, end=end)[0]


def bound(points: np.ndarray, h: int, jobs: int = 1) -> dict:
    """Least periods of any plan (under assumption A and monotone piece feasibility), in steps of ``h``;
    the distinct pieces are solved in ``jobs`` processes."""
    lines = [Line(points[i], points[i + 1]) for i in range(len(points) - 1)]
    for a, b in zip(lines[:-1], lines[1:]):
        r = switch_radius(a, b)
        if r >= min(a.length, b.length) / 2 - h * FEED * T:
            raise ValueError(f"line switches reach a cut (r = {r:.3f} mm): cuts are not where the script assumes")
    pieces = [(lines[0], None, lines[0].a, None)] + [(a, b, None, None) for a, b in zip(lines[:-1], lines[1:])]
    pieces.append((lines[-1], None, None, lines[-1].b))
    kinds: dict = {}
    for a, b, start, end in pieces:
        kinds.setdefault(_kind(a, b) + (end is not None,), (a, b, start, end, h))
    t0 = time.perf_counter()
    if jobs > 1:
        from multiprocessing import Pool
        with Pool(jobs) as pool:
            steps = pool.map(_least, list(kinds.values()))
    else:
        steps = [_least(v) for v in kinds.values()]
    cost = dict(zip(kinds, steps))
    # c steps of h periods: the piece took at least c h periods
    periods = [cost[_kind(a, b) + (end is not None,)] * h for a, b, _, end in pieces]
    return {"periods": int(sum(periods)), "pieces": periods, "kinds": len(kinds), "h": h,
            "wall": time.perf_counter() - t0}


def follows_in_order(positions: np.ndarray, points: np.ndarray, tol: float = TOL) -> bool:
    """Assumption A on a plan: a non-decreasing assignment of setpoints to segments within ``tol`` exists."""
    a, b = points[:-1], points[1:]
    d = b - a
    t = np.clip(np.einsum("kij,ij->ki", positions[:, None, :] - a[None], d) / np.einsum("ij,ij->i", d, d), 0, 1)
    near = np.linalg.norm(positions[:, None, :] - (a[None] + t[..., None] * d[None]), axis=2) <= tol + 1e-9
    j = 0
    for row in near:  # greedy: stay on the current segment while allowed, else take the next one that is near
        if row[j]:
            continue
        ahead = np.flatnonzero(row[j:])
        if len(ahead) == 0:
            return False
        j += int(ahead[0])
    return True


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("names", nargs="*", default=["star10", "zigzag40"])
    ap.add_argument("--linuxcnc", action="store_true", help="measure LinuxCNC's times now (real simulator)")
    ap.add_argument("--step", type=int, default=0, help="periods per step (default: star10 5, zigzag40 2)")
    ap.add_argument("--jobs", type=int, default=1, help="processes for the distinct pieces")
    args = ap.parse_args()
    sys.path.insert(0, str(FsPath(__file__).parent))
    import cam_programs as cp

    from flowmc.devices.linuxcnc.compare import flowmc_feed_time
    from flowmc.motion.planner import plan_smooth

    m = cp.machine()
    rows = []
    for name in args.names:
        data = json.loads((ROOT / "tests" / "data" / "reference" / "paths" / f"{name}.json").read_text())
        points = np.array(data["points"], dtype=float)[:, :2]
        b = bound(points, args.step or STEP.get(name, 2), args.jobs)
        path = cp.reference_path(name)
        plan = plan_smooth(path, m, tolerance=TOL)
        flow = flowmc_feed_time(plan.trajectory, path)
        lcnc, source = LINUXCNC_FEED_S.get(name, float("nan")), "cached"
        if args.linuxcnc:
            from flowmc.devices.linuxcnc.backend import run_program
            from flowmc.motion.gcode_write import path_to_gcode
            run = run_program(path_to_gcode(path, blend_tolerance=TOL), m, timeout=1200.0, name=f"{name}.ngc")
            lcnc, source = run.feed_time, "measured"
        rows.append((name, b, flow, lcnc, source, follows_in_order(plan.trajectory.positions[:, :2], points)))
        print(json.dumps({"name": name, **{k: v for k, v in b.items()}}), flush=True)
    print("\nLower bound on any plan (per-axis 200 mm/s, 200 mm/s^2, feed 200 mm/s, 0.05 mm, T = 1 ms)\n")
    head = (f"{'path':<10}{'bound s':>9}{'LinuxCNC s':>12}{'bound/LC':>10}{'0.90 x LC':>11}{'flowmc s':>10}"
            f"{'flowmc/LC':>11}{'flowmc/bound':>14}{'in order':>10}{'wall s':>8}")
    print(head)
    print("-" * len(head))
    for name, b, flow, lcnc, _source, ordered in rows:
        tb = b["periods"] * T
        print(f"{name:<10}{tb:>9.3f}{lcnc:>12.3f}{tb / lcnc:>10.3f}{0.9 * lcnc:>11.3f}{flow:>10.3f}{flow / lcnc:>11.3f}"
              f"{flow / tb:>14.3f}{str(ordered):>10}{b['wall']:>8.1f}")
    print(f"\nLinuxCNC times: {', '.join(f'{r[0]} {r[4]}' for r in rows)}. A bound above 0.90 x LinuxCNC means "
          "no plan under these limits reaches the target.")


if __name__ == "__main__":
    main()
