"""How far is an S-curve plan from the best retiming of its own curve? (issue 14, flowsnake)

flowmc's S-curve plan of a program is retimed where the curvature-change term of per-axis jerk holds the
speed (flowmc.motion.jerk_retime: sequential linear programs in u = v^2, with the planner's Effort). This
retimes the same plan's time law on the same curve with more effort (more rounds, a wider trust region,
control points closer together) and prints, for each: the feed time (as benchmarks/cam_programs.py
counts it) and its ratio to the trapezoid plan's, the CPU time of the retiming, the peaks per axis and the
deviation both ways from the raw 1 ms samples, and how close the samples run to the jerk limit where the
tool moves (median and 10th percentile of the largest axis's sampled jerk over jmax, on the samples at
over half the plan's median speed). If every effort ends near the same time with the jerk at its limit
nearly everywhere, the speed profile is what it can be along that curve and only other geometry can go
faster. This is not a proof: the programs are local methods, and a different speed profile family might
do better.

    python3 benchmarks/retime_bound.py [NAME ...]     # default: flowsnake
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path as FsPath

import numpy as np

sys.path.insert(0, str(FsPath(__file__).parent))
import cam_programs as cam  # noqa: E402

from flowmc.devices.linuxcnc.compare import flowmc_feed_time  # noqa: E402
from flowmc.motion.jerk_retime import PLANNED, Effort, retime_curvature_bound  # noqa: E402
from flowmc.motion.limits import PathLimits  # noqa: E402
from flowmc.motion.planner import plan_smooth  # noqa: E402
from flowmc.motion.trajectory import Trajectory  # noqa: E402

EFFORTS = (("planned", PLANNED),
           ("rounds 6", Effort(rounds=6, gain=0.0)),
           ("rounds 6, trust 0.9", Effort(rounds=6, gain=0.0, trust=0.9)),
           ("step 2 T, rounds 6", Effort(step_periods=2.0, rounds=6, gain=0.0)),
           ("step 1 T, rounds 6", Effort(step_periods=1.0, rounds=6, gain=0.0)))


def retimed(plan, path, machine, effort: Effort):
    """The plan's time law retimed with ``effort``, as a trajectory tagged as the planner tags it (None if the
    retiming keeps nothing), and the CPU seconds it took."""
    lim = PathLimits.of(machine)
    curve, sm = plan.smoothed.curve, plan.smoothed
    t0 = time.process_time()
    out = retime_curvature_bound(plan.law, curve, lim, lambda u: sm.seg_feed[curve.segment_at(u)], machine.period,
                                 sm.blend_u, effort=effort)
    cpu = time.process_time() - t0
    if out is None:
        return None, cpu
    u, dwell_seg, pos = out
    pos[0], pos[-1] = path.start, path.end
    tags = np.maximum.accumulate(np.where(dwell_seg >= 0, dwell_seg, curve.segment_at(u)))
    return Trajectory(pos[:, list(lim.cols)], machine.period, tags, axes=lim.axes), cpu


def saturation(traj: Trajectory, path, jmax: float) -> tuple[float, float]:
    """Median and 10th percentile of the largest axis's sampled jerk over jmax, on feed samples at over half
    the median feed speed."""
    pos, period = traj.positions, traj.period
    jerk = np.abs(np.diff(pos, 3, axis=0)).max(axis=1) / period**3 / jmax
    speed = np.linalg.norm(np.diff(pos, axis=0), axis=1) / period
    feed = cam.cutting(traj, path)
    moving = feed & (speed > 0.5 * np.median(speed[feed]))
    on = jerk[moving[1:-1] & moving[2:]]
    return float(np.median(on)), float(np.percentile(on, 10))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("names", nargs="*", default=["flowsnake"])
    args = ap.parse_args()
    m = cam.machine()
    for name in args.names:
        path = cam.program_path(name) if name in cam.CAM else cam.reference_path(name)
        trap = flowmc_feed_time(plan_smooth(path, m, tolerance=cam.TOL).trajectory, path)
        plan = plan_smooth(path, m, tolerance=cam.TOL, profile="scurve")
        print(f"\n{name}: trapezoid plan {trap:.3f} s of feed moves; S-curve plan {flowmc_feed_time(plan.trajectory, path):.3f} s"
              f" (its time law retimed again below)\n")
        head = (f"{'effort':<22}{'feed s':>8}{'/ trap':>8}{'CPU s':>7}{'v/vmax':>8}{'a/amax':>8}{'j/jmax':>8}"
                f"{'dev->':>8}{'dev<-':>8}{'j med':>7}{'j p10':>7}")
        print(head)
        print("-" * len(head))
        for label, effort in EFFORTS:
            traj, cpu = retimed(plan, path, m, effort)
            if traj is None:
                print(f"{label:<22}{'kept nothing':>16}{cpu:>7.1f}")
                continue
            feed = flowmc_feed_time(traj, path)
            meas = cam.measure(traj.positions, m.period, path, cam.cutting(traj, path))
            med, p10 = saturation(traj, path, cam.JERK)
            print(f"{label:<22}{feed:>8.3f}{feed / trap:>8.3f}{cpu:>7.1f}{meas['v'] / 200:>8.3f}{meas['a'] / 200:>8.3f}"
                  f"{meas['j'] / cam.JERK:>8.3f}{meas['dev_to_path']:>8.4f}{meas['dev_from_path']:>8.4f}{med:>7.3f}"
                  f"{p10:>7.3f}", flush=True)


if __name__ == "__main__":
    main()
