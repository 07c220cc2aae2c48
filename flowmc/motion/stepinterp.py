"""Step interpolators: point-by-point comparison (逐点比较法) and DDA (数字积分法) as whole step streams.

Every function works in integer step units (pulses) and returns a :class:`StepStream`: one row per
tick, each axis -1, 0 or +1. Nothing loops per step in Python; the streams are built from closed
forms (lines) or column-wise staircases (circles, ellipses), and DDA arcs from a chunked fixed-point
solve of the accumulator recurrences. The slow per-step loops these must equal live in the tests.

Point-by-point comparison, the rules used here
-----------------------------------------------
* Line to (Xe, Ye): F = y|Xe| - x|Ye| on absolute values; F >= 0 steps X, else Y (a line on the Y
  axis steps only Y). It takes |Xe| + |Ye| ticks, one step each. After tick k the X count is
  ``floor((k-1)|Xe|/N) + 1`` (N = |Xe| + |Ye|), which is what :func:`pbp_line` evaluates.
* Circles and ellipses use the deviation F = A x^2 + B y^2 - K relative to the centre (a circle:
  A = B = 1, K = R^2 from the start; an ellipse: A = b^2, B = a^2, K = a^2 b^2). In each quadrant
  one coordinate's magnitude falls (call it u) and the other's rises (v); F >= 0 steps u, F < 0 steps
  v. That is the textbook table (NR1: F >= 0 -> -X, F < 0 -> +Y, and so on).
* A point on an axis belongs to the quadrant the motion enters (start) or leaves (end), so a
  quadrant ends exactly when u reaches 0 and the next starts there with v = 0.
* End judgement is by step count: the last quadrant runs (u0 - ue) + (ve - v0) steps. So that the
  end point is exact even where it is not on the staircase, an axis that has reached its end
  coordinate in the last quadrant stops and the other finishes the count. An end point up to one
  step off the curve just behind a quadrant's start is reached by up to one reverse step per axis.

Because u only falls and v only rises inside a quadrant, the staircase is fixed by one number per
column u: the v at which F first turns >= 0, ``t(u) = ceil(sqrt((K - A u^2) / B))``. The v reached
when leaving column u is ``max(v0, t(u))``, so a whole quadrant is a few array operations over its
columns, with t(u) from a float sqrt corrected by exact integer tests (64-bit wrap-around arithmetic
is exact because F is small wherever it is evaluated).

DDA
---
An n-bit accumulator per axis overflows at Q = 2**n; each tick adds the integrand and an overflow
emits one step. ``preset="half"`` starts the accumulators at Q/2 (rounding instead of truncating,
the usual improvement); ``"zero"`` is the plain textbook register. Lines: integrands |Xe|, |Ye|,
exactly Q ticks, step count after k ticks ``floor((p + k|Xe|) / Q)``. Arcs: the integrand of the
axis whose magnitude falls is the other coordinate's magnitude and vice versa, updated as steps
occur; each quadrant is one block ending at the axis point (0, round(R)); an axis stops when it has
made its steps for the block; an axis whose integrand has dropped to 0 with steps still owed (the
zero preset can leave one) makes them one per tick. How close that stays to the circle (measured
over thousands of random arcs): within one step for integer radii with the half preset and the
default register (one spare bit); up to 1.41 steps for other radii, as the blocks' axis points are
up to half a step off such a circle; the zero preset lags, up to about 2.2 steps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

import flowmc.budget as budget
from flowmc.errors import PathError

__all__ = [
    "StepStream",
    "pbp_line",
    "pbp_arc",
    "pbp_ellipse",
    "pbp_conic",
    "dda_line",
    "dda_arc",
    "MAX_TICKS",
    "MAX_COORD",
]

#: Largest stream one call builds (rows); 2**27 ticks is 256 MiB of int8 steps.
MAX_TICKS = 1 << 27
#: Largest coordinate (steps from the start or centre) the exact integer arithmetic is sized for.
MAX_COORD = 1 << 30
_MASK64 = (1 << 64) - 1
_COLUMN_CHUNK = 1 << 18


@dataclass(frozen=True, eq=False)
class StepStream:
    """Steps per tick, shape (N, 2) int8 in {-1, 0, 1}, from ``start`` to ``end`` (step units)."""

    steps: np.ndarray
    start: np.ndarray
    end: np.ndarray

    def __len__(self) -> int:
        return len(self.steps)

    def positions(self) -> np.ndarray:
        """Position after each tick, with ``start`` as row 0: shape (N + 1, 2) int64."""
        out = np.empty((len(self.steps) + 1, 2), dtype=np.int64)
        out[0] = self.start
        np.cumsum(self.steps, axis=0, dtype=np.int64, out=out[1:])
        out[1:] += self.start
        return out

    def step_counts(self) -> np.ndarray:
        """Pulses sent per axis (|steps| summed), shape (2,)."""
        return np.count_nonzero(self.steps, axis=0).astype(np.int64)


def _stream(steps: np.ndarray, start, end) -> StepStream:
    steps.setflags(write=False)
    s = np.array(start, dtype=np.int64)
    e = np.array(end, dtype=np.int64)
    s.setflags(write=False)
    e.setflags(write=False)
    return StepStream(steps, s, e)


def _int_pair(value, name: str) -> tuple[int, int]:
    arr = np.asarray(value)
    if arr.shape != (2,):
        raise PathError(f"{name} must be two integers (step units), got {value!r}")
    out = []
    for item in arr.tolist():
        if isinstance(item, float):
            if not item.is_integer():
                raise PathError(f"{name} must be whole steps, got {value!r}")
            item = int(item)
        if not isinstance(item, int):
            raise PathError(f"{name} must be two integers (step units), got {value!r}")
        if abs(item) > MAX_COORD:
            raise PathError(f"{name} {value!r} is beyond the supported range of +-{MAX_COORD} steps")
        out.append(item)
    return out[0], out[1]


def _check_ticks(n: int, what: str) -> None:
    if n > MAX_TICKS:
        raise PathError(f"{what} needs at least {n} ticks, more than the {MAX_TICKS} one stream may hold; "
                        f"use a coarser step or split the segment")
    budget.check("steps", n, axes=2, what=what, change="use a coarser step or split the segment")


# ----------------------------------------------------------------------------------------------
# Point-by-point comparison: lines
# ----------------------------------------------------------------------------------------------
def pbp_line(end, start=(0, 0)) -> StepStream:
    """Point-by-point comparison line from ``start`` to ``end`` (integer steps), any quadrant."""
    x0, y0 = _int_pair(start, "line start")
    x1, y1 = _int_pair(end, "line end")
    dx, dy = x1 - x0, y1 - y0
    big_x, big_y = abs(dx), abs(dy)
    n = big_x + big_y
    if n == 0:
        raise PathError(f"zero-length line: start and end are both ({x0}, {y0})")
    _check_ticks(n, "this line")
    steps = np.zeros((n, 2), dtype=np.int8)
    if big_x == 0:
        is_x = np.zeros(n, dtype=bool)
    else:
        # X count after tick k is floor((k-1) X / N) + 1, so tick k steps X where that floor rises.
        h = np.arange(n, dtype=np.int64) * big_x // n
        is_x = np.empty(n, dtype=bool)
        is_x[0] = True
        np.not_equal(h[1:], h[:-1], out=is_x[1:])
    steps[is_x, 0] = 1 if dx > 0 else -1
    if big_y:
        steps[~is_x, 1] = 1 if dy > 0 else -1
    return _stream(steps, (x0, y0), (x1, y1))


# ----------------------------------------------------------------------------------------------
# Point-by-point comparison: circles and axis-aligned ellipses (the conic A x^2 + B y^2 = K)
# ----------------------------------------------------------------------------------------------
# Quadrants 0..3 = I..IV with their coordinate signs.
_QSIGN = ((1, 1), (-1, 1), (-1, -1), (1, -1))


def _quadrant_entering(x: int, y: int, ccw: bool) -> int:
    """Quadrant of (x, y), a point on an axis counting as the quadrant the motion enters."""
    if x > 0 and y > 0:
        return 0
    if x < 0 < y:
        return 1
    if x < 0 and y < 0:
        return 2
    if y < 0 < x:
        return 3
    if y == 0:
        return (0 if x > 0 else 2) if ccw else (3 if x > 0 else 1)
    return (1 if y > 0 else 3) if ccw else (0 if y > 0 else 2)


def _quadrant_leaving(x: int, y: int, ccw: bool) -> int:
    """Quadrant of (x, y), a point on an axis counting as the quadrant the motion leaves."""
    return _quadrant_entering(x, y, not ccw)


def _u_axis(q: int, ccw: bool) -> int:
    """Index of the axis whose magnitude falls in quadrant q (0 = X, 1 = Y)."""
    return (q % 2) if ccw else 1 - (q % 2)


class _Conic:
    """F = A x^2 + B y^2 - K with Python-int coefficients; exact sign tests on uint64 arrays."""

    def __init__(self, a_coef: int, b_coef: int, k: int):
        self.coef = (a_coef, b_coef)
        self.k = k
        self._w = tuple(np.uint64(c & _MASK64) for c in (a_coef, b_coef, k))

    def exact(self, x: int, y: int) -> int:
        return self.coef[0] * x * x + self.coef[1] * y * y - self.k

    def weights(self, u_axis: int) -> tuple[int, int]:
        return (self.coef[0], self.coef[1]) if u_axis == 0 else (self.coef[1], self.coef[0])

    def sign_ge0(self, u_axis: int, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """F(u, v) >= 0 elementwise (u, v >= 0 magnitudes); exact while |F| < 2**63 (callers keep it so)."""
        wa, wb, wk = self._w
        if u_axis == 1:
            wa, wb = wb, wa
        uu = u.astype(np.uint64)
        vv = v.astype(np.uint64)
        with np.errstate(over="ignore"):
            f = wa * uu * uu + wb * vv * vv - wk
        return f.view(np.int64) >= 0

    def thresholds(self, u_axis: int, u: np.ndarray) -> np.ndarray:
        """Per column u: the smallest v >= 0 with F(u, v) >= 0."""
        au, av = self.weights(u_axis)
        uf = u.astype(float)
        rest = np.maximum(float(self.k) - float(au) * uf * uf, 0.0)
        t = np.ceil(np.sqrt(rest / float(av))).astype(np.int64)
        while True:  # the float estimate is off by a step or two at most; F rises with v, so fix it exactly
            down = (t > 0) & self.sign_ge0(u_axis, u, t - 1)
            up = ~self.sign_ge0(u_axis, u, t)
            if not (down.any() or up.any()):
                return t
            t = t - down + up


def _staircase(conic: _Conic, u_axis: int, u0: int, v0: int, u_stop: int) -> np.ndarray:
    """v when leaving each column u = u0, u0-1, ..., u_stop+1 (the u-step happens there)."""
    cols = np.arange(u0, u_stop, -1, dtype=np.int64)
    v_out = np.empty_like(cols)
    for i in range(0, len(cols), _COLUMN_CHUNK):  # chunks keep the temporaries small
        v_out[i:i + _COLUMN_CHUNK] = conic.thresholds(u_axis, cols[i:i + _COLUMN_CHUNK])
    return np.maximum(v_out, v0, out=v_out)


def _u_step_flags(v_out: np.ndarray, v0: int, tail_v: int = 0) -> np.ndarray:
    """Flags (True = u-step) for columns leaving at ``v_out``, then ``tail_v`` more v-steps."""
    climbs = np.diff(v_out, prepend=v0)
    n_cols = len(v_out)
    total = n_cols + int(v_out[-1] - v0 if n_cols else 0) + tail_v
    flags = np.zeros(total, dtype=bool)
    if n_cols:
        flags[np.cumsum(climbs + 1) - 1] = True
    return flags


def _conic_piece(conic: _Conic, u_axis: int, u0: int, v0: int, target):
    """One quadrant, canonical: returns (u-step flags, reverse-step counts, v at its end).

    ``target`` None runs to u = 0; else (ue, ve) with the end rules in the module docstring.
    """
    if target is None:
        v_out = _staircase(conic, u_axis, u0, v0, 0)
        return _u_step_flags(v_out, v0), (0, 0), int(v_out[-1])
    ue, ve = target
    ue_c, ve_c = min(ue, u0), max(ve, v0)
    reverse = (ue - ue_c, ve_c - ve)
    v_out = _staircase(conic, u_axis, u0, v0, ue_c)
    j = int(np.searchsorted(v_out, ve_c, side="left"))
    if j < len(v_out):
        # v reaches its end while climbing column j: finish those climbs, then only u-steps.
        v_in = int(v_out[j - 1]) if j else v0
        head = _u_step_flags(v_out[:j], v0, tail_v=ve_c - v_in)
        flags = np.concatenate([head, np.ones(u0 - j - ue_c, dtype=bool)])
    else:
        v_last = int(v_out[-1]) if len(v_out) else v0
        flags = _u_step_flags(v_out, v0, tail_v=ve_c - v_last)
    return flags, reverse, ve


def _arc_plan(s, e, ccw: bool, turns: int):
    """Quadrants the arc passes, in order: list of quadrant indices (last one holds the end)."""
    q_s = _quadrant_entering(*s, ccw)
    q_e = _quadrant_leaving(*e, ccw)
    n = (q_e - q_s) % 4 if ccw else (q_s - q_e) % 4
    if n == 0:
        cross = s[0] * e[1] - s[1] * e[0]
        ahead = cross > 0 if ccw else cross < 0
        if not ahead:  # the end is behind the start (or on it): once round
            n = 4
    n += 4 * turns
    step = 1 if ccw else -1
    return [(q_s + step * i) % 4 for i in range(n + 1)]


def _to_canonical(p, q: int, ccw: bool) -> tuple[int, int]:
    ua = _u_axis(q, ccw)
    return abs(p[ua]), abs(p[1 - ua])


def _conic_steps(conic: _Conic, s, e, ccw: bool, turns: int) -> np.ndarray:
    """The whole arc from s to e (relative to the centre) as an (N, 2) int8 step array."""
    if conic.k <= max(conic.coef):
        raise PathError("curve too small for point-by-point comparison: it must reach beyond one step "
                        "from its centre along each axis")
    _check_ticks(8 * turns, "this arc")  # every quadrant takes at least two steps
    plan = _arc_plan(s, e, ccw, turns)
    parts = []
    u0, v0 = _to_canonical(s, plan[0], ccw)
    total = 0
    for i, q in enumerate(plan):
        last = i == len(plan) - 1
        ua = _u_axis(q, ccw)
        target = _to_canonical(e, q, ccw) if last else None
        if last:  # steps to the clamped end, plus any reverse steps
            ue_c, ve_c = min(target[0], u0), max(target[1], v0)
            ahead = (u0 - ue_c) + (ve_c - v0) + (target[0] - ue_c) + (ve_c - target[1])
        else:
            ahead = u0 + math.isqrt(conic.k // conic.weights(ua)[1]) + 1
        _check_ticks(total + ahead, "this arc")  # before any array of that size is made
        flags, (rev_u, rev_v), v_end = _conic_piece(conic, ua, u0, v0, target)
        total += len(flags) + rev_u + rev_v
        sx, sy = _QSIGN[q]
        u_dir = -(sx, sy)[ua]  # u falls in magnitude: step against the quadrant's sign
        v_dir = (sx, sy)[1 - ua]
        block = np.zeros((len(flags) + rev_u + rev_v, 2), dtype=np.int8)
        n = len(flags)
        block[:n, ua] = flags * np.int8(u_dir)
        block[:n, 1 - ua] = (~flags) * np.int8(v_dir)
        block[n:n + rev_u, ua] = -u_dir
        block[n + rev_u:, 1 - ua] = -v_dir
        parts.append(block)
        u0, v0 = v_end, 0
    return np.concatenate(parts) if len(parts) > 1 else parts[0]


def _check_turns(turns: int) -> int:
    if int(turns) != turns or turns < 0:
        raise PathError(f"extra turns must be a whole number >= 0, got {turns!r}")
    return int(turns)


def _check_magnitude(conic: _Conic, cmax: int, what: str) -> None:
    # |F| where it is evaluated stays below max(A, B) * 8 * (cmax + 2); keep that inside int64.
    if max(conic.coef) * 8 * (cmax + 2) >= 1 << 62:
        raise PathError(f"{what} is too large for exact 64-bit deviation arithmetic; use a coarser step")



def _arc_frame(start, end, center) -> tuple:
    """Start and end (as integers, then relative to the centre), R^2 and both radii.

    PathError unless the end is within one step of the start's circle.
    """
    c = _int_pair(center, "arc centre")
    p0 = _int_pair(start, "arc start")
    p1 = _int_pair(end, "arc end")
    s = (p0[0] - c[0], p0[1] - c[1])
    e = (p1[0] - c[0], p1[1] - c[1])
    k = s[0] * s[0] + s[1] * s[1]
    if k == 0:
        raise PathError(f"arc radius is zero: start ({p0[0]}, {p0[1]}) is the centre")
    r_s, r_e = math.sqrt(k), math.hypot(*e)
    if abs(r_e - r_s) > 1.0:
        raise PathError(f"arc end is not on the circle: start radius {r_s:.3f} steps, end radius "
                        f"{r_e:.3f} steps (they may differ by at most one step)")
    return p0, p1, s, e, k, r_s, r_e

def pbp_arc(start, end, center=(0, 0), ccw: bool = True, turns: int = 0) -> StepStream:
    """Point-by-point comparison circle from ``start`` to ``end`` about ``center`` (integer steps).

    The radius is the start's (F = 0 there); the end must be within one step of that circle.
    ``start == end`` is a full circle; ``turns`` adds whole extra turns.
    """
    p0, p1, s, e, k, r_s, r_e = _arc_frame(start, end, center)
    conic = _Conic(1, 1, k)
    _check_magnitude(conic, int(max(r_s, r_e)) + 2, "this arc")
    steps = _conic_steps(conic, s, e, bool(ccw), _check_turns(turns))
    return _stream(steps, p0, p1)


def _ellipse_distance(x: float, y: float, a: float, b: float) -> float:
    """Euclidean distance from (x, y) to the ellipse with semi-axes a (X) and b (Y).

    The nearest point is (a^2 x / (t + a^2), b^2 y / (t + b^2)) for the root t of
    (a x / (t + a^2))^2 + (b y / (t + b^2))^2 = 1, which is monotone in t: bisection finds it.
    """
    x, y = abs(x), abs(y)
    if a < b:
        a, b, x, y = b, a, y, x
    if y == 0.0:
        if x * a < a * a - b * b:  # inside the evolute: the nearest point is off the axis
            px = a * a * x / (a * a - b * b)
            return math.hypot(px - x, b * math.sqrt(max(0.0, 1.0 - (px / a) ** 2)))
        return abs(x - a)
    if x == 0.0:
        return abs(y - b)
    lo, hi = -b * b + b * y, -b * b + math.hypot(a * x, b * y)
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        g = (a * x / (mid + a * a)) ** 2 + (b * y / (mid + b * b)) ** 2 - 1.0
        if g > 0.0:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-13 * max(1.0, abs(hi)):
            break
    t = 0.5 * (lo + hi)
    return math.hypot(a * a * x / (t + a * a) - x, b * b * y / (t + b * b) - y)


def _conic_distance(conic: _Conic, x: int, y: int) -> float:
    """Distance (steps) from (x, y) to the curve F = 0, an ellipse with semi-axes sqrt(K/A), sqrt(K/B)."""
    a_coef, b_coef = conic.coef
    return _ellipse_distance(float(x), float(y), math.sqrt(conic.k / a_coef), math.sqrt(conic.k / b_coef))


def _pbp_conic(conic: _Conic, p0, p1, c, ccw: bool, turns: int, what: str) -> StepStream:
    s = (p0[0] - c[0], p0[1] - c[1])
    e = (p1[0] - c[0], p1[1] - c[1])
    for name, p in (("start", s), ("end", e)):
        if p == (0, 0):
            raise PathError(f"{what} {name} is the centre")
        d = _conic_distance(conic, *p)
        if d > 1.0:
            raise PathError(f"{what} {name} ({p[0] + c[0]}, {p[1] + c[1]}) is {d:.3f} steps off the curve "
                            f"(at most one step allowed)")
    cmax = max(abs(v) for v in (*s, *e))
    a, b = conic.coef
    cmax = max(cmax, math.isqrt(conic.k // min(a, b)) + 1)
    _check_magnitude(conic, cmax, what)
    steps = _conic_steps(conic, s, e, bool(ccw), _check_turns(turns))
    return _stream(steps, p0, p1)


def pbp_ellipse(start, end, a: int, b: int, center=(0, 0), ccw: bool = True, turns: int = 0) -> StepStream:
    """Point-by-point comparison ellipse arc, semi-axes ``a`` along X and ``b`` along Y (steps).

    Deviation F = b^2 x^2 + a^2 y^2 - a^2 b^2 (the integer form of x^2/a^2 + y^2/b^2 - 1). Start
    and end must be within one step of the ellipse; ``start == end`` runs the whole ellipse.
    """
    for name, value in (("a", a), ("b", b)):
        if int(value) != value or value < 1:
            raise PathError(f"ellipse semi-axis {name} must be a whole number of steps >= 1, got {value!r}")
    a, b = int(a), int(b)
    if max(a, b) > MAX_COORD:
        raise PathError(f"ellipse semi-axes ({a}, {b}) exceed the supported {MAX_COORD} steps")
    conic = _Conic(b * b, a * a, a * a * b * b)
    return _pbp_conic(conic, _int_pair(start, "ellipse start"), _int_pair(end, "ellipse end"),
                      _int_pair(center, "ellipse centre"), ccw, turns, "ellipse")


def pbp_conic(start, end, center, weights: tuple[int, int], ccw: bool = True, turns: int = 0) -> StepStream:
    """Point-by-point comparison on A x^2 + B y^2 = K through the start (weights = (A, B) integers).

    A circle in millimetres on axes with different step sizes is such a curve in step units; the
    path dispatcher uses this. K is taken from the start, so F = 0 there.
    """
    a_coef, b_coef = (int(w) for w in weights)
    if a_coef < 1 or b_coef < 1:
        raise PathError(f"conic weights must be integers >= 1, got {weights!r}")
    p0 = _int_pair(start, "arc start")
    c = _int_pair(center, "arc centre")
    s = (p0[0] - c[0], p0[1] - c[1])
    k = a_coef * s[0] * s[0] + b_coef * s[1] * s[1]
    return _pbp_conic(_Conic(a_coef, b_coef, k), p0, _int_pair(end, "arc end"), c, ccw, turns, "arc")


# ----------------------------------------------------------------------------------------------
# DDA
# ----------------------------------------------------------------------------------------------
_PRESETS = ("half", "zero")


def _preset_value(preset: str, bits: int) -> int:
    if preset not in _PRESETS:
        raise PathError(f"DDA accumulator preset must be one of {_PRESETS}, got {preset!r}")
    return (1 << bits) >> 1 if preset == "half" else 0


def _check_bits(bits, needed: int, what: str) -> int:
    """Register size: the integrands (up to ``needed``) must fit below 2**bits."""
    if int(bits) != bits or bits < 1:
        raise PathError(f"DDA register size must be a whole number of bits >= 1, got {bits!r}")
    bits = int(bits)
    if (1 << bits) <= needed:
        raise PathError(f"DDA register too small for {what}: {bits} bits hold integrands below "
                        f"{1 << bits}, but it needs {needed} (at least {needed.bit_length()} bits)")
    return bits


def dda_line(end, start=(0, 0), bits: int | None = None, preset: str = "half") -> StepStream:
    """DDA line: 2**bits ticks, integrands |dx|, |dy|; both axes may step on one tick.

    ``bits`` defaults to the smallest register that holds the larger of |dx|, |dy|.
    """
    x0, y0 = _int_pair(start, "line start")
    x1, y1 = _int_pair(end, "line end")
    dx, dy = x1 - x0, y1 - y0
    big = max(abs(dx), abs(dy))
    if big == 0:
        raise PathError(f"zero-length line: start and end are both ({x0}, {y0})")
    bits = big.bit_length() if bits is None else _check_bits(bits, big, "this line")
    q = 1 << bits
    _check_ticks(q, f"a {bits}-bit DDA line")
    p = _preset_value(preset, bits)
    k = np.arange(1, q + 1, dtype=np.int64)
    steps = np.zeros((q, 2), dtype=np.int8)
    for axis, d in ((0, dx), (1, dy)):
        if d:
            count = (p + k * abs(d)) >> bits
            steps[:, axis] = np.diff(count, prepend=0).astype(np.int8) * np.int8(1 if d > 0 else -1)
    return _stream(steps, (x0, y0), (x1, y1))


def _dda_block(u0: int, v0: int, nu: int, nv: int, bits: int, preset: int):
    """One DDA arc block in canonical form: u falls (integrand v), v rises (integrand u).

    Returns (u-step flags, v-step flags) per tick. The recurrence is causal: the counts after tick k
    depend on the integrands of ticks <= k only, so for a chunk of ticks we guess the v sequence,
    derive u, re-derive v, and repeat; a fixed point is the one solution of the recurrence. Chunks
    are a fraction of the 2**bits ticks one step of a unit integrand takes, so a guess that
    ignores the other axis's steps is nearly right and it settles in a few rounds.
    """
    q = 1 << bits
    shift = np.int64(bits)
    u, v, acc_u, acc_v, done_u, done_v = u0, v0, preset, preset, 0, 0
    chunk = max(256, q >> 4)
    du_parts, dv_parts = [], []
    ticks = 0
    while done_u < nu or done_v < nv:
        if done_u == nu and u == 0:
            # The v integrand is 0 for good: the owed v-steps go out one per tick.
            rest = nv - done_v
            du_parts.append(np.zeros(rest, dtype=bool))
            dv_parts.append(np.ones(rest, dtype=bool))
            break
        left_u, left_v = nu - done_u, nv - done_v
        guess = np.full(chunk, v, dtype=np.int64)
        while True:  # each round makes at least two more ticks exact, so this ends
            cu = np.minimum((acc_u + np.cumsum(guess)) >> shift, left_u)
            uu = u - np.concatenate(([0], cu[:-1]))
            cv = np.minimum((acc_v + np.cumsum(uu)) >> shift, left_v)
            vv = v + np.concatenate(([0], cv[:-1]))
            if np.array_equal(vv, guess):
                break
            guess = vv
        # Stop where both axes are done, or where u is done at 0 (then v's integrand is 0).
        stop = np.flatnonzero((cu == left_u) & ((cv == left_v) | (u == left_u)))
        if len(stop):
            end = int(stop[0]) + 1
            cu, cv, uu, vv = cu[:end], cv[:end], uu[:end], vv[:end]
        du_parts.append(np.diff(cu, prepend=0).astype(bool))
        dv_parts.append(np.diff(cv, prepend=0).astype(bool))
        ticks += len(cu)
        _check_ticks(ticks, "this DDA arc")
        acc_u = int((acc_u + int(vv.sum())) & (q - 1))
        acc_v = int((acc_v + int(uu.sum())) & (q - 1))
        done_u += int(cu[-1])
        done_v += int(cv[-1])
        u, v = u0 - done_u, v0 + done_v
    return np.concatenate(du_parts), np.concatenate(dv_parts)


def dda_arc(start, end, center=(0, 0), ccw: bool = True, bits: int | None = None,
            preset: str = "half", turns: int = 0) -> StepStream:
    """DDA circle from ``start`` to ``end`` about ``center`` (integer steps), any quadrants.

    Each quadrant is a block ending on the axis point at round(R). ``bits`` defaults to one more
    than the largest integrand needs (that spare bit keeps a half-preset DDA within a step of the
    circle); an explicit ``bits`` only has to hold the largest integrand.
    """
    p0, p1, s, e, k, r_s, r_e = _arc_frame(start, end, center)
    ccw = bool(ccw)
    turns = _check_turns(turns)
    _check_ticks(8 * turns, "this arc")
    plan = _arc_plan(s, e, ccw, turns)
    r_axis = math.isqrt(k)
    if k - r_axis * r_axis > r_axis:  # round(sqrt(k)) in integers
        r_axis += 1
    blocks = []
    u0, v0 = _to_canonical(s, plan[0], ccw)
    for i, q in enumerate(plan):
        ue, ve = _to_canonical(e, q, ccw) if i == len(plan) - 1 else (0, r_axis)
        ue_c, ve_c = min(ue, u0), max(ve, v0)
        blocks.append((q, u0, v0, ue_c, ve_c, ue - ue_c, ve_c - ve))
        u0, v0 = r_axis, 0
    needed = max(max(b[1], b[4]) for b in blocks)
    bits = needed.bit_length() + 1 if bits is None else _check_bits(bits, needed, "this arc")
    _check_ticks(1 << bits, f"a {bits}-bit DDA arc")
    p = _preset_value(preset, bits)
    parts = []
    total = 0
    for q, u0, v0, ue_c, ve_c, rev_u, rev_v in blocks:
        ua = _u_axis(q, ccw)
        du, dv = _dda_block(u0, v0, u0 - ue_c, ve_c - v0, bits, p)
        total += len(du) + rev_u + rev_v
        _check_ticks(total, "this DDA arc")
        sx, sy = _QSIGN[q]
        u_dir = -(sx, sy)[ua]
        v_dir = (sx, sy)[1 - ua]
        n = len(du)
        block = np.zeros((n + rev_u + rev_v, 2), dtype=np.int8)
        block[:n, ua] = du * np.int8(u_dir)
        block[:n, 1 - ua] = dv * np.int8(v_dir)
        block[n:n + rev_u, ua] = -u_dir
        block[n + rev_u:, 1 - ua] = -v_dir
        parts.append(block)
    steps = np.concatenate(parts) if len(parts) > 1 else parts[0]
    return _stream(steps, p0, p1)
