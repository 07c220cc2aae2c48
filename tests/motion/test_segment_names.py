"""Segments are named to users one way: 1-based, with where they came from (``segment 5 (row 4)``).

A Trajectory or Steps keeps 0-based ``segment`` indices per row and carries the path's
``segment_names`` so anything downstream (pre-flight, a card, the 3D view) can name a segment
with ``describe_segment`` as the user knows it.
"""

from __future__ import annotations

import numpy as np
import pytest

import flowmc
from flowmc.errors import PathError
from flowmc.motion.lookahead import plan_lookahead, plan_stop_and_go
from flowmc.motion.machine import Axis, Machine
from flowmc.motion.path import Dwell, Line, Path, describe_segment
from flowmc.motion.path_steps import path_to_steps
from flowmc.motion.segment_table import path_from_rows
from flowmc.motion.trajectory import Steps, Trajectory

MACHINE = Machine(axes=(Axis(name="X", step_mm=0.01), Axis(name="Y", step_mm=0.01), Axis(name="Z", min=-50, max=50)),
                  period=0.002)
ROWS = [
    {"type": "line", "end": [10, 0, 0]},
    {"type": "arc", "direction": "ccw", "radius": 5, "start_angle": -90, "end_angle": 0},
    {"type": "line", "end": [0, 5, 0]},
]


def spun_up_path() -> Path:
    """A dwell with no source in front of three table rows: numbers and rows no longer match."""
    rows = path_from_rows(ROWS, feed=20.0)
    return Path((Dwell((0, 0, 0), 0.05),) + rows.segments)


def test_describe_segment_counts_from_one_and_adds_the_source():
    names = ("node spindle: spin-up", "row 1", "row 2", "", "row 4")
    assert describe_segment(4, names) == "segment 5 (row 4)"
    assert describe_segment(0, names) == "segment 1 (node spindle: spin-up)"
    assert describe_segment(3, names) == "segment 4"  # a segment without a source
    assert describe_segment(7, names) == "segment 8"  # beyond the names: the number alone
    assert describe_segment(2) == "segment 3"
    assert describe_segment(np.int64(1), "part.ngc:12") == "segment 2 (part.ngc:12)"  # one segment's own name


def test_path_segment_names_are_the_sources_in_order():
    path = spun_up_path()
    assert path.segment_names() == ("", "row 1", "row 2", "row 3")
    assert Path.polyline([(0, 0), (1, 0), (1, 1)]).segment_names() == ("point 1", "point 2")
    assert Path().segment_names() == ()
    with pytest.raises(PathError, match=r"^segment 2 is a int, not a path segment"):
        Path([Line((0, 0), (1, 0)), 5])


def test_trajectory_and_steps_carry_names_in_their_digest_and_stay_backward_compatible():
    pos = np.zeros((4, 3))
    seg = np.array([0, 0, 1, 1])
    plain = Trajectory(pos, 0.001, seg)
    assert plain.segment_names == ()
    named = Trajectory(pos, 0.001, seg, segment_names=("row 1", "row 2"))
    assert named.segment_names == ("row 1", "row 2")
    assert named.digest() != plain.digest()
    assert named.digest() == Trajectory(pos, 0.001, seg, segment_names=["row 1", "row 2"]).digest()
    assert named.digest() != Trajectory(pos, 0.001, seg, segment_names=("row 1", "row 3")).digest()
    steps = np.ones((4, 2), dtype=np.int8)
    plain_steps = Steps(steps, 0.01, segment=seg)
    named_steps = Steps(steps, 0.01, segment=seg, segment_names=("a", ""))
    assert plain_steps.segment_names == () and named_steps.segment_names == ("a", "")
    assert named_steps.digest() != plain_steps.digest()
    with pytest.raises(ValueError, match="do not fit the 1 segment names"):
        Trajectory(pos, 0.001, seg, segment_names=("row 1",))
    with pytest.raises(ValueError, match="not a single string"):
        Steps(steps, 0.01, segment=seg, segment_names="row 1")
    with pytest.raises(ValueError, match="must be strings"):
        Trajectory(pos, 0.001, seg, segment_names=("row 1", 2))


@pytest.mark.parametrize("plan", [
    lambda path: plan_lookahead(path, MACHINE).trajectory,
    lambda path: plan_stop_and_go(path, MACHINE).trajectory,
    lambda path: path_to_steps(path, 0.01, "pbp"),
    lambda path: path_to_steps(path, 0.01, "dda", tick=1e-4),
])
def test_every_program_made_from_a_path_names_its_segments(plan):
    path = spun_up_path()
    program = plan(path)
    assert program.segment_names == path.segment_names()
    moving = np.unique(program.segment)
    assert set(moving.tolist()) <= set(range(len(path)))
    assert describe_segment(2, program.segment_names) == "segment 3 (row 2)"


@pytest.mark.parametrize("type_id, params, port", [
    ("interp.time_division", {"profile": "trapezoid"}, "trajectory"),
    ("interp.point_by_point", {}, "steps"),
    ("interp.dda", {}, "steps"),
    ("plan.lookahead", {}, "trajectory"),
    ("plan.stop_and_go", {}, "trajectory"),
])
def test_interpolator_and_planner_nodes_fill_the_names(type_id, params, port):
    g = flowmc.GraphBuilder()
    table = g.add("path.segment_table", id="table", rows=ROWS, feed=20.0)
    node = g.add(type_id, id="node", **params)
    g.wire(table.path, node.path)
    result = flowmc.run(g.build())
    assert result.ok, result.errors
    assert result.nodes["node"].outputs[port].segment_names == ("row 1", "row 2", "row 3")


def test_the_nurbs_interpolator_names_its_curve():
    g = flowmc.GraphBuilder()
    g.add("interp.nurbs", id="interp", control_points=[[0, 0, 0], [5, 5, 0], [10, 0, 0], [15, 5, 0]])
    result = flowmc.run(g.build())
    assert result.ok, result.errors
    traj = result.nodes["interp"].outputs["trajectory"]
    assert traj.segment_names == ("node interp",)
    assert set(traj.segment.tolist()) == {0}


def test_an_interpolator_names_both_sides_of_a_gap_as_users_count_them():
    g = flowmc.GraphBuilder()
    interp = g.add("interp.time_division", id="interp")
    g.input("path", "Path", interp.path)
    gap = Path([Line((0, 0, 0), (10, 0, 0), source="part.ngc:3"), Line((10, 1, 0), (20, 1, 0), source="part.ngc:4")])
    result = flowmc.run(g.build(), inputs={"path": gap})
    assert result.nodes["interp"].error == ("node 'interp': segment 2 (part.ngc:4): does not start where "
                                            "segment 1 (part.ngc:3) ends")
