"""Paths stored as columns: the G-code reader hands the planner arrays, segment objects come only on
demand, and a column path behaves exactly as the same path built from Segment objects."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from flowmc.errors import PlanningError
from flowmc.motion.gcode import parse_gcode
from flowmc.motion.lookahead import plan_lookahead, plan_stop_and_go
from flowmc.motion.machine import Machine
from flowmc.motion.path import Line, Path
from flowmc.motion.pieces import build_pieces
from flowmc.motion.planner import plan_smooth
from flowmc.motion.signals import path_signals

PROGRAM = """(every kind of row the reader makes)
G21 G90 G17 F1200 S9000 M3
G0 X0 Y0 Z2
G1 Z-1 F300
M62 P2
G1 X10 Y0 F1200
G1 X10 Y10
G2 X20 Y10 I5 J0
G3 X20 Y20 R5 Z-2
G18 G2 X30 Z-2 I5 K0
G19 G3 Y30 Z-2 J5 K0
G17 G2 X20 Y30 I-5 J0 P2 Z-3
G4 P0.5
M64 P3
M68 E1 Q2.5
G1 X0 Y30
M0 (MSG, look)
G5 I0 J5 P0 Q5 X10 Y40
M5
G0 Z5
M2
"""


@pytest.fixture(scope="module")
def both() -> tuple[Path, Path]:
    read = parse_gcode(PROGRAM, "part.ngc")
    return read, Path(read.segments)


def test_the_reader_hands_out_columns_and_the_planner_makes_no_segment_objects():
    path = parse_gcode(PROGRAM, "part.ngc")
    # every planner reads columns only: the segment-by-segment ones and the blend rule's smoothing
    # (flowmc.motion.smoothing), whose curve takes lines and arcs from the columns and curves from ``curves``
    plan = plan_lookahead(path, Machine(), rule="junction_deviation")
    plan_stop_and_go(path, Machine())
    smooth = plan_lookahead(path, Machine())
    path.summary()
    assert "segments" not in path.__dict__  # no Segment object was made for all of that
    assert len(plan.trajectory.positions) > 100 and len(smooth.trajectory.positions) > 100
    assert path[5].kind == "arc" and "segments" not in path.__dict__
    assert path.kind_counts() == {"arc": 5, "dwell": 3, "line": 6, "nurbs": 1}


def test_the_smoothed_plan_is_the_same_from_columns_and_from_segment_objects(both):
    cols, objs = both
    machine = Machine()
    a, b = plan_smooth(cols, machine), plan_smooth(objs, machine)
    np.testing.assert_allclose(a.trajectory.positions, b.trajectory.positions, atol=1e-9)
    np.testing.assert_array_equal(a.trajectory.segment, b.trajectory.segment)
    np.testing.assert_array_equal(a.smoothed.stop_u, b.smoothed.stop_u)
    np.testing.assert_array_equal(a.smoothed.stop_dwell, b.smoothed.stop_dwell)
    assert a.smoothed.stop_dwell.max() == 0.5  # G4 P0.5 waits where it is


def test_a_column_path_is_the_same_path_as_its_segment_objects(both):
    cols, objs = both
    assert cols.digest() == objs.digest()
    assert cols.summary() == objs.summary()
    assert cols.segment_names() == objs.segment_names() and cols.segment_names()[2] == "part.ngc:6"
    assert cols.segment_rapid() == objs.segment_rapid()
    assert cols.events() == objs.events() and cols.events()[0][1].message == "look"
    assert cols.gaps() == objs.gaps() == []
    np.testing.assert_allclose(cols.lengths, objs.lengths, rtol=1e-12)
    for tol in (0.1, 0.001):
        (p, i), (q, j) = cols.sample(tol), objs.sample(tol)
        np.testing.assert_array_equal(i, j)
        np.testing.assert_allclose(p, q, atol=1e-9)
    times = np.arange(len(cols), dtype=float)
    a, b = path_signals(cols, times), path_signals(objs, times)
    assert (a.kind.tolist(), a.channel.tolist()) == (b.kind.tolist(), b.channel.tolist())
    np.testing.assert_array_equal(a.value, b.value)
    assert {"dout", "da", "spindle_rpm", "tool"} <= set(a.kind.tolist())
    for k in range(len(cols)):
        assert cols[k].describe() == objs[k].describe()


def test_pieces_and_plans_agree_between_the_two_forms(both):
    cols, objs = both
    machine = Machine()
    a, b = build_pieces(cols, machine, 0.05), build_pieces(objs, machine, 0.05)
    for name in ("kind", "seg", "stop_after"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    for name in ("length", "origin", "u", "e2", "radius", "phi0", "sweep", "rise", "kappa", "vmax", "t_start", "t_end"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), atol=1e-9)
    ta, tb = plan_lookahead(cols, machine).trajectory, plan_lookahead(objs, machine).trajectory
    np.testing.assert_allclose(ta.positions, tb.positions, atol=1e-9)


def test_a_column_path_survives_pickling(both):
    cols, _ = both
    back = pickle.loads(pickle.dumps(cols))
    assert back.digest() == cols.digest() and back.segment_names() == cols.segment_names()
    assert "segments" not in back.__dict__


def test_paths_stay_immutable(both):
    cols, objs = both
    for path in (cols, objs):
        with pytest.raises(AttributeError):
            path.segments = ()


def test_a_bad_feed_on_an_object_path_is_named_as_before():
    path = Path([Line((0, 0, 0), (1, 0, 0), feed=10.0, source="row 1"),
                 Line((1, 0, 0), (2, 0, 0), feed="fast", source="row 2")])
    with pytest.raises(PlanningError, match=r"segment 2 \(row 2\).*feed must be > 0 mm/s, got 'fast'"):
        build_pieces(path, Machine())
