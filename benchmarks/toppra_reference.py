"""A per-axis time-optimal reference for any planned curve: TOPP-RA (Pham and Pham, IEEE T-RO 2018).

``toppra_time(plan)`` takes the curve a flowmc plan follows (``plan.smoothed``), splits it at the
points where the program must stop, and computes with the ``toppra`` package the fastest
parameterisation of each stretch under the same limits: every axis within its vmax and amax, and
the path speed within the feed (a virtual fourth joint, the arc length, limited to the feed). Jerk
is not limited, so for S-curve plans the ratio also shows what the jerk limit costs. The ratio
flowmc time / reference says how close flowmc's time law comes to optimal on its own geometry; it
says nothing about the smoothing, which the LinuxCNC comparison judges.

toppra is a benchmark/test dependency (pyproject ``test`` extra); it is on PyPI.
"""

from __future__ import annotations

import numpy as np
import toppra
import toppra.algorithm
import toppra.constraint
from toppra.interpolator import AbstractGeometricPath

from flowmc.motion.limits import PathLimits

__all__ = ["toppra_time"]

toppra.setup_logging("WARNING")


class _Stretch(AbstractGeometricPath):
    """One stretch [s0, s1] of a plan's curve, by arc length, as a toppra path: the X/Y/Z columns and the arc
    length itself (so that a joint velocity limit on it is the feed)."""

    def __init__(self, plan, cols, s0: float, s1: float):
        self.plan, self.cols, self.s0, self.s1 = plan, list(cols), float(s0), float(s1)

    def __call__(self, s, order: int = 0):
        scalar = np.ndim(s) == 0
        s = np.clip(np.atleast_1d(np.asarray(s, dtype=float)), self.s0, self.s1)
        curve = self.plan.smoothed.curve
        u = self.plan.law.u_at(s, curve)
        p, d1, d2 = curve.evaluate(u, 2)
        speed = np.maximum(np.linalg.norm(d1, axis=1), 1e-300)
        tan = d1 / speed[:, None]
        if order == 0:
            out = np.c_[p[:, self.cols], s]
        elif order == 1:
            out = np.c_[tan[:, self.cols], np.ones(len(s))]
        else:
            kv = (d2 - np.einsum("ij,ij->i", d2, tan)[:, None] * tan) / speed[:, None] ** 2
            out = np.c_[kv[:, self.cols], np.zeros(len(s))]
        return out[0] if scalar else out

    @property
    def dof(self) -> int:
        return len(self.cols) + 1

    @property
    def path_interval(self):
        return np.array([self.s0, self.s1])


def toppra_time(plan, machine, feed: float, grid_step: float = 0.01) -> float:
    """TOPP-RA's cycle time on ``plan``'s curve under ``machine``'s per-axis limits and path speed <= ``feed``.

    The curve is taken by arc length and split at the plan's stops (rest there, as in the plan); dwells add
    their time. ``grid_step`` (mm) is the grid spacing.
    """
    lim = PathLimits.of(machine)
    cols = list(lim.cols)
    law = plan.law
    stops = law.s[np.unique(np.r_[0, law.stop_node, len(law.s) - 1])]
    vlim = np.r_[lim.vmax[cols], feed]
    alim = np.r_[lim.amax[cols], 1e6]
    total = float(np.sum(law.stop_wait))
    for a, b in zip(stops[:-1], stops[1:]):
        if b - a <= 1e-9:
            continue
        path = _Stretch(plan, cols, a, b)
        # collocation (constraints at the grid points), the discretisation flowmc's time law uses too; the
        # default interpolation scheme fails on some gently curved stretches (controllable set empty)
        constraints = [toppra.constraint.JointVelocityConstraint(np.c_[-vlim, vlim]),
                       toppra.constraint.JointAccelerationConstraint(
                           np.c_[-alim, alim], discretization_scheme=toppra.constraint.DiscretizationType.Collocation)]
        for stretch in (1.0, 0.93, 1.07, 0.81):  # TOPP-RA's LPs now and then fail on one grid and not the next
            grid = np.linspace(a, b, int(np.ceil((b - a) / (grid_step * stretch))) + 1)  # uniform grids suit it
            algo = toppra.algorithm.TOPPRA(constraints, path, gridpoints=grid, parametrizer="ParametrizeConstAccel")
            _, sd, _, _ = algo.compute_parameterization(0.0, 0.0, return_data=True)
            if sd is not None and np.all(np.isfinite(sd)):
                break
        else:
            raise RuntimeError(f"TOPP-RA found no parameterisation of the stretch {a:.3f}..{b:.3f} mm")
        sd = np.maximum(sd, 0.0)
        total += float(np.sum(2.0 * np.diff(grid) / np.maximum(sd[:-1] + sd[1:], 1e-300)))
    return total
