"""The options of ``flowmc sweep`` (kept apart so that building the CLI's parser imports nothing heavy)."""

from __future__ import annotations

import argparse

__all__ = ["EXECUTORS", "POLICIES", "add_arguments"]

EXECUTORS = ("local", "dask")
POLICIES = ("refuse", "sim")  # what device nodes that drive hardware get: see flowmc.sweep.safety


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("graph", help="graph file (*.flowmc.json)")
    what = p.add_argument_group("what to sweep (several axes give their product)")
    what.add_argument("--grid", action="append", default=[], metavar="TARGET=V1,V2,...",
                      help="values of a setting: node.param or an interface input name; numbers also as "
                           "start:stop:step (stop included)")
    what.add_argument("--over", action="append", default=[], metavar="TARGET=PATTERN",
                      help="every file a glob pattern matches, e.g. gcode.file=programs/*.ngc")
    what.add_argument("--table", metavar="variants.csv", help="a CSV table: a header of targets, one variant per row")
    how = p.add_argument_group("where it runs")
    how.add_argument("--executor", choices=EXECUTORS, default="local",
                     help="local: processes on this machine; dask: a Dask LocalCluster, or --scheduler")
    how.add_argument("--workers", type=int, metavar="N", help="worker processes (default: one per core)")
    how.add_argument("--scheduler", metavar="ADDRESS", help="a running Dask scheduler, e.g. tcp://10.0.0.5:8786")
    how.add_argument("--ship", action=argparse.BooleanOptionalAction, default=None,
                     help="send the graph's folder to the workers (default: only with --scheduler)")
    how.add_argument("--batch", type=int, metavar="N", help="variants per task (default: about 8 tasks per worker)")
    how.add_argument("--devices", choices=POLICIES, default="refuse",
                     help="device nodes that drive hardware: refuse the sweep (default), or run them on the "
                          "simulated card")
    out = p.add_argument_group("results")
    out.add_argument("--out", metavar="DIR", help="results folder (default: GRAPH-STEM-sweep)")
    out.add_argument("--resume", action="store_true", help="skip the variants the results folder already holds")
    out.add_argument("--overwrite", action="store_true", help="start again in a results folder that holds rows")
    out.add_argument("--plot", metavar="OUT,...", help="outputs to plot (default: the numeric outputs)")
    out.add_argument("--against", metavar="SETTING,...", help="swept settings on the x axis (default: all)")
    out.add_argument("--pareto", metavar="A,B", help="two objectives for a Pareto front (minimised; max:NAME maximises)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress on stderr")
