"""Sweep benchmark: a 300-variant sweep of graphs/arm_lookahead.flowmc.json (look-ahead tolerance x corner
rule), with ``flowmc sweep`` on the local and the Dask executor, 1 and 2 workers, against a shell loop of
``flowmc run`` (one process per variant, as users did before sweeps).

Every figure is end to end, as a user waits for it: ``flowmc sweep`` from process start to the written
CSV, Parquet and report (worker start-up included). The shell loop is timed on ``--loop-runs`` variants
and scaled to the sweep's size (said so in the table). Configurations run side by side, round after
round, and the table gives medians over the rounds: the machine is shared. Target: the sweep at least
20x faster than the loop on a 2-core machine.

Per-variant overhead: the run phase's wall time per variant times the workers, less the median time a
worker spent inside a variant (what the executor, the transfer and the bookkeeping add).

    python3 benchmarks/sweep.py [--rounds 3] [--loop-runs 12] [--step 0.005]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
GRAPH = REPO / "graphs" / "arm_lookahead.flowmc.json"
RULES = ("blend", "arm_weighted", "junction_deviation")
CONFIGS = [("local", 1), ("local", 2), ("dask", 1), ("dask", 2)]


def tolerances(step: float) -> list[float]:
    count = round(0.5 / step)
    return [round(step * (k + 1), 10) for k in range(count)]


def flowmc_command() -> list[str]:
    return [sys.executable, "-m", "flowmc"]


def time_loop(runs: list[tuple[float, str]], folder: Path) -> list[float]:
    """A bash loop of ``flowmc run``, one process per variant; the seconds each took."""
    script = folder / "loop.sh"
    lines = ["set -e", f'TIMES="{folder / "times.txt"}"', ': > "$TIMES"']
    cmd = " ".join(flowmc_command())
    for tol, rule in runs:
        lines.append(f"s=$(date +%s.%N); {cmd} run {GRAPH} --set lookahead.tolerance={tol} --input rule={rule} -q "
                     f"> /dev/null || true; e=$(date +%s.%N); echo \"$s $e\" >> \"$TIMES\"")
    script.write_text("\n".join(lines) + "\n")
    subprocess.run(["bash", str(script)], check=True)
    return [float(e) - float(s) for s, e in (line.split() for line in (folder / "times.txt").read_text().splitlines())]


def time_sweep(executor: str, workers: int, step: float, folder: Path) -> dict:
    out = folder / f"{executor}{workers}"
    shutil.rmtree(out, ignore_errors=True)
    args = [*flowmc_command(), "sweep", str(GRAPH), "--grid", f"lookahead.tolerance={step}:0.5:{step}",
            "--grid", "rule=" + ",".join(RULES), "--executor", executor, "--workers", str(workers), "--out", str(out),
            "-q"]
    start = time.perf_counter()
    proc = subprocess.run(args, capture_output=True, text=True)
    wall = time.perf_counter() - start
    if proc.returncode not in (0, 1):
        raise SystemExit(f"flowmc sweep failed ({proc.returncode}): {proc.stderr}")
    run_phase = float(re.search(r"this run took ([0-9.]+) s", proc.stdout).group(1))
    rows = [json.loads(line) for line in (out / "rows.jsonl").read_text().splitlines()]
    inside = statistics.median(r["duration_s"] for r in rows)
    return {"wall": wall, "run": run_phase, "rows": len(rows), "inside": inside,
            "overhead_ms": 1000 * (run_phase * workers / len(rows) - inside),
            "cached": statistics.mean(r["cached"] for r in rows), "nodes": statistics.mean(r["cached"] + r["ran"]
                                                                                          for r in rows)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--loop-runs", type=int, default=12, help="flowmc run processes timed per round")
    parser.add_argument("--step", type=float, default=0.005, help="tolerance step (0.005: 100 x 3 rules = 300)")
    args = parser.parse_args()
    tols = tolerances(args.step)
    variants = len(tols) * len(RULES)
    sample = [(tols[(k * 7) % len(tols)], RULES[k % len(RULES)]) for k in range(args.loop_runs)]
    results: dict[str, list] = {"loop": []}
    with tempfile.TemporaryDirectory(prefix="flowmc-bench-sweep-") as tmp:
        folder = Path(tmp)
        for r in range(args.rounds):
            results["loop"] += time_loop(sample, folder)
            for executor, workers in CONFIGS:
                results.setdefault((executor, workers), []).append(time_sweep(executor, workers, args.step, folder))
            print(f"round {r + 1}/{args.rounds} done", file=sys.stderr, flush=True)

    per_run = statistics.median(results["loop"])
    loop_total = per_run * variants
    print(f"\nSweep of {GRAPH.name}: {variants} variants ({len(tols)} tolerances x {len(RULES)} rules), "
          f"{os.cpu_count()} cores, medians of {args.rounds} rounds run side by side\n")
    print("| how | workers | wall s | variants/s | vs loop | run phase s | in a variant ms | per-variant overhead ms "
          "| nodes cached |")
    print("|---|---|---|---|---|---|---|---|---|")
    print(f"| shell loop of `flowmc run` ({len(results['loop'])} runs timed, x{variants} scaled) | 1 | {loop_total:.1f} | "
          f"{variants / loop_total:.2f} | 1x | - | - | {1000 * per_run:.0f} (a process each) | 0 |")
    run_phase = {}
    for executor, workers in CONFIGS:
        rounds = results[(executor, workers)]
        assert all(r["rows"] == variants for r in rounds)
        wall = statistics.median(r["wall"] for r in rounds)
        run_phase[(executor, workers)] = statistics.median(r["run"] for r in rounds)
        overhead = statistics.median(r["overhead_ms"] for r in rounds)
        cached = statistics.median(r["cached"] for r in rounds)
        inside = statistics.median(r["inside"] for r in rounds)
        nodes = rounds[0]["nodes"]
        print(f"| `flowmc sweep --executor {executor}` | {workers} | {wall:.1f} | {variants / wall:.1f} | "
              f"{loop_total / wall:.0f}x | {run_phase[(executor, workers)]:.2f} | {1000 * inside:.1f} | {overhead:.1f} | "
              f"{cached:.1f} of {nodes:.0f} |")
    print("\nin a variant: median time a worker spent inside one variant (it grows when the workers do not get a "
          "core each).")
    for executor in ("local", "dask"):
        print(f"Scaling {executor}, 1 -> 2 workers: run phase {run_phase[(executor, 1)]:.2f} s -> "
              f"{run_phase[(executor, 2)]:.2f} s ({run_phase[(executor, 1)] / run_phase[(executor, 2)]:.2f}x)")
    best = min(statistics.median(r["wall"] for r in results[c]) for c in CONFIGS if c[1] == 2)
    print(f"Target: >= 20x faster than the loop with 2 workers: {loop_total / best:.0f}x "
          f"({'met' if loop_total / best >= 20 else 'NOT met'}).")


if __name__ == "__main__":
    main()
