"""Node types with typed ports, and the registry that maps a type id to its class.

A node type is one small class: typed ports declared once, a pydantic ``Params`` model
and a ``run`` method. ``@register`` checks the declaration when the module is imported,
so a mistake in a node type fails at once, not while a graph runs.

Every scalar param (float/int -> Number, bool -> Bool, str/Literal -> Text) is also an
optional input port of the same name: a wire there overrides the stored value.
"""

from __future__ import annotations

import contextlib
import keyword
import re
import types
import typing
from dataclasses import dataclass
from typing import Any, ClassVar, Iterator, Literal, NamedTuple

from pydantic import BaseModel, ConfigDict

from flowmc.errors import GraphError

__all__ = [
    "PORT_TYPES",
    "REQUIRED",
    "In",
    "Out",
    "Ports",
    "NodeType",
    "NoParams",
    "register",
    "unregister",
    "lookup",
    "registered",
    "describe",
    "describe_all",
    "scoped",
    "generation",
    "check_ports",
]

PORT_TYPES = ("Path", "Trajectory", "Steps", "Signal", "Machine", "Number", "Bool", "Text", "Table", "Log")

_TYPE_ID = re.compile(r"^[a-z][a-z0-9_]*(\.[a-z][a-z0-9_]*)*$")


class _Required:
    """Sentinel: an input with no default must be wired."""

    def __repr__(self) -> str:
        return "REQUIRED"


REQUIRED: Any = _Required()


@dataclass(frozen=True)
class In:
    """An input port. ``type`` is one port type or a tuple of accepted types."""

    name: str
    type: str | tuple[str, ...]
    doc: str = ""
    default: Any = REQUIRED
    param: bool = False  # True for the port that feeds a scalar param

    @property
    def types(self) -> tuple[str, ...]:
        return (self.type,) if isinstance(self.type, str) else tuple(self.type)

    @property
    def required(self) -> bool:
        return self.default is REQUIRED

    def accepts(self, port_type: str) -> bool:
        return port_type in self.types


@dataclass(frozen=True)
class Out:
    """An output port of exactly one type."""

    name: str
    type: str
    doc: str = ""


class Ports(NamedTuple):
    inputs: tuple[In, ...]
    outputs: tuple[Out, ...]


class NoParams(BaseModel):
    """Params of a node type that has none."""

    model_config = ConfigDict(extra="forbid")


class NodeType:
    """Base class of every node type; subclass, fill in the class attributes, write ``run``.

    ``run(self, ctx, params, **inputs)`` gets the validated params (wired values already
    merged in) and one keyword per data input; it returns ``{output_name: value}``.
    A fresh instance runs each time: keep no state between runs.
    """

    type_id: ClassVar[str]
    title: ClassVar[str]
    category: ClassVar[str]
    description: ClassVar[str]
    pure: ClassVar[bool] = True  # False: never cached (devices, clocks, files that change, checks)
    version: ClassVar[int] = 1  # bump when outputs change for the same inputs: invalidates caches
    Params: ClassVar[type[BaseModel]] = NoParams
    inputs: ClassVar[tuple[In, ...]] = ()
    outputs: ClassVar[tuple[Out, ...]] = ()
    fixed_params: ClassVar[tuple[str, ...]] = ()  # scalar params that cannot be fed by a wire
    host_resources: ClassVar[tuple[str, ...]] = ()  # what a run holds on its host, e.g. "linuxcnc" (one per host)

    @classmethod
    def ports(cls, params: BaseModel) -> Ports:
        """Data ports for these params. Override only when ports depend on params."""
        return Ports(cls.inputs, cls.outputs)

    @classmethod
    def param_ports(cls) -> tuple[In, ...]:
        """The optional input ports that feed scalar params (stored value is the default)."""
        return _param_ports(cls)

    @classmethod
    def dynamic_ports(cls) -> bool:
        return getattr(cls.ports, "__func__", None) is not NodeType.ports.__func__

    def run(self, ctx: Any, params: Any, **inputs: Any) -> dict[str, Any]:
        raise NotImplementedError


# ---------------------------------------------------------------- param ports

_SCALAR = {float: "Number", int: "Number", bool: "Bool", str: "Text"}


def _scalar_port_type(annotation: Any) -> str | None:
    """Port type of a scalar param annotation, or None when the param is not scalar."""
    origin = typing.get_origin(annotation)
    if origin is typing.Annotated:
        return _scalar_port_type(typing.get_args(annotation)[0])
    if origin is Literal:
        values = typing.get_args(annotation)
        return "Text" if values and all(isinstance(v, str) for v in values) else None
    if origin in (typing.Union, types.UnionType):
        found = {_scalar_port_type(a) for a in typing.get_args(annotation) if a is not type(None)}
        return found.pop() if len(found) == 1 and None not in found else None
    return _SCALAR.get(annotation)


_param_port_cache: dict[type, tuple[In, ...]] = {}


def _param_ports(cls: type[NodeType]) -> tuple[In, ...]:
    cached = _param_port_cache.get(cls)
    if cached is not None:
        return cached
    ports = []
    for name, field in cls.Params.model_fields.items():
        port_type = _scalar_port_type(field.annotation)
        if port_type is None or name in cls.fixed_params:
            continue
        default = REQUIRED if field.is_required() else field.get_default(call_default_factory=True)
        ports.append(In(name, port_type, doc=field.description or "", default=default, param=True))
    result = tuple(ports)
    _param_port_cache[cls] = result
    return result


# ---------------------------------------------------------------- registry

_types: dict[str, type[NodeType]] = {}
_generation = 0  # bumped on every change, so cached validation results can tell they are stale


def _changed() -> None:
    global _generation
    _generation += 1


def generation() -> int:
    return _generation


def _port_name_ok(name: str) -> bool:
    return name.isidentifier() and not keyword.iskeyword(name) and name not in ("ctx", "params", "self")


def _check_declaration(cls: type) -> None:
    """Raise TypeError naming the class and the mistake; runs once, at import time."""
    where = f"node type {cls.__module__}.{cls.__qualname__}"

    def fail(msg: str) -> None:
        raise TypeError(f"{where}: {msg}")

    if not (isinstance(cls, type) and issubclass(cls, NodeType)):
        fail("must subclass flowmc.registry.NodeType")
    type_id = getattr(cls, "type_id", None)
    if not isinstance(type_id, str) or not _TYPE_ID.match(type_id):
        fail(f"type_id {type_id!r} must look like 'area.name' (lowercase, digits, _)")
    if type_id.startswith("lib."):
        fail("type ids starting with 'lib.' are reserved for library graphs")
    for attr in ("title", "category", "description"):
        value = getattr(cls, attr, None)
        if not isinstance(value, str) or not value.strip():
            fail(f"{attr} must be a non-empty string")
    if "\n" in cls.description:
        fail("description must be one line")
    if not (isinstance(cls.Params, type) and issubclass(cls.Params, BaseModel)):
        fail("Params must be a pydantic BaseModel subclass")
    if cls.Params.model_config.get("extra") != "forbid":
        fail('Params must set model_config = ConfigDict(extra="forbid")')
    if cls.run is NodeType.run:
        fail("must define run(self, ctx, params, **inputs)")
    if not all(isinstance(p, In) for p in cls.inputs) or not all(isinstance(p, Out) for p in cls.outputs):
        fail("inputs must be a tuple of In(...), outputs a tuple of Out(...)")
    for name in cls.fixed_params:
        if name not in cls.Params.model_fields:
            fail(f"fixed_params names unknown param {name!r}")
    _param_port_cache.pop(cls, None)
    _check_ports(fail, cls.inputs + _param_ports(cls), cls.outputs)


def _check_ports(fail: Any, inputs: tuple[In, ...], outputs: tuple[Out, ...]) -> None:
    seen_in: set[str] = set()
    for port in inputs:
        if not _port_name_ok(port.name):
            fail(f"input name {port.name!r} is not a valid identifier")
        if port.name in seen_in:
            fail(f"input {port.name!r} declared twice (a data input and a scalar param share a name?)")
        seen_in.add(port.name)
        bad = [t for t in port.types if t not in PORT_TYPES]
        if bad or not port.types:
            fail(f"input {port.name!r} has unknown port type {bad or port.type!r}; known: {', '.join(PORT_TYPES)}")
    seen_out: set[str] = set()
    for port in outputs:
        if not _port_name_ok(port.name):
            fail(f"output name {port.name!r} is not a valid identifier")
        if port.name in seen_out:
            fail(f"output {port.name!r} declared twice")
        seen_out.add(port.name)
        if port.type not in PORT_TYPES:
            fail(f"output {port.name!r} has unknown port type {port.type!r}; known: {', '.join(PORT_TYPES)}")


def register(cls: type[NodeType]) -> type[NodeType]:
    """Class decorator: check the declaration and add the type to the registry."""
    _check_declaration(cls)
    existing = _types.get(cls.type_id)
    same = existing is not None and (existing.__module__, existing.__qualname__) == (cls.__module__, cls.__qualname__)
    if existing is not None and not same:
        raise TypeError(
            f"type_id {cls.type_id!r} of {cls.__module__}.{cls.__qualname__} is already used by "
            f"{existing.__module__}.{existing.__qualname__}"
        )
    _types[cls.type_id] = cls
    _changed()
    return cls


def unregister(type_id: str) -> None:
    if _types.pop(type_id, None) is not None:
        _changed()


def registered() -> dict[str, type[NodeType]]:
    """Registered (code) node types by id, sorted. Library graphs are listed by ``describe_all``."""
    return dict(sorted(_types.items()))


def lookup(type_id: str, graph_dir: Any = None) -> type[NodeType]:
    """The class for ``type_id``; ``lib.<stem>`` ids are library graphs (beside ``graph_dir`` first).

    Raises GraphError when the type is unknown.
    """
    cls = _types.get(type_id)
    if cls is not None:
        return cls
    if type_id.startswith("lib."):
        from flowmc.subgraph import library_type  # core module; imported late to keep this one small

        cls = library_type(type_id, graph_dir)
        if cls is not None:
            return cls
    raise GraphError(f"unknown node type {type_id!r}", where=None)


@contextlib.contextmanager
def scoped() -> Iterator[None]:
    """Restore the registry on exit: tests register throw-away types inside."""
    saved = dict(_types)
    try:
        yield
    finally:
        _types.clear()
        _types.update(saved)
        _changed()


# ---------------------------------------------------------------- describe

def _jsonable(value: Any) -> Any:
    if value is REQUIRED:
        return None
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, BaseModel):
        return value.model_dump(mode="json")
    return repr(value)


def _port_dict(port: In | Out) -> dict[str, Any]:
    if isinstance(port, Out):
        return {"name": port.name, "type": port.type, "doc": port.doc}
    return {
        "name": port.name,
        "types": list(port.types),
        "doc": port.doc,
        "required": port.required,
        "default": _jsonable(port.default),
        "param": port.param,
    }


def describe(cls_or_id: type[NodeType] | str, params: dict[str, Any] | None = None, graph_dir: Any = None) -> dict[str, Any]:
    """A JSON-able description of a node type: ports, param schema, text. For the CLI and the editor.

    ``params`` (raw dict) matters only for types whose ports depend on params; when they are
    invalid the declared (static) ports are described.
    """
    cls = lookup(cls_or_id, graph_dir) if isinstance(cls_or_id, str) else cls_or_id
    ports = Ports(cls.inputs, cls.outputs)
    if cls.dynamic_ports():
        with contextlib.suppress(Exception):
            ports = cls.ports(cls.Params.model_validate(params or {}))
    return {
        "type_id": cls.type_id,
        "title": cls.title,
        "category": cls.category,
        "description": cls.description,
        "pure": cls.pure,
        "version": cls.version,
        "inputs": [_port_dict(p) for p in ports.inputs],
        "param_inputs": [_port_dict(p) for p in cls.param_ports()],
        "outputs": [_port_dict(p) for p in ports.outputs],
        "params_schema": cls.Params.model_json_schema(),
        "dynamic_ports": cls.dynamic_ports(),
    }


def describe_all(graph_dir: Any = None) -> list[dict[str, Any]]:
    """Every registered type, then the library graphs (``lib.*``), sorted by type id."""
    from flowmc.subgraph import library_types

    found = dict(_types)
    found.update(library_types(graph_dir))
    return [describe(found[t]) for t in sorted(found)]


def check_ports(owner: str, ports: Ports) -> None:
    """Raise TypeError if ``ports`` (from an overridden ``ports(params)``) are malformed."""

    def fail(msg: str) -> None:
        raise TypeError(f"{owner}: {msg}")

    _check_ports(fail, ports.inputs, ports.outputs)

