"""Which motion cards exist, and ``open_device`` that opens one from a spec string.

Specs: ``"sim"`` (the simulated 6050 card, the default), ``"grbl:<serial port>"``, ``"grbl-sim"`` (the
GRBL streamer against the protocol simulator) and ``"linuxcnc"``. ``register_backend`` adds one.
A backend's module is imported only when its spec is opened.

What a caller wants of a card it does not choose (a device node, whose ``device`` param may name any
backend) travels as ``DeviceOptions``: one typed section per backend kind, plus the state an
earlier log ended in. Each backend reads its own section and takes ``resume`` only from a log of its
own kind, so callers never branch on backend names. Keyword arguments go to the backend's card as
they are, for callers that know which card they open.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable, Mapping

from flowmc.errors import DeviceError
from flowmc.motion.machine import Machine

if TYPE_CHECKING:  # the card interface (numpy, pre-flight) comes with the backend that opens one
    from flowmc.devices.card import MotionCard

__all__ = ["DeviceOptions", "SimOptions", "GrblOptions", "open_device", "unconnected", "check_spec",
           "register_backend", "known_devices"]


@dataclass(frozen=True)
class SimOptions:
    """The simulated card's wiring: PID loop, e-stop input, the shared PWM/DA terminal, the pen output."""

    closed_loop: bool = False
    estop_input: int | None = None  # digital input 1-8 wired to the e-stop
    analog: str = "da"  # what the shared PWM/DA terminal gives: "da" or "pwm"
    pen_output: int | None = None  # digital output the program's tool (pen) state drives
    inputs: tuple[tuple[float, int, bool], ...] = ()  # the world outside: (s after opening, input, closed)


@dataclass(frozen=True)
class GrblOptions:
    """GRBL's pen: the commands that put the tool down and lift it (empty: no pen)."""

    pen_down: str = ""
    pen_up: str = ""

    @property
    def pen(self) -> tuple[str, str] | None:
        pen = (self.pen_down.strip(), self.pen_up.strip())
        return pen if any(pen) else None


@dataclass(frozen=True)
class DeviceOptions:
    """Options for whichever card a spec opens; ``resume``: the state a previous device log ended in."""

    sim: SimOptions = field(default_factory=SimOptions)
    grbl: GrblOptions = field(default_factory=GrblOptions)
    resume: Mapping[str, Any] | None = None

    def resume_for(self, kind: str) -> dict[str, Any] | None:
        """``resume`` when it came from a card of this kind, else None."""
        return dict(self.resume) if self.resume and self.resume.get("device") == kind else None


Factory = Callable[..., "MotionCard"]  # factory(argument, machine, options, **kwargs)


def _no_argument(name: str, argument: str) -> None:
    if argument:
        raise DeviceError(f"'{name}' takes no argument, got '{name}:{argument}'", where="device")


def _open_sim(argument: str, machine: Machine, options: DeviceOptions, **kwargs: Any) -> MotionCard:
    from flowmc.devices.sim import SimCard

    _no_argument("sim", argument)
    sim = options.sim
    settings = {"closed_loop": sim.closed_loop, "estop_input": sim.estop_input, "analog": sim.analog,
                "pen_output": sim.pen_output, "state": options.resume_for("sim")}
    card = SimCard(machine, **{**settings, **kwargs})
    for t, channel, closed in sim.inputs:
        card.schedule_input(card.clock + t, channel, closed)
    return card


def _open_grbl(argument: str, machine: Machine, options: DeviceOptions, **kwargs: Any) -> MotionCard:
    from flowmc.devices.grbl import GrblCard

    if not argument:
        raise DeviceError("say which serial port: 'grbl:/dev/ttyUSB0'", where="device")
    return GrblCard(argument, machine, **{"pen": options.grbl.pen, **kwargs})


def _open_grbl_sim(argument: str, machine: Machine, options: DeviceOptions, **kwargs: Any) -> MotionCard:
    from flowmc.devices.grbl_sim_card import SimulatedGrblCard

    _no_argument("grbl-sim", argument)
    return SimulatedGrblCard(machine, **{"pen": options.grbl.pen, **kwargs})


def _open_linuxcnc(argument: str, machine: Machine, options: DeviceOptions, **kwargs: Any) -> MotionCard:
    try:
        from flowmc.devices.linuxcnc.card import LinuxCNCCard
    except ModuleNotFoundError as exc:
        raise DeviceError(f"the linuxcnc backend is not installed ({exc.name} is missing)", where="device") from None
    _no_argument("linuxcnc", argument)
    return LinuxCNCCard(machine, **kwargs)


_BACKENDS: dict[str, Factory] = {"sim": _open_sim, "grbl": _open_grbl, "grbl-sim": _open_grbl_sim,
                                 "linuxcnc": _open_linuxcnc}
_SPEC_HELP = {"sim": "sim", "grbl": "grbl:<serial port>", "grbl-sim": "grbl-sim", "linuxcnc": "linuxcnc"}


def register_backend(name: str, factory: Factory, help: str | None = None) -> None:
    """Add (or replace) a backend: ``factory(argument, machine, options: DeviceOptions, **kwargs) -> MotionCard``."""
    _BACKENDS[name] = factory
    _SPEC_HELP[name] = help or name


def known_devices() -> list[str]:
    """Device specs ``open_device`` understands, as shown in error messages and the editor."""
    return [_SPEC_HELP[k] for k in sorted(_BACKENDS)]


def check_spec(spec: str) -> None:
    """DeviceError unless ``spec`` names a known backend (nothing is opened or imported)."""
    name = spec.strip().partition(":")[0] if isinstance(spec, str) else ""
    if name not in _BACKENDS:
        raise DeviceError(f"unknown device {spec!r}; known: {', '.join(known_devices())}", where="device")


def unconnected(spec: str, machine: Machine | None = None, options: DeviceOptions | None = None) -> MotionCard:
    """The card ``spec`` names, made but not connected: a job checks its program against it before
    anything is opened (the GRBL simulator is started, like a port opened, only on connect)."""
    check_spec(spec)
    name, _, argument = spec.strip().partition(":")
    if name == "grbl-sim":
        name, argument = "grbl", "grbl-sim"
    return _BACKENDS[name](argument, machine if machine is not None else Machine(), options or DeviceOptions())


def open_device(spec: str = "sim", machine: Machine | None = None, options: DeviceOptions | None = None,
                **kwargs: Any) -> MotionCard:
    """Open and connect the device named by ``spec``; DeviceError for an unknown spec (listing the known ones).

    >>> from flowmc.motion.machine import Machine
    >>> with open_device("sim", Machine()) as card:
    ...     card.position().tolist()
    [0.0, 0.0, 0.0]
    """
    check_spec(spec)
    name, _, argument = spec.strip().partition(":")
    card = _BACKENDS[name](argument, machine if machine is not None else Machine(), options or DeviceOptions(),
                           **kwargs)
    card.connect()
    return card
