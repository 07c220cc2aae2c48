"""Path geometry against analytic values, transforms, sampling and the thesis pattern's lengths."""

import json
import math
from pathlib import Path as FsPath

import numpy as np
import pytest

from flowmc.errors import PathError
from flowmc.motion.path import Arc, Dwell, EllipseArc, Line, NurbsCurve, Path
from flowmc.motion.segment_table import path_from_rows

REFERENCE = FsPath(__file__).resolve().parents[1] / "data" / "reference"


def thesis_path() -> Path:
    data = json.loads((REFERENCE / "thesis_pattern.json").read_text())
    return path_from_rows(data["segments"], start=data["start"])


def test_thesis_pattern_xy_lengths_match_the_table_with_the_corrected_third_segment():
    expected = [32.01562, 28.28427, 15.0, 28.28427, 25.0, 75.0]
    chords = [np.linalg.norm((s.end - s.start)[:2]) for s in thesis_path()]
    np.testing.assert_allclose(chords, expected, atol=1e-5)


def test_thesis_pattern_arcs_have_the_stated_centres_and_directions():
    segs = thesis_path().segments
    assert segs[1].kind == "arc" and segs[1].ccw and segs[1].radius == pytest.approx(20)
    np.testing.assert_allclose(segs[1].center[:2], [-40, 25])
    assert segs[3].kind == "arc" and not segs[3].ccw
    np.testing.assert_allclose(segs[3].center[:2], [-75, 45])
    assert thesis_path().gaps() == []
    np.testing.assert_allclose(thesis_path().end, [0, 0, 0])


@pytest.mark.parametrize("normal", [0, 1, 2])
@pytest.mark.parametrize("ccw", [True, False])
def test_arc_points_stay_on_the_circle_and_length_is_r_times_sweep(normal, ccw):
    from flowmc.motion.path import PLANES

    iu, iv = PLANES[normal][1]
    start, end, center = np.zeros(3), np.zeros(3), np.zeros(3)
    start[iu], end[iv] = 10.0, 10.0
    arc = Arc(start, end, center, normal_axis=normal, ccw=ccw)
    sweep = math.pi / 2 if ccw else -3 * math.pi / 2
    assert arc.sweep == pytest.approx(sweep)
    assert arc.length == pytest.approx(10 * abs(sweep))
    pts = arc.point_at(np.linspace(0, arc.length, 50))
    np.testing.assert_allclose(np.linalg.norm(pts, axis=1), 10.0)
    np.testing.assert_allclose(pts[-1], end, atol=1e-12)
    # Tangents are unit and point along the motion.
    tang = arc.tangent_at(np.linspace(0, arc.length, 50))
    np.testing.assert_allclose(np.linalg.norm(tang, axis=1), 1.0)
    fd = np.diff(pts, axis=0)
    assert np.all(np.einsum("ij,ij->i", fd, tang[:-1]) > 0)


def test_helix_length_full_turns_and_rise():
    arc = Arc((10, 0, 0), (10, 0, 6), (0, 0, 0), ccw=True, turns=2)
    assert arc.sweep == pytest.approx(6 * math.pi)
    assert arc.length == pytest.approx(math.hypot(60 * math.pi, 6))
    np.testing.assert_allclose(arc.point_at(arc.length / 2), [-10, 0, 3], atol=1e-9)


def test_arc_that_cannot_reach_its_end_is_an_error_naming_the_source():
    with pytest.raises(PathError, match="part.ngc:7.*end radius"):
        Arc((10, 0, 0), (0, 12, 0), (0, 0, 0), source="part.ngc:7")


def test_ellipse_length_matches_ramanujan_and_points_satisfy_the_equation():
    e = EllipseArc.from_axes((5, -2, 0), 100, 50, 0.0, 0.0, 2 * math.pi)
    h = ((100 - 50) / (100 + 50)) ** 2
    ramanujan = math.pi * 150 * (1 + 3 * h / (10 + math.sqrt(4 - 3 * h)))
    assert e.length == pytest.approx(ramanujan, rel=1e-9)
    pts = e.point_at(np.linspace(0, e.length, 101))
    x, y = pts[:, 0] - 5, pts[:, 1] + 2
    np.testing.assert_allclose((x / 100) ** 2 + (y / 50) ** 2, 1.0, atol=1e-12)
    # Arc-length parameterisation: equal steps in s give equal chords (fine sampling).
    chords = np.linalg.norm(np.diff(e.point_at(np.linspace(0, e.length, 20001)), axis=0), axis=1)
    assert chords.max() / chords.min() - 1 < 1e-4


def test_sampling_respects_the_chord_tolerance_on_arcs_and_ellipses():
    tol = 0.01
    arc = Arc((50, 0, 0), (-50, 0, 0), (0, 0, 0))
    pts = arc.sample(tol)
    mids = 0.5 * (pts[1:] + pts[:-1])
    assert (50 - np.linalg.norm(mids[:, :2], axis=1)).max() <= tol
    e = EllipseArc.from_axes((0, 0, 0), 100, 20, 0.3, 0.0, math.pi)
    p2 = e.sample(tol)
    dense = e.point_at(np.linspace(0, e.length, 200001))
    for a, b in zip(p2[:-1:7], p2[1::7]):  # check a spread of chords against the dense curve
        ab = b - a
        inside = dense[(np.einsum("ij,j->i", dense - a, ab) >= 0) & (np.einsum("ij,j->i", dense - b, -ab) >= 0)]
        dist = np.linalg.norm(np.cross(inside - a, ab), axis=1) / np.linalg.norm(ab)
        assert dist.max() <= tol * 1.001


def test_transforms_are_exact_and_mirror_flips_arc_direction():
    p = thesis_path()
    moved = p.translated((10, 20, 5)).rotated(90).scaled(2.0)
    for orig, new in zip(p, moved):
        x, y, z = orig.end
        np.testing.assert_allclose(new.end, [2 * -(y + 20), 2 * (x + 10), 2 * (z + 5)], atol=1e-9)
        assert new.length == pytest.approx(2 * orig.length)
    mirrored = p.mirrored("X")
    assert [s.ccw for s in mirrored if s.kind == "arc"] == [False, True]
    with pytest.raises(PathError, match="ellipse"):
        p.scaled((1, 2, 1))


def test_concat_inserts_a_tool_up_rapid_and_digest_tracks_content():
    a = Path.polyline([(0, 0), (10, 0)])
    b = Path.polyline([(20, 0), (20, 10)])
    joined = a.concat(b)
    assert [s.rapid for s in joined] == [False, True, False]
    assert joined[1].tool_down is False
    assert joined.length == pytest.approx(30)
    assert a.digest() == Path.polyline([(0, 0), (10, 0)]).digest()
    assert a.digest() != a.with_feed(5).digest()


def test_path_sample_tags_points_with_segments_and_bbox_includes_arc_extremes():
    p = Path([Line((0, -10, 0), (10, 0, 0)), Arc((10, 0, 0), (-10, 0, 0), (0, 0, 0))])
    pts, idx = p.sample(0.001)
    assert idx[0] == 0 and idx[-1] == 1 and np.all(np.diff(idx) >= 0)
    lo, hi = p.bbox()
    assert hi[1] == pytest.approx(10, abs=1e-3) and lo[0] == pytest.approx(-10, abs=1e-9)


def test_dwell_has_no_length_and_nurbs_ends_at_its_end_control_points():
    d = Dwell((1, 2, 3), 0.5)
    assert d.length == 0 and d.seconds == 0.5
    curve = json.loads((REFERENCE / "nurbs_test_curve.json").read_text())
    n = NurbsCurve(curve["control_points"], curve["weights"], degree=curve["degree"])
    np.testing.assert_allclose(n.start[:2], curve["control_points"][0], atol=1e-12)
    np.testing.assert_allclose(n.end[:2], curve["control_points"][-1], atol=1e-12)
    assert n.length == pytest.approx(409.30, abs=0.05)


@pytest.mark.parametrize(
    "row, message",
    [
        ({"type": "arc", "direction": "cw", "radius": 5, "start_angle": 0, "end_angle": 90}, "row 2.*cw arc needs"),
        ({"type": "arc", "direction": "ccw", "radius": -5, "start_angle": 0, "end_angle": 90}, "row 2.*radius"),
        ({"type": "spiral"}, "row 2"),
        ({"type": "line", "end": [1, 2]}, "row 2.*end"),
    ],
)
def test_segment_table_errors_name_the_row(row, message):
    with pytest.raises(PathError, match=message):
        path_from_rows([{"type": "line", "end": [1, 0, 0]}, row])


def test_segment_table_full_turn_helix_and_ellipse_rows():
    p = path_from_rows([
        {"type": "arc", "direction": "ccw", "radius": 10, "start_angle": 0, "end_angle": 720, "dz": 4},
        {"type": "ellipse", "direction": "cw", "a": 20, "b": 10, "start_angle": 90, "end_angle": -90},
    ])
    helix, ell = p.segments
    assert helix.sweep == pytest.approx(4 * math.pi) and helix.rise == 4
    np.testing.assert_allclose(helix.end, [0, 0, 4], atol=1e-9)
    np.testing.assert_allclose(ell.start, helix.end, atol=1e-9)
    np.testing.assert_allclose(ell.end - ell.start, [0, -20, 0], atol=1e-9)
    assert p.gaps() == []
