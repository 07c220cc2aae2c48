"""Comparing a flowmc Path with rs274's moves, one move at a time (the G-code tests share this)."""

import numpy as np
import pytest

from flowmc.devices.linuxcnc.rs274 import ARC, FEED, NURBS, TRAVERSE
from flowmc.motion.path import Arc, Dwell


def moves_of(path) -> list:
    return [s for s in path if not isinstance(s, Dwell) or (s.event is not None and s.event.kind == "index")]


def assert_same_moves(path, ref, tol: float, lines: bool = True) -> None:
    ours = moves_of(path)
    assert len(ours) == len(ref), f"{len(ours)} moves, rs274 made {len(ref)}"
    for k, seg in enumerate(ours):
        where = f"move {k} ({seg.source})"
        if isinstance(seg, Dwell):  # an indexing stop: rs274 moves a rotary axis only
            assert ref.kind[k] == TRAVERSE and np.allclose(ref.start[k], ref.end[k], atol=tol), where
            continue
        kind = ARC if isinstance(seg, Arc) else NURBS if seg.kind == "nurbs" else TRAVERSE if seg.rapid else FEED
        assert kind == ref.kind[k], f"{where}: kind {kind}, rs274 {ref.kind[k]}"
        if kind == NURBS:
            continue  # rs274 prints no geometry for splines; the moves after them check where they ended
        if not np.isnan(ref.start[k]).any():
            assert np.max(np.abs(seg.start - ref.start[k])) <= tol, f"{where}: start {seg.start} vs {ref.start[k]}"
        assert np.max(np.abs(seg.end - ref.end[k])) <= tol, f"{where}: end {seg.end} vs {ref.end[k]}"
        if lines and ref.line[k]:
            assert int(seg.source.rsplit(":", 1)[1]) == ref.line[k], f"{where}: rs274 says line {ref.line[k]}"
        if kind == ARC:
            assert seg.normal_axis == ref.normal_axis[k], f"{where}: plane"
            assert (seg.turns + 1) * (1 if seg.ccw else -1) == ref.turn[k], f"{where}: turn"
            assert np.max(np.abs(seg.center - ref.center[k])) <= tol, f"{where}: centre {seg.center} vs {ref.center[k]}"
        if kind != TRAVERSE and not np.isnan(ref.feed[k]):
            assert seg.feed == pytest.approx(ref.feed[k], rel=1e-6, abs=1e-9), f"{where}: feed"


#: rs274's calls for the stops a path event stands for, compared with their arguments.
STOP_CALLS = ("PROGRAM_STOP", "OPTIONAL_PROGRAM_STOP", "PALLET_SHUTTLE", "CHANGE_TOOL")


def stops_of(program) -> list:
    """The stops in order. M60 is PALLET_SHUTTLE then PROGRAM_STOP; M30 makes a PALLET_SHUTTLE too, at
    the program's end, which is not a stop (a path does not say whether it ended with M2 or M30)."""
    events = [e for e in program.events if e.name in STOP_CALLS or e.name == "PROGRAM_END"]
    return [(e.index, e.name, e.text.strip()) for k, e in enumerate(events) if e.name != "PROGRAM_END"
            and not (e.name == "PALLET_SHUTTLE" and (k + 1 == len(events) or events[k + 1].name != "PROGRAM_STOP"))]


def assert_same_canon(ours, ref, tol: float) -> None:
    """Two rs274 runs (``ours`` on flowmc's written G-code, ``ref`` on the original, both in machine
    coordinates) make the same moves, rotary positions and stops. An arc whose radius is within
    ``tol`` of zero matches a feed line to the same end: G-code has no zero-radius arc to write."""
    assert len(ours) == len(ref), f"{len(ours)} moves, the original made {len(ref)}"
    radius = np.linalg.norm(np.nan_to_num(ref.center - ref.start), axis=1)
    for k in range(len(ref)):
        where = f"move {k} (original line {ref.line[k]})"
        kind = ref.kind[k]
        if kind == ARC and ours.kind[k] == FEED and radius[k] <= tol:
            kind = FEED
        assert ours.kind[k] == kind, f"{where}: kind {ours.kind[k]}, the original {ref.kind[k]}"
        if kind != NURBS:
            assert np.max(np.abs(ours.end[k] - ref.end[k])) <= tol, f"{where}: end {ours.end[k]} vs {ref.end[k]}"
        if kind == ARC:
            assert ours.normal_axis[k] == ref.normal_axis[k] and ours.turn[k] == ref.turn[k], f"{where}: plane, turn"
            assert np.max(np.abs(ours.center[k] - ref.center[k])) <= tol, f"{where}: centre"
        if kind != TRAVERSE and not np.isnan(ref.feed[k]):
            assert ours.feed[k] == pytest.approx(ref.feed[k], rel=1e-6, abs=1e-6), f"{where}: feed"
    if ref.rotary is not None:
        assert np.allclose(ours.rotary, ref.rotary, atol=tol), "rotary axis positions differ"
    assert stops_of(ours) == stops_of(ref), "pauses and tool changes differ"
