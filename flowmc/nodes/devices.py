"""Device nodes: the machine's limits, pre-flight, card output, homing, jogging, I/O now and waiting for an input.

The signal nodes that feed Card output and I/O now (Digital I/O, PWM, Analog/spindle) are in
``flowmc.nodes.signals``.

Nodes that drive a device (Card output, Home, Jog, I/O now) run in two phases: when the graph runs
they only prepare a job (pre-flighted; nothing opens, nothing moves) and are *ready*; an explicit
Start (the editor's button, ``flowmc run``) hands the job to a ``JobRunner``. Their optional
``after`` input takes the log of an earlier device node: it orders them (Home, Jog, then Card
output), only Start needs it, and the simulated card carries on from the state that log ends in.
"""

# No ``from __future__ import annotations``: pydantic would compile every model field's annotation from
# its text when a cold ``flowmc validate`` builds the models (docs/architecture.md).
from dataclasses import replace
from typing import TYPE_CHECKING, Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from flowmc.errors import DeviceError
from flowmc.motion.machine import Axis, Machine, default_machine
from flowmc.registry import In, NodeType, Out, register

if TYPE_CHECKING:  # the backends, the job machinery and numpy are imported when a node runs:
    from flowmc.devices.backends import DeviceOptions  # `flowmc validate` (params and ports only) stays light
    from flowmc.devices.jobs import Job
    from flowmc.devices.log import DeviceLog

_MOTION_IN = In("motion", ("Trajectory", "Steps"), doc="The program: setpoints or a step stream")
_MACHINE_IN = In("machine", "Machine", doc="Axis limits and period (default: the default machine)", default=None)
_SIGNALS_IN = In("signals", "Signal", doc="I/O events to send with the program", default=None)
_AFTER_IN = In("after", "Log", doc="Run after this device log (the sim carries on from its end state)",
               default=None)
_LOG_OUT = Out("log", "Log", doc="What the device did, per period")


class _Params(BaseModel):
    model_config = ConfigDict(extra="forbid", defer_build=True)


class _DeviceParams(_Params):
    device: Annotated[str, Field(description="sim, grbl:<serial port> or linuxcnc")] = "sim"
    closed_loop: Annotated[bool, Field(description="Simulated card: PID position loop on a first-order motor")] = False
    estop_input: Annotated[int, Field(ge=0, le=8, description="Simulated card: e-stop input 1-8 (0: none)")] = 0
    analog: Annotated[Literal["da", "pwm"], Field(description="Simulated card: what the shared PWM/DA "
                                                                 "terminal gives")] = "da"

    @field_validator("device")
    @classmethod
    def _known(cls, spec: str) -> str:
        from flowmc.devices.backends import check_spec  # the backends list: when a graph names a device

        try:
            check_spec(spec)
        except DeviceError as err:
            raise ValueError(err.message) from None
        return spec.strip()


def _machine_for(machine: Machine | None, motion=None) -> Machine:
    if machine is not None:
        return machine
    from flowmc.motion.trajectory import Trajectory

    if isinstance(motion, Trajectory):
        return default_machine(period=motion.period)
    return default_machine()


def _options(params: _DeviceParams) -> "DeviceOptions":
    """The device's options from the node's params (the state to resume from comes at Start)."""
    from flowmc.devices.backends import DeviceOptions, GrblOptions, SimOptions

    card = params if isinstance(params, CardOutputParams) else None  # only Card output drives a pen
    return DeviceOptions(
        sim=SimOptions(closed_loop=params.closed_loop, estop_input=params.estop_input or None, analog=params.analog,
                       pen_output=(card.pen_output or None) if card else None),
        grbl=GrblOptions(card.grbl_pen_down, card.grbl_pen_up) if card else GrblOptions())


def _report(ctx, log: "DeviceLog") -> None:
    for event in log.events:
        ctx.log(f"{event.kind} at t={event.t:.3f} s{' ' + event.axis if event.axis else ''}: {event.message}")
    if log.outcome != "done":
        ctx.log(f"stopped: {log.outcome}")


class _DeviceNode(NodeType):
    """A node that drives a device: ``prepare`` makes its job when the graph runs; ``start`` runs it at Start."""

    pure = False
    moves = True
    start_inputs = ("after",)

    def start(self, ctx, job: "Job", after: "DeviceLog | None" = None) -> dict:
        try:
            from flowmc.devices.jobs.prepare import start_job

            runner = start_job(job, after, ctx.start, ctx.node_id)
        except DeviceError as err:
            if err.log is not None:
                _report(ctx, err.log)
            raise
        log = runner.log
        assert log is not None  # a runner that ended without a fault has its log
        _report(ctx, log)
        return {"log": log, **{name: float(value) for name, value in runner.extra.items()}}


# ---------------------------------------------------------------- machine

class MachineParams(_Params):
    axes: Annotated[list[Axis], Field(min_length=1, max_length=4,
                                      description="One row per axis: name, soft limits, vmax, amax, jmax, "
                                                  "pulse equivalent, max step rate")] = \
        [Axis(name="X"), Axis(name="Y"), Axis(name="Z", min=-50.0, max=50.0)]
    period: Annotated[float, Field(gt=0, le=0.1, description="Interpolation period T",
                                   json_schema_extra={"unit": "s"})] = 0.004

    @field_validator("axes")
    @classmethod
    def _unique_names(cls, axes: list[Axis]) -> list[Axis]:  # checked when the graph is validated, not at run time
        names = [a.name for a in axes]
        if len(set(names)) != len(names):
            raise ValueError(f"axis names must be unique, got {names}")
        return axes


@register
class MachineNode(NodeType):
    type_id = "machine"
    title = "Machine limits"
    category = "Devices"
    description = "The machine's axes (soft limits, velocity, acceleration, jerk, pulse equivalent, step rate) and T."
    Params = MachineParams
    outputs = (Out("machine", "Machine", doc="Axis limits and period"),)

    def run(self, ctx, params: MachineParams):
        return {"machine": Machine(axes=tuple(params.axes), period=params.period)}


# ---------------------------------------------------------------- pre-flight

class PreflightParams(_Params):
    analog: Annotated[Literal["da", "pwm", "both"], Field(description="What the PWM/DA terminal gives")] = "da"


@register
class PreflightNode(NodeType):
    type_id = "device.preflight"
    title = "Pre-flight"
    category = "Devices"
    description = "Check a program against soft limits, velocity, acceleration, step rate and output ranges."
    pure = False  # a check: always run, so its verdict is never a stale cache entry
    Params = PreflightParams
    inputs = (_MOTION_IN, _SIGNALS_IN, _MACHINE_IN)
    outputs = (Out("report", "Table", doc="Per axis: travel, peak velocity, acceleration, step rate, limits"),)

    def run(self, ctx, params: PreflightParams, motion, signals=None, machine=None):
        machine = _machine_for(machine, motion)
        from flowmc.devices.preflight import preflight
        from flowmc.devices.ranges import CARD_6050

        report = preflight(motion, machine, signals, ranges=CARD_6050.with_analog(params.analog))
        return {"report": report.table(machine)}


# ---------------------------------------------------------------- card output, homing and jogging

class CardOutputParams(_DeviceParams):
    pen_output: Annotated[int, Field(ge=0, le=8, description="Simulated card: digital output the program's "
                                                             "tool (pen) state drives, on = down (0: none, as on a mill)")] = 0
    grbl_pen_down: Annotated[str, Field(description="GRBL: command for tool (pen) down (the pen on the "
                                                    "spindle output, e.g. M3 S1000; empty: no pen)")] = ""
    grbl_pen_up: Annotated[str, Field(description="GRBL: command for tool (pen) up, e.g. M5")] = ""
    safe_outputs_on: Annotated[list[int], Field(description="Digital outputs that stay on when a job is stopped, "
                                                            "e-stopped or faults (a brake release, a clamp); every "
                                                            "other output, the spindle, PWM and the pen go off")] = []


@register
class CardOutput(_DeviceNode):
    type_id = "device.card_output"
    title = "Card output"
    category = "Devices"
    description = "Check a program (pre-flight) as a job for a motion card; Start sends it and returns what the card did."
    Params = CardOutputParams
    inputs = (_MOTION_IN, _SIGNALS_IN, _MACHINE_IN, _AFTER_IN)
    outputs = (_LOG_OUT,)

    def prepare(self, ctx, params: CardOutputParams, motion, signals=None, machine=None) -> "Job":
        machine = _machine_for(machine, motion)
        from flowmc.devices.jobs import SafeOutputs
        from flowmc.devices.jobs.prepare import program_job

        job = program_job(params.device, machine, motion, signals, _options(params),
                          safe=SafeOutputs(tuple(params.safe_outputs_on)), name=ctx.node_id)
        ctx.log(f"ready: {job.describe()}; pre-flight passed")
        return job


class HomeParams(_DeviceParams):
    axes: Annotated[str, Field(description="Axes to home in order, e.g. 'ZXY' (empty: all)")] = ""
    method: Annotated[Literal["switch", "midpoint"],
                      Field(description="switch: the thesis's V1/V2 procedure; midpoint: between the limits")
                      ] = "switch"


@register
class Home(_DeviceNode):
    type_id = "device.home"
    title = "Home"
    category = "Devices"
    description = "Home axes on a device (home switch, or midway between the limit switches) and zero them."
    Params = HomeParams
    inputs = (_MACHINE_IN, _AFTER_IN)
    outputs = (_LOG_OUT,)

    def prepare(self, ctx, params: HomeParams, machine=None) -> "Job":
        axes = tuple(params.axes.replace(",", "").replace(" ", "").upper()) or None
        from flowmc.devices.jobs.prepare import home_job

        return home_job(params.device, _machine_for(machine), axes, params.method, _options(params), name=ctx.node_id)


class JogParams(_DeviceParams):
    axis: Annotated[str, Field(min_length=1, description="The axis to jog, e.g. X")] = "X"
    distance: Annotated[float, Field(description="How far, signed", json_schema_extra={"unit": "mm"})] = 10.0
    speed: Annotated[float, Field(gt=0, description="Top speed (the move ramps at the axis's amax)",
                                  json_schema_extra={"unit": "mm/s"})] = 10.0


@register
class Jog(_DeviceNode):
    type_id = "device.jog"
    title = "Jog"
    category = "Devices"
    description = "Move one axis of a device by a distance at a speed (e.g. to set the table before drawing)."
    Params = JogParams
    inputs = (_MACHINE_IN, _AFTER_IN)
    outputs = (_LOG_OUT,)

    def prepare(self, ctx, params: JogParams, machine=None) -> "Job":
        from flowmc.devices.jobs.prepare import jog_job

        return jog_job(params.device, _machine_for(machine), params.axis.strip().upper(), params.distance, params.speed,
                       _options(params), name=ctx.node_id)


# ---------------------------------------------------------------- I/O now

@register
class IONow(_DeviceNode):
    type_id = "device.io_now"
    title = "I/O now"
    category = "Devices"
    description = "Set outputs on a device at once (events in time order, times ignored) and read its inputs."
    Params = _DeviceParams
    inputs = (In("signals", "Signal", doc="Outputs to set", default=None), _MACHINE_IN, _AFTER_IN)
    outputs = (_LOG_OUT, Out("inputs", "Number", doc="Input levels as a bit mask: bit n-1 is input n"))

    def prepare(self, ctx, params: _DeviceParams, signals=None, machine=None) -> "Job":
        from flowmc.devices.jobs.prepare import io_job
        from flowmc.motion.trajectory import Signal

        return io_job(params.device, _machine_for(machine), signals if signals is not None else Signal(),
                      _options(params), name=ctx.node_id)


# ---------------------------------------------------------------- wait for an input

class WaitInputParams(_DeviceParams):
    input: Annotated[int, Field(ge=1, le=20, description="Digital input 1-20 (on the simulated card 9-20 are the "
                                                         "axes' limit and home switches)")] = 1
    on: Annotated[bool, Field(description="Wait for the input on (closed); off: wait for it open")] = True
    timeout: Annotated[float, Field(ge=0, le=86_400, description="Fail when it has not come by then",
                                    json_schema_extra={"unit": "s"})] = 10.0
    name: Annotated[str, Field(max_length=40, description="What the input is, for messages (e.g. clamp)")] = ""
    fail_on_timeout: Annotated[bool, Field(description="A timeout fails the node (off: 'came' says whether the "
                                                        "input came, for a Case to branch on)")] = True
    sim_after: Annotated[float | None, Field(ge=0, description="Simulated card: the world outside sets the input "
                                                               "this many seconds after the wait begins (empty: "
                                                               "never, and the wait times out)",
                                             json_schema_extra={"unit": "s"})] = None


@register
class WaitInput(_DeviceNode):
    type_id = "device.wait_input"
    title = "Wait for input"
    category = "Devices"
    description = ("At Start, wait until a digital input is on (or off), at most a timeout; gives the time waited "
                   "or fails naming the input. Order it with 'after' wires.")
    moves = True  # it moves nothing, but it waits on a device: only Start runs it
    Params = WaitInputParams
    inputs = (_MACHINE_IN, _AFTER_IN)
    outputs = (_LOG_OUT, Out("waited", "Number", doc="Seconds waited (s)"),
               Out("came", "Bool", doc="Whether the input came before the timeout"))

    def prepare(self, ctx, params: WaitInputParams, machine=None) -> "Job":
        from flowmc.devices.jobs.prepare import wait_job

        options = _options(params)
        if params.sim_after is not None:
            world = ((params.sim_after, params.input, params.on),)
            options = replace(options, sim=replace(options.sim, inputs=world))
        job = wait_job(params.device, _machine_for(machine), params.input, params.on, params.timeout, params.name,
                       options, required=params.fail_on_timeout, name=ctx.node_id)
        ctx.log(f"ready: {job.describe()}, at most {params.timeout:g} s")
        return job

    def start(self, ctx, job: "Job", after: "DeviceLog | None" = None) -> dict:
        outputs = super().start(ctx, job, after)
        return {**outputs, "came": bool(outputs["came"])}
