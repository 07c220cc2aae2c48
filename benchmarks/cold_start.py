"""Cold-start benchmark: whole processes of ``flowmc validate`` / ``flowmc run`` beside ``python -c pass``.

Each round starts every command once, in turn, so a slow spell of the (shared) machine hits them all;
the table gives medians of wall and CPU time (the process's user + system, from the OS) over the
rounds, and each command's median ratio to ``python -c pass`` from the same rounds. Target on a 2-core
machine: ``flowmc validate`` of an example graph in at most 0.35 s.

The "pydantic floor" row is what any process pays that validates one pydantic model (import pydantic,
define a model, validate once): the graph file is a pydantic model, so validate cannot start faster
than that; the rows beside it show what flowmc adds on top.

Byte-code caching is on (as after ``pip install``), whatever PYTHONDONTWRITEBYTECODE says; one round
runs first, untimed, to write the caches.

``--against PYTHON`` also times the flowmc commands with another interpreter (one with another
checkout of flowmc installed, e.g. main's), in the same rounds, with its median ratio to this one's.

    python3 benchmarks/cold_start.py [--rounds 15] [--graph graphs/thesis_3axis.flowmc.json] [--against PYTHON]
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
PYDANTIC_FLOOR = "from pydantic import BaseModel\nclass M(BaseModel):\n    x: int = 0\nM(x=1)"


def timed(command: list[str], env: dict[str, str], cwd: Path) -> tuple[float, float]:
    """Wall and CPU seconds of one run of ``command`` in ``cwd`` (it must succeed). ``python -m`` imports
    from its working folder first, so that is the graph's folder, not a checkout."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    proc = subprocess.run(command, env=env, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(command)} failed: {proc.stderr}")
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=15)
    parser.add_argument("--graph", type=Path, default=REPO / "graphs" / "thesis_3axis.flowmc.json")
    parser.add_argument("--against", metavar="PYTHON", help="another interpreter, another flowmc installed")
    args = parser.parse_args()
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    py = sys.executable
    commands = {
        "python -c pass": [py, "-c", "pass"],
        "python -c 'import flowmc'": [py, "-c", "import flowmc"],
        "pydantic floor": [py, "-c", PYDANTIC_FLOOR],
        "flowmc validate GRAPH": [py, "-m", "flowmc", "validate", str(args.graph)],
        "flowmc --help": [py, "-m", "flowmc", "--help"],
    }
    if args.against:
        for name in ("python -c 'import flowmc'", "flowmc validate GRAPH", "flowmc --help"):
            commands[f"{name} [against]"] = [args.against, *commands[name][1:]]
    for command in commands.values():  # write the byte-code caches
        timed(command, env, args.graph.parent)
    runs: dict[str, list[tuple[float, float]]] = {name: [] for name in commands}
    for _ in range(args.rounds):
        for name, command in commands.items():
            runs[name].append(timed(command, env, args.graph.parent))
    base = runs["python -c pass"]
    print(f"Cold start, {args.rounds} rounds side by side, {os.cpu_count()} cores, graph {args.graph.name}")
    for label, python in (("", py), (" [against]", args.against)):
        if python:
            where = subprocess.run([python, "-c", "import flowmc; print(flowmc.__file__)"], env=env,
                                   capture_output=True, text=True, cwd=args.graph.parent).stdout.strip()
            print(f"flowmc{label}: {python} -> {where}")
    print()
    print("| command | wall s (median) | cpu s (median) | wall / python -c pass | cpu / python -c pass |")
    print("|---|---|---|---|---|")
    for name, samples in runs.items():
        wall = statistics.median(w for w, _ in samples)
        cpu = statistics.median(c for _, c in samples)
        wall_ratio = statistics.median(w / b for (w, _), (b, _) in zip(samples, base))
        cpu_ratio = statistics.median(c / max(b, 1e-6) for (_, c), (_, b) in zip(samples, base))
        print(f"| {name} | {wall:.3f} | {cpu:.3f} | {wall_ratio:.1f}x | {cpu_ratio:.1f}x |")
    for name in [n for n in runs if n.endswith(" [against]")]:
        mine = runs[name.removesuffix(" [against]")]
        ratio = statistics.median(w / a for (w, _), (a, _) in zip(mine, runs[name]))
        print(f"\n{name.removesuffix(' [against]')}: this / against = {ratio:.2f} (median of per-round wall ratios)", end="")
    if args.against:
        print()
    validate = statistics.median(w for w, _ in runs["flowmc validate GRAPH"])
    print(f"\nflowmc validate: {validate:.3f} s median wall (target <= {TARGET_S} s): "
          f"{'met' if validate <= TARGET_S else 'NOT met'}")


if __name__ == "__main__":
    main()
