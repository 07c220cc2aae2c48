"""The simulated 6050 card: the default device and the reference implementation of ``MotionCard``."""

from flowmc.devices.sim.card import SimCard
from flowmc.devices.sim.homing import HomingSettings
from flowmc.devices.sim.pid import LoopSettings
from flowmc.devices.sim.world import AxisSwitches

__all__ = ["SimCard", "HomingSettings", "LoopSettings", "AxisSwitches"]
