"""A board's grid of corners judged and grown from the grey levels: the saddle each corner's four squares make,
the board's colouring, the points one step past a grid's edge, and a pattern grown corner by corner past what the
detector found (a board tiled over the frame), for :mod:`.detect`.

Convention: pixels (u, v) px, pixel centres at integers (as :mod:`panomap.geometry`); a corner's grid place is
(column, row) counted in squares; grid steps ``a``, ``b`` (n, 2) px are the ways to the next corner along the
columns and the rows.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from ...geometry import FloatArray

# A pattern's grid is grown (_grown) by corners that moved less than this fraction of the way to their neighbour
# from where the corners before them predict them, whose squares show this fraction of the grid's own corners'
# contrast (sampled this fraction of the way along each diagonal), and whose squares are this size (px) or more.
GROWN_MOVE = 0.25
GROWN_CONTRAST = 0.3
GROWN_SAMPLE = 0.3
GROWN_SQUARE_PX = 8.0
# ... and where the grey levels' Hessian (smoothed over GROWN_BLUR_PX) is a saddle this fraction as deep as at the
# grid's own corners (on a board rendered through a fisheye, its corners 0.21 or more, points of an edge between
# two sheared squares 0.15 or less).
GROWN_BLUR_PX = 1.75
GROWN_SADDLE = 0.18
# The most a corner is refined over (px, half-width): see detect.MIN_WINDOW_PX.
MAX_WINDOW_PX = 15


def _colouring(
    search: NDArray[np.uint8], pixels: FloatArray, grid: NDArray[np.intp], a: FloatArray, b: FloatArray
) -> tuple[FloatArray, NDArray[np.intp], float, float]:
    """A grid's own corners (n, 2) px at places ``grid`` (n, 2), grid steps ``a``, ``b`` (n, 2) px: each corner's
    contrast (n,) (:func:`_saddle`), its parity (n,) (+1 / -1 by column + row), the board's colouring (+1 / -1: the
    sign of the squares along the columns' and rows' diagonal, as most corners show it) and the contrast a corner
    needs to show it (``GROWN_CONTRAST`` of the median corner's)."""
    contrast = _saddle(search, pixels, a, b)
    parity = (grid[:, 0] + grid[:, 1]) % 2 * 2 - 1
    colouring = 1.0 if np.median(contrast * parity) > 0 else -1.0
    return contrast, parity, colouring, GROWN_CONTRAST * float(np.median(np.abs(contrast)))


def _least_width(a: FloatArray, b: FloatArray) -> FloatArray:
    """The least width (px, (n,)) of the squares with grid steps ``a``, ``b`` (n, 2) px."""
    out: FloatArray = np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]) / np.maximum(
        np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1)
    )
    return out


def _beyond(search: NDArray[np.uint8], placed: FloatArray, colouring: float, least: float) -> tuple[float, ...]:
    """For each edge of a grid ``placed`` (rows, columns, 2) px (first row, last row, first column, last column), the
    fraction of the points one step past it (a parabola through the three corners before each, as :func:`_grown`
    predicts them) inside the image whose four squares show the grid's colouring (``colouring``, contrast over
    ``least``): 0 past a board's edge (its outer squares' outer vertices), most of them where a pattern runs on."""
    height, width = search.shape
    rows, columns = placed.shape[:2]
    out = []
    for turned, flip in ((False, True), (False, False), (True, True), (True, False)):
        grid = np.transpose(placed, (1, 0, 2)) if turned else placed  # (lines across the edge, along it, 2)
        grid = grid[::-1] if flip else grid
        edge, before, further = grid[-1], grid[-2], grid[-3]
        ahead = 3.0 * edge - 3.0 * before + further
        step = ahead - edge
        along = np.gradient(edge, axis=0)
        # the parity of the points ahead: the next line's, in the grid's own (column + row) count
        line = (rows if not turned else columns) - 1 if not flip else 0
        line = line + (-1 if flip else 1)
        place = np.arange(edge.shape[0])
        parity = ((place + line) % 2) * 2 - 1
        a, b = (along, step) if not turned else (step, along)
        inside = (ahead[:, 0] >= 0) & (ahead[:, 1] >= 0) & (ahead[:, 0] <= width - 1) & (ahead[:, 1] <= height - 1)
        if not inside.any():
            out.append(0.0)
            continue
        contrast = _saddle(search, ahead[inside], a[inside], b[inside])
        sign = -1.0 if flip else 1.0  # the step across the edge points back along the grid's count
        out.append(float(np.mean(sign * contrast * parity[inside] * colouring > least)))
    return tuple(out)


def _grown(
    search: NDArray[np.uint8], pixels: FloatArray, grid: NDArray[np.intp]
) -> tuple[FloatArray, NDArray[np.intp]]:
    """A pattern's corners (n, 2) px and grid places (n, 2), grown from the detector's part of it to all it shows.

    The detector stops growing a grid at about ``PATTERN_CORNERS`` corners (a board tiled over the frame: a
    third of it). From the grid's edge, corner by corner outwards: each missing neighbour is predicted from
    the two or three corners before it in line (a parabola: the lens bends the rows), refined by the saddle of
    the grey levels (``cornerSubPix``, a quarter of the way to its neighbour) and kept where it moved less
    than ``GROWN_MOVE`` of that way, where the four squares round it are dark and light as the board's colouring
    has them (``GROWN_CONTRAST`` of the grid's own corners' contrast) and the grey levels are a saddle
    (``GROWN_SADDLE``: a point on the edge between two thin, sheared squares passes the others). Growth stops
    where the squares' least width is under ``GROWN_SQUARE_PX``, at the image's edge and where no corner
    passes.
    """
    height, width = search.shape
    steps = ((1, 0), (-1, 0), (0, 1), (0, -1))
    a, b = _steps(pixels, grid)
    handed = 1.0 if np.median(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]) > 0 else -1.0
    known = {(int(c), int(r)): p for (c, r), p in zip(grid, pixels, strict=True)}
    _, _, colouring, least = _colouring(search, pixels, grid, a, b)
    saddle = _hessian(search)
    deepest = GROWN_SADDLE * float(np.median(_sampled(saddle, pixels)))
    frontier = set(known)
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 40, 0.01)
    while frontier:
        targets: dict[tuple[int, int], tuple[FloatArray, FloatArray, FloatArray]] = {}
        spread: dict[tuple[int, int], float] = {}  # the farthest apart two lines predict it (px)
        for c, r in frontier:
            for dc, dr in steps:
                target, back = (c + dc, r + dr), (c - dc, r - dr)
                if target in known or back not in known:
                    continue
                here, before = known[(c, r)], known[back]
                further = known.get((c - 2 * dc, r - 2 * dr))
                predicted = 2.0 * here - before if further is None else 3.0 * here - 3.0 * before + further
                if target in targets:
                    first = targets[target][0]
                    spread[target] = max(spread.get(target, 0.0), float(np.hypot(*(predicted - first))))
                    continue
                step = (here - before) * (dc + dr)  # along +column or +row
                # the steps along the columns and the rows there (the other from the corner it grows from)
                other = _axis(known, (c, r), 1 if dr == 0 else 0)
                if other is None:  # a quarter turn the grid's way
                    other = handed * (np.array([-step[1], step[0]]) if dr == 0 else np.array([step[1], -step[0]]))
                targets[target] = (predicted, step, other) if dr == 0 else (predicted, other, step)
        if not targets:
            break
        places = list(targets)
        predicted = np.array([targets[t][0] for t in places])
        a = np.array([targets[t][1] for t in places])
        b = np.array([targets[t][2] for t in places])
        spacing = _least_width(a, b)  # a lens that squeezes the squares radially shears them into thin rhombi
        half = np.floor(spacing / 4.0)
        margin = np.minimum.reduce(
            [predicted[:, 0], predicted[:, 1], width - 1 - predicted[:, 0], height - 1 - predicted[:, 1]]
        )
        usable = (spacing >= GROWN_SQUARE_PX) & (margin > np.minimum(half, MAX_WINDOW_PX) + 2.0)
        refined = predicted.copy()
        for size in np.unique(np.clip(half[usable], 2, MAX_WINDOW_PX)):
            these = usable & (np.clip(half, 2, MAX_WINDOW_PX) == size)
            corners = predicted[these].astype(np.float32).reshape(-1, 1, 2)
            refined[these] = cv2.cornerSubPix(search, corners, (int(size), int(size)), (-1, -1), criteria).reshape(
                -1, 2
            )
        expected = colouring * (np.array([(c + r) % 2 for c, r in places]) * 2 - 1)
        apart = np.array([spread.get(t, 0.0) for t in places])
        passed = usable & (np.linalg.norm(refined - predicted, axis=1) + apart < GROWN_MOVE * spacing)
        passed &= _saddle(search, refined, a, b) * expected > least
        passed &= _sampled(saddle, refined) < deepest  # a saddle, not a point on an edge between two
        frontier = set()
        for k in np.flatnonzero(passed):
            known[places[k]] = refined[k]
            frontier.add(places[k])
    found = np.array(list(known), dtype=np.intp)
    order = np.lexsort((found[:, 0], found[:, 1]))  # row by row, as the detector's
    out = np.array([known[(int(c), int(r))] for c, r in found[order]])
    return out, found[order] - found.min(axis=0)


def _steps(pixels: FloatArray, grid: NDArray[np.intp]) -> tuple[FloatArray, FloatArray]:
    """The steps (px, (n, 2) each) along the columns and the rows at each corner of a whole rectangular grid."""
    placed = pixels.reshape(int(grid[:, 1].max()) + 1, int(grid[:, 0].max()) + 1, 2)
    along = np.asarray(np.gradient(placed, axis=1)).reshape(-1, 2)
    across = np.asarray(np.gradient(placed, axis=0)).reshape(-1, 2)
    return along, across


def _axis(known: dict[tuple[int, int], FloatArray], place: tuple[int, int], which: int) -> FloatArray | None:
    """The grid's step (px) along its columns (``which`` 0) or rows (1) at a known corner; None where neither
    neighbour that way is known."""
    c, r = place
    ahead = (c + 1, r) if which == 0 else (c, r + 1)
    behind = (c - 1, r) if which == 0 else (c, r - 1)
    if ahead in known:
        return known[ahead] - known[place]
    if behind in known:
        return known[place] - known[behind]
    return None


def _hessian(search: NDArray[np.uint8]) -> NDArray[np.float32]:
    """The determinant of the grey levels' Hessian (H, W), smoothed over ``GROWN_BLUR_PX``: deeply negative at a
    checkerboard's corner (a saddle), near 0 on an edge between two squares."""
    smooth = cv2.GaussianBlur(search.astype(np.float32), (0, 0), GROWN_BLUR_PX)
    xx = cv2.Sobel(smooth, cv2.CV_32F, 2, 0)
    yy = cv2.Sobel(smooth, cv2.CV_32F, 0, 2)
    xy = cv2.Sobel(smooth, cv2.CV_32F, 1, 1)
    out: NDArray[np.float32] = xx * yy - xy * xy
    return out


def _sampled(image: NDArray[np.float32], at: FloatArray) -> FloatArray:
    """``image`` (H, W) at points ``at`` (n, 2) px, bilinear, (n,)."""
    point = at.astype(np.float32)
    grey = cv2.remap(image, point[:, None, 0].copy(), point[:, None, 1].copy(), cv2.INTER_LINEAR)
    return np.asarray(grey, dtype=np.float64).ravel()


def _saddle(search: NDArray[np.uint8], at: FloatArray, a: FloatArray, b: FloatArray) -> FloatArray:
    """The grey levels' checkerboard contrast (n,) at corners ``at`` (n, 2) px with grid steps ``a``, ``b`` (n, 2): the
    lesser of the two squares on the diagonal along a + b less the greater of the two on the other diagonal, or
    the reverse, negated, where that is larger (0 where neither diagonal is the lighter)."""
    sampled = []
    for sa, sb in ((1, 1), (-1, -1), (1, -1), (-1, 1)):
        point = (at + GROWN_SAMPLE * (sa * a + sb * b)).astype(np.float32)
        grey = cv2.remap(
            search,
            point[:, None, 0].copy(),
            point[:, None, 1].copy(),
            cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_REPLICATE,
        )
        sampled.append(grey.ravel().astype(np.float64))
    pp, mm, pm, mp = sampled
    lighter = np.minimum(pp, mm) - np.maximum(pm, mp)
    darker = np.minimum(pm, mp) - np.maximum(pp, mm)
    out: FloatArray = np.where(lighter > 0, lighter, np.where(darker > 0, -darker, 0.0))
    return out
