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
