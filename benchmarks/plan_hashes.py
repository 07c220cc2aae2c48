"""Every blend plan of the benchmarks, hashed, to show a change to the planner's arithmetic leaves plans alone.

The plans: benchmarks/cam_programs.py's programs (trapezoid and S-curve on its machine, T = 1 ms, and its
mixed at j = 500 mm/s^3, T = 4 ms) and benchmarks/planning.py's (the reference paths at T = 4 and 1 ms and
lines+arcs at 1 ms, on its machine). A plan's hash covers its setpoints' positions (bit for bit), the
segment each is tagged with and the period, so equal hashes mean the same plan. ``--save DIR`` also keeps
the arrays; ``--compare DIR`` then reports, for any plan whose hash differs, its largest position
difference (mm) and its duration against the saved one.

    python3 benchmarks/plan_hashes.py [--save DIR | --compare DIR] [NAME ...]
"""

from __future__ import annotations

import argparse
import hashlib
import sys
from pathlib import Path as FsPath

import numpy as np

from flowmc.motion.machine import Machine
from flowmc.motion.planner import plan_smooth

sys.path.insert(0, str(FsPath(__file__).parent))
from cam_programs import CAM, REFERENCE, TOL, machine, program_path, reference_path  # noqa: E402
from planning import NAMES, lines_and_arcs, reference  # noqa: E402


def plans():
    """(name, path, machine, profile) of every blend plan the benchmarks make."""
    for name in (*CAM, *REFERENCE):
        path = program_path(name) if name in CAM else reference_path(name)
        for profile in ("trapezoid", "scurve"):
            yield f"cam/{name}/{profile}", path, machine(), profile
    yield "cam/mixed/scurve/j500/T4", reference_path("mixed"), machine(500.0, 0.004), "scurve"
    programs = [(name, reference(name)[0]) for name in NAMES] + [("lines+arcs", lines_and_arcs())]
    for period in (0.004, 0.001):
        for name, path in programs:
            if name == "lines+arcs" and period == 0.004:
                continue
            for profile in ("trapezoid", "scurve"):
                yield f"planning/{name}/{profile}/T{period * 1e3:g}", path, Machine(period=period), profile


def digest(positions: np.ndarray, segment: np.ndarray, period: float) -> str:
    h = hashlib.sha256()
    for part in (np.ascontiguousarray(positions, dtype=np.float64), np.asarray(segment, dtype=np.int64),
                 np.float64(period)):
        h.update(np.ascontiguousarray(part).tobytes())
    return h.hexdigest()[:16]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("names", nargs="*", help="only plans whose key contains one of these")
    group = ap.add_mutually_exclusive_group()
    group.add_argument("--save", type=FsPath)
    group.add_argument("--compare", type=FsPath)
    args = ap.parse_args()
    if args.save:
        args.save.mkdir(parents=True, exist_ok=True)
    differ = 0
    for key, path, mach, profile in plans():
        if args.names and not any(n in key for n in args.names):
            continue
        traj = plan_smooth(path, mach, tolerance=TOL, profile=profile).trajectory
        h = digest(traj.positions, traj.segment, traj.period)
        line = f"{key:<40}{len(traj):>9} setpoints  {len(traj) * traj.period:>10.3f} s  {h}"
        file = key.replace("/", "_") + ".npz"
        if args.save:
            np.savez(args.save / file, positions=traj.positions, segment=traj.segment, period=traj.period, hash=h)
        elif args.compare:
            old = np.load(args.compare / file)
            if str(old["hash"]) == h:
                line += "  same"
            else:
                differ += 1
                n = min(len(old["positions"]), len(traj))
                dmax = float(np.max(np.abs(old["positions"][:n] - traj.positions[:n]))) if n else 0.0
                tags = "same" if np.array_equal(old["segment"][:n], traj.segment[:n]) else "differ"
                line += (f"  DIFFERS: {len(old['positions'])} -> {len(traj)} setpoints, max |dp| {dmax:.3g} mm over "
                         f"the common ones, segment tags {tags}")
        print(line, flush=True)
    if args.compare:
        print(f"\n{differ} plan(s) differ")


if __name__ == "__main__":
    main()
