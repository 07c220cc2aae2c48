"""Program text as the interpreter walks it: files, their lines, O-word lines, subroutine files.

A program may be spread over files: the main file, and subroutine files ``<name>.ngc`` that
``o<name> call`` finds in the configured folders (LinuxCNC's SUBROUTINE_PATH). Each file keeps
its raw lines (for quoting in errors and for line numbers) and where reading stops: after a
closing ``%`` line when the first non-blank line is ``%``.
"""

from __future__ import annotations

import os
import re
from pathlib import Path as FsPath

import flowmc.budget as budget
from flowmc.errors import GcodeError, printable
from flowmc.fileio import read_bytes
from flowmc.motion.gcode.lexer import Block, LexError, parse_line, split_comments

__all__ = ["Source", "load_text", "read_program_file", "quote"]

_PERCENT = re.compile(r"^[ \t]*%")
_OWORD_LINE = re.compile(r"^[ \t]*(?:/[ \t]*)?(?:[nN][ \t\d.]*)?[oO]")
_SUB_NAME = re.compile(r"[a-z0-9_\-]+")


def quote(text: str, limit: int = 60) -> str:
    """A line as shown in messages: stripped, shortened, control characters (terminal escapes) shown
    as ``\\xNN`` so a message can never drive a terminal."""
    return printable(text.strip(), limit)


class Source:
    """One file of a program: name (for messages), lines, the first and past-the-last line read."""

    __slots__ = ("name", "index", "lines", "first", "end", "_owords", "cache", "runs", "tokens", "scans")

    def __init__(self, name: str, index: int, text: str):
        self.name = name
        self.index = index
        text = text.lstrip("\ufeff").replace("\r\n", "\n").replace("\r", "\n")
        self.lines = text.split("\n")
        if self.lines and self.lines[-1] == "":
            self.lines.pop()
        self.first = 0
        self.end = len(self.lines)
        for k, raw in enumerate(self.lines):
            if raw.strip():
                if _PERCENT.match(raw):
                    if raw.strip() != "%":
                        raise self.error(k, "'%' may only open and close the program, on a line of its own")
                    self.first = k + 1
                    for j in range(k + 1, len(self.lines)):
                        if _PERCENT.match(self.lines[j]):
                            self.end = j
                            break
                break
        self._owords: dict | None = None
        self.cache: dict[int, Block | None] = {}
        self.runs = None  # for each line, where its run of plain lines ends (fastpath)
        self.tokens = None  # the last run fastpath read: (first, stop, its words)
        self.scans: dict = {}  # where O-word searches ended (interp._scan)

    def plain_run_ends(self) -> list[int]:
        """For each line, where the run of plain lines starting there ends (the line itself when it is
        not plain); see ``fastpath``."""
        if self.runs is None:
            import numpy as np

            from flowmc.motion.gcode.fastpath import plain_lines

            plain, clean = plain_lines(self.lines)
            plain[self.end:] = False
            breaks = np.append(np.flatnonzero(~plain), len(self.lines))
            index = np.arange(len(self.lines))
            ends = np.where(plain, breaks[np.searchsorted(breaks, index)], index)
            self.runs = (ends.tolist(), clean)
        return self.runs[0]

    def where(self, line: int) -> str:
        return f"{self.name}:{line + 1}"

    def error(self, line: int, message: str) -> GcodeError:
        text = quote(self.lines[line]) if 0 <= line < len(self.lines) else ""
        return GcodeError(f"{message} (in: {text})" if text else message, where=self.where(line))

    def parse(self, line: int) -> Block | None:
        """The Block of a line (None for a blank one). Errors name the line."""
        raw = self.lines[line]
        try:
            code, comment = split_comments(raw)
            if not code:
                if comment is None:
                    return None
                block = Block()
            else:
                if "%" in code:
                    raise LexError("'%' may only open and close the program, on a line of its own")
                block = parse_line(code)
            block.comment = comment
            return block
        except LexError as exc:
            raise self.error(line, str(exc)) from None
        except Exception as exc:  # EvalError while folding constants (e.g. [1/0])
            from flowmc.motion.gcode.expr import EvalError

            if isinstance(exc, EvalError):
                raise self.error(line, str(exc)) from None
            raise

    def oword_lines(self) -> list[int]:
        """Indices of the lines that hold an O-word (found once, by a cheap text match)."""
        if self._owords is None:
            self._owords = [k for k in range(self.first, self.end) if _OWORD_LINE.match(self.lines[k])]
        return self._owords


def read_program_file(path: str | os.PathLike, name: str) -> str:
    """The text of a G-code file; refuses what is not a regular file (a FIFO would block forever)."""
    try:
        data = read_bytes(path, limit=budget.cap("bytes"), what="G-code file", error=GcodeError)
    except GcodeError as exc:
        raise GcodeError(exc.message, where=name) from None
    return data.decode("utf-8-sig", errors="replace")  # a byte-order mark some editors write is dropped


def load_text(text: str, name: str, index: int) -> Source:
    return Source(name, index, text)


def subroutine_file(name: str, folders) -> FsPath | None:
    """``<name>.ngc`` in the first folder that has it (LinuxCNC: lower-case names, digits, '-', '_');
    a link that leads out of its folder does not count."""
    if not _SUB_NAME.fullmatch(name):
        return None
    for folder in folders:
        root = FsPath(folder).resolve()
        candidate = (root / f"{name}.ngc").resolve()
        try:
            if candidate.is_relative_to(root) and candidate.is_file():
                return candidate
        except OSError:
            continue
    return None
