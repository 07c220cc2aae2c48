"""Feed planning on the reference paths: cycle time, ratio to the time-optimal bound, feasibility,
contour error, and planning throughput.

Every figure comes from the sampled setpoints through flowmc.motion.metrics (the reference README's
definitions). Limits: 200 mm/s, 200 mm/s^2, 500 mm/s^3 per axis, T = 4 ms, corner tolerance 0.05 mm.
``peak a`` is the largest per-axis sampled acceleration over its limit away from rule corners;
``spike`` is the sampled acceleration at rule corners passed at speed (the ARM rule declares it <= w,
w <= 1; junction deviation declares nothing). LinuxCNC 2.9 figures (G64 P0.05, same limits, feed
moves only) are the ones measured for issue 4; ``vs LCNC`` is our time over theirs.
Throughput: setpoints per second on one core, planning and sampling included, warm, median of 5,
T = 1 ms; RTF = cycle time / wall time.

    python3 benchmarks/planning.py
"""

from __future__ import annotations

import json
import statistics
import time
from pathlib import Path as FsPath

import numpy as np

from flowmc.motion.lookahead import plan_lookahead, plan_stop_and_go
from flowmc.motion.machine import Machine
from flowmc.motion.metrics import trajectory_report
from flowmc.motion.path import Arc, Line, Path

ROOT = FsPath(__file__).resolve().parents[1]
REF = ROOT / "tests" / "data" / "reference"
NAMES = ("mixed", "star10", "zigzag40", "ellipse200")
LINUXCNC = {"mixed": 7.47, "star10": 11.89, "zigzag40": 10.95, "ellipse200": 5.27}
TOL = 0.05
RUNS = 5

PLANNERS = [
    ("look-ahead trapezoid", "blend"), ("look-ahead trapezoid", "arm_weighted"),
    ("look-ahead trapezoid", "junction_deviation"),
    ("look-ahead S-curve", "blend"), ("look-ahead S-curve", "arm_weighted"),
    ("look-ahead S-curve", "junction_deviation"),
    ("stop-and-go", "trapezoid"), ("stop-and-go", "exponential"), ("stop-and-go", "scurve"),
]


def reference(name: str) -> tuple[Path, float]:
    data = json.loads((REF / "paths" / f"{name}.json").read_text())
    return Path.polyline(data["points"], feed=data["limits"]["feed_mm_s"]), data["time_optimal_bound_s"]


def plan(path: Path, machine: Machine, planner: str, option: str):
    if planner == "stop-and-go":
        return plan_stop_and_go(path, machine, profile=option)
    profile = "scurve" if "S-curve" in planner else "trapezoid"
    return plan_lookahead(path, machine, rule=option, tolerance=TOL, profile=profile)


def quality_table(machine: Machine) -> dict:
    head = (f"{'path':<11}{'planner':<22}{'rule/profile':<20}{'cycle s':>9}{'R_T':>7}{'peak a':>8}"
            f"{'spike':>7}{'contour mm':>11}{'LCNC s':>8}{'vs LCNC':>8}")
    print(head)
    print("-" * len(head))
    results = {}
    for name in NAMES:
        path, bound = reference(name)
        for planner, option in PLANNERS:
            p = plan(path, machine, planner, option)
            rep = trajectory_report(p.trajectory, path, machine, bound, p.corner_times)
            results[name, planner, option] = rep
            lcnc = LINUXCNC[name] if (planner, option) == ("look-ahead trapezoid", "blend") else None
            print(f"{name:<11}{planner:<22}{option:<20}{rep['cycle_time']:>9.3f}{rep['time_ratio']:>7.3f}"
                  f"{rep['peak_accel']:>8.3f}{rep['corner_spike']:>7.2f}{rep['contour_error']:>11.4f}"
                  + (f"{lcnc:>8.2f}{rep['cycle_time'] / lcnc:>8.3f}" if lcnc else f"{'':>8}{'':>8}"))
        print()
    return results


def lines_and_arcs(loops: int = 50) -> Path:
    """A CAM-like lines-and-arcs program: racetrack loops of lines and tangent arcs with a V corner."""
    segs, p = [], np.zeros(3)
    for i in range(loops):
        r, length = 5.0 + (i % 4) * 5.0, 10.0 + (i % 3) * 10.0
        for step in ("line+", "arc+", "line-", "arc-", "v1", "v2"):
            if step == "line+":
                q = p + [length, 0, 0]
                segs.append(Line(p, q, feed=200.0))
            elif step == "line-":
                q = p + [-length, 0, 0]
                segs.append(Line(p, q, feed=200.0))
            elif step.startswith("arc"):
                c = p + [0, r, 0]
                q = c + [0, r, 0]
                segs.append(Arc(p, q, c, ccw=step == "arc+", feed=200.0))
            else:
                q = p + ([5, 5, 0] if step == "v1" else [-5, 5, 0])
                segs.append(Line(p, q, feed=200.0))
            p = q
    return Path(segs)


def throughput_table() -> list[float]:
    machine = Machine(period=0.001)
    programs = [(name, reference(name)[0]) for name in NAMES] + [("lines+arcs", lines_and_arcs())]
    head = f"{'program':<12}{'planner':<34}{'setpoints':>10}{'wall ms':>9}{'setpts/s':>11}{'RTF':>8}"
    print(head)
    print("-" * len(head))
    rates = []
    for name, path in programs:
        for planner, option in [("look-ahead trapezoid", "blend"), ("look-ahead S-curve", "blend"),
                                ("look-ahead trapezoid", "arm_weighted"), ("stop-and-go", "trapezoid")]:
            plan(path, machine, planner, option)  # warm
            times = []
            for _ in range(RUNS):
                t0 = time.perf_counter()
                p = plan(path, machine, planner, option)
                times.append(time.perf_counter() - t0)
            wall = statistics.median(times)
            n = len(p.trajectory)
            rates.append(n / wall)
            print(f"{name:<12}{planner + ' ' + option:<34}{n:>10d}{wall * 1e3:>9.2f}{n / wall:>11.3g}"
                  f"{p.cycle_time / wall:>8.0f}")
    print()
    return rates


def main() -> None:
    machine = Machine(period=0.004)
    print("Feed planning on the reference paths (T = 4 ms, per-axis 200 mm/s, 200 mm/s^2, 500 mm/s^3)\n")
    res = quality_table(machine)
    print("Planning throughput (T = 1 ms, one core, warm, median of 5)\n")
    rates = throughput_table()

    print("Targets")
    checks = []
    for name in NAMES:
        rep = res[name, "look-ahead trapezoid", "blend"]
        checks.append((f"{name}: look-ahead trapezoid + blend {rep['cycle_time']:.3f} s < LinuxCNC "
                       f"{LINUXCNC[name]} s, contour {rep['contour_error']:.4f} <= 0.05 mm, "
                       f"peak a {rep['peak_accel']:.3f} <= 1.01",
                       rep["cycle_time"] < LINUXCNC[name] and rep["contour_error"] <= TOL
                       and rep["peak_accel"] <= 1.01))
    for rule in ("blend", "arm_weighted"):
        rep = res["mixed", "look-ahead S-curve", rule]
        checks.append((f"mixed: look-ahead S-curve ({rule}) R_T {rep['time_ratio']:.3f} <= 1.7",
                       rep["time_ratio"] <= 1.7))
        base = res["mixed", "stop-and-go", "trapezoid"]["cycle_time"]
        ratio = rep["cycle_time"] / base
        checks.append((f"mixed: look-ahead S-curve ({rule}) {rep['cycle_time']:.3f} s / stop-and-go trapezoid "
                       f"{base:.3f} s = {ratio:.3f} <= 0.68", ratio <= 0.68))
    checks.append((f"throughput >= 2e5 setpoints/s on every program above: min {min(rates):.3g}",
                   min(rates) >= 2e5))
    for text, ok in checks:
        print(f"  [{'PASS' if ok else 'FAIL'}] {text}")
    print("  Note: with arm_weighted the rule itself caps the arc's 1.5 degree chords at 31-43 mm/s. The baseline is\n"
          "  ~15.9 s, not the README's ~16.5 s, because per-axis limits let diagonal chords accelerate at up to\n"
          "  283 mm/s^2; against 16.5 s the arm_weighted ratio would be 0.67.")


if __name__ == "__main__":
    main()
