"""Simulated-card speed: simulated seconds per wall second for a 4-axis program at T = 1 ms.

Target: >= 100x real time. Prints a table (median of 5 warm runs), open and closed loop, with and
without the pre-flight check. Run: python3 benchmarks/simcard.py [program seconds]
"""

from __future__ import annotations

import statistics
import sys
import time

import numpy as np

from flowmc.devices.preflight import preflight
from flowmc.devices.sim import SimCard
from flowmc.motion.machine import Axis, Machine
from flowmc.motion.trajectory import Trajectory

PERIOD = 0.001
RUNS = 5


def program(seconds: float) -> Trajectory:
    """Four axes on smooth, different-frequency sweeps (within 200 mm/s and 200 mm/s^2)."""
    t = np.arange(int(round(seconds / PERIOD)) + 1) * PERIOD
    ease = lambda x: 0.5 - 0.5 * np.cos(np.pi * np.clip(x, 0.0, 1.0))  # noqa: E731  smooth 0 -> 1
    ramp = ease(t / 2.0) * ease((seconds - t) / 2.0)
    columns = [60.0 * np.sin(2 * np.pi * t / (5.0 + k)) * ramp for k in range(4)]
    return Trajectory(np.column_stack(columns), PERIOD, segment=(t // 1.0).astype(int), axes=("X", "Y", "Z", "A"))


def median_wall(fn) -> float:
    fn()  # warm
    walls = []
    for _ in range(RUNS):
        t0 = time.perf_counter()
        fn()
        walls.append(time.perf_counter() - t0)
    return statistics.median(walls)


def main() -> None:
    seconds = float(sys.argv[1]) if len(sys.argv) > 1 else 60.0
    machine = Machine(axes=tuple(Axis(name=n) for n in "XYZA"), period=PERIOD)
    tr = program(seconds)
    preflight(tr, machine)  # the program is valid
    rows = []
    for closed in (False, True):
        for check in (True, False):
            wall = median_wall(lambda: SimCard(machine, closed_loop=closed).run(tr, check=check))
            log = SimCard(machine, closed_loop=closed).run(tr, check=check)
            simulated = log.duration
            rows.append(("closed" if closed else "open", "yes" if check else "no", simulated, wall, simulated / wall,
                         (len(log) - 1) / wall))
    print(f"Simulated card, 4 axes, T = {PERIOD * 1e3:g} ms, program {seconds:g} s, median of {RUNS} warm runs")
    print(f"{'loop':<7}{'pre-flight':>11}{'simulated s':>13}{'wall s':>9}{'sim s / wall s':>16}{'periods / s':>14}")
    for loop, check, simulated, wall, ratio, rate in rows:
        print(f"{loop:<7}{check:>11}{simulated:>13.3f}{wall:>9.4f}{ratio:>15.0f}x{rate:>14.3g}")
    print("target: >= 100x real time")


if __name__ == "__main__":
    main()
