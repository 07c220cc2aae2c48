"""A whole Path through a step interpolator: each segment in step units from where the last ended.

Positions are snapped to the step grid (multiples of each axis's ``step_mm``); a segment runs from
the grid point where the previous one stopped to the grid point nearest its own end, so rounding
never accumulates. What each kind becomes (the XY projection; Z is not stepped here):

* Line: a line.
* Arc in the XY plane: a circle about its centre snapped to the grid, through the current point.
  With different X and Y step sizes that circle is an ellipse in step units, which point-by-point
  comparison runs as A x^2 + B y^2 = K; DDA cuts such arcs into chords instead.
* EllipseArc whose axes lie along X and Y: the same conic (point-by-point); chords for DDA.
* Anything else (NURBS, rotated ellipses, arcs in XZ/YZ): chords within ``chord_tol``, each a line.
* Dwell: no steps.

The path's I/O (outputs, analog, spindle, and the tool/pen state) goes on ``Steps.signals`` by the one
rule in ``flowmc.motion.signals``: each change just before its segment's first step, at ``row * tick``
seconds, or at ``row`` (a tick index) when the stream is untimed.

A curve ends at the grid point nearest its end's projection onto the step-unit curve; where that
is not the grid point nearest the programmed end (the centre was snapped), a short line closes it.
"""

from __future__ import annotations

import math

import numpy as np

import flowmc.budget as budget
from flowmc.errors import PathError
from flowmc.motion import stepinterp
from flowmc.motion.path import Arc, Dwell, EllipseArc, Line, Path, describe_segment
from flowmc.motion.signals import path_signals, program_events, step_start_times
from flowmc.motion.trajectory import Steps

__all__ = ["path_to_steps", "METHODS"]

#: Interpolation methods: point-by-point comparison and DDA.
METHODS = ("pbp", "dda")


def _grid(point, step: np.ndarray) -> tuple[int, int]:
    g = np.rint(np.asarray(point, dtype=float)[:2] / step)
    return int(g[0]), int(g[1])


def _sweep_on_grid(s, e, ccw: bool) -> float:
    """Angle from s to e about the origin in the turn direction, in (0, 2 pi] (2 pi on the same ray)."""
    delta = math.atan2(e[1], e[0]) - math.atan2(s[1], s[0])
    if not ccw:
        delta = -delta
    delta %= 2.0 * math.pi
    same_ray = s[0] * e[1] - s[1] * e[0] == 0 and s[0] * e[0] + s[1] * e[1] > 0
    return 2.0 * math.pi if same_ray or delta == 0.0 else delta


class _Interp:
    """The chosen method's line and arc functions, with its DDA settings."""

    def __init__(self, method: str, bits: int | None, preset: str):
        if method not in METHODS:
            raise PathError(f"interpolation method must be one of {METHODS}, got {method!r}")
        self.method, self.bits, self.preset = method, bits, preset

    def line(self, a, b) -> list[stepinterp.StepStream]:
        if a == b:
            return []
        if self.method == "pbp":
            return [stepinterp.pbp_line(b, a)]
        return [stepinterp.dda_line(b, a, self.bits, self.preset)]

    def polyline(self, grid_points) -> list[stepinterp.StepStream]:
        out = []
        for a, b in zip(grid_points[:-1], grid_points[1:]):
            out.extend(self.line(a, b))
        return out


def _rows_at_least(a, b) -> int:
    """Rows a move between grid points needs whatever the method: one per step of the longer axis."""
    return max(abs(b[0] - a[0]), abs(b[1] - a[1]))


def _check_rows(count: float, seg) -> None:
    """Refuse a segment whose streams would be over the steps budget, before they are made."""
    budget.check("steps", count, axes=2, what="stepping this segment",
                 change="use a coarser step or chord tolerance, or a shorter path", where=seg.source)


def _chords(seg, cur, end, step, tol, interp: _Interp):
    coarse = np.asarray(seg.point_at(np.linspace(0.0, seg.length, 257)), dtype=float)[:, :2]
    xy = float(np.linalg.norm(np.diff(coarse, axis=0), axis=1).sum())  # a chord polyline: at most the curve's length
    _check_rows(xy / (math.sqrt(2.0) * float(step.max())), seg)  # before sampling it finely
    grid = np.rint(np.asarray(seg.sample(tol), dtype=float)[1:-1, :2] / step)
    _check_rows(float(np.abs(np.diff(np.vstack([cur, grid, end]), axis=0)).max(axis=1, initial=0).sum()), seg)
    pts = [(int(x), int(y)) for x, y in grid]
    return interp.polyline([cur, *pts, end])


def _axis_aligned_semi_axes(seg: EllipseArc):
    """(a along X, b along Y, ccw) for an XY ellipse whose axes lie along X and Y, else None."""
    u, v = seg.u_axis, seg.v_axis
    scale = max(np.linalg.norm(u), np.linalg.norm(v))
    tiny = 1e-12 * scale
    if abs(u[2]) > tiny or abs(v[2]) > tiny or abs(seg.center[2] - seg.start[2]) > tiny:
        return None
    if abs(u[1]) <= tiny and abs(v[0]) <= tiny:
        ax, ay = abs(u[0]), abs(v[1])
    elif abs(u[0]) <= tiny and abs(v[1]) <= tiny:
        ax, ay = abs(v[0]), abs(u[1])
    else:
        return None
    turn = u[0] * v[1] - u[1] * v[0]
    return ax, ay, (turn > 0) == (seg.t1 > seg.t0)


def _conic_arc(seg, cur, end, center_mm, semi_axes_mm, ccw, sweep, step, interp: _Interp):
    """An arc of the conic through ``cur`` whose semi-axes in mm along X, Y are ``semi_axes_mm``."""
    c = _grid(center_mm, step)
    s = (cur[0] - c[0], cur[1] - c[1])
    ax, ay = semi_axes_mm[0] / step[0], semi_axes_mm[1] / step[1]
    circle = math.isclose(ax, ay, rel_tol=1e-12)
    if min(ax, ay) < 2.0 or s == (0, 0) or (interp.method == "dda" and not circle):
        return None  # too small to compare against, or a DDA ellipse: chords
    cmax = int(max(ax, ay, abs(s[0]), abs(s[1]))) + 4
    if circle:
        weights = (1, 1)
    else:
        wx, wy = 1.0 / (ax * ax), 1.0 / (ay * ay)
        m = 2.0**58 / (max(wx, wy) * 8 * (cmax + 2))
        weights = (max(1, round(wx * m)), max(1, round(wy * m)))
    k = weights[0] * s[0] ** 2 + weights[1] * s[1] ** 2
    e = (end[0] - c[0], end[1] - c[1])
    level = weights[0] * e[0] ** 2 + weights[1] * e[1] ** 2
    if level == 0:
        return None
    lam = math.sqrt(k / level)
    e_on = (round(lam * e[0]), round(lam * e[1]))
    turns = round((abs(sweep) - _sweep_on_grid(s, e_on, ccw)) / (2.0 * math.pi))
    if turns < 0:  # shorter than a step: nothing to go round
        return interp.line(cur, end)
    arc_end = (e_on[0] + c[0], e_on[1] + c[1])
    if interp.method == "dda":
        out = [stepinterp.dda_arc(cur, arc_end, c, ccw, interp.bits, interp.preset, turns)]
    elif circle:
        out = [stepinterp.pbp_arc(cur, arc_end, c, ccw, turns)]
    else:
        out = [stepinterp.pbp_conic(cur, arc_end, c, weights, ccw, turns)]
    return out + interp.line(arc_end, end)


def _segment_streams(seg, cur, step, tol, interp: _Interp):
    start, end = _grid(seg.start, step), _grid(seg.end, step)
    least = float(_rows_at_least(cur, start) + (_rows_at_least(start, end) if isinstance(seg, Line) else 0))
    if isinstance(seg, Arc) and seg.normal_axis == 2:  # its XY length, in steps of the larger axis step
        least += 0.5 * (seg.radius + seg.end_radius) * abs(seg.sweep) / (math.sqrt(2.0) * float(step.max()))
    _check_rows(least, seg)
    out = interp.line(cur, start)  # a gap before this segment (the path does not join up)
    if isinstance(seg, Dwell):
        return out
    if isinstance(seg, Line):
        return out + interp.line(start, end)
    arc = None
    if isinstance(seg, Arc) and seg.normal_axis == 2:
        arc = _conic_arc(seg, start, end, seg.center, (seg.radius, seg.radius), seg.ccw, seg.sweep, step, interp)
    elif isinstance(seg, EllipseArc):
        aligned = _axis_aligned_semi_axes(seg)
        if aligned is not None:
            ax, ay, ccw = aligned
            arc = _conic_arc(seg, start, end, seg.center, (ax, ay), ccw, seg.t1 - seg.t0, step, interp)
    if arc is None:
        arc = _chords(seg, start, end, step, tol, interp)
    return out + arc


def path_to_steps(path: Path, step_mm, method: str = "pbp", *, bits: int | None = None, preset: str = "half",
                  chord_tol: float | None = None, tick: float = 0.0) -> Steps:
    """X/Y step streams for a path, one block per segment, concatenated; ``Steps.segment`` says whose
    and ``Steps.segment_names`` where each segment came from.

    ``method`` is "pbp" (point-by-point comparison) or "dda"; ``bits`` and ``preset`` set the DDA
    register (None: sized per move). ``chord_tol`` (mm, default half the smaller step) is the
    chord tolerance for curves cut into chords; ``tick`` is the time per row (0: untimed). The
    path's I/O changes are the stream's ``signals`` (times in ticks when untimed).
    """
    step = np.broadcast_to(np.asarray(step_mm, dtype=float), (2,)).copy()
    if not np.all(np.isfinite(step) & (step > 0)):
        raise PathError(f"step_mm must be > 0 mm for X and Y, got {step_mm!r}")
    tol = 0.5 * float(step.min()) if chord_tol is None else float(chord_tol)
    if not tol > 0:
        raise PathError(f"chord tolerance must be > 0 mm, got {chord_tol!r}")
    interp = _Interp(method, bits, preset)
    if not len(path):
        raise PathError("the path is empty")
    origin = _grid(path.start, step)
    cur = origin
    blocks: list[np.ndarray] = []
    labels: list[np.ndarray] = []
    for i, seg in enumerate(path):
        try:
            streams = _segment_streams(seg, cur, step, tol, interp)
        except PathError as exc:
            raise PathError(exc.message, where=describe_segment(i, seg.source)) from None
        budget.check("steps", sum(len(b) for b in blocks) + sum(len(st.steps) for st in streams), axes=2,
                     what=f"stepping up to {describe_segment(i, seg.source)}",
                     change="use a coarser step, or split the program")
        for st in streams:
            blocks.append(st.steps)
            labels.append(np.full(len(st.steps), i, dtype=np.int64))
            cur = (int(st.end[0]), int(st.end[1]))
    steps = np.concatenate(blocks) if blocks else np.zeros((0, 2), dtype=np.int8)
    segment = np.concatenate(labels) if labels else np.zeros(0, dtype=np.int64)
    signals = path_signals(path, step_start_times(segment, tick, len(path)))
    return Steps(steps, step, np.array(origin, dtype=float) * step, tick=tick, segment=segment, axes=("X", "Y"),
                 signals=signals, segment_names=path.segment_names(),
                 segment_rapid=path.segment_rapid(), events=program_events(path))
