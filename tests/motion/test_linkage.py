"""Two-axis linkage pulse table: pulses, directions and frequencies so both axes arrive together."""

import math

import numpy as np
import pytest

from flowmc.errors import PathError
from flowmc.motion.linkage import COLUMNS, linkage_table, path_linkage_table
from flowmc.motion.path import Arc, Dwell, EllipseArc, Line, Path
from flowmc.motion.table import Table


def durations(t: Table):
    """Each axis's time: pulses / frequency (None where it sends no pulses)."""
    out = []
    for axis in "xy":
        p, f = t[f"{axis}_pulses"], t[f"{axis}_freq_hz"]
        out.append(np.where(p > 0, p / np.where(f > 0, f, 1.0), np.nan))
    return out


def test_the_papers_line_12_7():
    # The teaching-machine paper's example: O(0, 0) -> A(12, 7); here 0.01 mm per pulse at 30 mm/s.
    t = linkage_table([[0, 0], [12, 7]], [0.01, 0.01], 30.0)
    assert t.names == COLUMNS
    row = t.to_rows()[0]
    length = math.hypot(12, 7)
    assert (row["x_pulses"], row["y_pulses"], row["x_dir"], row["y_dir"]) == (1200, 700, 1, 1)
    assert row["x_freq_hz"] == pytest.approx(30.0 * 12 / length / 0.01, rel=1e-12)
    assert row["y_freq_hz"] == pytest.approx(30.0 * 7 / length / 0.01, rel=1e-12)
    assert row["duration_s"] == pytest.approx(length / 30.0, rel=1e-12)
    assert row["x_freq_hz"] / row["y_freq_hz"] == pytest.approx(12 / 7, rel=1e-12)
    assert not row["rate_limited"]


def test_axes_arrive_together_in_every_direction():
    rng = np.random.default_rng(3)
    pts = np.cumsum(rng.uniform(-20, 20, size=(60, 2)), axis=0)
    pts[5] = pts[4] + [7.0, 0.0]  # along X only
    pts[9] = pts[8] + [0.0, -3.0]  # along Y only
    t = linkage_table(pts, [0.005, 0.0125], 25.0)
    tx, ty = durations(t)
    both = ~np.isnan(tx) & ~np.isnan(ty)
    assert np.allclose(tx[both], ty[both], rtol=1e-12)
    assert np.allclose(tx[both], t["duration_s"][both], rtol=1e-12)
    assert np.allclose(np.where(np.isnan(tx), ty, tx), t["duration_s"], rtol=1e-12)
    # directions follow the moves, all four quadrants appear
    moves = np.diff(pts, axis=0)
    assert np.array_equal(t["x_dir"], np.sign(np.rint(pts[1:, 0] / 0.005) - np.rint(pts[:-1, 0] / 0.005)))
    assert {(a, b) for a, b in zip(t["x_dir"], t["y_dir"])} >= {(1, 1), (1, -1), (-1, 1), (-1, -1)}
    assert t["y_pulses"][4] == 0 and t["x_pulses"][8] == 0
    # the path speed is the programmed feed, up to the rounding of the move to whole steps
    speed = np.hypot(t["x_pulses"] * 0.005, t["y_pulses"] * 0.0125) / t["duration_s"]
    lengths = np.linalg.norm(moves, axis=1)
    assert np.all(np.abs(speed - 25.0) <= 25.0 * math.hypot(0.005, 0.0125) / lengths)


def test_rounding_is_carried_so_the_end_is_exact_and_error_never_grows():
    # 1000 moves of 0.0173 mm on 0.01 mm steps: rounding each move alone would lose 0.0027 mm each.
    n = 1000
    pts = np.c_[np.arange(n + 1) * 0.0173, np.arange(n + 1) * -0.0061]
    t = linkage_table(pts, [0.01, 0.01], 10.0)
    x = np.concatenate([[0], np.cumsum(t["x_pulses"] * t["x_dir"])])
    y = np.concatenate([[0], np.cumsum(t["y_pulses"] * t["y_dir"])])
    assert x[-1] == round(n * 1.73) and y[-1] == round(-n * 0.61)  # the end point in steps
    assert np.abs(x * 0.01 - pts[:, 0]).max() <= 0.005 + 1e-12  # never more than half a step off
    assert np.abs(y * 0.01 - pts[:, 1]).max() <= 0.005 + 1e-12
    naive = np.rint(np.diff(pts[:, 0]) / 0.01).sum()
    assert abs(naive - x[-1]) > 100  # what carrying the residual prevents


def test_max_step_rate_slows_the_move_and_says_so():
    t = linkage_table([[0, 0], [40, 10], [41, 10]], [0.01, 0.01], [200.0, 5.0], max_step_rate=[8000.0, 12000.0])
    first, second = t.to_rows()
    # 200 mm/s would need 19403 Hz on X: slowed until X runs at exactly 8000 Hz
    assert first["rate_limited"] and first["x_freq_hz"] == pytest.approx(8000.0)
    assert first["feed_mm_s"] == pytest.approx(8000.0 * 0.01 * math.hypot(40, 10) / 40)
    assert first["y_freq_hz"] == pytest.approx(2000.0)
    assert first["duration_s"] == pytest.approx(4000 / 8000.0)
    assert not second["rate_limited"] and second["feed_mm_s"] == 5.0 and second["x_freq_hz"] == pytest.approx(500.0)
    # the Y limit binds where Y moves most
    t = linkage_table([[0, 0], [1, 50]], [0.01, 0.01], 200.0, max_step_rate=[8000.0, 12000.0])
    assert t["y_freq_hz"][0] == pytest.approx(12000.0) and t["x_freq_hz"][0] < 8000.0


def test_z_counts_towards_time_but_sends_no_pulses():
    t = linkage_table([[0, 0, 0], [3, 4, 12], [3, 4, 0]], [0.01, 0.01], 13.0)
    assert t["duration_s"].tolist() == pytest.approx([1.0, 12 / 13])
    assert t["x_pulses"].tolist() == [300, 0] and t["y_pulses"].tolist() == [400, 0]
    assert t["x_freq_hz"][0] == pytest.approx(300.0)


def test_path_table_cuts_arcs_into_chords_and_keeps_segment_numbers():
    path = Path([
        Line((0, 0, 0), (10, 0, 0), feed=20.0),
        Arc((10, 0, 0), (-10, 0, 0), (0, 0, 0), ccw=True, feed=15.0),
        Dwell((-10, 0, 0), 0.75),
        EllipseArc.from_axes((-4, 0, 0), 6.0, 3.0, 0.0, math.pi, -2 * math.pi, feed=10.0),
        Line((-10, 0, 0), (-10, 0, 0)),  # no motion: left out
        Line((-10, 0, 0), (0, -5, 0), feed=30.0),
    ])
    step = [0.01, 0.02]
    t = path_linkage_table(path, step, max_step_rate=[50_000.0, 50_000.0], chord_tol=0.001)
    seg = t["segment"]
    assert seg[0] == 1 and set(seg.tolist()) == {1, 2, 3, 4, 6}  # segment numbers count from 1
    assert np.all(np.diff(seg) >= 0)
    dwell = t.to_rows()[int(np.flatnonzero(seg == 3)[0])]
    assert dwell["duration_s"] == 0.75 and dwell["x_pulses"] == dwell["y_pulses"] == 0
    # the chords' pulses add up to the end point in steps
    x = np.sum(t["x_pulses"] * t["x_dir"])
    y = np.sum(t["y_pulses"] * t["y_dir"])
    assert (x, y) == (0, round(-5 / 0.02))
    # each chord of the arc stays within the chord tolerance: rebuild the points in mm
    xs = np.concatenate([[0], np.cumsum(t["x_pulses"] * t["x_dir"])]) * step[0]
    ys = np.concatenate([[0], np.cumsum(t["y_pulses"] * t["y_dir"])]) * step[1]
    arc_rows = np.flatnonzero(seg == 2)
    radius = np.hypot(xs[arc_rows + 1], ys[arc_rows + 1])
    assert np.abs(radius - 10).max() <= 0.01  # points on the circle to half a step
    assert len(arc_rows) >= math.ceil(10 * math.pi / (2 * math.sqrt(2 * 10 * 0.001)))
    # time per segment: its chords' length over its feed (chords are a little shorter than the arc)
    arc_time = t["duration_s"][arc_rows].sum()
    assert 10 * math.pi / 15.0 * (1 - 1e-4) <= arc_time < 10 * math.pi / 15.0
    tx, ty = durations(t)
    both = ~np.isnan(tx) & ~np.isnan(ty)
    assert np.allclose(tx[both], ty[both], rtol=1e-12)


def test_path_table_closes_a_gap_between_segments():
    path = Path([Line((0, 0, 0), (5, 0, 0)), Line((5, 2, 0), (5, 7, 0))])
    t = path_linkage_table(path, [0.01, 0.01])
    assert t["segment"].tolist() == [1, 2, 2]
    assert t["y_pulses"].tolist() == [0, 200, 500]


@pytest.mark.parametrize("call, message", [
    (lambda: linkage_table([[0, 0], [1, 1], [1, 1], [2, 0]], [0.01, 0.01], 10.0),
     "segment 2: zero-length move: points 2 and 3 are both [1.0, 1.0]"),
    (lambda: linkage_table([[0, 0], [1, 1]], [0.01, 0.01], 0.0), "feed must be > 0 mm/s, got 0.0 for move 1"),
    (lambda: linkage_table([[0, 0], [1, 1]], [0.01, -1], 5.0), "step_mm must be > 0 mm for X and Y"),
    (lambda: linkage_table([[0, 0], [1, 1]], [0.01, 0.01], 5.0, max_step_rate=0), "max_step_rate must be > 0 Hz"),
    (lambda: linkage_table([[0, 0]], [0.01, 0.01], 5.0), "at least two points"),
    (lambda: linkage_table([[0, 0], [1, 1], [2, 2]], [0.01, 0.01], [5.0]),
     "feed must be one number or one per move (2)"),
    (lambda: linkage_table([[0, 0], [np.nan, 1]], [0.01, 0.01], 5.0), "point 2 is not finite"),
])
def test_bad_input_is_a_path_error(call, message):
    with pytest.raises(PathError) as info:
        call()
    assert message in str(info.value)
