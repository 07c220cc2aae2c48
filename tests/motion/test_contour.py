"""Image contours: the report's 4-neighbour method against marching squares on a drawn test image.

The test image is a filled circle and a rectangle, drawn in millimetres at 0.1 mm per pixel, once
with hard edges (each pixel ink or paper by its centre) and once anti-aliased (ink by 8 x 8
sub-pixel coverage, as a scan or a rendered PNG has). Both methods trace it; the figures (point
count, closure, distance of the traced polylines to the true outline) are printed by
``pytest -s tests/motion/test_contour.py`` and the default method must be the closer one.
"""

import math

import numpy as np
import pytest
from PIL import Image

from flowmc.errors import PathError
from flowmc.motion import contour
from flowmc.motion.contour import (
    DEFAULT_METHOD,
    METHODS,
    Contour,
    contours_report_4neighbour,
    image_contours,
    image_to_path,
    load_gray,
    order_contours,
)

H, W, MPP = 200, 300, 0.1  # px, px, mm per pixel: a 30 x 20 mm picture
CIRCLE = (8.03, 10.02, 6.01)  # centre x, y and radius, mm
RECT = (16.03, 4.07, 27.04, 15.92)  # x0, y0, x1, y1, mm (edges off the pixel grid)


def draw(inside, supersample: int, h: int = H, w: int = W, mpp: float = MPP) -> np.ndarray:
    """Dark ink (0) on white paper (255): each pixel's ink share over supersample^2 sub-pixels."""
    i, j = np.mgrid[:h, :w]
    offsets = (np.arange(supersample) + 0.5) / supersample - 0.5
    cover = np.zeros((h, w))
    for di in offsets:
        for dj in offsets:
            cover += inside((j + 0.5 + dj) * mpp, (h - i - 0.5 - di) * mpp)
    return np.round(255.0 * (1.0 - cover / supersample**2)).astype(np.uint8)


def circle_and_rectangle(x, y):
    cx, cy, r = CIRCLE
    x0, y0, x1, y1 = RECT
    return ((x - cx) ** 2 + (y - cy) ** 2 <= r * r) | ((x >= x0) & (x <= x1) & (y >= y0) & (y <= y1))


def distance_to_outline(p: np.ndarray) -> np.ndarray:
    """Exact distance from points (N, 2) in mm to the nearer true outline (circle or rectangle)."""
    cx, cy, r = CIRCLE
    x0, y0, x1, y1 = RECT
    to_circle = np.abs(np.hypot(p[:, 0] - cx, p[:, 1] - cy) - r)
    dx = np.abs(p[:, 0] - (x0 + x1) / 2) - (x1 - x0) / 2
    dy = np.abs(p[:, 1] - (y0 + y1) / 2) - (y1 - y0) / 2
    outside = np.hypot(np.maximum(dx, 0), np.maximum(dy, 0))
    to_rect = np.where((dx <= 0) & (dy <= 0), np.minimum(-dx, -dy), outside)
    return np.minimum(to_circle, to_rect)


def densified(points: np.ndarray, step: float = 0.005) -> np.ndarray:
    """Points every ``step`` mm along a polyline, so chords are measured as well as vertices."""
    seg = np.diff(points, axis=0)
    n = np.maximum(1, np.ceil(np.linalg.norm(seg, axis=1) / step).astype(int))
    t = np.concatenate([np.arange(k) / k for k in n])
    return np.vstack([np.repeat(points[:-1], n, axis=0) + t[:, None] * np.repeat(seg, n, axis=0), points[-1:]])


def cut_bbox(path) -> tuple[np.ndarray, np.ndarray]:
    """Bounding box of the pen-down moves only (the first rapid starts at the origin)."""
    pts = np.array([p for s in path if not s.rapid for p in (s.start, s.end)])
    return pts.min(axis=0), pts.max(axis=0)


def measure(gray: np.ndarray, method: str, simplify_mm: float) -> dict:
    found = image_contours(gray, method, mm_per_pixel=MPP, simplify_mm=simplify_mm)
    dist = np.concatenate([distance_to_outline(densified(c.points)) for c in found])
    return {"contours": len(found), "closed": sum(c.closed for c in found),
            "points": sum(len(c.points) for c in found), "max": float(dist.max()), "mean": float(dist.mean())}


@pytest.fixture(scope="module")
def test_images(tmp_path_factory):
    folder = tmp_path_factory.mktemp("images")
    out = {}
    for name, ss in (("hard", 1), ("antialiased", 8)):
        file = folder / f"{name}.png"
        Image.fromarray(draw(circle_and_rectangle, ss)).save(file)
        out[name] = file
    return out


@pytest.fixture(scope="module")
def comparison(test_images):
    rows = {}
    for name, file in test_images.items():
        gray = load_gray(file)
        for method in METHODS:
            for tol in (0.0, 0.02):
                rows[name, method, tol] = measure(gray, method, tol)
    print("\nimage        method             simplify  contours closed points  max mm  mean mm")
    for (name, method, tol), m in rows.items():
        print(f"{name:12s} {method:18s} {tol:8.2f}  {m['contours']:8d} {m['closed']:6d} {m['points']:6d}"
              f"  {m['max']:.4f}  {m['mean']:.4f}")
    return rows


# ------------------------------------------------------------------ the comparison

@pytest.mark.parametrize("image", ["hard", "antialiased"])
@pytest.mark.parametrize("method", METHODS)
def test_both_methods_find_the_two_closed_outlines(comparison, image, method):
    for tol in (0.0, 0.02):
        m = comparison[image, method, tol]
        assert (m["contours"], m["closed"]) == (2, 2)
        assert m["max"] < 1.5 * MPP  # neither strays much more than a pixel from the true outline


@pytest.mark.parametrize("image", ["hard", "antialiased"])
def test_default_method_is_the_one_closer_to_the_true_outline(comparison, image):
    assert DEFAULT_METHOD == "marching_squares"
    other = next(m for m in METHODS if m != DEFAULT_METHOD)
    for tol in (0.0, 0.02):
        best, worse = comparison[image, DEFAULT_METHOD, tol], comparison[image, other, tol]
        assert best["mean"] < 0.5 * worse["mean"]
        assert best["max"] < worse["max"]


def test_report_method_sits_half_a_pixel_inside_the_ink(comparison):
    """Boundary pixel centres lie inside the ink edge by up to a pixel: the report's known loss."""
    m = comparison["antialiased", "report_4neighbour", 0.0]
    assert 0.3 * MPP < m["mean"] < 0.7 * MPP


def test_simplifying_drops_points_but_keeps_within_the_tolerance(comparison):
    for method in METHODS:
        raw, simple = comparison["antialiased", method, 0.0], comparison["antialiased", method, 0.02]
        assert simple["points"] < raw["points"] / 4
        assert simple["max"] <= raw["max"] + 0.02 + 1e-9


# ------------------------------------------------------------------ the report's tracing

def test_report_tracing_follows_an_open_stroke_from_end_to_end():
    """A one-pixel 'A' without its bar (an inverted V): the raster scan meets its apex first."""
    mask = np.zeros((40, 60), dtype=bool)
    for k in range(30):
        mask[5 + k, 30 - k] = mask[5 + k, 30 + k] = True
    found = contours_report_4neighbour(mask)
    assert len(found) == 1 and not found[0].closed
    ends = {tuple(found[0].points[0]), tuple(found[0].points[-1])}
    assert ends == {(34.0, 1.0), (34.0, 59.0)}
    assert len(found[0].points) == 59


def test_report_tracing_keeps_holes_as_separate_closed_outlines():
    yy, xx = np.mgrid[:80, :80]
    ring = ((yy - 40) ** 2 + (xx - 40) ** 2 <= 30**2) & ((yy - 40) ** 2 + (xx - 40) ** 2 > 15**2)
    found = contours_report_4neighbour(ring)
    assert len(found) == 2 and all(c.closed for c in found)
    radii = sorted(float(np.mean(np.hypot(*(c.points - 40).T))) for c in found)
    assert radii[0] == pytest.approx(15.5, abs=0.7) and radii[1] == pytest.approx(29.5, abs=0.7)
    # every chain step is to one of the eight neighbours
    for c in found:
        assert np.max(np.abs(np.diff(c.points, axis=0))) == 1


# ------------------------------------------------------------------ the Path

def test_path_lifts_the_pen_between_outlines_and_lowers_it_along_them(test_images):
    path = image_to_path(test_images["antialiased"], mm_per_pixel=MPP, feed=15.0, simplify_mm=0.0)
    assert path.gaps() == []
    rapids = [s for s in path if s.rapid]
    assert len(rapids) == 2 and all(not s.tool_down for s in rapids)
    cuts = [s for s in path if not s.rapid]
    assert all(s.tool_down and s.feed == 15.0 for s in cuts)
    np.testing.assert_allclose(path.start, (0, 0, 0))
    # the nearer shape (the circle, from the origin) is drawn first and each outline closes on itself
    first = [s for s in cuts if s.source.endswith("contour 1")]
    assert np.allclose(first[0].start, first[-1].end)
    assert np.all(distance_to_outline(np.array([s.end[:2] for s in first])) < MPP)
    assert np.hypot(first[0].start[0] - CIRCLE[0], first[0].start[1] - CIRCLE[1]) < CIRCLE[2] + MPP
    lo, hi = cut_bbox(path)
    np.testing.assert_allclose(lo[:2], [CIRCLE[0] - CIRCLE[2], CIRCLE[1] - CIRCLE[2]], atol=0.5 * MPP)
    np.testing.assert_allclose(hi[:2], [RECT[2], CIRCLE[1] + CIRCLE[2]], atol=0.5 * MPP)


def test_y_points_up_and_scale_and_origin_place_the_picture(tmp_path):
    gray = np.full((100, 200), 255, dtype=np.uint8)
    gray[10:30, 20:60] = 0  # a block near the top-left of the picture
    file = tmp_path / "block.png"
    Image.fromarray(gray).save(file)
    path = image_to_path(file, width_mm=50.0, origin=(100.0, -20.0), simplify_mm=0.01)
    lo, hi = cut_bbox(path)
    mpp = 50.0 / 200
    # rows 10..29 are 70..89 px above the bottom edge; columns 20..59; edges between pixel centres
    np.testing.assert_allclose([lo[0], hi[0]], [100.0 + 20 * mpp, 100.0 + 60 * mpp], atol=1e-9)
    np.testing.assert_allclose([lo[1], hi[1]], [-20.0 + 70 * mpp, -20.0 + 90 * mpp], atol=1e-9)
    # the four sides, less half a pixel's diagonal cut at each hard corner (marching squares)
    outline = sum(s.length for s in path if not s.rapid)
    assert outline == pytest.approx(2 * (40 + 20) * mpp - 4 * (1 - math.sqrt(0.5)) * mpp, abs=1e-9)


def test_fit_into_width_and_height_takes_the_tighter_scale(tmp_path):
    gray = np.full((100, 200), 255, dtype=np.uint8)
    gray[40:60, 90:110] = 0
    file = tmp_path / "dot.png"
    Image.fromarray(gray).save(file)
    lo, hi = cut_bbox(image_to_path(file, width_mm=100.0, height_mm=20.0))
    assert hi[0] - lo[0] == pytest.approx(20 * 0.2, abs=1e-6)  # 20 mm / 100 px beats 100 mm / 200 px
    with pytest.raises(PathError, match="not both"):
        image_to_path(file, mm_per_pixel=0.1, width_mm=10.0)


def test_contours_are_visited_nearest_first(tmp_path):
    gray = np.full((40, 200), 255, dtype=np.uint8)
    for col in (150, 30, 110, 70, 10):  # five dots in a row, in a scrambled raster-independent order
        gray[15:25, col:col + 10] = 0
    file = tmp_path / "dots.png"
    Image.fromarray(gray).save(file)
    path = image_to_path(file, mm_per_pixel=1.0, start=(0.0, 0.0))
    firsts = [s.end[0] for s in path if s.rapid]
    assert firsts == sorted(firsts) and len(firsts) == 5
    assert all(s.source.endswith(f"contour {k}") for k, s in enumerate((s for s in path if s.rapid), start=1))


def test_order_enters_each_next_outline_at_its_nearest_point():
    def stroke(x):
        return Contour(np.array([[x, 0.0], [x, 5.0]]), closed=False)

    ring = Contour(np.array([[30.0, 0.0], [32.0, 0.0], [32.0, 2.0], [30.0, 2.0], [30.0, 0.0]]), closed=True)
    ordered = order_contours([stroke(50.0), stroke(10.0), ring, stroke(20.0)], start=(0.0, 4.0))
    assert [c.points[0].tolist() for c in ordered] == [[10.0, 5.0], [20.0, 0.0], [30.0, 2.0], [50.0, 0.0]]
    assert ordered[0].points[-1].tolist() == [10.0, 0.0]  # the first stroke is drawn downwards
    assert ordered[2].closed and ordered[2].points[-1].tolist() == [30.0, 2.0]  # round the ring, back to its entry
    ordered = order_contours([ring], start=(33.0, 3.0))  # a closed outline starts at its nearest vertex
    assert ordered[0].points[0].tolist() == [32.0, 2.0] and ordered[0].points[-1].tolist() == [32.0, 2.0]
    assert len(ordered[0].points) == 5


def test_invert_traces_light_shapes_on_a_dark_ground(tmp_path):
    def disc(x, y):
        return (x - 5.0) ** 2 + (y - 5.0) ** 2 > 3.0**2  # ink everywhere but a disc: a white disc on black

    file = tmp_path / "white_disc.png"
    Image.fromarray(draw(disc, 4, 100, 100, 0.1)).save(file)
    light = image_contours(load_gray(file), invert=True, mm_per_pixel=0.1)
    assert len(light) == 1
    assert np.allclose(np.hypot(*(light[0].points - 5.0).T), 3.0, atol=0.02)
    dark = image_contours(load_gray(file), invert=False, mm_per_pixel=0.1)
    assert len(dark) == 2  # the ink's outer edge (the picture's border) and the hole


def test_fixed_threshold_picks_which_gray_counts_as_ink(tmp_path):
    gray = np.full((60, 120), 255, dtype=np.uint8)
    gray[20:40, 10:30] = 60  # dark gray
    gray[20:40, 80:100] = 180  # light gray
    file = tmp_path / "grays.png"
    Image.fromarray(gray).save(file)
    for method in METHODS:
        assert len(image_contours(load_gray(file), method, threshold=100)) == 1
        assert len(image_contours(load_gray(file), method, threshold=200)) == 2
    # the report's rule: a pixel brighter than the level is paper, any other is ink
    assert len(image_contours(load_gray(file), "report_4neighbour", threshold=60)) == 1
    assert len(image_contours(load_gray(file), "report_4neighbour", threshold=180)) == 2
    with pytest.raises(PathError, match="0..255"):
        image_contours(load_gray(file), threshold=300)


def test_colour_and_transparent_images_are_read_as_gray_on_white(tmp_path):
    rgba = np.zeros((50, 50, 4), dtype=np.uint8)  # fully transparent ...
    rgba[10:40, 10:40] = (200, 0, 0, 255)  # ... with an opaque red square
    file = tmp_path / "red.png"
    Image.fromarray(rgba, "RGBA").save(file)
    gray = load_gray(file)
    assert gray[0, 0] == 255 and gray[20, 20] < 100
    assert len(image_contours(gray)) == 1


# ------------------------------------------------------------------ bad input

def test_unreadable_image_names_the_file(tmp_path):
    bad = tmp_path / "notes.png"
    bad.write_text("this is not a picture")
    with pytest.raises(PathError) as err:
        image_to_path(bad)
    assert str(err.value).startswith(f"{bad}:") and "image" in str(err.value)
    missing = tmp_path / "gone.jpg"
    with pytest.raises(PathError, match=r"gone\.jpg: image file not found"):
        image_to_path(missing)
    truncated = tmp_path / "half.png"
    good = tmp_path / "good.png"
    Image.fromarray(draw(circle_and_rectangle, 1)).save(good)
    truncated.write_bytes(good.read_bytes()[:300])
    with pytest.raises(PathError, match=r"half\.png: "):
        image_to_path(truncated)


def test_blank_image_or_bad_method_names_the_file(tmp_path):
    blank = tmp_path / "blank.png"
    Image.fromarray(np.full((30, 30), 255, dtype=np.uint8)).save(blank)
    with pytest.raises(PathError, match=r"blank\.png: .*flat gray"):
        image_to_path(blank)
    speck = tmp_path / "speck.png"
    gray = np.full((30, 30), 255, dtype=np.uint8)
    gray[5:25, 5:25] = 250
    Image.fromarray(gray).save(speck)
    with pytest.raises(PathError, match=r"speck\.png: no outlines"):
        image_to_path(speck, threshold=100)
    with pytest.raises(PathError, match=r"speck\.png: unknown contour method 'sobel'"):
        image_to_path(speck, method="sobel")


def test_methods_list_matches_the_module():
    assert set(METHODS) == {"report_4neighbour", "marching_squares"} and contour.DEFAULT_METHOD in METHODS
    assert math.isclose(contour.image_scale((100, 200)), 0.1)
