"""Sweep results: one row per variant, kept as they arrive and written as CSV and Parquet.

A results folder holds ``rows.jsonl`` (the journal: one JSON row per finished variant, appended and
flushed as batches come back, so Ctrl-C or a crash loses at most the batches in flight), and, written
whole at the end or on an interruption, ``rows.csv``, ``rows.parquet`` and ``report.html``.

A table row: ``variant``, ``status`` (done, failed, lost: a worker died), ``error``, ``duration_s``,
``ran``/``cached`` (nodes run and reused from the worker's cache), ``worker``, then one column per swept
setting (as named on the command line), then ``out.<output>`` columns: every graph output's summary
flattened (a Number as it is; a name/value Table as ``out.<table>.<name>``; other summaries by key).
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from flowmc.errors import FlowmcError
from flowmc.fileio import write_atomic
from flowmc.settings import UsageError

__all__ = ["FIXED_COLUMNS", "Journal", "flatten_outputs", "table", "write_tables", "write_atomic"]

FIXED_COLUMNS = ("variant", "status", "error", "duration_s", "ran", "cached", "worker")
JOURNAL = "rows.jsonl"
_SKIPPED_KEYS = {"type", "columns"}


def flatten_outputs(outputs: dict[str, Any]) -> dict[str, Any]:
    """``{output: summary}`` -> ``{"out.<output>[.<key>...]": scalar}`` (lists as JSON text)."""
    flat: dict[str, Any] = {}
    for name, summary in outputs.items():
        _flatten(f"out.{name}", summary, flat)
    return flat


def _flatten(prefix: str, value: Any, flat: dict[str, Any]) -> None:
    if isinstance(value, dict):
        columns = value.get("columns") or []
        if value.get("type") == "Table" and "data" in value and "name" in columns and "value" in columns:
            for row in value["data"]:
                flat[f"{prefix}.{row['name']}"] = row["value"]
            return
        for key, item in value.items():
            if key in _SKIPPED_KEYS:
                continue
            _flatten(prefix if key == "stats" else f"{prefix}.{key}", item, flat)
    elif isinstance(value, (list, tuple)):
        flat[prefix] = json.dumps(value, default=str)
    else:
        flat[prefix] = value


def table(rows: Iterable[dict[str, Any]], params: list[str]) -> tuple[list[str], list[dict[str, Any]]]:
    """Journal rows -> (columns, flat rows) sorted by variant; output columns in first-seen order."""
    flat_rows, outputs = [], {}
    for row in sorted(rows, key=lambda r: r["variant"]):
        flat = {c: row.get(c) for c in FIXED_COLUMNS}
        flat.update({p: row.get("params", {}).get(p) for p in params})
        out = flatten_outputs(row.get("outputs") or {})
        outputs.update(dict.fromkeys(out))
        flat.update(out)
        flat_rows.append(flat)
    return [*FIXED_COLUMNS, *params, *outputs], flat_rows


def _csv_bytes(columns: list[str], rows: list[dict[str, Any]]) -> bytes:
    text = io.StringIO()
    writer = csv.writer(text, lineterminator="\n")
    writer.writerow(columns)
    for row in rows:
        writer.writerow(["" if row.get(c) is None else _cell(row.get(c)) for c in columns])
    return text.getvalue().encode("utf-8")


def _cell(value: Any) -> Any:
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else str(value)
    return value


def _arrow(columns: list[str], rows: list[dict[str, Any]]) -> Any:
    """A pyarrow table; a column whose values mix kinds (numbers and text, say) is stored as text."""
    import pyarrow as pa

    arrays = {}
    for column in columns:
        values = [row.get(column) for row in rows]
        try:
            arrays[column] = pa.array(values)
        except (pa.ArrowInvalid, pa.ArrowTypeError):
            arrays[column] = pa.array([None if v is None else str(v) for v in values], type=pa.string())
    return pa.table(arrays)


def write_tables(folder: Path, columns: list[str], rows: list[dict[str, Any]]) -> list[Path]:
    """``rows.csv`` and ``rows.parquet`` in ``folder`` (each written whole, atomically)."""
    import pyarrow.parquet as pq

    csv_path, parquet_path = folder / "rows.csv", folder / "rows.parquet"
    write_atomic(csv_path, _csv_bytes(columns, rows))
    buffer = io.BytesIO()
    pq.write_table(_arrow(columns, rows), buffer)
    write_atomic(parquet_path, buffer.getvalue())
    return [csv_path, parquet_path]


class Journal:
    """``rows.jsonl`` in a results folder. ``rows``: by variant key, the latest row (those already there too
    when resuming);
    a folder that holds a journal is refused unless resuming or ``overwrite``."""

    def __init__(self, folder: Path, *, resume: bool = False, overwrite: bool = False):
        self.folder = folder
        self.path = folder / JOURNAL
        self.rows: dict[str, dict[str, Any]] = {}
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise FlowmcError(f"cannot make the results folder: {exc.strerror or exc}", where=str(folder)) from None
        if self.path.exists() and self.path.stat().st_size and not (resume or overwrite):
            raise UsageError("holds the rows of an earlier sweep: --resume to skip the variants done, "
                              "--overwrite to start again, or choose another --out", where=str(folder))
        if resume and self.path.exists():
            self.rows = self._read()
        text = "".join(json.dumps(r) + "\n" for r in self.rows.values())
        write_atomic(self.path, text.encode("utf-8"))  # drops a line cut short by a crash
        self._file = open(self.path, "a", encoding="utf-8")

    def _read(self) -> dict[str, dict[str, Any]]:
        rows = {}
        with open(self.path, encoding="utf-8") as f:
            for line in f:
                try:
                    row = json.loads(line)
                except json.JSONDecodeError:
                    continue  # the last line of a journal cut off mid-write
                if isinstance(row, dict) and "key" in row:
                    rows[row["key"]] = row
        return rows

    @property
    def finished(self) -> set[str]:
        """Keys of the variants that ran to an answer (done or failed): ``--resume`` skips them."""
        return {k for k, r in self.rows.items() if r.get("status") in ("done", "failed")}

    def add(self, rows: list[dict[str, Any]]) -> None:
        for row in rows:
            self._file.write(json.dumps(row) + "\n")
            self.rows[row["key"]] = row
        self._file.flush()
        os.fsync(self._file.fileno())

    def close(self) -> None:
        self._file.close()
