"""Node types with typed ports, and the Registry that maps a type id to its class.

A node type is one small class: typed ports declared once, a pydantic ``Params`` model
and a ``run`` method. ``@register`` checks the declaration when the module is imported,
so a mistake in a node type fails at once, not while a graph runs, and declares the class
for any registry that loads its module (``flowmc.plugins`` builds the default one).

A ``Registry`` is a plain object: the runtime is given one, and tests build their own.
Library graphs (``lib.<stem>``) come from a ``LibrarySource`` the registry is given.

Every scalar param (float/int -> Number, bool -> Bool, str/Literal -> Text) is also an
optional input port of the same name: a wire there overrides the stored value.
"""

from __future__ import annotations

import contextlib
import itertools
import keyword
import re
import threading
import types
import typing
from pathlib import Path
from typing import Any, Callable, ClassVar, Iterable, Literal, Protocol

from pydantic import BaseModel, ConfigDict

from flowmc.errors import GraphError
from flowmc.ports import PORT_TYPES, REQUIRED, In, Out, Ports

__all__ = [
    "PORT_TYPES",
    "REQUIRED",
    "In",
    "Out",
    "Ports",
    "NodeType",
    "NoParams",
    "Registry",
    "Loader",
    "LibrarySource",
    "register",
    "declared_in",
    "describe",
    "check_ports",
]

_TYPE_ID = re.compile(r"^[a-z][a-z0-9_]*(\.[a-z][a-z0-9_]*)*$")


class NoParams(BaseModel):
    """Params of a node type that has none."""

    model_config = ConfigDict(extra="forbid", defer_build=True)


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
    reads: ClassVar[tuple[str, ...]] = ()  # params naming every file or folder it reads: cached while they are unchanged
    moves: ClassVar[bool] = False  # drives a device: prepare() a job when the graph runs, start() it at Start
    start_inputs: ClassVar[tuple[str, ...]] = ()  # inputs only start() needs (an earlier device's log)

    @classmethod
    def ports(cls, params: Any) -> Ports:
        """Data ports for these params. Override only when ports depend on params."""
        return Ports(cls.inputs, cls.outputs)

    @classmethod
    def param_ports(cls) -> tuple[In, ...]:
        """The optional input ports that feed scalar params (stored value is the default)."""
        return _param_ports(cls)

    @classmethod
    def param_type(cls, name: str) -> str | None:
        """The scalar type (Number, Bool, Text) a param declares, fixed params included; None when the
        param is not scalar (a list, a table) or does not exist."""
        field = cls.Params.model_fields.get(name)
        return None if field is None else _scalar_port_type(field.annotation)

    @classmethod
    def dynamic_ports(cls) -> bool:
        """True when the class (or a base below NodeType) overrides ``ports``."""
        return any("ports" in vars(c) for c in cls.__mro__ if c is not NodeType and issubclass(c, NodeType))

    def run(self, ctx: Any, params: Any, /, *args: Any, **inputs: Any) -> dict[str, Any]:
        """Subclasses name their inputs: ``run(self, ctx, params, path, feed=None)``. (``*args`` is never
        passed; with ``**inputs`` it lets a type checker accept every subclass's own signature.)"""
        raise NotImplementedError

    def prepare(self, ctx: Any, params: Any, /, *args: Any, **inputs: Any) -> Any:
        """A device node (``moves``): the job, pre-flighted, from every input but ``start_inputs``. Nothing moves."""
        raise NotImplementedError

    def start(self, ctx: Any, job: Any, /, *args: Any, **start_inputs: Any) -> dict[str, Any]:
        """A device node at the explicit Start (``ctx.start``): run ``job`` on its device; the outputs."""
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


# ---------------------------------------------------------------- declarations

def _port_name_ok(name: str) -> bool:
    return name.isidentifier() and not keyword.iskeyword(name) and name not in ("ctx", "params", "self")


def _check_declaration(cls: type) -> None:
    """Raise TypeError naming the class and the mistake; runs once, at import time."""
    where = f"node type {cls.__module__}.{cls.__qualname__}"

    def fail(msg: str) -> typing.NoReturn:
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
    if cls.moves:
        if cls.prepare is NodeType.prepare or cls.start is NodeType.start:
            fail("a node that moves (moves = True) must define prepare(ctx, params, **inputs) and "
                 "start(ctx, job, **start_inputs)")
        if cls.pure:
            fail("a node that moves cannot be pure")
        unknown = [name for name in cls.start_inputs if name not in {p.name for p in cls.inputs}]
        if unknown:
            fail(f"start_inputs name inputs it does not have: {unknown}")
    elif cls.run is NodeType.run:
        fail("must define run(self, ctx, params, **inputs)")
    if not all(isinstance(p, In) for p in cls.inputs) or not all(isinstance(p, Out) for p in cls.outputs):
        fail("inputs must be a tuple of In(...), outputs a tuple of Out(...)")
    for attribute in ("fixed_params", "reads"):
        for name in getattr(cls, attribute):
            if name not in cls.Params.model_fields:
                fail(f"{attribute} names unknown param {name!r}")
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
    for out in outputs:
        if not _port_name_ok(out.name):
            fail(f"output name {out.name!r} is not a valid identifier")
        if out.name in seen_out:
            fail(f"output {out.name!r} declared twice")
        seen_out.add(out.name)
        if out.type not in PORT_TYPES:
            fail(f"output {out.name!r} has unknown port type {out.type!r}; known: {', '.join(PORT_TYPES)}")


def check_ports(owner: str, ports: Ports) -> None:
    """Raise TypeError if ``ports`` (from an overridden ``ports(params)``) are malformed."""

    def fail(msg: str) -> typing.NoReturn:
        raise TypeError(f"{owner}: {msg}")

    _check_ports(fail, ports.inputs, ports.outputs)


_declared: dict[tuple[str, str], type[NodeType]] = {}  # (module, qualname) -> class, in import order
_checked: set[type] = set()


def register(cls: type[NodeType]) -> type[NodeType]:
    """Class decorator for node modules: check the declaration now (TypeError naming the class),
    and declare the class so that a registry loading its module picks it up."""
    _check_declaration(cls)
    _checked.add(cls)
    _declared[(cls.__module__, cls.__qualname__)] = cls
    return cls


def declared_in(module: str) -> list[type[NodeType]]:
    """Classes declared with ``@register`` in ``module`` or its submodules, in declaration order."""
    prefix = module + "."
    return [cls for (name, _), cls in _declared.items() if name == module or name.startswith(prefix)]


# ---------------------------------------------------------------- the registry

_build_lock = threading.Lock()


def _built(cls: type[NodeType]) -> type[NodeType]:
    """``cls`` with its params model built. flowmc's params models build when first used (``defer_build``:
    a graph builds only those of its types), and pydantic's build is not thread-safe (a model validated
    by two threads while it builds can be checked as its parent class): the registry builds each once,
    under a lock, before handing its type out."""
    params = cls.Params
    if not params.__pydantic_complete__:
        with _build_lock:
            if not params.__pydantic_complete__:
                params.model_rebuild(raise_errors=False)
    return cls


_generations = itertools.count(1)  # one counter for all registries: a generation names one state of one registry


class LibrarySource(Protocol):
    """Where ``lib.<stem>`` types come from: graph files with an interface, used as nodes."""

    def lookup(self, type_id: str, graph_dir: Path | None, registry: Registry) -> type[NodeType] | None: ...

    def types(self, graph_dir: Path | None, registry: Registry) -> dict[str, type[NodeType]]: ...


class Registry:
    """Node types by id, the library graphs they may use, and what failed to load.

    A source of types may be deferred (``defer``): its module is imported only when one of its
    type ids is looked up, or when every type is listed, so a command that needs a few types
    does not import them all. Loading a deferred source is not a change (``generation`` stays):
    the registry offered those types already.

    >>> reg = Registry()
    >>> "basic.add" in reg
    False
    >>> reg.lookup("basic.add")
    Traceback (most recent call last):
    ...
    flowmc.errors.GraphError: unknown node type 'basic.add'
    """

    def __init__(self, node_types: Iterable[type[NodeType]] = (), *, library: LibrarySource | None = None) -> None:
        self._types: dict[str, type[NodeType]] = {}
        self._origins: dict[str, str] = {}
        self.library = library
        self.failures: dict[str, str] = {}  # where (a module, an entry point, a folder) -> what went wrong
        self.node_folders: list[Path] = []  # folders of node files loaded (another process rebuilds from them)
        self._generation = next(_generations)
        self._pending: list[Loader] = []  # deferred sources not loaded yet, in the order given
        self._by_id: dict[str, Loader] = {}  # type ids a deferred source says it holds
        self._lock = threading.RLock()
        self._loading = False
        for cls in node_types:
            self.add(cls)

    @property
    def generation(self) -> int:
        """Changes whenever the registry does (and differs between registries): plans cache on it."""
        return self._generation

    def _changed(self) -> None:
        self._generation = next(_generations)

    def defer(self, load: Loader, type_ids: Iterable[str] | None = None) -> None:
        """A source loaded on first need: ``load(registry)`` adds its types (``add``) and records its
        failures (``failures``). ``type_ids``: the ids it holds when known without loading it."""
        with self._lock:
            self._pending.append(load)
            for type_id in type_ids or ():
                self._by_id.setdefault(type_id, load)

    def _load(self, sources: list[Loader]) -> None:
        with self._lock:
            generation, loading = self._generation, self._loading
            self._loading = True
            try:
                for load in sources:
                    if load in self._pending:
                        self._pending.remove(load)
                        load(self)
            finally:
                self._loading, self._generation = loading, generation

    def _load_all(self) -> None:
        if self._pending and not self._loading:
            self._load(list(self._pending))

    def add(self, cls: type[NodeType], origin: str = "") -> type[NodeType]:
        """Add a node type (checked as ``@register`` checks it); usable as a class decorator.

        Deferred sources load first (they came earlier). TypeError when another class already has its type id."""
        with self._lock:
            self._load_all()
            if cls not in _checked:
                _check_declaration(cls)
                _checked.add(cls)
            existing = self._types.get(cls.type_id)
            if existing is not None and existing is not cls and _name(existing) != _name(cls):
                raise TypeError(f"type_id {cls.type_id!r} of {_name(cls)} is already used by {_name(existing)}")
            self._types[cls.type_id] = cls
            self._origins[cls.type_id] = origin or cls.__module__
            self._changed()
            return cls

    register = add

    def remove(self, type_id: str) -> None:
        with self._lock:
            self._load_all()
            if self._types.pop(type_id, None) is not None:
                self._origins.pop(type_id, None)
                self._changed()

    def copy(self) -> Registry:
        """An independent registry with the same types and library (tests add their own types to one)."""
        with self._lock:
            self._load_all()
            other = Registry(library=self.library)
            other._types, other._origins, other.failures = dict(self._types), dict(self._origins), dict(self.failures)
            other.node_folders = list(self.node_folders)
            return other

    def __contains__(self, type_id: object) -> bool:
        return isinstance(type_id, str) and type_id in self.types()

    def types(self) -> dict[str, type[NodeType]]:
        """Node types from code, by id, sorted (every deferred source loads). Library graphs are in ``describe_all``."""
        with self._lock:
            self._load_all()
            return {type_id: _built(cls) for type_id, cls in sorted(self._types.items())}

    def origin(self, type_id: str) -> str:
        """Where a type came from: its module, an entry point or a node folder."""
        self.types()
        return self._origins.get(type_id, "library graph" if type_id.startswith("lib.") else "")

    def _code_type(self, type_id: str) -> type[NodeType] | None:
        cls = self._types.get(type_id)
        if cls is None and self._pending and not self._loading:
            with self._lock:
                source = self._by_id.get(type_id)
                if source is not None:
                    self._load([source])
                cls = self._types.get(type_id)
                if cls is None:  # a source may hold ids it did not announce
                    self._load_all()
                    cls = self._types.get(type_id)
        return cls

    def lookup(self, type_id: str, graph_dir: Any = None) -> type[NodeType]:
        """The class for ``type_id``; ``lib.<stem>`` ids are library graphs (beside ``graph_dir`` first).

        Raises GraphError when the type is unknown.
        """
        if type_id.startswith("lib."):
            if self.library is not None:
                found = self.library.lookup(type_id, Path(graph_dir) if graph_dir is not None else None, self)
                if found is not None:
                    return _built(found)
        else:
            cls = self._code_type(type_id)
            if cls is not None:
                return _built(cls)
        raise GraphError(f"unknown node type {type_id!r}", where=None)

    def unknown_type_hint(self) -> str:
        """What to add to an unknown-type message: the node sources that failed to load."""
        self.types()
        if not self.failures:
            return ""
        return " (node modules that failed to load: " + "; ".join(f"{m}: {e}" for m, e in self.failures.items()) + ")"

    def describe(self, cls_or_id: type[NodeType] | str, params: dict[str, Any] | None = None,
                 graph_dir: Any = None) -> dict[str, Any]:
        """``describe`` for a type id or class."""
        cls = self.lookup(cls_or_id, graph_dir) if isinstance(cls_or_id, str) else cls_or_id
        return describe(cls, params)

    def describe_all(self, graph_dir: Any = None) -> list[dict[str, Any]]:
        """Every type, then the library graphs (``lib.*``) seen from ``graph_dir``, sorted by type id."""
        found: dict[str, type[NodeType]] = self.types()
        if self.library is not None:
            found.update(self.library.types(Path(graph_dir) if graph_dir is not None else None, self))
        return [describe(found[t]) for t in sorted(found)]


Loader = Callable[[Registry], None]


def _name(cls: type) -> str:
    return f"{cls.__module__}.{cls.__qualname__}"


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


def describe(cls: type[NodeType], params: dict[str, Any] | None = None) -> dict[str, Any]:
    """A JSON-able description of a node type: ports, param schema, text. For the CLI and the editor.

    ``params`` (raw dict) matters only for types whose ports depend on params; when they are
    invalid the declared (static) ports are described.
    """
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
