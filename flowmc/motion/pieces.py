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
from flowmc.motion.path import Path, describe_segment
from flowmc.motion.path_columns import ARC as ARC_ROW
from flowmc.motion.path_columns import CURVE as CURVE_ROW
from flowmc.motion.path_columns import DWELL as DWELL_ROW
from flowmc.motion.path_columns import LINE as LINE_ROW
from flowmc.motion.path_columns import PathColumns

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
    segments: Path  # the planned path: ``segments[g]`` is segment g (curve pieces evaluate through it)

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


_VEC = ("origin", "u", "e2", "w", "t_start", "t_end")
_FLT = ("length", "radius", "phi0", "sweep", "rise", "seg_s0", "kappa", "vmax", "accel", "jerk", "dwell")


class _Table:
    """Piece columns of a known length, filled a kind at a time by row positions."""

    def __init__(self, n: int):
        self.kind = np.zeros(n, dtype=np.int8)
        self.seg = np.zeros(n, dtype=int)
        self.cols = {name: np.zeros((n, 3)) for name in _VEC} | {name: np.zeros(n) for name in _FLT}
        self.stops = np.zeros(n, dtype=bool)

    def put(self, rows, kind: int, seg, **fields) -> None:
        self.kind[rows] = kind
        self.seg[rows] = seg
        for name, value in fields.items():
            self.cols[name][rows] = value

    def build(self, path: Path) -> Pieces:
        length = self.cols["length"]
        s0 = np.concatenate([[0.0], np.cumsum(length)[:-1]])
        return Pieces(kind=self.kind, seg=self.seg, s0=s0, stop_after=self.stops, segments=path, **self.cols)


def _check_axes(path: Path, cols: list[int], machine: Machine) -> None:
    """PlanningError naming the first segment that moves along an axis the machine lacks: its end
    points, 16 points along each arc and a curve's samples are held against the path's start."""
    missing = [k for k in range(3) if k not in cols]
    if not missing or not len(path):
        return
    columns = path.columns
    origin = path.start[missing]
    moved = (np.abs(columns.start[:, missing] - origin) > 1e-9) | (np.abs(columns.end[:, missing] - origin) > 1e-9)
    geo = columns.arcs
    if len(geo.rows):
        arc = np.repeat(np.arange(len(geo.rows)), 17)
        pts = geo.points(arc, np.tile(np.linspace(0.0, 1.0, 17), len(geo.rows)), columns)
        off = (np.abs(pts[:, missing] - origin) > 1e-9).reshape(len(geo.rows), 17, len(missing)).any(axis=1)
        moved[geo.rows] |= off
    for k, curve in columns.curves.items():
        moved[k] |= (np.abs(curve.sample(0.01)[:, missing] - origin) > 1e-9).any(axis=0)
    hit = np.flatnonzero(moved.any(axis=1))
    if len(hit):
        i = int(hit[0])
        names = ", ".join("XYZ"[k] for k, m in zip(missing, moved[i]) if m)
        raise PlanningError(f"moves along {names}, which machine axes {machine.names} lack",
                            where=describe_segment(i, path.segment_names()))


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


def _blends(cols: PathColumns, is_line, u, lengths, feeds, tol: float | None, lim: PathLimits) -> _Blends:
    """Trim d and radius R of the tangent arc at each line-line corner.

    R keeps the arc within ``tol`` of the corner point (R (1/cos(alpha/2) - 1) <= tol) and, with
    the sampling chord sagitta A T^2/8 added, within ``tol`` of the programmed lines. The trims at
    the two ends of a line are scaled down together when the line is too short for both.
    """
    n = len(cols)
    u_in, u_out = u[:-1], u[1:]
    alpha = corner_angle(u_in, u_out)
    moved = (np.abs(u_in) + np.abs(u_out)) > 1e-12
    v_lim, a_lim, j_lim = lim.over(moved)
    v_lim = np.minimum(v_lim, np.minimum(feeds[:-1], feeds[1:]))
    period = lim.period
    trim = np.zeros(n - 1)
    radius = np.zeros(n - 1)
    if tol is not None and n > 1:
        same = (cols.tool_down[:-1] == cols.tool_down[1:]) & (cols.spindle[:-1] == cols.spindle[1:])
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
    corner = cols.end[:-1]
    center = corner - u_in * trim[:, None] + radius[:, None] * normal
    mid = np.cos(0.5 * alpha)[:, None] * u_in + np.sin(0.5 * alpha)[:, None] * normal
    return _Blends(trim, radius, center, normal, u_in, u_out, mid, alpha, v_lim, a_lim, j_lim)


def checked_feeds(path: Path) -> np.ndarray:
    """Each segment's path-speed cap (inf for dwells), from the path's columns; PlanningError for an empty
    path, a gap (naming the segment that does not start where the one before ends) or the first bad feed."""
    if not len(path):
        raise PlanningError("the path has no segments", where="path")
    cols = path.columns
    for i in path.gaps(1e-6):
        raise PlanningError(
            f"starts at {np.round(cols.start[i], 6).tolist()} but the segment before ends at "
            f"{np.round(cols.end[i - 1], 6).tolist()}", where=describe_segment(i, path.segment_names()))
    feeds = np.where(cols.kind == DWELL_ROW, math.inf, cols.feed)
    bad = np.flatnonzero(~(feeds > 0) | np.isnan(feeds) | (np.isinf(feeds) & (cols.kind != DWELL_ROW)))
    if len(bad):
        i = int(bad[0])
        seg = path[i]
        segment_feed(seg, describe_segment(i, seg.source))
        raise PlanningError(f"feed must be > 0 mm/s, got {seg.feed!r}", where=describe_segment(i, seg.source))
    return feeds


def build_pieces(path: Path, machine: Machine, blend_tol: float | None = None) -> Pieces:
    """Cut a path into pieces; with ``blend_tol`` (mm) round line-line corners by tangent arcs.

    Works on the path's columns, every kind of piece at once (curves one segment at a time).
    Raises PlanningError naming the segment for gaps, bad feeds, or motion on axes the machine lacks.
    """
    lim = PathLimits.of(machine)
    feeds = checked_feeds(path)
    cols = path.columns
    _check_axes(path, list(lim.cols), machine)
    n = len(cols)
    lengths = np.asarray(cols.lengths, dtype=float)
    kind = cols.kind
    dwell = kind == DWELL_ROW
    is_line = (kind == LINE_ROW) & (lengths > _EPS_LEN)
    u = np.zeros((n, 3))
    u[is_line] = (cols.end[is_line] - cols.start[is_line]) / lengths[is_line, None]
    line_v, line_a, line_j = lim.along(u)
    line_v = np.minimum(line_v, feeds)
    bl = _blends(cols, is_line, u, lengths, feeds, blend_tol, lim)
    trims = np.r_[0.0, bl.trim, 0.0]  # trims[i] at segment i's start, trims[i + 1] at its end

    # Rows per segment, in order: a blend's second half, the body (a line, arc or curve pieces, or
    # the dwell), a blend's first half. Segments of no length (and not dwells) have none.
    active = dwell | (lengths > _EPS_LEN)
    head = active & (trims[:-1] > 0)
    tail = active & (trims[1:] > 0)
    line_len = lengths - trims[:-1] - trims[1:]
    body = np.zeros(n, dtype=np.int64)
    body[dwell] = 1
    body[is_line & (line_len > _EPS_LEN)] = 1
    arc = active & (kind == ARC_ROW)
    curve = active & (kind == CURVE_ROW)
    body[arc] = np.minimum(_MAX_SUBPIECES, np.maximum(1, np.ceil(lengths[arc] / _ARC_PIECE))).astype(np.int64)
    body[curve] = np.minimum(_MAX_SUBPIECES, np.maximum(1, np.ceil(lengths[curve] / _CURVE_PIECE))).astype(np.int64)
    count = head + body + tail
    first = np.cumsum(count) - count
    total = int(count.sum())
    if total == 0:
        raise PlanningError("the path does not move (every segment has zero length)", where="path")
    table = _Table(total)

    # Stops: after the last piece before a tool or spindle change and before a dwell; after a dwell; at the end.
    change = np.zeros(n, dtype=bool)
    change[1:] = (cols.tool_down[1:] != cols.tool_down[:-1]) | (cols.spindle[1:] != cols.spindle[:-1])
    before = first[change | dwell]
    table.stops[before[before > 0] - 1] = True
    table.stops[first[dwell]] = True
    table.stops[-1] = True

    k = np.flatnonzero(head)
    _put_blend_half(table, bl, first[k], k - 1, k, second=True)
    k = np.flatnonzero(tail)
    _put_blend_half(table, bl, first[k] + head[k] + body[k], k, k, second=False)
    k = np.flatnonzero(dwell)
    table.put(first[k], DWELL, k, origin=cols.start[k], accel=1.0, jerk=1.0, dwell=cols.seconds[k])
    k = np.flatnonzero(is_line & (line_len > _EPS_LEN))
    table.put(first[k] + head[k], LINE, k, length=line_len[k], origin=cols.start[k] + u[k] * trims[k, None], u=u[k],
              vmax=line_v[k], accel=line_a[k], jerk=line_j[k], t_start=u[k], t_end=u[k])
    _put_arcs(table, cols, np.flatnonzero(arc), first, body, feeds, lim)
    for i in np.flatnonzero(curve).tolist():
        _put_curve(table, first[i] + np.arange(body[i]), path[i], i, feeds[i], lim)
    return table.build(path)


def _put_blend_half(table: _Table, bl: _Blends, rows, k, tag, *, second: bool):
    """Half of the blend arc at junctions k: the first half belongs to the segment before the corner."""
    half = 0.5 * bl.alpha[k]
    table.put(rows, ARC, tag, length=bl.radius[k] * half, origin=bl.center[k], u=-bl.normal[k], e2=bl.u_in[k],
              radius=bl.radius[k], phi0=half if second else 0.0, sweep=half, kappa=1.0 / bl.radius[k],
              vmax=bl.vmax[k], accel=bl.accel[k], jerk=bl.jerk[k], t_start=bl.mid[k] if second else bl.u_in[k],
              t_end=bl.u_out[k] if second else bl.mid[k])


def _put_arcs(table: _Table, cols: PathColumns, segs: np.ndarray, first, body, feeds, lim: PathLimits):
    """Programmed arcs and helices cut into ``body`` pieces each, all arcs at once."""
    if not len(segs):
        return
    geo = cols.arcs
    which = np.searchsorted(geo.rows, segs)  # each arc segment's row in the arc geometry
    eye = np.eye(3)
    e1, e2, w = eye[geo.iu[which]], eye[geo.iv[which]], eye[geo.normal[which]]
    r, sweep, rise = geo.r0[which], geo.sweep[which], geo.rise[which]
    pitch = rise / np.abs(sweep)
    kappa = r / (r * r + pitch * pitch)
    moved = (e1 + e2 + np.where(np.abs(rise)[:, None] > 1e-12, w, 0.0)) > 0
    v, a, j = lim.over(moved)
    v = np.minimum(v, feeds[segs])
    m = body[segs]
    owner = np.repeat(np.arange(len(segs)), m)  # index into segs, one per piece
    k = np.arange(len(owner)) - np.repeat(np.cumsum(m) - m, m)
    frac0, frac1 = k / m[owner], (k + 1) / m[owner]
    length = cols.lengths[segs]
    rows = first[segs][owner] + k
    arc_of = which[owner]
    table.put(rows, ARC, segs[owner], length=length[owner] * frac1 - length[owner] * frac0,
              origin=cols.center[segs][owner] + w[owner] * (rise[owner] * frac0)[:, None], u=e1[owner],
              e2=e2[owner], w=w[owner], radius=r[owner], phi0=geo.angle0[arc_of] + sweep[owner] * frac0,
              sweep=sweep[owner] / m[owner], rise=rise[owner] / m[owner], kappa=kappa[owner], vmax=v[owner],
              accel=a[owner], jerk=j[owner], t_start=geo.tangents(arc_of, frac0), t_end=geo.tangents(arc_of, frac1))


def _put_curve(table: _Table, rows: np.ndarray, seg, i: int, feed: float, lim: PathLimits):
    """A tabulated curve (ellipse, NURBS) cut into ``len(rows)`` pieces, each with its curvature bound."""
    length = seg.length
    n = len(rows)
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
    s_a = length * np.arange(n) / n
    s_b = length * np.arange(1, n + 1) / n
    table.put(rows, CURVE, i, length=s_b - s_a, origin=seg.point_at(s_a), seg_s0=s_a, kappa=kappa, vmax=min(v, feed),
              accel=a, jerk=j, t_start=tan[0:16 * n:16], t_end=tan[16:16 * n + 1:16])
