"""Where a tool-centre path would cut into the programmed contour, and the pocket clearing loops.

The interference check is pyclipper's: the programmed contour's cutting segments (arcs as chords within
``CHORD_MM``) are grown by a little less than the tool radius into the region the tool centre must never
enter; each tool-centre segment, sampled the same way, is clipped against it. The ends of what lies
inside are then found on the exact segments (lines and arcs, by bisection on the exact distance to the
contour), so a trimmed path keeps its exact arcs.

Pockets (``pocket_loops``) are pyclipper offsets of the region the closed contours enclose (even-odd:
islands are holes) by the tool radius, then by the step-over again and again until nothing is left.
"""

from __future__ import annotations

import math

import numpy as np
import pyclipper

from flowmc.errors import PathError
from flowmc.motion.path import Arc, Line, Segment, describe_segment

__all__ = ["CHORD_MM", "gouges", "distance_to", "sub_segment", "pocket_loops", "closed_polygons"]

CHORD_MM = 1e-3  # arcs as chords within this, for pyclipper
_SCALE = 1e6  # pyclipper works in integers: nanometres
_MARGIN_MM = 5e-3  # the grown contour stays this far inside the tool radius (chord and rounding error)
_EXACT_MM = 1e-6  # a tool centre closer than radius - this to the contour cuts into it


def _polyline(seg: Segment, chord: float) -> np.ndarray:
    """XY points along a line or XY arc (chords within ``chord``)."""
    if isinstance(seg, Arc):
        r = seg.radius
        step = 2.0 * math.acos(max(-1.0, 1.0 - chord / r)) if r > chord else math.pi / 2
        n = max(2, int(math.ceil(abs(seg.sweep) / step)) + 1)
        s = np.linspace(0.0, seg.length, n)
        return np.array([seg.point_at(x)[:2] for x in s])
    return np.array([seg.start[:2], seg.end[:2]])


def _ints(points: np.ndarray) -> list[tuple[int, int]]:
    return [(int(round(x * _SCALE)), int(round(y * _SCALE))) for x, y in points]


def _floats(path) -> np.ndarray:
    return np.asarray(path, dtype=float) / _SCALE


def distance_to(p: np.ndarray, contour: list[Segment]) -> tuple[float, int]:
    """Exact XY distance from p to the nearest contour segment, and that segment's position in the list."""
    best, which = math.inf, -1
    for k, seg in enumerate(contour):
        if isinstance(seg, Arc):
            c = seg.center[:2]
            v = p - c
            angle = math.atan2(v[1], v[0])
            rel = (angle - seg.start_angle) % (2 * math.pi) if seg.ccw else (seg.start_angle - angle) % (2 * math.pi)
            if rel <= abs(seg.sweep) + 1e-12 or seg.turns > 0:
                d = abs(float(np.hypot(*v)) - seg.radius)
            else:
                d = min(float(np.hypot(*(p - seg.start[:2]))), float(np.hypot(*(p - seg.end[:2]))))
        else:
            a, b = seg.start[:2], seg.end[:2]
            ab = b - a
            den = float(ab @ ab)
            t = 0.0 if den == 0 else min(1.0, max(0.0, float((p - a) @ ab) / den))
            d = float(np.hypot(*(a + t * ab - p)))
        if d < best:
            best, which = d, k
    return best, which


def _region(contour: list[Segment], radius: float) -> list:
    grow = pyclipper.PyclipperOffset(2.0, CHORD_MM * _SCALE)
    for seg in contour:
        grow.AddPath(_ints(_polyline(seg, CHORD_MM)), pyclipper.JT_ROUND, pyclipper.ET_OPENROUND)
    return grow.Execute((radius - _MARGIN_MM) * _SCALE)


def gouges(tool_path: list[tuple[int, Segment]], contour: list[tuple[int, Segment]], radius: float
           ) -> list[tuple[int, Segment, float, float, int, float]]:
    """(index, segment, s0, s1, contour index, distance) for each stretch [s0, s1] (arc length) of a
    tool-centre segment that passes closer than ``radius`` to the contour."""
    if radius <= _MARGIN_MM or not contour:
        return []
    segs = [seg for _, seg in contour]
    region = _region(segs, radius)
    if not region:
        return []
    found: list[tuple[int, Segment, float, float, int, float]] = []
    for index, seg in tool_path:
        if seg.rapid or not isinstance(seg, (Line, Arc)) or seg.length <= 0:
            continue
        points = _ints(_polyline(seg, CHORD_MM))
        if len(set(points)) < 2:
            continue  # no travel in XY (a plunge)
        clip = pyclipper.Pyclipper()
        clip.AddPaths(region, pyclipper.PT_CLIP, True)
        clip.AddPath(points, pyclipper.PT_SUBJECT, False)
        inside = pyclipper.OpenPathsFromPolyTree(clip.Execute2(pyclipper.CT_INTERSECTION, pyclipper.PFT_NONZERO,
                                                               pyclipper.PFT_NONZERO))
        for piece in inside:
            pts = _floats(piece)
            s_a, s_b = sorted((_arc_length_of(seg, pts[0]), _arc_length_of(seg, pts[-1])))
            stretch = _exact_stretch(seg, segs, radius, s_a, s_b)
            if stretch is not None:
                s0, s1, deepest = stretch
                dist, k = distance_to(seg.point_at(deepest)[:2], segs)
                found.append((index, seg, s0, s1, contour[k][0], dist))
    return found


def _arc_length_of(seg: Segment, p: np.ndarray) -> float:
    if isinstance(seg, Arc):
        v = p - seg.center[:2]
        angle = math.atan2(v[1], v[0])
        rel = (angle - seg.start_angle) % (2 * math.pi) if seg.ccw else (seg.start_angle - angle) % (2 * math.pi)
        if rel > abs(seg.sweep) + 1e-9:  # just before the start, by rounding
            rel = 0.0 if 2 * math.pi - rel < rel - abs(seg.sweep) else abs(seg.sweep)
        return min(seg.length, rel * seg.radius)
    d = seg.end[:2] - seg.start[:2]
    return float(min(seg.length, max(0.0, (p - seg.start[:2]) @ d / float(np.hypot(*d)))))


def _exact_stretch(seg: Segment, contour: list[Segment], radius: float, s_a: float, s_b: float):
    """The stretch of seg, around [s_a, s_b], where the exact distance is below radius (None: none)."""
    limit = radius - _EXACT_MM

    def close(s: float) -> bool:
        return distance_to(seg.point_at(s)[:2], contour)[0] < limit

    samples = np.linspace(s_a, s_b, 9)
    inside = [s for s in samples if close(s)]
    if not inside:
        return None
    deepest = min(inside, key=lambda s: distance_to(seg.point_at(s)[:2], contour)[0])

    def edge(inner: float, outer: float) -> float:
        if close(outer):
            return outer
        for _ in range(60):
            mid = 0.5 * (inner + outer)
            if close(mid):
                inner = mid
            else:
                outer = mid
        return outer

    lo = edge(inside[0], max(0.0, s_a - 2 * CHORD_MM - _MARGIN_MM))
    hi = edge(inside[-1], min(seg.length, s_b + 2 * CHORD_MM + _MARGIN_MM))
    return lo, hi, deepest


def sub_segment(seg: Segment, s0: float, s1: float, **state) -> Segment:
    """The part of a line or XY arc between arc lengths s0 and s1 (exact: an arc stays an arc)."""
    start, end = seg.point_at(s0), seg.point_at(s1)
    fields = {name: getattr(seg, name) for name in ("feed", "rapid", "tool_down", "spindle", "outputs",
                                                    "analog", "source")}
    fields.update(state)
    if isinstance(seg, Arc):
        return Arc(start, end, np.append(seg.center[:2], start[2]), normal_axis=2, ccw=seg.ccw,
                   turns=int(abs(seg.sweep) * (s1 - s0) / seg.length / (2 * math.pi) - 1e-9) if seg.turns else 0,
                   **fields)
    return Line(start, end, **fields)


# Pockets ------------------------------------------------------------------------------------------
def closed_polygons(chains: list[list[tuple[int, Segment]]], tolerance: float) -> list:
    """Each closed chain as an integer polygon (chords within ``tolerance``)."""
    polygons = []
    for chain in chains:
        first, last = chain[0], chain[-1]
        if np.hypot(*(first[1].start[:2] - last[1].end[:2])) > 1e-6:
            raise PathError("a pocket boundary must be closed: this contour ends away from its start",
                            where=describe_segment(last[0], last[1].source))
        points = np.vstack([_polyline(seg, tolerance)[:-1] for _, seg in chain])
        polygons.append(_ints(points))
    return polygons


def pocket_loops(polygons: list, radius: float, stepover: float, tolerance: float, max_loops: int = 10_000
                 ) -> list[list[np.ndarray]]:
    """Offsets of the enclosed region (even-odd) by radius, radius + stepover, ...: one list of closed XY
    polylines per ring, outermost first, until nothing is left."""
    union = pyclipper.Pyclipper()
    union.AddPaths(polygons, pyclipper.PT_SUBJECT, True)
    region = union.Execute(pyclipper.CT_UNION, pyclipper.PFT_EVENODD, pyclipper.PFT_EVENODD)
    rings: list[list[np.ndarray]] = []
    for k in range(max_loops + 1):
        shrink = pyclipper.PyclipperOffset(2.0, tolerance * _SCALE)
        shrink.AddPaths(region, pyclipper.JT_ROUND, pyclipper.ET_CLOSEDPOLYGON)
        loops = shrink.Execute(-(radius + k * stepover) * _SCALE)
        if not loops:
            return rings
        rings.append([_floats(loop) for loop in loops])
    raise PathError(f"the pocket needs more than {max_loops} rings: is the step-over ({stepover:g} mm) meant "
                    f"to be so small?")


def pocket_path(path, radius: float, stepover: float, *, direction: str = "climb", feed: float | None = None,
                tolerance: float = 0.005):
    """Clear the region inside the path's closed contours (islands are holes): rings of the tool centre
    from the middle outwards, each a closed loop, the last one the tool radius inside the boundary;
    pen-up (tool up) rapids between loops. Lines within ``tolerance`` of the round offsets."""
    from flowmc.motion.path import Path

    if not (math.isfinite(radius) and radius > 0):
        raise PathError(f"the tool radius must be > 0 mm, got {radius}")
    if not (math.isfinite(stepover) and 0 < stepover <= 2 * radius):
        raise PathError(f"the step-over must be > 0 and at most the tool diameter ({2 * radius:g} mm), got "
                        f"{stepover}")
    if direction not in ("climb", "conventional"):
        raise PathError(f"direction must be 'climb' or 'conventional', got {direction!r}")
    if not (math.isfinite(tolerance) and tolerance > 0):
        raise PathError(f"the tolerance must be > 0 mm, got {tolerance}")
    chains: list[list[tuple[int, Segment]]] = []
    for i, seg in enumerate(path.segments):
        if seg.rapid or seg.kind == "dwell":
            if chains and chains[-1]:
                chains.append([])
            continue
        if not isinstance(seg, (Line, Arc)) or (isinstance(seg, Arc) and seg.normal_axis != 2):
            raise PathError(f"a pocket boundary is made of lines and XY arcs; this segment is a {seg.kind}",
                            where=describe_segment(i, seg.source))
        if seg.length <= 0 or (isinstance(seg, Line) and np.hypot(*(seg.end - seg.start)[:2]) == 0):
            continue
        if not chains or (chains[-1] and np.hypot(*(seg.start - chains[-1][-1][1].end)[:2]) > 1e-6):
            chains.append([])
        chains[-1].append((i, seg))
    chains = [c for c in chains if c]
    if not chains:
        raise PathError("the pocket boundary has no cutting moves")
    z = float(chains[0][0][1].start[2])
    feed = float(chains[0][0][1].feed if feed is None else feed)
    rings = pocket_loops(closed_polygons(chains, tolerance), radius, stepover, tolerance)
    if not rings:
        raise PathError(f"the tool (radius {radius:g} mm) does not fit in the pocket anywhere")
    segments: list[Segment] = []
    here = None
    for ring_no, ring in enumerate(reversed(rings)):
        ring_no = len(rings) - ring_no
        loops = list(ring)
        while loops:
            if here is None:
                pick = 0
            else:
                pick = min(range(len(loops)), key=lambda k: float(np.min(np.hypot(*(loops[k] - here).T))))
            loop = loops.pop(pick)
            if direction == "climb":  # pyclipper: outer loops counter-clockwise, holes clockwise
                loop = loop[::-1]
            if here is not None:
                loop = np.roll(loop, -int(np.argmin(np.hypot(*(loop - here).T))), axis=0)
            source = f"pocket ring {ring_no}" + (" (finish)" if ring_no == 1 else "")
            points = np.vstack([loop, loop[:1]])
            p3 = np.column_stack([points, np.full(len(points), z)])
            if here is not None:
                segments.append(Line(np.append(here, z), p3[0], feed=feed, rapid=True, tool_down=False,
                                     source=source))
            segments.extend(Line(a, b, feed=feed, source=source) for a, b in zip(p3[:-1], p3[1:])
                            if np.hypot(*(b - a)[:2]) > 0)
            here = points[-1]
    return Path(segments)
