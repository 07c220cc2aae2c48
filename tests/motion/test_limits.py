"""One machine-limits module, and one meaning of a rapid's feed for every planner and interpolator."""

import math

import numpy as np
import pytest

from flowmc.errors import PlanningError
from flowmc.motion.interpolation import time_division
from flowmc.motion.limits import AxisLimits, PathLimits, axis_limits
from flowmc.motion.lookahead import plan_lookahead, plan_stop_and_go
from flowmc.motion.machine import Axis, Machine
from flowmc.motion.path import Line, Path

MACHINE = Machine(axes=(Axis(name="X", vmax=200, amax=200, jmax=5000), Axis(name="Y", vmax=120, amax=150, jmax=4000),
                        Axis(name="Z", min=-50, max=50, vmax=50, amax=100, jmax=1000)), period=0.001)


def test_axis_limits_by_name_in_the_order_asked():
    lim = AxisLimits.of(MACHINE, ("y", "X"))
    assert lim.vmax.tolist() == [120, 200] and lim.amax.tolist() == [150, 200] and lim.jmax.tolist() == [4000, 5000]
    assert axis_limits(MACHINE, ("Z",), "jmax").tolist() == [1000]
    with pytest.raises(ValueError, match="not machine axes"):
        AxisLimits.of(MACHINE, ("A",))


def test_path_limits_along_a_direction_are_per_axis():
    lim = PathLimits.of(MACHINE)
    u = np.array([[1.0, 0, 0], [0, 1.0, 0], [math.sqrt(0.5), math.sqrt(0.5), 0]])
    v, a, j = lim.along(u)
    assert v.tolist() == pytest.approx([200, 120, 120 * math.sqrt(2)])
    assert a.tolist() == pytest.approx([200, 150, 150 * math.sqrt(2)])
    assert lim.smallest() == (50.0, 100.0, 1000.0)
    xy = PathLimits.of(Machine(axes=(Axis(name="X"), Axis(name="Y"))))
    assert xy.cols == (0, 1) and math.isinf(xy.vmax[2])
    with pytest.raises(PlanningError, match="none of the axes"):
        PathLimits.of(Machine(axes=(Axis(name="A"),)))


def _rapid_path(feed: float) -> Path:
    return Path([Line((0, 0, 0), (150, 150, 0), feed=feed, rapid=True, tool_down=False),
                 Line((150, 150, 0), (150, 150, -10), feed=feed, rapid=True, tool_down=False)])


@pytest.mark.parametrize("planner", ["lookahead", "stop_and_go", "time_division"])
def test_a_rapid_moves_at_most_at_its_feed_along_the_path_and_each_axis_within_vmax(planner):
    machine = Machine(period=0.001)  # 200 mm/s on every axis: a diagonal could go 283 mm/s
    for feed in (200.0, 90.0):
        path = _rapid_path(feed)
        if planner == "lookahead":
            traj = plan_lookahead(path, machine).trajectory
        elif planner == "stop_and_go":
            traj = plan_stop_and_go(path, machine).trajectory
        else:
            traj = time_division(path, machine, profile="trapezoid").trajectory
        speed = traj.speed()
        v, _, _ = traj.derivatives()
        assert speed.max() <= feed * (1 + 1e-9)
        assert speed.max() >= 0.95 * feed  # it does reach its rapid rate on the 212 mm diagonal
        assert np.abs(v).max(axis=0).max() <= 200.0 * (1 + 1e-9)
