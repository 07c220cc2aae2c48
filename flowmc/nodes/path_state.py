"""Set the tool state a path carries (spindle, pen, feed) and the moves around it (spin-up dwell, pen-up approach).

Planners turn this state into timed signals with one rule (flowmc.motion.signals), so a spindle or a
pen set here reaches every device the same way.
"""

# No ``from __future__ import annotations``: pydantic would compile every model field's annotation from
# its text when a cold ``flowmc validate`` builds the models (docs/architecture.md).
from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

from flowmc.errors import PathError
from flowmc.registry import In, NodeType, Out, register

_PATH_IN = In("path", "Path", doc="Path to change")
_PATH_OUT = Out("path", "Path", doc="The changed path")


class StateParams(BaseModel):
    model_config = ConfigDict(extra="forbid", defer_build=True)

    spindle_rpm: Annotated[float | None, Field(ge=-24000, le=24000, description="Spindle speed on every segment "
                                               "(+ cw, - ccw, 0 off; empty: keep)", json_schema_extra={"unit": "rpm"})] = None
    spin_up_s: Annotated[float, Field(ge=0, le=60, description="Dwell at the start so the spindle reaches speed",
                                      json_schema_extra={"unit": "s"})] = 0.0
    feed: Annotated[float | None, Field(gt=0, description="Feed of every cutting segment (empty: keep)",
                                        json_schema_extra={"unit": "mm/s"})] = None


@register
class SetState(NodeType):
    type_id = "path.set_state"
    title = "Spindle and feed"
    category = "Path"
    description = "Set the spindle speed and feed along a path, with a spin-up dwell before it starts."
    Params = StateParams
    inputs = (_PATH_IN,)
    outputs = (_PATH_OUT,)

    def run(self, ctx, params: StateParams, path):
        from flowmc.motion.path import Dwell, Path

        if not len(path):
            raise PathError("the path is empty", where=f"node {ctx.node_id}")
        out = path.with_feed(params.feed) if params.feed is not None else path
        if params.spindle_rpm is not None:
            out = Path(seg.with_state(spindle=params.spindle_rpm) for seg in out)
        if params.spin_up_s > 0:
            first = out.segments[0]
            wait = Dwell(out.start, params.spin_up_s, spindle=first.spindle, tool_down=False,
                         source=f"node {ctx.node_id}: spin-up")
            out = Path((wait,) + out.segments)
        return {"path": out}


class ApproachParams(BaseModel):
    model_config = ConfigDict(extra="forbid", defer_build=True)

    x: Annotated[float, Field(description="Where the pen is before the move", json_schema_extra={"unit": "mm"})] = 0.0
    y: Annotated[float, Field(description="Where the pen is before the move", json_schema_extra={"unit": "mm"})] = 0.0
    z: Annotated[float, Field(description="Where the pen is before the move", json_schema_extra={"unit": "mm"})] = 0.0
    rapid_feed: Annotated[float, Field(gt=0, description="Feed of the pen-up move",
                                       json_schema_extra={"unit": "mm/s"})] = 100.0


@register
class Approach(NodeType):
    type_id = "path.approach"
    title = "Pen up, rapid, pen down"
    category = "Path"
    description = "Lift the pen, rapid from a point to the path's start, then draw the path with the pen down."
    Params = ApproachParams
    inputs = (_PATH_IN,)
    outputs = (_PATH_OUT,)

    def run(self, ctx, params: ApproachParams, path):
        from flowmc.motion.path import Line, Path

        if not len(path):
            raise PathError("the path is empty", where=f"node {ctx.node_id}")
        here = (params.x, params.y, params.z)
        drawn = Path(seg if seg.rapid else seg.with_state(tool_down=True) for seg in path)
        move = Line(here, path.start, feed=params.rapid_feed, rapid=True, tool_down=False,
                    source=f"node {ctx.node_id}: pen-up move")
        return {"path": Path((move,) + drawn.segments)}
