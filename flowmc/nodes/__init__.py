"""Node types: thin adapters over flowmc.motion and flowmc.devices, one module per area.

``load_all()`` imports every module of this package (and only this package) so that their
``@register`` decorators run. A module that fails to import is recorded, not fatal: graphs
that do not use its types still run, and the failure is shown where a type is missing.
"""

from __future__ import annotations

import importlib
import pkgutil

from flowmc import registry

__all__ = ["load_all", "load_failures"]

_failures: dict[str, str] = {}
_loaded: dict[str, type] = {}  # type_id -> class registered by our modules
_imported = False


def load_all() -> dict[str, str]:
    """Import every ``flowmc.nodes.*`` module once; return ``{module: error}`` for those that failed."""
    global _imported
    if not _imported:
        _imported = True
        for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
            name = f"{__name__}.{info.name}"
            try:
                importlib.import_module(name)
            except Exception as exc:  # a teammate's broken module must not break every graph
                _failures[name] = f"{type(exc).__name__}: {exc}"
        from flowmc.subgraph import Subgraph  # the core's one node type, registered with the rest

        registry.register(Subgraph)
        prefix = __name__ + "."
        _loaded["subgraph"] = Subgraph
        _loaded.update({t: c for t, c in registry.registered().items() if c.__module__.startswith(prefix)})
    else:  # a registry.scoped() block may have dropped types imported inside it
        current = registry.registered()
        for type_id, cls in _loaded.items():
            if type_id not in current:
                registry.register(cls)
    return dict(_failures)


def load_failures() -> dict[str, str]:
    return dict(_failures)
