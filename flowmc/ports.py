"""Port declarations: the port types that flow on wires, and the In/Out records node types declare.

A leaf module (standard library only): the graph file model, the registry and the runtime all
name port types, and none of them has to import another to do so.

>>> In("path", ("Path", "Trajectory")).accepts("Trajectory")
True
>>> In("feed", "Number", default=10.0).required
False
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

__all__ = ["PORT_TYPES", "SCALAR_PORT_TYPES", "REQUIRED", "In", "Out", "Ports"]

PORT_TYPES = ("Path", "Trajectory", "Steps", "Signal", "Machine", "Number", "Bool", "Text", "Table", "Log")
SCALAR_PORT_TYPES = ("Number", "Bool", "Text")  # the types a command line, a param or a default can hold


class _Required:
    """Sentinel: an input with no default must be wired."""

    def __repr__(self) -> str:
        return "REQUIRED"


REQUIRED: Any = _Required()


@dataclass(frozen=True)
class In:
    """An input port. ``type`` is one port type or a tuple of accepted types."""

    name: str
    type: str | tuple[str, ...]
    doc: str = ""
    default: Any = REQUIRED
    param: bool = False  # True for the port that feeds a scalar param

    @property
    def types(self) -> tuple[str, ...]:
        return (self.type,) if isinstance(self.type, str) else tuple(self.type)

    @property
    def required(self) -> bool:
        return self.default is REQUIRED

    def accepts(self, port_type: str) -> bool:
        return port_type in self.types


@dataclass(frozen=True)
class Out:
    """An output port of exactly one type."""

    name: str
    type: str
    doc: str = ""


class Ports(NamedTuple):
    inputs: tuple[In, ...]
    outputs: tuple[Out, ...]
