"""Vector drawings (SVG, DXF) into Paths: strokes drawn with the tool down, rapids with it up between them.

SVG is read with svgelements (paths, lines, polylines, rects, circles, ellipses, arcs, quadratic and cubic
Béziers, nested transforms, units: user units are CSS pixels, 96 per inch); DXF with ezdxf (LINE, ARC,
CIRCLE, LWPOLYLINE with bulges, POLYLINE, SPLINE, ELLIPSE; $INSUNITS). SVG's Y axis points down, so Y is
mirrored to the machine's Y up.

Lines stay lines and circular arcs stay exact arcs. Curves (Béziers, splines, ellipses, elliptical and
skewed arcs) become either circular arcs within ``tolerance`` mm of the curve (``curves="arcs"``: each
arc passes through the curve at its ends and middle and is split until every check point is within the
tolerance), or stay exact (``curves="exact"``: Béziers and splines as NURBS segments, ellipses and
elliptical arcs as ellipse segments).

Layers (DXF layer names, SVG ``<g>`` ids or ``inkscape:label``s) and colours (SVG stroke, DXF ACI or true
colour) pick the tool/pen and feed through ``Style`` rules; strokes are grouped by tool in the order the
tools first appear, and each change of tool is a ``tool_change`` path event (a job stops for it; a plotter
can treat it as a pen swap).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path as FsPath
from typing import Any, Callable, Literal

import numpy as np

from flowmc.errors import PathError
from flowmc.motion.path import Arc, Dwell, EllipseArc, Line, NurbsCurve, Path, PathEvent

__all__ = ["Style", "Stroke", "curve_to_arcs", "svg_strokes", "dxf_strokes", "strokes_to_path", "read_vector"]

Curves = Literal["arcs", "exact"]
_DXF_UNITS_MM = {0: 1.0, 1: 25.4, 2: 304.8, 4: 1.0, 5: 10.0, 6: 1000.0, 8: 25.4e-6, 9: 25.4e-3, 10: 914.4,
                 13: 1e-3, 14: 1e-4, 15: 1e-2}
_MAX_DEPTH = 24
_GAP_MM = 1e-6  # closing lines shorter than this are rounding, not drawing


@dataclass(frozen=True)
class Style:
    """A rule: strokes on ``layer`` (name, or '*' for any) and/or of ``colour`` ('#rrggbb', or a DXF colour
    number as text) are drawn with ``tool`` at ``feed``, or left out (``skip``)."""

    layer: str = "*"
    colour: str = "*"
    tool: int = 1
    feed: float = 20.0
    skip: bool = False

    def matches(self, layer: str, colour: str) -> bool:
        return self.layer in ("*", layer) and self.colour.lower() in ("*", colour.lower())


@dataclass
class Stroke:
    """One continuous drawn line: ``pieces`` are ('line', end) / ('arc', end, centre, ccw) /
    ('nurbs', control points, weights, knots, degree), in mm, starting at ``start``."""

    start: np.ndarray
    pieces: list
    layer: str
    colour: str
    source: str


# Curves ---------------------------------------------------------------------------------------------
def _cross2(a, b) -> float:
    return float(a[0] * b[1] - a[1] * b[0])


def _circle_through(a: np.ndarray, m: np.ndarray, b: np.ndarray):
    """Centre of the circle through three XY points and whether a->m->b turns counter-clockwise (None: in line)."""
    ax, ay = a
    bx, by = m
    cx, cy = b
    d = 2.0 * (ax * (by - cy) + bx * (cy - ay) + cx * (ay - by))
    chord = math.hypot(cx - ax, cy - ay) + math.hypot(bx - ax, by - ay)
    if abs(d) <= 1e-12 * max(chord * chord, 1e-300):
        return None, None
    ux = ((ax * ax + ay * ay) * (by - cy) + (bx * bx + by * by) * (cy - ay) + (cx * cx + cy * cy) * (ay - by)) / d
    uy = ((ax * ax + ay * ay) * (cx - bx) + (bx * bx + by * by) * (ax - cx) + (cx * cx + cy * cy) * (bx - ax)) / d
    return np.array([ux, uy]), d > 0


def curve_to_arcs(point: Callable[[float], np.ndarray], t0: float, t1: float, tolerance: float) -> list:
    """Circular arcs (and lines) within ``tolerance`` of the XY curve ``point(t)``, t0 <= t <= t1: pieces
    ('line', end) or ('arc', end, centre, ccw), each through the curve at both ends and its middle."""
    if tolerance <= 0:
        raise PathError(f"the curve tolerance must be > 0 mm, got {tolerance!r}")
    out: list = []

    def fit(s: float, e: float, ps: np.ndarray, pe: np.ndarray, depth: int) -> None:
        tm = 0.5 * (s + e)
        pm = point(tm)
        checks = [(s + (e - s) * f, point(s + (e - s) * f)) for f in (0.125, 0.25, 0.375, 0.625, 0.75, 0.875)]
        centre, ccw = _circle_through(ps, pm, pe)
        if centre is None:
            chord = pe - ps
            length = float(np.hypot(*chord))
            worst = 0.0 if length == 0 else max(abs(_cross2(chord, p - ps)) / length for _, p in checks)
            worst = max(worst, 0.0 if length == 0 else abs(_cross2(chord, pm - ps)) / length)
            piece: tuple = ("line", pe)
        else:
            r = float(np.hypot(*(ps - centre)))
            worst = max(abs(float(np.hypot(*(p - centre))) - r) for _, p in checks)
            piece = ("arc", pe, centre, bool(ccw))
        if worst <= tolerance or depth >= _MAX_DEPTH:
            if piece[0] == "line" or np.hypot(*(pe - ps)) > 0:
                out.append(piece)
            return
        fit(s, tm, ps, pm, depth + 1)
        fit(tm, e, pm, pe, depth + 1)

    fit(t0, t1, point(t0), point(t1), 0)
    return out


def _bezier(points: np.ndarray) -> Callable[[float], np.ndarray]:
    n = len(points) - 1
    coeff = [math.comb(n, k) for k in range(n + 1)]

    def at(t: float) -> np.ndarray:
        u = 1.0 - t
        return sum(coeff[k] * u ** (n - k) * t ** k * points[k] for k in range(n + 1))

    return at


def _curve_pieces(points: np.ndarray, weights, knots, degree: int, point: Callable[[float], np.ndarray],
                  t0: float, t1: float, curves: Curves, tolerance: float) -> list:
    if curves == "exact":
        return [("nurbs", np.asarray(points, float), None if weights is None else np.asarray(weights, float),
                 np.asarray(knots, float), degree)]
    return curve_to_arcs(point, t0, t1, tolerance)


def _bezier_pieces(points: np.ndarray, curves: Curves, tolerance: float) -> list:
    degree = len(points) - 1
    knots = [0.0] * (degree + 1) + [1.0] * (degree + 1)
    return _curve_pieces(points, None, knots, degree, _bezier(points), 0.0, 1.0, curves, tolerance)


# SVG ------------------------------------------------------------------------------------------------
def _svg_colour(element) -> str:
    stroke = getattr(element, "stroke", None)
    if stroke is None or getattr(stroke, "value", None) is None:
        fill = getattr(element, "fill", None)
        stroke = fill if fill is not None and getattr(fill, "value", None) is not None else None
    if stroke is None:
        return "none"
    return str(stroke.hexrgb).lower()


_LABEL = "{http://www.inkscape.org/namespaces/inkscape}label"


def _svg_shapes(node, layer: str):
    """(shape, layer) for every shape under node; a group's Inkscape label, else its id, names the layer."""
    import svgelements as se

    for child in node:
        if isinstance(child, se.Group):
            values = getattr(child, "values", {}) or {}
            label = values.get(_LABEL)
            inherited = (getattr(node, "values", {}) or {}).get(_LABEL)
            yield from _svg_shapes(child, (label if label != inherited else None) or child.id or layer)
        elif isinstance(child, se.Shape) and not isinstance(child, se.Text):
            yield child, layer


def svg_strokes(source: str | FsPath, *, curves: Curves = "arcs", tolerance: float = 0.01,
                name: str | None = None) -> list[Stroke]:
    """Strokes of an SVG file (path) or text, in mm with Y up."""
    import io

    import svgelements as se

    label = name or (str(source) if isinstance(source, FsPath) else "svg")
    try:
        if isinstance(source, FsPath):
            svg = se.SVG.parse(str(source), reify=True, ppi=96.0)
        else:
            svg = se.SVG.parse(io.BytesIO(source.encode()), reify=True, ppi=96.0)
    except Exception as exc:  # svgelements raises many kinds on bad input
        raise PathError(f"cannot read the SVG: {exc}", where=label) from None
    strokes: list[Stroke] = []

    # svgelements' own mm (3.7795 px) turns physical sizes back exactly; a unitless file is 96 px per inch
    # to 5e-7 of its size.
    px_mm = 1.0 / float(se.Length("1mm").value(ppi=96.0))

    def mm(p) -> np.ndarray:
        return np.array([float(p.x) * px_mm, -float(p.y) * px_mm])

    for count, (element, layer) in enumerate(_svg_shapes(svg, ""), 1):
        if (getattr(element, "values", {}) or {}).get("visibility") == "hidden":
            continue
        where = f"{label} {type(element).__name__.lower()} {element.id or count}"
        colour = _svg_colour(element)
        path = se.Path(element)
        current: Stroke | None = None
        for seg in path.segments(transformed=True):
            if isinstance(seg, se.Move):
                current = None
                continue
            start, end = mm(seg.start), mm(seg.end)
            if current is None:
                current = Stroke(start, [], layer, colour, where)
                strokes.append(current)
            if isinstance(seg, (se.Line, se.Close)):
                if np.hypot(*(end - start)) > _GAP_MM:
                    current.pieces.append(("line", end))
            elif isinstance(seg, se.QuadraticBezier):
                pts = np.array([start, mm(seg.control), end])
                current.pieces.extend(_bezier_pieces(pts, curves, tolerance))
            elif isinstance(seg, se.CubicBezier):
                pts = np.array([start, mm(seg.control1), mm(seg.control2), end])
                current.pieces.extend(_bezier_pieces(pts, curves, tolerance))
            elif isinstance(seg, se.Arc):
                current.pieces.extend(_svg_arc(seg, start, end, mm, curves, tolerance))
            if isinstance(seg, se.Close):
                current = None
    return [s for s in strokes if s.pieces]


def _svg_arc(seg, start: np.ndarray, end: np.ndarray, mm, curves: Curves, tolerance: float) -> list:
    if float(seg.rx) == 0 or float(seg.ry) == 0 or seg.sweep is None:
        return [("line", end)]
    centre = mm(seg.center)
    u, v = mm(seg.prx) - centre, mm(seg.pry) - centre  # conjugate semi-diameters after the transforms
    t0 = float(seg.get_start_t())
    return _ellipse_pieces(centre, u, v, t0, t0 + float(seg.sweep), curves, tolerance)


def _ellipse_pieces(centre: np.ndarray, u: np.ndarray, v: np.ndarray, t0: float, t1: float, curves: Curves,
                    tolerance: float) -> list:
    """centre + u cos t + v sin t, t0 -> t1: exact arcs for a circle, else an exact ellipse or arcs."""
    def point(t: float) -> np.ndarray:
        return centre + u * math.cos(t) + v * math.sin(t)

    ru, rv = float(np.hypot(*u)), float(np.hypot(*v))
    if abs(ru - rv) <= 1e-9 * max(ru, rv) and abs(float(np.dot(u, v))) <= 1e-9 * ru * rv:
        ccw = (_cross2(u, v) > 0) == (t1 > t0)
        n = max(1, math.ceil(abs(t1 - t0) / math.pi - 1e-9))  # no piece a full turn
        return [("arc", point(t0 + (t1 - t0) * k / n), centre, ccw) for k in range(1, n + 1)]
    if curves == "exact":
        return [("ellipse", centre, u, v, t0, t1)]
    return curve_to_arcs(point, t0, t1, tolerance)


# DXF ------------------------------------------------------------------------------------------------
def _dxf_colour(entity, doc) -> str:
    rgb = entity.rgb if entity.dxf.hasattr("true_color") else None
    if rgb is not None:
        return "#%02x%02x%02x" % tuple(rgb)
    index = entity.dxf.color
    if index == 256:  # BYLAYER
        layer = doc.layers.get(entity.dxf.layer) if entity.dxf.layer in doc.layers else None
        index = abs(layer.color) if layer is not None else 7
    return str(index)


def dxf_strokes(source: FsPath, *, curves: Curves = "arcs", tolerance: float = 0.01,
                name: str | None = None) -> list[Stroke]:
    """Strokes of a DXF file's model space, in mm."""
    import ezdxf
    from ezdxf.math import OCS, Vec3

    label = name or str(source)
    try:
        doc = ezdxf.readfile(str(source))
    except (OSError, ezdxf.DXFError) as exc:
        raise PathError(f"cannot read the DXF: {exc}", where=label) from None
    scale = _DXF_UNITS_MM.get(int(doc.header.get("$INSUNITS", 4)), 1.0)
    strokes: list[Stroke] = []

    def xy(v) -> np.ndarray:
        return np.array([float(v[0]) * scale, float(v[1]) * scale])

    entity: Any
    for count, entity in enumerate(doc.modelspace(), 1):
        e = entity
        kind = e.dxftype()
        where = f"{label} {kind} #{count} ({e.dxf.handle})"
        layer = e.dxf.layer if e.dxf.hasattr("layer") else "0"
        colour = _dxf_colour(e, doc)

        def stroke(start, layer=layer, colour=colour, where=where) -> Stroke:
            s = Stroke(xy(start), [], layer, colour, where)
            strokes.append(s)
            return s

        if kind == "LINE":
            stroke(e.dxf.start).pieces.append(("line", xy(e.dxf.end)))
        elif kind in ("ARC", "CIRCLE"):
            ocs = OCS(e.dxf.extrusion)
            centre = ocs.to_wcs(e.dxf.center)
            r = float(e.dxf.radius)
            a0, a1 = (math.radians(e.dxf.start_angle), math.radians(e.dxf.end_angle)) if kind == "ARC" \
                else (0.0, 2 * math.pi)
            if kind == "ARC" and a1 <= a0:
                a1 += 2 * math.pi
            ccw = bool(Vec3(e.dxf.extrusion).z >= 0)  # a mirrored OCS (extrusion -Z) turns the arc round
            p = [ocs.to_wcs(Vec3(e.dxf.center) + Vec3(r * math.cos(a), r * math.sin(a), 0)) for a in
                 (a0, 0.5 * (a0 + a1), a1)]
            s = stroke(p[0])
            if kind == "CIRCLE":
                s.pieces.append(("arc", xy(p[1]), xy(centre), ccw))
            s.pieces.append(("arc", xy(p[2]), xy(centre), ccw))
        elif kind in ("LWPOLYLINE", "POLYLINE"):
            _dxf_polyline(e, kind, xy, stroke)
        elif kind == "SPLINE":
            spline = e.construction_tool()
            ctrl = np.array([xy(p) for p in spline.control_points])
            weights = list(spline.weights()) or None
            knots = np.asarray(spline.knots(), float)
            degree = spline.degree
            lo, hi = float(knots[degree]), float(knots[-degree - 1])

            def point(t: float, spline=spline) -> np.ndarray:
                return xy(spline.point(t))

            s = stroke(spline.point(lo))
            s.pieces.extend(_curve_pieces(ctrl, weights, knots, degree, point, lo, hi, curves, tolerance))
        elif kind == "ELLIPSE":
            ellipse = e.construction_tool()
            t0, t1 = float(ellipse.start_param), float(ellipse.end_param)
            if t1 <= t0:
                t1 += 2 * math.pi
            centre, u, v = xy(ellipse.center), xy(ellipse.major_axis), xy(ellipse.minor_axis)
            s = stroke(ellipse.center + ellipse.major_axis * math.cos(t0) + ellipse.minor_axis * math.sin(t0))
            s.pieces.extend(_ellipse_pieces(centre, u, v, t0, t1, curves, tolerance))
    return [s for s in strokes if s.pieces]


def _dxf_polyline(e, kind: str, xy, stroke) -> None:
    if kind == "LWPOLYLINE":
        points = [(x, y, b) for x, y, b in e.get_points("xyb")]
        closed = e.closed
    else:
        points = [(v.dxf.location[0], v.dxf.location[1], v.dxf.bulge) for v in e.vertices]
        closed = e.is_closed
    if len(points) < 2:
        return
    if closed:
        points = points + [points[0]]
    s = stroke(points[0][:2])
    for (x0, y0, bulge), (x1, y1, _b) in zip(points[:-1], points[1:]):
        a, b = xy((x0, y0)), xy((x1, y1))
        if np.hypot(*(b - a)) == 0:
            continue
        if abs(bulge) < 1e-12:
            s.pieces.append(("line", b))
            continue
        # bulge = tan(sweep / 4), positive counter-clockwise
        sweep = 4.0 * math.atan(bulge)
        chord = b - a
        half = float(np.hypot(*chord)) / 2.0
        r = half / abs(math.sin(sweep / 2.0))
        mid = (a + b) / 2.0
        normal = np.array([-chord[1], chord[0]]) / (2.0 * half)
        offset = math.sqrt(max(r * r - half * half, 0.0))
        # the centre lies left of the chord for a counter-clockwise arc shorter than half a turn
        side = 1.0 if (bulge > 0) == (abs(sweep) < math.pi) else -1.0
        centre = mid + side * offset * normal
        if abs(abs(sweep) - 2 * math.pi) < 1e-9:
            continue
        s.pieces.append(("arc", b, centre, bool(bulge > 0)))


# To a Path --------------------------------------------------------------------------------------------
def strokes_to_path(strokes: list[Stroke], styles: list[Style] | tuple = (), *, default: Style = Style(),
                    origin=(0.0, 0.0), scale: float = 1.0, rapid_feed: float = 50.0, z: float = 0.0,
                    ) -> Path:
    """Strokes grouped by tool (first-seen order), each stroke after a pen-up rapid; a tool change event
    before each tool after the first."""
    chosen: dict[int, list[tuple[Stroke, Style]]] = {}
    for s in strokes:
        style = next((rule for rule in styles if rule.matches(s.layer, s.colour)), default)
        if style.skip:
            continue
        chosen.setdefault(style.tool, []).append((s, style))
    o = np.asarray(origin, float)

    def p3(p) -> np.ndarray:
        q = np.asarray(p, float) * scale + o
        return np.array([q[0], q[1], z])

    segments: list = []
    here = None
    for k, (tool, items) in enumerate(chosen.items()):
        if k > 0 and here is not None:
            layers = ", ".join(dict.fromkeys(s.layer or s.colour for s, _ in items))
            segments.append(Dwell(here, 0.0, PathEvent("tool_change", f"pen/tool {tool} for {layers}", tool),
                                  feed=rapid_feed, rapid=True, tool_down=False, source=items[0][0].source))
        for s, style in items:
            start = p3(s.start)
            if here is None or np.hypot(*(start - here)[:2]) > 0:
                segments.append(Line(start if here is None else here, start, feed=rapid_feed, rapid=True,
                                     tool_down=False, source=s.source))
            cur = start
            for piece in s.pieces:
                kind = piece[0]
                if kind == "line":
                    end = p3(piece[1])
                    segments.append(Line(cur, end, feed=style.feed, source=s.source))
                elif kind == "arc":
                    end = p3(piece[1])
                    segments.append(Arc(cur, end, p3(piece[2]), ccw=piece[3], feed=style.feed, source=s.source))
                elif kind == "ellipse":
                    _, c, u, v, t0, t1 = piece
                    ellipse = EllipseArc(p3(c), np.append(np.asarray(u) * scale, 0.0),
                                         np.append(np.asarray(v) * scale, 0.0), t0, t1, feed=style.feed,
                                         source=s.source)
                    end = ellipse.end
                    segments.append(ellipse)
                else:
                    _, ctrl, weights, knots, degree = piece
                    pts = np.column_stack([np.asarray(ctrl) * scale + o, np.full(len(ctrl), z)])
                    curve = NurbsCurve(pts, weights, knots, degree, feed=style.feed, source=s.source)
                    end = curve.end
                    segments.append(curve)
                cur = end
            here = cur
    if not segments:
        raise PathError("the drawing has nothing to draw (no strokes, or every layer skipped)")
    return Path(segments)


def read_vector(file: FsPath, *, curves: Curves = "arcs", tolerance: float = 0.01, name: str | None = None
                ) -> list[Stroke]:
    """Strokes of an .svg or .dxf file."""
    suffix = file.suffix.lower()
    if suffix == ".svg":
        return svg_strokes(file, curves=curves, tolerance=tolerance, name=name)
    if suffix == ".dxf":
        return dxf_strokes(file, curves=curves, tolerance=tolerance, name=name)
    raise PathError(f"not a vector drawing (.svg or .dxf): {file.name}", where=name or str(file))
