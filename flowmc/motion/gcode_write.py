"""G-code out: a Path as the RS274/NGC text that ``flowmc.motion.gcode`` and LinuxCNC read back.

``path_to_gcode`` / ``write_gcode`` write a header ``G21 G90 G91.1 G17 G94`` (mm, absolute
coordinates, arc centres relative to the arc start as I/J/K - the default of LinuxCNC and of GRBL),
optional ``G64 P<blend_tolerance>``, one explicit G0/G1/G2/G3/G4 per segment, F in mm/min when it
changes, ``S.. M3/M4`` / ``M5`` when the spindle changes, M62/M63 and M67 for changes at a move's
start, M64/M65 and M68 for changes at a dwell, path events as the codes that make them (M0, M1,
M60 with their ``(MSG, ...)``, ``T.. M6``, a G0 of the rotary axes alone for an indexing stop), then
``M2``. A NURBS that is one cubic or quadratic Bezier span in an XY plane (what G5 and G5.1 read as)
is written as G5 or G5.1; other NURBS and ellipse segments as G1 chords within ``chord_tolerance``.
Reading back what was written gives the same Path (to 10**-decimals mm), except that an arc whose
radius prints as zero is a line; G-code cannot carry the feed of rapids and dwells, ``tool_down``
(it follows rapid) or ``source``.
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path as FsPath

import numpy as np

from flowmc.errors import GcodeError
from flowmc.fileio import write_atomic
from flowmc.motion.path import PLANES, Arc, Dwell, Line, NurbsCurve, Path, PathEvent, Segment, describe_segment

__all__ = ["path_to_gcode", "write_gcode", "format_mm"]


def format_mm(value: float, decimals: int = 6) -> str:
    """A number as G-code prints it: fixed point, no trailing zeros, never -0."""
    text = f"{value:.{decimals}f}"
    if "." in text:
        text = text.rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def path_to_gcode(path: Path, *, decimals: int = 6, blend_tolerance: float | None = None,
                  chord_tolerance: float = 0.001, program_end: bool = True, comment: str | None = None,
                  events: str = "codes") -> str:
    """A Path as G-code text that ``parse_gcode`` (and LinuxCNC) read back as the same moves.

    Coordinates are printed with ``decimals`` places (mm); arcs read back need their end within
    0.0001 mm of their circle, so keep ``decimals`` >= 5 for paths with arcs. ``blend_tolerance``
    (mm) adds ``G64 P<tol>`` (LinuxCNC's path blending); without it nothing about blending is said.
    Ellipses, and NURBS other than single XY Bezier spans (G5/G5.1), become G1 chords within
    ``chord_tolerance`` mm. A path that does not start at X0 Y0 Z0 (where a reader starts) begins
    with a G0 to its start, and a gap between two segments becomes a G0 as well. ``comment`` adds a
    first line ``(comment)``. ``events``: "codes" writes path events as the codes that make them (M0,
    M1, M60, T.. M6, a rotary G0); "dwells" as zero-second G4 dwells, for a machine that is to run
    the path straight through.
    """
    if not isinstance(path, Path):
        raise GcodeError(f"expected a Path, got {type(path).__name__}", where="G-code out")
    if not (isinstance(decimals, int) and 1 <= decimals <= 12):
        raise GcodeError(f"decimals must be a whole number from 1 to 12, got {decimals!r}", where="G-code out")
    if not chord_tolerance > 0:
        raise GcodeError(f"chord tolerance must be > 0 mm, got {chord_tolerance}", where="G-code out")
    if events not in ("codes", "dwells"):
        raise GcodeError(f"events must be 'codes' or 'dwells', got {events!r}", where="G-code out")
    out: list[str] = []
    if comment:
        out.append("(" + re.sub(r"[()\n\r]", " ", comment) + ")")
    out.append("G21 G90 G91.1 G17 G94")
    if blend_tolerance is not None:
        if not (blend_tolerance >= 0 and math.isfinite(blend_tolerance)):
            raise GcodeError(f"blend tolerance must be >= 0 mm, got {blend_tolerance}", where="G-code out")
        out.append(f"G64 P{format_mm(blend_tolerance, decimals)}")
    w = _Writer(out, decimals, events == "codes")
    for i, seg in enumerate(path.segments):
        w.segment(seg, i, chord_tolerance)
    if program_end:
        out.append("M2")
    return "\n".join(out) + "\n"


class _Writer:
    """Keeps what a reader of the text so far would have in force: position (as printed), plane,
    feed, spindle - so each line says only what changes."""

    def __init__(self, out: list[str], decimals: int, event_codes: bool = True):
        self.out = out
        self.d = decimals
        self.event_codes = event_codes
        self.pos = ["0", "0", "0"]
        self.plane = 2
        self.feed: str | None = None
        self.spindle = 0.0

    def num(self, value: float) -> str:
        return format_mm(float(value), self.d)

    def axes(self, point) -> tuple[str, list[str]]:
        new = [self.num(v) for v in point]
        words = [f"{'XYZ'[k]}{new[k]}" for k in range(3) if new[k] != self.pos[k]]
        return " ".join(words), new

    def state(self, seg: Segment, at_once: bool, where: str) -> None:
        spindle = float(seg.spindle)
        if spindle != self.spindle:
            if spindle == 0:
                self.out.append("M5")
            else:
                self.out.append(f"S{self.num(abs(spindle))} {'M3' if spindle > 0 else 'M4'}")
            self.spindle = spindle
        for channel, on in seg.outputs:
            code = (64 if on else 65) if at_once else (62 if on else 63)
            self.out.append(f"M{code} P{_channel(channel, where)}")
        for channel, volts in seg.analog:
            self.out.append(f"M{68 if at_once else 67} E{_channel(channel, where)} Q{self.num(volts)}")

    def gap_to(self, point) -> None:
        words, new = self.axes(point)
        if words:
            self.out.append(f"G0 {words}")
            self.pos = new

    def feed_word(self, seg: Segment) -> str:
        f = self.num(seg.feed * 60.0)
        if f == self.feed:
            return ""
        self.feed = f
        return f" F{f}"

    def segment(self, seg: Segment, index: int, chord_tol: float) -> None:
        where = describe_segment(index, seg.source)
        self.gap_to(seg.start)
        if isinstance(seg, Dwell):
            self.state(seg, True, where)
            if seg.seconds > 0 or seg.event is None or not self.event_codes:
                self.out.append(f"G4 P{self.num(seg.seconds)}")
            if seg.event is not None and self.event_codes:
                self.event(seg.event)
            return
        self.state(seg, False, where)
        if isinstance(seg, Line) or (isinstance(seg, Arc) and self.vanishing(seg)):
            words, new = self.axes(seg.end)
            code = "G0" if seg.rapid else "G1"
            feed = "" if seg.rapid else self.feed_word(seg)
            self.out.append(f"{code}{' ' + words if words else ''}{feed}")
            self.pos = new
        elif isinstance(seg, Arc):
            self.arc(seg)
        elif isinstance(seg, NurbsCurve) and self.spline(seg):
            pass
        else:
            points = seg.sample(chord_tol)[1:]
            for p in points:
                words, new = self.axes(p)
                feed = "" if seg.rapid else self.feed_word(seg)
                self.out.append(f"{'G0' if seg.rapid else 'G1'}{' ' + words if words else ''}{feed}")
                self.pos = new

    def vanishing(self, seg: Arc) -> bool:
        """An arc written as a line: one short of a full turn whose ends print the same in its plane
        (a reader would take it for a full circle), or one whose radius prints as zero (cutter
        compensation with a tool the size of the hole makes these; G-code has no zero-radius arc)."""
        iu, iv = PLANES[seg.normal_axis][1]
        same = self.num(seg.end[iu]) == self.pos[iu] and self.num(seg.end[iv]) == self.pos[iv]
        if same and abs(seg.sweep) < 2 * math.pi * (1 - 1e-9):
            return True
        return all(self.num(float(seg.center[k]) - float(self.pos[k])) == "0" for k in (iu, iv))

    def event(self, event: PathEvent) -> None:
        """A path event as the code that makes it: M0/M1/M60 (after its message as ``(MSG, ...)``),
        T.. M6, or a G0 of the rotary or UVW axes alone for an indexing stop."""
        if event.kind == "index":
            if event.axes:
                self.out.append("G0 " + " ".join(f"{a}{self.num(v)}" for a, v in event.axes))
            else:
                self.out.append("M0")
            return
        if event.kind == "tool_change":
            self.out.append(("" if event.tool is None else f"T{event.tool} ") + "M6")
            return
        if event.message:
            self.out.append("(MSG, " + re.sub(r"[()\n\r]", " ", event.message) + ")")
        self.out.append({"pause": "M0", "optional_pause": "M1", "pallet_change": "M60"}[event.kind])

    def spline(self, seg: NurbsCurve) -> bool:
        """A NURBS that is one polynomial Bezier span in an XY plane (what G5 and G5.1 make) as
        G5 (cubic) or G5.1 (quadratic); False for any other, which is written as chords."""
        ctrl, deg, knots = seg.control_points, seg.degree, seg.knots
        if seg.rapid or deg not in (2, 3) or len(ctrl) != deg + 1:
            return False
        clamped = np.ptp(knots[: deg + 1]) == 0 and np.ptp(knots[-deg - 1:]) == 0
        if not clamped or np.ptp(seg.weights) > 1e-12 * np.max(seg.weights):
            return False
        if np.ptp(ctrl[:, 2]) > 0 or self.num(ctrl[0, 2]) != self.pos[2]:
            return False
        words = [] if self.plane == 2 else ["G17"]
        self.plane = 2
        axis_words, new = self.axes(seg.end)
        words += ["G5" if deg == 3 else "G5.1"] + ([axis_words] if axis_words else [])
        words += [f"I{self.num(ctrl[1, 0] - float(self.pos[0]))}", f"J{self.num(ctrl[1, 1] - float(self.pos[1]))}"]
        if deg == 3:
            words += [f"P{self.num(ctrl[2, 0] - float(new[0]))}", f"Q{self.num(ctrl[2, 1] - float(new[1]))}"]
        self.out.append(" ".join(words) + self.feed_word(seg))
        self.pos = new
        return True

    def arc(self, seg: Arc) -> None:
        normal = seg.normal_axis
        words = []
        if normal != self.plane:
            words.append({2: "G17", 1: "G18", 0: "G19"}[normal])
            self.plane = normal
        words.append("G3" if seg.ccw else "G2")
        axis_words, new = self.axes(seg.end)
        if axis_words:
            words.append(axis_words)
        iu, iv = PLANES[normal][1]
        for k in (iu, iv):
            # Relative to the start as the reader has it, so the printed centre is the nearest one.
            offset = float(seg.center[k]) - float(self.pos[k])
            words.append(f"{'IJK'[k]}{self.num(offset)}")
        if seg.turns:
            words.append(f"P{seg.turns + 1}")
        feed = self.feed_word(seg)
        self.out.append(" ".join(words) + feed)
        self.pos = new


def _channel(channel, where: str) -> int:
    if isinstance(channel, (bool, np.bool_)) or int(channel) != channel or channel < 0:
        raise GcodeError(f"output channel must be a whole number >= 0, got {channel!r}", where=where)
    return int(channel)


def write_gcode(path: Path, file: str | os.PathLike, **options) -> str:
    """Write ``path_to_gcode(path, **options)`` to ``file`` atomically (a temp file, then a rename);
    return the text written."""
    text = path_to_gcode(path, **options)
    write_atomic(FsPath(file), text, what="G-code file", error=GcodeError)
    return text

