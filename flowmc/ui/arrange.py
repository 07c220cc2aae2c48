"""Where nodes go: a free spot for a new node, the layered auto-layout, align and distribute.

Everything here is plain geometry in canvas pixels (x right, y down) over ``Rect`` sizes, so it is
tested without a browser. The auto-layout is the classic layered drawing: networkx's topological
generations give the columns (a node with no inputs moves right to sit just before its first
consumer), a few barycenter sweeps order each column to cut crossings, and nodes are stacked in
their column with gaps, pulled toward the nodes they connect to. Columns are as wide as their
widest node, so nothing overlaps; unconnected groups of nodes are laid out one under another.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import networkx as nx

__all__ = ["Rect", "free_spot", "auto_layout", "crossings", "overlaps", "align", "ALIGNMENTS"]

GAP_X = 60.0  # between columns
GAP_Y = 36.0  # between nodes in a column
GAP_GROUP = 80.0  # between unconnected groups
SWEEPS = 6


@dataclass(frozen=True)
class Rect:
    """A box in canvas pixels: top-left (x, y), width, height."""

    x: float
    y: float
    w: float
    h: float

    def moved(self, x: float, y: float) -> "Rect":
        return Rect(x, y, self.w, self.h)

    def overlaps(self, other: "Rect", gap: float = 0.0) -> bool:
        return not (self.x + self.w + gap <= other.x or other.x + other.w + gap <= self.x
                    or self.y + self.h + gap <= other.y or other.y + other.h + gap <= self.y)


def free_spot(taken: Iterable[Rect], size: tuple[float, float], near: tuple[float, float],
              gap: float = 30.0) -> tuple[float, float]:
    """Top-left of a ``size`` box as close to ``near`` (where its centre should be) as it can be
    without touching any of ``taken`` (``gap`` pixels apart), searched on rings of a fine grid."""
    taken = list(taken)
    w, h = size
    x0, y0 = near[0] - w / 2, near[1] - h / 2
    step = 20.0
    for ring in range(0, 400):
        cells = [(i, j) for i in range(-ring, ring + 1) for j in range(-ring, ring + 1) if max(abs(i), abs(j)) == ring]
        cells.sort(key=lambda c: (c[0] ** 2 + c[1] ** 2, -c[0], c[1]))
        for i, j in cells:
            spot = Rect(x0 + i * step, y0 + j * step, w, h)
            if not any(spot.overlaps(t, gap) for t in taken):
                return round(spot.x, 1), round(spot.y, 1)
    return round(x0, 1), round(y0, 1)


def overlaps(rects: dict[str, Rect], gap: float = 0.0) -> list[tuple[str, str]]:
    """Every pair of ids whose rectangles overlap (closer than ``gap``)."""
    items = sorted(rects.items(), key=lambda kv: kv[1].x)
    found = []
    for k, (a, ra) in enumerate(items):
        for b, rb in items[k + 1:]:
            if rb.x >= ra.x + ra.w + gap:
                break
            if ra.overlaps(rb, gap):
                found.append((a, b))
    return found


def _layers(dag: nx.DiGraph) -> dict[str, int]:
    """Column of each node: its longest path from a source, pulled right next to its first consumer;
    interface terminals (``@in:`` / ``@out:`` ids) take the first and the last column."""
    layer = {n: k for k, gen in enumerate(nx.topological_generations(dag)) for n in gen}
    for n in reversed(list(nx.topological_sort(dag))):
        succ = [layer[s] for s in dag.successors(n)]
        if succ and not n.startswith("@in:"):
            layer[n] = max(layer[n], min(succ) - 1)
    last = max(layer.values()) + 1
    return {n: last if n.startswith("@out:") else k for n, k in layer.items()}


def _barycenter(order: list[list[str]], neighbours: dict[str, list[str]]) -> None:
    """One sweep: each column sorted by the mean place of its neighbours in the column before it."""
    for k in range(1, len(order)):
        place = {n: i for i, n in enumerate(order[k - 1])}
        keyed = []
        for i, n in enumerate(order[k]):
            near = [place[m] for m in neighbours[n] if m in place]
            keyed.append((sum(near) / len(near) if near else i, i, n))
        order[k] = [n for *_, n in sorted(keyed)]


def crossings(order: list[list[str]], edges: Iterable[tuple[str, str]]) -> int:
    """Wire crossings between neighbouring columns of a layered drawing (the count the layout cuts)."""
    col = {n: (k, i) for k, column in enumerate(order) for i, n in enumerate(column)}
    by_gap: dict[int, list[tuple[int, int]]] = {}
    for a, b in edges:
        (ka, ia), (kb, ib) = col[a], col[b]
        if ka > kb:
            (ka, ia), (kb, ib) = (kb, ib), (ka, ia)
        if kb == ka + 1:
            by_gap.setdefault(ka, []).append((ia, ib))
    return sum(1 for pairs in by_gap.values() for k, (a1, b1) in enumerate(pairs) for a2, b2 in pairs[k + 1:]
               if (a1 - a2) * (b1 - b2) < 0)


def _component(ids: list[str], rects: dict[str, Rect], edges: list[tuple[str, str]]) -> dict[str, tuple[float, float]]:
    """Layered layout of one connected group, with its top-left at (0, 0)."""
    dag = nx.DiGraph()
    dag.add_nodes_from(ids)
    dag.add_edges_from(edges)
    layer = _layers(dag)
    order = [sorted((n for n in ids if layer[n] == k), key=lambda n: (rects[n].y, rects[n].x, n))
             for k in range(max(layer.values()) + 1)]
    order = [column for column in order if column]
    undirected = {n: sorted(set(dag.predecessors(n)) | set(dag.successors(n))) for n in ids}
    best, best_count = [list(c) for c in order], crossings(order, edges)
    for _ in range(SWEEPS):
        _barycenter(order, undirected)
        order.reverse()
        _barycenter(order, undirected)
        order.reverse()
        count = crossings(order, edges)
        if count < best_count:
            best, best_count = [list(c) for c in order], count
    xs, x = [], 0.0
    for column in best:
        xs.append(x)
        x += max(rects[n].w for n in column) + GAP_X
    ys: dict[str, float] = {}
    for column in best:  # stack each column, then pull it toward the nodes it connects to on its left
        y = 0.0
        for n in column:
            ys[n] = y
            y += rects[n].h + GAP_Y
    for _ in range(2):
        for column in best:
            _settle(column, rects, ys, undirected)
    top = min(ys.values())
    return {n: (xs[k], ys[n] - top) for k, column in enumerate(best) for n in column}


def _settle(column: list[str], rects: dict[str, Rect], ys: dict[str, float], neighbours: dict[str, list[str]]) -> None:
    """Move a column's nodes toward the middle of their neighbours, in order, never closer than GAP_Y."""
    want = []
    for n in column:
        near = [ys[m] + rects[m].h / 2 for m in neighbours[n] if m in ys and m not in column]
        want.append(sum(near) / len(near) - rects[n].h / 2 if near else ys[n])
    placed, bottom = [], None
    for n, y in zip(column, want):
        y = y if bottom is None else max(y, bottom + GAP_Y)
        placed.append(y)
        bottom = y + rects[n].h
    push = sum(p - w for p, w in zip(placed, want)) / len(placed)  # share the push evenly up and down
    for n, y in zip(column, placed):
        ys[n] = y - push


def auto_layout(rects: dict[str, Rect], edges: Iterable[tuple[str, str]],
                origin: tuple[float, float] | None = None) -> dict[str, tuple[float, float]]:
    """New top-left corners for every box in ``rects`` (ids to sizes; their old places set the
    starting order) given the wires between them (``(from id, to id)``, loops ignored). The drawing
    starts at ``origin`` (default: where the old drawing's top-left corner was)."""
    if not rects:
        return {}
    edges = sorted({(a, b) for a, b in edges if a in rects and b in rects and a != b})
    graph = nx.DiGraph(edges)
    graph.add_nodes_from(rects)
    dag = graph if nx.is_directed_acyclic_graph(graph) else nx.DiGraph(
        e for e in edges if not nx.has_path(graph, e[1], e[0]))
    dag.add_nodes_from(rects)
    groups = sorted((sorted(c) for c in nx.weakly_connected_components(dag)),
                    key=lambda c: (min(rects[n].y for n in c), min(rects[n].x for n in c)))
    x0 = origin[0] if origin else min(r.x for r in rects.values())
    y = origin[1] if origin else min(r.y for r in rects.values())
    out: dict[str, tuple[float, float]] = {}
    for ids in groups:
        placed = _component(ids, rects, [e for e in dag.edges if e[0] in ids])
        for n, (px, py) in placed.items():
            out[n] = (round(x0 + px, 1), round(y + py, 1))
        y += max(py + rects[n].h for n, (px, py) in placed.items()) + GAP_GROUP
    return out


ALIGNMENTS = ("left", "centre", "right", "top", "middle", "bottom", "distribute across", "distribute down")


def align(rects: dict[str, Rect], how: str) -> dict[str, tuple[float, float]]:
    """New top-left corners that line ``rects`` up (``left``, ``centre``, ``right``, ``top``, ``middle``,
    ``bottom``) or spread them with equal gaps (``distribute across`` / ``distribute down``)."""
    if how not in ALIGNMENTS:
        raise ValueError(f"unknown alignment {how!r}; one of {', '.join(ALIGNMENTS)}")
    r = rects
    if not r:
        return {}
    if how.startswith("distribute"):
        across = how.endswith("across")
        ids = sorted(r, key=lambda n: (r[n].x, r[n].y) if across else (r[n].y, r[n].x))
        lo = r[ids[0]].x if across else r[ids[0]].y
        hi = max(r[n].x + r[n].w if across else r[n].y + r[n].h for n in ids)
        total = sum(r[n].w if across else r[n].h for n in ids)
        gap = (hi - lo - total) / max(len(ids) - 1, 1)
        out, at = {}, lo
        for n in ids:
            out[n] = (round(at, 1), r[n].y) if across else (r[n].x, round(at, 1))
            at += (r[n].w if across else r[n].h) + gap
        return out
    left, right = min(b.x for b in r.values()), max(b.x + b.w for b in r.values())
    top, bottom = min(b.y for b in r.values()), max(b.y + b.h for b in r.values())
    place = {"left": lambda b: (left, b.y), "right": lambda b: (right - b.w, b.y),
             "centre": lambda b: ((left + right - b.w) / 2, b.y), "top": lambda b: (b.x, top),
             "bottom": lambda b: (b.x, bottom - b.h), "middle": lambda b: (b.x, (top + bottom - b.h) / 2)}[how]
    return {n: tuple(round(v, 1) for v in place(b)) for n, b in r.items()}
