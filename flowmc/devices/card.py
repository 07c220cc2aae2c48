"""The one motion-card interface, and ``open_device`` that picks a backend from a spec string.

Specs: ``"sim"`` (the simulated 6050 card, the default), ``"grbl:<serial port>"``, ``"grbl-sim"`` (the
GRBL streamer against the protocol simulator) and ``"linuxcnc"``
(or ``"linuxcnc:<argument>"``). Backends are factories in a small table; ``register_backend`` adds
one. The LinuxCNC backend lives in ``flowmc.devices.linuxcnc.backend`` and is imported only when a
``linuxcnc`` spec is opened; that module provides ``open_card(argument, machine, **options)``
returning a ``MotionCard``.

Every operation that moves or sets something returns the ``DeviceLog`` of what the device did.
"""

from __future__ import annotations

import importlib
from abc import ABC, abstractmethod
from typing import Callable

import numpy as np

from flowmc.devices.log import DeviceLog
from flowmc.devices.preflight import PreflightReport, preflight
from flowmc.devices.ranges import CARD_6050, CardRanges
from flowmc.errors import DeviceError
from flowmc.motion.machine import Machine
from flowmc.motion.trajectory import Signal, Steps, Trajectory

__all__ = ["MotionCard", "open_device", "check_spec", "register_backend", "known_devices", "HOME_METHODS"]

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

    def close(self) -> None:
        """Release the connection; safe to call twice."""

    def __enter__(self) -> "MotionCard":  # open_device has connected it already
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def check(self, motion: Trajectory | Steps, signals: Signal | None = None) -> PreflightReport:
        """Pre-flight against this card's machine and output ranges; raises LimitError."""
        return preflight(motion, self.machine, signals, ranges=self.ranges)

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


Factory = Callable[..., MotionCard]  # factory(argument, machine, **options)


def _open_sim(argument: str, machine: Machine, **options) -> MotionCard:
    from flowmc.devices.sim import SimCard

    if argument:
        raise DeviceError(f"'sim' takes no argument, got 'sim:{argument}'", where="device")
    return SimCard(machine, **options)


def _open_grbl(argument: str, machine: Machine, **options) -> MotionCard:
    from flowmc.devices.grbl import GrblCard

    if not argument:
        raise DeviceError("say which serial port: 'grbl:/dev/ttyUSB0'", where="device")
    return GrblCard(argument, machine, **options)


_BACKENDS: dict[str, Factory] = {"sim": _open_sim, "grbl": _open_grbl}
_LAZY_BACKENDS: dict[str, str] = {"linuxcnc": "flowmc.devices.linuxcnc.backend",
                                   "grbl-sim": "flowmc.devices.grbl_sim_card"}
_SPEC_HELP = {"sim": "sim", "grbl": "grbl:<serial port>", "grbl-sim": "grbl-sim", "linuxcnc": "linuxcnc"}


def register_backend(name: str, factory: Factory, help: str | None = None) -> None:
    """Add (or replace) a backend: ``factory(argument, machine, **options) -> MotionCard``."""
    _BACKENDS[name] = factory
    _SPEC_HELP[name] = help or name


def known_devices() -> list[str]:
    """Device specs ``open_device`` understands, as shown in error messages and the editor."""
    return [_SPEC_HELP[k] for k in sorted(set(_BACKENDS) | set(_LAZY_BACKENDS))]


def _backend(name: str) -> Factory:
    """The factory for a known backend name, importing a lazy backend on first use."""
    if name in _BACKENDS:
        return _BACKENDS[name]
    module_name = _LAZY_BACKENDS[name]
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        if exc.name and module_name.startswith(exc.name):
            raise DeviceError(f"the {name} backend is not installed ({module_name} is missing)",
                              where="device") from None
        raise DeviceError(f"the {name} backend cannot load: {exc}", where="device") from exc
    factory = getattr(module, "open_card", None)
    if factory is None:
        raise DeviceError(f"{module_name} has no open_card(argument, machine, **options)", where="device")
    return factory


def check_spec(spec: str) -> None:
    """DeviceError unless ``spec`` names a known backend (nothing is opened or imported)."""
    name = spec.strip().partition(":")[0] if isinstance(spec, str) else ""
    if name not in _BACKENDS and name not in _LAZY_BACKENDS:
        raise DeviceError(f"unknown device {spec!r}; known: {', '.join(known_devices())}", where="device")


def open_device(spec: str = "sim", machine: Machine | None = None, **options) -> MotionCard:
    """Open and connect the device named by ``spec``; DeviceError for an unknown spec (listing the known ones).

    Example
    -------
    >>> from flowmc.motion.machine import Machine
    >>> with open_device("sim", Machine()) as card:
    ...     card.position().tolist()
    [0.0, 0.0, 0.0]
    """
    check_spec(spec)
    name, _, argument = spec.strip().partition(":")
    factory = _backend(name)
    card = factory(argument, machine if machine is not None else Machine(), **options)
    card.connect()
    return card
