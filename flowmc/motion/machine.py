"""A machine's axes and their limits: the one place planners, interpolators and pre-flight read them from."""

# No ``from __future__ import annotations``: pydantic would compile every model field's annotation from
# its text when a cold ``flowmc validate`` builds the models (docs/architecture.md).
from typing import TYPE_CHECKING, Annotated

from pydantic import BaseModel, ConfigDict, Field, model_validator

if TYPE_CHECKING:
    import numpy as np  # imported where used: a graph's params validate without numpy

__all__ = ["RAPID_FEED", "Axis", "Machine", "default_machine"]

#: Feed given to G0 moves (mm/s) when the machine names none: G-code leaves the rapid rate to the machine.
RAPID_FEED = 200.0


class Axis(BaseModel):
    """One axis: travel (soft limits) and dynamics."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    name: Annotated[str, Field(min_length=1, max_length=8, description="Axis letter")] = "X"
    min: Annotated[float, Field(description="Soft limit, low end", json_schema_extra={"unit": "mm"})] = -200.0
    max: Annotated[float, Field(description="Soft limit, high end", json_schema_extra={"unit": "mm"})] = 200.0
    vmax: Annotated[float, Field(gt=0, description="Max velocity", json_schema_extra={"unit": "mm/s"})] = 200.0
    amax: Annotated[float, Field(gt=0, description="Max acceleration", json_schema_extra={"unit": "mm/s^2"})] = 200.0
    jmax: Annotated[float, Field(gt=0, description="Max jerk", json_schema_extra={"unit": "mm/s^3"})] = 500.0
    step_mm: Annotated[float, Field(gt=0, description="Pulse equivalent (mm per step)",
                                    json_schema_extra={"unit": "mm"})] = 0.0025
    max_step_rate: Annotated[float, Field(gt=0, description="Max step rate",
                                          json_schema_extra={"unit": "Hz"})] = 100_000.0

    @model_validator(mode="after")
    def _travel_ordered(self):
        if not self.min < self.max:
            raise ValueError(f"axis {self.name}: min ({self.min}) must be below max ({self.max})")
        return self


def _default_axes() -> tuple[Axis, ...]:
    return (Axis(name="X"), Axis(name="Y"), Axis(name="Z", min=-50.0, max=50.0))


class Machine(BaseModel):
    """Axes in order (X, Y, Z[, A]) and the interpolation period T."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    axes: tuple[Axis, ...] = Field(default_factory=_default_axes, min_length=1, max_length=4)
    period: Annotated[float, Field(gt=0, le=0.1, description="Interpolation period T",
                                   json_schema_extra={"unit": "s"})] = 0.004

    @model_validator(mode="after")
    def _unique_names(self):
        names = [a.name for a in self.axes]
        if len(set(names)) != len(names):
            raise ValueError(f"axis names must be unique, got {names}")
        return self

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(a.name for a in self.axes)

    def column(self, field: str) -> "np.ndarray":
        """One limit for every axis as an array, e.g. ``machine.column("vmax")``."""
        import numpy as np

        return np.array([getattr(a, field) for a in self.axes], dtype=float)

    def digest(self) -> str:
        from flowmc.motion.values import array_digest

        return array_digest("Machine", self.model_dump_json())

    def summary(self) -> dict:
        return {"type": "Machine", **self.model_dump()}


def default_machine(**overrides) -> Machine:
    """The default 3-axis machine (the reference paths' limits), with fields overridden by keyword."""
    return Machine(**overrides)
