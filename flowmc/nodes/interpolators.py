"""Step interpolator nodes: point-by-point comparison, DDA, and the two-axis linkage pulse table.

All three read the X and Y axes' pulse equivalents (``step_mm``) from the machine; the pulse table
also reads their ``max_step_rate``. The work is in flowmc.motion.path_steps and flowmc.motion.linkage.
"""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from flowmc.errors import NodeError
from flowmc.motion.linkage import path_linkage_table
from flowmc.motion.machine import Axis, Machine, default_machine
from flowmc.motion.path import Path
from flowmc.motion.path_steps import path_to_steps
from flowmc.motion.stepinterp import MAX_TICKS
from flowmc.registry import In, NodeType, Out, register

_MM = {"unit": "mm"}
_S = {"unit": "s"}

_PATH_IN = In("path", "Path", doc="Path to interpolate (its XY projection)")
_MACHINE_IN = In("machine", "Machine", doc="X and Y step_mm (default: the default machine)", default=None)
_STEPS_OUT = Out("steps", "Steps", doc="X and Y step streams, one row per tick")


def _xy_axes(machine: Machine | None) -> tuple[Axis, Axis]:
    axes = {a.name: a for a in (machine or default_machine()).axes}
    if "X" not in axes or "Y" not in axes:
        raise NodeError(f"the machine needs axes named X and Y, it has {', '.join(axes)}")
    return axes["X"], axes["Y"]


class _Params(BaseModel):
    model_config = ConfigDict(extra="forbid", defer_build=True)

    chord_tol: Annotated[float | None, Field(gt=0, description="Chord tolerance where curves are cut into chords "
                                                               "(empty: half a step)", json_schema_extra=_MM)] = None


class _StepParams(_Params):
    tick_s: Annotated[float, Field(ge=0, description="Time per tick (0: untimed, the device paces the steps)",
                                   json_schema_extra=_S)] = 0.0


def _log_steps(ctx, steps) -> None:
    pulses = np.count_nonzero(steps.steps, axis=0)
    ctx.log(f"{len(steps)} ticks, {pulses[0]} X and {pulses[1]} Y pulses")


@register
class PointByPointInterpolator(NodeType):
    type_id = "interp.point_by_point"
    title = "Point-by-point interpolator"
    category = "Interpolation"
    description = "Point-by-point comparison: one step per tick, lines, circles and ellipses within a step."
    Params = _StepParams
    inputs = (_PATH_IN, _MACHINE_IN)
    outputs = (_STEPS_OUT,)

    def run(self, ctx, params: _StepParams, path: Path, machine: Machine | None = None):
        x, y = _xy_axes(machine)
        steps = path_to_steps(path, (x.step_mm, y.step_mm), "pbp", chord_tol=params.chord_tol, tick=params.tick_s)
        _log_steps(ctx, steps)
        return {"steps": steps}


class DdaParams(_StepParams):
    bits: Annotated[int | None, Field(ge=1, le=MAX_TICKS.bit_length() - 1,
                                      description="Register size in bits (empty: sized per move)")] = None
    preset: Annotated[Literal["half", "zero"], Field(description="Accumulators start half full (rounds) or "
                                                                 "empty (the plain textbook register)")] = "half"


@register
class DdaInterpolator(NodeType):
    type_id = "interp.dda"
    title = "DDA interpolator"
    category = "Interpolation"
    description = "Digital differential analyser: n-bit accumulators, both axes may step on a tick."
    Params = DdaParams
    inputs = (_PATH_IN, _MACHINE_IN)
    outputs = (_STEPS_OUT,)

    def run(self, ctx, params: DdaParams, path: Path, machine: Machine | None = None):
        x, y = _xy_axes(machine)
        steps = path_to_steps(path, (x.step_mm, y.step_mm), "dda", bits=params.bits, preset=params.preset,
                              chord_tol=params.chord_tol, tick=params.tick_s)
        _log_steps(ctx, steps)
        return {"steps": steps}


@register
class LinkagePulseTable(NodeType):
    type_id = "interp.linkage_table"
    version = 2  # 2: the table's segment column counts from 1
    title = "Linkage pulse table"
    category = "Interpolation"
    description = "Per move: X/Y pulse counts, directions and frequencies so both axes arrive together."
    Params = _Params
    inputs = (_PATH_IN, _MACHINE_IN)
    outputs = (Out("table", "Table", doc="One row per move (arcs as chords), with its path segment number (from 1)"),
               Out("duration", "Number", doc="Total time of the rows (s)"))

    def run(self, ctx, params: _Params, path: Path, machine: Machine | None = None):
        x, y = _xy_axes(machine)
        table = path_linkage_table(path, (x.step_mm, y.step_mm), (x.max_step_rate, y.max_step_rate),
                                   params.chord_tol)
        limited = int(table["rate_limited"].sum())
        ctx.log(f"{len(table)} rows" + (f", {limited} slowed to the max step rate" if limited else ""))
        return {"table": table, "duration": float(table["duration_s"].sum())}
