"""Time-division (data-sampling) interpolation: lines and circular arcs at period T.

A profile gives the distance s_k travelled by t = kT; lines map s_k to points exactly. Arcs step
the radius vector by the angle d_k = (s_{k+1} - s_k) / R each period, either by the exact rotation
recurrence (x' = x cos d - y sin d, y' = x sin d + y cos d; the DSP thesis's improvement) or by the
LabVIEW thesis's second-order form (cos d ~ 1 - d^2/2, sin d ~ d). The second-order step has
modulus sqrt(1 + d^4/4) > 1, so its radius grows by that factor every period (radial drift
outward) and it turns d + d^3/6 instead of d. The recurrences run as cumulative products of
complex rotation factors, which is the same sequence of multiplications, vectorised.
"""

from __future__ import annotations

import math

import numpy as np

from flowmc.errors import PathError

__all__ = ["arc_feed_limit", "line_points", "arc_points", "arc_geometry", "circle_errors"]

_RADIUS_TOL = 1e-4  # mm: start and end radii of an arc may differ this much


def arc_feed_limit(radius: float, period: float, eps: float) -> float:
    """Highest feed whose chord per period stays within eps of a circle of this radius:
    v <= (2/T) sqrt(2 R eps - eps^2) (inf when eps >= 2R: no chord can deviate more)."""
    if radius <= 0 or period <= 0 or eps <= 0:
        raise PathError(f"radius, period and eps must be > 0, got {radius}, {period}, {eps}", where="time division")
    q = 2.0 * radius * eps - eps * eps
    return math.inf if eps >= 2.0 * radius else 2.0 / period * math.sqrt(q)


def line_points(start, end, s) -> np.ndarray:
    """Points at distances s along the line start -> end: (len(s), dim). Exact (no approximation)."""
    start = np.asarray(start, dtype=float)
    end = np.asarray(end, dtype=float)
    s = np.asarray(s, dtype=float).reshape(-1)
    length = float(np.linalg.norm(end - start))
    if length == 0.0:
        return np.repeat(start[None, :], len(s), axis=0)
    pts = start + np.outer(s / length, end - start)
    pts[s >= length] = end
    return pts


def arc_geometry(start, end, centre, ccw: bool = True, plane=(0, 1), turns: int = 0) -> tuple[float, float, float]:
    """(radius, signed sweep in radians, length) of the arc from start to end about centre in the plane
    of axes ``plane`` (in-plane coordinates in that order; ccw is positive from the first towards the
    second); other axes move linearly (helix). start == end in the plane is a full circle; ``turns``
    adds full turns."""
    start, end, centre = (np.asarray(x, dtype=float) for x in (start, end, centre))
    i, j = plane
    r0 = math.hypot(start[i] - centre[i], start[j] - centre[j])
    r1 = math.hypot(end[i] - centre[i], end[j] - centre[j])
    if r0 <= 0:
        raise PathError("arc start coincides with its centre", where="time division")
    if abs(r0 - r1) > _RADIUS_TOL:
        raise PathError(f"arc end is not on the circle: start radius {r0:.6f}, end radius {r1:.6f} mm",
                        where="time division")
    a0 = math.atan2(start[j] - centre[j], start[i] - centre[i])
    a1 = math.atan2(end[j] - centre[j], end[i] - centre[i])
    sweep = (a1 - a0) % (2 * math.pi) if ccw else -((a0 - a1) % (2 * math.pi))
    if abs(sweep) < 1e-12:
        sweep = 2 * math.pi if ccw else -2 * math.pi
    sweep += (2 * math.pi if ccw else -2 * math.pi) * int(turns)
    rise = np.delete(end - start, [i, j])
    return r0, sweep, math.hypot(r0 * sweep, float(np.linalg.norm(rise)))


def arc_points(start, end, centre, s, *, ccw: bool = True, plane=(0, 1), turns: int = 0,
               method: str = "exact") -> np.ndarray:
    """Setpoints (len(s), dim) at distances s (from 0 to the arc length) along an arc.

    ``method="exact"`` rotates by cos/sin of each step angle; ``"second_order"`` uses cos d ~ 1 - d^2/2,
    sin d ~ d (drifts outward). The first point is ``start``; a point at s >= length is ``end`` exactly,
    so a second-order sequence shows its accumulated drift as a jump into the end point.
    """
    start, end, centre = (np.asarray(x, dtype=float) for x in (start, end, centre))
    s = np.asarray(s, dtype=float).reshape(-1)
    radius, sweep, length = arc_geometry(start, end, centre, ccw, plane, turns)
    i, j = plane
    frac = np.clip(s / length, 0.0, 1.0)
    d = np.diff(frac) * sweep  # step angles, signed
    if method == "exact":
        step = np.exp(1j * d)
    elif method == "second_order":
        step = (1.0 - 0.5 * d * d) + 1j * d
    else:
        raise PathError(f"method must be 'exact' or 'second_order', got {method!r}", where="time division")
    z0 = complex(start[i] - centre[i], start[j] - centre[j])
    z = z0 * np.concatenate([[1.0 + 0j], np.cumprod(step)])
    pts = start + np.outer(frac, end - start)  # axes outside the plane: linear (helix)
    pts[:, i] = centre[i] + z.real
    pts[:, j] = centre[j] + z.imag
    pts[s >= length] = end
    return pts


def circle_errors(points, centre, radius: float, plane=(0, 1)) -> tuple[np.ndarray, np.ndarray]:
    """Errors of a setpoint sequence against a circle, in the plane of axes ``plane``.

    Returns (chord_error (N-1,), radial_error (N,)): radial_error = |p - c| - R (signed, + outside);
    chord_error of chord k = largest distance between the chord and the circle, max(R - distance from
    the centre to the chord's nearest point, |radial error| of its two ends).
    """
    p = np.asarray(points, dtype=float)[:, list(plane)] - np.asarray(centre, dtype=float)[list(plane)]
    radial = np.linalg.norm(p, axis=1) - radius
    a, b = p[:-1], p[1:]
    ab = b - a
    len2 = np.einsum("ij,ij->i", ab, ab)
    t = np.clip(-np.einsum("ij,ij->i", a, ab) / np.where(len2 > 0, len2, 1.0), 0.0, 1.0)
    nearest = np.linalg.norm(a + t[:, None] * ab, axis=1)
    chord = np.maximum(radius - nearest, np.maximum(np.abs(radial[:-1]), np.abs(radial[1:])))
    return chord, radial
