"""Start-up: build the registry a process runs graphs with, from every place node types come from.

1. The built-in node modules: every module of ``flowmc.nodes``.
2. Installed plugins: entry points in the ``flowmc.nodes`` group. An entry point names a module
   (its ``@register`` classes are taken), a node class, or a list of node classes.
3. Node folders: every ``*.py`` file in a folder named in the user config or given with
   ``flowmc --nodes DIR``. The config is ``$XDG_CONFIG_HOME/flowmc/config.toml`` (default
   ``~/.config/flowmc/config.toml``; ``FLOWMC_CONFIG`` names another file) and holds
   ``node_folders = ["~/my-nodes", ...]`` (relative folders are relative to the config file).
4. Library graphs: ``lib.<stem>`` for flowmc's own library (package data, ``flowmc/lib``) and
   for a ``lib/`` folder beside the graph being run.

Graph files never name code: only the person running flowmc chooses plugins and node folders.
A source that fails to load (an import error, a declaration mistake, a type id already taken)
is recorded in ``registry.failures``, shown by ``flowmc nodes`` and in unknown-type messages,
and never stops the others.
"""

from __future__ import annotations

import functools
import hashlib
import importlib
import importlib.util
import os
import sys
import threading
from importlib import resources
from pathlib import Path
from typing import Any, Iterable

import flowmc.nodes
from flowmc.nodes.subgraph import GraphLibrary
from flowmc.registry import NodeType, Registry, declared_in

__all__ = ["ENTRY_POINT_GROUP", "build_registry", "default_registry", "add_node_folder", "config_path",
           "package_library"]

ENTRY_POINT_GROUP = "flowmc.nodes"

_default: Registry | None = None
_lock = threading.Lock()


def package_library() -> Path:
    """flowmc's own library graphs, shipped inside the package."""
    return Path(str(resources.files("flowmc").joinpath("lib")))


def config_path() -> Path:
    explicit = os.environ.get("FLOWMC_CONFIG")
    if explicit:
        return Path(explicit).expanduser()
    base = os.environ.get("XDG_CONFIG_HOME") or Path.home() / ".config"
    return Path(base) / "flowmc" / "config.toml"


def default_registry() -> Registry:
    """The process's registry, built on first use (``build_registry()``)."""
    global _default
    with _lock:
        if _default is None:
            _default = build_registry()
        return _default


def build_registry(*, node_folders: Iterable[str | os.PathLike] = (), entry_points: bool = True,
                   config: bool = True) -> Registry:
    """A registry from the built-in nodes, entry points, the config's node folders and ``node_folders``.

    Built-in node modules and entry points are deferred: a module is imported when one of its types
    is first looked up (``flowmc.nodes.BUILT_IN`` names their ids), entry points when a
    type is not found elsewhere or every type is listed. Node folders load at once."""
    registry = Registry(library=GraphLibrary([package_library()]))
    for module, type_ids in flowmc.nodes.BUILT_IN.items():
        registry.defer(functools.partial(_load_module, f"{flowmc.nodes.__name__}.{module}"), type_ids)
    if entry_points:
        registry.defer(_load_entry_points)
    folders = [*(_config_folders(registry) if config else []), *(Path(f) for f in node_folders)]
    for node_folder in dict.fromkeys(Path(f).expanduser().resolve() for f in folders):  # each folder once
        add_node_folder(registry, node_folder)
    return registry


def _add_all(registry: Registry, classes: Iterable[type[NodeType]], origin: str) -> list[str]:
    added = []
    for cls in classes:
        try:
            registry.add(cls, origin=origin)
        except TypeError as exc:
            registry.failures[f"{origin} ({getattr(cls, '__qualname__', cls)})"] = str(exc)
        else:
            added.append(cls.type_id)
    return added


def _load_module(name: str, registry: Registry) -> None:
    try:
        importlib.import_module(name)
    except Exception as exc:  # a broken module must not break every graph
        registry.failures[name] = f"{type(exc).__name__}: {exc}"
        return
    _add_all(registry, declared_in(name), name)


def _load_entry_points(registry: Registry) -> None:
    from importlib import metadata  # scanning the installed packages costs time: only when needed

    for entry in sorted(metadata.entry_points(group=ENTRY_POINT_GROUP), key=lambda e: e.name):
        _load_entry_point(registry, entry)


def _load_entry_point(registry: Registry, entry: Any) -> None:
    """One ``importlib.metadata.EntryPoint``."""
    origin = f"entry point {entry.name} ({entry.value})"
    try:
        target: Any = entry.load()
    except Exception as exc:
        registry.failures[origin] = f"{type(exc).__name__}: {exc}"
        return
    if isinstance(target, type(sys)):
        classes = declared_in(target.__name__)
    elif isinstance(target, type):
        classes = [target]
    elif isinstance(target, (list, tuple)):
        classes = list(target)
    else:
        registry.failures[origin] = "must name a module, a node type or a list of node types"
        return
    _add_all(registry, classes, origin)


def add_node_folder(registry: Registry, folder: str | os.PathLike) -> list[str]:
    """Import every ``*.py`` in ``folder`` as a node module and add its types; returns their ids.

    Each file is one module (named after the folder, so two folders may hold the same file name);
    a file that fails is recorded in ``registry.failures``."""
    path = Path(folder).expanduser().resolve()
    where = f"node folder {path}"
    if not path.is_dir():
        registry.failures[where] = "not a folder"
        return []
    if path not in registry.node_folders:
        registry.node_folders.append(path)
    package = "flowmc_node_folder_" + hashlib.blake2b(str(path).encode(), digest_size=6).hexdigest()
    added = []
    for file in sorted(path.glob("*.py")):
        if file.name.startswith(("_", ".")):
            continue
        name = f"{package}_{file.stem}"
        origin = f"{where}: {file.name}"
        try:
            spec = importlib.util.spec_from_file_location(name, file)
            if spec is None or spec.loader is None:
                raise ImportError("cannot be imported")
            module = importlib.util.module_from_spec(spec)
            sys.modules[name] = module
            spec.loader.exec_module(module)
        except Exception as exc:
            sys.modules.pop(name, None)
            registry.failures[origin] = f"{type(exc).__name__}: {exc}"
            continue
        added += _add_all(registry, declared_in(name), origin)
    return added


def _config_folders(registry: Registry) -> list[Path]:
    path = config_path()
    if not path.is_file():
        return []
    import tomllib

    where = f"config {path}"
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        registry.failures[where] = str(exc)
        return []
    folders = data.get("node_folders", [])
    if not isinstance(folders, list) or not all(isinstance(f, str) for f in folders):
        registry.failures[where] = "node_folders must be a list of folder names"
        return []
    return [path.parent / Path(f).expanduser() for f in folders]
