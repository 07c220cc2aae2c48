"""Where a graph lives (its folder and the root files must stay under) and what a node sees.

Graph files never reach outside their folder: ``resolve_inside`` refuses absolute paths,
``..`` that climbs out, and symlinks that point out (it resolves them first).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from flowmc.errors import GraphError, printable

__all__ = ["Site", "NodeContext", "resolve_inside", "files_read"]

NAME_MAX = 255  # bytes in one file or folder name (Linux, macOS and Windows file systems)


def resolve_inside(root: Path, base: Path, rel: str, where: str | None = None) -> Path:
    """``base / rel`` with symlinks resolved; GraphError unless it stays under ``root``."""
    if not isinstance(rel, str) or not rel.strip():
        raise GraphError("empty file name", where=where)
    shown = f"'{printable(rel, 120)}'"
    if "\x00" in rel or printable(rel) != rel:
        raise GraphError(f"{shown}: a file name may not hold control characters (NUL, escapes, lone surrogates)",
                         where=where)
    if any(len(os.fsencode(part)) > NAME_MAX for part in Path(rel).parts):
        raise GraphError(f"{shown}: a file or folder name longer than {NAME_MAX} bytes", where=where)
    if os.path.isabs(rel) or rel.startswith("~"):
        raise GraphError(f"{shown}: absolute paths are refused; use a path relative to the graph's folder", where=where)
    try:
        target = (base / rel).resolve()
        root_resolved = root.resolve()
    except (OSError, ValueError) as exc:  # a name too long for the file system, a symlink loop
        raise GraphError(f"{shown}: not a usable file name ({getattr(exc, 'strerror', None) or exc})",
                         where=where) from None
    if not target.is_relative_to(root_resolved):
        raise GraphError(f"{shown} leaves the graph's folder {root_resolved}", where=where)
    return target


@dataclass(frozen=True)
class Site:
    """The folder of the graph being validated, the root its files must stay under,
    and the chain of sub-graph files that led here (to refuse recursion)."""

    graph_dir: Path
    root: Path
    chain: tuple[Path, ...] = ()

    @classmethod
    def for_graph(cls, graph_dir: Path, file: Path | None = None) -> "Site":
        graph_dir = Path(graph_dir).resolve()
        return cls(graph_dir, graph_dir, (file.resolve(),) if file is not None else ())

    def name(self, path: Path) -> str:
        """How to show ``path`` in a message: relative to the root when possible."""
        try:
            return str(path.relative_to(self.root))
        except ValueError:
            return path.name


@dataclass
class NodeContext:
    """What ``run`` gets as ``ctx``: the node id, the graph folder, safe file access, logging."""

    node_id: str
    site: Site
    _log: Callable[[str], None] = field(repr=False)
    binding: Any = field(default=None, repr=False)  # sub-graph node types: their bound inner plan
    _child: Callable[[], Any] | None = field(default=None, repr=False)
    start: Any = field(default=None, repr=False)  # the explicit Start a device node's start() runs under
    _announce: Callable[[Any], None] | None = field(default=None, repr=False)  # an Event into the run
    _reads: Callable[[], frozenset[Path]] | None = field(default=None, repr=False)  # files the graph reads

    @property
    def graph_dir(self) -> Path:
        return self.site.graph_dir

    def resolve(self, rel: str) -> Path:
        """A file named in a param, relative to the graph's folder; refuses paths that leave it."""
        return resolve_inside(self.site.root, self.site.graph_dir, rel, where=f"node {self.node_id!r}")

    def resolve_output(self, rel: str) -> Path:
        """A file a node writes, named in a param. Like ``resolve``, and it must not be a graph file, a
        file the graph reads (its own inputs, sub-graphs), a symbolic link, or a folder:
        a writing node never replaces what it or another node reads."""
        where = f"node {self.node_id!r}"
        target = self.resolve(rel)
        named = self.site.graph_dir / rel
        shown = printable(rel, 120)
        if named.is_symlink():
            raise GraphError(f"'{shown}' is a symbolic link; nodes do not write through links", where=where)
        if target.is_dir():
            raise GraphError(f"'{shown}' is a folder; name a file to write", where=where)
        if target.name.endswith(".flowmc.json"):
            raise GraphError(f"'{shown}' is a graph file; nodes never overwrite graph files", where=where)
        reads = self._reads() if self._reads is not None else frozenset()
        if target in reads:  # a folder it reads (subroutines) may take new files: they are read only when called
            raise GraphError(f"'{shown}' is a file this graph reads; write to another name", where=where)
        return target

    def log(self, message: str) -> None:
        self._log(str(message))

    def announce(self, event: Any) -> None:
        """Put an event (``flowmc.runtime.events.Event``) into the run: structures announce iterations."""
        if self._announce is not None:
            self._announce(event)

    def child_runtime(self) -> Any:
        """A runtime owned by the running runtime for this node (sub-graphs keep their cache there)."""
        if self._child is None:
            raise RuntimeError("no child runtime outside a run")
        return self._child()


def files_read(plan: Any) -> frozenset[Path]:
    """Every file and folder a plan reads (resolved): its graph file, its sub-graph files, and what each
    node's ``reads`` params name, through sub-graphs in turn. What writing nodes may not replace."""
    out: set[Path] = set()
    seen: set[int] = set()
    stack = [plan]
    while stack:
        current = stack.pop()
        if id(current) in seen:
            continue
        seen.add(id(current))
        if current.graph.path is not None:
            out.add(Path(current.graph.path).resolve())
        out.update(Path(p).resolve() for p in current.deps)
        site = current.site
        for node in current.nodes.values():
            for name in node.cls.reads:
                rel = node.raw_params.get(name)
                if isinstance(rel, str) and rel:
                    try:
                        out.add(resolve_inside(site.root, site.graph_dir, rel))
                    except GraphError:
                        pass  # the node reports it when it runs
            if node.binding is not None and hasattr(node.binding, "nodes"):
                stack.append(node.binding)
    return frozenset(out)
