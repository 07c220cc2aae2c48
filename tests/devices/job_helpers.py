"""Helpers for job tests: a real example graph's planned program, and checks made from raw setpoints."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

import flowmc
from flowmc.devices.jobs import Job

GRAPHS = Path(__file__).resolve().parents[2] / "graphs"


@functools.lru_cache(maxsize=4)
def example_program(name: str = "thesis_3axis", node: str = "plan", port: str = "trajectory"):
    """(motion, machine) as the example graph plans them (pure nodes only: nothing moves)."""
    result = flowmc.run(flowmc.load(GRAPHS / f"{name}.flowmc.json"))
    machine_node = next(n.id for n in flowmc.load(GRAPHS / f"{name}.flowmc.json").nodes if n.type == "machine")
    return result.nodes[node].outputs[port], result.nodes[machine_node].outputs["machine"]


def thesis_job(**kwargs) -> Job:
    motion, machine = example_program()
    return Job("sim", machine, "program", motion, name="card", **kwargs)


def limits_ratio(setpoints: np.ndarray, machine, period: float) -> tuple[float, float]:
    """Peak |v|/vmax and |a|/amax over all axes, from the sampled setpoints (finite differences)."""
    v = np.diff(setpoints, axis=0) / period
    a = np.diff(v, axis=0) / period
    return float((np.abs(v) / machine.column("vmax")).max()), float((np.abs(a) / machine.column("amax")).max())


def distance_to_polyline(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    """Each point's distance to the polyline through ``line`` (vectorised over segments in blocks)."""
    a, b = line[:-1], line[1:]
    ab = b - a
    denom = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-30)
    out = np.empty(len(points))
    for i in range(0, len(points), 256):
        p = points[i:i + 256]
        u = np.clip(np.einsum("pij,ij->pi", p[:, None, :] - a[None], ab) / denom, 0.0, 1.0)
        d = np.linalg.norm(p[:, None, :] - (a[None] + u[..., None] * ab[None]), axis=2)
        out[i:i + 256] = d.min(axis=1)
    return out


def moving_rows(setpoints: np.ndarray) -> np.ndarray:
    """Indices of the periods in which the commanded position changed."""
    return np.flatnonzero(np.linalg.norm(np.diff(setpoints, axis=0), axis=1) > 0)
