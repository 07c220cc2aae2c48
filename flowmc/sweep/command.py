"""``flowmc sweep GRAPH``: the command line over ``flowmc.sweep``.

Exit codes: 0 every variant done, 1 some variant failed (its row says why) or a worker was lost,
2 the graph or an argument is invalid (nothing ran), 130 stopped by Ctrl-C (the rows done so far are
written; ``--resume`` carries on).
"""

from __future__ import annotations

import sys
import time
from collections import Counter
from pathlib import Path
from typing import Any

from flowmc.graph import load
from flowmc.settings import UsageError
from flowmc.sweep.executors import open_executor
from flowmc.sweep.report import choose, write_report
from flowmc.sweep.results import Journal, write_tables
from flowmc.sweep.sweep import Outcome, Progress, Sweep
from flowmc.sweep.variants import files_axis, grid_axis, table_axis

__all__ = ["sweep_main"]


def _split(text: str | None) -> list[str] | None:
    return [t.strip() for t in text.split(",") if t.strip()] if text else None


class _ProgressLine:
    """A tqdm bar on a terminal; elsewhere (logs, CI) a plain line at most every few seconds."""

    def __init__(self, total: int, quiet: bool):
        self.quiet, self.last = quiet, 0.0
        self.bar = None
        if not quiet and sys.stderr.isatty():
            from tqdm import tqdm

            self.bar = tqdm(total=total, unit="variant", file=sys.stderr, dynamic_ncols=True)

    def __call__(self, p: Progress) -> None:
        if self.bar is not None:
            self.bar.n = p.done + p.failed
            self.bar.set_postfix_str(f"done {p.done}, failed {p.failed}, left {p.left}", refresh=False)
            self.bar.refresh()
        elif not self.quiet and (time.monotonic() - self.last > 5.0 or p.left == 0):
            self.last = time.monotonic()
            print(f"[{p.done + p.failed}/{p.total}] done {p.done}, failed {p.failed}, left {p.left}, "
                  f"{p.rate:.1f} variants/s", file=sys.stderr, flush=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def sweep_main(args: Any, registry: Any) -> int:
    """``flowmc sweep``: ``registry`` holds the node types (with ``--nodes`` folders) the graph is checked with."""
    graph = load(args.graph)
    axes = [grid_axis(graph, g, registry=registry) for g in args.grid]
    axes += [files_axis(graph, o, registry=registry) for o in args.over]
    if args.table:
        axes.append(table_axis(graph, args.table, registry=registry))
    if not axes:
        raise UsageError("say what to sweep: --grid TARGET=VALUES, --over TARGET=PATTERN or --table FILE")
    if args.scheduler and args.executor != "dask":
        raise UsageError("--scheduler goes with --executor dask")
    for option in ("workers", "batch"):
        if getattr(args, option) is not None and getattr(args, option) < 1:
            raise UsageError(f"--{option} must be at least 1")
    folder = Path(args.out) if args.out else Path(Path(args.graph).name.removesuffix(".json").removesuffix(".flowmc")
                                                    + "-sweep")
    ship = args.ship if args.ship is not None else bool(args.scheduler)
    sweep = Sweep(graph, axes, devices=args.devices, ship=ship, skip=(folder,), registry=registry)
    for note in sweep.safety.notes:
        print(f"note: {note}", file=sys.stderr)
    journal = Journal(folder, resume=args.resume, overwrite=args.overwrite)
    progress = _ProgressLine(len(sweep.variants), args.quiet)
    try:
        with open_executor(args.executor, sweep.job, workers=args.workers, address=args.scheduler,
                           resources=sweep.resources) as executor:
            if not args.quiet:
                print(f"sweeping {len(sweep.variants)} variants of {args.graph} on {executor.describe()}",
                      file=sys.stderr, flush=True)
            outcome = sweep.run(executor, journal, on_progress=progress, size=args.batch)
    finally:
        progress.close()
        journal.close()
    return _finish(args, sweep, outcome, folder)


def _finish(args: Any, sweep: Sweep, outcome: Outcome, folder: Path) -> int:
    paths = write_tables(folder, outcome.columns, outcome.rows)
    counts = Counter(r["status"] for r in outcome.rows)
    not_run = len(sweep.variants) - len(outcome.rows)
    summary = [f"{len(sweep.variants)} variants: {counts['done']} done, {counts['failed']} failed"
               + (f", {counts['lost']} lost" if counts["lost"] else "") + (f", {not_run} not run" if not_run else "")
               + f" ({outcome.skipped} from an earlier run); this run took {outcome.elapsed:.1f} s", *outcome.notes]
    try:
        choice = choose(outcome.columns, outcome.rows, sweep.params, outputs=_split(args.plot),
                        against=_split(args.against), pareto=_split(args.pareto))
    except UsageError as exc:
        print(f"error: {exc} (the tables are written; no report)", file=sys.stderr)
        return 2
    title = f"Sweep of {Path(args.graph).name}"
    paths.append(write_report(folder / "report.html", title=title, summary=summary, choice=choice, rows=outcome.rows,
                              params=sweep.params))
    failed = [r for r in outcome.rows if r["status"] != "done"]
    for row in failed[:5]:
        print(f"variant {row['variant']} {row['status']}: {row['error']}", file=sys.stderr)
    if len(failed) > 5:
        print(f"... and {len(failed) - 5} more not done (see rows.csv)", file=sys.stderr)
    print(summary[0])
    print("wrote " + ", ".join(str(p) for p in paths))
    if outcome.interrupted:
        print(f"interrupted: {not_run} variants not run; run again with --resume to finish", file=sys.stderr)
        return 130
    return 0 if not failed and not not_run else 1
