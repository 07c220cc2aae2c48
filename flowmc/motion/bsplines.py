"""Cubic B-splines of many runs at once: basis values and evaluation, vectorised over every point of every run.

Why: the smoothing (flowmc.motion.smoothing) fits hundreds of runs on dense CAM code; a scipy BSpline (or
design matrix) per run costs far more in Python overhead than the arithmetic it does. Here every run's
clamped knot vector is stacked in one flat array and the Cox-de Boor recursion (Piegl and Tiller, The
NURBS Book, 2nd ed., algorithm A2.2) runs over all points of all runs at once. Derivatives are the
splines of the differenced control points on the same knots, one degree lower (A3.3's construction).
"""

from __future__ import annotations

import numpy as np

__all__ = ["RunKnots"]


class RunKnots:
    """Clamped cubic knot vectors of many runs: run r has ``spans[r]`` equal spans over [a_r, a_r + w_r],
    its knots at ``flat[start[r]:start[r] + spans[r] + 7]`` and its control points at ``offset[r]`` onwards
    in the stacked control points."""

    def __init__(self, a: np.ndarray, width: np.ndarray, spans: np.ndarray, offset: np.ndarray):
        self.a, self.width, self.spans, self.offset = a, width, spans, offset
        # each run: a three times, then spans + 1 knots as np.linspace(a, a + w, spans + 1) lays them, b three times
        size = spans + 7
        self.start = np.r_[0, np.cumsum(size)[:-1]]
        run = np.repeat(np.arange(len(a)), size)
        j = np.clip(np.arange(int(size.sum())) - self.start[run] - 3, 0, spans[run])
        end = a + width
        flat = j * ((end - a) / spans)[run] + a[run]
        flat = np.where(j == spans[run], end[run], flat)
        self.flat = flat
        self.knots = np.split(flat, self.start[1:])
        h = width / spans  # per run, what span() needs for its guesses
        self._guess = (self.start + 3, spans - 1, np.where(h > 0, h, 1.0))

    @classmethod
    def of(cls, knots: list[np.ndarray], offset: np.ndarray) -> RunKnots:
        """Runs whose clamped knot vectors are given as they are (a fit's, kept run by run)."""
        a, end = np.array([k[3] for k in knots]), np.array([k[-1] for k in knots])
        runs = cls(a, end - a, np.array([len(k) - 7 for k in knots]), offset)
        runs.flat, runs.knots = np.concatenate(knots), list(knots)
        return runs

    def span(self, run: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Index in ``flat`` of the knot t_i <= x < t_{i+1} of each point's run (the run's first or last span
        for x outside it, as scipy's BSpline extrapolates). Runs may overlap: each point searches its own
        run's knots (a guess from the equal spacing, then moved while a knot says otherwise)."""
        first, top, h = (v[run] for v in self._guess)
        last = first + top
        guess = np.floor((x - self.a[run]) / h)
        i = first + np.clip(np.nan_to_num(guess), 0, top).astype(int)
        t = self.flat
        while True:
            down = (i > first) & (x < t[i])
            up = (i < last) & (x >= t[np.minimum(i + 1, len(t) - 1)])
            if not (down.any() or up.any()):
                return i
            i = i - down + up

    def basis(self, i: np.ndarray, x: np.ndarray, degree: int = 3) -> np.ndarray:
        """(n, degree + 1) values of the non-zero basis functions of ``degree`` at x in span i (A2.2)."""
        return self.bases(i, x, (degree,))[degree].T

    def bases(self, i: np.ndarray, x: np.ndarray, degrees) -> dict[int, np.ndarray]:
        """The non-zero basis functions, (degree + 1, n), of every degree in ``degrees`` at x in span i: the
        recursion passes through each lower degree on its way up, so one pass gives them all."""
        t = self.flat
        top = max(degrees)
        n = np.empty((top + 1, len(x)))  # one row per function: numpy's loops run along the points
        n[0] = 1.0
        left = [None] + [x - t[i + 1 - j] for j in range(1, top + 1)]
        right = [None] + [t[i + j] - x for j in range(1, top + 1)]
        out = {0: n[:1].copy()} if 0 in degrees else {}
        for j in range(1, top + 1):
            saved = np.zeros(len(x))
            for r in range(j):
                temp = n[r] / (right[r + 1] + left[j - r])
                n[r] = saved + right[r + 1] * temp
                saved = left[j - r] * temp
            n[j] = saved
            if j in degrees:
                out[j] = n[:j + 1] if j == top else n[:j + 1].copy()
        return out

    def first_cp(self, run: np.ndarray, i: np.ndarray) -> np.ndarray:
        """Stacked index of the first of the four control points acting in span i of each run."""
        return self.offset[run] + (i - self.start[run] - 3)

    def evaluate(self, coef: np.ndarray, run: np.ndarray, x: np.ndarray, order: int,
                 only: tuple[int, ...] | None = None) -> list[np.ndarray]:
        """[p, p', ..., p^(order)] (each (n, 3)) of the runs' splines (stacked control points ``coef``); with
        ``only``, just those derivatives (in that order)."""
        wanted = tuple(range(order + 1)) if only is None else only
        i = self.span(run, x)
        j0 = self.first_cp(run, i)
        nb = self.bases(i, x, [3 - m for m in wanted])
        out = {}
        c = coef
        # knot differences of the derivative splines: c'_j = 3 (c_{j+1} - c_j) / (t_{j+4} - t_{j+1}), and so on
        local = np.arange(len(coef)) - np.repeat(self.offset, self.spans + 3)
        kstart = np.minimum(np.repeat(self.start, self.spans + 3) + local, len(self.flat) - 5)
        for m in range(max(wanted) + 1):
            deg = 3 - m
            if m in wanted:  # worked as (3, n) rows, along the points
                b, by_axis = nb[deg], c.T
                val = np.take(by_axis, j0, axis=1) * b[0]
                for a in range(1, deg + 1):
                    val += np.take(by_axis, j0 + a, axis=1) * b[a]
                out[m] = val.T
            if m < max(wanted):
                step = self.flat[kstart + 4] - self.flat[kstart + 1 + m]
                diff = np.zeros_like(c)
                diff[:-1] = (c[1:] - c[:-1]) * deg / np.where(step[:-1] > 0, step[:-1], 1.0)[:, None]
                c = diff
        return [out[m] for m in wanted]
