"""Schema-version migrations of graph files: the one place that knows old formats.

``MIGRATIONS[n]`` turns a raw (parsed JSON) graph of version ``n`` into version ``n + 1``; an
unknown version is refused.

- 1 -> 2: version 2 lets a node hold ``bodies`` (the graphs of loops and case structures) and adds the
  optional ``view`` section (comments, labels, interface terminal places); a version-1 file is a
  version-2 file whose nodes hold no bodies and that has no view, so it loads unchanged.
"""

from __future__ import annotations

from typing import Any, Callable, Final

from flowmc.errors import GraphError

__all__ = ["SCHEMA_VERSION", "MIGRATIONS", "migrate"]

SCHEMA_VERSION: Final = 2


def _to_2(raw: dict[str, Any]) -> dict[str, Any]:
    return {**raw, "schema_version": 2}


MIGRATIONS: dict[int, Callable[[dict[str, Any]], dict[str, Any]]] = {1: _to_2}


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
