"""G-code in: the RS274/NGC subset flowmc reads, read the way LinuxCNC reads it.

``parse_gcode`` / ``read_gcode`` follow LinuxCNC's interpreter (``rs274``), and the
tests compare every move with it. The subset:

- motion G0, G1, G2, G3 (I/J/K centre or R radius, negative R for the long way round, full
  circles with I/J/K, helices, P = number of turns), G80 (no motion mode), G4 P dwell (seconds);
- modes G17/G18/G19 (plane), G20/G21 (inch/mm), G90/G91 (absolute/incremental), G90.1/G91.1
  (absolute/incremental arc centre); and, because they only name the one mode flowmc has, G94
  (units per minute), G40 (no cutter compensation), G49 (no tool length offset), G54 (first work
  system, no offsets) and G61/G61.1/G64 [P Q] (path control: accepted, does not change the path);
- F (mm/min or in/min, converted to the Path's mm/s), S (rpm), M3/M4/M5 (spindle: signed rpm on
  the segments that follow), M62/M63 P (digital output with the next move), M64/M65 P (digital
  output at once), M67 E Q (analog output with the next move), M68 E Q (analog output at once),
  M2/M30 (end: later lines are not read);
- N line numbers (ignored), comments ``( )`` and ``;``, ``%`` program delimiters, block delete
  ``/`` (the line runs unless ``block_delete=True``, as rs274's switch is off by default).

Anything else (other G/M codes, T, O-words, #parameters, [expressions], A/B/C/U/V/W axes) is a
GcodeError naming the word and the line; nothing is skipped silently. Errors are ``file:line``.

What a program becomes:

- The tool starts at X0 Y0 Z0, as in rs274. G0 gives rapid lines (``rapid=True``,
  ``tool_down=False``, ``feed=rapid_feed``); G1 lines and G2/G3 arcs have ``tool_down=True``.
- A G0/G1 word on a line without axis words is still a (zero-length) move, as in LinuxCNC.
- M62/M63/M67 changes ride on the next move's ``outputs``/``analog``. M64/M65/M68 happen when
  reached, i.e. after the moves before them have finished: they ride on the next G4 dwell if one
  comes before the next move, or else on a zero-second Dwell placed at that point. Changes left
  over at the end, and a spindle change after the last move, go on a final zero-second Dwell, so
  nothing is lost.
- F is turned into mm/s with the units in force when it is read (an F on a G20 line is read
  before the G20, as in LinuxCNC) and keeps its speed across later G20/G21.
- Arcs given by I/J/K must end on their circle: LinuxCNC refuses a radius difference over
  0.028 mm (0.0028 in) and 0.1 %, and accepts smaller ones by cutting a spiral; flowmc arcs are
  circles, so a difference over 0.0001 mm is an error that says so.
- Where we differ from rs274 on purpose: a program may simply end (rs274 wants M2/M30 or a closing
  %), and a P word wanted by two codes on one line (G64 and G2, say) is an error rather than given
  to one of them.

"""

from __future__ import annotations

import contextlib
import gc
import math
import os
import re
import warnings
from pathlib import Path as FsPath

import numpy as np

from flowmc.errors import GcodeError, printable
from flowmc.motion.gcode_write import format_mm
from flowmc.motion.path import _RADIUS_TOL, PLANES, Arc, Dwell, Line, Path, Segment

__all__ = ["RAPID_FEED", "parse_gcode", "read_gcode"]

#: Feed given to G0 moves (mm/s): G-code leaves the rapid rate to the machine (the default
#: machine's axes allow 200 mm/s).
RAPID_FEED = 200.0

# LinuxCNC's tolerances, in program units (measured with rs274 2.9): an I/J/K arc whose end radius
# differs from its start radius by more than _SPIRAL_ABS (and by more than 0.1 %), or by more than
# 100 * _SPIRAL_ABS, is refused; an R arc may fall short of half the chord by _R_REACH.
_SPIRAL_ABS = {1.0: 0.02 * math.sqrt(2.0), 25.4: 0.002 * math.sqrt(2.0)}
_SPIRAL_REL = 0.001
_R_REACH_MM = 0.00005 * 25.4

# ---------------------------------------------------------------------------------------------
# The words of the subset.

_G_MOTION, _G_PLANE, _G_DIST, _G_ARCDIST, _G_UNITS, _G_PATH, _G_DWELL = range(7)
_M_STOP, _M_SPINDLE, _M_IO = 8, 9, 10
_GROUP_NAMES = {_G_MOTION: "motion", _G_PLANE: "plane", _G_DIST: "distance mode", _G_ARCDIST: "arc centre mode",
                _G_UNITS: "units", _G_PATH: "path control", _G_DWELL: "dwell",
                _M_STOP: "program end", _M_SPINDLE: "spindle", _M_IO: "output"}
# G code * 10 -> (group, value). The no-op codes each get their own group id (>= 16) so two of
# the same on a line are still caught.
_G_CODES = {
    0: (_G_MOTION, 0), 10: (_G_MOTION, 1), 20: (_G_MOTION, 2), 30: (_G_MOTION, 3), 800: (_G_MOTION, -1),
    40: (_G_DWELL, 0),
    170: (_G_PLANE, 2), 180: (_G_PLANE, 1), 190: (_G_PLANE, 0),
    200: (_G_UNITS, 25.4), 210: (_G_UNITS, 1.0),
    900: (_G_DIST, 0), 910: (_G_DIST, 1),
    901: (_G_ARCDIST, 1), 911: (_G_ARCDIST, 0),
    610: (_G_PATH, 0), 611: (_G_PATH, 1), 640: (_G_PATH, 2),
    940: (16, 0), 400: (17, 0), 490: (18, 0), 540: (19, 0),
}
_M_CODES = {2: (_M_STOP, 2), 30: (_M_STOP, 30), 3: (_M_SPINDLE, 1), 4: (_M_SPINDLE, -1), 5: (_M_SPINDLE, 0),
            62: (_M_IO, 62), 63: (_M_IO, 63), 64: (_M_IO, 64), 65: (_M_IO, 65), 67: (_M_IO, 67), 68: (_M_IO, 68)}
_G_TABLE_SIZE = 1000
_G_GROUP = np.full(_G_TABLE_SIZE, -1, dtype=np.int64)
_G_VALUE = np.zeros(_G_TABLE_SIZE)
for _code, (_grp, _val) in _G_CODES.items():
    _G_GROUP[_code], _G_VALUE[_code] = _grp, _val
_M_GROUP = np.full(200, -1, dtype=np.int64)
_M_VALUE = np.zeros(200)
for _code, (_grp, _val) in _M_CODES.items():
    _M_GROUP[_code], _M_VALUE[_code] = _grp, _val

_G_HINTS = [
    ((50, 51, 52, 53), "splines and NURBS (G5, G5.x) are not supported: use the NURBS node"),
    ((70, 80), "lathe diameter/radius mode is not supported"),
    ((100,), "setting offsets and tool data is not supported"),
    ((150, 160), "polar coordinates are not supported"),
    ((280, 281, 300, 301), "going to a stored home position is not supported"),
    ((330, 331, 760), "spindle-synchronised motion and threading are not supported"),
    ((382, 383, 384, 385), "probing is not supported"),
    ((410, 411, 420, 421), "tool radius compensation: use the Tool-radius offset node"),
    ((430, 431, 432), "tool length offsets are not supported"),
    ((520, 920, 921, 922, 923), "coordinate offsets are not supported"),
    ((530,), "machine coordinates are not supported"),
    ((550, 560, 570, 580, 590, 591, 592, 593), "only the first work coordinate system (G54, no offsets) is supported"),
    ((700, 710, 711, 720, 721, 730, 740, 810, 820, 830, 840, 850, 860, 870, 880, 890),
     "canned cycles are not supported"),
    ((930, 950), "only units-per-minute feed (G94) is supported"),
    ((960, 970), "constant surface speed is not supported"),
    ((980, 990), "canned-cycle return modes are not supported"),
]
_M_HINTS = [
    ((0, 1, 60), "program pauses are not supported"),
    ((6, 61), "tool changes are not supported"),
    ((7, 8, 9), "coolant is not supported"),
    ((19,), "spindle orientation is not supported"),
    ((48, 49, 50, 51, 52, 53), "override switches are not supported"),
    ((66,), "waiting on inputs is not supported"),
    ((70, 71, 72, 73), "saving and restoring modal state is not supported"),
    ((98, 99), "subprograms are not supported"),
]
_LETTER_HINTS = {
    "A": "rotary axis A is not supported (flowmc paths have X, Y and Z)",
    "B": "rotary axis B is not supported (flowmc paths have X, Y and Z)",
    "C": "rotary axis C is not supported (flowmc paths have X, Y and Z)",
    "U": "axis U is not supported (flowmc paths have X, Y and Z)",
    "V": "axis V is not supported (flowmc paths have X, Y and Z)",
    "W": "axis W is not supported (flowmc paths have X, Y and Z)",
    "T": "tool selection (T) is not supported",
    "D": "D words (tool radius compensation) are not supported",
    "H": "H words (tool length offsets) are not supported",
    "L": "L words (G10 and canned-cycle repeats) are not supported",
    "O": "O-words (subroutines, loops, conditions) are not supported",
    "N": "an N word (line number) must come first on its line",
}
_CHAR_HINTS = {
    "#": "parameters (#) are not supported",
    "[": "expressions ([ ]) are not supported",
    "]": "expressions ([ ]) are not supported",
    "@": "polar coordinates (@ ^) are not supported",
    "^": "polar coordinates (@ ^) are not supported",
    "(": "comment is not closed: ')' is missing",
    ")": "')' without a '(' before it",
    "%": "'%' may only open and close the program, on a line of its own",
}

_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)"
_WORD = re.compile(rf"([A-Z])({_NUM})")
_COMMENT = re.compile(r"\([^()\n]*\)")
_SEMICOLON = re.compile(r";[^\n]*")
_BLOCK_DELETE_MARK = re.compile(r"(?m)^[ \t]*/")
_BLOCK_DELETE_LINE = re.compile(r"(?m)^[ \t]*/[^\n]*")
_LINE_NUMBER = re.compile(r"(?m)^N\d+(?:\.\d*)?")
_LINE_NUMBER_BYTES = re.compile(rb"\nN\d+(?:\.\d*)?")
_LINE_NUMBER_FIRST = re.compile(rb"N\d+(?:\.\d*)?")
_ALLOWED = b"ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789.+-\n"
_NUMBER_CHARS = b"0123456789.+-"
_LETTERS_TO_SPACE = bytes.maketrans(b"ABCDEFGHIJKLMNOPQRSTUVWXYZ\n", b" " * 27)


def _code_name(letter: str, value: float) -> str:
    if math.isfinite(value) and value == int(value):
        return f"{letter}{int(value)}"
    return f"{letter}{value:g}"


def _g_message(value: float) -> str:
    name = _code_name("G", value)
    code = round(value * 10) if math.isfinite(value) else -1
    if abs(value * 10 - code) < 1e-6:
        for codes, hint in _G_HINTS:
            if code in codes:
                return f"{name} is not supported ({hint})"
    return f"{name} is not in flowmc's G-code subset"


def _m_message(value: float) -> str:
    name = _code_name("M", value)
    if math.isfinite(value) and value == int(value):
        if 100 <= value <= 199:
            return f"{name} is not supported (user-defined M codes are not supported)"
        for codes, hint in _M_HINTS:
            if int(value) in codes:
                return f"{name} is not supported ({hint})"
    return f"{name} is not in flowmc's G-code subset"


# ---------------------------------------------------------------------------------------------
# Text -> words: letter codes, values and the (0-based) line of each word.

class _Program:
    """The program's words in order: letter (ASCII code), value, 0-based line; and its text."""

    def __init__(self, source: str, text: str, letters, values, lines, n_lines: int,
                 pending: tuple[int, str] | None = None):
        self.source = source
        self.text = text  # the program as given (newlines normalised), for quoting a line in errors
        self.letters = letters
        self.values = values
        self.lines = lines
        self.n_lines = n_lines
        self.pending = pending  # (line, message) of a token error after the words kept

    def where(self, line: int) -> str:
        return f"{self.source}:{line + 1}"

    def error(self, line: int, message: str) -> GcodeError:
        raw = self.text.split("\n")
        text = printable(raw[line].strip(), 60) if 0 <= line < len(raw) else ""
        return GcodeError(f"{message} (in: {text})" if text else message, where=self.where(line))


def _clean(text: str, block_delete: bool) -> str:
    """Strip what carries no words (comments, %, block-delete marks), upper-case the rest; every
    newline stays, so line numbers stay the file's. Spaces and N words go in ``_words_only``."""
    stripped = text.lstrip()
    if stripped.startswith("%"):
        first = len(text) - len(stripped)
        eol = text.find("\n", first)
        head = text[:first]
        if eol < 0:
            return head
        text = head + text[eol:]  # the opening % line becomes blank
        closing = re.search(r"(?m)^[ \t]*%", text[first + 1:])
        if closing is not None:
            text = text[:first + 1 + closing.start()]
    if "(" in text:
        text = _COMMENT.sub("", text)
    if ";" in text:
        text = _SEMICOLON.sub("", text)
    if "/" in text:
        text = (_BLOCK_DELETE_LINE if block_delete else _BLOCK_DELETE_MARK).sub("", text)
    return text.upper()


def _words_only(clean: str) -> str:
    """Spaces and tabs out (RS274/NGC ignores them, even inside numbers), leading N words out."""
    text = clean.replace(" ", "").replace("\t", "")
    return _LINE_NUMBER.sub("", text) if "N" in text else text


def _tokenise(clean: str, text: str, source: str) -> _Program:
    """Words of a cleaned program, all at once; the per-line reader explains anything odd."""
    try:
        data = clean.encode("ascii").translate(None, b" \t")
    except UnicodeEncodeError:
        return _tokenise_lines(clean, text, source)
    if b"N" in data:
        data = _LINE_NUMBER_BYTES.sub(b"\n", data)
        if data.startswith(b"N"):
            data = _LINE_NUMBER_FIRST.sub(b"", data, count=1)
    if data.translate(None, _ALLOWED):
        return _tokenise_lines(clean, text, source)
    letter_stream = data.translate(None, _NUMBER_CHARS)
    codes = np.frombuffer(letter_stream, dtype=np.uint8)
    newline = codes == 10
    n_lines = int(np.count_nonzero(newline)) + 1
    letters = codes[~newline]
    if letters.size == 0:
        if data.translate(None, b"\n"):
            return _tokenise_lines(clean, text, source)
        return _Program(source, text, letters, np.zeros(0), np.zeros(0, dtype=np.int64), n_lines)
    chars = np.frombuffer(data, dtype=np.uint8)
    after = chars[1:]
    # Every letter must be followed by a number (a sign, a digit or a point).
    if chars[-1] >= 65 or np.any((chars[:-1] >= 65) & ((after >= 65) | (after == 10))):
        return _tokenise_lines(clean, text, source)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            values = np.fromstring(data.translate(_LETTERS_TO_SPACE), sep=" ")
        except (ValueError, DeprecationWarning):
            return _tokenise_lines(clean, text, source)
    # Each letter has at least one number after it, so equal counts mean exactly one each.
    if values.size != letters.size:
        return _tokenise_lines(clean, text, source)
    lines = np.cumsum(newline)[~newline]
    return _Program(source, text, letters, values, lines, n_lines)


def _tokenise_lines(clean: str, text: str, source: str) -> _Program:
    """Line by line: the words up to the first line that does not read, and that line's error.

    Reading stops after an M2/M30 line, so what follows the program's end is never looked at.
    """
    letters: list[int] = []
    values: list[float] = []
    lines: list[int] = []
    clean_lines = _words_only(clean).split("\n")
    pending = None
    for i, line in enumerate(clean_lines):
        pos, words = 0, []
        while pos < len(line):
            m = _WORD.match(line, pos)
            if m is None:
                pending = (i, _token_error(line, pos))
                break
            words.append((m.group(1), float(m.group(2))))
            pos = m.end()
        if pending is not None:
            break
        for letter, value in words:
            letters.append(ord(letter))
            values.append(value)
            lines.append(i)
        if any(letter == "M" and value in (2.0, 30.0) for letter, value in words):
            break
    return _Program(source, text, np.array(letters, dtype=np.uint8), np.array(values, dtype=float),
                    np.array(lines, dtype=np.int64), len(clean_lines), pending)


def _token_error(line: str, pos: int) -> str:
    ch = line[pos]
    if line.startswith("O"):
        return _LETTER_HINTS["O"]
    if ch in _CHAR_HINTS:
        return _CHAR_HINTS[ch]
    if "A" <= ch <= "Z":
        after = line[pos + 1:pos + 2]
        if after in _CHAR_HINTS:
            return _CHAR_HINTS[after]
        return f"{ch} word has no number after it"
    if ch.isdigit() or ch in ".+-":
        start = pos
        while start > 0 and (line[start - 1].isdigit() or line[start - 1] in ".+-"):
            start -= 1
        end = pos
        while end < len(line) and (line[end].isdigit() or line[end] in ".+-"):
            end += 1
        if start > 0 and "A" <= line[start - 1] <= "Z":
            return f"malformed number after {line[start - 1]}: {line[start:end]!r}"
        return f"number {line[start:end]!r} has no letter before it"
    return f"unexpected character {ch!r}"


# ---------------------------------------------------------------------------------------------
# Words -> moves, vectorised over lines.

class _Errors:
    """The first problem by line (then by the order checks are made), raised at the end."""

    def __init__(self, prog: _Program):
        self.prog = prog
        self.best: tuple[int, int, str] | None = None
        self.order = 0
        if prog.pending is not None:
            self.best = (prog.pending[0], 1 << 30, prog.pending[1])

    def at(self, line: int, message, late: bool = False) -> None:
        """Report a problem on ``line``; ``message`` may be a callable of the line (made lazily).
        On one line, problems are told in the order reported, ``late`` ones after the others."""
        self.order += 1
        order = self.order + (1 << 20 if late else 0)
        if self.best is None or (line, order) < self.best[:2]:
            self.best = (int(line), order, message)

    def first(self, mask: np.ndarray, message, lines: np.ndarray | None = None) -> None:
        """Report the first line where ``mask`` holds (mask over lines, or over ``lines``)."""
        hit = np.flatnonzero(mask)
        if hit.size:
            line = int(hit[0] if lines is None else lines[hit[0]])
            self.at(line, message)

    def raise_first(self) -> None:
        if self.best is not None:
            line, _, message = self.best
            raise self.prog.error(line, message(line) if callable(message) else message)


def _ffill(n: int, lines: np.ndarray, values, initial) -> np.ndarray:
    """The value in force on each of n lines, given the lines that set it (in order)."""
    values = np.asarray(values)
    dtype = np.result_type(values.dtype if values.size else np.asarray(initial).dtype, np.asarray(initial).dtype)
    if lines.size == 0:
        return np.full(n, initial, dtype=dtype)
    last = np.full(n, -1, dtype=np.int64)
    last[lines] = np.arange(lines.size)
    np.maximum.accumulate(last, out=last)
    out = values.astype(dtype)[np.maximum(last, 0)]
    out[last < 0] = initial
    return out


def _is_whole(v: np.ndarray) -> np.ndarray:
    return np.isfinite(v) & (v == np.round(v))


class _Lines:
    """Per-line view of the words: value of each single letter (NaN when absent) and the codes."""

    SINGLE = "EFIJKPQRSXYZ"

    def __init__(self, prog: _Program, errors: _Errors):
        n = prog.n_lines
        letters, values, lines = prog.letters, prog.values, prog.lines
        order = np.argsort(letters, kind="stable")
        sorted_letters = letters[order]
        bounds = np.searchsorted(sorted_letters, np.arange(65, 92))
        self.by_letter = {}
        for k in range(26):
            lo, hi = bounds[k], bounds[k + 1]
            if hi > lo:
                idx = order[lo:hi]
                self.by_letter[chr(65 + k)] = (lines[idx], values[idx])
        for letter in sorted(self.by_letter):
            if letter not in self.SINGLE and letter not in "GM":
                errors.at(self.by_letter[letter][0][0], _LETTER_HINTS.get(letter, f"{letter} words are not supported"),
                          late=True)
        bad = ~np.isfinite(values)
        errors.first(bad, "number too large", lines)
        self.n = n
        self.val = {}
        for letter in self.SINGLE:
            arr = np.full(n, np.nan)
            if letter in self.by_letter:
                wl, wv = self.by_letter[letter]
                errors.first(wl[1:] == wl[:-1], f"two {letter} words on one line", wl[1:])
                arr[wl] = wv
            self.val[letter] = arr
        self.has = {letter: ~np.isnan(arr) for letter, arr in self.val.items()}

    def words(self, letter: str) -> tuple[np.ndarray, np.ndarray]:
        return self.by_letter.get(letter, (np.zeros(0, dtype=np.int64), np.zeros(0)))


def _codes(lines_of: _Lines, errors: _Errors) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """G and M words by group: (lines, values); unknown codes and group clashes reported."""
    groups: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    keys = []
    for letter, group_of, value_of, scale, size, message in (
        ("G", _G_GROUP, _G_VALUE, 10, _G_TABLE_SIZE, _g_message),
        ("M", _M_GROUP, _M_VALUE, 1, 200, _m_message),
    ):
        wl, wv = lines_of.words(letter)
        if wl.size == 0:
            continue
        scaled = wv * scale
        code = np.rint(np.where(np.isfinite(scaled), scaled, -1.0))
        known = (np.abs(scaled - code) < 1e-6) & (code >= 0) & (code < size)
        code = np.where(known, code, 0).astype(np.int64)
        grp = np.where(known, group_of[code], -1)
        unknown = np.flatnonzero(grp < 0)
        if unknown.size:
            k = unknown[0]
            errors.at(wl[k], message(float(wv[k])))
        val = value_of[code]
        for g in np.flatnonzero(np.bincount(grp[grp >= 0], minlength=1)).tolist():
            m = grp == g
            groups[g] = (wl[m], val[m])
        keys.append(wl * 64 + np.where(grp >= 0, grp, 63))
    if keys:
        k = np.sort(np.concatenate(keys))
        dup = np.flatnonzero((k[1:] == k[:-1]) & (k[1:] % 64 != 63))
        if dup.size:
            g = int(k[dup[0] + 1] % 64)
            name = _GROUP_NAMES.get(g, "modal")
            errors.at(int(k[dup[0] + 1] // 64), f"two {'M' if g in (_M_STOP, _M_SPINDLE, _M_IO) else 'G'} codes "
                                                f"from the same group ({name}) on one line")
    return groups


def _interpret(prog: _Program, rapid_feed: float) -> Path:
    errors = _Errors(prog)
    with np.errstate(all="ignore"), _gc_paused():
        segments = _build(prog, errors, rapid_feed)
        errors.raise_first()
        return Path(segments)


@contextlib.contextmanager
def _gc_paused():
    """Pause the cyclic garbage collector while segments are made: they hold no cycles, and the
    collector's passes over 100k new objects would otherwise cost more than making them."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def _build(prog: _Program, errors: _Errors, rapid_feed: float) -> list[Segment]:
    # Program end: M2/M30 ends reading after its line.
    wl, wv = (prog.lines[prog.letters == 77], prog.values[prog.letters == 77])
    ends = np.flatnonzero((wv == 2.0) | (wv == 30.0))
    if ends.size:
        last = int(wl[ends[0]])
        keep = prog.lines <= last
        prog.letters, prog.values, prog.lines = prog.letters[keep], prog.values[keep], prog.lines[keep]
        prog.n_lines = last + 1
        if prog.pending is not None and prog.pending[0] > last:
            errors.best = None
    n = prog.n_lines
    lines_of = _Lines(prog, errors)
    val, has = lines_of.val, lines_of.has
    groups = _codes(lines_of, errors)
    none_i = np.zeros(0, dtype=np.int64)

    def group(g):
        return groups.get(g, (none_i, np.zeros(0)))

    def on_line(g, mask_values=None):
        gl, gv = group(g)
        out = np.zeros(n, dtype=bool)
        if mask_values is None:
            out[gl] = True
        else:
            out[gl[np.isin(gv, mask_values)]] = True
        return out

    motion_lines, motion_values = group(_G_MOTION)
    mode = _ffill(n, motion_lines, motion_values.astype(np.int64), -1)
    explicit = on_line(_G_MOTION, [0, 1, 2, 3])
    scale = _ffill(n, *group(_G_UNITS), 1.0)
    incremental = _ffill(n, *group(_G_DIST), 0.0) > 0
    arc_absolute = _ffill(n, *group(_G_ARCDIST), 0.0) > 0
    plane = _ffill(n, group(_G_PLANE)[0], group(_G_PLANE)[1].astype(np.int64), 2)
    dwell = on_line(_G_DWELL)
    blend = on_line(_G_PATH, [2])
    io_lines, io_values = group(_M_IO)
    io = np.zeros(n, dtype=np.int64)
    io[io_lines] = io_values.astype(np.int64)

    # Plain value checks.
    errors.first(val["F"] < 0, "negative F word (feed)")
    errors.first(val["S"] < 0, "negative S word (spindle speed)")

    has_axis = has["X"] | has["Y"] | has["Z"]
    has_ijk = has["I"] | has["J"] | has["K"]
    arc_mode = (mode == 2) | (mode == 3)
    move = (mode >= 0) & (explicit | has_axis | (arc_mode & has_ijk))
    arc = move & arc_mode
    errors.first(has_axis & (mode < 0), "X/Y/Z words with no motion mode in force (G0, G1, G2 or G3)")
    for letter in "IJK":
        errors.first(has[letter] & ~arc, f"{letter} word with no G2 or G3 to use it")
    errors.first(has["R"] & ~arc, "R word with no G2 or G3 to use it")
    g_name = np.array(["G0", "G1", "G2", "G3"])

    def named(text):
        return lambda line: text.format(g=g_name[max(int(mode[line]), 0)])

    errors.first(arc & ~has["R"] & ~has_ijk, named("{g} needs a centre (I, J, K) or a radius (R)"))
    errors.first(arc & has["R"] & has_ijk, named("{g} has both a radius (R) and a centre (I, J, K)"))
    for normal, letter, name in ((2, "K", "XY (G17)"), (1, "J", "XZ (G18)"), (0, "I", "YZ (G19)")):
        errors.first(arc & (plane == normal) & has[letter], f"{letter} word given for an arc in the {name} plane")
    ijk_arc = arc & ~has["R"]
    for normal, (first_l, second_l) in ((2, "IJ"), (1, "KI"), (0, "JK")):
        sel = ijk_arc & arc_absolute & (plane == normal)
        for letter in (first_l, second_l):
            errors.first(sel & ~has[letter], f"{letter} word missing in an absolute-centre arc (G90.1)")
    # F is turned into mm/s with the units in force when it is read, which on its own line is before
    # that line's G20/G21 (LinuxCNC's order of execution); a later change of units keeps the speed.
    f_lines, f_values = lines_of.words("F")
    scale_before = np.concatenate([[1.0], scale[:-1]])
    feed_number = _ffill(n, f_lines, f_values, 0.0)
    feed = _ffill(n, f_lines, f_values * scale_before[f_lines] / 60.0, 0.0)
    errors.first(move & (mode >= 1) & ~(feed_number > 0),
                 named("{g} with no feed rate: program an F word first"))

    # P, E and Q: each must have exactly one user on its line.
    io_p = (io >= 62) & (io <= 65)
    io_analog = (io == 67) | (io == 68)
    users = dwell.astype(int) + arc + blend + io_p
    errors.first(dwell & arc, named("G4 and {g} on one line: both would use the P word"))
    errors.first(has["P"] & (users == 0), "P word with nothing to use it (G4, G2/G3, G64 or M62-M65 use P)")
    errors.first(has["P"] & (users > 1) & ~(dwell & arc), "P word claimed by two codes on this line")
    errors.first(dwell & ~has["P"], "G4 needs a P word (seconds)")
    errors.first(dwell & (val["P"] < 0), "G4 dwell time (P) must be >= 0 seconds")
    errors.first(arc & has["P"] & ~(_is_whole(val["P"]) & (val["P"] >= 1)),
                 named("P on {g} must be a whole number of turns, 1 or more"))
    errors.first(io_p & ~has["P"], lambda line: f"M{io[line]} needs a P word (output number)")
    errors.first(io_p & has["P"] & ~(_is_whole(val["P"]) & (val["P"] >= 0)),
                 lambda line: f"M{io[line]} output number (P) must be a whole number >= 0")
    errors.first(io_analog & ~has["E"], lambda line: f"M{io[line]} needs an E word (analog output number)")
    errors.first(io_analog & has["E"] & ~(_is_whole(val["E"]) & (val["E"] >= 0)),
                 lambda line: f"M{io[line]} analog output number (E) must be a whole number >= 0")
    errors.first(io_analog & ~has["Q"], lambda line: f"M{io[line]} needs a Q word (volts)")
    errors.first(has["E"] & ~io_analog, "E word with nothing to use it (M67/M68 use E)")
    errors.first(has["Q"] & ~io_analog & ~blend, "Q word with nothing to use it (M67/M68 and G64 use Q)")

    # Where each move ends (mm), in order of moves.
    mi = np.flatnonzero(move)
    m = mi.size
    msc = scale[mi]
    minc = incremental[mi]
    end = np.zeros((m, 3))
    for axis, letter in enumerate("XYZ"):
        h = has[letter][mi]
        v = val[letter][mi] * msc
        step = np.where(h & minc, v, 0.0)
        csum = np.cumsum(step)
        reset = h & ~minc
        last = np.where(reset, np.arange(m), -1)
        np.maximum.accumulate(last, out=last)
        base = np.where(last >= 0, v[np.maximum(last, 0)] - csum[np.maximum(last, 0)], 0.0)
        end[:, axis] = base + csum
    start = np.vstack([np.zeros((1, 3)), end[:-1]])

    # Arc centres.
    ai_local = np.flatnonzero(arc[mi])
    ai = mi[ai_local]
    a_start, a_end = start[ai_local], end[ai_local]
    a_normal = plane[ai]
    uv = np.array([PLANES[k][1] for k in range(3)])[a_normal]
    rows = np.arange(ai.size)
    iu, iv = uv[:, 0], uv[:, 1]
    su, sv = a_start[rows, iu], a_start[rows, iv]
    eu, ev = a_end[rows, iu], a_end[rows, iv]
    a_scale = scale[ai]
    words_ijk = np.column_stack([val["I"][ai], val["J"][ai], val["K"][ai]]) * a_scale[:, None]
    wu, wv_ = words_ijk[rows, iu], words_ijk[rows, iv]
    absolute = arc_absolute[ai]
    cu = np.where(absolute, wu, su + np.nan_to_num(wu))
    cv = np.where(absolute, wv_, sv + np.nan_to_num(wv_))
    r_form = has["R"][ai]
    if np.any(r_form):
        radius = val["R"][ai] * a_scale
        du, dv = eu - su, ev - sv
        chord = np.hypot(du, dv)
        half = chord / 2.0
        same = r_form & (eu == su) & (ev == sv)
        errors.first(same, "an R arc cannot end where it starts: give the centre (I, J, K) for a full circle", ai)
        short = r_form & ~same & ((half - np.abs(radius) > _R_REACH_MM) | (radius == 0))
        errors.first(short, lambda line: (f"arc radius R{format_mm(abs(val['R'][line]))} is too small to reach the end "
                                          f"point (half the chord is {_half_chord(line, ai, half, a_scale)})"), ai)
        ratio = np.clip(half / np.abs(radius), 0.0, 1.0)
        ratio[ratio > 1.0 - 1e-12] = 1.0  # LinuxCNC's allowance for a semicircle
        offset = np.abs(radius) * np.sqrt((1.0 - ratio) * (1.0 + ratio))
        right = (mode[ai] == 2) == (radius > 0)  # cw with R > 0, or ccw with R < 0: centre right of travel
        sign = np.where(right, -1.0, 1.0)
        with np.errstate(all="ignore"):
            nu, nv = -dv / chord, du / chord  # left normal of the chord
        cu = np.where(r_form, (su + eu) / 2.0 + sign * offset * nu, cu)
        cv = np.where(r_form, (sv + ev) / 2.0 + sign * offset * nv, cv)
    r0 = np.hypot(su - cu, sv - cv)
    r1 = np.hypot(eu - cu, ev - cv)
    ijk = ~r_form
    errors.first(ijk & ((r0 < 1e-9) | (r1 < 1e-9)), "zero-radius arc: the centre is on the start or end point", ai)
    diff = np.abs(r0 - r1)
    diff_units = diff / a_scale
    abs_tol = np.where(a_scale == 1.0, _SPIRAL_ABS[1.0], _SPIRAL_ABS[25.4])
    refused = (diff_units > 100.0 * abs_tol) | ((diff / np.maximum(r0, r1) > _SPIRAL_REL) & (diff_units > abs_tol))
    errors.first(ijk & refused, lambda line: _radius_message(line, ai, r0, r1, a_scale,
                                                               "radius to the end of the arc differs from radius to "
                                                               "its start"), ai)
    spiral = ijk & ~refused & (diff > np.maximum(_RADIUS_TOL, 1e-9 * r0))
    errors.first(spiral, lambda line: _radius_message(line, ai, r0, r1, a_scale,
                                                      "arc end is off the circle through its start (LinuxCNC would "
                                                      "cut a spiral; flowmc arcs must be circles to "
                                                      f"{_RADIUS_TOL} mm)"), ai)
    centre = a_start.copy()
    centre[rows, iu] = cu
    centre[rows, iv] = cv
    turns = np.where(has["P"][ai], val["P"][ai], 1.0) - 1.0

    if errors.best is not None:
        return []
    return _assemble(prog, n, mi, end, ai_local, centre, a_normal, turns, mode, feed, val, lines_of, groups, dwell,
                     io, rapid_feed)


def _half_chord(line: int, ai: np.ndarray, half: np.ndarray, scale: np.ndarray) -> str:
    k = int(np.flatnonzero(ai == line)[0])
    return format_mm(half[k] / scale[k], 6)


def _radius_message(line, ai, r0, r1, scale, text) -> str:
    k = int(np.flatnonzero(ai == line)[0])
    unit = "mm" if scale[k] == 1.0 else "in"
    return (f"{text}: start radius {r0[k] / scale[k]:.6f} {unit}, end radius {r1[k] / scale[k]:.6f} {unit}")


def _assemble(prog, n, mi, end, ai_local, centre, a_normal, turns, mode, feed, val, lines_of, groups, dwell, io,
              rapid_feed) -> list[Segment]:
    """Segment objects in program order: per line, an at-once output dwell, a G4 dwell, then the move."""
    source = prog.source
    m = mi.size
    # Spindle: S and the direction in force on each line.
    s_lines, s_values = lines_of.words("S")
    speed = _ffill(n, s_lines, s_values, 0.0)
    sp_lines, sp_values = groups.get(_M_SPINDLE, (np.zeros(0, dtype=np.int64), np.zeros(0)))
    direction = _ffill(n, sp_lines, sp_values, 0.0)
    spindle = speed * direction + 0.0  # + 0.0 turns -0.0 into 0.0

    m_mode = mode[mi]
    rapid = m_mode == 0
    before = np.full(n, -1, dtype=np.int64)  # index of the last move on or before each line
    before[mi] = np.arange(m)
    np.maximum.accumulate(before, out=before)

    # Output changes, as (digital dict, analog dict, first line) per carrier. Synchronised ones
    # (M62/M63/M67) ride on the next move, same line included. At-once ones (M64/M65/M68) ride on
    # the next G4 dwell if it comes first, else on a zero dwell just before the next move (named
    # after the line of its first change). Leftovers go on a zero dwell at the end.
    sync: dict[int, tuple[dict, dict, int]] = {}
    at_once: dict[tuple[str, int], tuple[dict, dict, int]] = {}
    leftover: tuple[dict, dict, int] | None = None
    dwell_lines = np.flatnonzero(dwell)
    for line in np.flatnonzero(io).tolist():
        code = int(io[line])
        k = int(np.searchsorted(mi, line))
        if code in (62, 63, 67):
            slot = sync.setdefault(k, ({}, {}, line)) if k < m else None
        else:
            d = int(np.searchsorted(dwell_lines, line))
            next_dwell = int(dwell_lines[d]) if d < dwell_lines.size else n
            next_move = int(mi[k]) if k < m else n
            if next_dwell < n and next_dwell <= next_move:
                slot = at_once.setdefault(("dwell", next_dwell), ({}, {}, line))
            elif k < m:
                slot = at_once.setdefault(("zero", next_move), ({}, {}, line))
            else:
                slot = None
        if slot is None:
            leftover = leftover or ({}, {}, line)
            slot = leftover
        if code in (62, 63, 64, 65):
            slot[0][int(val["P"][line])] = code in (62, 64)
        else:
            slot[1][int(val["E"][line])] = float(val["Q"][line])

    # A spindle change after the last move (M5 before M2) is kept too: the end dwell carries it.
    if m and spindle[n - 1] != spindle[mi[-1]]:
        leftover = (leftover or ({}, {}, n - 1))[:2] + (n - 1,)

    # Order: per line, 3*line (zero dwell), 3*line + 1 (G4 dwell), 3*line + 2 (move); end dwell last.
    zero_lines = sorted(line for kind, line in at_once if kind == "zero")
    has_end = leftover is not None
    keys = np.concatenate([3 * np.array(zero_lines, dtype=np.int64), 3 * dwell_lines + 1, 3 * mi + 2,
                           np.array([3 * n + 3] if has_end else [], dtype=np.int64)])
    order = np.argsort(keys, kind="stable")
    position = np.empty(order.size, dtype=np.int64)
    position[order] = np.arange(order.size)

    ends_frozen = np.ascontiguousarray(end)
    ends_frozen.setflags(write=False)
    origin = np.zeros(3)
    origin.setflags(write=False)
    end_rows = list(ends_frozen)
    start_rows = [origin] + end_rows[:-1]

    segments: list = [None] * order.size
    new = object.__new__

    def add_dwell(slot: int, k: int, line: int, seconds: float, changes: tuple[dict, dict, int]) -> None:
        """A dwell after move k (-1: before any), with the state in force on ``line``."""
        point = end_rows[k] if k >= 0 else origin
        f = float(feed[line])
        seg = new(Dwell)
        seg.__dict__.update(start=point, end=point, seconds=seconds, feed=f if f > 0 else rapid_feed, rapid=False,
                            tool_down=bool(not rapid[k]) if k >= 0 else True, spindle=float(spindle[line]),
                            outputs=tuple(changes[0].items()), analog=tuple(changes[1].items()),
                            source=f"{source}:{line + 1}")
        segments[position[slot]] = seg

    slot = 0
    for line in zero_lines:
        changes = at_once[("zero", line)]
        add_dwell(slot, int(before[line - 1]) if line > 0 else -1, changes[2], 0.0, changes)
        slot += 1
    for line in dwell_lines.tolist():
        add_dwell(slot, int(before[line - 1]) if line > 0 else -1, line, float(val["P"][line]),
                  at_once.get(("dwell", line), ({}, {}, line)))
        slot += 1
    if has_end:
        add_dwell(slot + m, m - 1, leftover[2], 0.0, leftover)
    idx = slot

    # Moves: the bulk. Lines and arcs are built without re-checking what was checked above.
    m_feed = np.where(rapid, rapid_feed, feed[mi]).tolist()
    m_spindle = spindle[mi].tolist()
    m_rapid = rapid.tolist()
    m_src = [f"{source}:{line}" for line in (mi + 1).tolist()]
    m_pos = position[idx:idx + m].tolist()
    arc_of = np.full(m, -1, dtype=np.int64)
    arc_of[ai_local] = np.arange(ai_local.size)
    centre = np.ascontiguousarray(centre)
    centre.setflags(write=False)
    centre_rows = list(centre)
    normal_list = a_normal.tolist()
    ccw_list = (m_mode[ai_local] == 3).tolist()
    turns_list = turns.astype(np.int64).tolist()
    arc_list = arc_of.tolist()
    for s, e, f, r, sp, src, pos, a in zip(start_rows, end_rows, m_feed, m_rapid, m_spindle, m_src, m_pos, arc_list):
        if a < 0:
            seg = new(Line)
            seg.__dict__.update(start=s, end=e, feed=f, rapid=r, tool_down=not r, spindle=sp, outputs=(),
                                analog=(), source=src)
        else:
            seg = new(Arc)
            seg.__dict__.update(start=s, end=e, center=centre_rows[a], normal_axis=normal_list[a], ccw=ccw_list[a],
                                turns=turns_list[a], feed=f, rapid=False, tool_down=True, spindle=sp, outputs=(),
                                analog=(), source=src)
        segments[pos] = seg
    for k, (outputs, analog, _) in sync.items():
        segments[m_pos[k]].__dict__.update(outputs=tuple(outputs.items()), analog=tuple(analog.items()))
    return segments


# ---------------------------------------------------------------------------------------------
# Public reading API.

def parse_gcode(text: str, source: str = "<text>", *, rapid_feed: float = RAPID_FEED,
                block_delete: bool = False) -> Path:
    """Read a G-code program (the subset in this module's docstring) into a Path.

    ``source`` names the program in errors and in each segment's ``source`` (``"name:line"``,
    1-based file lines). ``rapid_feed`` (mm/s) is the feed given to G0 moves. With
    ``block_delete`` lines starting with ``/`` are skipped (LinuxCNC's block-delete switch).
    """
    if not isinstance(text, str):
        raise GcodeError(f"G-code must be text, got {type(text).__name__}", where=source)
    if not (isinstance(rapid_feed, (int, float)) and rapid_feed > 0 and math.isfinite(rapid_feed)):
        raise GcodeError(f"rapid feed must be > 0 mm/s, got {rapid_feed!r}", where=source)
    text = text.replace("\r\n", "\n").replace("\r", "\n")
    prog = _tokenise(_clean(text, block_delete), text, source)
    return _interpret(prog, float(rapid_feed))


def read_gcode(path: str | os.PathLike, *, rapid_feed: float = RAPID_FEED, block_delete: bool = False,
               source: str | None = None) -> Path:
    """Read a G-code file into a Path; errors and segment sources name the file (``part.ngc:12``)."""
    path = FsPath(path)
    name = source or path.name
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise GcodeError(f"cannot read the G-code file: {exc.strerror or exc}", where=source or str(path)) from exc
    return parse_gcode(data.decode("utf-8", errors="replace"), name, rapid_feed=rapid_feed,
                       block_delete=block_delete)
