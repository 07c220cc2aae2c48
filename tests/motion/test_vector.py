"""SVG and DXF drawings into paths: geometry, units, curves within the tolerance, layers to tools."""

import math

import ezdxf
import numpy as np
import pytest

from flowmc.errors import PathError
from flowmc.motion.path import Arc, EllipseArc, Line, NurbsCurve
from flowmc.motion.vector import Style, curve_to_arcs, dxf_strokes, read_vector, strokes_to_path, svg_strokes

SVG = """<svg xmlns="http://www.w3.org/2000/svg" xmlns:inkscape="http://www.inkscape.org/namespaces/inkscape"
     width="100mm" height="60mm" viewBox="0 0 100 60">
  <g inkscape:label="Outline"><rect x="5" y="5" width="90" height="50" fill="none" stroke="#000000"/>
    <circle cx="50" cy="30" r="15" fill="none" stroke="#000000"/></g>
  <g id="detail" transform="translate(10,0)">
    <path d="M 10 20 C 20 5, 40 5, 50 20 Q 60 35 70 20 A 8 8 0 0 1 80 30" fill="none" stroke="#ff0000"/>
    <ellipse cx="30" cy="40" rx="10" ry="5" stroke="#ff0000" fill="none"/>
  </g>
  <line x1="0" y1="50" x2="20" y2="55" stroke="#0000ff"/>
</svg>"""


def bezier(points, t):
    n = len(points) - 1
    return sum(math.comb(n, k) * (1 - t) ** (n - k) * t ** k * np.asarray(points[k], float) for k in range(n + 1))


def distance_to_arcs(pieces, start, p):
    """Distance from p to the nearest piece (lines and arcs) starting at start."""
    best, cur = np.inf, np.asarray(start, float)
    for piece in pieces:
        end = piece[1]
        if piece[0] == "line":
            d = end - cur
            t = np.clip(np.dot(p - cur, d) / np.dot(d, d), 0, 1)
            best = min(best, float(np.hypot(*(cur + t * d - p))))
        else:
            c = piece[2]
            r = np.hypot(*(cur - c))
            a0, a1, ap = (math.atan2(*(q - c)[::-1]) for q in (cur, end, p))
            sweep = (a1 - a0) % (2 * math.pi) if piece[3] else -((a0 - a1) % (2 * math.pi))
            rel = (ap - a0) % (2 * math.pi) if piece[3] else -((a0 - ap) % (2 * math.pi))
            if abs(rel) <= abs(sweep):
                best = min(best, abs(float(np.hypot(*(p - c))) - r))
            best = min(best, float(np.hypot(*(p - end))))
        cur = end
    return best


@pytest.mark.parametrize("tol", [0.1, 0.01, 0.001])
def test_a_cubic_bezier_becomes_arcs_within_the_tolerance(tol):
    pts = [(0, 0), (10, 15), (30, -15), (40, 0)]
    pieces = curve_to_arcs(lambda t: bezier(pts, t), 0.0, 1.0, tol)
    assert all(p[0] == "arc" for p in pieces)
    worst = max(distance_to_arcs(pieces, pts[0], bezier(pts, t)) for t in np.linspace(0, 1, 801))
    assert worst <= tol * 1.05
    np.testing.assert_allclose(pieces[-1][1], pts[-1], atol=1e-12)
    assert len(curve_to_arcs(lambda t: bezier(pts, t), 0.0, 1.0, tol / 10)) > len(pieces)


def test_svg_units_y_up_layers_colours_and_exact_circles():
    strokes = svg_strokes(SVG, name="t.svg")
    assert [(s.layer, s.colour) for s in strokes] == [("Outline", "#000000"), ("Outline", "#000000"),
                                                       ("detail", "#ff0000"), ("detail", "#ff0000"), ("", "#0000ff")]
    rect, circle = strokes[0], strokes[1]
    np.testing.assert_allclose(rect.start, [5, -5], atol=1e-9)  # mm, Y mirrored
    assert [p[0] for p in rect.pieces] == ["line"] * 4
    assert {p[0] for p in circle.pieces} == {"arc"}
    for piece in circle.pieces:
        np.testing.assert_allclose(piece[2], [50, -30], atol=1e-9)
    # the translate(10, 0) of the group
    np.testing.assert_allclose(strokes[2].start, [20, -20], atol=1e-9)
    assert strokes[0].source == "t.svg rect 1"


def test_svg_curves_stay_exact_as_nurbs_and_ellipses_when_asked():
    strokes = svg_strokes(SVG, curves="exact")
    kinds = [p[0] for p in strokes[2].pieces]
    assert kinds == ["nurbs", "nurbs", "arc"]  # cubic, quadratic, the circular arc
    path = strokes_to_path(strokes)
    curves = [s for s in path if isinstance(s, NurbsCurve)]
    mid = curves[0]._eval(np.array([0.5]), 0)[0]
    np.testing.assert_allclose(mid[:2], bezier([(20, -20), (30, -5), (50, -5), (60, -20)], 0.5), atol=1e-9)
    assert any(isinstance(s, EllipseArc) for s in path)


def test_layers_pick_tools_and_feeds_and_a_tool_change_is_a_path_event():
    strokes = svg_strokes(SVG)
    path = strokes_to_path(strokes, [Style(layer="detail", tool=2, feed=7.5), Style(colour="#0000FF", skip=True)],
                           default=Style(tool=1, feed=30.0))
    segs = list(path)
    for a, b in zip(segs, segs[1:]):
        np.testing.assert_allclose(a.end, b.start, atol=1e-9)  # continuous, rapids between strokes
    events = path.events()
    assert len(events) == 1 and events[0][1].kind == "tool_change" and events[0][1].tool == 2
    assert {s.feed for s in segs[:events[0][0]] if not s.rapid} == {30.0}
    assert {s.feed for s in segs[events[0][0] + 1:] if not s.rapid} == {7.5}
    assert all(not s.tool_down for s in segs if s.rapid)
    assert not any("simpleline" in s.source for s in segs) and any("simpleline" in s.source for s in strokes)


def make_dxf(path, units=4):
    doc = ezdxf.new()
    doc.header["$INSUNITS"] = units
    doc.layers.add("CUT", color=1)
    doc.layers.add("ENGRAVE", color=5)
    msp = doc.modelspace()
    msp.add_line((0, 0), (50, 0), dxfattribs={"layer": "CUT"})
    msp.add_arc((50, 20), 20, -90, 90, dxfattribs={"layer": "CUT"})
    msp.add_circle((25, 20), 5, dxfattribs={"layer": "ENGRAVE", "color": 3})
    msp.add_lwpolyline([(0, 40, 0), (20, 40, 1), (20, 60, 0), (0, 60, -0.5)], format="xyb", close=True,
                       dxfattribs={"layer": "CUT"})
    msp.add_spline([(0, 70), (10, 80), (20, 70), (30, 80)], dxfattribs={"layer": "ENGRAVE"})
    msp.add_ellipse((60, 70), major_axis=(10, 0), ratio=0.5, start_param=0, end_param=math.pi,
                    dxfattribs={"layer": "ENGRAVE"})
    doc.saveas(path)


def test_dxf_entities_layers_colours_bulges_and_units(tmp_path):
    make_dxf(tmp_path / "a.dxf")
    strokes = dxf_strokes(tmp_path / "a.dxf", name="a.dxf")
    assert [s.source.split()[1] for s in strokes] == ["LINE", "ARC", "CIRCLE", "LWPOLYLINE", "SPLINE", "ELLIPSE"]
    assert [s.layer for s in strokes] == ["CUT", "CUT", "ENGRAVE", "CUT", "ENGRAVE", "ENGRAVE"]
    assert strokes[0].colour == "1" and strokes[2].colour == "3"  # BYLAYER, then the entity's own colour
    arc = strokes[1].pieces[0]
    np.testing.assert_allclose(strokes[1].start, [50, 0], atol=1e-9)
    np.testing.assert_allclose(arc[1], [50, 40], atol=1e-9)
    assert arc[0] == "arc" and arc[3] is True
    poly = strokes[3].pieces
    assert [p[0] for p in poly] == ["line", "arc", "line", "arc"]
    np.testing.assert_allclose(poly[1][2], [20, 50], atol=1e-9)  # bulge 1: a half circle on the chord
    assert poly[1][3] is True and poly[3][3] is False
    r = 10 / math.sin(2 * math.atan(0.5))
    assert np.hypot(*(poly[3][2] - [0, 40])) == pytest.approx(r)
    make_dxf(tmp_path / "in.dxf", units=1)
    inch = dxf_strokes(tmp_path / "in.dxf")
    np.testing.assert_allclose(inch[0].pieces[0][1], [50 * 25.4, 0], atol=1e-9)


def test_dxf_spline_and_ellipse_as_arcs_within_tolerance_or_exact(tmp_path):
    make_dxf(tmp_path / "a.dxf")
    spline = ezdxf.readfile(tmp_path / "a.dxf").modelspace().query("SPLINE")[0].construction_tool()
    for tol in (0.05, 0.005):
        stroke = dxf_strokes(tmp_path / "a.dxf", tolerance=tol)[4]
        lo, hi = spline.knots()[spline.degree], spline.knots()[-spline.degree - 1]
        worst = max(distance_to_arcs(stroke.pieces, stroke.start, np.array(spline.point(t))[:2])
                    for t in np.linspace(lo, hi, 400))
        assert worst <= tol * 1.05
    exact = strokes_to_path(dxf_strokes(tmp_path / "a.dxf", curves="exact"))
    kinds = [s.kind for s in exact if not s.rapid]
    assert "nurbs" in kinds and "ellipse" in kinds
    ellipse = next(s for s in exact if s.kind == "ellipse")
    np.testing.assert_allclose(ellipse.end[:2], [50, 70], atol=1e-9)


def test_unreadable_or_empty_drawings_are_refused(tmp_path):
    bad = tmp_path / "bad.dxf"
    bad.write_text("not a dxf")
    with pytest.raises(PathError, match="cannot read the DXF"):
        read_vector(bad)
    with pytest.raises(PathError, match="not a vector drawing"):
        read_vector(tmp_path / "x.png")
    with pytest.raises(PathError, match="nothing to draw"):
        strokes_to_path(svg_strokes(SVG), [Style(skip=True)])
    with pytest.raises(PathError, match="cannot read the SVG"):
        svg_strokes("<svg")
    assert isinstance(strokes_to_path(svg_strokes(SVG))[1], (Line, Arc))
