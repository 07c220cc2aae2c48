"""Gouge checks of the tool-radius offset (refuse or trim, exact arcs kept) and pocket clearing."""

import math

import numpy as np
import pytest

from flowmc.errors import PathError
from flowmc.motion.clearance import distance_to, pocket_path
from flowmc.motion.offset import offset_path
from flowmc.motion.path import Arc, Line, Path


def polygon(points, feed=10.0):
    pts = [np.array([x, y, 0.0]) for x, y in points]
    return Path([Line(a, b, feed=feed, source=f"row {k + 1}") for k, (a, b) in enumerate(zip(pts[:-1], pts[1:]))])


# A part 20 x 10 mm with a 3 mm wide notch cut down into it from the top, 7 mm deep, counter-clockwise
# (left of travel is inside the material: the tool runs along the inside).
NOTCH = [(0, 0), (20, 0), (20, 10), (11.5, 10), (11.5, 3), (8.5, 3), (8.5, 10), (0, 10), (0, 0)]


def min_distance(tool_path: Path, contour: Path) -> float:
    segs = [s for s in contour.segments if not s.rapid]
    worst = math.inf
    for seg in tool_path.segments:
        if seg.rapid:
            continue
        for s in np.linspace(0, seg.length, 40):
            worst = min(worst, distance_to(seg.point_at(s)[:2], segs)[0])
    return worst


def test_a_gap_narrower_than_the_tool_is_refused_naming_both_segments():
    with pytest.raises(PathError) as err:
        offset_path(polygon(NOTCH), 2.0, "left")
    message = str(err.value)
    assert "would cut into segment 5 (row 5)" in message and "segment 1 (row 1)" in err.value.where
    assert "gouge 'trim'" in message
    # a tool that fits (3 mm between the notch bottom and the edge: radius 1.4) is fine
    fits = offset_path(polygon(NOTCH), 1.4, "left")
    assert min_distance(fits, polygon(NOTCH)) >= 1.4 - 1e-6


def test_the_reported_case_a_1_mm_slot_with_a_1_mm_tool_radius_is_refused_and_trimmed_clear():
    # the tool outside the part (right of a counter-clockwise outline) must go down the 1 mm slot
    slot = [(0, 0), (20, 0), (20, 10), (10.5, 10), (10.5, 4), (9.5, 4), (9.5, 10), (0, 10), (0, 0)]
    with pytest.raises(PathError, match=r"segment 5 \(row 5\): the tool radius 1 mm is too large"):
        offset_path(polygon(slot), 1.0, "right")
    trimmed = offset_path(polygon(slot), 1.0, "right", gouge="trim")
    assert min_distance(trimmed, polygon(slot)) >= 1.0 - 1e-5
    # a slot a hair wider than the tool is cut down to its bottom
    wide = offset_path(polygon([(x * 1.01 - 0.05 if 9 < x < 11 else x, y) for x, y in slot]), 0.5, "right")
    assert min(p[1] for s in wide for p in (s.start, s.end)) < 4.6


def test_trimming_lifts_over_the_gouges_and_never_cuts_into_the_contour():
    path = polygon(NOTCH)
    trimmed = offset_path(path, 2.0, "left", gouge="trim")
    lifted = [s for s in trimmed if s.rapid]
    assert lifted and all(not s.tool_down and "gouge lifted over" in s.source for s in lifted)
    assert min_distance(trimmed, path) >= 2.0 - 1e-5
    segs = list(trimmed)
    for a, b in zip(segs, segs[1:]):
        np.testing.assert_allclose(a.end, b.start, atol=1e-9)
    # the parts kept are the exact offset pieces: the long bottom edge is cut on both sides of the notch
    cut = [s for s in trimmed if not s.rapid and s.source == "row 1"]
    assert len(cut) == 2 and all(abs(s.start[1] - 2.0) < 1e-12 and abs(s.end[1] - 2.0) < 1e-12 for s in cut)


def test_a_concave_arc_tighter_than_the_tool_is_refused_naming_it_and_convex_arcs_stay_exact():
    # A channel whose round end (radius 1.5) is smaller than the tool radius 2; left of travel is inside it.
    a, b = np.array([0.0, 0.0, 0.0]), np.array([10.0, 0.0, 0.0])
    c, d = np.array([10.0, 3.0, 0.0]), np.array([0.0, 3.0, 0.0])
    path = Path([Line(a, b, source="floor"), Arc(b, c, np.array([10.0, 1.5, 0.0]), ccw=True, source="end"),
                 Line(c, d, source="roof")])
    with pytest.raises(PathError) as err:
        offset_path(path, 2.0, "left")
    assert err.value.where == "segment 2 (end)" and "arc's radius 1.5 mm" in str(err.value)
    with pytest.raises(PathError, match="no room anywhere along this contour"):  # trim: nothing left to cut
        offset_path(path, 2.0, "left", gouge="trim")
    # a wall with a round recess (radius 1.5) the tool cannot enter: trim runs straight past it
    p1, p2 = np.array([10.0, 5.0, 0.0]), np.array([10.0, 8.0, 0.0])
    wall = Path([Line(a, b, source="floor"), Line(b, p1, source="wall"),
                 Arc(p1, p2, np.array([10.0, 6.5, 0.0]), ccw=True, source="recess"),
                 Line(p2, np.array([10.0, 12.0, 0.0]), source="wall 2")])
    with pytest.raises(PathError, match="arc's radius 1.5 mm"):
        offset_path(wall, 2.0, "left")
    trimmed = offset_path(wall, 2.0, "left", gouge="trim")
    assert not any(s.source == "recess" for s in trimmed)
    past = [s for s in trimmed if "no room for the tool" in s.source]
    assert len(past) == 1 and not past[0].rapid
    np.testing.assert_allclose([past[0].start[:2], past[0].end[:2]], [[8, 5], [8, 8]], atol=1e-9)
    assert min_distance(trimmed, wall) >= 2.0 - 1e-5
    outside = offset_path(path, 2.0, "right")  # round the outside the arc grows and stays an arc
    arcs = [s for s in outside if isinstance(s, Arc) and s.source == "end"]
    assert len(arcs) == 1 and arcs[0].radius == pytest.approx(3.5)
    np.testing.assert_allclose(arcs[0].center[:2], [10.0, 1.5])


def test_an_offset_that_clears_everything_is_unchanged_by_the_check():
    square = polygon([(0, 0), (30, 0), (30, 30), (0, 30), (0, 0)])
    a, b = offset_path(square, 2.0, "left", gouge="trim"), offset_path(square, 2.0, "left")
    assert [s.kind for s in a] == [s.kind for s in b] and not any(s.rapid for s in a)
    np.testing.assert_allclose([s.end for s in a], [s.end for s in b])


def test_a_pocket_clears_the_region_inside_and_leaves_the_island():
    boundary = polygon([(0, 0), (40, 0), (40, 30), (0, 30), (0, 0)])
    island = [Line(np.array([0.0, 0.0, 0.0]), np.array([15.0, 15.0, 0.0]), rapid=True, tool_down=False),
              Arc(np.array([15.0, 15.0, 0.0]), np.array([25.0, 15.0, 0.0]), np.array([20.0, 15.0, 0.0]), ccw=True,
                  source="island"),
              Arc(np.array([25.0, 15.0, 0.0]), np.array([15.0, 15.0, 0.0]), np.array([20.0, 15.0, 0.0]), ccw=True,
                  source="island")]
    path = Path([*boundary.segments, *island])
    radius, step = 2.0, 1.5
    pocket = pocket_path(path, radius, step)
    cuts = [s for s in pocket if not s.rapid]
    contour = [s for s in path.segments if not s.rapid]
    # never closer than the radius to the boundary or the island
    assert min_distance(pocket, path) >= radius - 0.006
    # every point of the region is within reach of the tool: sample a grid, the nearest tool-centre
    # point is closer than the radius (the pocket is cleared)
    centres = np.vstack([np.array([s.point_at(x)[:2] for x in np.linspace(0, s.length, max(2, int(s.length / 0.2)))])
                         for s in cuts])
    for x in np.linspace(0.5, 39.5, 40):
        for y in np.linspace(0.5, 29.5, 30):
            if math.hypot(x - 20, y - 15) <= 5.5:
                continue  # the island (and its edge)
            # a round tool cannot reach into the square corners: skip points no tool position covers
            if math.hypot(max(2 - x, 0, x - 38), max(2 - y, 0, y - 28)) >= radius:
                continue
            assert np.min(np.hypot(*(centres - [x, y]).T)) < radius + 1e-6, (x, y)
    assert cuts[-1].source == "pocket ring 1 (finish)"
    assert all(not s.tool_down for s in pocket if s.rapid)
    assert {s.feed for s in cuts} == {10.0}
    assert contour  # the input is left as it was


def test_pocket_direction_and_refusals():
    square = polygon([(0, 0), (20, 0), (20, 20), (0, 20), (0, 0)])

    def turning(p):
        first = [s for s in p if not s.rapid]
        pts = np.array([s.start[:2] for s in first[-4:]] + [first[-1].end[:2]])
        return sum(a[0] * b[1] - a[1] * b[0] for a, b in zip(pts[:-1], pts[1:]))

    assert turning(pocket_path(square, 1.0, 1.0)) < 0  # climb: clockwise
    assert turning(pocket_path(square, 1.0, 1.0, direction="conventional")) > 0
    with pytest.raises(PathError, match="must be closed"):
        pocket_path(polygon([(0, 0), (20, 0), (20, 20)]), 1.0, 1.0)
    with pytest.raises(PathError, match="does not fit"):
        pocket_path(polygon([(0, 0), (2, 0), (2, 2), (0, 2), (0, 0)]), 1.5, 1.0)
    with pytest.raises(PathError, match="step-over"):
        pocket_path(square, 1.0, 3.0)
