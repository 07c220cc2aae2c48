"""Path -> pieces: the geometry a planner moves along, with corners rounded and per-piece limits.

A piece is a straight line, a circular arc (programmed arcs and helices, and the tangent blend arcs
that round a corner within a tolerance), a short stretch of a tabulated curve (ellipse, NURBS) or a
dwell. Planners work on pieces rather than segments because blends trim the segments they join and
because curves are cut into stretches that each have one curvature bound. Every piece keeps the
index of the segment it belongs to (a blend's first half belongs to the segment before the corner,
its second half to the one after), so any setpoint can name its segment.

Limits are per axis (flowmc.motion.limits: the machine's vmax/amax/jmax, and every segment's feed,
rapids included, as its path-speed cap). On a line with unit direction u the path may
move at min_i vmax_i/|u_i| and accelerate at min_i amax_i/|u_i|, which is exact. On curved pieces the
acceleration vector has a normal part v^2*kappa as well; planners keep |a_t * t + a_n * n| <= A where
A is the smallest amax among the axes the piece moves, which keeps every axis within its own limit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from flowmc.errors import PlanningError
from flowmc.motion.limits import PathLimits, segment_feed
from flowmc.motion.machine import Machine
from flowmc.motion.path import PLANES, Arc, Dwell, Line, Path, describe_segment

__all__ = ["LINE", "ARC", "CURVE", "DWELL", "REVERSAL", "Pieces", "build_pieces", "corner_angle"]

LINE, ARC, CURVE, DWELL = 0, 1, 2, 3

_EPS_LEN = 1e-9  # mm: shorter pieces are dropped
_ARC_PIECE = 5.0  # mm: programmed arcs are cut into pieces this long at most (speed-dependent budget)
_CURVE_PIECE = 2.0  # mm: tabulated curves likewise, each piece with its own curvature bound
_MAX_SUBPIECES = 2048
REVERSAL = math.radians(179.9)  # corners sharper than this are reversals: always a stop


def corner_angle(t_in: np.ndarray, t_out: np.ndarray) -> np.ndarray:
    """Direction change alpha (radians, 0 = straight on, pi = reversal) between unit tangents, row-wise."""
    diff = np.linalg.norm(t_out - t_in, axis=-1)
    summ = np.linalg.norm(t_out + t_in, axis=-1)
    return 2.0 * np.arctan2(diff, summ)


@dataclass(frozen=True, eq=False)
class Pieces:
    """Struct of arrays, one row per piece, in path order.

    Geometry: lines ``origin + u*s``; arcs ``origin + radius*(cos(phi) u + sin(phi) e2) + w*rise*s/length``
    with ``phi = phi0 + sweep*s/length``; curves ``segments[seg].point_at(seg_s0 + s)``; dwells sit at
    ``origin``. Limits: ``vmax`` (feed and per-axis velocity), ``accel`` (line: tangential limit;
    curved: the norm budget A), ``kappa`` (curvature bound, 0 on lines), ``jerk`` (tangential).
    ``stop_after[p]`` forces rest at the junction after piece p (tool or spindle change, dwell, end).
    """

    kind: np.ndarray
    seg: np.ndarray
    length: np.ndarray
    s0: np.ndarray
    origin: np.ndarray
    u: np.ndarray
    e2: np.ndarray
    w: np.ndarray
    radius: np.ndarray
    phi0: np.ndarray
    sweep: np.ndarray
    rise: np.ndarray
    seg_s0: np.ndarray
    kappa: np.ndarray
    vmax: np.ndarray
    accel: np.ndarray
    jerk: np.ndarray
    dwell: np.ndarray
    t_start: np.ndarray
    t_end: np.ndarray
    stop_after: np.ndarray
    segments: tuple

    def __len__(self) -> int:
        return len(self.kind)

    @property
    def total_length(self) -> float:
        return float(self.s0[-1] + self.length[-1]) if len(self) else 0.0

    def point_at(self, index: np.ndarray, s: np.ndarray) -> np.ndarray:
        """Points (M, 3) at local arc length ``s`` within pieces ``index`` (both (M,)), vectorised by kind."""
        out = self.origin[index].copy()
        kind = self.kind[index]
        sel = np.flatnonzero(kind == LINE)
        if len(sel):
            p = index[sel]
            out[sel] += self.u[p] * s[sel, None]
        sel = np.flatnonzero(kind == ARC)
        if len(sel):
            p = index[sel]
            frac = s[sel] / self.length[p]
            phi = self.phi0[p] + self.sweep[p] * frac
            out[sel] += self.radius[p, None] * (np.cos(phi)[:, None] * self.u[p] + np.sin(phi)[:, None] * self.e2[p])
            out[sel] += self.w[p] * (self.rise[p] * frac)[:, None]
        sel = np.flatnonzero(kind == CURVE)
        if len(sel):
            segs = self.seg[index[sel]]
            for g in np.unique(segs):
                rows = sel[segs == g]
                out[rows] = self.segments[g].point_at(self.seg_s0[index[rows]] + s[rows])
        return out


_FIELDS = ("kind", "seg", "length", "origin", "u", "e2", "w", "radius", "phi0", "sweep", "rise", "seg_s0",
           "kappa", "vmax", "accel", "jerk", "dwell", "t_start", "t_end")
_ZERO3 = (0.0, 0.0, 0.0)


class _Rows:
    """Collects piece rows as tuples in _FIELDS order; turned into arrays once."""

    def __init__(self):
        self.rows: list[tuple] = []
        self.stops: list[bool] = []

    def add(self, *, kind, seg, length, origin, u=_ZERO3, e2=_ZERO3, w=_ZERO3, radius=0.0, phi0=0.0, sweep=0.0,
            rise=0.0, seg_s0=0.0, kappa=0.0, vmax=0.0, accel=0.0, jerk=0.0, dwell=0.0, t_start=_ZERO3,
            t_end=_ZERO3):
        self.rows.append((kind, seg, length, origin, u, e2, w, radius, phi0, sweep, rise, seg_s0, kappa, vmax,
                          accel, jerk, dwell, t_start, t_end))
        self.stops.append(False)

    def mark_stop(self):
        if self.stops:
            self.stops[-1] = True

    def build(self, segments) -> Pieces:
        cols = dict(zip(_FIELDS, zip(*self.rows)))
        vec = lambda name: np.asarray(cols[name], dtype=float).reshape(-1, 3)  # noqa: E731
        flt = lambda name: np.asarray(cols[name], dtype=float)  # noqa: E731
        length = flt("length")
        s0 = np.concatenate([[0.0], np.cumsum(length)[:-1]])
        return Pieces(
            kind=np.asarray(cols["kind"], dtype=np.int8), seg=np.asarray(cols["seg"], dtype=int), length=length,
            s0=s0, origin=vec("origin"), u=vec("u"), e2=vec("e2"), w=vec("w"), radius=flt("radius"),
            phi0=flt("phi0"), sweep=flt("sweep"), rise=flt("rise"), seg_s0=flt("seg_s0"), kappa=flt("kappa"),
            vmax=flt("vmax"), accel=flt("accel"), jerk=flt("jerk"), dwell=flt("dwell"), t_start=vec("t_start"),
            t_end=vec("t_end"), stop_after=np.asarray(self.stops, dtype=bool), segments=tuple(segments),
        )


def _check_axes(path: Path, cols: list[int], machine: Machine) -> None:
    missing = [k for k in range(3) if k not in cols]
    if not missing or not len(path):
        return
    for i, seg in enumerate(path.segments):
        pts = seg.sample(0.01)
        moved = np.ptp(pts[:, missing], axis=0) > 1e-9 if len(pts) > 1 else np.zeros(len(missing), bool)
        moved |= np.abs(pts[0, missing] - path.start[missing]) > 1e-9
        if np.any(moved):
            names = ", ".join("XYZ"[k] for k, m in zip(missing, moved) if m)
            raise PlanningError(f"moves along {names}, which machine axes {machine.names} lack",
                                where=describe_segment(i, seg.source))


@dataclass
class _Blends:
    """Tangent arcs at line-line corners, one row per junction (trim 0 where there is none)."""

    trim: np.ndarray
    radius: np.ndarray
    center: np.ndarray
    normal: np.ndarray
    u_in: np.ndarray
    u_out: np.ndarray
    mid: np.ndarray
    alpha: np.ndarray
    vmax: np.ndarray
    accel: np.ndarray
    jerk: np.ndarray


def _blends(segs, is_line, u, lengths, feeds, tol: float | None, lim: PathLimits) -> _Blends:
    """Trim d and radius R of the tangent arc at each line-line corner.

    R keeps the arc within ``tol`` of the corner point (R (1/cos(alpha/2) - 1) <= tol) and, with
    the sampling chord sagitta A T^2/8 added, within ``tol`` of the programmed lines. The trims at
    the two ends of a line are scaled down together when the line is too short for both.
    """
    n = len(segs)
    u_in, u_out = u[:-1], u[1:]
    alpha = corner_angle(u_in, u_out)
    moved = (np.abs(u_in) + np.abs(u_out)) > 1e-12
    v_lim, a_lim, j_lim = lim.over(moved)
    v_lim = np.minimum(v_lim, np.minimum(feeds[:-1], feeds[1:]))
    period = lim.period
    trim = np.zeros(n - 1)
    radius = np.zeros(n - 1)
    if tol is not None and n > 1:
        same = np.array([a.tool_down == b.tool_down and a.spindle == b.spindle for a, b in zip(segs[:-1], segs[1:])])
        sag = a_lim * period**2 / 8.0
        ok = is_line[:-1] & is_line[1:] & same & (alpha > 1e-7) & (alpha < REVERSAL) & (tol > sag)
        half = 0.5 * alpha[ok]
        one_minus_cos = 2.0 * np.sin(0.5 * half) ** 2
        r_max = np.minimum(tol * np.cos(half), tol - sag[ok]) / one_minus_cos
        want = np.zeros(n - 1)
        want[ok] = r_max * np.tan(half)
        start_need, end_need = np.r_[0.0, want], np.r_[want, 0.0]
        need = start_need + end_need
        scale = np.where(need > lengths, lengths / np.maximum(need, 1e-300), 1.0)
        trim = np.where(ok, np.minimum(end_need[:-1] * scale[:-1], start_need[1:] * scale[1:]), 0.0)
        radius[ok] = trim[ok] / np.tan(half)
    normal = u_out - np.einsum("ij,ij->i", u_in, u_out)[:, None] * u_in
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    corner = np.array([seg.end for seg in segs[:-1]]).reshape(-1, 3)
    center = corner - u_in * trim[:, None] + radius[:, None] * normal
    mid = np.cos(0.5 * alpha)[:, None] * u_in + np.sin(0.5 * alpha)[:, None] * normal
    return _Blends(trim, radius, center, normal, u_in, u_out, mid, alpha, v_lim, a_lim, j_lim)


def build_pieces(path: Path, machine: Machine, blend_tol: float | None = None) -> Pieces:
    """Cut a path into pieces; with ``blend_tol`` (mm) round line-line corners by tangent arcs.

    Raises PlanningError naming the segment for gaps, bad feeds, or motion on axes the machine lacks.
    """
    lim = PathLimits.of(machine)
    cols = list(lim.cols)
    segs = path.segments
    if not segs:
        raise PlanningError("the path has no segments", where="path")
    _check_axes(path, cols, machine)
    for i in path.gaps(1e-6):
        raise PlanningError(
            f"starts at {np.round(segs[i].start, 6).tolist()} but the segment before ends at "
            f"{np.round(segs[i - 1].end, 6).tolist()}", where=describe_segment(i, segs[i].source))
    lengths = np.array([seg.length for seg in segs], dtype=float)
    is_line = np.array([isinstance(seg, Line) for seg in segs]) & (lengths > _EPS_LEN)
    feeds = np.array([math.inf if isinstance(seg, Dwell) else segment_feed(seg, describe_segment(i, seg.source))
                      for i, seg in enumerate(segs)])
    u = np.zeros((len(segs), 3))
    if is_line.any():
        ends = np.array([seg.end for seg in segs])
        starts = np.array([seg.start for seg in segs])
        u[is_line] = (ends[is_line] - starts[is_line]) / lengths[is_line, None]
    line_v, line_a, line_j = lim.along(u)
    line_v = np.minimum(line_v, feeds)
    bl = _blends(segs, is_line, u, lengths, feeds, blend_tol, lim)
    trims = np.r_[0.0, bl.trim, 0.0]  # trims[i] at segment i's start, trims[i + 1] at its end

    rows = _Rows()
    for i, seg in enumerate(segs):
        if i > 0 and (seg.tool_down != segs[i - 1].tool_down or seg.spindle != segs[i - 1].spindle):
            rows.mark_stop()
        if isinstance(seg, Dwell):
            rows.mark_stop()
            rows.add(kind=DWELL, seg=i, length=0.0, origin=seg.start, accel=1.0, jerk=1.0, dwell=seg.seconds)
            rows.mark_stop()
            continue
        if lengths[i] <= _EPS_LEN:
            continue
        if trims[i] > 0:
            _add_blend_half(rows, bl, i - 1, i, second=True)
        if is_line[i]:
            length = lengths[i] - trims[i] - trims[i + 1]
            if length > _EPS_LEN:
                rows.add(kind=LINE, seg=i, length=length, origin=seg.start + u[i] * trims[i], u=u[i],
                         vmax=line_v[i], accel=line_a[i], jerk=line_j[i], t_start=u[i], t_end=u[i])
        elif isinstance(seg, Arc):
            _add_arc(rows, seg, i, feeds[i], lim)
        else:
            _add_curve(rows, seg, i, feeds[i], lim)
        if trims[i + 1] > 0:
            _add_blend_half(rows, bl, i, i, second=False)
    rows.mark_stop()
    if not rows.rows:
        raise PlanningError("the path does not move (every segment has zero length)", where="path")
    return rows.build(segs)


def _add_blend_half(rows: _Rows, bl: _Blends, k: int, tag: int, *, second: bool):
    """Half of the blend arc at junction k: the first half belongs to the segment before the corner."""
    half = 0.5 * bl.alpha[k]
    rows.add(kind=ARC, seg=tag, length=bl.radius[k] * half, origin=bl.center[k], u=-bl.normal[k], e2=bl.u_in[k],
             radius=bl.radius[k], phi0=half if second else 0.0, sweep=half, kappa=1.0 / bl.radius[k],
             vmax=bl.vmax[k], accel=bl.accel[k], jerk=bl.jerk[k], t_start=bl.mid[k] if second else bl.u_in[k],
             t_end=bl.u_out[k] if second else bl.mid[k])


def _add_arc(rows, seg: Arc, i, feed, lim: PathLimits):
    iu, iv = PLANES[seg.normal_axis][1]
    e1, e2, w = np.eye(3)[iu], np.eye(3)[iv], np.eye(3)[seg.normal_axis]
    r, sweep, rise = seg.radius, seg.sweep, seg.rise
    pitch = rise / abs(sweep)
    kappa = r / (r * r + pitch * pitch)
    moved = e1 + e2 + (w if abs(rise) > 1e-12 else 0.0)
    v, a, j = (float(x[0]) for x in lim.over(moved > 0))
    v = min(v, feed)
    n = int(min(_MAX_SUBPIECES, max(1, math.ceil(seg.length / _ARC_PIECE))))
    center = seg.center.copy()
    for k in range(n):
        s_a, s_b = seg.length * k / n, seg.length * (k + 1) / n
        rows.add(kind=ARC, seg=i, length=s_b - s_a, origin=center + w * (rise * k / n), u=e1, e2=e2, w=w,
                 radius=r, phi0=seg.start_angle + sweep * k / n, sweep=sweep / n, rise=rise / n, kappa=kappa,
                 vmax=v, accel=a, jerk=j, t_start=seg.tangent_at(s_a), t_end=seg.tangent_at(s_b))


def _add_curve(rows, seg, i, feed, lim: PathLimits):
    length = seg.length
    n = int(min(_MAX_SUBPIECES, max(1, math.ceil(length / _CURVE_PIECE))))
    m = 16 * n
    s = np.linspace(0.0, length, m + 1)
    tan = seg.tangent_at(s)
    step_angle = corner_angle(tan[:-1], tan[1:])
    kappa_iv = step_angle / (length / m)
    # Bound each piece's curvature by its intervals and their neighbours, with a small margin.
    padded = np.maximum(kappa_iv, np.maximum(np.r_[kappa_iv[1:], 0.0], np.r_[0.0, kappa_iv[:-1]]))
    kappa = 1.02 * padded.reshape(n, 16).max(axis=1)
    moved = np.max(np.abs(tan), axis=0) > 1e-9
    v, a, j = (float(x[0]) for x in lim.over(moved))
    v = min(v, feed)
    for k in range(n):
        s_a, s_b = length * k / n, length * (k + 1) / n
        rows.add(kind=CURVE, seg=i, length=s_b - s_a, origin=seg.point_at(s_a), seg_s0=s_a, kappa=kappa[k],
                 vmax=v, accel=a, jerk=j, t_start=tan[16 * k], t_end=tan[16 * (k + 1)])
