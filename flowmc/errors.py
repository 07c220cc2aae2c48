"""The error hierarchy: every error a user can cause is a FlowmcError.

The CLI and the editor print ``str(error)``, never a traceback, so each error
says *where* (file, line, node id, segment) before *what*.
"""

from __future__ import annotations

__all__ = [
    "FlowmcError",
    "GraphError",
    "NodeError",
    "PathError",
    "GcodeError",
    "PlanningError",
    "DeviceError",
    "LimitError",
]


class FlowmcError(Exception):
    """Base class. ``where`` names the place (``"part.ngc:12"``, ``"node 'plan'"``, ``"segment 5 (row 4)"``)."""

    def __init__(self, message: str, *, where: str | None = None):
        self.message = message
        self.where = where
        super().__init__(f"{where}: {message}" if where else message)


class GraphError(FlowmcError):
    """A graph file or graph that cannot be loaded or validated; ``issues`` lists every problem."""

    def __init__(self, message: str, *, where: str | None = None, issues: list | None = None):
        self.issues = list(issues or [])
        super().__init__(message, where=where)


class NodeError(FlowmcError):
    """A node failed while running; ``node_id`` names it."""


class PathError(FlowmcError):
    """Geometry that cannot be built: an arc that cannot reach its end, a bad NURBS, a bad table row."""


class GcodeError(FlowmcError):
    """G-code we cannot read or write; ``where`` is ``file:line``."""


class PlanningError(FlowmcError):
    """A path that cannot be planned under the given machine limits."""


class DeviceError(FlowmcError):
    """A device that refuses, faults or does not answer."""


class LimitError(DeviceError):
    """A program that would break a machine limit; raised by pre-flight before anything is sent."""
