"""The error hierarchy: every error a user can cause is a FlowmcError.

The CLI and the editor print ``str(error)``, never a traceback, so each error
says *where* (file, line, node id, segment) before *what*.
"""

from __future__ import annotations

import re
from typing import Any

__all__ = [
    "FlowmcError",
    "GraphError",
    "NodeError",
    "PathError",
    "GcodeError",
    "PlanningError",
    "DeviceError",
    "LimitError",
    "BudgetError",
    "UsageError",
    "printable",
]

_CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f-\x9f\u2028\u2029\ud800-\udfff]")


def printable(text: object, limit: int | None = None) -> str:
    """``text`` safe to quote in a message: control characters (a terminal escape, NUL, a lone
    surrogate) shown as ``\\x1b``-style escapes, and cut to ``limit`` characters with an ellipsis."""
    s = text if isinstance(text, str) else str(text)
    if _CONTROL.search(s):
        s = _CONTROL.sub(lambda m: f"\\x{ord(m.group()):02x}" if ord(m.group()) < 0x100 else f"\\u{ord(m.group()):04x}", s)
    if limit is not None and len(s) > limit:
        s = s[:max(limit - 1, 0)] + "…"
    return s


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
    """A device that refuses, faults or does not answer. ``log``: what the device did up to then (a
    ``DeviceLog``, when there is one), so a stopped job still reports where it got to."""

    log: Any = None


class LimitError(DeviceError):
    """A program that would break a machine limit; raised by pre-flight before anything is sent."""


class BudgetError(FlowmcError):
    """A node would produce more than the resource budget allows (``flowmc.budget``); the
    message says how much was asked for, the cap, and what to change."""


class UsageError(FlowmcError):
    """A bad argument from the command line or a sweep definition (exit 2)."""
