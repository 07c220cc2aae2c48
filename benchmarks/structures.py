"""Loop benchmark: what a For loop costs per iteration over what its body's nodes cost themselves.

The body is 10 pure nodes (a multiply fed by the index i, then nine adds in a chain, the last one a
shift register), so the loop really runs all ten each iteration. Side by side, in one process:

- "body nodes alone": the ten nodes' ``run`` methods called directly, in order (what the work costs);
- "loop, iterations run": a For loop of N iterations on a runtime whose caches are cleared first;
- "loop, iterations cached": the same loop with N + 1 iterations after a run of N (all but one from
  the per-iteration cache);
- overhead = loop per iteration - body nodes alone per iteration. Target: <= 1 ms per iteration.

Prints medians over repeats (not a timed test).

    python3 benchmarks/structures.py [--iterations 200] [--repeats 15]
"""

from __future__ import annotations

import argparse
import statistics
import time

from timing import median_ms

import flowmc
from flowmc.graph import Graph
from flowmc.nodes.basic import Add, BinaryParams, Multiply

BODY_NODES = 10


def body_graph() -> Graph:
    b = flowmc.GraphBuilder(title="10-node body")
    first = b.add("basic.multiply", id="n0", b=0.5)
    b.input("i", "Number", [first.a])
    previous = first
    for k in range(1, BODY_NODES):
        node = b.add("basic.add", id=f"n{k}", b=float(k))
        b.wire(previous.result, node.a)
        previous = node
    b.input("total", "Number", [previous.b])  # the last add sums into the shift register
    b.output("total", "Number", previous.result)
    return b.build()


def loop_graph(count: int) -> Graph:
    g = flowmc.GraphBuilder(title="loop benchmark")
    loop = g.add("struct.for", id="loop", count=count, shift=["total"], bodies={"body": body_graph()})
    start = g.add("basic.number", id="start", value=0.0)
    g.wire(start.value, loop.total)
    g.output("total", "Number", loop.total)
    return g.build()


def direct(count: int) -> float:
    """The body's arithmetic through the node classes' own run(), without the runtime."""
    total = 0.0
    mul, add = Multiply(), Add()
    for i in range(count):
        value = mul.run(None, BinaryParams(a=float(i), b=0.5))["result"]
        for k in range(1, BODY_NODES - 1):
            value = add.run(None, BinaryParams(a=value, b=float(k)))["result"]
        total = add.run(None, BinaryParams(a=value, b=total))["result"]
    return total


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iterations", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=15)
    args = parser.parse_args()
    n = args.iterations
    graph = loop_graph(n)
    more = loop_graph(n + 1)
    rt = flowmc.Runtime()
    check = rt.run(graph)
    assert check.ok, check.errors
    assert check.outputs["total"] == direct(n), (check.outputs["total"], direct(n))

    def uncached() -> None:
        rt.clear_cache()
        assert rt.run(graph).ok

    def cached() -> None:
        rt.clear_cache()
        rt.run(graph)
        start = time.perf_counter()
        assert rt.run(more).ok
        times.append((time.perf_counter() - start) * 1000)

    times: list[float] = []
    body_ms = median_ms(lambda: direct(n), args.repeats) / n
    loop_ms = median_ms(uncached, args.repeats) / n
    for _ in range(args.repeats):
        cached()
    cached_ms = statistics.median(times) / (n + 1)
    overhead = loop_ms - body_ms
    print(f"flowmc loop benchmark: For loop of {n} iterations, {BODY_NODES}-node pure body, median of {args.repeats}")
    print(f"{'case':<44} {'ms / iteration':>15} {'target':>8} {'ratio':>7}")
    print(f"{'body nodes alone (run() called directly)':<44} {body_ms:>15.4f}")
    print(f"{'loop, iterations run (caches cleared)':<44} {loop_ms:>15.4f}")
    print(f"{'loop, iterations cached (N+1 after N)':<44} {cached_ms:>15.4f}")
    print(f"{'overhead: loop - body nodes alone':<44} {overhead:>15.4f} {1.0:>8.1f} {overhead / 1.0:>7.2f}")


if __name__ == "__main__":
    main()
