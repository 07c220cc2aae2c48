"""Where a rapid meets a feed move the tool rests, on LinuxCNC and in flowmc's plan alike.

LinuxCNC's planner does not blend a traverse into a feed move or back, even under G64 P (on 3dtest.ngc
its speed falls to 0.02-0.15 mm/s, one servo period from rest, at each of the 18 such junctions), so
flowmc stops there too and the feed times of the two stay comparable; a corner between two feed moves is
blended by both.
"""

import numpy as np
import pytest

from flowmc.devices.linuxcnc.backend import run_program
from flowmc.motion.gcode import parse_gcode
from flowmc.motion.gcode_write import path_to_gcode
from flowmc.motion.planner import plan_smooth
from linuxcnc_programs import TOL, machine

pytestmark = pytest.mark.linuxcnc

PROGRAM = """G21 G90 G17
G0 X20 Y0 Z0
G1 Y20 F3000
G1 X40
G0 Z10
M2
"""
RAPID_IN, FEED_CORNER, RAPID_OUT = (20.0, 0.0, 0.0), (20.0, 20.0, 0.0), (40.0, 20.0, 0.0)


def slowest_near(positions: np.ndarray, period: float, point, radius: float = 0.2) -> float:
    """The least path speed (mm/s) over the periods that start within ``radius`` of ``point``."""
    speed = np.linalg.norm(np.diff(positions, axis=0), axis=1) / period
    near = np.linalg.norm(positions[:-1] - np.asarray(point), axis=1) <= radius
    assert near.any(), f"the tool never came within {radius} mm of {point}"
    return float(speed[near].min())


def test_a_rapid_feed_junction_is_a_stop_on_both_sides_and_a_feed_corner_a_blend():
    path = parse_gcode(PROGRAM, rapid_feed=200.0)
    ours = plan_smooth(path, machine(), tolerance=TOL).trajectory
    run = run_program(path_to_gcode(path, blend_tolerance=TOL), machine(), name="junctions.ngc")
    for name, positions, period in (("flowmc", ours.positions, ours.period),
                                    ("LinuxCNC", run.samples, run.servo_period)):
        assert slowest_near(positions, period, RAPID_IN) < 0.5, name
        assert slowest_near(positions, period, RAPID_OUT) < 0.5, name
        assert slowest_near(positions, period, FEED_CORNER) > 2.0, name
