"""The planned curve: the geometry a planner moves along, after corners and short-segment runs are smoothed.

One global parameter ``u`` runs along the whole program, continuously differentiable: lines, arcs
and tangent-arc blends by their arc length; a fitted spline that replaces the stretch [u_a, u_b]
of the programmed path by the programmed arc length over that stretch (its speed ``|dp/du|`` is
1 at both ends, where it joins its neighbours, and a little below 1 where it cuts corners). Each
interval also knows which stretch of the programmed path it stands for (``pu0``, ``prate``: the
programmed arc length at its start and per mm of u), so segment tags, feeds and tool state are a
plain look-up (``segment_at``).

Intervals are polynomials (lines, fitted cubic splines, tabulated curves; coefficients in powers
of ``u - u0``) or circular/helical arcs (closed form). ``evaluate(u, order)`` gives positions and
derivatives up to the third (what per-axis jerk needs), vectorised by kind.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from flowmc.motion.ranges import CHUNK, CHUNKED, search_right

__all__ = ["POLY", "ARC", "PlannedCurve", "CurveBuilder"]

POLY, ARC = 0, 1


@dataclass(frozen=True, eq=False)
class PlannedCurve:
    """Struct of arrays over intervals [u0, u1) in order, and the programmed segments' boundaries.

    POLY rows: ``coef[k]`` (4, 3), p(u) = sum_m coef[k, m] (u - u0[k])^m.
    ARC rows: p(u) = centre + radius (cos(phi) e1 + sin(phi) e2) + rise * (u - u0) w, with
    phi = phi0 + dphi * (u - u0) (radians per mm of u) and ``rise`` in mm per mm of u.
    ``pu0``, ``prate``: programmed arc length at the interval's start and its rate per mm of u.
    ``seg_u0``: where each programmed segment starts in programmed arc length (non-decreasing; a
    dwell has zero length).
    """

    u0: np.ndarray
    u1: np.ndarray
    kind: np.ndarray
    coef: np.ndarray
    centre: np.ndarray
    e1: np.ndarray
    e2: np.ndarray
    w: np.ndarray
    radius: np.ndarray
    phi0: np.ndarray
    dphi: np.ndarray
    rise: np.ndarray
    pu0: np.ndarray
    prate: np.ndarray
    seg_u0: np.ndarray

    def __len__(self) -> int:
        return len(self.u0)

    @property
    def length(self) -> float:
        return float(self.u1[-1]) if len(self) else 0.0

    def interval_at(self, u: np.ndarray) -> np.ndarray:
        return np.clip(search_right(self.u0, u) - 1, 0, len(self.u0) - 1)

    def programmed_u(self, u) -> np.ndarray:
        """Programmed arc length at curve parameters u."""
        u = np.asarray(u, dtype=float)
        k = self.interval_at(u)
        return self.pu0[k] + self.prate[k] * (u - self.u0[k])

    def curve_u(self, pu) -> np.ndarray:
        """Curve parameter at programmed arc lengths ``pu`` (the inverse of ``programmed_u``)."""
        pu = np.asarray(pu, dtype=float)
        k = np.clip(np.searchsorted(self.pu0, pu, side="right") - 1, 0, len(self.pu0) - 1)
        return np.minimum(self.u0[k] + (pu - self.pu0[k]) / self.prate[k], self.u1[k])

    def constant_speed(self) -> np.ndarray:
        """Per interval: |dp/du| is constant on it (a line or an arc), so arc length is linear in u there."""
        return (self.kind == ARC) | np.all(self.coef[:, 2:] == 0.0, axis=(1, 2))

    def segment_at(self, u: np.ndarray) -> np.ndarray:
        """Index of the programmed segment at each curve parameter u (the last one starting at or before it;
        a segment of zero length, a dwell, owns no u)."""
        pu = self.programmed_u(u)
        return np.clip(np.searchsorted(self.seg_u0, pu, side="right") - 1, 0, len(self.seg_u0) - 1)

    def evaluate(self, u, order: int = 0, index: np.ndarray | None = None, lowest: int = 0) -> list[np.ndarray]:
        """[p^(lowest), ..., p^(order)] at the parameters u (by default [p, p', ...]), each (len(u), 3);
        ``index``: their intervals if known. Derivatives alone skip the positions' arithmetic. Worked out
        CHUNK points at a time: the same arithmetic point by point, with every temporary in cache."""
        u = np.asarray(u, dtype=float).reshape(-1)
        k = self.interval_at(u) if index is None else np.asarray(index)
        if len(u) <= CHUNKED:
            return self._evaluate(u, k, order, lowest)
        parts = [self._evaluate(u[i:i + CHUNK], k[i:i + CHUNK], order, lowest) for i in range(0, len(u), CHUNK)]
        return [np.concatenate(p, axis=0) for p in zip(*parts)]

    def _evaluate(self, u: np.ndarray, k: np.ndarray, order: int, lowest: int) -> list[np.ndarray]:
        is_arc = self.kind[k] == ARC
        if not is_arc.any():
            return self._poly(u, k, order, lowest)
        out = [np.empty((len(u), 3)) for _ in range(lowest, order + 1)]
        poly = np.flatnonzero(~is_arc)
        if len(poly):
            for o, values in zip(out, self._poly(u[poly], k[poly], order, lowest)):
                o[poly] = values
        arc = np.flatnonzero(is_arc)
        kk = k[arc]
        x = u[arc] - self.u0[kk]
        phi = self.phi0[kk] + self.dphi[kk] * x
        # (3, n) rows, as in _poly
        r, d, rise = self.radius[kk], self.dphi[kk], self.rise[kk]
        cos, sin = np.cos(phi), np.sin(phi)
        rows = self.arc_rows
        e1, e2, w = (np.take(rows[i], kk, axis=1) for i in range(3))
        radial = cos * e1 + sin * e2
        if lowest <= 0:
            out[0 - lowest][arc] = (np.take(rows[3], kk, axis=1) + r * radial + (rise * x) * w).T
        if order >= 1 and lowest <= 1:
            out[1 - lowest][arc] = ((r * d) * (cos * e2 - sin * e1) + rise * w).T
        if order >= 2 and lowest <= 2:
            out[2 - lowest][arc] = (-(r * d**2) * radial).T
        if order >= 3:
            out[3 - lowest][arc] = ((r * d**3) * (sin * e1 - cos * e2)).T
        return out

    @cached_property
    def by_power(self) -> np.ndarray:
        """``coef`` as (power, axis, interval), contiguous: a gather of intervals reads whole rows."""
        return np.ascontiguousarray(self.coef.transpose(1, 2, 0))

    @cached_property
    def arc_rows(self) -> np.ndarray:
        """e1, e2, w and centre as (vector, axis, interval), contiguous: an arc's gathers read whole rows, and
        its (3, n) arithmetic runs along the points (as ``by_power`` for polynomials)."""
        return np.ascontiguousarray(np.stack([self.e1, self.e2, self.w, self.centre]).transpose(0, 2, 1))

    def _poly(self, u: np.ndarray, k: np.ndarray, order: int, lowest: int = 0) -> list[np.ndarray]:
        # worked as (3, n) rows, so numpy's inner loops run along the points rather than over 3 columns; the
        # constant term is gathered only for positions
        by_power = self.by_power
        c1, c2, c3 = (np.take(by_power[m], k, axis=1) for m in range(1, 4))
        x = u - self.u0[k]
        out = []
        if lowest <= 0:
            c0 = np.take(by_power[0], k, axis=1)
            out.append(c0 + x * (c1 + x * (c2 + x * c3)))
        if order >= 1 and lowest <= 1:
            out.append(c1 + x * (2.0 * c2 + x * (3.0 * c3)))
        if order >= 2 and lowest <= 2:
            out.append(2.0 * c2 + (6.0 * x) * c3)
        if order >= 3:
            out.append(6.0 * c3)
        return [o.T for o in out]

    def points(self, u) -> np.ndarray:
        return self.evaluate(u, 0)[0]


class CurveBuilder:
    """Collects intervals by the stretch of the programmed path they stand for; ``build`` orders them and
    lays the curve parameter out continuously."""

    _VEC = ("centre", "e1", "e2", "w")
    _SCALAR = ("radius", "phi0", "dphi", "rise")

    def __init__(self):
        self.chunks: list[dict] = []

    def polys(self, pu_breaks, coef, widths=None) -> None:
        """Polynomial intervals, coefficients (n, 4, 3) in powers of the curve parameter from each interval's
        start, over programmed stretches ``pu_breaks``: (n + 1,) for consecutive stretches, or (n, 2) rows
        [start, end] for stretches apart; ``widths``: their lengths in curve parameter (default: the
        programmed stretches' lengths)."""
        pu_breaks = np.asarray(pu_breaks, dtype=float)
        pu0, pu1 = (pu_breaks[:, 0], pu_breaks[:, 1]) if pu_breaks.ndim == 2 else (pu_breaks[:-1], pu_breaks[1:])
        coef = np.asarray(coef, dtype=float).reshape(-1, 4, 3)
        n = len(coef)
        width = pu1 - pu0 if widths is None else np.asarray(widths, dtype=float)
        chunk = {"pu0": pu0, "pu1": pu1, "width": width, "kind": np.full(n, POLY, dtype=np.int8), "coef": coef}
        chunk.update({k: np.zeros((n, 3)) for k in self._VEC})
        chunk.update({k: np.zeros(n) for k in self._SCALAR})
        self.chunks.append(chunk)

    def arcs(self, pu0, pu1, width, centre, e1, e2, w, radius, phi0, dphi, rise) -> None:
        """Arc intervals standing for programmed stretches [pu0, pu1], ``width`` mm of curve parameter each
        (their arc length); phi and rise per mm of curve parameter. Arrays over rows; see PlannedCurve."""
        pu0 = np.atleast_1d(np.asarray(pu0, dtype=float))
        n = len(pu0)
        chunk = {"pu0": pu0, "pu1": np.broadcast_to(np.asarray(pu1, dtype=float), (n,)).copy(),
                 "width": np.broadcast_to(np.asarray(width, dtype=float), (n,)).copy(),
                 "kind": np.full(n, ARC, dtype=np.int8), "coef": np.zeros((n, 4, 3))}
        for name, value in zip(self._VEC, (centre, e1, e2, w)):
            chunk[name] = np.broadcast_to(np.asarray(value, dtype=float), (n, 3)).copy()
        for name, value in zip(self._SCALAR, (radius, phi0, dphi, rise)):
            chunk[name] = np.broadcast_to(np.asarray(value, dtype=float), (n,)).copy()
        self.chunks.append(chunk)

    def build(self, seg_u0) -> PlannedCurve:
        cat = {key: np.concatenate([c[key] for c in self.chunks]) for key in self.chunks[0]}
        order = np.argsort(cat["pu0"], kind="stable")
        order = order[cat["width"][order] > 0]
        width = cat["width"][order]
        u1 = np.cumsum(width)
        u0 = u1 - width
        fields = {key: cat[key][order] for key in ("kind", "coef", *self._VEC, *self._SCALAR)}
        pu0, pu1 = cat["pu0"][order], cat["pu1"][order]
        return PlannedCurve(u0=u0, u1=u1, pu0=pu0, prate=(pu1 - pu0) / width, seg_u0=np.asarray(seg_u0, dtype=float),
                            **fields)
