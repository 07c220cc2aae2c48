"""The 3D View node: a sink that names what the editor's docked 3D view shows.

Wire a Path, a Trajectory, a step stream and a device log into it (any of them), and a Machine for
the travel box. The editor's 3D view shows what the selected (or the only) 3D View node is wired to,
inside sub-graphs too; a graph may hold several. Running headless, the node does nothing; ``flowmc
run --snapshot DIR`` writes a PNG of each view (``flowmc.runtime.views``). Graphs without one keep the
editor's old behaviour (the view shows the run's most downstream values).
"""

# No ``from __future__ import annotations``: pydantic would compile every model field's annotation from
# its text when a cold ``flowmc validate`` builds the models (docs/architecture.md).
from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

from flowmc.registry import In, NodeType, register

__all__ = ["View3D", "ViewParams"]


class ViewParams(BaseModel):
    model_config = ConfigDict(extra="forbid", defer_build=True)

    title: Annotated[str, Field(description="Shown above the view (empty: the node's id)")] = ""
    travel_box: Annotated[bool, Field(description="Draw the machine's travel box when a Machine is wired")] = True
    tolerance: Annotated[float, Field(gt=0, le=10.0, description="Chord tolerance for drawing curves",
                                      json_schema_extra={"unit": "mm"})] = 0.01


@register
class View3D(NodeType):
    type_id = "view.view3d"
    title = "3D View"
    category = "View"
    description = "Show the wired path, trajectory, steps and device log in the editor's 3D view (a PNG headless)."
    Params = ViewParams
    fixed_params = ("title", "travel_box", "tolerance")  # view settings, not values a wire should feed
    inputs = (In("path", "Path", doc="Programmed path (feed moves grey, rapids orange)", default=None),
              In("trajectory", "Trajectory", doc="Setpoints, coloured by speed", default=None),
              In("steps", "Steps", doc="A step stream, played by tick or time", default=None),
              In("log", "Log", doc="What a device did", default=None),
              In("machine", "Machine", doc="Travel box", default=None))
    outputs = ()

    def run(self, ctx, params: ViewParams, path=None, trajectory=None, steps=None, log=None, machine=None):
        return {}
