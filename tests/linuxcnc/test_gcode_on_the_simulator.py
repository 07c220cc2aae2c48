"""Where rs274 and LinuxCNC's machine part ways, LinuxCNC's simulator says what the machine does.

rs274's stand-alone canon re-reads its position after a tool change without the tool length offset
set on the same line; LinuxCNC's task re-reads it with the offsets. A tool length offset set on the
line of an M6 therefore moves Z on the next X/Y move in rs274's listing, and not on the machine.
flowmc follows the machine (docs/gcode.md lists skeleton.ngc for this).
"""

import numpy as np
import pytest

from flowmc.devices.linuxcnc.backend import run_program
from flowmc.devices.linuxcnc.rs274 import run_rs274
from flowmc.motion.gcode import parse_gcode

pytestmark = pytest.mark.linuxcnc

PROGRAM = "G21 G90\nG0 X0 Y0 Z-10\nT1 M6 G43.1 Z5\nG0 X10\nG0 Y10\nM2\n"


def test_a_tool_length_offset_set_with_m6_does_not_move_z_on_the_machine():
    run = run_program(PROGRAM)
    z = run.samples[:, 2]
    reached = np.flatnonzero(np.isclose(z, -10.0, atol=1e-6))[0]
    assert np.allclose(z[reached:], -10.0, atol=1e-6)  # once down at -10, Z never moves again
    np.testing.assert_allclose(run.end_position[:3], [10, 10, -10], atol=1e-6)
    path = parse_gcode(PROGRAM, "t.ngc")
    moves = [s for s in path if s.kind == "line"]
    np.testing.assert_allclose([s.end[2] for s in moves], [-10, -10, -10])
    listing = run_rs274(PROGRAM).in_machine_coordinates()
    assert listing.end[1][2] == -5.0  # rs274's stand-alone listing moves Z by the offset instead
