"""Two source trees of flowmc planning the same programs in one run, for a change's speed on a shared machine.

Warm: one worker process per tree (PYTHONPATH set to the tree), each planning a program once to warm up,
then the two plan it in strict turns (who goes first alternates), ``--rounds`` times; CPU time of each
plan (the process's own clock). Medians per tree, setpoints per second, and the median of the paired
ratios (B / A), which a busy spell hits on both sides alike. Cold (``--cold N``): N fresh processes per
tree, alternated, each importing the reader and planner, reading the program and planning it (trapezoid),
as benchmarks/cam_programs.py's cold table does; CPU time of the whole process from the OS. Programs
are cam_programs.py's, the four reference paths among them (its machine, T = 1 ms, tolerance 0.05 mm). A tree
is a folder holding ``flowmc/`` (a worktree, or ``git archive REV | tar -x -C DIR``).

    python3 benchmarks/side_by_side.py TREE_A TREE_B [PROGRAM:PROFILE ...] [--rounds 7] [--cold 5]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
from pathlib import Path as FsPath

sys.path.insert(0, str(FsPath(__file__).parent))
import cam_programs  # noqa: E402

WORKER = """
import json, sys, time
sys.path.insert(0, {bench!r})
from cam_programs import REFERENCE, machine, program_path, reference_path
from flowmc.motion.planner import plan_smooth
paths = {{}}
for line in sys.stdin:
    name, profile = line.split()
    if name not in paths:
        paths[name] = reference_path(name) if name in REFERENCE else program_path(name)
        plan_smooth(paths[name], machine(), tolerance=0.05, profile=profile)
    c = time.process_time()
    plan = plan_smooth(paths[name], machine(), tolerance=0.05, profile=profile)
    print(json.dumps([time.process_time() - c, len(plan.trajectory)]), flush=True)
"""


def env_for(tree: str) -> dict:
    return {**os.environ, "PYTHONPATH": str(FsPath(tree).resolve())}


def warm(trees: list[str], jobs: list[tuple[str, str]], rounds: int) -> None:
    bench = str(FsPath(__file__).resolve().parent)
    workers = [subprocess.Popen([sys.executable, "-c", WORKER.format(bench=bench)], stdin=subprocess.PIPE,
                                stdout=subprocess.PIPE, text=True, env=env_for(t), cwd="/") for t in trees]
    print(f"Warm plans, CPU s, {rounds} in strict turns; A = {trees[0]}, B = {trees[1]}\n")
    print(f"{'program':<11}{'profile':<11}{'setpoints':>10}{'A s':>8}{'A setpts/s':>12}{'B s':>8}{'B setpts/s':>12}"
          f"{'B/A paired':>12}{'load':>6}")
    try:
        for name, profile in jobs:
            cpu: list[list[float]] = [[], []]
            n = 0
            for r in range(rounds):
                for i in ((0, 1) if r % 2 == 0 else (1, 0)):
                    workers[i].stdin.write(f"{name} {profile}\n")
                    workers[i].stdin.flush()
                    seconds, n = json.loads(workers[i].stdout.readline())
                    cpu[i].append(seconds)
            a, b = statistics.median(cpu[0]), statistics.median(cpu[1])
            paired = statistics.median(y / x for x, y in zip(*cpu))
            print(f"{name:<11}{profile:<11}{n:>10}{a:>8.3f}{n / a:>12.3g}{b:>8.3f}{n / b:>12.3g}{paired:>12.3f}"
                  f"{os.getloadavg()[0]:>6.1f}", flush=True)
    finally:
        for w in workers:
            w.stdin.close()
            w.wait()


def cold(trees: list[str], name: str, runs: int) -> None:
    script = cam_programs._COLD_CHILD.format(file=str(cam_programs.NCFILES / f"{name}.ngc"), feed=cam_programs.FEED,
                                             jerk=cam_programs.JERK, tol=cam_programs.TOL)
    rows: list[list[tuple]] = [[], []]
    for r in range(runs):
        for i in ((0, 1) if r % 2 == 0 else (1, 0)):
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env_for(trees[i]),
                                 cwd="/", check=True)
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            phases = json.loads(out.stdout.strip().splitlines()[-1])
            rows[i].append(((after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime),
                            phases["import"][1], phases["read"][1], phases["plan"][1]))
    print(f"\nCold process, {name} (trapezoid), CPU s, medians of {runs} alternated (load {os.getloadavg()[0]:.1f})\n")
    print(f"{'tree':<6}{'process':>9}{'import':>8}{'read':>7}{'plan':>7}  every process")
    for label, data in zip("AB", rows):
        med = [statistics.median(x[k] for x in data) for k in range(4)]
        print(f"{label:<6}{med[0]:>9.2f}{med[1]:>8.2f}{med[2]:>7.2f}{med[3]:>7.2f}  {[round(x[0], 2) for x in data]}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("tree_a")
    ap.add_argument("tree_b")
    ap.add_argument("jobs", nargs="*", default=["3D_Chips:trapezoid", "3D_Chips:scurve", "flowsnake:trapezoid",
                                                 "spiral:trapezoid"])
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--cold", type=int, default=0, help="fresh processes per tree (3D_Chips and flowsnake)")
    args = ap.parse_args()
    trees = [args.tree_a, args.tree_b]
    warm(trees, [tuple(j.split(":")) for j in args.jobs], args.rounds)
    if args.cold:
        for name in ("3D_Chips", "flowsnake"):
            cold(trees, name, args.cold)


if __name__ == "__main__":
    main()
