"""Cold-start benchmark: whole processes of ``flowmc validate`` / ``flowmc run`` beside ``python -c pass``.

Each round starts every command once, in turn, so a slow spell of the (shared) machine hits them all;
the table gives medians of wall and CPU time (the process's user + system, from the OS) over the
rounds, and each command's median ratio to ``python -c pass`` from the same rounds. Target on a 2-core
machine: ``flowmc validate`` of an example graph in at most 0.35 s.

Byte-code caching is on (as after ``pip install``), whatever PYTHONDONTWRITEBYTECODE says; one round
runs first, untimed, to write the caches.

    python3 benchmarks/cold_start.py [--rounds 15] [--graph graphs/thesis_3axis.flowmc.json]
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
TARGET_S = 0.35


def timed(command: list[str], env: dict[str, str]) -> tuple[float, float]:
    """Wall and CPU seconds of one run of ``command`` (it must succeed)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    proc = subprocess.run(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(command)} failed: {proc.stderr}")
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=15)
    parser.add_argument("--graph", type=Path, default=REPO / "graphs" / "thesis_3axis.flowmc.json")
    args = parser.parse_args()
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    py = sys.executable
    commands = {
        "python -c pass": [py, "-c", "pass"],
        "python -c 'import flowmc'": [py, "-c", "import flowmc"],
        "flowmc validate GRAPH": [py, "-m", "flowmc", "validate", str(args.graph)],
        "flowmc --help": [py, "-m", "flowmc", "--help"],
    }
    for command in commands.values():  # write the byte-code caches
        timed(command, env)
    runs: dict[str, list[tuple[float, float]]] = {name: [] for name in commands}
    for _ in range(args.rounds):
        for name, command in commands.items():
            runs[name].append(timed(command, env))
    base = runs["python -c pass"]
    print(f"Cold start, {args.rounds} rounds side by side, {os.cpu_count()} cores, graph {args.graph.name}\n")
    print("| command | wall s (median) | cpu s (median) | wall / python -c pass | cpu / python -c pass |")
    print("|---|---|---|---|---|")
    for name, samples in runs.items():
        wall = statistics.median(w for w, _ in samples)
        cpu = statistics.median(c for _, c in samples)
        wall_ratio = statistics.median(w / b for (w, _), (b, _) in zip(samples, base))
        cpu_ratio = statistics.median(c / max(b, 1e-6) for (_, c), (_, b) in zip(samples, base))
        print(f"| {name} | {wall:.3f} | {cpu:.3f} | {wall_ratio:.1f}x | {cpu_ratio:.1f}x |")
    validate = statistics.median(w for w, _ in runs["flowmc validate GRAPH"])
    print(f"\nflowmc validate: {validate:.3f} s median wall (target <= {TARGET_S} s): "
          f"{'met' if validate <= TARGET_S else 'NOT met'}")


if __name__ == "__main__":
    main()
