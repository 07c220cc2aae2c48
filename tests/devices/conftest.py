"""Device test fixtures: a machine at T = 1 ms and a GRBL protocol simulator per test."""

import pytest

from flowmc.devices.grbl_sim import GrblSimulator
from flowmc.motion.machine import Machine


@pytest.fixture
def machine() -> Machine:
    return Machine(period=0.001)


@pytest.fixture
def grbl_sim():
    """Start a GRBL protocol simulator on a pty; ``grbl_sim(**options)`` returns it, stopped after the test."""
    started = []

    def start(**options) -> GrblSimulator:
        sim = GrblSimulator(idle_timeout=20.0, lifetime=120.0, **options)
        sim.start()
        started.append(sim)
        return sim

    yield start
    for sim in started:
        sim.stop()
