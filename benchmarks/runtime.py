"""Runtime benchmark: validate + schedule a generated 500-node graph, run it, re-run it cached.

Prints a table of medians over repeats (not a timed test). Targets on a 2-core machine:
validation + scheduling <= 50 ms, fully cached re-run <= 20 ms.

    python3 benchmarks/runtime.py [--nodes 500] [--repeats 21]
"""

from __future__ import annotations

import argparse
import random

from timing import median_ms

import flowmc
from flowmc.graph import Graph


def generate(n_nodes: int, seed: int = 1) -> Graph:
    """A random DAG: 10% number sources, the rest add nodes wired from two earlier nodes."""
    rng = random.Random(seed)
    g = flowmc.GraphBuilder(title=f"bench {n_nodes}")
    refs = []
    n_sources = max(2, n_nodes // 10)
    for i in range(n_sources):
        refs.append(g.add("basic.number", id=f"src{i:04d}", value=rng.uniform(-1, 1)))
    for i in range(n_nodes - n_sources):
        node = g.add("basic.add", id=f"add{i:04d}", a=0.0, b=0.0)
        a, b = rng.sample(refs[-60:], 2)
        g.wire(a.value if a.id.startswith("src") else a.result, node.a)
        g.wire(b.value if b.id.startswith("src") else b.result, node.b)
        refs.append(node)
    return g.build()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--nodes", type=int, default=500)
    parser.add_argument("--repeats", type=int, default=21)
    args = parser.parse_args()
    graph = generate(args.nodes)
    flowmc.Runtime().plan(graph)  # warm imports and node modules

    def cold_plan():
        plan = flowmc.Runtime().plan(graph)
        assert plan.ok, plan.issues[:3]

    warm = flowmc.Runtime()
    warm.plan(graph)

    def first_run():
        flowmc.Runtime().run(graph)

    cached_rt = flowmc.Runtime()
    cached_rt.run(graph)

    def cached_run():
        result = cached_rt.run(graph)
        assert not result.executed

    edit_rt = flowmc.Runtime()
    edit_rt.run(graph)
    middle = graph.node(f"src{max(2, args.nodes // 10) - 1:04d}")
    cone = len(edit_rt.plan(graph).downstream(middle.id)) + 1
    step = [0]

    def one_param_changed():  # a new value each time: a new revision, so it is validated again
        step[0] += 1
        middle.params["value"] = float(step[0])
        assert len(edit_rt.run(graph).executed) == cone

    rows = [
        ("validate + schedule (new runtime)", median_ms(cold_plan, args.repeats), 50.0),
        ("plan reuse (same revision)", median_ms(lambda: warm.plan(graph), args.repeats), None),
        ("first run (nothing cached)", median_ms(first_run, args.repeats), None),
        ("re-run, fully cached", median_ms(cached_run, args.repeats), 20.0),
        ("re-run, one source param changed", median_ms(one_param_changed, args.repeats), None),
    ]
    print(f"flowmc runtime benchmark: {args.nodes} nodes, {len(graph.wires)} wires, median of {args.repeats}")
    print(f"{'case':<36} {'median ms':>10} {'target ms':>10} {'ratio':>7}")
    for name, ms, target in rows:
        ratio = f"{ms / target:.2f}" if target else ""
        print(f"{name:<36} {ms:>10.2f} {target if target else '':>10} {ratio:>7}")
    print(f"(one param changed: re-validated, then its downstream cone re-runs: {cone} of {args.nodes} nodes)")


if __name__ == "__main__":
    main()
