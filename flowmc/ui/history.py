"""Undo and redo as whole-graph snapshots: graphs are small, and a snapshot cannot drift out of step
with the edit that made it (as a hand-written inverse command can)."""

from __future__ import annotations

from flowmc.graph import Graph

__all__ = ["History"]


class History:
    def __init__(self, limit: int = 200):
        self.limit = limit
        self._undo: list[Graph] = []
        self._redo: list[Graph] = []

    @property
    def can_undo(self) -> bool:
        return bool(self._undo)

    @property
    def can_redo(self) -> bool:
        return bool(self._redo)

    def record(self, graph: Graph) -> None:
        """Remember ``graph`` as it is before an edit; a new edit forgets what could be redone."""
        self._undo.append(graph.model_copy(deep=True))
        del self._undo[:-self.limit]
        self._redo.clear()

    def undo(self, current: Graph) -> Graph | None:
        """The graph before the last edit (None when there is none); ``current`` becomes redoable."""
        if not self._undo:
            return None
        self._redo.append(current.model_copy(deep=True))
        return self._restored(self._undo.pop(), current)

    def redo(self, current: Graph) -> Graph | None:
        if not self._redo:
            return None
        self._undo.append(current.model_copy(deep=True))
        return self._restored(self._redo.pop(), current)

    @staticmethod
    def _restored(snapshot: Graph, current: Graph) -> Graph:
        snapshot.path = current.path
        return snapshot
