"""Tool-radius compensation (G41/G42): a Path of lines and XY arcs offset left or right by the tool radius.

The LabVIEW thesis (seeds/000, chapter 6) blames most of its plexiglass machining error on cutting
with the tool centre on the drawn line; an offset path puts the cutter's edge there instead.

Each cutting segment is offset in XY (a line shifts by r along its left or right normal; an arc's
radius grows or shrinks by r) and keeps the original's start and end Z, spread over the offset piece,
so a sloped line or a helix stays one and corners stay at the corner's Z.
Consecutive offsets are then joined: where they open a gap (a convex corner, seen from the offset
side) an arc of radius r about the original corner bridges it; where they overlap (a concave
corner) both are trimmed at their intersection. A chain that ends where it started is closed and
its last segment is joined to its first too. Rapids split the path into chains and are re-aimed at
the offset chains' new ends; moves without XY travel (plunges, dwells) are kept at the offset point.
Adjacent segments are compared exactly; then every tool-centre segment is checked against the whole
programmed contour (pyclipper, flowmc.motion.clearance): a stretch that passes closer than the tool radius
to any part of it (a slot narrower than the tool, a concave arc tighter than the radius, a wall the
offset runs into) would gouge it. ``gouge="refuse"`` refuses the path naming both segments;
``gouge="trim"`` leaves such stretches uncut (the tool lifts over them: a rapid with the tool up), and
keeps the rest exact, arcs as arcs. Where the tool has no room at all (a slot narrower than it, a
concave arc tighter than it), refuse names the segment, and trim joins the offsets around it by a
straight connector that the check then lifts over; trim refuses only when nothing is left to cut.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from flowmc.errors import PathError
from flowmc.motion.clearance import gouges, sub_segment
from flowmc.motion.path import MAX_COORD_MM, Arc, Dwell, Line, Path, Segment, describe_segment

__all__ = ["offset_path"]

_TOL = 1e-9  # mm: offsets that meet closer than this need no corner
_STATE = ("feed", "rapid", "tool_down", "spindle", "outputs", "analog", "source")


def _state(seg: Segment, **changes) -> dict:
    return {**{name: getattr(seg, name) for name in _STATE}, **changes}


def _unit(v: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(v)
    if not norm > 0:  # a piece shorter than float precision at this size has no direction to offset along
        raise PathError("a piece of the path is too short, next to its size, to offset (no direction)")
    return v / norm


def _left(v: np.ndarray) -> np.ndarray:
    return np.array([-v[1], v[0]])


def _cross(a: np.ndarray, b: np.ndarray) -> float:
    return float(a[0] * b[1] - a[1] * b[0])


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


@dataclass
class _Piece:
    """The XY offset of one line or arc, trimmed to the fractions [t0, t1] of its own extent."""

    index: int
    seg: Segment
    a: np.ndarray | None = None  # offset line ends (XY)
    b: np.ndarray | None = None
    c: np.ndarray | None = None  # offset arc centre, radius, start angle and signed sweep
    radius: float = 0.0
    theta0: float = 0.0
    sweep: float = 0.0
    t0: float = 0.0
    t1: float = 1.0

    @property
    def where(self) -> str:
        return describe_segment(self.index, self.seg.source)

    @property
    def is_line(self) -> bool:
        return self.a is not None

    def point(self, t: float) -> np.ndarray:
        if self.is_line:
            return self.a + t * (self.b - self.a)
        th = self.theta0 + t * self.sweep
        return self.c + self.radius * np.array([math.cos(th), math.sin(th)])

    def tangent(self, t: float) -> np.ndarray:
        if self.is_line:
            return _unit(self.b - self.a)
        th = self.theta0 + t * self.sweep
        return math.copysign(1.0, self.sweep) * np.array([-math.sin(th), math.cos(th)])

    def z(self, t: float) -> float:
        """Z runs from the segment's start Z to its end Z over the trimmed piece (as G41/G42 controls do)."""
        f = (t - self.t0) / (self.t1 - self.t0)
        return float(self.seg.start[2] + f * (self.seg.end[2] - self.seg.start[2]))

    def param(self, x: np.ndarray, near: float) -> float:
        """The fraction at which the offset curve passes through x, taking the turn nearest ``near``."""
        if self.is_line:
            d = self.b - self.a
            return float((x - self.a) @ d / (d @ d))
        angle = math.atan2(x[1] - self.c[1], x[0] - self.c[0])
        nominal = self.theta0 + near * self.sweep
        return near + _wrap(angle - nominal) / self.sweep

    def extent(self) -> float:
        """Length of the trimmed piece in XY."""
        span = self.t1 - self.t0
        return span * (float(np.linalg.norm(self.b - self.a)) if self.is_line else self.radius * abs(self.sweep))

    def build(self) -> Segment:
        p0, p1 = self.point(self.t0), self.point(self.t1)
        start = np.append(p0, self.z(self.t0))
        end = np.append(p1, self.z(self.t1))
        state = _state(self.seg)
        if self.is_line:
            return Line(start, end, **state)
        return _arc(start, end, self.c, (self.t1 - self.t0) * self.sweep, state)


def _arc(start: np.ndarray, end: np.ndarray, center: np.ndarray, sweep: float, state: dict) -> Arc:
    """An XY arc of the given signed sweep (full turns included) from start to end."""
    turns_f = abs(sweep) / (2.0 * math.pi)
    whole = round(turns_f)
    if whole >= 1 and abs(turns_f - whole) * 2.0 * math.pi * np.linalg.norm(start[:2] - center[:2]) < _TOL:
        end = end.copy()
        end[:2] = start[:2]  # whole turns: land exactly on the start so the arc is not a sliver
        turns = whole - 1
    else:
        turns = int(turns_f)
    return Arc(start, end, np.append(center, start[2]), normal_axis=2, ccw=sweep > 0, turns=turns, **state)


def _piece(index: int, seg: Segment, r: float, sign: float) -> _Piece:
    """Offset one segment by r to the left (sign +1) or right (sign -1) of travel."""
    if isinstance(seg, Line):
        d = _unit((seg.end - seg.start)[:2])
        shift = sign * r * _left(d)
        return _Piece(index, seg, a=seg.start[:2] + shift, b=seg.end[:2] + shift)
    turn = 1.0 if seg.ccw else -1.0
    radius = seg.radius - sign * turn * r  # the left of a ccw arc is towards its centre
    if radius <= _TOL:
        raise PathError(
            f"the tool radius {r:g} mm is not smaller than this arc's radius {seg.radius:g} mm on the "
            f"offset side: the offset arc would have radius {radius:g} mm",
            where=describe_segment(index, seg.source))
    return _Piece(index, seg, c=np.array(seg.center[:2]), radius=radius, theta0=seg.start_angle, sweep=seg.sweep)


# --------------------------------------------------------------------------- intersections (XY)

def _line_circle(p: np.ndarray, d: np.ndarray, c: np.ndarray, radius: float) -> list[np.ndarray]:
    d = _unit(d)
    w = p - c
    b = float(d @ w)
    disc = b * b - (float(w @ w) - radius * radius)
    if disc < -_TOL:
        return []
    root = math.sqrt(max(disc, 0.0))
    return [p + (-b - root) * d, p + (-b + root) * d]


def _circle_circle(c1: np.ndarray, r1: float, c2: np.ndarray, r2: float) -> list[np.ndarray]:
    v = c2 - c1
    dist = float(np.linalg.norm(v))
    if dist < _TOL:
        return []
    along = (dist * dist + r1 * r1 - r2 * r2) / (2.0 * dist)
    h2 = r1 * r1 - along * along
    if h2 < -_TOL:
        return []
    h = math.sqrt(max(h2, 0.0))
    e = v / dist
    base = c1 + along * e
    return [base + h * _left(e), base - h * _left(e)]


def _intersections(p: _Piece, q: _Piece) -> list[np.ndarray]:
    if p.is_line and q.is_line:
        d, e = p.b - p.a, q.b - q.a
        den = _cross(d, e)
        if abs(den) < 1e-15 * (d @ d + e @ e):
            return []
        return [p.a + _cross(q.a - p.a, e) / den * d]
    if p.is_line:
        return _line_circle(p.a, p.b - p.a, q.c, q.radius)
    if q.is_line:
        return _line_circle(q.a, q.b - q.a, p.c, p.radius)
    return _circle_circle(p.c, p.radius, q.c, q.radius)


# --------------------------------------------------------------------------- joins

def _join(p: _Piece, q: _Piece, corner: np.ndarray, r: float, sign: float) -> Segment | None:
    """Join p's end to q's start: trim both (concave) or return the corner arc (convex)."""
    end, start = p.point(1.0), q.point(0.0)
    if np.linalg.norm(end - start) <= _TOL:
        return None
    t_in, t_out = p.tangent(1.0), q.tangent(0.0)
    turn = _cross(t_in, t_out)
    convex = sign * turn < 0 or (abs(turn) < 1e-12 and t_in @ t_out < 0)
    z = float(q.seg.start[2])
    if convex:
        n_in, n_out = (end - corner[:2]) / r, (start - corner[:2]) / r
        sweep = math.atan2(_cross(n_in, n_out), float(n_in @ n_out))
        if sweep * sign > 0:  # the bridge turns with the path: cw for a left offset, ccw for a right one
            sweep -= math.copysign(2.0 * math.pi, sweep)
        return _arc(np.append(end, z), np.append(start, z), corner[:2], sweep,
                    _state(q.seg, outputs=(), analog=(), source=f"{q.where} corner"))
    found = _intersections(p, q)
    if not found:
        raise PathError(f"the tool radius {r:g} mm is too large here: the offsets of this segment and "
                        f"{p.where} do not meet", where=q.where)

    def score(x):
        tp, tq = p.param(x, 1.0), q.param(x, 0.0)
        proper = tp <= 1.0 + 1e-9 and tq >= -1e-9
        return (not proper, float(np.linalg.norm(x - end) + np.linalg.norm(x - start)))

    x = min(found, key=score)
    p.t1, q.t0 = p.param(x, 1.0), q.param(x, 0.0)
    return None


def _chains(path: Path):
    """Split into ('chain', [(i, seg), ...]) runs of cutting moves and ('rapid', [...]) runs."""
    runs: list[tuple[str, list]] = []
    for i, seg in enumerate(path.segments):
        kind = "rapid" if seg.rapid else "chain"
        joined = runs and runs[-1][0] == kind and (
            kind == "rapid" or np.linalg.norm(seg.start - runs[-1][1][-1][1].end) <= 1e-6)
        if joined:
            runs[-1][1].append((i, seg))
        else:
            runs.append((kind, [(i, seg)]))
    return runs


def _moves_in_xy(index: int, seg: Segment) -> bool:
    if isinstance(seg, Dwell):
        return False
    if isinstance(seg, Line):
        return float(np.linalg.norm((seg.end - seg.start)[:2])) > _TOL
    if isinstance(seg, Arc) and seg.normal_axis == 2:
        return True
    what = f"an arc in the {seg.plane} plane" if isinstance(seg, Arc) else f"a {seg.kind}"
    raise PathError(f"tool-radius offset handles lines and XY arcs only; this segment is {what}",
                    where=describe_segment(index, seg.source))


def _placed(seg: Segment, xy: np.ndarray) -> Segment:
    """A move without XY travel (plunge, dwell) moved to the offset point."""
    if isinstance(seg, Dwell):
        return Dwell(np.append(xy, seg.start[2]), seg.seconds, seg.event, **_state(seg))
    return Line(np.append(xy, seg.start[2]), np.append(xy, seg.end[2]), **_state(seg))


def _connector(p: _Piece, q: _Piece) -> Line:
    """Where the exact offset cannot be made (trim mode): a straight move from p's end to q's start. It
    passes inside the tool radius of the contour, so the gouge check lifts it over."""
    z = float(q.seg.start[2])
    return Line(np.append(p.point(p.t1), z), np.append(q.point(q.t0), z),
                **_state(q.seg, outputs=(), analog=(), source=f"{q.where} (no room for the tool)"))


def _offset_chain(chain: list[tuple[int, Segment]], r: float, sign: float, lenient: bool = False) -> list[Segment]:
    """The offset of one chain of cutting moves. ``lenient`` (trim mode): where the tool has no room
    (a concave arc tighter than it, offsets that do not meet, a segment whose offset vanishes between
    its neighbours') the offsets are joined by connectors for the gouge check to lift over, instead of
    refusing."""
    pieces: list[_Piece] = []
    still: dict[int, list[Segment]] = {}  # moves without XY travel after piece k (-1: before the first)
    moving: list[Segment] = []
    for i, seg in chain:
        if _moves_in_xy(i, seg):
            moving.append(seg)
            try:
                pieces.append(_piece(i, seg, r, sign))
            except PathError:
                if not lenient:
                    raise
        else:
            still.setdefault(len(pieces) - 1, []).append(seg)
    if not pieces:
        return [seg for _, seg in chain]
    n = len(pieces)
    closed = np.linalg.norm(moving[0].start - moving[-1].end) <= 1e-6
    corners: dict[int, Segment | None] = {}
    for k in range(n if closed else n - 1):
        p, q = pieces[k], pieces[(k + 1) % n]
        if lenient and np.linalg.norm(p.seg.end - q.seg.start) > 1e-6:  # a dropped arc between them
            corners[k] = _connector(p, q)
            continue
        try:
            corners[k] = _join(p, q, p.seg.end, r, sign)
        except PathError:
            if not lenient:
                raise
            corners[k] = _connector(p, q)
    vanished = [k for k, p in enumerate(pieces) if p.extent() <= _TOL]
    while lenient and vanished:
        for k in vanished:  # undo the trims at both its corners, and join there by connectors
            for c in ((k - 1) % n, k):
                if c in corners:
                    pieces[c].t1, pieces[(c + 1) % n].t0 = 1.0, 0.0
            for c in ((k - 1) % n, k):
                if c in corners:
                    corners[c] = _connector(pieces[c], pieces[(c + 1) % n])
        vanished = [k for k, p in enumerate(pieces) if p.extent() <= _TOL]
    for p in pieces:
        if p.extent() <= _TOL:
            raise PathError(f"the tool radius {r:g} mm is too large here: the offset of this segment vanishes "
                            "between the trims of its neighbours", where=p.where)
    built = [p.build() for p in pieces]
    first_xy = built[0].start[:2]
    out = [_placed(s, first_xy) for s in still.get(-1, [])]
    for k, seg in enumerate(built):
        out.append(seg)
        tail = still.get(k, [])
        if k < n - 1 or not closed:
            out.extend(_placed(s, seg.end[:2]) for s in tail)
        if corners.get(k) is not None:
            out.append(corners[k])
        if k == n - 1 and closed:
            out.extend(_placed(s, first_xy) for s in tail)
    return out


def _relinked(rapids: list[tuple[int, Segment]], start: np.ndarray | None, end: np.ndarray | None) -> list[Segment]:
    """Rapids re-aimed from the previous chain's new end and at the next chain's new start."""
    out = [seg for _, seg in rapids]
    for pos, point in ((0, start), (-1, end)):
        if point is None or np.array_equal(getattr(out[pos], "start" if pos == 0 else "end"), point):
            continue
        i = rapids[pos][0]
        seg = out[pos]
        if not isinstance(seg, Line):
            raise PathError(f"a rapid {seg.kind} cannot be re-aimed at the offset path",
                            where=describe_segment(i, seg.source))
        out[pos] = Line(point, seg.end, **_state(seg)) if pos == 0 else Line(seg.start, point, **_state(seg))
    return out


def offset_path(path: Path, radius: float, side: Literal["left", "right"],
                gouge: Literal["refuse", "trim"] = "refuse") -> Path:
    """The path offset by ``radius`` to the ``side`` of travel (left: G41, right: G42), in XY.

    Lines and XY arcs only; errors name the segment, 1-based with its source (``segment 4 (row 4)``).
    Where the tool would cut into the programmed contour, ``gouge`` refuses or trims (see the module).
    """
    if side not in ("left", "right"):
        raise PathError(f"offset side must be 'left' or 'right', got {side!r}")
    if gouge not in ("refuse", "trim"):
        raise PathError(f"gouge must be 'refuse' or 'trim', got {gouge!r}")
    if not (0 <= radius <= MAX_COORD_MM):
        raise PathError(f"tool radius must be a number >= 0 mm and at most {MAX_COORD_MM:g} mm, got {radius}")
    if radius == 0 or not path.segments:
        return path
    sign = 1.0 if side == "left" else -1.0
    runs = _chains(path)
    done: list[list[Segment]] = [
        _offset_chain(items, radius, sign, gouge == "trim") if kind == "chain" else [] for kind, items in runs]
    out: list[Segment] = []
    for k, (kind, items) in enumerate(runs):
        if kind == "chain":
            out.extend(done[k])
            continue
        before = done[k - 1][-1].end if k > 0 and done[k - 1] else None
        after = done[k + 1][0].start if k + 1 < len(runs) and done[k + 1] else None
        out.extend(_relinked(items, before, after))
    contour = [(i, seg) for i, seg in enumerate(path.segments) if not seg.rapid and _moves_in_xy(i, seg)]
    found = gouges(list(enumerate(out)), contour, radius)
    if not found:
        return Path(out)
    if gouge == "refuse":
        k, seg, s0, s1, hit, dist = found[0]
        raise PathError(f"the tool (radius {radius:g} mm) would cut into {describe_segment(hit, path.segments[hit].source)}"
                        f": its centre passes {dist:.4f} mm from it for {s1 - s0:.4f} mm of this offset segment (a "
                        f"slot narrower than the tool, or a concave arc smaller than the radius); choose gouge "
                        f"'trim' to leave that stretch uncut", where=describe_segment(k, seg.source))
    trimmed = _trimmed(out, found)
    if not any(not seg.rapid and seg.length > _TOL for seg in trimmed):
        raise PathError(f"the tool (radius {radius:g} mm) has no room anywhere along this contour: trimming the "
                        f"gouges leaves nothing to cut", where=describe_segment(found[0][0], found[0][1].source))
    return Path(trimmed)


def _trimmed(out: list[Segment], found: list) -> list[Segment]:
    """The tool path with the gouging stretches lifted over (rapids with the tool up)."""
    spans: dict[int, list[tuple[float, float]]] = {}
    for k, _seg, s0, s1, _hit, _dist in found:
        spans.setdefault(k, []).append((s0, s1))
    result: list[Segment] = []
    for k, seg in enumerate(out):
        cuts = sorted(spans.get(k, []))
        if not cuts:
            result.append(seg)
            continue
        pos = 0.0
        for a, b in cuts:
            if b <= pos:
                continue
            a = max(a, pos)
            if a > pos + _TOL:
                result.append(sub_segment(seg, pos, a))
            result.append(Line(seg.point_at(a), seg.point_at(b), **_state(seg, rapid=True, tool_down=False,
                                                                        outputs=(), analog=(),
                                                                        source=f"{seg.source} (gouge lifted over)")))
            pos = b
        if seg.length - pos > _TOL:
            result.append(sub_segment(seg, pos, seg.length))
    return result
