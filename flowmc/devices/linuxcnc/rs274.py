"""LinuxCNC's own G-code interpreter (the standalone ``rs274``) as a reference.

``rs274 -g`` reads a program and prints the canonical machining calls it makes
(``STRAIGHT_FEED(...)``, ``ARC_FEED(...)``, ...). We parse that text into
columns of moves in mm and mm/s, so flowmc's own G-code importer can be
checked against the interpreter LinuxCNC itself runs.

rs274 prints an N word, not the line number, in front of each call; so before
running it we number every line ``N<line>`` (N words are labels only in
LinuxCNC and change nothing else). Positions are program (work) coordinates as
the interpreter hands them to the canon layer: rs274 starts at X0 Y0 Z0, and
offsets (G92, G10 L2), the XY rotation and tool length offsets show up as events, not applied;
``CanonProgram.in_machine_coordinates()`` applies them as LinuxCNC's canon layer does (the
machine starts at its origin). Only X, Y and Z are followed.
"""

from __future__ import annotations

import os
import re
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flowmc.errors import GcodeError

__all__ = [
    "MACHINE_UNITS_MM",
    "TRAVERSE",
    "FEED",
    "ARC",
    "NURBS",
    "KIND_NAMES",
    "CanonEvent",
    "CanonProgram",
    "number_lines",
    "parse_canon",
    "run_rs274",
    "run_rs274_file",
]

TRAVERSE, FEED, ARC, NURBS = 0, 1, 2, 3
KIND_NAMES = ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED", "ARC_FEED", "NURBS_FEED")
_KIND = {name: k for k, name in enumerate(KIND_NAMES)}

#: mm per machine unit in the standalone rs274: it reads tool tables and parameter files in inches,
#: converting with its "external length units" of 0.03937007874016 inch per mm (not exactly 1/25.4).
MACHINE_UNITS_MM = 1.0 / 0.03937007874016

CONFIG_DIR = Path(__file__).with_name("config")
TOOL_TABLE = CONFIG_DIR / "tool.tbl"

# LinuxCNC reads at most 255 characters of a line; we never push a line past it.
_MAX_LINE = 255
_CALL = re.compile(r"^ *\d+ N(\d*|\.{5}) *([A-Z_0-9]+)\((.*)\)$", re.M)
_LEADING_N = re.compile(r"^(\s*/?\s*)(?:[nN]\s*\d[\d\s]*(?:\.[\d\s]*)?)?")
_UNITS_MM = {"CANON_UNITS_MM": 1.0, "CANON_UNITS_INCHES": 25.4, "CANON_UNITS_CM": 10.0}
# ARC_FEED's (first, second) axes and the axis normal to them, per plane.
_PLANES = {"CANON_PLANE_XY": (0, 1, 2), "CANON_PLANE_XZ": (2, 0, 1), "CANON_PLANE_YZ": (1, 2, 0)}
# Calls folded into the move columns rather than reported as events.
_STATE_CALLS = {"SET_FEED_RATE", "USE_LENGTH_UNITS", "SELECT_PLANE", "SET_FEED_MODE"}
_NUMBER = re.compile(r"[-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?")


@dataclass(frozen=True)
class CanonEvent:
    """A canonical call that is not a move: DWELL(s), SET_SPINDLE_SPEED(spindle, rpm),
    START_SPINDLE_CLOCKWISE / _COUNTERCLOCKWISE, STOP_SPINDLE_TURNING, SET_MOTION_OUTPUT_BIT /
    CLEAR_MOTION_OUTPUT_BIT (M62/M63), SET_AUX_OUTPUT_BIT / CLEAR_AUX_OUTPUT_BIT (M64/M65),
    SET_MOTION_OUTPUT_VALUE (M67), SET_AUX_OUTPUT_VALUE (M68), SET_G92_OFFSET, PROGRAM_END, ...

    ``index`` is the number of moves before it; ``values`` the numbers in its arguments,
    as printed (seconds, rpm, volts; offsets in the program's units); ``text`` the raw arguments.
    """

    index: int
    line: int
    name: str
    values: tuple[float, ...]
    text: str
    scale: float = 1.0  # mm per program unit when the call was made


@dataclass(frozen=True, eq=False)
class CanonProgram:
    """The moves rs274 made, one row each, in program order; mm and mm/s.

    kind: TRAVERSE / FEED / ARC / NURBS (names in KIND_NAMES). start, end: (N, 3); rs274 prints no
    geometry for a NURBS (G5, G5.1, G5.2): its end, and the next move's start, are NaN. A rigid tap
    (G33.1, RIGID_TAP) is two feed moves, down and back to where it started. rotary: (N, 3) A, B, C
    at the end of each move (degrees), for moves that index a rotary axis without moving X, Y, Z.
    center: (N, 3) arc centre, its normal coordinate that of the start; NaN for lines.
    normal_axis: 0/1/2 for arcs in the YZ/XZ/XY plane (G19/G18/G17), -1 for lines.
    turn: signed for arcs, +n counter-clockwise about +normal_axis with n-1 extra full
    turns (G3 P n), -n clockwise; 0 for lines. feed: mm/s; NaN for traverses and in
    units-per-revolution mode (G95). line: 1-based source line, 0 where unknown.
    """

    source: str
    kind: np.ndarray
    start: np.ndarray
    end: np.ndarray
    center: np.ndarray
    normal_axis: np.ndarray
    turn: np.ndarray
    feed: np.ndarray
    line: np.ndarray
    events: tuple[CanonEvent, ...]
    rotary: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.kind.shape[0])

    @property
    def end_position(self) -> np.ndarray:
        """Where the program leaves the tool (X0 Y0 Z0 for a program without moves)."""
        return self.end[-1].copy() if len(self) else np.zeros(3)

    def in_machine_coordinates(self) -> "CanonProgram":
        """The same moves in machine coordinates: each point p becomes rotate(p + G92 offset, XY
        rotation) + G5x offset + tool length offset, with the offsets in force at that move, as
        LinuxCNC's canon layer moves the machine. The first move starts at the machine origin."""
        g5x, g92, tlo = np.zeros(3), np.zeros(3), np.zeros(3)
        rot = 0.0
        events = sorted(self.events, key=lambda e: e.index)
        end = self.end.copy()
        center = self.center.copy()
        k = 0
        for m in range(len(self)):
            while k < len(events) and events[k].index <= m:
                e = events[k]
                v = np.array(e.values, dtype=float)
                if e.name == "SET_G5X_OFFSET":
                    g5x = v[1:4] * e.scale
                elif e.name == "SET_G92_OFFSET":
                    g92 = v[0:3] * e.scale
                elif e.name == "SET_XY_ROTATION":
                    rot = float(v[0])
                elif e.name == "USE_TOOL_LENGTH_OFFSET":
                    tlo = v[0:3] * e.scale
                k += 1
            c, s = np.cos(np.radians(rot)), np.sin(np.radians(rot))
            for arr in (end, center):
                p = arr[m] + g92
                arr[m] = (c * p[0] - s * p[1], s * p[0] + c * p[1], p[2]) + g5x + tlo
        start = np.vstack([np.zeros((1, 3)), end[:-1]])
        arcs = np.flatnonzero(self.kind == ARC)
        center[arcs, self.normal_axis[arcs]] = start[arcs, self.normal_axis[arcs]]
        return CanonProgram(self.source, self.kind, start, end, center, self.normal_axis, self.turn, self.feed,
                            self.line, self.events, self.rotary)


def number_lines(text: str) -> str:
    """Put ``N<line>`` at the start of every program line, replacing any N word there.

    Blank lines, ``%`` lines and lines that would grow past LinuxCNC's 255 characters
    are left as they are (their calls then carry line 0).
    """
    out = []
    for i, raw in enumerate(text.splitlines(), start=1):
        body = raw.strip()
        if not body or body.startswith("%"):
            out.append(raw)
            continue
        m = _LEADING_N.match(raw)
        lead, rest = m.group(1), raw[m.end():]
        numbered = f"{lead}N{i} {rest}"
        out.append(numbered if len(numbered) <= _MAX_LINE else raw)
    return "\n".join(out) + "\n"


def run_rs274(text: str, *, name: str = "program.ngc", tool_table: str | os.PathLike | None = None,
              parameters: str | os.PathLike | None = None, subroutine_dir: str | os.PathLike | None = None,
              timeout: float = 120.0) -> CanonProgram:
    """Run LinuxCNC's ``rs274`` on G-code ``text`` and parse what it does.

    ``name`` is used in error locations (``name:line``). The tool table defaults to
    flowmc's (tools 1-9, zero length and diameter), so G43 and G41 change nothing; rs274 reads
    tool tables and parameter files in inches. ``parameters`` is a parameter (.var) file to start
    from (a copy is used); ``subroutine_dir`` is where ``o<name> call`` finds ``name.ngc`` (rs274
    looks in its working directory). Raises GcodeError naming the line when the interpreter
    refuses the program.
    """
    table = Path(tool_table) if tool_table is not None else TOOL_TABLE
    with tempfile.TemporaryDirectory(prefix="flowmc-rs274-") as tmp:
        prog = Path(tmp) / "program.ngc"
        prog.write_text(number_lines(text))
        command = ["rs274", "-t", str(table)]
        if parameters is not None:
            var = Path(tmp) / "program.var"
            var.write_bytes(Path(parameters).read_bytes())
            command += ["-v", str(var)]
        # rs274 maps its tool table at $HOME/.tool.mmap, truncating it first: runs sharing a HOME crash each
        # other with SIGBUS, so each run gets its own.
        env = {**os.environ, "HOME": tmp}
        try:
            done = subprocess.run(
                command + ["-g", str(prog)],
                stdin=subprocess.DEVNULL, capture_output=True, text=True, env=env,
                timeout=timeout, cwd=str(subroutine_dir) if subroutine_dir is not None else tmp,
            )
        except FileNotFoundError as exc:
            raise GcodeError("LinuxCNC's rs274 is not installed (Debian package linuxcnc-uspace)",
                             where=name) from exc
        except subprocess.TimeoutExpired as exc:
            raise GcodeError(f"rs274 did not finish within {timeout:g} s", where=name) from exc
    if done.returncode != 0:
        raise _rs274_error(done.stderr, name)
    return parse_canon(done.stdout, name=name)


def run_rs274_file(path: str | os.PathLike, **kwargs) -> CanonProgram:
    """``run_rs274`` on a file; errors name the file."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise GcodeError(f"cannot read the program: {exc.strerror}", where=str(path)) from exc
    kwargs.setdefault("name", path.name)
    return run_rs274(text, **kwargs)


def _rs274_error(stderr: str, name: str) -> GcodeError:
    """rs274 prints the message, then the text of the line it stopped on."""
    lines = [ln for ln in stderr.splitlines() if ln.strip() and ln.strip() != "executing"]
    if not lines:
        return GcodeError("rs274 failed without a message", where=name)
    m = re.match(r"\s*/?\s*N(\d+)", lines[-1])
    if m is None:
        return GcodeError(" ".join(lines), where=name)
    message = " ".join(lines[:-1]) or "rs274 refused this line"
    shown = re.sub(r"^\s*(/?)\s*N\d+ ?", r"\1", lines[-1])
    return GcodeError(f"{message} (in: {shown.strip()})", where=f"{name}:{m.group(1)}")


def _floats(rows: list[str], width: int) -> np.ndarray:
    if not rows:
        return np.zeros((0, width))
    return np.array(",".join(rows).split(","), dtype=float).reshape(len(rows), width)


def _forward_fill(n: int, at: np.ndarray, values: np.ndarray, initial) -> np.ndarray:
    """Value in force at each of n calls, given the calls ``at`` that set ``values``."""
    if at.size == 0:
        return np.full(n, initial)
    last = np.full(n, -1)
    last[at] = np.arange(at.size)
    last = np.maximum.accumulate(last)
    return np.where(last >= 0, np.asarray(values)[np.maximum(last, 0)], initial)


def _expand_rigid_taps(calls: list) -> list:
    """RIGID_TAP(x, y, z) goes to the point and back where it started: two feed calls."""
    out = []
    here = "0, 0, 0"
    for nword, call, args in calls:
        if call == "RIGID_TAP":
            out.append((nword, "STRAIGHT_FEED", args + ", 0, 0, 0"))
            out.append((nword, "STRAIGHT_FEED", here + ", 0, 0, 0"))
            continue
        if call in ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED"):
            here = ", ".join(args.split(",")[:3])
        out.append((nword, call, args))
    return out


def parse_canon(output: str, *, name: str = "program.ngc") -> CanonProgram:
    """Parse rs274's canonical-call listing into moves and events."""
    calls = _CALL.findall(output)
    if "RIGID_TAP" in output:
        calls = _expand_rigid_taps(calls)
    n = len(calls)
    nwords = np.array([c[0] for c in calls], dtype=object)
    names = np.array([c[1] for c in calls], dtype=object)
    args = [c[2] for c in calls]
    line = np.array([int(w) if w.isdigit() else 0 for w in nwords], dtype=np.int64)

    for unsupported in ("SPLINE_FEED", "STRAIGHT_PROBE"):
        hit = np.flatnonzero(names == unsupported)
        if hit.size:
            raise GcodeError(f"the rs274 reference does not follow {unsupported} (probing is not printed "
                             "with its geometry)", where=f"{name}:{line[hit[0]]}")

    def setting(call: str, parse, initial):
        at = np.flatnonzero(names == call)
        return _forward_fill(n, at, [parse(args[i]) for i in at], initial)

    scale = setting("USE_LENGTH_UNITS", lambda a: _UNITS_MM[a.strip()], 1.0)
    # LinuxCNC converts F with the units in force when it is set (a later G20/G21 keeps the speed).
    at = np.flatnonzero(names == "SET_FEED_RATE")
    feed_mm_s = _forward_fill(n, at, np.array([float(args[i]) for i in at]) * scale[at] / 60.0, 0.0)
    per_rev = setting("SET_FEED_MODE", lambda a: int(a.split(",")[-1]) == 1, False)
    # Spindle-synchronised moves (G33, G33.1) run at pitch x spindle speed, not at F.
    sync_at = np.flatnonzero(np.isin(names, ["START_SPEED_FEED_SYNC", "STOP_SPEED_FEED_SYNCH"]))
    synced = _forward_fill(n, sync_at, [names[i] == "START_SPEED_FEED_SYNC" for i in sync_at], False)
    plane = setting("SELECT_PLANE", lambda a: list(_PLANES).index(a.strip()), 0)

    is_move = np.isin(names, KIND_NAMES)
    idx = np.flatnonzero(is_move)
    kind = np.array([_KIND[names[i]] for i in idx], dtype=np.int8)
    m = idx.size
    end = np.zeros((m, 3))
    center = np.full((m, 3), np.nan)
    normal_axis = np.full(m, -1, dtype=np.int8)
    turn = np.zeros(m, dtype=np.int64)

    rotary = np.zeros((m, 3))
    straight = np.flatnonzero((kind == TRAVERSE) | (kind == FEED))
    values = _floats([args[idx[k]] for k in straight], 6)
    end[straight] = values[:, :3]
    rotary[straight] = values[:, 3:6]
    for k in np.flatnonzero(kind == NURBS):
        end[k] = np.nan
        rotary[k] = rotary[k - 1] if k else 0.0
    arcs = np.flatnonzero(kind == ARC)
    if arcs.size:
        vals = _floats([args[idx[k]] for k in arcs], 9)
        axes = np.array(list(_PLANES.values()))[plane[idx[arcs]]]  # (A, 3): first, second, normal
        rows = np.arange(arcs.size)
        e = np.zeros((arcs.size, 3))
        c = np.zeros((arcs.size, 3))
        e[rows, axes[:, 0]] = vals[:, 0]
        e[rows, axes[:, 1]] = vals[:, 1]
        e[rows, axes[:, 2]] = vals[:, 5]
        c[rows, axes[:, 0]] = vals[:, 2]
        c[rows, axes[:, 1]] = vals[:, 3]
        end[arcs] = e
        rotary[arcs] = vals[:, 6:9]
        center[arcs] = c
        normal_axis[arcs] = axes[:, 2]
        turn[arcs] = vals[:, 4].astype(np.int64)
    s = scale[idx][:, None]
    end *= s
    center *= s
    start = np.vstack([np.zeros((1, 3)), end[:-1]])
    if arcs.size:
        center[arcs, normal_axis[arcs]] = start[arcs, normal_axis[arcs]]
    feed = feed_mm_s[idx]
    feed[(kind == TRAVERSE) | per_rev[idx].astype(bool) | synced[idx].astype(bool)] = np.nan

    before = np.cumsum(is_move) - is_move
    events = tuple(
        CanonEvent(int(before[i]), int(line[i]), names[i],
                   tuple(float(v) for v in _NUMBER.findall(args[i])), args[i], float(scale[i]))
        for i in np.flatnonzero(~is_move & ~np.isin(names, list(_STATE_CALLS)))
    )
    return CanonProgram(name, kind, start, end, center, normal_axis, turn, feed, line[idx], events, rotary)
