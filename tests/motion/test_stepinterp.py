"""Point-by-point and DDA step interpolators: step for step equal to plain per-step loops, and the
geometric promises (one step per tick, end point exact, within one step of the curve)."""

import math
import random

import numpy as np
import pytest
from scipy.spatial import cKDTree

from flowmc.errors import PathError
from flowmc.motion import stepinterp as si

# ------------------------------------------------------------------ reference loops (slow, per step)

# Textbook direction tables: quadrant I..IV -> (step when F >= 0, step when F < 0).
CCW = {0: ((-1, 0), (0, 1)), 1: ((0, -1), (-1, 0)), 2: ((1, 0), (0, -1)), 3: ((0, 1), (1, 0))}
CW = {0: ((0, -1), (1, 0)), 1: ((1, 0), (0, 1)), 2: ((0, 1), (-1, 0)), 3: ((-1, 0), (0, -1))}


def ref_pbp_line(dx, dy):
    xe, ye = abs(dx), abs(dy)
    x = y = f = 0
    out = []
    for _ in range(xe + ye):
        if f >= 0 and xe > 0:
            out.append((1 if dx > 0 else -1, 0))
            x += 1
            f -= ye
        else:
            out.append((0, 1 if dy > 0 else -1))
            y += 1
            f += xe
    return np.array(out, dtype=np.int8).reshape(-1, 2)


def ref_dda_line(dx, dy, bits, preset):
    q = 1 << bits
    ax = ay = q // 2 if preset == "half" else 0
    out = []
    for _ in range(q):
        ax += abs(dx)
        ay += abs(dy)
        row = [0, 0]
        if ax >= q:
            ax -= q
            row[0] = 1 if dx > 0 else -1
        if ay >= q:
            ay -= q
            row[1] = 1 if dy > 0 else -1
        out.append(row)
    return np.array(out, dtype=np.int8)


def quadrant(x, y, ccw, entering=True):
    """Quadrant 0..3 of (x, y); a point on an axis goes to the quadrant entered (or left)."""
    if x > 0 and y > 0:
        return 0
    if x < 0 < y:
        return 1
    if x < 0 and y < 0:
        return 2
    if y < 0 < x:
        return 3
    forward = ccw if entering else not ccw
    if y == 0:
        return (0 if x > 0 else 2) if forward else (3 if x > 0 else 1)
    return (1 if y > 0 else 3) if forward else (0 if y > 0 else 2)


def axes_crossed(s, e, ccw, turns=0):
    """Axis half-lines strictly inside the sweep from s to e (a whole turn when e is on s's ray)."""
    def on_ray(p, d):
        return p[0] * d[1] - p[1] * d[0] == 0 and p[0] * d[0] + p[1] * d[1] > 0

    def sweep_to(p):
        if on_ray(s, p):
            return 2 * math.pi
        a = math.atan2(p[1], p[0]) - math.atan2(s[1], s[0])
        return ((a if ccw else -a) % (2 * math.pi)) or 2 * math.pi

    total = sweep_to(e)
    axes = [d for d in ((1, 0), (0, 1), (-1, 0), (0, -1)) if not on_ray(s, d) and not on_ray(e, d)]
    return sum(sweep_to(d) < total for d in axes) + 4 * turns


def ref_pbp_conic(a_coef, b_coef, k, s, e, ccw, turns=0):
    """F = A x^2 + B y^2 - K relative to the centre, per step, quadrant from the current point."""
    table = CCW if ccw else CW
    p = list(s)
    out = []

    def step(d):
        p[0] += d[0]
        p[1] += d[1]
        out.append(d)

    def f():
        return a_coef * p[0] ** 2 + b_coef * p[1] ** 2 - k

    q = quadrant(*p, ccw)
    for _ in range(axes_crossed(s, e, ccw, turns)):
        while quadrant(*p, ccw) == q:
            step(table[q][0] if f() >= 0 else table[q][1])
        q = quadrant(*p, ccw)
    # Last quadrant: an axis that reached its end coordinate stops, the other finishes.
    u_step, v_step = table[q]
    ui = 0 if u_step[0] else 1
    vi = 1 - ui
    ue = min(abs(e[ui]), abs(p[ui]))
    ve = max(abs(e[vi]), abs(p[vi]))
    while (abs(p[ui]), abs(p[vi])) != (ue, ve):
        if abs(p[ui]) == ue:
            step(v_step)
        elif abs(p[vi]) == ve:
            step(u_step)
        else:
            step(u_step if f() >= 0 else v_step)
    while tuple(p) != tuple(e):  # an end just behind the quadrant's start: straight back to it
        step((1 if e[0] > p[0] else -1, 0) if p[0] != e[0] else (0, 1 if e[1] > p[1] else -1))
    return np.array(out, dtype=np.int8).reshape(-1, 2)


def ref_dda_arc(s, e, ccw, bits, preset, turns=0):
    """Per tick: X integrand |y|, Y integrand |x|; quadrant blocks end on the axis at round(R)."""
    q_size = 1 << bits
    r_axis = round(math.sqrt(s[0] ** 2 + s[1] ** 2))
    table = CCW if ccw else CW
    p = list(s)
    q = quadrant(*p, ccw)
    n_blocks = axes_crossed(s, e, ccw, turns) + 1
    out = []
    for block in range(n_blocks):
        u_step, v_step = table[q]
        ui = 0 if u_step[0] else 1
        vi = 1 - ui
        last = block == n_blocks - 1
        tu, tv = (abs(e[ui]), abs(e[vi])) if last else (0, r_axis)
        tu, tv = min(tu, abs(p[ui])), max(tv, abs(p[vi]))
        acc_u = acc_v = q_size // 2 if preset == "half" else 0
        while (abs(p[ui]), abs(p[vi])) != (tu, tv):
            if abs(p[ui]) == tu == 0:  # v's integrand is 0 for good: one step per tick
                row = v_step
            else:
                ju, jv = abs(p[vi]), abs(p[ui])  # integrands at the tick's start
                row = [0, 0]
                if abs(p[ui]) != tu:
                    acc_u += ju
                    if acc_u >= q_size:
                        acc_u -= q_size
                        row = [row[0] + u_step[0], row[1] + u_step[1]]
                if abs(p[vi]) != tv:
                    acc_v += jv
                    if acc_v >= q_size:
                        acc_v -= q_size
                        row = [row[0] + v_step[0], row[1] + v_step[1]]
            p[0] += row[0]
            p[1] += row[1]
            out.append(tuple(row))
        if last:
            while tuple(p) != tuple(e):
                d = (1 if e[0] > p[0] else -1, 0) if p[0] != e[0] else (0, 1 if e[1] > p[1] else -1)
                p[0] += d[0]
                p[1] += d[1]
                out.append(d)
        q = (q + (1 if ccw else -1)) % 4
    return np.array(out, dtype=np.int8).reshape(-1, 2)


def ellipse_distance(pts, a, b):
    """Exact distance from points to the ellipse x^2/a^2 + y^2/b^2 = 1 (dense sampling, then Newton)."""
    pts = np.abs(np.asarray(pts, dtype=float))
    th = np.linspace(0.0, np.pi / 2, 20001)
    t = th[cKDTree(np.c_[a * np.cos(th), b * np.sin(th)]).query(pts)[1]]
    for _ in range(30):  # minimise |P(t) - p|^2 from the nearest sample
        c, s = np.cos(t), np.sin(t)
        dx, dy = a * c - pts[:, 0], b * s - pts[:, 1]
        g = -a * s * dx + b * c * dy
        h = (a * s) ** 2 + (b * c) ** 2 - a * c * dx - b * s * dy
        t = np.clip(t - g / np.where(h > 1e-9, h, 1e-9), 0.0, np.pi / 2)
    return np.hypot(a * np.cos(t) - pts[:, 0], b * np.sin(t) - pts[:, 1])


def random_arc(rng, r_lo, r_hi):
    """A start on a circle (a lattice point) and an end rounded from the same circle."""
    while True:
        r = rng.uniform(r_lo, r_hi)
        a = rng.uniform(-math.pi, math.pi)
        s = (round(r * math.cos(a)), round(r * math.sin(a)))
        if rng.random() < 0.15:
            s = rng.choice([(round(r), 0), (0, round(r)), (-round(r), 0), (0, -round(r))])
        k = s[0] ** 2 + s[1] ** 2
        if k >= 2:
            break
    rs = math.sqrt(k)
    choice = rng.random()
    if choice < 0.1:
        e = s  # full circle
    elif choice < 0.2:
        e = rng.choice([(round(rs), 0), (0, round(rs)), (-round(rs), 0), (0, -round(rs))])
    else:
        a = rng.uniform(-math.pi, math.pi)
        e = (round(rs * math.cos(a)), round(rs * math.sin(a)))
    return s, e, rng.random() < 0.5


# ------------------------------------------------------------------ point-by-point lines

def test_pbp_line_textbook_example():
    # (5, 3) by hand: F = 0 +X, -3 +Y, 2 +X, -1 +Y, 4 +X, 1 +X, -2 +Y, 3 +X
    got = si.pbp_line((5, 3))
    assert got.steps.tolist() == [[1, 0], [0, 1], [1, 0], [0, 1], [1, 0], [1, 0], [0, 1], [1, 0]]


ENDS = [(12, 7), (7, 12), (-12, 7), (-7, -12), (12, -7), (9, 0), (-9, 0), (0, 9), (0, -9), (1, 1),
        (-1, 1), (1000, -1), (1, -1000), (-333, -332), (17, 17)]


@pytest.mark.parametrize("end", ENDS)
def test_pbp_line_equals_reference_loop_in_every_quadrant(end):
    got = si.pbp_line(end)
    assert np.array_equal(got.steps, ref_pbp_line(*end))


def test_pbp_line_random_lines_equal_reference():
    rng = random.Random(4)
    for _ in range(300):
        start = (rng.randint(-50, 50), rng.randint(-50, 50))
        end = (start[0] + rng.randint(-400, 400), start[1] + rng.randint(-400, 400))
        if end == start:
            continue
        got = si.pbp_line(end, start)
        assert np.array_equal(got.steps, ref_pbp_line(end[0] - start[0], end[1] - start[1]))


@pytest.mark.parametrize("end", ENDS)
def test_pbp_line_one_step_per_tick_exact_end_within_a_step(end):
    start = (3, -4)
    target = (start[0] + end[0], start[1] + end[1])
    got = si.pbp_line(target, start)
    assert len(got) == abs(end[0]) + abs(end[1])
    assert np.all(np.abs(got.steps).sum(axis=1) == 1)
    pos = got.positions()
    assert tuple(pos[0]) == start and tuple(pos[-1]) == target
    rel = pos - start
    # distance to the programmed line: |x ye - y xe| / L
    dist = np.abs(rel[:, 0] * end[1] - rel[:, 1] * end[0]) / math.hypot(*end)
    assert dist.max() <= 1.0
    assert got.step_counts().tolist() == [abs(end[0]), abs(end[1])]


# ------------------------------------------------------------------ point-by-point circles

def test_pbp_circle_textbook_example_first_quadrant_ccw():
    # NR1 from (4, 0) to (0, 4), F = x^2 + y^2 - 16 by hand:
    # 0 -X, -7 +Y, -6 +Y, -3 +Y, 2 -X, -3 +Y, 4 -X, 1 -X
    got = si.pbp_arc((4, 0), (0, 4))
    assert got.steps.tolist() == [[-1, 0], [0, 1], [0, 1], [0, 1], [-1, 0], [0, 1], [-1, 0], [-1, 0]]


@pytest.mark.parametrize("ccw", [True, False])
@pytest.mark.parametrize("start", [(10, 0), (0, 10), (-10, 0), (0, -10), (6, 8), (-8, 6), (-6, -8), (8, -6)])
def test_pbp_full_circle_of_integer_radius(start, ccw):
    got = si.pbp_arc(start, start, ccw=ccw)
    pos = got.positions()
    assert tuple(pos[-1]) == start
    assert len(got) == 8 * 10  # each quadrant: 10 steps in and 10 out
    assert np.all(np.abs(got.steps).sum(axis=1) == 1)
    assert np.abs(np.hypot(pos[:, 0], pos[:, 1]) - 10).max() <= 1.0
    # it really goes round: every quadrant is visited in the turn direction
    angles = np.unwrap(np.arctan2(pos[:, 1], pos[:, 0]))
    assert abs(abs(angles[-1] - angles[0]) - 2 * math.pi) < 1e-9
    assert np.all(np.diff(angles) * (1 if ccw else -1) >= -1e-12)


def test_pbp_arcs_equal_reference_loop():
    rng = random.Random(11)
    for trial in range(600):
        s, e, ccw = random_arc(rng, 1.5, 120 if trial % 3 else 12)
        turns = 1 if trial % 17 == 0 else 0
        c = (rng.randint(-9, 9), rng.randint(-9, 9))
        got = si.pbp_arc((s[0] + c[0], s[1] + c[1]), (e[0] + c[0], e[1] + c[1]), c, ccw, turns)
        ref = ref_pbp_conic(1, 1, s[0] ** 2 + s[1] ** 2, s, e, ccw, turns)
        assert np.array_equal(got.steps, ref), (s, e, ccw, turns)


def test_pbp_arcs_stay_within_a_step_and_end_exactly():
    rng = random.Random(12)
    for _ in range(300):
        s, e, ccw = random_arc(rng, 2, 400)
        got = si.pbp_arc(s, e, ccw=ccw)
        pos = got.positions()
        assert tuple(pos[-1]) == e and tuple(pos[0]) == s
        assert np.all(np.abs(got.steps).sum(axis=1) == 1)
        dev = np.abs(np.hypot(pos[:, 0], pos[:, 1]) - math.hypot(*s))
        assert dev.max() <= 1.0, (s, e, ccw)


def test_pbp_arc_end_off_the_staircase_is_still_reached():
    # R^2 = 50; (-1, 8) is 0.99 steps outside, just past the top where the staircase turns at y = 7.
    got = si.pbp_arc((5, 5), (-1, 8))
    assert tuple(got.positions()[-1]) == (-1, 8)
    assert got.steps[-1].tolist() == [0, 1]  # the one reverse step: |y| was to fall in quadrant II
    assert np.array_equal(got.steps, ref_pbp_conic(1, 1, 50, (5, 5), (-1, 8), True))
    dda = si.dda_arc((5, 5), (-1, 8))
    assert tuple(dda.positions()[-1]) == (-1, 8)
    assert np.array_equal(dda.steps, ref_dda_arc((5, 5), (-1, 8), True, 4, "half"))  # integrands up to 7


def test_pbp_arc_extra_turns_add_whole_circles():
    one = si.pbp_arc((30, 0), (0, 30))
    two = si.pbp_arc((30, 0), (0, 30), turns=1)
    assert len(two) == len(one) + 8 * 30
    assert np.array_equal(two.steps[-len(one):], one.steps)


# ------------------------------------------------------------------ point-by-point ellipses

def test_pbp_ellipses_equal_reference_and_stay_within_a_step():
    rng = random.Random(21)
    for trial in range(250):
        a, b = rng.randint(2, 150), rng.randint(2, 150)
        t0, t1 = rng.uniform(-4, 4), rng.uniform(-4, 4)
        s = (round(a * math.cos(t0)), round(b * math.sin(t0)))
        e = s if trial % 10 == 0 else (round(a * math.cos(t1)), round(b * math.sin(t1)))
        ccw = rng.random() < 0.5
        got = si.pbp_ellipse(s, e, a, b, ccw=ccw)
        assert np.array_equal(got.steps, ref_pbp_conic(b * b, a * a, a * a * b * b, s, e, ccw)), (a, b, s, e)
        pos = got.positions()
        assert tuple(pos[-1]) == e
        assert ellipse_distance(pos, a, b).max() <= 1.0 + 1e-9, (a, b, s, e, ccw)


def test_pbp_full_ellipse_counts_and_centre_offset():
    a, b = 40, 15
    got = si.pbp_ellipse((140, 50), (140, 50), a, b, center=(100, 50), ccw=False)
    pos = got.positions() - (100, 50)
    assert len(got) == 4 * (a + b)
    assert ellipse_distance(pos, a, b).max() <= 1.0
    assert tuple(got.end) == (140, 50)


def test_pbp_large_ellipse_is_exact_where_products_pass_64_bits():
    # a^2 b^2 is about 2^70 here; deviation signs must still be exact.
    a, b = 200_000, 150_000
    t1 = 0.7
    e = (round(a * math.cos(t1)), round(b * math.sin(t1)))
    got = si.pbp_ellipse((a, 0), e, a, b)
    pos = got.positions()
    assert tuple(pos[-1]) == e
    x, y = pos[:, 0].astype(object), pos[:, 1].astype(object)
    f = b * b * x * x + a * a * y * y - a * a * b * b  # Python ints: exact
    # where it stepped X (towards the inside) F was >= 0, where it stepped Y F was < 0
    moved_x = got.steps[:, 0] != 0
    assert all(v >= 0 for v in f[:-1][moved_x]) and all(v < 0 for v in f[:-1][~moved_x])


def test_pbp_conic_with_integer_weights_is_a_circle_on_unequal_steps():
    # Circle of radius 3 mm on X steps of 0.01 mm and Y steps of 0.02 mm: 300 x 150 steps.
    got = si.pbp_conic((300, 0), (0, 150), (0, 0), (1, 4))
    pos = got.positions()
    mm = pos * (0.01, 0.02)
    assert tuple(pos[-1]) == (0, 150)
    assert ellipse_distance(pos, 300, 150).max() <= 1.0
    assert np.abs(np.hypot(mm[:, 0], mm[:, 1]) - 3.0).max() <= 0.02


# ------------------------------------------------------------------ DDA lines

def test_dda_line_textbook_example():
    # 3-bit registers, empty at the start, integrands 5 and 3.
    got = si.dda_line((5, 3), bits=3, preset="zero")
    assert got.steps.tolist() == [[0, 0], [1, 0], [0, 1], [1, 0], [1, 0], [0, 1], [1, 0], [1, 1]]


@pytest.mark.parametrize("preset", ["half", "zero"])
@pytest.mark.parametrize("bits", [None, 9, 12])
@pytest.mark.parametrize("end", [(300, 170), (-300, 170), (-170, -300), (170, -300), (0, 255), (-255, 0), (1, -1)])
def test_dda_lines_equal_reference_and_end_exactly(end, bits, preset):
    got = si.dda_line(end, bits=bits, preset=preset)
    n = bits or max(abs(end[0]), abs(end[1])).bit_length()
    assert len(got) == 2**n
    assert np.array_equal(got.steps, ref_dda_line(*end, n, preset))
    pos = got.positions()
    assert tuple(pos[-1]) == end
    dist = np.abs(pos[:, 0] * end[1] - pos[:, 1] * end[0]) / math.hypot(*end)
    assert dist.max() < 1.0
    if preset == "half":  # rounding instead of truncation: each axis within half a step
        k = np.arange(len(pos))
        assert np.abs(pos[:, 0] - k * end[0] / 2**n).max() <= 0.5
    assert got.step_counts().tolist() == [abs(end[0]), abs(end[1])]


# ------------------------------------------------------------------ DDA arcs

def test_dda_arc_textbook_quarter():
    # Quarter circle (5, 0) -> (0, 5) with 3-bit empty registers, worked through by hand:
    # tick: JX=|y| JY=|x|, accumulators after the add, steps
    #  1: 0,5 -> X 0, Y 5        -
    #  2: 0,5 -> X 0, Y 10->2    +Y   (y=1)
    #  3: 1,5 -> X 1, Y 7        -
    #  4: 1,5 -> X 2, Y 12->4    +Y   (y=2)
    #  5: 2,5 -> X 4, Y 9->1     +Y   (y=3)
    #  6: 3,5 -> X 7, Y 6        -
    #  7: 3,5 -> X 10->2, Y 11->3  -X +Y (x=4, y=4)
    #  8: 4,4 -> X 6, Y 7        -
    #  9: 4,4 -> X 10->2, Y 11->3  -X +Y (x=3, y=5: Y done)
    # 10: 5,3 -> X 7             -
    # 11: 5   -> X 12->4         -X (x=2)
    # 12: 5   -> X 9->1          -X (x=1)
    # 13: 5   -> X 6             -
    # 14: 5   -> X 11->3         -X (x=0: done)
    got = si.dda_arc((5, 0), (0, 5), bits=3, preset="zero")
    expect = [[0, 0], [0, 1], [0, 0], [0, 1], [0, 1], [0, 0], [-1, 1], [0, 0], [-1, 1], [0, 0],
              [-1, 0], [-1, 0], [0, 0], [-1, 0]]
    assert got.steps.tolist() == expect


def test_dda_arcs_equal_reference_loop():
    rng = random.Random(31)
    for trial in range(250):
        s, e, ccw = random_arc(rng, 1.5, 90 if trial % 3 else 10)
        preset = "zero" if trial % 2 else "half"
        needed = max(abs(v) for v in (*s, *e, round(math.hypot(*s))))
        bits = needed.bit_length() + rng.choice([0, 1, 2])
        turns = 1 if trial % 29 == 0 else 0
        got = si.dda_arc(s, e, ccw=ccw, bits=bits, preset=preset, turns=turns)
        assert np.array_equal(got.steps, ref_dda_arc(s, e, ccw, bits, preset, turns)), (s, e, ccw, bits, preset)
        assert tuple(got.positions()[-1]) == e


def test_dda_arc_default_register_is_one_bit_more_than_needed():
    got = si.dda_arc((100, 0), (0, 100))
    assert np.array_equal(got.steps, ref_dda_arc((100, 0), (0, 100), True, 8, "half"))


def test_dda_arcs_within_a_step_of_integer_radius_circles():
    """Half-preset accumulators with the default register (one spare bit)."""
    rng = random.Random(41)
    for _ in range(200):
        r = rng.randint(2, 400)
        s = rng.choice([(r, 0), (0, r), (-r, 0), (0, -r)])
        a = rng.uniform(-math.pi, math.pi)
        e = (round(r * math.cos(a)), round(r * math.sin(a)))
        ccw = rng.random() < 0.5
        pos = si.dda_arc(s, e, ccw=ccw).positions()
        assert tuple(pos[-1]) == e
        assert np.abs(np.hypot(pos[:, 0], pos[:, 1]) - r).max() <= 1.0, (s, e, ccw)


def test_dda_arcs_of_any_radius_stay_within_one_and_a_half_steps():
    """Quadrant blocks end on the axis at round(R): against a radius off the grid that adds up to
    half a step to the DDA's own error (measured worst 1.41 steps over 6000 random arcs)."""
    rng = random.Random(42)
    worst = 0.0
    for _ in range(300):
        s, e, ccw = random_arc(rng, 2, 400)
        pos = si.dda_arc(s, e, ccw=ccw).positions()
        assert tuple(pos[-1]) == e
        worst = max(worst, np.abs(np.hypot(pos[:, 0], pos[:, 1]) - math.hypot(*s)).max())
    assert worst <= 1.5


def test_dda_arc_zero_preset_sends_owed_steps_once_the_integrand_is_gone():
    # Empty 4-bit registers: X reaches the axis with Y at 12, one short of round(sqrt(160)) = 13;
    # Y's integrand |x| is now 0, so the owed step goes out on the next tick.
    got = si.dda_arc((4, 12), (0, 13), bits=4, preset="zero")
    pos = got.positions()
    assert tuple(pos[-2]) == (0, 12) and got.steps[-1].tolist() == [0, 1]
    assert np.array_equal(got.steps, ref_dda_arc((4, 12), (0, 13), True, 4, "zero"))


# ------------------------------------------------------------------ results and bad input

def test_positions_and_counts():
    got = si.pbp_line((12, 9), start=(10, 10))
    assert got.positions().tolist() == [[10, 10], [11, 10], [11, 9], [12, 9]]
    assert got.step_counts().tolist() == [2, 1]
    assert got.steps.dtype == np.int8 and not got.steps.flags.writeable


@pytest.mark.parametrize("call, message", [
    (lambda: si.pbp_line((3, 4), (3, 4)), "zero-length line"),
    (lambda: si.dda_line((0, 0)), "zero-length line"),
    (lambda: si.pbp_arc((10, 0), (0, 12)),
     "arc end is not on the circle: start radius 10.000 steps, end radius 12.000"),
    (lambda: si.dda_arc((10, 0), (0, 8)), "arc end is not on the circle"),
    (lambda: si.pbp_arc((0, 0), (1, 0)), "arc radius is zero"),
    (lambda: si.pbp_arc((1, 0), (0, 1)), "curve too small"),
    (lambda: si.dda_line((300, 20), bits=8), "DDA register too small for this line: 8 bits hold integrands below 256, "
                                             "but it needs 300 (at least 9 bits)"),
    (lambda: si.dda_arc((100, 0), (0, 100), bits=6), "DDA register too small for this arc"),
    (lambda: si.dda_line((3, 3), preset="full"), "preset must be one of"),
    (lambda: si.pbp_ellipse((50, 0), (0, 20), 40, 20), "ellipse start (50, 0) is 10.000 steps off the curve"),
    (lambda: si.pbp_ellipse((40, 0), (0, 20), 40, 0), "semi-axis b must be a whole number of steps >= 1"),
    (lambda: si.pbp_line((1.5, 2)), "must be whole steps"),
    (lambda: si.pbp_line((1, 2, 3)), "must be two integers"),
    (lambda: si.pbp_arc((5, 0), (0, 5), turns=-1), "extra turns must be a whole number"),
    (lambda: si.pbp_line((1 << 40, 0)), "beyond the supported range"),
    (lambda: si.dda_line((5, 5), bits=40), "needs at least 1099511627776 ticks"),
])
def test_bad_input_is_a_path_error(call, message):
    with pytest.raises(PathError) as info:
        call()
    assert message in str(info.value)
