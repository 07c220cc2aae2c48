"""Batches of variants for workers, in an order that keeps upstream work shared.

The runtime caches each pure node's last result. Variants are ordered by the axes nearest the graph's
sources first, so consecutive variants on a worker differ downstream and reuse what is upstream.
Variants that agree on every axis but the most downstream one form a group (the same G-code file, say);
a batch never spans two groups, and batches go out in order, so each worker computes a group's shared
upstream nodes once, however many of the group's batches it runs.
"""

from __future__ import annotations

import math
from typing import Any

from flowmc.sweep.variants import Axis, Variant

__all__ = ["upstream_first", "batches", "batch_size"]


def _depth(plan: Any, axis: Axis) -> int:
    """How far down the graph's order the first node an axis reaches is."""
    position = {node_id: k for k, node_id in enumerate(plan.order)}
    reached = []
    for tgt in axis.targets:
        if tgt.node is not None:
            reached.append(tgt.node)
        else:
            reached += [node for node, _port in plan.iface_inputs.get(tgt.name, (None, []))[1]]
    return min((position.get(n, len(position)) for n in reached), default=len(position))


def upstream_first(plan: Any, axes: list[Axis]) -> list[int]:
    """Axis indices ordered from the graph's sources down (ties keep the axes' order)."""
    return sorted(range(len(axes)), key=lambda a: (_depth(plan, axes[a]), a))


def batch_size(count: int, workers: int, cap: int = 8) -> int:
    """About eight batches per worker (progress stays live, Ctrl-C loses little), at most ``cap`` variants."""
    return max(1, min(cap, math.ceil(count / max(1, workers * 8))))


def batches(variants: list[Variant], order: list[int], size: int) -> list[list[Variant]]:
    """Variants sorted by ``order`` (axis indices, upstream first), cut into batches of at most ``size``
    that never mix groups."""
    if not variants:
        return []
    ranked = sorted(variants, key=lambda v: (tuple(v.coords[a] for a in order), v.index))
    shared = order[:-1]  # every axis but the most downstream one

    def group(v: Variant) -> tuple[int, ...]:
        return tuple(v.coords[a] for a in shared)

    out: list[list[Variant]] = []
    for v in ranked:
        if out and len(out[-1]) < size and group(out[-1][-1]) == group(v):
            out[-1].append(v)
        else:
            out.append([v])
    return out
