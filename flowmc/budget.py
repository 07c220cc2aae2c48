"""Resource budgets: how much any one node may produce, checked *before* it allocates.

A tiny input can ask for an enormous output (``G1 X1000 F0.05`` at a 1 ms period is 1.2 billion
setpoints; an arc of 100,000 turns; a 6000x6000 picture). Producers call ``check(kind, count, ...)``
with the count they are about to allocate; over the cap it raises ``BudgetError``, which says how many
were asked for, the cap, and what to change. The runtime puts the node's name in front.

Caps come from one memory budget (``memory_mb``: 256 MB unless set, never more than a quarter of
this computer's RAM) divided by what one item costs while it is built, which for setpoints and steps
depends on the machine's axis count (``per_axis``). Counts that are not memory (arc turns, nesting
depth, sub-graph expansion) have caps of their own. All are configurable: ``FLOWMC_MEMORY_MB`` and
``FLOWMC_BUDGET_<KIND>`` in the environment, ``flowmc run --memory-mb``, or ``configure``/``limits``.
"""

from __future__ import annotations

import contextlib
import math
import os
import threading
from dataclasses import dataclass, replace
from typing import Iterator

from flowmc.errors import BudgetError

__all__ = ["BudgetError", "Budget", "check", "cap", "current", "configure", "limits", "KINDS"]

# Bytes one item costs at the peak of building it (the output and the temporaries beside it), measured
# on the producers: a setpoint of a 3-axis plan peaks near 170 bytes (t, phase, s, piece, position...).
_BYTES = {
    "setpoints": (80, 30),   # base + per axis
    "steps": (40, 12),
    "points": (120, 0),      # sampled path points (chord tolerance)
    "pixels": (48, 0),       # a picture's pixels while it is traced
    "rows": (2_000, 0),      # segment-table rows, polyline points, table rows (Python objects)
    "segments": (1_500, 0),  # path segments (one Python object each)
    "bytes": (12, 0),        # a text file read whole (G-code: the text and its word arrays)
    "json_bytes": (24, 0),   # a graph file's text (JSON objects cost ~20x their text)
}
_FIXED = {"turns": 10_000, "depth": 64, "expansion": 20_000, "iterations": 100_000}
KINDS = tuple(_BYTES) + tuple(_FIXED)

_ENV_MEMORY = "FLOWMC_MEMORY_MB"
DEFAULT_MEMORY_MB = 256


def _ram_mb() -> float:
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**20
    except (ValueError, OSError, AttributeError):
        return 4096.0


@dataclass(frozen=True)
class Budget:
    memory_mb: float
    fixed: tuple[tuple[str, float], ...]  # caps of the counts that are not memory

    def cap(self, kind: str, axes: int = 3) -> int:
        if kind in _FIXED:
            return int(dict(self.fixed)[kind])
        base, per_axis = _BYTES[kind]
        return int(self.memory_mb * 2**20 // (base + per_axis * max(axes, 1)))


def _from_environment() -> Budget:
    memory = float(os.environ.get(_ENV_MEMORY, min(DEFAULT_MEMORY_MB, _ram_mb() / 4)))
    fixed = tuple((k, float(os.environ.get(f"FLOWMC_BUDGET_{k.upper()}", v))) for k, v in _FIXED.items())
    return Budget(memory, fixed)


_state = threading.local()
_default: list[Budget] = []


def current() -> Budget:
    """The budget in force (per thread inside ``limits``; else the process-wide one)."""
    scoped = getattr(_state, "budget", None)
    if scoped is not None:
        return scoped
    if not _default:
        _default.append(_from_environment())
    return _default[0]


def _updated(base: Budget, memory_mb: float | None, caps: dict[str, float]) -> Budget:
    unknown = set(caps) - set(_FIXED)
    if unknown:
        raise ValueError(f"unknown budget {sorted(unknown)}; fixed caps are {sorted(_FIXED)}")
    if memory_mb is not None and not (math.isfinite(memory_mb) and memory_mb > 0):
        raise ValueError(f"memory budget must be > 0 MB, got {memory_mb}")
    fixed = tuple((k, caps.get(k, v)) for k, v in base.fixed)
    return replace(base, memory_mb=base.memory_mb if memory_mb is None else float(memory_mb), fixed=fixed)


def configure(memory_mb: float | None = None, **caps: float) -> Budget:
    """Set the process-wide budget (the CLI's ``--memory-mb``)."""
    budget = _updated(current(), memory_mb, caps)
    _default[:] = [budget]
    return budget


@contextlib.contextmanager
def limits(memory_mb: float | None = None, **caps: float) -> Iterator[Budget]:
    """A different budget for the code inside (this thread only): tests, and callers that know better."""
    previous = getattr(_state, "budget", None)
    _state.budget = _updated(current(), memory_mb, caps)
    try:
        yield _state.budget
    finally:
        _state.budget = previous


def cap(kind: str, axes: int = 3) -> int:
    return current().cap(kind, axes)


def check(kind: str, count: float, *, what: str, change: str, axes: int = 3, where: str | None = None) -> None:
    """Raise BudgetError if ``count`` items of ``kind`` are over the cap. ``what`` names the request
    (``"planning 1000 mm at 0.05 mm/min"``), ``change`` says what to change in the graph."""
    limit = cap(kind, axes)
    if count <= limit:
        return
    shown = f"{count:,.0f}" if math.isfinite(count) else "unboundedly many"
    if kind in _FIXED:
        raise_with = f"or raise the limit (FLOWMC_BUDGET_{kind.upper()})"
    else:
        raise_with = (f"or raise the memory budget ({current().memory_mb:g} MB: flowmc run --memory-mb, "
                      f"{_ENV_MEMORY})")
    raise BudgetError(f"{what} needs {shown} {kind}, over the budget of {limit:,}: {change}, {raise_with}",
                      where=where)
