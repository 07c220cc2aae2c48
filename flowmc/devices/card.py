"""The one motion-card interface every backend implements (``flowmc.devices.backends`` opens them).

Every operation that moves or sets something returns the ``DeviceLog`` of what the device did.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from flowmc.devices.log import DeviceLog
from flowmc.devices.preflight import PreflightReport, preflight
from flowmc.devices.ranges import CARD_6050, CardRanges
from flowmc.errors import DeviceError
from flowmc.motion.machine import Machine
from flowmc.motion.trajectory import Signal, Steps, Trajectory

__all__ = ["MotionCard", "HOME_METHODS"]

#: ``switch``: the thesis's procedure (to the home switch at V1, off it at V2, a set distance more,
#: zero). ``midpoint``: the XY plotter report's (find both limits, zero halfway between them).
HOME_METHODS = ("switch", "midpoint")


class MotionCard(ABC):
    """A motion card: runs programs, homes, jogs, stops, and drives I/O. Positions are mm per machine axis."""

    spec: str = ""
    machine: Machine
    ranges: CardRanges = CARD_6050

    def connect(self) -> None:
        """Open the connection (a no-op where there is none)."""
        return None

    def close(self) -> None:
        """Release the connection; safe to call twice."""
        return None

    def __enter__(self) -> "MotionCard":  # open_device has connected it already
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def check(self, motion: Trajectory | Steps, signals: Signal | None = None) -> PreflightReport:
        """Pre-flight against this card's machine and output ranges; raises LimitError."""
        return preflight(motion, self.machine, signals, ranges=self.ranges)

    def check_program(self, motion: Trajectory | Steps, signals: Signal | None = None) -> PreflightReport:
        """Everything this card can say against a program before it runs, without connecting: the
        pre-flight, and what the card refuses of its signals (a job is prepared with this)."""
        return self.check(motion, signals)

    @abstractmethod
    def run(self, motion: Trajectory | Steps, signals: Signal | None = None, *, check: bool = True) -> DeviceLog:
        """Execute a program (after pre-flight unless ``check=False``) and return the log."""

    @abstractmethod
    def home(self, axes: tuple[str, ...] | None = None, method: str = "switch") -> DeviceLog:
        """Home the named axes (all when None), one after another."""

    @abstractmethod
    def jog(self, axis: str, distance: float, speed: float) -> DeviceLog:
        """Move one axis by ``distance`` mm at up to ``speed`` mm/s."""

    @abstractmethod
    def estop(self) -> DeviceLog:
        """Stop every axis at once and latch the stop."""

    def reset(self) -> DeviceLog:
        """Clear a latched e-stop or alarm once its cause is gone (DeviceError while it is not).

        Backends that latch override this; the default says the device has no reset.
        """
        raise DeviceError(f"{type(self).__name__} has no reset", where=self.spec or "device")

    @abstractmethod
    def set_output(self, channel: int, on: bool) -> DeviceLog:
        """Set digital output ``channel`` (from 1)."""

    @abstractmethod
    def read_inputs(self) -> dict[int, bool]:
        """Digital input levels by channel (from 1); True is closed."""

    @abstractmethod
    def set_pwm(self, freq: float, duty: float) -> DeviceLog:
        """PWM frequency (Hz) and duty (%)."""

    @abstractmethod
    def set_da(self, volts: float) -> DeviceLog:
        """Analog output voltage."""

    @abstractmethod
    def set_spindle(self, rpm: float) -> DeviceLog:
        """Spindle speed, signed: + clockwise (M3), - counter-clockwise (M4), 0 stops it."""

    @abstractmethod
    def position(self) -> np.ndarray:
        """Axis positions in mm, in machine axis order."""

    @abstractmethod
    def status(self) -> dict:
        """A small JSON-able dict: position, state, I/O, whatever the device reports."""

    def input_names(self) -> dict[int, str]:
        """What is wired to digital inputs, by channel (``{9: "X +lim"}``), for status displays; {} when unknown."""
        return {}

    def snapshot(self) -> DeviceLog:
        """The device now, as a one-row log (nothing moves)."""
        pos = self.position()
        return DeviceLog(self.spec, self.machine.names, 0.0, [0.0], np.zeros((1, len(pos)), dtype=np.int32),
                         pos[None, :], state=self.status())
