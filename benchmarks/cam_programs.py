"""flowmc's planner against LinuxCNC on real CAM code and the reference paths, measured in the same run.

Programs: LinuxCNC's own sample programs flowsnake, 3D_Chips, spiral, arcspiral and 3dtest (Debian's
linuxcnc-uspace installs them in /usr/share/linuxcnc/ncfiles), ``raster`` (a dense 2.5D finishing raster
written here: 0.25 mm steps along X over a wavy surface, 1 mm step-over, 3,200 short lines) and the four
reference paths. flowmc's
G-code reader (flowmc.motion.gcode, LinuxCNC semantics: O-words, parameters, polar and relative moves)
reads them; the Path it gives is what both sides run (LinuxCNC gets it back through flowmc's G-code
writer). Every feed is set to F12000 mm/min (200 mm/s; 3D_Chips asks for more, the axes allow 200),
rapids move at 200 mm/s.

Both sides: per-axis 200 mm/s, 200 mm/s^2 (and 5000 mm/s^3 for flowmc's S-curve), servo period and
setpoint period 1 ms, corner tolerance 0.05 mm (LinuxCNC: G64 P0.05 with its default Q; flowmc's
blend tolerance). LinuxCNC runs through flowmc's own LinuxCNC backend (the real simulator, samples
every servo period). Times are feed moves only, as LinuxCNC counts them. Every other figure comes from
the raw 1 ms samples: deviation both ways over the feed moves (chords between setpoints on feed moves
to the programmed path, and every point of the programmed feed moves to the tool path; rapids are not
cut), peak per-axis velocity, acceleration and jerk over the limit. ``TOPP-RA`` is the per-axis
time-optimal parameterisation of flowmc's own smoothed curve (benchmarks/toppra_reference.py, total
time including rapids), so ``/topp`` says how close flowmc's time law comes to optimal on its geometry.

    python3 benchmarks/cam_programs.py [--no-linuxcnc] [--no-toppra] [--no-cold | --cold-only] [NAME ...]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path as FsPath

import numpy as np

from flowmc.devices.linuxcnc.backend import run_program
from flowmc.devices.linuxcnc.compare import flowmc_feed_time
from flowmc.motion.gcode import read_gcode
from flowmc.motion.gcode_write import path_to_gcode
from flowmc.motion.lookahead import plan_stop_and_go
from flowmc.motion.machine import Axis, Machine
from flowmc.motion.metrics import contour_error, farthest_from, programmed_polyline
from flowmc.motion.path import Path
from flowmc.motion.planner import plan_smooth

ROOT = FsPath(__file__).resolve().parents[1]
NCFILES = FsPath("/usr/share/linuxcnc/ncfiles")
CAM = ("flowsnake", "3D_Chips", "spiral", "arcspiral", "3dtest", "raster")
REFERENCE = ("mixed", "star10", "zigzag40", "ellipse200")
FEED = 200.0  # mm/s: F12000 mm/min
TOL = 0.05
JERK = 5000.0


def machine(jerk: float = JERK, period: float = 0.001) -> Machine:
    return Machine(axes=tuple(Axis(name=n, min=-500, max=500, vmax=200, amax=200, jmax=jerk) for n in "XYZ"),
                   period=period)


def raster_gcode(step: float = 0.25, stepover: float = 1.0, width: float = 40.0, lines: int = 20) -> str:
    """A dense finishing raster over z = 2 sin(x/4) cos(y/5): back and forth along X, ``step`` mm moves."""
    out = ["G21 G90 G17 G64 P0.05", "G0 Z5", "G0 X0 Y0"]
    xs = np.linspace(0.0, width, int(round(width / step)) + 1)
    for i in range(lines):
        y = i * stepover
        row = xs if i % 2 == 0 else xs[::-1]
        z = 2.0 * np.sin(row / 4.0) * np.cos(y / 5.0) - 3.0
        out.append(f"G1 X{row[0]:.4f} Y{y:.4f} Z{z[0]:.4f} F12000")
        out += [f"X{x:.4f} Z{zz:.4f}" for x, zz in zip(row[1:], z[1:])]
    out += ["G0 Z5", "M2"]
    return "\n".join(out) + "\n"


def program_path(name: str) -> Path:
    """The program as flowmc's G-code reader reads it (LinuxCNC semantics), every feed F12000."""
    if name == "raster":
        import tempfile
        with tempfile.TemporaryDirectory() as tmp:
            file = FsPath(tmp) / "raster.ngc"
            file.write_text(raster_gcode())
            return read_gcode(file).with_feed(FEED)
    return read_gcode(NCFILES / f"{name}.ngc").with_feed(FEED)


def reference_path(name: str) -> Path:
    data = json.loads((ROOT / "tests" / "data" / "reference" / "paths" / f"{name}.json").read_text())
    pts = np.array(data["points"], dtype=float)
    return Path.polyline(np.c_[pts, np.zeros(len(pts))], feed=FEED)


def sampled(traj_positions: np.ndarray, period: float, limit: float) -> dict:
    d, out = traj_positions, {}
    for name in ("v", "a", "j"):
        d = np.diff(d, axis=0) / period
        out[name] = float(np.abs(d).max())
    return out


def feed_points(path: Path, spacing: float = 0.005) -> np.ndarray:
    """Points at most ``spacing`` apart along the path's feed moves (rapids are not cut, so not judged)."""
    pts, seg = path.sample(1e-4)  # every point after the first ends a chord of the segment it belongs to
    feed = np.array([not s.rapid for s in path.segments])
    keep = feed[seg[1:]]
    a, b = pts[:-1][keep], pts[1:][keep]
    n = np.maximum(1, np.ceil(np.linalg.norm(b - a, axis=1) / spacing).astype(int))
    frac = np.concatenate([np.arange(k) / k for k in n])
    owner = np.repeat(np.arange(len(a)), n)
    return np.vstack([a[owner] + frac[:, None] * (b - a)[owner], b[-1:]])


def measure(positions: np.ndarray, period: float, path: Path, cutting: np.ndarray) -> dict:
    """Peaks per axis; deviation both ways over the feed moves: every chord between two setpoints on a feed
    move to the programmed path, and every point of a feed move to the tool path."""
    programmed = programmed_polyline(path)
    out = sampled(positions, period, 200.0)
    edges = np.flatnonzero(np.diff(np.r_[0, cutting.astype(int), 0]))
    out["dev_to_path"] = max((contour_error(positions[a:b + 1], programmed) for a, b in zip(edges[::2], edges[1::2])),
                             default=0.0)
    out["dev_from_path"] = farthest_from(positions, feed_points(path))
    return out


def cutting(traj, path: Path) -> np.ndarray:
    """Per chord: on a feed move (not a rapid, not a dwell)."""
    feed = np.array([not (s.rapid or s.kind == "dwell") for s in path.segments])
    return feed[traj.segment[1:]]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("names", nargs="*", default=[*CAM, *REFERENCE])
    ap.add_argument("--no-linuxcnc", action="store_true")
    ap.add_argument("--no-toppra", action="store_true")
    ap.add_argument("--no-cold", action="store_true")
    ap.add_argument("--cold-only", action="store_true", help="only the cold-process table (3D_Chips beside rs274)")
    args = ap.parse_args()
    if args.cold_only:
        cold_start()
        return
    if not args.no_toppra:
        sys.path.insert(0, str(FsPath(__file__).parent))
        from toppra_reference import toppra_time
    m = machine()
    rows = []
    for name in args.names:
        path = program_path(name) if name in CAM else reference_path(name)
        t0 = time.perf_counter()
        trap = plan_smooth(path, m, tolerance=TOL)
        wall_trap = time.perf_counter() - t0
        t0 = time.perf_counter()
        scurve = plan_smooth(path, m, tolerance=TOL, profile="scurve")
        wall_s = time.perf_counter() - t0
        row = {"name": name, "segments": len(path), "wall_trap": wall_trap, "wall_scurve": wall_s,
               "trap_feed": flowmc_feed_time(trap.trajectory, path), "trap_total": trap.cycle_time,
               "s_feed": flowmc_feed_time(scurve.trajectory, path), "s_total": scurve.cycle_time,
               "trap": measure(trap.trajectory.positions, 0.001, path, cutting(trap.trajectory, path)),
               "s": measure(scurve.trajectory.positions, 0.001, path, cutting(scurve.trajectory, path))}
        if not args.no_toppra:
            row["topp"] = toppra_time(trap, m, FEED, grid_step=0.05 if len(path) > 200 else 0.01)
        if not args.no_linuxcnc:
            run = run_program(path_to_gcode(path, blend_tolerance=TOL), m, timeout=1200.0, name=f"{name}.ngc")
            row["lcnc_feed"] = run.feed_time
            row["lcnc"] = measure(run.samples, run.servo_period, path, np.isin(run.motion_type[1:], (2, 3)))
        rows.append(row)
        print(json.dumps({k: (round(v, 4) if isinstance(v, float) else v) for k, v in row.items()
                          if not isinstance(v, dict)}), flush=True)
    report(rows, args)
    if not args.no_cold:
        cold_start()


_COLD_CHILD = """
import time
t0, c0 = time.perf_counter(), time.process_time()
import json
from flowmc.motion.gcode import read_gcode
from flowmc.motion.machine import Axis, Machine
from flowmc.motion.planner import plan_smooth
t1, c1 = time.perf_counter(), time.process_time()
path = read_gcode({file!r}).with_feed({feed!r})
t2, c2 = time.perf_counter(), time.process_time()
machine = Machine(axes=tuple(Axis(name=n, min=-500, max=500, vmax=200, amax=200, jmax={jerk!r}) for n in "XYZ"),
                  period=0.001)
plan = plan_smooth(path, machine, tolerance={tol!r})
t3, c3 = time.perf_counter(), time.process_time()
print(json.dumps({{"import": (t1 - t0, c1 - c0), "read": (t2 - t1, c2 - c1), "plan": (t3 - t2, c3 - c2),
                  "setpoints": len(plan.trajectory)}}))
"""


def cold_start(name: str = "3D_Chips", runs: int = 3) -> None:
    """LinuxCNC's rs274 interpreting the program beside a fresh Python process that imports flowmc, reads the
    program and plans it (trapezoid, T = 1 ms), in turns: medians of ``runs`` of the whole process's wall
    and CPU time (user + system, from the OS), and of the flowmc process's own phases (its wall and CPU
    clocks; the machine is shared, so CPU time is the steadier figure)."""
    import resource
    import statistics
    import tempfile

    from flowmc.devices.linuxcnc.rs274 import number_lines

    table = ROOT / "flowmc" / "devices" / "linuxcnc" / "config" / "tool.tbl"
    # the child imports only what reading and planning need (not this benchmark's LinuxCNC backend)
    script = _COLD_CHILD.format(file=str(NCFILES / f"{name}.ngc"), feed=FEED, jerk=JERK, tol=TOL)
    assert machine().axes[0].jmax == JERK and machine().period == 0.001  # the child's machine is machine()
    timings: dict[str, list[tuple[float, float]]] = {"rs274": [], "flowmc": []}
    phases = []
    with tempfile.TemporaryDirectory() as tmp:
        prog = FsPath(tmp) / f"{name}.ngc"
        prog.write_text(number_lines((NCFILES / f"{name}.ngc").read_text()))
        for _ in range(runs):
            for key, argv in (("rs274", ["rs274", "-t", str(table), "-g", str(prog)]),
                              ("flowmc", [sys.executable, "-c", script])):
                before = resource.getrusage(resource.RUSAGE_CHILDREN)
                t0 = time.perf_counter()
                out = subprocess.run(argv, capture_output=True, stdin=subprocess.DEVNULL, check=True, cwd=tmp,
                                     text=True)
                wall = time.perf_counter() - t0
                after = resource.getrusage(resource.RUSAGE_CHILDREN)
                cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
                timings[key].append((wall, cpu))
                if key == "flowmc":
                    phases.append(json.loads(out.stdout.strip().splitlines()[-1]))

    def med(values) -> float:
        return statistics.median(values)

    rs_wall, rs_cpu = med(w for w, _ in timings["rs274"]), med(c for _, c in timings["rs274"])
    fm_wall, fm_cpu = med(w for w, _ in timings["flowmc"]), med(c for _, c in timings["flowmc"])
    print(f"\nCold process, {name} ({phases[0]['setpoints']} setpoints; medians of {runs}, taken in turns; "
          f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores)\n")
    print("| process | wall s | CPU s | wall / rs274 |")
    print("|---|---|---|---|")
    print(f"| rs274 interprets it | {rs_wall:.2f} | {rs_cpu:.2f} | 1 |")
    print(f"| flowmc imports, reads and plans it (trapezoid, T = 1 ms) | {fm_wall:.2f} | {fm_cpu:.2f} | "
          f"{fm_wall / rs_wall:.1f} |")
    for key, what in (("import", "import flowmc and the planner"), ("read", "read the G-code"),
                      ("plan", "plan (smoothing, time law, sampling)")):
        print(f"| ... {what} | {med(p[key][0] for p in phases):.2f} | {med(p[key][1] for p in phases):.2f} | |")


def report(rows: list[dict], args) -> None:
    print("\nTrapezoid, per-axis 200 mm/s and 200 mm/s^2, tolerance 0.05 mm, T = 1 ms (feed moves, s)\n")
    head = (f"{'program':<11}{'segs':>6}{'flowmc':>9}{'LinuxCNC':>10}{'ratio':>7}{'TOPP-RA':>9}{'/topp':>7}"
            f"{'dev->':>8}{'dev<-':>8}{'LC dev->':>9}{'LC dev<-':>9}{'v/vmax':>7}{'a/amax':>7}{'LC v':>6}{'LC a':>6}"
            f"{'plan s':>8}")
    print(head)
    print("-" * len(head))
    for r in rows:
        lc = r.get("lcnc_feed", float("nan"))
        lcd = r.get("lcnc", {})
        print(f"{r['name']:<11}{r['segments']:>6}{r['trap_feed']:>9.3f}{lc:>10.3f}{r['trap_feed'] / lc:>7.3f}"
              f"{r.get('topp', float('nan')):>9.3f}{r['trap_total'] / r.get('topp', float('nan')):>7.3f}"
              f"{r['trap']['dev_to_path']:>8.4f}{r['trap']['dev_from_path']:>8.4f}"
              f"{lcd.get('dev_to_path', float('nan')):>9.4f}{lcd.get('dev_from_path', float('nan')):>9.4f}"
              f"{r['trap']['v'] / 200:>7.3f}{r['trap']['a'] / 200:>7.3f}{lcd.get('v', float('nan')) / 200:>6.2f}"
              f"{lcd.get('a', float('nan')) / 200:>6.2f}{r['wall_trap']:>8.2f}")
    print("\nS-curve, per-axis jerk 5000 mm/s^3 (and the same limits), T = 1 ms\n")
    head = (f"{'program':<11}{'S-curve s':>10}{'/ trap':>8}{'v/vmax':>8}{'a/amax':>8}{'j/jmax':>8}{'dev->':>8}{'dev<-':>8}"
            f"{'plan s':>8}")
    print(head)
    print("-" * len(head))
    for r in rows:
        print(f"{r['name']:<11}{r['s_feed']:>10.3f}{r['s_feed'] / r['trap_feed']:>8.3f}{r['s']['v'] / 200:>8.3f}"
              f"{r['s']['a'] / 200:>8.3f}{r['s']['j'] / JERK:>8.3f}"
              f"{r['s']['dev_to_path']:>8.4f}{r['s']['dev_from_path']:>8.4f}{r['wall_scurve']:>8.2f}")
    if "mixed" in [r["name"] for r in rows]:
        m4 = machine(500.0, 0.004)
        path = reference_path("mixed")
        s500 = plan_smooth(path, m4, tolerance=TOL, profile="scurve")
        base = plan_stop_and_go(path, m4, profile="trapezoid")
        j = float(np.abs(np.diff(s500.trajectory.positions, 3, axis=0)).max()) / 0.004**3
        print(f"\nmixed at j = 500 mm/s^3, T = 4 ms: S-curve {s500.cycle_time:.3f} s, stop-and-go trapezoid "
              f"{base.cycle_time:.3f} s, ratio {s500.cycle_time / base.cycle_time:.3f} (target 0.64); "
              f"peak jerk {j / 500:.3f} x limit")
    print("\nTargets")
    checks = []
    for r in rows:
        if "lcnc_feed" in r:
            checks.append((f"{r['name']}: trapezoid {r['trap_feed'] / r['lcnc_feed']:.3f} x LinuxCNC <= 0.90",
                           r["trap_feed"] <= 0.9 * r["lcnc_feed"]))
        dev = max(r["trap"]["dev_to_path"], r["trap"]["dev_from_path"])
        checks.append((f"{r['name']}: trapezoid deviation {dev:.4f} mm <= 0.05 both ways", dev <= TOL))
        checks.append((f"{r['name']}: S-curve peak jerk {r['s']['j'] / JERK:.3f} x limit <= 1.05",
                       r["s"]["j"] <= 1.05 * JERK))
        checks.append((f"{r['name']}: S-curve {r['s_feed'] / r['trap_feed']:.3f} x trapezoid <= 1.3",
                       r["s_feed"] <= 1.3 * r["trap_feed"]))
    for text, ok in checks:
        print(f"  [{'PASS' if ok else 'FAIL'}] {text}")


if __name__ == "__main__":
    main()
