"""Tool-radius compensation against shapes with known offsets and the thesis's six-segment pattern."""

import json
import math
from pathlib import Path as FsPath

import numpy as np
import pytest

from flowmc.errors import PathError
from flowmc.motion.offset import offset_path
from flowmc.motion.path import Arc, Dwell, EllipseArc, Line, Path
from flowmc.motion.segment_table import path_from_rows

REFERENCE = FsPath(__file__).resolve().parents[1] / "data" / "reference"


def thesis_path() -> Path:
    data = json.loads((REFERENCE / "thesis_pattern.json").read_text())
    return path_from_rows(data["segments"], start=data["start"])


def square(s: float, ccw: bool = True) -> Path:
    pts = [(0, 0), (s, 0), (s, s), (0, s), (0, 0)]
    return Path.polyline(pts if ccw else pts[::-1])


def circle(radius: float, ccw: bool = True) -> Path:
    return Path([Arc((radius, 0, 0), (radius, 0, 0), (0, 0, 0), ccw=ccw)])


def xy_distance(points: np.ndarray, path: Path) -> np.ndarray:
    """Exact XY distance from each point to a path of lines and XY arcs."""
    p = np.asarray(points)[:, :2]
    best = np.full(len(p), np.inf)
    for seg in path:
        a, b = seg.start[:2], seg.end[:2]
        if seg.kind == "line":
            d = b - a
            t = np.clip((p - a) @ d / (d @ d), 0.0, 1.0)
            dist = np.linalg.norm(p - (a + t[:, None] * d), axis=1)
        else:
            rel = p - seg.center[:2]
            ang = np.arctan2(rel[:, 1], rel[:, 0])
            off = (ang - seg.start_angle) * np.sign(seg.sweep) % (2 * np.pi)
            on_arc = (off <= abs(seg.sweep)) | (abs(seg.sweep) >= 2 * np.pi)
            ends = np.minimum(np.linalg.norm(p - a, axis=1), np.linalg.norm(p - b, axis=1))
            dist = np.where(on_arc, np.abs(np.linalg.norm(rel, axis=1) - seg.radius), ends)
        best = np.minimum(best, dist)
    return best


def dense_points(path: Path, step: float = 0.05) -> np.ndarray:
    pts = [seg.point_at(np.linspace(0, seg.length, max(2, math.ceil(seg.length / step) + 1))) for seg in path]
    return np.vstack(pts)


def shoelace(path: Path) -> float:
    pts, _ = path.sample(0.001)
    x, y = pts[:, 0], pts[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


# ------------------------------------------------------------------ squares and circles

@pytest.mark.parametrize("ccw", [True, False])
def test_square_outward_keeps_sides_and_rounds_corners_with_the_tool_radius(ccw):
    s, r = 10.0, 1.5
    outward = "right" if ccw else "left"
    out = offset_path(square(s, ccw), r, outward)
    assert [seg.kind for seg in out] == ["line", "arc"] * 4
    assert out.length == pytest.approx(4 * s + 2 * math.pi * r, abs=1e-9)
    corners = {(0, 0), (s, 0), (s, s), (0, s)}
    for seg in out:
        if seg.kind == "line":
            assert seg.length == pytest.approx(s, abs=1e-12)
        else:
            assert seg.radius == pytest.approx(r) and abs(seg.sweep) == pytest.approx(math.pi / 2)
            assert tuple(np.round(seg.center[:2], 9)) in corners
            assert seg.ccw == ccw
    assert out.gaps() == [] and np.allclose(out.start, out.end)
    np.testing.assert_allclose(xy_distance(dense_points(out), square(s)), r, atol=1e-9)


@pytest.mark.parametrize("ccw", [True, False])
def test_square_inward_is_a_square_of_side_s_minus_2r(ccw):
    s, r = 10.0, 1.5
    out = offset_path(square(s, ccw), r, "left" if ccw else "right")
    assert [seg.kind for seg in out] == ["line"] * 4
    corners = np.array([seg.start[:2] for seg in out])
    assert sorted(map(tuple, np.round(corners, 9))) == [(r, r), (r, s - r), (s - r, r), (s - r, s - r)]
    np.testing.assert_allclose([seg.length for seg in out], s - 2 * r, atol=1e-12)
    assert out.gaps() == [] and np.allclose(out.start, out.end)


@pytest.mark.parametrize("ccw,side,expected", [(True, "left", 7.0), (True, "right", 13.0),
                                               (False, "left", 13.0), (False, "right", 7.0)])
def test_circle_offsets_to_radius_r_plus_or_minus_tool_radius(ccw, side, expected):
    out = offset_path(circle(10.0, ccw), 3.0, side)
    assert len(out) == 1 and out[0].kind == "arc" and out[0].ccw == ccw
    assert out[0].radius == pytest.approx(expected)
    assert abs(out[0].sweep) == pytest.approx(2 * math.pi)
    np.testing.assert_allclose(out[0].center[:2], 0.0, atol=1e-12)


def test_an_inward_tool_as_large_as_the_arc_is_refused_naming_the_segment():
    path = Path([Line((20, 0), (10, 0), source="row 1"), Arc((10, 0, 0), (10, 0, 0), (0, 0, 0), source="row 2")])
    with pytest.raises(PathError) as err:
        offset_path(path, 10.0, "left")
    assert str(err.value).startswith("segment 2 (row 2):") and "radius" in str(err.value)


# ------------------------------------------------------------------ line-arc and arc-arc joins

def d_shape(radius: float) -> Path:
    """Up the Y axis, then a ccw half circle back through (-R, 0): a closed ccw 'D'."""
    return Path([Line((0, -radius), (0, radius)), Arc((0, radius), (0, -radius), (0, 0), ccw=True)])


def test_d_shape_inward_trims_line_and_arc_at_their_intersection():
    big, r = 10.0, 2.0
    out = offset_path(d_shape(big), r, "left")
    assert [seg.kind for seg in out] == ["line", "arc"]
    inner = big - r
    half = math.sqrt(inner**2 - r**2)
    np.testing.assert_allclose(out[0].start[:2], (-r, -half), atol=1e-12)
    np.testing.assert_allclose(out[0].end[:2], (-r, half), atol=1e-12)
    assert out[1].radius == pytest.approx(inner)
    assert out.length == pytest.approx(2 * half + inner * (math.pi - 2 * math.asin(r / inner)), abs=1e-9)
    assert out.gaps() == [] and np.allclose(out.start, out.end)


def test_d_shape_outward_adds_quarter_arcs_at_its_two_corners():
    big, r = 10.0, 2.0
    out = offset_path(d_shape(big), r, "right")
    assert [seg.kind for seg in out] == ["line", "arc", "arc", "arc"]
    assert out.length == pytest.approx(2 * big + math.pi * (big + r) + math.pi * r, abs=1e-9)
    np.testing.assert_allclose(xy_distance(dense_points(out), d_shape(big)), r, atol=1e-9)


def lens(radius: float, d: float) -> Path:
    """The overlap of two discs of radius R centred at (+-d, 0), traced ccw."""
    h = math.sqrt(radius**2 - d**2)
    return Path([Arc((0, -h), (0, h), (-d, 0), ccw=True), Arc((0, h), (0, -h), (d, 0), ccw=True)])


def test_lens_inward_trims_two_arcs_at_their_intersection():
    big, d, r = 10.0, 6.0, 1.0
    out = offset_path(lens(big, d), r, "left")
    assert [seg.kind for seg in out] == ["arc", "arc"]
    alpha = math.acos(d / (big - r))
    assert out.length == pytest.approx(4 * (big - r) * alpha, abs=1e-9)
    np.testing.assert_allclose(out[0].start[:2], (0, -math.sqrt((big - r) ** 2 - d**2)), atol=1e-12)
    assert out.gaps() == [] and np.allclose(out.start, out.end)


def test_convex_closed_shapes_grow_by_2_pi_r_outward():
    for path in (lens(10.0, 6.0), d_shape(5.0), square(3.0)):
        assert offset_path(path, 0.7, "right").length == pytest.approx(path.length + 2 * math.pi * 0.7, abs=1e-9)


# ------------------------------------------------------------------ open paths, chains, state

def test_open_corner_is_trimmed_inside_and_rounded_outside():
    path = Path.polyline([(0, 0), (10, 0), (10, 10)])
    inside = offset_path(path, 1.0, "left")
    np.testing.assert_allclose([s.start[:2] for s in inside] + [inside.end[:2]], [(0, 1), (9, 1), (9, 10)], atol=1e-12)
    outside = offset_path(path, 1.0, "right")
    assert [s.kind for s in outside] == ["line", "arc", "line"]
    np.testing.assert_allclose(outside.start[:2], (0, -1))
    np.testing.assert_allclose(outside.end[:2], (11, 10))
    assert outside[1].ccw and outside[1].radius == pytest.approx(1.0)


def test_a_reversal_gets_a_half_circle_on_the_offset_side():
    out = offset_path(Path.polyline([(0, 0), (10, 0), (0, 0)]), 1.0, "left")
    assert [s.kind for s in out] == ["line", "arc", "line", "arc"]  # closed: both ends are reversals
    assert out[1].sweep == pytest.approx(-math.pi) and out[3].sweep == pytest.approx(-math.pi)
    assert out.length == pytest.approx(20 + 2 * math.pi)


def test_rapids_are_re_aimed_at_each_offset_contour():
    a, b = square(10.0), square(4.0).translated((20, 3, 0))
    path = a.concat(b)
    out = offset_path(path, 1.0, "right")
    assert out.gaps() == []
    rapids = [s for s in out if s.rapid]
    assert len(rapids) == 1 and not rapids[0].tool_down
    cut = [s for s in out if not s.rapid]
    expected = list(offset_path(a, 1.0, "right")) + list(offset_path(b, 1.0, "right"))
    assert len(cut) == len(expected)
    for got, want in zip(cut, expected):
        np.testing.assert_allclose(got.start, want.start, atol=1e-12)
        np.testing.assert_allclose(got.end, want.end, atol=1e-12)


def test_plunge_dwell_and_retract_stay_at_the_offset_point():
    square_at_depth = [Line(p, q) for p, q in zip(
        [(0, 0, -1), (10, 0, -1), (10, 10, -1), (0, 10, -1)], [(10, 0, -1), (10, 10, -1), (0, 10, -1), (0, 0, -1)])]
    path = Path([Line((-5, -5, 5), (0, 0, 5), rapid=True, tool_down=False), Line((0, 0, 5), (0, 0, -1)),
                 *square_at_depth, Dwell((0, 0, -1), 0.5), Line((0, 0, -1), (0, 0, 5))])
    out = offset_path(path, 1.0, "left")
    assert out.gaps() == []
    plunge, dwell, retract = out[1], out[-2], out[-1]
    np.testing.assert_allclose(plunge.start, (1, 1, 5))
    np.testing.assert_allclose(plunge.end, (1, 1, -1))
    assert dwell.kind == "dwell" and dwell.seconds == 0.5
    np.testing.assert_allclose(dwell.start, (1, 1, -1))
    np.testing.assert_allclose(retract.end, (1, 1, 5))
    np.testing.assert_allclose(out[0].end, (1, 1, 5))  # the rapid now aims at the offset start


def test_feed_and_tool_state_follow_their_segments():
    path = Path([Line((0, 0), (10, 0), feed=5.0, spindle=1000.0, source="a"),
                 Line((10, 0), (10, 10), feed=7.0, spindle=1000.0, outputs=((3, True),), source="b")])
    out = offset_path(path, 1.0, "right")
    assert [(s.feed, s.spindle) for s in out] == [(5.0, 1000.0), (7.0, 1000.0), (7.0, 1000.0)]
    assert out[1].source == "segment 2 (b) corner" and out[1].outputs == ()
    assert out[2].outputs == ((3, True),) and out[2].source == "b"


def test_a_helix_keeps_its_rise_and_a_sloped_line_its_end_heights():
    path = Path([Line((0, -5, 0), (5, -5, 2)), Arc((5, -5, 2), (5, 5, 4), (5, 0, 0), ccw=True)])
    out = offset_path(path, 1.0, "right")
    helix = out[-1]
    assert helix.kind == "arc" and helix.radius == pytest.approx(6.0) and helix.rise == pytest.approx(2.0)
    np.testing.assert_allclose([out[0].start[2], out[0].end[2]], [0, 2])


# ------------------------------------------------------------------ the thesis pattern

@pytest.mark.parametrize("side", ["left", "right"])
def test_thesis_pattern_offset_is_exactly_the_tool_radius_away_and_continuous(side):
    r = 2.0
    original = thesis_path()
    out = offset_path(original, r, side)
    assert out.gaps() == [] and np.allclose(out.start, out.end)
    for pts in (out.sample(0.001)[0], dense_points(out, 0.02)):
        dist = xy_distance(pts, original)
        assert np.max(np.abs(dist - r)) < 1e-6
    # every row's offset runs between that row's start and end heights; corners stay at the corner height
    rows = {seg.source: seg for seg in original}
    for seg in out:
        if seg.source in rows:
            np.testing.assert_allclose([seg.start[2], seg.end[2]], [rows[seg.source].start[2], rows[seg.source].end[2]])
        else:
            assert seg.source.endswith("corner") and seg.start[2] == seg.end[2]
    # the pattern runs ccw: left is inside, right outside, and the arcs change radius accordingly
    area = shoelace(original)
    assert area > 0
    assert (shoelace(out) < area) == (side == "left")
    arcs = {seg.source: round(seg.radius, 9) for seg in out if seg.kind == "arc" and seg.source in rows}
    assert arcs == ({"row 2": 18.0, "row 4": 22.0} if side == "left" else {"row 2": 22.0, "row 4": 18.0})


# ------------------------------------------------------------------ bad input

def test_a_tool_too_large_for_a_square_is_refused_naming_a_segment():
    with pytest.raises(PathError) as err:
        offset_path(square(4.0), 2.5, "left")
    assert str(err.value).startswith("segment ") and "too large" in str(err.value)


def test_ellipses_and_other_plane_arcs_are_refused_naming_the_segment():
    path = Path([Line((0, 0), (1, 0)), EllipseArc.from_axes((1, 1, 0), 2, 1, 0, -math.pi / 2, 0, source="e.ngc:4")])
    with pytest.raises(PathError, match=r"^segment 2 \(e.ngc:4\): .*lines and XY arcs"):
        offset_path(path, 1.0, "left")
    xz = Path([Arc((1, 0, 0), (0, 0, 1), (0, 0, 0), normal_axis=1)])
    with pytest.raises(PathError, match=r"^segment 1: .*XZ plane"):
        offset_path(xz, 0.1, "left")


def test_bad_side_or_radius_is_refused_and_zero_radius_changes_nothing():
    with pytest.raises(PathError, match="left.*right"):
        offset_path(square(1.0), 0.1, "up")
    with pytest.raises(PathError, match=">= 0"):
        offset_path(square(1.0), -0.1, "left")
    path = square(1.0)
    assert offset_path(path, 0.0, "left") is path
