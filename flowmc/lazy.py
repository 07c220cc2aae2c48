"""Package names imported on first read (PEP 562 module ``__getattr__``): ``import flowmc`` and
``import flowmc.runtime`` stay light, and a name's module is imported when the name is first used."""

from __future__ import annotations

import importlib
from typing import Any


def load(package: str, namespace: dict[str, Any], lazy: dict[str, str], name: str) -> Any:
    """``name`` from the module ``lazy`` maps it to, kept in the package's ``namespace`` for next time."""
    module = lazy.get(name)
    if module is None:
        raise AttributeError(f"module {package!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    namespace[name] = value
    return value


def names(namespace: dict[str, Any]) -> list[str]:
    """What ``dir(package)`` lists: the names loaded so far and every exported one."""
    return sorted(set(namespace) | set(namespace["__all__"]))
