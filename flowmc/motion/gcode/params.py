"""Parameters: numbered (#1-#5602), named local (#<name>), named global (#<_name>), predefined read-only
ones (#<_x>, #<_metric>, ...), and LinuxCNC's parameter file (``.var``) with the persistent ones.

As in LinuxCNC: an unset numbered parameter reads 0, an unset named one is an error; #1-#30 and
local named parameters belong to the subroutine call that set them; the coordinate-system table
(#5161-#5390) holds machine units. The parameter file has two numbers a line (number, value) in
ascending order; the persistent range 5161-5390 is always written back, with any user parameters
(31-5000) the file listed.
"""

from __future__ import annotations

import math
import os
from pathlib import Path as FsPath

import flowmc.budget as budget
from flowmc.errors import GcodeError
from flowmc.fileio import read_bytes
from flowmc.motion.gcode.expr import NUM_PARAMS, EvalError

__all__ = ["Parameters", "read_var_file", "format_var_file", "PERSISTENT"]

#: LinuxCNC's persistent range (G28/G30 homes, G92, the nine coordinate systems).
PERSISTENT = range(5161, 5391)
# Numbered parameters the interpreter computes when read (tool, position); writing them is an error.
_COMPUTED = set(range(5400, 5414)) | set(range(5420, 5429)) | set(range(5021, 5030)) | set(range(5081, 5090))


class Parameters:
    """The parameter store of one interpretation. ``owner`` answers ``computed(index)`` for the
    computed numbered parameters and ``predefined(name)`` for #<_...> names it knows."""

    def __init__(self, owner, initial: dict[int, float] | None = None):
        self.owner = owner
        self.num = [0.0] * (NUM_PARAMS + 1)
        self.file_numbers: set[int] = set()
        for index, value in (initial or {}).items():
            self.num[index] = float(value)
            self.file_numbers.add(index)
        self.globals: dict[str, float] = {}
        self.locals: dict[str, float] = {}

    # Reading -----------------------------------------------------------------------------------
    def number(self, index: int) -> float:
        if index in _COMPUTED:
            return self.owner.computed(index)
        return self.num[index]

    def named(self, name: str) -> float:
        if name[0] == "_":
            value = self.globals.get(name)
            if value is None:
                value = self.owner.predefined(name)
                if value is None:
                    raise EvalError(f"named parameter #<{name}> is not defined")
            return value
        value = self.locals.get(name)
        if value is None:
            raise EvalError(f"named parameter #<{name}> is not defined"
                            + (" (named parameters without a leading '_' are local to their subroutine)"
                               if self.owner.call_level() > 0 else ""))
        return value

    def exists(self, name: str) -> bool:
        if name[0] == "_":
            return name in self.globals or self.owner.predefined(name) is not None
        return name in self.locals

    # Writing (all settings of a line at once, after its values were read) ---------------------
    def set_number(self, index: int, value: float) -> None:
        if index in _COMPUTED:
            raise EvalError(f"parameter #{index} is read-only (the interpreter computes it)")
        self.num[index] = value

    def set_named(self, name: str, value: float) -> None:
        if name[0] == "_":
            if name not in self.globals and self.owner.predefined(name) is not None:
                raise EvalError(f"parameter #<{name}> is read-only")
            self.globals[name] = value
        else:
            self.locals[name] = value

    def persistent(self) -> dict[int, float]:
        """What LinuxCNC writes back to the parameter file: the persistent range and the file's own."""
        keep = set(PERSISTENT) | {i for i in self.file_numbers if 31 <= i <= 5000}
        return {i: self.num[i] for i in sorted(keep)}


def read_var_file(path: str | os.PathLike, source: str | None = None) -> dict[int, float]:
    """A LinuxCNC parameter file: lines of ``number value``; other lines are skipped, as LinuxCNC does."""
    path = FsPath(path)
    name = source or path.name
    try:
        text = read_bytes(path, limit=budget.cap("bytes"), what="parameter file", error=GcodeError).decode(
            "utf-8", errors="replace")
    except GcodeError as exc:
        raise GcodeError(exc.message, where=name) from None
    values: dict[int, float] = {}
    last = 0
    for k, raw in enumerate(text.lstrip("\ufeff").splitlines()):
        parts = raw.split()
        if len(parts) != 2:
            continue
        try:
            number, value = float(parts[0]), float(parts[1])
        except ValueError:
            continue
        where = f"{name}:{k + 1}"
        if number != int(number) or not 1 <= number <= NUM_PARAMS:
            raise GcodeError(f"parameter file: parameter number {parts[0]} is out of range (1 to {NUM_PARAMS})",
                             where=where)
        if not math.isfinite(value):
            raise GcodeError(f"parameter file: value {parts[1]} is not a finite number", where=where)
        if int(number) <= last:
            raise GcodeError("parameter file out of order: numbers must go up (as LinuxCNC requires)", where=where)
        last = int(number)
        values[int(number)] = value
    return values


def format_var_file(values: dict[int, float]) -> str:
    """Parameter-file text for ``values`` (LinuxCNC's layout: number, tab, value with 6 decimals)."""
    return "".join(f"{i}\t{values[i]:.6f}\n" for i in sorted(values))
