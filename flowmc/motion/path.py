"""The Path value: an ordered list of geometric segments, each with its feed and tool state.

Every path source (segment table, G-code, NURBS, image contours) produces a Path and every planner
or interpolator consumes one. Segments are immutable; transforms return new ones. Arc length ``s``
runs from 0 at a segment's start to ``segment.length`` at its end, and every geometric method is
vectorised over ``s``.
"""

from __future__ import annotations

import copy
import math
from dataclasses import FrozenInstanceError, dataclass, field
from functools import cached_property
from typing import Iterable, Sequence, TypeVar

import numpy as np

import flowmc.budget as budget
from flowmc.errors import PathError
from flowmc.motion.path_columns import ARC, CURVE, DWELL, LINE, PLANES, PathColumns
from flowmc.motion.values import array_digest, frozen_array

__all__ = [
    "Segment",
    "Line",
    "Arc",
    "EllipseArc",
    "NurbsCurve",
    "Dwell",
    "PathEvent",
    "EVENT_KINDS",
    "Path",
    "PLANES",
    "chord_count",
    "describe_segment",
]

_RADIUS_TOL = 1e-4  # mm: start and end radii closer than this make a circular arc
# An arc whose end radius differs more is a spiral, as LinuxCNC cuts it (the radius blends along the
# sweep): accepted up to LinuxCNC's inch tolerance (0.002 * sqrt(2) in) or 0.1 % of the radius, and
# never past 100 times that tolerance (LinuxCNC's limits, see flowmc/motion/gcode/arcs.py).
_SPIRAL_ABS = 0.002 * math.sqrt(2.0) * 25.4
_SPIRAL_REL = 0.001


MAX_COORD_MM = 1e9  # 1000 km: beyond any machine, and squares of it stay far from overflow


def _vec3(value, name: str) -> np.ndarray:
    arr = np.asarray(value, dtype=float).reshape(-1)
    if arr.shape == (2,):
        arr = np.append(arr, 0.0)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise PathError(f"{name} must be 2 or 3 finite numbers, got {value!r}")
    if np.abs(arr).max() > MAX_COORD_MM:
        raise PathError(f"{name} {arr.tolist()} is out of range: coordinates must be within +-{MAX_COORD_MM:g} mm")
    return frozen_array(arr)


def describe_segment(index: int, names: str | Sequence[str] = ()) -> str:
    """How every user-facing message names segment ``index`` (0-based) of a path or of a planned program.

    Users count segments from 1 and know them by where they came from, so the name is the 1-based
    number and the segment's ``source``: ``describe_segment(4, ("", "row 1", ..., "row 4"))`` is
    ``"segment 5 (row 4)"``. ``names`` is the segment's own name (a str) or one name per segment
    (``Path.segment_names()``, ``Trajectory.segment_names``); without a name: ``"segment 5"``.
    """
    index = int(index)
    if isinstance(names, str):
        name = names
    else:
        name = names[index] if 0 <= index < len(names) else ""
    return f"segment {index + 1} ({name})" if name else f"segment {index + 1}"


def chord_count(length: float, min_radius: float, tol: float) -> int:
    """Chords needed so none deviates more than ``tol`` from a curve of the given min radius."""
    if not math.isfinite(min_radius) or min_radius <= tol:
        step = max(math.sqrt(8.0 * min(min_radius, tol) * tol), 1e-6) if min_radius > 0 else length
    else:
        step = 2.0 * math.sqrt(2.0 * min_radius * tol - tol * tol)
    count = length / max(step, 1e-12)
    budget.check("points", count, what=f"sampling {length:.6g} mm of curve within {tol:g} mm",
                 change="loosen the chord tolerance, or make the curve shorter (fewer turns)")
    return max(1, math.ceil(count))


@dataclass(frozen=True, eq=False, kw_only=True)
class Segment:
    """Fields every segment carries: feed, rapid flag and the tool state at its start.

    ``spindle`` is signed rpm (+ clockwise/M3, - counter-clockwise/M4, 0 off); ``outputs`` and
    ``analog`` are ``(channel, value)`` changes applied as the segment starts; ``source`` says where
    the segment came from (``"part.ngc:12"``, ``"row 3"``) for error messages.
    """

    feed: float = 100.0
    rapid: bool = False
    tool_down: bool = True
    spindle: float = 0.0
    outputs: tuple[tuple[int, bool], ...] = ()
    analog: tuple[tuple[int, float], ...] = ()
    source: str = ""

    kind = "segment"

    def _meta(self) -> tuple:
        return (self.kind, self.feed, self.rapid, self.tool_down, self.spindle, self.outputs, self.analog)

    def with_state(self, **changes) -> "Segment":
        """A copy with feed/tool-state fields changed (geometry, and its cached values, shared)."""
        unknown = set(changes) - set(_STATE_FIELDS)
        if unknown:
            raise TypeError(f"not a segment state field: {sorted(unknown)}")
        new = copy.copy(self)
        for key, value in changes.items():
            object.__setattr__(new, key, value)
        return new

    # Geometry every kind provides -------------------------------------------------------------
    start: np.ndarray = field(init=False, repr=False)
    end: np.ndarray = field(init=False, repr=False)

    @property
    def length(self) -> float:
        raise NotImplementedError

    def point_at(self, s) -> np.ndarray:
        raise NotImplementedError

    def tangent_at(self, s) -> np.ndarray:
        raise NotImplementedError

    def sample(self, tol: float) -> np.ndarray:
        raise NotImplementedError

    def transformed(self, matrix: np.ndarray, offset: np.ndarray) -> "Segment":
        raise NotImplementedError

    def digest_parts(self) -> tuple:
        raise NotImplementedError

    def describe(self) -> dict:
        return {"kind": self.kind, "start": self.start.round(6).tolist(), "end": self.end.round(6).tolist(),
                "length": round(self.length, 6), "feed": self.feed, "rapid": self.rapid}


def _clip_s(seg: Segment, s) -> np.ndarray:
    return np.clip(np.asarray(s, dtype=float), 0.0, seg.length)


@dataclass(frozen=True, eq=False, kw_only=True)
class Line(Segment):
    """A straight 3D move."""

    kind = "line"

    def __init__(self, start, end, **state):
        object.__setattr__(self, "start", _vec3(start, "line start"))
        object.__setattr__(self, "end", _vec3(end, "line end"))
        for key, value in {**_defaults(), **state}.items():
            object.__setattr__(self, key, value)

    @classmethod
    def chain(cls, points, **state) -> list["Line"]:
        """Lines through ``points`` (N, 3), all with the same state: checked once, built without the
        per-line checks (a traced picture has hundreds of thousands)."""
        pts = np.asarray(points, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 3 or not np.all(np.abs(pts) <= MAX_COORD_MM):
            raise PathError(f"line points must be (N, 3) within +-{MAX_COORD_MM:g} mm, got shape {pts.shape}",
                            where=state.get("source"))
        rows = [frozen_array(p) for p in pts]
        fields = {**_defaults(), **state}
        out = []
        for a, b in zip(rows[:-1], rows[1:]):
            line = object.__new__(cls)
            line.__dict__.update(fields, start=a, end=b)
            out.append(line)
        return out

    @cached_property
    def length(self) -> float:
        return float(np.linalg.norm(self.end - self.start))

    def point_at(self, s) -> np.ndarray:
        s = _clip_s(self, s)
        if self.length == 0.0:
            return np.broadcast_to(self.start, np.shape(s) + (3,)).copy()
        return self.start + np.multiply.outer(s / self.length, self.end - self.start)

    def tangent_at(self, s) -> np.ndarray:
        d = self.end - self.start
        unit = d / self.length if self.length > 0 else d
        return np.broadcast_to(unit, np.shape(np.asarray(s)) + (3,)).copy()

    def sample(self, tol: float) -> np.ndarray:
        return np.vstack([self.start, self.end])

    def transformed(self, matrix, offset) -> "Line":
        return Line(matrix @ self.start + offset, matrix @ self.end + offset, **_state(self))

    def digest_parts(self) -> tuple:
        return (*self._meta(), self.start, self.end)


@dataclass(frozen=True, eq=False, kw_only=True)
class Arc(Segment):
    """A circular arc in the plane normal to ``normal_axis`` (2: XY/G17, 1: XZ/G18, 0: YZ/G19).

    ``ccw`` is the turn direction seen from the positive normal axis. The normal coordinate may
    change linearly along the arc: then it is a helix. ``turns`` adds full turns (RS274's P word);
    a full circle has ``start == end`` in the plane.
    """

    center: np.ndarray = field(init=False)
    normal_axis: int = 2
    ccw: bool = True
    turns: int = 0

    kind = "arc"

    def __init__(self, start, end, center, normal_axis: int = 2, ccw: bool = True, turns: int = 0, **state):
        if normal_axis not in PLANES:
            raise PathError(f"arc normal axis must be 0, 1 or 2, got {normal_axis!r}", where=state.get("source"))
        budget.check("turns", turns, what="an arc", change="give the arc fewer turns (G-code P, the row's angles)",
                     where=state.get("source") or None)
        if int(turns) < 0:
            raise PathError(f"arc extra turns must be >= 0, got {turns}", where=state.get("source"))
        object.__setattr__(self, "start", _vec3(start, "arc start"))
        object.__setattr__(self, "end", _vec3(end, "arc end"))
        center = _vec3(center, "arc centre").copy()
        center[normal_axis] = self.start[normal_axis]
        center.setflags(write=False)
        object.__setattr__(self, "center", center)
        object.__setattr__(self, "normal_axis", int(normal_axis))
        object.__setattr__(self, "ccw", bool(ccw))
        object.__setattr__(self, "turns", int(turns))
        for key, value in {**_defaults(), **state}.items():
            object.__setattr__(self, key, value)
        r0, r1 = self._radii()
        if r0 <= 0 or r1 <= 0:
            raise PathError("arc radius is zero (start or end point is the centre)", where=self.source or None)
        diff = abs(r0 - r1)
        if diff > max(_RADIUS_TOL, 1e-9 * r0) and (diff > 100.0 * _SPIRAL_ABS or (
                diff > _SPIRAL_ABS and diff > _SPIRAL_REL * max(r0, r1))):
            raise PathError(
                f"arc end is not on the circle: start radius {r0:.6f} mm, end radius {r1:.6f} mm",
                where=self.source or None,
            )

    @property
    def plane(self) -> str:
        return PLANES[self.normal_axis][0]

    def _uv(self, p: np.ndarray) -> np.ndarray:
        iu, iv = PLANES[self.normal_axis][1]
        return np.stack([p[..., iu] - self.center[iu], p[..., iv] - self.center[iv]], axis=-1)

    def _radii(self) -> tuple[float, float]:
        return float(np.linalg.norm(self._uv(self.start))), float(np.linalg.norm(self._uv(self.end)))

    @cached_property
    def radius(self) -> float:
        """The start radius (the radius of a circular arc)."""
        return self._radii()[0]

    @cached_property
    def end_radius(self) -> float:
        """The end radius: equal to ``radius`` within 0.0001 mm, except for a spiral (an arc whose end
        LinuxCNC accepts off the circle; the radius then blends linearly along the sweep)."""
        return self._radii()[1]

    @cached_property
    def start_angle(self) -> float:
        u, v = self._uv(self.start)
        return math.atan2(v, u)

    @cached_property
    def sweep(self) -> float:
        """Signed swept angle in radians (positive ccw), full turns included."""
        u0, v0 = self._uv(self.start)
        u1, v1 = self._uv(self.end)
        delta = math.atan2(v1, u1) - math.atan2(v0, u0)
        two_pi = 2.0 * math.pi
        if self.ccw:
            delta %= two_pi
            if delta < 1e-12:
                delta = two_pi
        else:
            delta = -((-delta) % two_pi)
            if delta > -1e-12:
                delta = -two_pi
        return delta + (two_pi if self.ccw else -two_pi) * self.turns

    @cached_property
    def rise(self) -> float:
        """Change of the normal coordinate along the arc (non-zero for a helix)."""
        return float(self.end[self.normal_axis] - self.start[self.normal_axis])

    @cached_property
    def length(self) -> float:
        return math.hypot(0.5 * (self.radius + self.end_radius) * abs(self.sweep), self.rise)

    def _theta(self, s) -> np.ndarray:
        return self.start_angle + _clip_s(self, s) / self.length * self.sweep

    def point_at(self, s) -> np.ndarray:
        s = np.asarray(s, dtype=float)
        theta = self._theta(s)
        iu, iv = PLANES[self.normal_axis][1]
        f = _clip_s(self, s) / self.length
        r = self.radius + (self.end_radius - self.radius) * f
        out = np.empty(np.shape(s) + (3,))
        out[..., iu] = self.center[iu] + r * np.cos(theta)
        out[..., iv] = self.center[iv] + r * np.sin(theta)
        out[..., self.normal_axis] = self.start[self.normal_axis] + f * self.rise
        return out

    def tangent_at(self, s) -> np.ndarray:
        s = np.asarray(s, dtype=float)
        theta = self._theta(s)
        iu, iv = PLANES[self.normal_axis][1]
        dr = self.end_radius - self.radius
        r = self.radius + dr * _clip_s(self, s) / self.length
        w = self.sweep * r
        out = np.empty(np.shape(s) + (3,))
        out[..., iu] = -np.sin(theta) * w + np.cos(theta) * dr
        out[..., iv] = np.cos(theta) * w + np.sin(theta) * dr
        out[..., self.normal_axis] = self.rise
        return out / np.linalg.norm(out, axis=-1, keepdims=True)

    def sample(self, tol: float) -> np.ndarray:
        r = min(self.radius, self.end_radius)
        n = chord_count(r * abs(self.sweep), r, tol)
        return self.point_at(np.linspace(0.0, self.length, n + 1))

    def transformed(self, matrix, offset) -> "Arc":
        matrix = np.asarray(matrix, dtype=float)
        iu, iv = PLANES[self.normal_axis][1]
        eu, ev = np.eye(3)[iu], np.eye(3)[iv]
        mu, mv = matrix @ eu, matrix @ ev
        scale = np.linalg.norm(mu)
        if scale == 0 or abs(np.linalg.norm(mv) - scale) > 1e-9 * scale or abs(mu @ mv) > 1e-9 * scale**2:
            raise PathError("a non-uniform scale would turn this arc into an ellipse", where=self.source or None)
        omega = np.sign(np.linalg.det(matrix)) * (matrix @ np.eye(3)[self.normal_axis]) / scale
        axis = int(np.argmax(np.abs(omega)))
        if abs(abs(omega[axis]) - 1.0) > 1e-9:
            raise PathError("this transform would tip the arc out of the XY, XZ or YZ plane", where=self.source or None)
        return Arc(matrix @ self.start + offset, matrix @ self.end + offset, matrix @ self.center + offset,
                   normal_axis=axis, ccw=(omega[axis] > 0) == self.ccw, turns=self.turns, **_state(self))

    def digest_parts(self) -> tuple:
        return (*self._meta(), self.start, self.end, self.center, self.normal_axis, self.ccw, self.turns)

    def describe(self) -> dict:
        return {**super().describe(), "center": self.center.round(6).tolist(), "plane": self.plane,
                "ccw": self.ccw, "radius": round(self.radius, 6), "sweep_deg": round(math.degrees(self.sweep), 6)}


class _TabulatedCurve:
    """Arc-length parameterisation by a dense table, for curves without a closed form (ellipse, NURBS)."""

    _TABLE = 2049

    def _param_range(self) -> tuple[float, float]:
        raise NotImplementedError

    def _eval(self, t: np.ndarray, nderiv: int) -> np.ndarray:
        """Points (nderiv=0) or first derivatives (nderiv=1) at parameters t, shape (len(t), 3)."""
        raise NotImplementedError

    @cached_property
    def _table(self) -> tuple[np.ndarray, np.ndarray]:
        t0, t1 = self._param_range()
        t = np.linspace(t0, t1, self._TABLE)
        speed = np.linalg.norm(self._eval(t, 1), axis=1)
        # Simpson's rule on each table interval, accumulated.
        mid = np.linalg.norm(self._eval(0.5 * (t[1:] + t[:-1]), 1), axis=1)
        ds = (speed[1:] + 4.0 * mid + speed[:-1]) / 6.0 * np.diff(t)
        return t, np.concatenate([[0.0], np.cumsum(ds)])

    @property
    def length(self) -> float:
        return float(self._table[1][-1])

    def param_at(self, s) -> np.ndarray:
        """Curve parameter at arc length s: table lookup plus one Newton step."""
        t_tab, s_tab = self._table
        s = np.clip(np.asarray(s, dtype=float), 0.0, s_tab[-1])
        t = np.interp(s, s_tab, t_tab)
        seg = np.clip(np.searchsorted(s_tab, s) - 1, 0, len(s_tab) - 2)
        t_left = t_tab[seg]
        mid = 0.5 * (t_left + t)
        speed_left = np.linalg.norm(self._eval(np.atleast_1d(t_left), 1), axis=1)
        speed_mid = np.linalg.norm(self._eval(np.atleast_1d(mid), 1), axis=1)
        speed_t = np.linalg.norm(self._eval(np.atleast_1d(t), 1), axis=1)
        partial = (speed_left + 4.0 * speed_mid + speed_t) / 6.0 * (np.atleast_1d(t) - t_left)
        err = s_tab[seg] + partial - np.atleast_1d(s)
        t_new = np.atleast_1d(t) - err / np.maximum(speed_t, 1e-12)
        t0, t1 = self._param_range()
        return np.clip(t_new, min(t0, t1), max(t0, t1)).reshape(np.shape(s))

    def point_at(self, s) -> np.ndarray:
        s = np.asarray(s, dtype=float)
        return self._eval(np.atleast_1d(self.param_at(s)), 0).reshape(np.shape(s) + (3,))

    def tangent_at(self, s) -> np.ndarray:
        s = np.asarray(s, dtype=float)
        d = self._eval(np.atleast_1d(self.param_at(s)), 1)
        d = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
        return d.reshape(np.shape(s) + (3,))


@dataclass(frozen=True, eq=False, kw_only=True)
class EllipseArc(_TabulatedCurve, Segment):
    """An elliptical arc ``center + U cos t + V sin t`` for t from ``t0`` to ``t1`` (t1 < t0 runs clockwise).

    U and V are the semi-axis vectors (perpendicular for an ordinary ellipse); any affine transform
    maps them to another ellipse, so transforms stay exact.
    """

    center: np.ndarray = field(init=False)
    u_axis: np.ndarray = field(init=False)
    v_axis: np.ndarray = field(init=False)
    t0: float = 0.0
    t1: float = 0.0

    kind = "ellipse"

    def __init__(self, center, u_axis, v_axis, t0: float, t1: float, **state):
        object.__setattr__(self, "center", _vec3(center, "ellipse centre"))
        object.__setattr__(self, "u_axis", _vec3(u_axis, "ellipse U axis"))
        object.__setattr__(self, "v_axis", _vec3(v_axis, "ellipse V axis"))
        object.__setattr__(self, "t0", float(t0))
        object.__setattr__(self, "t1", float(t1))
        for key, value in {**_defaults(), **state}.items():
            object.__setattr__(self, key, value)
        if np.linalg.norm(np.cross(self.u_axis, self.v_axis)) == 0.0:
            raise PathError("ellipse semi-axes must be non-zero and not parallel", where=self.source or None)
        if self.t0 == self.t1:
            raise PathError("ellipse arc sweeps no angle (start angle equals end angle)", where=self.source or None)
        object.__setattr__(self, "start", frozen_array(self._eval(np.array([self.t0]), 0)[0]))
        object.__setattr__(self, "end", frozen_array(self._eval(np.array([self.t1]), 0)[0]))

    @classmethod
    def from_axes(cls, center, a: float, b: float, rotation: float, t0: float, t1: float, **state) -> "EllipseArc":
        """An XY ellipse with semi-axes a, b, its a-axis turned ``rotation`` radians from X."""
        if a <= 0 or b <= 0:
            raise PathError(f"ellipse semi-axes must be > 0, got a={a}, b={b}", where=state.get("source"))
        c, s = math.cos(rotation), math.sin(rotation)
        return cls(center, (a * c, a * s, 0.0), (-b * s, b * c, 0.0), t0, t1, **state)

    def _param_range(self):
        return self.t0, self.t1

    def _eval(self, t, nderiv):
        c, s = np.cos(t)[:, None], np.sin(t)[:, None]
        if nderiv == 0:
            return self.center + c * self.u_axis + s * self.v_axis
        return -s * self.u_axis + c * self.v_axis

    @cached_property
    def min_radius(self) -> float:
        a, b = np.linalg.norm(self.u_axis), np.linalg.norm(self.v_axis)
        lo, hi = min(a, b), max(a, b)
        return lo * lo / hi

    def sample(self, tol: float) -> np.ndarray:
        n = chord_count(self.length, self.min_radius, tol)
        return self.point_at(np.linspace(0.0, self.length, n + 1))

    def transformed(self, matrix, offset) -> "EllipseArc":
        return EllipseArc(matrix @ self.center + offset, matrix @ self.u_axis, matrix @ self.v_axis,
                          self.t0, self.t1, **_state(self))

    def digest_parts(self) -> tuple:
        return (*self._meta(), self.center, self.u_axis, self.v_axis, self.t0, self.t1)


@dataclass(frozen=True, eq=False, kw_only=True)
class NurbsCurve(_TabulatedCurve, Segment):
    """A NURBS curve: control points (n, 3), weights (n,), knots (n + degree + 1,), degree."""

    control_points: np.ndarray = field(init=False)
    weights: np.ndarray = field(init=False)
    knots: np.ndarray = field(init=False)
    degree: int = 3

    kind = "nurbs"

    def __init__(self, control_points, weights=None, knots=None, degree: int = 3, **state):
        from flowmc.motion import nurbs

        ctrl = np.asarray(control_points, dtype=float)
        if ctrl.ndim != 2 or ctrl.shape[1] not in (2, 3):
            raise PathError(f"NURBS control points must be a list of [x, y] or [x, y, z], got shape {ctrl.shape}",
                            where=state.get("source"))
        if ctrl.shape[1] == 2:
            ctrl = np.column_stack([ctrl, np.zeros(len(ctrl))])
        if not np.all(np.abs(ctrl) <= MAX_COORD_MM):
            raise PathError(f"NURBS control points must be finite and within +-{MAX_COORD_MM:g} mm",
                            where=state.get("source"))
        w = np.ones(len(ctrl)) if weights is None else np.asarray(weights, dtype=float)
        k = nurbs.clamped_uniform_knots(len(ctrl), degree) if knots is None else np.asarray(knots, dtype=float)
        nurbs.check_nurbs(ctrl, w, k, degree)
        object.__setattr__(self, "control_points", frozen_array(ctrl))
        object.__setattr__(self, "weights", frozen_array(w))
        object.__setattr__(self, "knots", frozen_array(k))
        object.__setattr__(self, "degree", int(degree))
        for key, value in {**_defaults(), **state}.items():
            object.__setattr__(self, key, value)
        ends = self._eval(np.array([k[degree], k[-degree - 1]]), 0)
        object.__setattr__(self, "start", frozen_array(ends[0]))
        object.__setattr__(self, "end", frozen_array(ends[1]))

    def _param_range(self):
        return float(self.knots[self.degree]), float(self.knots[-self.degree - 1])

    def _eval(self, t, nderiv):
        from flowmc.motion import nurbs

        return nurbs.evaluate(self.control_points, self.weights, self.knots, self.degree, t, nderiv=nderiv)[nderiv]

    @cached_property
    def min_radius(self) -> float:
        from flowmc.motion import nurbs

        t_tab, _ = self._table
        kappa = nurbs.curvature(self.control_points, self.weights, self.knots, self.degree, t_tab)
        kappa = kappa[np.isfinite(kappa)]  # a cusp (speed 0) has no curvature to sample by
        return float(1.0 / max(np.max(kappa, initial=0.0), 1e-12))

    def sample(self, tol: float) -> np.ndarray:
        n = chord_count(self.length, self.min_radius, tol)
        return self.point_at(np.linspace(0.0, self.length, n + 1))

    def transformed(self, matrix, offset) -> "NurbsCurve":
        ctrl = self.control_points @ np.asarray(matrix, dtype=float).T + offset
        return NurbsCurve(ctrl, self.weights, self.knots, self.degree, **_state(self))

    def digest_parts(self) -> tuple:
        return (*self._meta(), self.control_points, self.weights, self.knots, self.degree)


#: What a PathEvent asks of whoever runs the path (see ``PathEvent``).
EVENT_KINDS = ("pause", "optional_pause", "pallet_change", "tool_change", "index")


@dataclass(frozen=True)
class PathEvent:
    """Something between motions that needs the operator, carried by a zero-second ``Dwell``.

    ``kind``: ``"pause"`` (M0: stop until resumed), ``"optional_pause"`` (M1: stop only when the
    optional-stop switch is on), ``"pallet_change"`` (M60: stop for a pallet shuttle), ``"tool_change"``
    (M6: stop for a manual tool change to ``tool``; a plotter may treat it as a pen swap), ``"index"``
    (a G0/G1 that moves only a rotary or UVW axis, which flowmc paths do not have: stop so it can be
    indexed; ``axes`` says where to: ``(("B", 45.0),)``, degrees for A/B/C, mm for U/V/W). ``message``
    is what to show the operator (a preceding ``(MSG, ...)``, or the new tool's table entry).
    Motion before the event has come to a stop when it happens; nothing after it starts until the
    job resumes.
    """

    kind: str
    message: str = ""
    tool: int | None = None
    axes: tuple[tuple[str, float], ...] = ()

    def __post_init__(self):
        if self.kind not in EVENT_KINDS:
            raise PathError(f"path event kind must be one of {', '.join(EVENT_KINDS)}, got {self.kind!r}")
        if any(not (isinstance(a, str) and len(a) == 1 and a in "ABCUVW") or not math.isfinite(v)
               for a, v in self.axes):
            raise PathError(f"an event's axes are (letter A/B/C/U/V/W, finite value) pairs, got {self.axes!r}")

    def describe(self) -> dict:
        out: dict = {"kind": self.kind}
        if self.message:
            out["message"] = self.message
        if self.tool is not None:
            out["tool"] = self.tool
        if self.axes:
            out["axes"] = dict(self.axes)
        return out


@dataclass(frozen=True, eq=False, kw_only=True)
class Dwell(Segment):
    """A pause at a point (G4): no motion for ``seconds``; with an ``event``, a stop for the operator."""

    seconds: float = 0.0
    event: PathEvent | None = None

    kind = "dwell"

    def __init__(self, point, seconds: float, event: PathEvent | None = None, **state):
        p = _vec3(point, "dwell point")
        if not seconds >= 0:
            raise PathError(f"dwell time must be >= 0 s, got {seconds}", where=state.get("source"))
        if event is not None and not isinstance(event, PathEvent):
            raise PathError(f"a dwell's event must be a PathEvent, got {type(event).__name__}",
                            where=state.get("source"))
        object.__setattr__(self, "start", p)
        object.__setattr__(self, "end", p)
        object.__setattr__(self, "seconds", float(seconds))
        object.__setattr__(self, "event", event)
        for key, value in {**_defaults(), **state}.items():
            object.__setattr__(self, key, value)

    length = 0.0

    def point_at(self, s) -> np.ndarray:
        return np.broadcast_to(self.start, np.shape(np.asarray(s)) + (3,)).copy()

    def tangent_at(self, s) -> np.ndarray:
        return np.zeros(np.shape(np.asarray(s)) + (3,))

    def sample(self, tol: float) -> np.ndarray:
        return self.start[None, :].copy()

    def transformed(self, matrix, offset) -> "Dwell":
        return Dwell(matrix @ self.start + offset, self.seconds, self.event, **_state(self))

    def digest_parts(self) -> tuple:
        return (*self._meta(), self.start, self.seconds, self.event)

    def describe(self) -> dict:
        out = {**super().describe(), "seconds": self.seconds}
        if self.event is not None:
            out["event"] = self.event.describe()
        return out


_STATE_FIELDS = ("feed", "rapid", "tool_down", "spindle", "outputs", "analog", "source")


def _defaults() -> dict:
    return {"feed": 100.0, "rapid": False, "tool_down": True, "spindle": 0.0, "outputs": (), "analog": (), "source": ""}


def _state(seg: Segment) -> dict:
    return {name: getattr(seg, name) for name in _STATE_FIELDS}


def _rotation_z(degrees: float) -> np.ndarray:
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


_S = TypeVar("_S", bound=Segment)


def _trusted(cls: type[_S], fields: dict, **more) -> _S:
    """A segment from fields already checked (a column row, a checked chain of points), without
    re-running its constructor's checks."""
    seg = object.__new__(cls)
    seg.__dict__.update(fields, **more)
    return seg


def _segment_at(cols: PathColumns, k: int) -> Segment:
    """Row ``k`` of the columns as a Segment object (a curve row is its stored object)."""
    kind = int(cols.kind[k])
    if kind == CURVE:
        return cols.curves[k]
    fields = {"feed": float(cols.feed[k]), "rapid": bool(cols.rapid[k]), "tool_down": bool(cols.tool_down[k]),
              "spindle": float(cols.spindle[k]), "outputs": cols.outputs.get(k, ()),
              "analog": cols.analog.get(k, ()), "source": cols.names[k], "start": cols.start[k]}
    if kind == LINE:
        return _trusted(Line, fields, end=cols.end[k])
    if kind == ARC:
        return _trusted(Arc, fields, end=cols.end[k], center=cols.center[k], normal_axis=int(cols.normal_axis[k]),
                        ccw=bool(cols.ccw[k]), turns=int(cols.turns[k]))
    return _trusted(Dwell, fields, end=cols.start[k], seconds=float(cols.seconds[k]), event=cols.events.get(k))


def _segments_of(cols: PathColumns) -> tuple[Segment, ...]:
    """Every row as a Segment object: ``_segment_at`` for all rows, with the columns read once."""
    starts, ends, centers = list(cols.start), list(cols.end), list(cols.center)
    feed, rapid, tool, spindle = (cols.feed.tolist(), cols.rapid.tolist(), cols.tool_down.tolist(),
                                  cols.spindle.tolist())
    normal, ccw, turns, seconds = (cols.normal_axis.tolist(), cols.ccw.tolist(), cols.turns.tolist(),
                                   cols.seconds.tolist())
    names, outputs, analog, events = cols.names, cols.outputs, cols.analog, cols.events
    out = []
    for k, kind in enumerate(cols.kind.tolist()):
        if kind == CURVE:
            out.append(cols.curves[k])
            continue
        fields = {"feed": feed[k], "rapid": rapid[k], "tool_down": tool[k], "spindle": spindle[k],
                  "outputs": outputs.get(k, ()), "analog": analog.get(k, ()), "source": names[k], "start": starts[k]}
        if kind == LINE:
            out.append(_trusted(Line, fields, end=ends[k]))
        elif kind == ARC:
            out.append(_trusted(Arc, fields, end=ends[k], center=centers[k], normal_axis=normal[k], ccw=ccw[k],
                                turns=turns[k]))
        else:
            out.append(_trusted(Dwell, fields, end=starts[k], seconds=seconds[k], event=events.get(k)))
    return tuple(out)


def _number(value) -> float:
    """A feed or spindle value as a float column entry; NaN for what is not a real number (a planner
    then refuses it, naming the segment)."""
    if isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_)):
        return float(value)
    return math.nan


def columns_of(segments: Sequence[Segment]) -> PathColumns:
    """Segment objects as columns (what a planner reads); curves other than arcs stay objects."""
    n = len(segments)
    kinds = {Line: LINE, Arc: ARC, Dwell: DWELL}
    kind = np.array([kinds.get(type(seg), CURVE) for seg in segments], dtype=np.int8)
    start = np.array([seg.start for seg in segments], dtype=float).reshape(n, 3)
    end = np.array([seg.end for seg in segments], dtype=float).reshape(n, 3)
    center = np.zeros((n, 3))
    normal = np.full(n, 2, dtype=np.int8)
    ccw = np.ones(n, dtype=bool)
    turns = np.zeros(n, dtype=np.int64)
    seconds = np.zeros(n)
    events, outputs, analog, curves = {}, {}, {}, {}
    for k, seg in enumerate(segments):
        if isinstance(seg, Arc):
            center[k], normal[k], ccw[k], turns[k] = seg.center, seg.normal_axis, seg.ccw, seg.turns
        elif isinstance(seg, Dwell):
            seconds[k] = seg.seconds
            if seg.event is not None:
                events[k] = seg.event
        elif kind[k] == CURVE:
            curves[k] = seg
        if seg.outputs:
            outputs[k] = seg.outputs
        if seg.analog:
            analog[k] = seg.analog
    return PathColumns(
        kind=kind, start=start, end=end, feed=np.array([_number(seg.feed) for seg in segments]).reshape(n),
        rapid=np.array([bool(seg.rapid) for seg in segments], dtype=bool).reshape(n),
        tool_down=np.array([bool(seg.tool_down) for seg in segments], dtype=bool).reshape(n),
        spindle=np.array([_number(seg.spindle) for seg in segments]).reshape(n), center=center, normal_axis=normal,
        ccw=ccw, turns=turns, seconds=seconds, files=tuple(seg.source or "" for seg in segments),
        file=np.arange(n, dtype=np.int64), line=np.full(n, -1, dtype=np.int64), events=events, outputs=outputs,
        analog=analog, curves=curves)


class Path:
    """An ordered, immutable list of segments. Consecutive segments should join end to start.

    A path is held either as Segment objects (what most sources build) or as columns
    (``Path.from_columns``: what the G-code reader builds, 100k moves without 100k objects). Both
    behave the same; ``path.columns`` is the column form (made once from objects when asked),
    ``path.segments`` the objects (made once from columns when asked), ``path[i]`` one segment.
    """

    _cols: PathColumns | None

    def __init__(self, segments: Iterable[Segment] = ()):
        segs = tuple(segments)
        for i, seg in enumerate(segs):
            if not isinstance(seg, Segment):
                raise PathError(f"{describe_segment(i)} is a {type(seg).__name__}, not a path segment")
        self.__dict__.update(segments=segs, _cols=None)

    @classmethod
    def from_columns(cls, columns: PathColumns) -> "Path":
        """A path over columns whose rows the caller has checked (a reader's output)."""
        path = cls.__new__(cls)
        path.__dict__.update(_cols=columns)
        return path

    def __setattr__(self, name, value):
        raise FrozenInstanceError(f"cannot assign to field {name!r}")

    def __repr__(self) -> str:
        return f"Path({len(self)} segments)"

    @cached_property
    def segments(self) -> tuple[Segment, ...]:
        cols = self._cols
        assert cols is not None  # an object path's segments are set by __init__
        return _segments_of(cols)

    @cached_property
    def columns(self) -> PathColumns:
        """The path as columns, one row per segment (see PathColumns)."""
        return self._cols if self._cols is not None else columns_of(self.segments)

    def __len__(self) -> int:
        return len(self._cols) if self._cols is not None else len(self.segments)

    def __iter__(self):
        return iter(self.segments)

    def __getitem__(self, i):
        if self._cols is not None and "segments" not in self.__dict__ and isinstance(i, (int, np.integer)):
            n = len(self._cols)
            if not -n <= i < n:
                raise IndexError("path segment index out of range")
            return _segment_at(self._cols, int(i) % n)
        return self.segments[i]

    def __getstate__(self):
        return {"segments": self.segments} if self._cols is None else {"_cols": self._cols}

    def __setstate__(self, state):
        self.__dict__.update({"_cols": None, **state})

    def kind_counts(self) -> dict[str, int]:
        """How many segments of each kind (``{"arc": 3, "line": 10}``), kinds in name order."""
        if self._cols is not None:
            return self._cols.kind_counts()
        return {k: sum(s.kind == k for s in self.segments) for k in sorted({s.kind for s in self.segments})}

    def events(self) -> tuple[tuple[int, PathEvent], ...]:
        """``(segment index, event)`` for every segment carrying a PathEvent, in order: the pauses
        and tool changes a job stops for (see ``PathEvent``)."""
        if self._cols is not None:
            return tuple(sorted(self._cols.events.items()))
        return tuple((i, seg.event) for i, seg in enumerate(self.segments)
                     if isinstance(seg, Dwell) and seg.event is not None)

    def segment_names(self) -> tuple[str, ...]:
        """Each segment's ``source`` ("" where it has none): what a Trajectory or Steps planned from this
        path carries as ``segment_names``, so messages can say ``segment 5 (row 4)``."""
        if self._cols is not None:
            return self._cols.names
        return tuple(seg.source or "" for seg in self.segments)

    def segment_rapid(self) -> tuple[bool, ...]:
        """Each segment's rapid flag: what a Trajectory or Steps planned from this path carries as
        ``segment_rapid``, so a job's rapid override knows which moves are rapids."""
        if self._cols is not None:
            return tuple(self._cols.rapid.tolist())
        return tuple(bool(seg.rapid) for seg in self.segments)

    @property
    def start(self) -> np.ndarray:
        if not len(self):
            raise PathError("the path is empty")
        return self._cols.start[0] if self._cols is not None else self.segments[0].start

    @property
    def end(self) -> np.ndarray:
        if not len(self):
            raise PathError("the path is empty")
        return self._cols.end[-1] if self._cols is not None else self.segments[-1].end

    @cached_property
    def lengths(self) -> np.ndarray:
        if self._cols is not None:
            return self._cols.lengths
        return frozen_array([seg.length for seg in self.segments])

    @property
    def length(self) -> float:
        return float(self.lengths.sum())

    def gaps(self, tol: float = 1e-6) -> list[int]:
        """Indices i where segment i does not start at the end of segment i-1."""
        cols = self.columns  # built once and kept: the planners read the columns next anyway
        jump = np.linalg.norm(cols.start[1:] - cols.end[:-1], axis=1)
        return (np.flatnonzero(jump > tol) + 1).tolist()

    def sample(self, tol: float = 0.01) -> tuple[np.ndarray, np.ndarray]:
        """Points along the whole path with chord error <= tol, and the segment index of each point.

        The first point is the path's start; every later point belongs to the segment it ends. A
        segment's first point is dropped only where it repeats the previous segment's last point.
        """
        if not len(self):
            return np.zeros((0, 3)), np.zeros(0, dtype=int)
        if self._cols is not None:
            return self._cols.sample(tol)
        chunks, index = [], []
        last, total = None, 0
        for i, seg in enumerate(self.segments):
            pts = seg.sample(tol)
            total += len(pts)
            budget.check("points", total, what=f"sampling a path of {len(self.segments)} segments within {tol:g} mm",
                         change="loosen the chord tolerance, or split the program")
            if last is not None and np.allclose(pts[0], last, rtol=0.0, atol=1e-9):
                pts = pts[1:]
            if len(pts):
                last = pts[-1]
            chunks.append(pts)
            index.append(np.full(len(pts), i, dtype=int))
        return np.vstack(chunks), np.concatenate(index)

    def bbox(self, tol: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
        """(min corner, max corner) of the path, exact to ``tol``."""
        pts, _ = self.sample(tol)
        if len(pts) == 0:
            raise PathError("the path is empty")
        return pts.min(axis=0), pts.max(axis=0)

    # Transforms ------------------------------------------------------------------------------
    def transformed(self, matrix, offset=(0.0, 0.0, 0.0)) -> "Path":
        """Apply ``p -> matrix @ p + offset`` to every segment."""
        m = np.asarray(matrix, dtype=float)
        o = np.asarray(offset, dtype=float)
        return Path(seg.transformed(m, o) for seg in self.segments)

    def translated(self, offset) -> "Path":
        return self.transformed(np.eye(3), _vec3(offset, "offset"))

    def rotated(self, degrees: float, about=(0.0, 0.0, 0.0)) -> "Path":
        """Rotate about the Z axis through ``about`` (degrees, counter-clockwise)."""
        r = _rotation_z(degrees)
        c = _vec3(about, "rotation centre")
        return self.transformed(r, c - r @ c)

    def scaled(self, factor, about=(0.0, 0.0, 0.0)) -> "Path":
        """Scale about ``about`` by a number or per-axis factors (arcs need equal factors in their plane)."""
        f = np.broadcast_to(np.asarray(factor, dtype=float), (3,))
        if np.any(f == 0):
            raise PathError(f"scale factor must be non-zero, got {factor!r}")
        c = _vec3(about, "scale centre")
        m = np.diag(f)
        return self.transformed(m, c - m @ c)

    def mirrored(self, axis: str, about: float = 0.0) -> "Path":
        """Mirror across the plane ``axis = about`` (axis 'X', 'Y' or 'Z')."""
        k = "XYZ".find(axis.upper())
        if k < 0 or len(axis) != 1:
            raise PathError(f"mirror axis must be X, Y or Z, got {axis!r}")
        m = np.eye(3)
        m[k, k] = -1.0
        o = np.zeros(3)
        o[k] = 2.0 * about
        return self.transformed(m, o)

    def concat(self, other: "Path", rapid_feed: float | None = None) -> "Path":
        """This path, then a rapid (tool up) to the other's start if they do not meet, then the other."""
        if not self.segments:
            return other
        if not other.segments:
            return self
        return Path.joined((self, other), rapid_feed)

    @staticmethod
    def joined(paths: Iterable["Path"], rapid_feed: float | None = None) -> "Path":
        """The paths one after another, linked as ``concat`` links two (in one pass, however many)."""
        segments: list[Segment] = []
        end = None
        for path in paths:
            if not path.segments:
                continue
            if end is not None and np.linalg.norm(path.start - end) > 1e-9:
                first = path.segments[0]
                segments.append(Line(end, path.start, feed=rapid_feed or first.feed, rapid=True, tool_down=False,
                                     spindle=first.spindle, source="join"))
            segments.extend(path.segments)
            end = path.end
        return Path(segments)

    def with_feed(self, feed: float) -> "Path":
        """Every non-rapid segment at the given feed (mm/s)."""
        if not feed > 0:
            raise PathError(f"feed must be > 0 mm/s, got {feed}")
        return Path(seg if seg.rapid else seg.with_state(feed=float(feed)) for seg in self.segments)

    # Runtime protocol ------------------------------------------------------------------------
    @cached_property
    def _digest(self) -> str:
        return _columns_digest(self.columns)

    def digest(self) -> str:
        return self._digest

    def summary(self) -> dict:
        out: dict = {"type": "Path", "segments": len(self), "length_mm": round(self.length, 6)}
        if len(self):
            lo, hi = self.bbox()
            out.update(start=self.start.round(6).tolist(), end=self.end.round(6).tolist(),
                       bbox_min=lo.round(4).tolist(), bbox_max=hi.round(4).tolist(),
                       kinds=self.kind_counts())
            events = self.events()
            if events:
                out["events"] = [{"segment": i + 1, **event.describe()} for i, event in events]
        return out

    @staticmethod
    def polyline(points: Sequence, feed: float = 100.0, **state) -> "Path":
        """Lines through the given points (2D or 3D)."""
        pts = np.asarray(points, dtype=float)
        if pts.ndim != 2 or len(pts) < 2 or pts.shape[1] not in (2, 3):
            raise PathError(f"a polyline needs at least two 2D or 3D points, got shape {pts.shape}")
        if pts.shape[1] == 2:
            pts = np.column_stack([pts, np.zeros(len(pts))])
        return Path(Line(a, b, feed=feed, source=state.pop("source", f"point {i + 1}"), **state)
                    for i, (a, b) in enumerate(zip(pts[:-1], pts[1:])))


def _columns_digest(cols: PathColumns) -> str:
    """The content hash of a column path: every column but the sources, as segment digests leave them out."""
    arc = cols.kind == ARC
    sparse = [sorted(d.items()) for d in (cols.events, cols.outputs, cols.analog)]
    curves = [(k, *c.digest_parts()) for k, c in sorted(cols.curves.items())]
    return array_digest("Path", len(cols), cols.kind, cols.start, cols.end, cols.feed, cols.rapid, cols.tool_down,
                        cols.spindle, cols.center[arc], cols.normal_axis[arc], cols.ccw[arc], cols.turns[arc],
                        cols.seconds, *sparse, *curves)
