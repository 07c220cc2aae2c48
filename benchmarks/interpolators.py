"""Step interpolators: steps per second on one core against the 5e6 steps/s target.

Each case builds a whole step stream from integer end points (the array included, nothing cached
between runs): medians of 5 runs after a warm-up, wall time. "steps" counts pulses (a tick where
both axes step counts two); DDA rows are ticks, and the ticks/s column shows that rate too. For
scale, the per-step Python loop the tests compare against is timed on a smaller case of each kind.

    python3 benchmarks/interpolators.py
"""

from __future__ import annotations

import math
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from flowmc.motion import stepinterp as si

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "motion"))
import test_stepinterp as ref  # noqa: E402  (the slow per-step reference loops)

RUNS = 5
TARGET = 5e6


def timed(fn) -> tuple[float, object]:
    fn()  # warm-up
    times, out = [], None
    for _ in range(RUNS):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def loop_rate(fn) -> float:
    t0 = time.perf_counter()
    out = fn()
    return int(np.count_nonzero(out)) / (time.perf_counter() - t0)


def main() -> None:
    r_arc = 250_000
    e_arc = (round(r_arc * math.cos(2.5)), round(r_arc * math.sin(2.5)))
    cases = [
        ("point-by-point line (3e6, -1.7e6)", lambda: si.pbp_line((3_000_000, -1_700_000)),
         lambda: ref.ref_pbp_line(30_000, -17_000)),
        ("point-by-point full circle R 3e5", lambda: si.pbp_arc((300_000, 0), (300_000, 0)),
         lambda: ref.ref_pbp_conic(1, 1, 3000**2, (3000, 0), (3000, 0), True)),
        ("point-by-point arc R 2.5e5, 3 quadrants, cw", lambda: si.pbp_arc((0, -r_arc), e_arc, ccw=False),
         lambda: ref.ref_pbp_conic(1, 1, 2500**2, (0, -2500), (-2001, 1496), False)),
        ("point-by-point full ellipse 3e5 x 1e5", lambda: si.pbp_ellipse((300_000, 0), (300_000, 0), 300_000, 100_000),
         lambda: ref.ref_pbp_conic(1000**2, 3000**2, 3000**2 * 1000**2, (3000, 0), (3000, 0), True)),
        ("DDA line (3e6, -1.7e6), 22 bits", lambda: si.dda_line((3_000_000, -1_700_000)),
         lambda: ref.ref_dda_line(30_000, -17_000, 15, "half")),
        ("DDA full circle R 1e5, 18 bits", lambda: si.dda_arc((100_000, 0), (100_000, 0)),
         lambda: ref.ref_dda_arc((1000, 0), (1000, 0), True, 11, "half")),
        ("DDA quarter R 1e5, 17 bits (no spare)", lambda: si.dda_arc((100_000, 0), (0, 100_000), bits=17),
         lambda: ref.ref_dda_arc((1000, 0), (0, 1000), True, 10, "half")),
        ("DDA quarter R 1e5, 17 bits, zero preset",
         lambda: si.dda_arc((100_000, 0), (0, 100_000), bits=17, preset="zero"),
         lambda: ref.ref_dda_arc((1000, 0), (0, 1000), True, 10, "zero")),
    ]
    head = f"{'case':44s} {'steps':>10s} {'ticks':>10s} {'median ms':>10s} {'steps/s':>10s} {'ticks/s':>10s} " \
           f"{'x target':>9s} {'loop st/s':>10s} {'x loop':>8s}"
    print(f"Step interpolators, {RUNS} warm runs, median; target {TARGET:.0e} steps/s on one core")
    print(head)
    print("-" * len(head))
    for name, fast, slow in cases:
        dt, out = timed(fast)
        steps = int(np.count_nonzero(out.steps))
        rate = steps / dt
        base = loop_rate(slow)
        ok = "ok" if rate >= TARGET else "BELOW"
        print(f"{name:44s} {steps:10d} {len(out):10d} {dt * 1e3:10.1f} {rate:10.3g} {len(out) / dt:10.3g} "
              f"{rate / TARGET:8.1f}x {base:10.3g} {rate / base:7.0f}x  {ok}")


if __name__ == "__main__":
    main()
