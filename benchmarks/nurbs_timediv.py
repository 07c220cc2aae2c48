"""NURBS Taylor interpolation, time-division lines/arcs and velocity profiles: accuracy and speed.

Prints tables (medians of 5 warm runs; wall time on one core, everything from the raw curve /
geometry to the setpoints included). Targets: NURBS max feed fluctuation by chord <= 1e-4 % with the
corrector (about 0.3 % without, at constant feed), chord error <= 1.05 eps, >= 1e5 NURBS setpoints/s;
time-division >= 2e5 setpoints/s.

Feed fluctuation is |chord_k/T - V_k| / V_k with the CHORD length (the corrector matches the chord):
below 1e-4 % in both modes (9e-8 % adaptive, 1.5e-5 % at a constant 200 mm/s, T = 4 ms). By ARC
length (the "arc max %" column) it is larger, because the arc of a step is longer than its chord by
about L^3 k^2 / 24: 0.006 % in the adaptive mode and 0.09 % at a constant 200 mm/s on the curve's
5.4 mm radius. That floor is the chord's, not the interpolator's: stepping by exact chords, no corrector
can also make every arc V*T. Quote the chord figure as "feed fluctuation" and the arc one beside it. The last step of a move is
a partial step to the end (its feed is defined as chord/T) and is left out of the statistics.

    python3 benchmarks/nurbs_timediv.py
"""

from __future__ import annotations

import json
import math
import statistics
import time
from pathlib import Path

import numpy as np

from flowmc.motion import nurbs, profiles, timediv

ROOT = Path(__file__).resolve().parents[1]
CURVE = ROOT / "tests" / "data" / "reference" / "nurbs_test_curve.json"
RUNS = 5


def median_time(fn) -> tuple[float, object]:
    fn()  # warm
    times, out = [], None
    for _ in range(RUNS):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def nurbs_table() -> None:
    spec = json.loads(CURVE.read_text())
    ctrl, w, p = spec["control_points"], spec["weights"], spec["degree"]
    knots = nurbs.clamped_uniform_knots(len(ctrl), p)
    curve = nurbs.Nurbs(ctrl, w, knots, p)
    print(f"NURBS test curve: length {curve.length:.4f} mm, tightest radius "
          f"{1 / curve.curvature(np.linspace(0, 1, 200001)).max():.4f} mm")
    u = np.random.default_rng(0).random(100_000)
    t_eval, _ = median_time(lambda: curve.evaluate(u, 2))
    print(f"evaluation with 2 derivatives: {t_eval / len(u) * 1e6:.3f} us/point (batch of {len(u)})\n")

    cases = [("adaptive: eps 1 um, amax 1000", dict(eps=1e-3, amax=1000.0)),
             ("constant feed (no limits)", dict(eps=math.inf, amax=math.inf))]
    head = (f"{'condition':<34}{'F mm/s':>7}{'T ms':>6}{'corr':>6}{'N':>7}{'max %':>11}{'mean %':>11}"
            f"{'RMS %':>11}{'arc max %':>11}{'chord/eps':>10}{'sweeps':>7}{'setpts/s':>10}{'RTF':>8}")
    print(head)
    print("-" * len(head))
    for label, opts in cases:
        for feed, period in [(200.0, 0.004), (100.0, 0.001)]:
            for corrector in (True, False):
                def run():
                    c = nurbs.Nurbs(ctrl, w, knots, p)  # from scratch: table, schedule, steps
                    return nurbs.taylor_steps(c, feed, period, corrector=corrector, **opts)
                wall, steps = median_time(run)
                fl = nurbs.feed_fluctuation(steps)[:-1] * 100
                arc = nurbs.feed_fluctuation(steps, curve, "arc")[:-1] * 100
                chord = nurbs.chord_errors(curve, steps.u).max()
                ce = f"{chord / opts['eps']:.4f}" if math.isfinite(opts["eps"]) else f"{chord * 1e3:.1f}um"
                n = len(steps.points)
                rtf = f"{(n - 1) * period / wall:.0f}" if period == 0.001 else "-"
                print(f"{label:<34}{feed:>7.0f}{period * 1e3:>6.0f}{'yes' if corrector else 'no':>6}{n:>7}"
                      f"{fl.max():>11.3g}{fl.mean():>11.3g}{math.sqrt(np.mean(fl ** 2)):>11.3g}{arc.max():>11.3g}"
                      f"{ce:>10}{steps.sweeps:>7}{n / wall:>10.3g}{rtf:>8}")
    print()


def timediv_table() -> None:
    period, eps = 0.001, 1e-4
    head = f"{'time division (T = 1 ms)':<44}{'N':>8}{'setpts/s':>11}{'max chord/eps':>15}{'max |radial| mm':>17}"
    print(head)
    print("-" * len(head))
    start, end = np.array([0.0, 0.0, 0.0]), np.array([300.0, 400.0, 0.0])

    def line():
        s = profiles.sample_profile(profiles.plan_scurve(500.0, 0.0, 0.0, 100.0, 1000.0, 10000.0), period)
        return timediv.line_points(start, end, s)

    wall, pts = median_time(line)
    print(f"eps = {eps * 1e3:g} um")
    print(f"{'line 500 mm, S-curve, 100 mm/s':<44}{len(pts):>8}{len(pts) / wall:>11.3g}{'0 (exact)':>15}{'-':>17}")
    radius, centre = 20.0, np.zeros(3)
    vmax = min(150.0, timediv.arc_feed_limit(radius, period, eps))
    for method in ("exact", "second_order"):
        def arc(method=method):
            length = timediv.arc_geometry((radius, 0, 0), (radius, 0, 0), centre, turns=9)[2]
            s = profiles.sample_profile(profiles.plan_scurve(length, 0.0, 0.0, vmax, 1000.0, 10000.0), period)
            return timediv.arc_points((radius, 0, 0), (radius, 0, 0), centre, s, turns=9, method=method)

        wall, pts = median_time(arc)
        chord, radial = timediv.circle_errors(pts[:-1], centre, radius)
        label = f"arc R20 x10 turns, {vmax:.0f} mm/s, {method}"
        print(f"{label:<44}{len(pts):>8}{len(pts) / wall:>11.3g}{chord.max() / eps:>15.4f}"
              f"{np.abs(radial).max():>17.3g}")
    print("(radial error before the final setpoint, which is the exact end point)\n")


def profile_table() -> None:
    head = f"{'profile':<14}{'plan short us':>15}{'plan long us':>14}{'sample Msamples/s':>19}"
    print(head)
    print("-" * len(head))
    plans = {
        "trapezoid": lambda L, v0, v1: profiles.plan_trapezoid(L, v0, v1, 200.0, 200.0),
        "exponential": lambda L, v0, v1: profiles.plan_exponential(L, v0, v1, 200.0, 200.0),
        "scurve": lambda L, v0, v1: profiles.plan_scurve(L, v0, v1, 200.0, 200.0, 500.0),
    }
    t = np.linspace(0.0, 3.0, 1_000_000)
    for name, plan in plans.items():
        short, _ = median_time(lambda: [plan(8.0, 20.0, 10.0) for _ in range(200)])
        long_, prof = median_time(lambda: [plan(2000.0, 20.0, 10.0) for _ in range(200)])
        samp, _ = median_time(lambda: prof[0].sample(t))
        print(f"{name:<14}{short / 200 * 1e6:>15.1f}{long_ / 200 * 1e6:>14.1f}{len(t) / samp / 1e6:>19.2f}")


if __name__ == "__main__":
    nurbs_table()
    timediv_table()
    profile_table()
