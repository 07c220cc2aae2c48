"""A Path through the step interpolators: per-segment dispatch, grid snapping, exact ends."""

import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

from flowmc.errors import PathError
from flowmc.motion import stepinterp as si
from flowmc.motion.path import Arc, Dwell, EllipseArc, Line, NurbsCurve, Path
from flowmc.motion.path_steps import path_to_steps


def xy_distance(points_mm, seg, n=200_000):
    """Distance from XY points to a segment's XY projection (dense samples)."""
    s = np.linspace(0.0, seg.length, n)
    return cKDTree(seg.point_at(s)[:, :2]).query(points_mm)[0]


def per_segment_positions(steps):
    """Positions after each row (mm) and the segment of each row."""
    return steps.positions()[1:], steps.segment


def mixed_path():
    """Every kind, each starting where the last ended."""
    segs = [
        Line((1, 1, 0), (20, 6, 0), source="row 1"),
        Arc((20, 6, 0), (10, 16, 0), (10, 6, 0), ccw=True, source="row 2"),
        Arc((10, 16, 0), (10, 16, 0), (10, 11, 0), ccw=False, source="row 3"),  # full circle, cw
        Dwell((10, 16, 0), 1.0),
        Arc((10, 16, 0), (4, 10, 2), (4, 16, 0), ccw=True, source="row 5"),  # helix: XY quarter
        EllipseArc.from_axes((0, 10, 2), 4.0, 2.5, 0.0, 0.0, 1.5 * math.pi, source="row 6"),  # to (0, 7.5)
    ]
    a, rot = 3.0, 0.5
    centre = np.array([0.0, 7.5, 2.0]) - a * np.array([math.cos(rot), math.sin(rot), 0.0])
    segs.append(EllipseArc.from_axes(centre, a, 1.5, rot, 0.0, math.pi, source="row 7"))  # rotated: chords
    p = segs[-1].end
    segs.append(NurbsCurve([p, (-6, 4, 2), (-4, -2, 2), (2, -3, 2)], source="row 8"))
    segs.append(Arc((2, -3, 2), (2, -3, 8), (2, -3, 5), normal_axis=0, ccw=True, source="row 9"))  # YZ: chords
    segs.append(Line((2, -3, 8), (1, 1, 0), source="row 10"))
    path = Path(segs)
    assert path.gaps() == []
    return path


@pytest.mark.parametrize("method", ["pbp", "dda"])
def test_every_kind_ends_exactly_and_stays_near_its_geometry(method):
    path = mixed_path()
    step = 0.05
    out = path_to_steps(path, [step, step], method)
    assert out.axes == ("X", "Y") and out.steps.dtype == np.int8
    assert out.origin.tolist() == [1.0, 1.0]
    pos, seg = per_segment_positions(out)
    assert np.allclose(pos[-1], [1.0, 1.0])
    assert np.all(np.diff(seg) >= 0)
    assert set(seg.tolist()) == {0, 1, 2, 4, 5, 6, 7, 8, 9}  # the dwell (3) makes no steps
    # every segment ends on the grid point nearest its programmed end
    for i, s in enumerate(path):
        rows = np.flatnonzero(seg == i)
        if len(rows):
            assert np.allclose(pos[rows[-1]], np.rint(s.end[:2] / step) * step), i
    # distance from the programmed curve: a step from the grid curve, plus the snapping of start
    # and centre to the grid (each within half a diagonal), plus the chord tolerance
    bound = {"pbp": 1.0, "dda": 1.5}[method] * step + 3 * math.sqrt(0.5) * step + 0.5 * step
    for i, s in enumerate(path):
        rows = np.flatnonzero(seg == i)
        if len(rows) and s.length > 0:
            assert xy_distance(pos[rows], s).max() <= bound, (method, i)


def test_point_by_point_blocks_are_the_interpolator_functions_on_grid_points():
    step = 0.01
    path = Path([
        Line((0, 0, 0), (0.3, 0.07, 0)),
        Arc((0.3, 0.07, 0), (0.14, 0.23, 0), (0.14, 0.07, 0), ccw=True),  # R 0.16 = 16 steps, ends on grid
        Arc((0.14, 0.23, 0), (0.14, 0.23, 0), (0.14, 0.16, 0), ccw=False, turns=1),  # two full turns
        EllipseArc.from_axes((0.14, 0.18, 0), 0.30, 0.05, 0.0, math.pi / 2, 2 * math.pi),
    ])
    out = path_to_steps(path, [step, step], "pbp")
    parts = [
        si.pbp_line((30, 7), (0, 0)),
        si.pbp_arc((30, 7), (14, 23), (14, 7), ccw=True),
        si.pbp_arc((14, 23), (14, 23), (14, 16), ccw=False, turns=1),
    ]
    head = np.concatenate([p.steps for p in parts])
    assert np.array_equal(out.steps[:len(head)], head)
    assert np.bincount(out.segment).tolist()[:3] == [len(p) for p in parts]
    ellipse = out.steps[len(head):]
    # the ellipse (30 x 5 steps, 3/4 of it) as A x^2 + B y^2 = K: one step per tick, exact end
    assert np.all(np.abs(ellipse).sum(axis=1) == 1)
    assert np.count_nonzero(ellipse[:, 0]) == 30 + 30 + 30 and np.count_nonzero(ellipse[:, 1]) == 5 + 5 + 5
    assert np.allclose(out.positions()[-1], [0.44, 0.18])


def test_dda_blocks_are_the_dda_functions_and_bits_apply_to_every_move():
    step = 0.01
    path = Path([Line((0, 0, 0), (0.3, 0.07, 0)), Arc((0.3, 0.07, 0), (0.14, 0.23, 0), (0.14, 0.07, 0), ccw=True)])
    out = path_to_steps(path, [step, step], "dda", bits=7, preset="zero")
    line = si.dda_line((30, 7), (0, 0), bits=7, preset="zero")
    arc = si.dda_arc((30, 7), (14, 23), (14, 7), ccw=True, bits=7, preset="zero")
    assert np.array_equal(out.steps, np.concatenate([line.steps, arc.steps]))
    assert len(line) == 128


def test_unequal_step_sizes_run_circles_as_conics_in_point_by_point():
    # X 0.01 mm, Y 0.025 mm per step: a circle of 5 mm is 500 x 200 steps.
    path = Path([Arc((5, 0, 0), (5, 0, 0), (0, 0, 0), ccw=True)])
    out = path_to_steps(path, [0.01, 0.025], "pbp")
    pos = out.positions()
    assert np.all(np.abs(out.steps).sum(axis=1) == 1)  # one step per tick: not chords of DDA lines
    assert np.count_nonzero(out.steps[:, 0]) == 4 * 500 and np.count_nonzero(out.steps[:, 1]) == 4 * 200
    assert np.abs(np.hypot(pos[:, 0], pos[:, 1]) - 5.0).max() <= 0.025  # within a (larger) step
    # DDA has no conic: it cuts the circle into chords, each a DDA line
    dda = path_to_steps(path, [0.01, 0.025], "dda")
    dpos = dda.positions()
    assert np.allclose(dpos[-1], [5.0, 0.0])
    assert np.abs(np.hypot(dpos[:, 0], dpos[:, 1]) - 5.0).max() <= 0.025 + 0.005 + 0.01


def test_an_arc_shorter_than_a_step_does_not_go_round():
    # start and end land on the same grid point, but the sweep is tiny: not a full circle
    path = Path([Arc((10, 0, 0), (10 * math.cos(1e-4), 10 * math.sin(1e-4), 0), (0, 0, 0), ccw=True)])
    out = path_to_steps(path, [0.01, 0.01], "pbp")
    assert len(out) == 0
    full = path_to_steps(Path([Arc((10, 0, 0), (10, 0, 0), (0, 0, 0))]), [0.01, 0.01], "pbp")
    assert len(full) == 8 * 1000


def test_a_gap_in_the_path_is_closed_with_a_line():
    path = Path([Line((0, 0, 0), (1, 0, 0)), Line((1, 0.5, 0), (2, 0.5, 0))])
    out = path_to_steps(path, [0.1, 0.1], "pbp")
    assert np.bincount(out.segment).tolist() == [10, 5 + 10]
    assert np.allclose(out.positions()[-1], [2.0, 0.5])


def test_tick_and_step_sizes_are_carried_to_the_steps_value():
    out = path_to_steps(Path.polyline([(0, 0), (1, 1)]), [0.01, 0.02], "pbp", tick=1e-4)
    assert out.tick == 1e-4 and out.step_mm.tolist() == [0.01, 0.02]
    assert np.allclose(out.positions()[-1], [1.0, 1.0])


@pytest.mark.parametrize("call, message", [
    (lambda: path_to_steps(Path([]), [0.01, 0.01]), "the path is empty"),
    (lambda: path_to_steps(Path.polyline([(0, 0), (1, 1)]), [0.01, 0.01], "spline"), "method must be one of"),
    (lambda: path_to_steps(Path.polyline([(0, 0), (1, 1)]), [0.0, 0.01]), "step_mm must be > 0 mm"),
    (lambda: path_to_steps(Path.polyline([(0, 0), (0.1, 0.1), (5, 1)]), [0.01, 0.01], "dda", bits=8),
     "segment 2 (point 2): DDA register too small for this line: 8 bits hold integrands below 256, but it needs 490"),
    (lambda: path_to_steps(Path.polyline([(0, 0), (1, 1)]), [0.01, 0.01], chord_tol=0), "chord tolerance must be > 0"),
])
def test_bad_input_names_the_segment(call, message):
    with pytest.raises(PathError) as info:
        call()
    assert message in str(info.value)
