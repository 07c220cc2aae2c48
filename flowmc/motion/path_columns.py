"""A path as columns (struct of arrays): one row per segment, shared by readers and planners.

A CAM program of 100k moves is 100k rows of a few arrays here, not 100k objects: the G-code reader
fills the columns, the planner and the signal builder read them, and a Segment object is made only
when someone asks for one (``Path[i]``, iterating a Path). Curves without a closed form (ellipse,
NURBS) stay objects, in ``curves``. Arc geometry (radii, angles, sweep, length, points, tangents)
is computed here for all arcs at once, with the same formulas as ``flowmc.motion.path.Arc``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, Mapping

import numpy as np

import flowmc.budget as budget

__all__ = ["LINE", "ARC", "DWELL", "CURVE", "KIND_NAMES", "PLANES", "PathColumns"]

LINE, ARC, DWELL, CURVE = 0, 1, 2, 3
KIND_NAMES = {LINE: "line", ARC: "arc", DWELL: "dwell"}  # a curve row is named by its object's kind

#: Arc planes by their normal axis index, as G17/G18/G19 name them. Plane coordinates (u, v) are
#: ordered so that ccw in (u, v) is a right-handed turn about the normal axis (RS274/NGC's rule).
PLANES = {2: ("XY", (0, 1)), 1: ("XZ", (2, 0)), 0: ("YZ", (1, 2))}
_UV = np.array([PLANES[k][1] for k in range(3)])  # (iu, iv) by normal axis


@dataclass(frozen=True)
class ArcGeometry:
    """The arcs of a PathColumns, one row per arc (``rows`` are their segment indices)."""

    rows: np.ndarray
    normal: np.ndarray
    iu: np.ndarray
    iv: np.ndarray
    r0: np.ndarray
    r1: np.ndarray
    angle0: np.ndarray
    sweep: np.ndarray
    rise: np.ndarray
    length: np.ndarray

    def points(self, arc: np.ndarray, f: np.ndarray, columns: "PathColumns") -> np.ndarray:
        """Points (M, 3) at fractions ``f`` (0 at the start, 1 at the end) along arcs ``arc`` (M,)."""
        theta = self.angle0[arc] + f * self.sweep[arc]
        r = self.r0[arc] + (self.r1[arc] - self.r0[arc]) * f
        seg = self.rows[arc]
        m = np.arange(len(arc))
        out = np.empty((len(arc), 3))
        iu, iv, nrm = self.iu[arc], self.iv[arc], self.normal[arc]
        out[m, iu] = columns.center[seg, iu] + r * np.cos(theta)
        out[m, iv] = columns.center[seg, iv] + r * np.sin(theta)
        out[m, nrm] = columns.start[seg, nrm] + f * self.rise[arc]
        return out

    def tangents(self, arc: np.ndarray, f: np.ndarray) -> np.ndarray:
        """Unit tangents (M, 3) at fractions ``f`` along arcs ``arc``."""
        theta = self.angle0[arc] + f * self.sweep[arc]
        dr = self.r1[arc] - self.r0[arc]
        w = self.sweep[arc] * (self.r0[arc] + dr * f)
        m = np.arange(len(arc))
        out = np.empty((len(arc), 3))
        out[m, self.iu[arc]] = -np.sin(theta) * w + np.cos(theta) * dr
        out[m, self.iv[arc]] = np.cos(theta) * w + np.sin(theta) * dr
        out[m, self.normal[arc]] = self.rise[arc]
        return out / np.linalg.norm(out, axis=1, keepdims=True)


@dataclass(frozen=True, eq=False)
class PathColumns:
    """Segments as columns, row k being segment k.

    Every row: ``kind`` (LINE, ARC, DWELL, CURVE), ``start``/``end`` (n, 3) mm, ``feed`` mm/s,
    ``rapid``, ``tool_down``, ``spindle`` rpm, and where it came from: ``files[file[k]]`` and
    ``line[k]`` (-1: no line number; the source is the file entry alone). Arc rows: ``center``
    (its normal coordinate equal to the start's), ``normal_axis``, ``ccw``, ``turns``. Dwell rows:
    ``seconds``. Sparse, by row: ``events`` (PathEvent), ``outputs``/``analog`` (``(channel, value)``
    tuples), ``curves`` (the segment objects of CURVE rows). Arrays are read-only.
    """

    kind: np.ndarray
    start: np.ndarray
    end: np.ndarray
    feed: np.ndarray
    rapid: np.ndarray
    tool_down: np.ndarray
    spindle: np.ndarray
    center: np.ndarray
    normal_axis: np.ndarray
    ccw: np.ndarray
    turns: np.ndarray
    seconds: np.ndarray
    files: tuple[str, ...]
    file: np.ndarray
    line: np.ndarray
    events: Mapping[int, Any] = field(default_factory=dict)
    outputs: Mapping[int, tuple] = field(default_factory=dict)
    analog: Mapping[int, tuple] = field(default_factory=dict)
    curves: Mapping[int, Any] = field(default_factory=dict)

    def __post_init__(self):
        for name in ("kind", "start", "end", "feed", "rapid", "tool_down", "spindle", "center", "normal_axis",
                     "ccw", "turns", "seconds", "file", "line"):
            getattr(self, name).setflags(write=False)

    def __len__(self) -> int:
        return len(self.kind)

    @cached_property
    def names(self) -> tuple[str, ...]:
        """Each row's source (``part.ngc:12``; the file entry alone where there is no line)."""
        files, lines = self.files, self.line.tolist()
        if len(files) == 1:
            prefix = files[0] + ":"
            return tuple(files[0] if ln < 0 else prefix + str(ln) for ln in lines)
        return tuple(files[f] if ln < 0 else f"{files[f]}:{ln}" for f, ln in zip(self.file.tolist(), lines))

    @cached_property
    def arcs(self) -> ArcGeometry:
        """Radii, start angle, signed sweep (turns included), rise and length of every arc row."""
        rows = np.flatnonzero(self.kind == ARC)
        normal = self.normal_axis[rows].astype(np.intp)
        iu, iv = _UV[normal, 0], _UV[normal, 1]
        c, s, e = self.center[rows], self.start[rows], self.end[rows]
        m = np.arange(len(rows))
        su, sv = s[m, iu] - c[m, iu], s[m, iv] - c[m, iv]
        eu, ev = e[m, iu] - c[m, iu], e[m, iv] - c[m, iv]
        r0, r1 = np.sqrt(su * su + sv * sv), np.sqrt(eu * eu + ev * ev)
        angle0 = np.arctan2(sv, su)
        delta = np.arctan2(ev, eu) - angle0
        two_pi = 2.0 * math.pi
        ccw = self.ccw[rows]
        up = np.mod(delta, two_pi)
        up = np.where(up < 1e-12, two_pi, up)
        down = -np.mod(-delta, two_pi)
        down = np.where(down > -1e-12, -two_pi, down)
        sweep = np.where(ccw, up, down) + np.where(ccw, two_pi, -two_pi) * self.turns[rows]
        rise = e[m, normal] - s[m, normal]
        length = np.hypot(0.5 * (r0 + r1) * np.abs(sweep), rise)
        return ArcGeometry(rows, normal, iu, iv, r0, r1, angle0, sweep, rise, length)

    @cached_property
    def lengths(self) -> np.ndarray:
        """Arc length of every row (0 for dwells)."""
        out = np.linalg.norm(self.end - self.start, axis=1)
        out[self.kind == DWELL] = 0.0
        out[self.arcs.rows] = self.arcs.length
        for k, curve in self.curves.items():
            out[k] = curve.length
        out.setflags(write=False)
        return out

    def kind_counts(self) -> dict[str, int]:
        counts = np.bincount(self.kind, minlength=4)
        out = {KIND_NAMES[k]: int(counts[k]) for k in (LINE, ARC, DWELL) if counts[k]}
        for curve in self.curves.values():
            out[curve.kind] = out.get(curve.kind, 0) + 1
        return dict(sorted(out.items()))

    def sample(self, tol: float) -> tuple[np.ndarray, np.ndarray]:
        """``Path.sample`` over the columns: lines and dwells by their end points, arcs by chords
        within ``tol`` (vectorised over all arcs), curves by their own ``sample``."""
        n = len(self)
        kind = self.kind
        counts = np.where(kind == LINE, 2, 1)
        geo = self.arcs
        chords = _chord_counts(np.minimum(geo.r0, geo.r1), np.abs(geo.sweep), tol)
        counts[geo.rows] = chords + 1
        curve_pts = {k: c.sample(tol) for k, c in self.curves.items()}
        for k, pts in curve_pts.items():
            counts[k] = len(pts)
        total = int(counts.sum())
        budget.check("points", total, what=f"sampling a path of {n} segments within {tol:g} mm",
                     change="loosen the chord tolerance, or split the program")
        first = np.cumsum(counts) - counts
        pts = np.empty((total, 3))
        owner = np.repeat(np.arange(n), counts)
        simple = np.flatnonzero(kind != CURVE)
        pts[first[simple]] = self.start[simple]
        lines = np.flatnonzero(kind == LINE)
        pts[first[lines] + 1] = self.end[lines]
        if len(geo.rows):
            arc = np.repeat(np.arange(len(geo.rows)), chords + 1)
            j = np.arange(len(arc)) - np.repeat(np.cumsum(chords + 1) - (chords + 1), chords + 1)
            f = j / chords[arc]
            pts[first[geo.rows[arc]] + j] = geo.points(arc, f, self)
        for k, p in curve_pts.items():
            pts[first[k]:first[k] + len(p)] = p
        # A segment's first point goes where it repeats the point before it (the previous segment's end).
        heads = first[1:]
        heads = heads[np.all(np.abs(pts[heads] - pts[heads - 1]) <= 1e-9, axis=1)]
        keep = np.ones(total, dtype=bool)
        keep[heads] = False
        return pts[keep], owner[keep]


def _chord_counts(radius: np.ndarray, sweep: np.ndarray, tol: float) -> np.ndarray:
    """``flowmc.motion.path.chord_count`` for many arcs of radius ``radius`` sweeping ``sweep`` rad."""
    length = radius * sweep
    small = ~np.isfinite(radius) | (radius <= tol)
    with np.errstate(invalid="ignore"):
        big_step = 2.0 * np.sqrt(np.maximum(2.0 * radius * tol - tol * tol, 0.0))
        small_step = np.where(radius > 0, np.maximum(np.sqrt(8.0 * np.minimum(radius, tol) * tol), 1e-6), length)
    step = np.where(small, small_step, big_step)
    count = length / np.maximum(step, 1e-12)
    if len(count):
        budget.check("points", float(count.max()), what=f"sampling an arc within {tol:g} mm",
                     change="loosen the chord tolerance, or make the curve shorter (fewer turns)")
    return np.maximum(1, np.ceil(count)).astype(np.int64)
