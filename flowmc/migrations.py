"""Schema-version migrations of graph files: the one place that knows old formats.

``MIGRATIONS[n]`` turns a raw (parsed JSON) graph of version ``n`` into version ``n + 1``.
There is only version 1 so far, so the table is empty; an unknown version is refused.
"""

from __future__ import annotations

from typing import Any, Callable, Final

from flowmc.errors import GraphError

__all__ = ["SCHEMA_VERSION", "MIGRATIONS", "migrate"]

SCHEMA_VERSION: Final = 1

MIGRATIONS: dict[int, Callable[[dict[str, Any]], dict[str, Any]]] = {}


def migrate(raw: Any, where: str) -> Any:
    """Bring a parsed graph file up to ``SCHEMA_VERSION`` or raise GraphError naming the file."""
    if not isinstance(raw, dict):
        raise GraphError(f"$: a graph file holds a JSON object, not {type(raw).__name__}", where=where)
    version = raw.get("schema_version")
    if isinstance(version, bool) or not isinstance(version, int):
        raise GraphError(f"$.schema_version: missing or not an integer ({version!r}); this flowmc reads {SCHEMA_VERSION}",
                         where=where)
    while version != SCHEMA_VERSION:
        step = MIGRATIONS.get(version)
        if step is None:
            raise GraphError(
                f"$.schema_version: unknown schema version {version} (this flowmc reads {SCHEMA_VERSION})", where=where
            )
        raw = step(raw)
        version = raw["schema_version"]
    return raw
