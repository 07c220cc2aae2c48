"""Table: named numpy columns of equal length (reports, pulse tables).

Immutable: the columns are read-only copies, so a Table can be cached and shared
between nodes without one node changing what another sees.

Example
-------
>>> t = Table({"name": ["cycle_s", "error_mm"], "value": [1.5, 0.002]})
>>> len(t), t.names
(2, ('name', 'value'))
>>> t.to_rows()[0]
{'name': 'cycle_s', 'value': 1.5}
"""

from __future__ import annotations

import hashlib
from typing import Any, Iterable, Mapping

import numpy as np

from flowmc.errors import FlowmcError

__all__ = ["Table"]


class Table:
    """Named columns of equal length; column order is kept as given."""

    __slots__ = ("_columns", "_digest")

    def __init__(self, columns: Mapping[str, Any]):
        cols: dict[str, np.ndarray] = {}
        length = None
        for name, values in columns.items():
            if not isinstance(name, str) or not name:
                raise FlowmcError(f"column names must be non-empty strings, got {name!r}", where="table")
            array = np.array(values)  # a copy: the caller keeps their array
            if array.ndim != 1:
                raise FlowmcError(f"column {name!r} must be one-dimensional, got shape {array.shape}", where="table")
            if array.dtype == object:
                raise FlowmcError(f"column {name!r} mixes value kinds; use numbers or strings", where="table")
            if length is not None and len(array) != length:
                raise FlowmcError(f"column {name!r} has {len(array)} rows, expected {length}", where="table")
            length = len(array)
            array.setflags(write=False)
            cols[name] = array
        self._columns = cols
        self._digest: str | None = None

    @classmethod
    def from_rows(cls, rows: Iterable[Mapping[str, Any]]) -> "Table":
        """Build from dicts sharing the same keys (the first row's key order is kept)."""
        rows = list(rows)
        if not rows:
            return cls({})
        names = list(rows[0])
        for i, row in enumerate(rows):
            if list(row) != names:
                raise FlowmcError(f"row {i} has keys {sorted(row)}, expected {sorted(names)}", where="table")
        return cls({n: [row[n] for row in rows] for n in names})

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self._columns)

    @property
    def columns(self) -> Mapping[str, np.ndarray]:
        return dict(self._columns)

    def __len__(self) -> int:
        return len(next(iter(self._columns.values()))) if self._columns else 0

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self._columns[name]
        except KeyError:
            raise FlowmcError(f"no column {name!r}; columns: {', '.join(self.names)}", where="table") from None

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Table) and self.digest() == other.digest()

    def __hash__(self) -> int:
        return hash(self.digest())

    def __repr__(self) -> str:
        return f"Table({len(self)} rows: {', '.join(self.names)})"

    def digest(self) -> str:
        """Content hash over column names, dtypes, shapes and bytes."""
        if self._digest is None:
            h = hashlib.blake2b(b"Table", digest_size=16)
            for name, array in self._columns.items():
                h.update(repr((name, array.dtype.str, array.shape)).encode())
                h.update(np.ascontiguousarray(array).tobytes())
            self._digest = h.hexdigest()
        return self._digest

    def to_rows(self) -> list[dict[str, Any]]:
        """Rows as dicts of plain Python scalars (JSON-able)."""
        lists = {name: array.tolist() for name, array in self._columns.items()}
        return [{name: lists[name][i] for name in lists} for i in range(len(self))]

    def summary(self, max_rows: int = 20) -> dict[str, Any]:
        """Small and JSON-able: all rows when short, else per-column min/max/mean."""
        out: dict[str, Any] = {"type": "Table", "rows": len(self), "columns": list(self.names)}
        if len(self) <= max_rows:
            out["data"] = self.to_rows()
            return out
        stats = {}
        for name, array in self._columns.items():
            if np.issubdtype(array.dtype, np.number) and len(array):
                stats[name] = {"min": float(array.min()), "max": float(array.max()), "mean": float(array.mean())}
        out["stats"] = stats
        return out
