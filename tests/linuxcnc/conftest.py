"""One LinuxCNC run per reference program for the whole test session (each takes 5-15 s of machine time)."""

import pytest

from flowmc.devices.linuxcnc.backend import run_program
from flowmc.motion.gcode_write import path_to_gcode
from linuxcnc_programs import MEASURED, TOL, machine, reference_path, thesis_path


@pytest.fixture(scope="session")
def runs():
    out = {}
    for name in ["thesis", *MEASURED]:
        path = thesis_path() if name == "thesis" else reference_path(name)
        lines = []
        gcode = path_to_gcode(path, blend_tolerance=TOL)
        out[name] = (path, run_program(gcode, machine(), on_progress=lines.append), lines, gcode)
    return out
