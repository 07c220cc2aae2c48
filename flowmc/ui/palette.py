"""The node palette: every registered node type, every library graph and the graph files with an
interface beside the open graph, searchable by id, title, category, description and port type
("Trajectory" finds every node that takes or gives one), grouped by category."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from flowmc.errors import GraphError
from flowmc.graph import load

__all__ = ["PaletteItem", "palette_items", "search", "categories"]

SUFFIX = ".flowmc.json"
CATEGORY_ORDER = ("Path", "Interpolation", "Planning", "View", "Devices", "Math", "Basic", "Graph", "Library",
                  "Graph files")


@dataclass(frozen=True)
class PaletteItem:
    """What adding this entry creates: a node of ``type_id`` with ``params``."""

    type_id: str
    title: str
    category: str
    description: str
    params: dict[str, Any] = field(default_factory=dict, hash=False, compare=False)
    ports: str = ""  # "in: path Path · out: trajectory Trajectory" (searched, and shown as a hint)

    @property
    def key(self) -> str:
        """Unique per entry (graph files share the type ``subgraph``)."""
        file = self.params.get("file")
        return f"{self.type_id}:{file}" if file else self.type_id

    @property
    def haystack(self) -> str:
        return " ".join((self.type_id, self.title, self.category, self.description, self.ports,
                         str(self.params.get("file", "")))).lower()


def _graph_files(folder: Path, exclude: Path | None) -> list[PaletteItem]:
    """Graph files in ``folder`` that declare an interface, usable as ``subgraph`` nodes."""
    items = []
    for path in sorted(folder.glob(f"*{SUFFIX}")):
        if exclude is not None and path.resolve() == exclude.resolve():
            continue
        try:
            graph = load(path)
        except GraphError:
            continue
        if graph.interface is None:
            continue
        description = (graph.description.strip().splitlines() or [f"Sub-graph file {path.name}"])[0]
        ports = _ports_text([{"name": i.name, "type": i.type} for i in graph.interface.inputs],
                            [{"name": o.name, "type": o.type} for o in graph.interface.outputs])
        items.append(PaletteItem("subgraph", graph.title or path.name[: -len(SUFFIX)], "Graph files", description,
                                 {"file": path.name}, ports))
    return items


def _ports_text(inputs: list[dict], outputs: list[dict]) -> str:
    def types(port: dict) -> str:
        kind = port.get("types") or port.get("type")
        return " or ".join(kind) if isinstance(kind, list) else str(kind)

    def listed(ports: list[dict]) -> str:
        return ", ".join(f"{p['name']} {types(p)}" for p in ports)

    parts = [f"in: {listed(inputs)}" if inputs else "", f"out: {listed(outputs)}" if outputs else ""]
    return " · ".join(p for p in parts if p)


def palette_items(registry: Any, graph_dir: Any = None, exclude: Path | None = None) -> list[PaletteItem]:
    """Every node type of ``registry`` (``describe_all``: types, then ``lib.*`` graphs) and the graph files
    beside the open graph (``exclude``: the open graph itself)."""
    items = [PaletteItem(d["type_id"], d["title"], d["category"], d["description"], ports=_ports_text(d["inputs"], d["outputs"]))
             for d in registry.describe_all(graph_dir)]
    if graph_dir is not None and Path(graph_dir).is_dir():
        items += _graph_files(Path(graph_dir), exclude)
    return items


def _score(item: PaletteItem, query: str) -> int:
    title, type_id = item.title.lower(), item.type_id.lower()
    if query in (title, type_id, type_id.rsplit(".", 1)[-1]):
        return 0
    if title.startswith(query) or type_id.startswith(query) or type_id.rsplit(".", 1)[-1].startswith(query):
        return 1
    if query in title or query in type_id:
        return 2
    return 3


def categories(items: list[PaletteItem]) -> dict[str, list[PaletteItem]]:
    """Items by category, categories in a fixed reading order (sources first, devices last), then by name."""
    order = {c: k for k, c in enumerate(CATEGORY_ORDER)}
    grouped: dict[str, list[PaletteItem]] = {}
    for item in items:
        grouped.setdefault(item.category, []).append(item)
    return {c: grouped[c] for c in sorted(grouped, key=lambda c: (order.get(c, len(order)), c))}


def search(items: list[PaletteItem], query: str, limit: int | None = None) -> list[PaletteItem]:
    """Entries whose text holds every word of ``query`` (case-insensitive), best matches first:
    exact title or id, then prefixes, then title/id containing it, then description matches.
    An empty query lists everything by category and title."""
    query = " ".join(query.lower().split())
    words = query.split()
    found = [item for item in items if all(w in item.haystack for w in words)]
    found.sort(key=lambda i: (_score(i, query) if query else 0, i.category, i.title.lower(), i.key))
    return found if limit is None else found[:limit]
