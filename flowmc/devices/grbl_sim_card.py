"""The ``grbl-sim`` device: flowmc's GRBL streamer talking to the GRBL protocol simulator on a pty.

It lets a graph written for a GRBL board (the teaching machine's Arduino) run anywhere: the real
serial code path (pyserial, character counting, ok/error/ALARM parsing) against the simulator that
``flowmc.devices.grbl_sim`` documents. The simulator models the protocol, not motion timing, so a
log from it shows what GRBL acknowledged and where it says it is, not how it got there.
"""

from __future__ import annotations

from flowmc.devices.grbl import GrblCard
from flowmc.devices.grbl_sim import GrblSimulator
from flowmc.motion.machine import Machine

__all__ = ["SimulatedGrblCard"]


class SimulatedGrblCard(GrblCard):
    """A GrblCard whose port is a GRBL simulator started on connect and stopped on close."""

    def __init__(self, machine: Machine, **options):
        travel = tuple((a.min, a.max) for a in machine.axes[:3])
        travel += ((-200.0, 200.0),) * (3 - len(travel))
        self.simulator = GrblSimulator(travel=travel, line_time=0.0002, idle_timeout=30.0, lifetime=600.0)
        super().__init__(self.simulator.start(), machine, **options)
        self.spec = "grbl-sim"

    def close(self) -> None:
        try:
            super().close()
        finally:
            self.simulator.stop()
