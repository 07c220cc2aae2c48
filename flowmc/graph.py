"""The graph file model (``*.flowmc.json``): one pydantic tree is the schema.

Loading refuses unknown fields and schema versions, naming the file and the JSON path;
malformed JSON is reported with line and column. Saving is canonical (fixed key order,
nodes sorted by id, wires sorted) and atomic (temp file + ``os.replace``), so
load -> save of a saved file is byte-identical and a crash never leaves half a file.

Params are stored by name as plain JSON; they are checked against the node type's
params model by validation (``flowmc.runtime``), not here, so a file naming a node
type this flowmc does not know still loads and round-trips.

Structure nodes (loops, case) hold their bodies inside the file, under the node
(``"bodies": {"body": {...}}``): a body reads in place, beside the wires that feed it, and
a change to it diffs as a change to that node. Reusable graphs stay separate files
(sub-graphs, ``file``); docs/structures.md says why.
"""

# No ``from __future__ import annotations`` here: with it every field's annotation is a string that pydantic
# compiles when it builds the model, at the start of every command (benchmarks/cold_start.py).
import json
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, ValidationError

import flowmc.budget as budget
from flowmc.errors import GraphError
from flowmc.fileio import read_text, write_atomic
from flowmc.migrations import SCHEMA_VERSION, migrate
from flowmc.ports import PORT_TYPES

__all__ = [
    "SCHEMA_VERSION",
    "Issue",
    "Node",
    "Wire",
    "InterfaceInput",
    "InterfaceOutput",
    "Interface",
    "Body",
    "Comment",
    "Label",
    "View",
    "Graph",
    "split_ref",
    "load",
    "loads",
    "save",
    "dumps",
    "json_schema",
]

ID_PATTERN = r"^[A-Za-z_][A-Za-z0-9_-]*$"
NAME_PATTERN = r"^[A-Za-z_][A-Za-z0-9_]*$"
REF_PATTERN = r"^[A-Za-z_][A-Za-z0-9_-]*\.[A-Za-z_][A-Za-z0-9_]*$"

PortType = Literal[PORT_TYPES]  # type: ignore[valid-type]


@dataclass(frozen=True)
class Issue:
    """One problem with a graph: a stable ``code``, a ``location`` path into the file
    (``("nodes", "n3", "params", "feed")``) for the editor, and a message for people."""

    code: str
    location: tuple[Any, ...]
    message: str

    def __str__(self) -> str:
        return self.message


# Fields default to these, not to ``list`` or ``dict``: pydantic reads each default factory's signature,
# and the first signature of a built-in type compiles the tokenizer's expressions, a cost every
# ``flowmc validate`` would pay at start (benchmarks/cold_start.py).
def _empty_list() -> list[Any]:
    return []


def _empty_dict() -> dict[str, Any]:
    return {}


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", populate_by_name=True, validate_assignment=True)


BODY_NAME_PATTERN = r"^[^\x00-\x1f\x7f]{1,80}$"  # a case label is text: anything printable, kept short


class Node(_Model):
    """A node: stable id, type id, params by name, canvas position (never affects a result), and for a
    structure (loop, case) the graphs it holds, by name ("body" for a loop, one per case label)."""

    id: str = Field(pattern=ID_PATTERN, description="Stable node id, unique in the graph")
    type: str = Field(min_length=1, description="Node type id, e.g. 'path.scale' or 'lib.pocket'")
    params: dict[str, Any] = Field(default_factory=_empty_dict, description="Param values by name")
    pos: tuple[float, float] = Field((0.0, 0.0), description="Canvas position [x, y]")
    bodies: dict[Annotated[str, Field(pattern=BODY_NAME_PATTERN)], "Body"] = Field(
        default_factory=_empty_dict, description="Structures only: the graphs the node holds, by name")


class Wire(_Model):
    """A wire from an output ``node.port`` to an input ``node.port`` (a data input or a scalar param)."""

    from_: str = Field(alias="from", pattern=REF_PATTERN, description="Source 'node.output'")
    to: str = Field(pattern=REF_PATTERN, description="Target 'node.input' or 'node.param'")


class InterfaceInput(_Model):
    """A named input of the graph, fed into internal ports when the graph is used as a node."""

    name: str = Field(pattern=NAME_PATTERN)
    type: PortType
    description: str = ""
    default: Any = Field(None, description="Value used when not given; null: internal ports keep their own")
    to: list[str] = Field(default_factory=_empty_list, description="Internal 'node.port' targets (none: not wired yet)")


class InterfaceOutput(_Model):
    """A named output of the graph, taken from one internal output port."""

    name: str = Field(pattern=NAME_PATTERN)
    type: PortType
    description: str = ""
    from_: str = Field(alias="from", pattern=REF_PATTERN, description="Internal 'node.output' source")


class Interface(_Model):
    inputs: list[InterfaceInput] = Field(default_factory=_empty_list)
    outputs: list[InterfaceOutput] = Field(default_factory=_empty_list)


class Body(_Model):
    """A graph a structure node holds: its nodes and wires (ids of its own, as in a sub-graph file)
    and its interface, which is what the structure's ports are made from."""

    nodes: list[Node] = Field(default_factory=_empty_list)
    wires: list[Wire] = Field(default_factory=_empty_list)
    interface: Interface = Field(default_factory=Interface)

    def as_graph(self, outer: "Graph") -> "Graph":
        """This body as a graph of its own, living where ``outer`` lives (files resolve beside it)."""
        graph = Graph(nodes=self.nodes, wires=self.wires, interface=self.interface)
        graph.path = outer.path
        return graph


_Size = Annotated[float, Field(gt=0)]
TERMINAL_PATTERN = r"^(in|out)\.[A-Za-z_][A-Za-z0-9_]*$"


class Comment(_Model):
    """A comment box on the canvas: text over a frame behind nodes. View state: it never changes a result."""

    id: str = Field(pattern=ID_PATTERN, description="Stable id, unique among comments and labels")
    text: str = ""
    pos: tuple[float, float] = Field((0.0, 0.0), description="Top-left corner [x, y], canvas pixels")
    size: tuple[_Size, _Size] = Field((320.0, 200.0), description="[width, height], canvas pixels")


class Label(_Model):
    """A free text label on the canvas. View state."""

    id: str = Field(pattern=ID_PATTERN, description="Stable id, unique among comments and labels")
    text: str = ""
    pos: tuple[float, float] = Field((0.0, 0.0), description="Top-left corner [x, y], canvas pixels")


class View(_Model):
    """How the graph is drawn apart from node positions: comments, labels, where the interface's input
    and output terminals sit (``"in.<name>"`` / ``"out.<name>"``), and the probed wires. Never part of a
    result."""

    comments: list[Comment] = Field(default_factory=_empty_list)
    labels: list[Label] = Field(default_factory=_empty_list)
    terminals: dict[Annotated[str, Field(pattern=TERMINAL_PATTERN)], tuple[float, float]] = Field(default_factory=_empty_dict)
    probes: list[Annotated[str, Field(pattern=REF_PATTERN)]] = Field(
        default_factory=_empty_list, description="Wires probed in the editor, by their source 'node.output'")

    @property
    def empty(self) -> bool:
        return not (self.comments or self.labels or self.terminals or self.probes)


class Graph(_Model):
    """A flowmc graph. ``path`` (not stored in the file) is where it was loaded from or saved to."""

    schema_version: Literal[2] = SCHEMA_VERSION
    title: str = ""
    description: str = ""
    nodes: list[Node] = Field(default_factory=_empty_list)
    wires: list[Wire] = Field(default_factory=_empty_list)
    interface: Interface | None = None
    view: View = Field(default_factory=View, description="Comments, labels, terminal places: view state only")

    _path: Path | None = PrivateAttr(None)

    @property
    def path(self) -> Path | None:
        return self._path

    @path.setter
    def path(self, value: str | os.PathLike | None) -> None:
        self._path = None if value is None else Path(value)

    @property
    def base_dir(self) -> Path:
        """Folder that relative file params resolve against (cwd for graphs never saved)."""
        return self._path.parent if self._path is not None else Path.cwd()

    def node(self, node_id: str) -> Node:
        for node in self.nodes:
            if node.id == node_id:
                return node
        raise GraphError(f"no node {node_id!r}", where=self.where)

    @property
    def where(self) -> str:
        return str(self._path) if self._path is not None else "<graph>"

    def fingerprint_json(self) -> str:
        """Everything that can change a result (not title, description, positions or the view section, in
        bodies too)."""
        data = self.model_dump(mode="json", exclude={"title", "description", "view"})
        return json.dumps(_without_positions(data), sort_keys=True)


def _without_positions(data: dict[str, Any]) -> dict[str, Any]:
    for node in data["nodes"]:
        del node["pos"]
        for body in node["bodies"].values():
            _without_positions(body)
    return data


Node.model_rebuild()


def split_ref(ref: str) -> tuple[str, str]:
    """``"node.port"`` -> ``("node", "port")`` (node ids have no dots)."""
    node, _, port = ref.partition(".")
    return node, port


# ---------------------------------------------------------------- loading

def _reject_constant(name: str) -> None:
    raise ValueError(f"{name} is not valid JSON")


def _json_path(loc: tuple[Any, ...]) -> str:
    out = "$"
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else f".{'from' if part == 'from_' else part}"
    return out


def _node_hint(raw: Any, loc: tuple[Any, ...]) -> str:
    """' (node "n3")' when the path points inside a node that has an id."""
    if len(loc) >= 2 and loc[0] == "nodes" and isinstance(loc[1], int) and isinstance(raw, dict):
        nodes = raw.get("nodes")
        if isinstance(nodes, list) and loc[1] < len(nodes) and isinstance(nodes[loc[1]], dict):
            node_id = nodes[loc[1]].get("id")
            if isinstance(node_id, str):
                return f" (node {node_id!r})"
    return ""


def _schema_issues(exc: ValidationError, raw: Any) -> list[Issue]:
    issues = []
    for err in exc.errors():
        loc = tuple(err["loc"])
        if err["type"] == "extra_forbidden":
            what = f"unknown field {str(loc[-1])!r}" if loc else "unknown field"
        else:
            what = err["msg"]
        issues.append(Issue("schema", loc, f"{_json_path(loc)}{_node_hint(raw, loc)}: {what}"))
    return issues


def _check_shape(raw: Any, where: str) -> None:
    """Refuse JSON nested deeper than the budget (deep nesting exhausts recursion later), numbers that
    overflow (``1e400`` reads as infinity) and text that is not Unicode (a lone surrogate ``\\ud800``
    cannot be saved or shown)."""
    limit = budget.cap("depth")
    stack: list[tuple[Any, tuple[Any, ...]]] = [(raw, ())]
    while stack:
        value, loc = stack.pop()
        if len(loc) > limit:
            raise GraphError(f"{_json_path(loc[:limit])}: nested deeper than {limit} levels", where=where)
        if isinstance(value, dict):
            stack.extend((v, (*loc, k)) for k, v in value.items())
            items: Any = value.keys()
        elif isinstance(value, list):
            stack.extend((v, (*loc, i)) for i, v in enumerate(value))
            items = ()
        else:
            items = (value,)
        for text in items:
            if isinstance(text, float) and not math.isfinite(text):
                raise GraphError(f"{_json_path(loc)}: a number too large to hold (it overflows to infinity)",
                                 where=where)
            if isinstance(text, str) and _SURROGATE.search(text):
                raise GraphError(f"{_json_path(loc)}: text holds a lone surrogate (\\ud800-\\udfff), "
                                 "which is not Unicode text", where=where)


_SURROGATE = re.compile("[\ud800-\udfff]")


def loads(text: str, where: str = "<string>") -> Graph:
    """Parse graph JSON; raise GraphError (with ``issues``) naming ``where`` and the JSON path."""
    if text.startswith("\ufeff"):
        text = text[1:]  # a byte-order mark some editors write
    limit = budget.cap("json_bytes")
    if len(text) > limit:
        raise GraphError(f"the graph is {len(text):,} characters, over the budget of {limit:,}: keep big data "
                         "in the files it reads (G-code, pictures), or raise the memory budget "
                         "(flowmc run --memory-mb, FLOWMC_MEMORY_MB)", where=where)
    try:
        raw = json.loads(text, parse_constant=_reject_constant)
    except json.JSONDecodeError as exc:
        raise GraphError(f"invalid JSON: {exc.msg} (line {exc.lineno}, column {exc.colno})",
                         where=f"{where}:{exc.lineno}:{exc.colno}") from None
    except RecursionError:
        raise GraphError(f"invalid JSON: nested deeper than {budget.cap('depth')} levels", where=where) from None
    except ValueError as exc:
        raise GraphError(f"invalid JSON: {exc}", where=where) from None
    _check_shape(raw, where)
    raw = migrate(raw, where)
    try:
        return Graph.model_validate(raw)
    except ValidationError as exc:
        issues = _schema_issues(exc, raw)
        message = issues[0].message if len(issues) == 1 else f"{len(issues)} problems in the graph file"
        raise GraphError(message, where=where, issues=issues) from None


def load(path: str | os.PathLike) -> Graph:
    """Load a ``*.flowmc.json`` file. Missing or unreadable files raise GraphError naming the file."""
    path = Path(path)
    text = read_text(path, limit=budget.cap("json_bytes"), what="graph file", error=GraphError)
    graph = loads(text, where=str(path))
    graph.path = path
    return graph


# ---------------------------------------------------------------- saving

def _canonical(graph: Graph) -> dict[str, Any]:
    data = graph.model_dump(by_alias=True)  # python mode: NaN stays NaN and is refused, not turned into null
    if data["interface"] is None:
        del data["interface"]
    if graph.view.empty:
        del data["view"]
    else:
        data["view"]["terminals"] = dict(sorted(data["view"]["terminals"].items()))
        if not data["view"]["probes"]:
            del data["view"]["probes"]  # files without probes read as they did before probes existed
    return _canonical_nodes(data)


def _canonical_nodes(data: dict[str, Any]) -> dict[str, Any]:
    """Nodes sorted by id, wires sorted, params by name; bodies (kept in their order) the same way."""
    for node in data["nodes"]:
        node["params"] = _sorted_keys(node["params"])
        if node["bodies"]:
            for body in node["bodies"].values():
                _canonical_nodes(body)
        else:
            del node["bodies"]
    data["nodes"].sort(key=lambda n: n["id"])
    data["wires"].sort(key=lambda w: (w["to"], w["from"]))
    return data


def _sorted_keys(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _sorted_keys(value[k]) for k in sorted(value)}
    if isinstance(value, (list, tuple)):
        return [_sorted_keys(v) for v in value]
    return value


def _format(value: Any, indent: str = "") -> str:
    """JSON with 2-space indent; short lists and objects of scalars (positions, wires) stay on one line."""
    inner = indent + "  "
    if isinstance(value, dict):
        if not value:
            return "{}"
        if not any(isinstance(v, (dict, list, tuple)) for v in value.values()):
            flat = "{" + ", ".join(f"{json.dumps(k, ensure_ascii=False)}: {json.dumps(v, ensure_ascii=False, allow_nan=False)}"
                                   for k, v in value.items()) + "}"
            if len(flat) + len(indent) <= 100:
                return flat
        items = [f"{inner}{json.dumps(k, ensure_ascii=False)}: {_format(v, inner)}" for k, v in value.items()]
        return "{\n" + ",\n".join(items) + "\n" + indent + "}"
    if isinstance(value, (list, tuple)):
        if not value:
            return "[]"
        if not any(isinstance(v, (dict, list, tuple)) for v in value):
            flat = "[" + ", ".join(json.dumps(v, ensure_ascii=False, allow_nan=False) for v in value) + "]"
            if len(flat) + len(indent) <= 100:
                return flat
        return "[\n" + ",\n".join(inner + _format(v, inner) for v in value) + "\n" + indent + "]"
    return json.dumps(value, ensure_ascii=False, allow_nan=False)


def dumps(graph: Graph) -> str:
    """Canonical JSON text of ``graph`` (ends with a newline)."""
    try:
        return _format(_canonical(graph)) + "\n"
    except (TypeError, ValueError) as exc:  # NaN/Infinity or a non-JSON param value
        raise GraphError(f"cannot be saved as JSON: {exc}", where=graph.where) from None


def save(graph: Graph, path: str | os.PathLike) -> Path:
    """Write ``graph`` canonically and atomically to ``path``; sets ``graph.path``."""
    path = Path(path)
    write_atomic(path, dumps(graph), what="graph file", error=GraphError)
    graph.path = path
    return path


def json_schema() -> dict[str, Any]:
    """JSON Schema of the graph file (what ``flowmc schema`` prints)."""
    schema = Graph.model_json_schema(by_alias=True)
    schema["$id"] = "https://flowmc/graph.schema.json"
    schema["title"] = f"flowmc graph file (schema_version {SCHEMA_VERSION})"
    return schema
