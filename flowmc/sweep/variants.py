"""The variants of a sweep: grid axes (``node.param=a,b,c``, ranges ``start:stop:step``), a CSV table of
rows, or a folder of input files (``node.file=DIR/*.ngc``); several axes give their product.

A setting's target is a stored param (``node.param``) or an interface input (``name``), with the same
rules and typing as ``flowmc run --set/--input`` (``flowmc.settings``); node types are looked up in
``registry`` (default: the process's default registry). A variant's ``key`` hashes the
graph and its settings: ``--resume`` skips the keys a results folder already holds.
"""

from __future__ import annotations

import csv
import glob
import hashlib
import io
import itertools
import json
import math
import os
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from flowmc.settings import Target, UsageError, target

__all__ = ["Axis", "Variant", "grid_axis", "values_axis", "files_axis", "table_axis", "variants", "MAX_VARIANTS"]

MAX_VARIANTS = 1_000_000


@dataclass(frozen=True)
class Axis:
    """Settings that vary together: one target for a grid or files axis, a table's columns for a table.
    ``rows[i][j]`` is the value of ``targets[j]`` in the axis's i-th row (None: leave it as the graph has it)."""

    targets: tuple[Target, ...]
    rows: tuple[tuple[Any, ...], ...]
    label: str

    def __post_init__(self) -> None:
        if not self.rows:
            raise UsageError(f"{self.label}: no values")


@dataclass(frozen=True)
class Variant:
    """One run of the graph. ``index``: its place in the sweep; ``settings``: (target name, value) pairs;
    ``coords``: the row it takes from each axis (sweep order and grouping use them)."""

    index: int
    key: str
    settings: tuple[tuple[str, Any], ...]
    coords: tuple[int, ...]

    @property
    def params(self) -> dict[str, Any]:
        return dict(self.settings)


def _numbers(text: str, what: str) -> list[float | int]:
    """``start:stop:step`` inclusive of ``stop`` (within rounding), as ints when all three are whole."""
    parts = text.split(":")
    if len(parts) != 3:
        raise UsageError(f"{what}: a range is start:stop:step, got {text!r}")
    try:
        start, stop, step = (float(p) for p in parts)
    except ValueError:
        raise UsageError(f"{what}: {text!r} is not a range of numbers") from None
    if not all(math.isfinite(v) for v in (start, stop, step)) or step == 0 or (stop - start) * step < 0:
        raise UsageError(f"{what}: the range {text!r} never reaches its stop")
    count = math.floor((stop - start) / step + 1e-9) + 1
    if count > MAX_VARIANTS:
        raise UsageError(f"{what}: the range {text!r} has {count} values (at most {MAX_VARIANTS})")
    whole = all(v.is_integer() for v in (start, stop, step)) and "." not in text and "e" not in text.lower()
    values = [start + k * step for k in range(count)]
    return [int(v) for v in values] if whole else [float(f"{v:.12g}") for v in values]


def _registry(registry: Any) -> Any:
    if registry is not None:
        return registry
    from flowmc.plugins import default_registry

    return default_registry()


def grid_axis(graph: Any, spec: str, *, registry: Any = None) -> Axis:
    """``--grid TARGET=V1,V2,...``: comma-separated values (spaces around them dropped); a Number target
    also takes ranges ``start:stop:step`` among them (``0.01:0.05:0.01,0.1``)."""
    name, sep, text = spec.partition("=")
    what = f"--grid {name.strip()}"
    if not sep or not name.strip():
        raise UsageError(f"--grid {spec!r}: expected TARGET=V1,V2,... (TARGET: node.param or an input name)")
    tgt = target(graph, name, what, _registry(registry))
    values: list[Any] = []
    for item in text.split(","):
        if tgt.port_type == "Number" and ":" in item:
            values += _numbers(item.strip(), what)
        else:
            values.append(tgt.parse(item.strip(), what))
    return Axis((tgt,), tuple((v,) for v in values), what)


def values_axis(graph: Any, name: str, values: Iterable[Any], *, registry: Any = None) -> Axis:
    """An axis of Python values (the editor's controls give them typed) for a setting named as on the
    command line."""
    tgt = target(graph, name, name, _registry(registry))
    return Axis((tgt,), tuple((v,) for v in values), name)


def files_axis(graph: Any, spec: str, cwd: Path | None = None, *, registry: Any = None) -> Axis:
    """``--over TARGET=PATTERN``: every file the glob pattern matches (relative to ``cwd``), sorted, each
    given as a path relative to the graph's folder (files outside that folder are refused: graph files
    only read files under their folder)."""
    name, sep, pattern = spec.partition("=")
    what = f"--over {name.strip()}"
    if not sep or not name.strip() or not pattern.strip():
        raise UsageError(f"--over {spec!r}: expected TARGET=PATTERN, e.g. gcode.file=programs/*.ngc")
    tgt = target(graph, name, what, _registry(registry))
    if tgt.port_type not in ("Text", None):
        raise UsageError(f"{what}: takes file names, but it is a {tgt.port_type}")
    cwd = Path.cwd() if cwd is None else cwd
    pattern = pattern.strip()
    full = pattern if os.path.isabs(pattern) else str(cwd / pattern)
    files = sorted(Path(p) for p in glob.glob(full, recursive=True) if Path(p).is_file())
    if not files:
        raise UsageError(f"{what}: no file matches {pattern!r}")
    root = graph.base_dir.resolve()
    values = []
    for file in files:
        resolved = file.resolve()
        if not resolved.is_relative_to(root):
            raise UsageError(f"{what}: {file} is outside the graph's folder {root}; graph files only read "
                             "files under their folder")
        values.append(resolved.relative_to(root).as_posix())
    return Axis((tgt,), tuple((v,) for v in values), what)


def table_axis(graph: Any, file: str | os.PathLike, text: str | None = None, *, registry: Any = None) -> Axis:
    """``--table variants.csv``: a header of targets, then one variant per row; an empty cell leaves that
    target as the graph has it. Errors name ``file:line``."""
    where = str(file)
    if text is None:
        try:
            text = Path(file).read_text(encoding="utf-8-sig")
        except (OSError, UnicodeDecodeError) as exc:
            raise UsageError(f"{where}: cannot read the table: {getattr(exc, 'strerror', None) or exc}") from None
    reader = csv.reader(io.StringIO(text))
    try:
        header = next(reader)
    except StopIteration:
        raise UsageError(f"{where}: the table is empty (a header of targets, then one row per variant)") from None
    except csv.Error as exc:
        raise UsageError(f"{where}:1: {exc}") from None
    names = [h.strip() for h in header]
    if len(set(names)) != len(names) or not all(names):
        raise UsageError(f"{where}:1: the header needs distinct, non-empty targets, got {header}")
    reg = _registry(registry)
    targets = tuple(target(graph, n, f"{where}:1: column {n!r}", reg) for n in names)
    rows = []
    try:
        for record in reader:
            line = reader.line_num
            if not any(cell.strip() for cell in record):
                continue
            if len(record) != len(targets):
                raise UsageError(f"{where}:{line}: {len(record)} cells, the header has {len(targets)}")
            rows.append(tuple(None if cell.strip() == "" else t.parse(cell.strip(),
                                                                      f"{where}:{line}: {t.name}")
                              for t, cell in zip(targets, record)))
    except csv.Error as exc:
        raise UsageError(f"{where}:{reader.line_num}: {exc}") from None
    return Axis(targets, tuple(rows), where)


def _key(fingerprint: str, settings: Iterable[tuple[str, Any]]) -> str:
    text = fingerprint + "\0" + json.dumps(sorted(settings), sort_keys=True, default=str)
    return hashlib.blake2b(text.encode(), digest_size=10).hexdigest()


def variants(graph: Any, axes: list[Axis]) -> list[Variant]:
    """The product of the axes, first axis outermost. Two settings of one target are refused."""
    seen: dict[str, str] = {}
    for axis in axes:
        for tgt in axis.targets:
            if tgt.name in seen:
                raise UsageError(f"{axis.label}: {tgt.name} is already swept by {seen[tgt.name]}")
            seen[tgt.name] = axis.label
    total = math.prod(len(a.rows) for a in axes) if axes else 1
    if total > MAX_VARIANTS:
        raise UsageError(f"the sweep has {total} variants (at most {MAX_VARIANTS}); use fewer values")
    fingerprint = graph.fingerprint_json()
    out = []
    for index, coords in enumerate(itertools.product(*(range(len(a.rows)) for a in axes))):
        settings = tuple((t.name, v) for axis, c in zip(axes, coords)
                         for t, v in zip(axis.targets, axis.rows[c]) if v is not None)
        out.append(Variant(index, _key(fingerprint, settings), settings, tuple(coords)))
    return out
