"""Image contours to a plotter Path: grayscale, threshold, trace outlines, simplify, order, scale.

The XY-plotter course report (seeds/004) turns a picture into pen strokes: average the colour to
gray, threshold it, keep the foreground pixels that have a background pixel among their four
neighbours (its "4-neighbour method"), and walk from pixel to neighbouring pixel with the pen down,
lifting it between outlines. ``method="report_4neighbour"`` does that; ``"marching_squares"`` uses
scikit-image's ``find_contours`` on the gray image instead, which puts the outline between pixel
centres where the gray level crosses the threshold (sub-pixel). tests/motion/test_contour.py
measures both against a drawn circle and rectangle; marching squares is the default because it lies
closer to the true outline.

Coordinates: pixel (row i, column j) has its centre at x = (j + 0.5) * mm_per_pixel, y = (H - i -
0.5) * mm_per_pixel from ``origin``, so the image covers [origin, origin + (W, H) * mm_per_pixel]
with Y up although image rows run down. Pillow and scikit-image are imported when used.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Any, Literal, Sequence

import numpy as np

import flowmc.budget as budget
from flowmc.errors import PathError
from flowmc.motion.path import MAX_COORD_MM, Line, Path

__all__ = [
    "METHODS",
    "DEFAULT_METHOD",
    "Contour",
    "load_gray",
    "threshold_level",
    "contours_report_4neighbour",
    "contours_marching_squares",
    "image_contours",
    "simplify",
    "simplify_all",
    "order_contours",
    "contours_to_path",
    "image_to_path",
]

Method = Literal["report_4neighbour", "marching_squares"]
METHODS: tuple[str, ...] = ("report_4neighbour", "marching_squares")
DEFAULT_METHOD: Method = "marching_squares"

#: Contours shorter than this (in pixels) are specks and are dropped (the report drops lone pixels).
MIN_LENGTH_PX = 3.0


@dataclass(frozen=True)
class Contour:
    """One outline as an ordered polyline; a closed one repeats its first point at the end."""

    points: np.ndarray  # (N, 2)
    closed: bool

    @property
    def length(self) -> float:
        return float(np.linalg.norm(np.diff(self.points, axis=0), axis=1).sum())


# --------------------------------------------------------------------------- loading and threshold

def load_gray(file: str | os.PathLike) -> np.ndarray:
    """The image as gray levels 0..255 (float, rows top-down); transparent pixels count as white paper."""
    from PIL import Image, UnidentifiedImageError

    name = os.fspath(file)
    try:
        with Image.open(name) as img:
            width, height = img.size
            budget.check("pixels", width * height, what=f"a {width} x {height} px picture", where=name,
                         change="scale the picture down (a plotter needs far fewer pixels)")
            img.load()
            if "A" in img.getbands() or "transparency" in img.info:
                rgba = img.convert("RGBA")
                paper = Image.new("RGBA", rgba.size, (255, 255, 255, 255))
                img = Image.alpha_composite(paper, rgba)
            gray = np.asarray(img.convert("L"), dtype=float)
    except FileNotFoundError:
        raise PathError("image file not found", where=name) from None
    except UnidentifiedImageError:
        raise PathError("not an image Pillow can read (PNG, JPEG, BMP, ...)", where=name) from None
    except (OSError, ValueError, Image.DecompressionBombError) as exc:
        raise PathError(f"cannot read the image: {exc}", where=name) from None
    if gray.ndim != 2 or min(gray.shape) < 2:
        raise PathError(f"the image is too small to trace ({gray.shape[1]} x {gray.shape[0]} px)", where=name)
    return gray


def threshold_level(gray: np.ndarray, threshold: float | None = None) -> float:
    """The gray level that splits ink from paper: the given one, or Otsu's when ``threshold`` is None.

    Otsu's split is returned as the midpoint of the two classes' mean levels (the 50 % coverage
    level of an anti-aliased edge): skimage's own value is the top of the dark class, which on a
    two-level image is the dark level itself and would put an iso-line on the ink pixels' centres.
    """
    if threshold is not None:
        if not 0.0 <= threshold <= 255.0:
            raise PathError(f"threshold must be a gray level 0..255, got {threshold}")
        return float(threshold)
    if float(gray.max()) == float(gray.min()):
        raise PathError(f"the image is one flat gray level ({gray.min():.0f}): nothing to trace")
    from skimage.filters import threshold_otsu

    dark = gray <= threshold_otsu(gray)
    return 0.5 * float(gray[dark].mean() + gray[~dark].mean())


def _foreground(gray: np.ndarray, level: float, invert: bool) -> np.ndarray:
    """Ink pixels: at or below the level (dark ink, the report's rule), above it when inverted."""
    return gray > level if invert else gray <= level


# --------------------------------------------------------------------------- the report's method

def _boundary_pixels(mask: np.ndarray) -> np.ndarray:
    """Foreground pixels with a background (or off-image) pixel up, down, left or right."""
    p = np.pad(mask, 1)
    interior = p[:-2, 1:-1] & p[2:, 1:-1] & p[1:-1, :-2] & p[1:-1, 2:]
    return mask & ~interior


def contours_report_4neighbour(mask: np.ndarray) -> list[Contour]:
    """Outlines of a binary image by the report's 4-neighbour method, in pixel (row, col) coordinates.

    Boundary pixels are classified in one vectorised step. Tracing then follows the report: take
    the first unvisited boundary pixel in raster order, step to an unvisited neighbour searching
    counter-clockwise from "right" (the four edge neighbours before the diagonals, which keeps the
    walk on the outline at staircase corners), mark it visited, and repeat; when the walk stops it is
    resumed from the seed in the other direction. A chain whose ends touch is closed.
    """
    boundary = _boundary_pixels(np.asarray(mask, dtype=bool))
    budget.check("segments", int(np.count_nonzero(boundary)), what="tracing the outline pixels of the picture",
                 change="trace a cleaner picture (fewer specks and edges), or a smaller one")
    h, w = boundary.shape
    width = w + 2
    padded = np.pad(boundary, 1)
    todo = bytearray(padded.ravel().astype(np.uint8).tobytes())
    # right, up, left, down, then up-right, up-left, down-left, down-right (rows run down)
    steps = (1, -width, -1, width, 1 - width, -1 - width, width - 1, width + 1)
    touching = frozenset(steps)

    def walk(p: int) -> list[int]:
        out = []
        while True:
            for step in steps:
                q = p + step
                if todo[q]:
                    break
            else:
                return out
            todo[q] = 0
            out.append(q)
            p = q

    contours = []
    for seed in np.flatnonzero(padded).tolist():
        if not todo[seed]:
            continue
        todo[seed] = 0
        chain = [seed] + walk(seed)
        if not (len(chain) > 2 and (chain[-1] - seed) in touching):
            chain = walk(seed)[::-1] + chain
        if len(chain) < MIN_LENGTH_PX:
            continue
        closed = len(chain) > 2 and (chain[-1] - chain[0]) in touching
        flat = np.asarray(chain + chain[:1] if closed else chain)
        rows, cols = np.divmod(flat, width)
        contours.append(Contour(np.column_stack([rows - 1, cols - 1]).astype(float), closed))
    return contours


# --------------------------------------------------------------------------- marching squares

def contours_marching_squares(gray: np.ndarray, level: float, invert: bool = False) -> list[Contour]:
    """Sub-pixel outlines where the gray level crosses ``level`` (scikit-image), pixel (row, col) coordinates.

    The image is padded with one pixel of paper so that shapes touching the edge still close.
    """
    from skimage.measure import find_contours

    paper = 0.0 if invert else 255.0
    padded = np.pad(np.asarray(gray, dtype=float), 1, constant_values=paper)
    out = []
    for pts in find_contours(padded, level, fully_connected="high" if invert else "low"):
        pts = pts - 1.0
        closed = len(pts) > 2 and bool(np.all(pts[0] == pts[-1]))
        contour = Contour(pts, closed)
        if contour.length >= MIN_LENGTH_PX:
            out.append(contour)
    return out


# --------------------------------------------------------------------------- polylines

SIMPLIFY_CHUNK = 256  # Douglas-Peucker recurses up to n deep on a zigzag: long outlines go in pieces


def simplify(points: np.ndarray, tol: float) -> np.ndarray:
    """Douglas-Peucker within ``tol``, keeping both end points (distances as scikit-image's
    ``approximate_polygon``: to the chord where a point projects onto it, else to its nearer end)."""
    return simplify_all([points], tol)[0]


def simplify_all(polylines: Sequence[np.ndarray], tol: float) -> list[np.ndarray]:
    """``simplify`` of each polyline, all in the same numpy passes."""
    polylines = [np.asarray(p, dtype=float) for p in polylines]
    if tol <= 0 or not polylines:
        return polylines
    sizes = np.array([len(p) for p in polylines])
    points = np.vstack(polylines)
    starts, ends = [], []
    for offset, size in zip(np.cumsum(sizes) - sizes, sizes):
        if size >= 3:
            cuts = offset + np.unique(np.r_[np.arange(0, size - 1, SIMPLIFY_CHUNK), size - 1])
            starts.append(cuts[:-1])
            ends.append(cuts[1:])
    keep = np.ones(len(points), dtype=bool)
    if starts:
        inner = _douglas_peucker(points, tol, np.concatenate(starts), np.concatenate(ends))
        spans = np.zeros(len(points) + 1, dtype=np.int64)  # points strictly inside some piece are decided there
        np.add.at(spans, np.concatenate(starts) + 1, 1)
        np.add.at(spans, np.concatenate(ends), -1)
        inside = np.cumsum(spans[:-1]) > 0
        keep[inside] = inner[inside]
    return np.split(points[keep], np.cumsum([int(k.sum()) for k in np.split(keep, np.cumsum(sizes)[:-1])])[:-1])


def _douglas_peucker(points: np.ndarray, tol: float, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Mask of the points kept inside the pieces ``starts[i]..ends[i]``. Every open piece is split in the
    same numpy pass, one level of the recursion at a time; an outline longer than ``SIMPLIFY_CHUNK``
    starts as pieces of that length sharing their end points (still within ``tol``), so the passes are
    at most that many and the time is linear in the number of points."""
    keep = np.zeros(len(points), dtype=bool)
    keep[starts] = keep[ends] = True
    while starts.size:
        inner = ends - starts - 1
        open_ = inner > 0
        starts, ends, inner = starts[open_], ends[open_], inner[open_]
        if not starts.size:
            break
        piece = np.repeat(np.arange(starts.size), inner)
        first = np.cumsum(inner) - inner
        idx = starts[piece] + 1 + (np.arange(piece.size) - first[piece])
        a, b, p = points[starts][piece], points[ends][piece], points[idx]
        ab, ap, bp = b - a, p - a, p - b
        along0 = np.einsum("ij,ij->i", ap, ab)
        along1 = -np.einsum("ij,ij->i", bp, ab)
        perp = (along0 > 0) & (along1 > 0)
        dist = np.minimum(np.sqrt(ap[:, 1] ** 2 + ap[:, 0] ** 2), np.sqrt(bp[:, 1] ** 2 + bp[:, 0] ** 2))
        angle = -np.arctan2(ab[perp, 0], ab[perp, 1])  # the chord's normal form, as scikit-image writes it
        cos, sin = np.cos(angle), np.sin(angle)
        dist[perp] = np.abs(p[perp, 0] * cos + p[perp, 1] * sin - (a[perp, 1] * sin + a[perp, 0] * cos))
        far = np.maximum.reduceat(dist, first)
        at_far = np.flatnonzero(dist == far[piece])
        pieces_hit, first_hit = np.unique(piece[at_far], return_index=True)
        split_at = np.empty(starts.size, dtype=np.int64)
        split_at[pieces_hit] = idx[at_far[first_hit]]
        split = far > tol
        mid = split_at[split]
        keep[mid] = True
        starts, ends = np.r_[starts[split], mid], np.r_[mid, ends[split]]
    return keep


def order_contours(contours: Sequence[Contour], start=(0.0, 0.0)) -> list[Contour]:
    """Nearest neighbour from ``start``: each next contour is the one with the closest entry point.

    A closed contour may be entered at any of its vertices (it is rotated to start there); an open
    one at either end (it is reversed when entered at its end).
    """
    if not contours:
        return []
    cand, owner, vertex = [], [], []
    for k, c in enumerate(contours):
        idx = np.arange(len(c.points) - 1) if c.closed else np.array([0, len(c.points) - 1])
        cand.append(c.points[idx])
        owner.append(np.full(len(idx), k))
        vertex.append(idx)
    pts, owner, vertex = np.vstack(cand), np.concatenate(owner), np.concatenate(vertex)
    free = np.ones(len(pts), dtype=bool)
    here = np.asarray(start, dtype=float)[:2]
    from scipy.spatial import cKDTree

    tree = cKDTree(pts)  # nearest free entry point in O(log n), not a scan of every point per contour
    out = []
    for _ in range(len(contours)):
        pick = _nearest_free(tree, free, here)
        k, v = int(owner[pick]), int(vertex[pick])
        c = contours[k]
        if c.closed:
            ring = c.points[:-1]
            ring = np.roll(ring, -v, axis=0)
            c = Contour(np.vstack([ring, ring[:1]]), True)
        elif v != 0:
            c = Contour(c.points[::-1], False)
        out.append(c)
        free[owner == k] = False
        here = c.points[-1]
    return out


def _nearest_free(tree: Any, free: np.ndarray, here: np.ndarray) -> int:
    """Index of the free point nearest ``here`` (the lowest index among equally near ones)."""
    n = len(free)
    k = 16
    while True:
        k = min(k, n)
        dist, idx = tree.query(here, k=k)
        dist, idx = np.atleast_1d(dist), np.atleast_1d(idx)
        found = idx < n  # the tree pads with index n where it has no neighbour (distances overflowing)
        dist, idx = dist[found], idx[found]
        ok = free[idx]
        if ok.any():
            best = dist[ok].min()
            if k == n or dist[-1] > best:  # every point as near as the best one is in hand
                return int(idx[ok & (dist <= best)].min())
        elif k == n:
            raise ValueError("no free point left")
        k *= 4


def _to_mm(contours: Sequence[Contour], shape: tuple[int, int], mm_per_pixel: float, origin) -> list[Contour]:
    """Pixel (row, col) to machine millimetres, Y up."""
    h = shape[0]
    ox, oy = float(origin[0]), float(origin[1])
    out = []
    for c in contours:
        x = ox + (c.points[:, 1] + 0.5) * mm_per_pixel
        y = oy + (h - 0.5 - c.points[:, 0]) * mm_per_pixel
        out.append(Contour(np.column_stack([x, y]), c.closed))
    return out


def image_scale(shape: tuple[int, int], mm_per_pixel: float | None = None, width_mm: float | None = None,
                height_mm: float | None = None) -> float:
    """mm per pixel: given, or the largest that fits the image into width_mm x height_mm; 0.1 by default."""
    h, w = shape
    if mm_per_pixel is not None and (width_mm is not None or height_mm is not None):
        raise PathError("give mm_per_pixel or a width/height to fit into, not both")
    for name, value in (("mm_per_pixel", mm_per_pixel), ("width_mm", width_mm), ("height_mm", height_mm)):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise PathError(f"{name} must be > 0, got {value}")
    if mm_per_pixel is not None:
        return float(mm_per_pixel)
    fits = [v / n for v, n in ((width_mm, w), (height_mm, h)) if v is not None]
    return min(fits) if fits else 0.1


def image_contours(gray: np.ndarray, method: Method = DEFAULT_METHOD, threshold: float | None = None,
                   invert: bool = False, mm_per_pixel: float = 0.1, origin=(0.0, 0.0),
                   simplify_mm: float = 0.0) -> list[Contour]:
    """Outlines of a gray image in machine millimetres (unordered), simplified within ``simplify_mm``."""
    level = threshold_level(gray, threshold)
    if method == "report_4neighbour":
        found = contours_report_4neighbour(_foreground(gray, level, invert))
    elif method == "marching_squares":
        found = contours_marching_squares(gray, level, invert)
    else:
        raise PathError(f"unknown contour method {method!r}; use one of {', '.join(METHODS)}")
    tol_px = simplify_mm / mm_per_pixel
    found = [Contour(p, c.closed) for p, c in zip(simplify_all([c.points for c in found], tol_px), found)]
    _check_moves(found, "picture")
    return _to_mm([c for c in found if len(c.points) >= 2], gray.shape, mm_per_pixel, origin)


def _check_moves(contours: Sequence[Contour], name: str) -> None:
    moves = sum(len(c.points) for c in contours) + len(contours)
    budget.check("segments", moves, what=f"tracing {len(contours):,} outlines as {moves:,} moves", where=name,
                 change="raise simplify_mm, or trace a smaller or cleaner picture")


def contours_to_path(contours: Sequence[Contour], feed: float, start=(0.0, 0.0), name: str = "image") -> Path:
    """Pen up (rapid, tool up) to each contour's start, pen down along it; Z is 0 throughout."""
    if not feed > 0:
        raise PathError(f"feed must be > 0 mm/s, got {feed}")
    _check_moves(contours, name)
    here = np.append(np.asarray(start, dtype=float)[:2], 0.0)
    segments = []
    for k, c in enumerate(contours, start=1):
        pts = np.column_stack([c.points, np.zeros(len(c.points))])
        keep = np.concatenate([[True], np.any(pts[1:] != pts[:-1], axis=1)])
        pts = pts[keep]
        if len(pts) < 2:
            continue
        source = f"{name} contour {k}"
        if np.any(pts[0] != here):
            segments.append(Line(here, pts[0], feed=feed, rapid=True, tool_down=False, source=source))
        segments.extend(Line.chain(pts, feed=feed, source=source))
        here = pts[-1]
    return Path(segments)


def image_to_path(file: str | os.PathLike, method: Method = DEFAULT_METHOD, threshold: float | None = None,
                  invert: bool = False, mm_per_pixel: float | None = None, width_mm: float | None = None,
                  height_mm: float | None = None, origin=(0.0, 0.0), feed: float = 20.0,
                  simplify_mm: float = 0.05, start=(0.0, 0.0)) -> Path:
    """A picture file to a pen-plotter Path: outlines in mm, ordered to shorten pen-up travel.

    ``invert`` traces light shapes on a dark ground (the default is dark ink on light paper);
    ``threshold`` None picks Otsu's level. Errors name the file.
    """
    name = os.fspath(file)
    gray = load_gray(name)
    try:
        scale = image_scale(gray.shape, mm_per_pixel, width_mm, height_mm)
        reach = scale * max(gray.shape) + max(abs(float(origin[0])), abs(float(origin[1])))
        if not reach <= MAX_COORD_MM:
            raise PathError(f"the picture would reach {reach:.3g} mm from the origin; coordinates must be within "
                            f"+-{MAX_COORD_MM:g} mm (a smaller scale or width)")
        if simplify_mm < 0:
            raise PathError(f"simplify tolerance must be >= 0 mm, got {simplify_mm}")
        found = image_contours(gray, method, threshold, invert, scale, origin, simplify_mm)
    except PathError as exc:
        raise PathError(exc.message, where=name) from None
    if not found:
        raise PathError("no outlines found: the image is all paper or all ink at this threshold "
                        "(try another threshold, or invert)", where=name)
    return contours_to_path(order_contours(found, start), feed, start, os.path.basename(name))
