"""An example flowmc plugin: an Archimedean spiral as a Path source.

Installed with pip, it is found through the ``flowmc.nodes`` entry point in pyproject.toml:
``flowmc nodes`` lists ``example.spiral``, ``flowmc run`` runs graphs that use it, and the
editor's palette shows it under "Examples".
"""

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from flowmc.motion.path import Path
from flowmc.registry import NodeType, Out, register


class SpiralParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    turns: float = Field(3.0, gt=0, le=100, description="Number of turns")
    pitch: float = Field(2.0, gt=0, description="Radius gained per turn, mm")
    feed: float = Field(20.0, gt=0, description="Feed, mm/s")


@register
class Spiral(NodeType):
    type_id = "example.spiral"
    title = "Spiral"
    category = "Examples"
    description = "An Archimedean spiral from the origin, as short lines (a plugin's node)."
    Params = SpiralParams
    outputs = (Out("path", "Path", doc="The spiral"),)

    def run(self, ctx, params: SpiralParams):
        angle = np.linspace(0.0, 2 * np.pi * params.turns, int(36 * params.turns) + 1)
        radius = params.pitch * angle / (2 * np.pi)
        points = np.column_stack([radius * np.cos(angle), radius * np.sin(angle)])
        return {"path": Path.polyline(points, feed=params.feed)}
