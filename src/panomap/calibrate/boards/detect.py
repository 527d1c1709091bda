"""The inner corners of a checkerboard in an omni-image, with their place on the board's grid.

Convention: pixels (u, v) px, pixel centres at integers (as :mod:`panomap.geometry`); a corner's grid
place is (column, row) counted in squares from the first corner found.

OpenCV's sector-based detector (``findChessboardCornersSB``) finds boards bent by a mirror or a
fisheye lens, to a fraction of a pixel; told that the board may be larger than the pattern asked for
(``CALIB_CB_LARGER``) it grows the grid to the whole board, so the board's size need not be known.
It grows from a small seed that it may not find on every board, so several seeds are tried and the
largest grid kept.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from ...geometry import FloatArray

# Seeds (columns, rows of inner corners) the detector grows from; the largest board found is kept.
SEEDS = ((3, 3), (4, 4), (5, 5))
# Seeds tried in the searches after a board was found.
LATER_SEEDS = 2
# The detector draws random samples from OpenCV's global generator; it is seeded before every search.
RNG_SEED = 20071
# Most boards searched for in one image.
MAX_BOARDS = 6
# Fewest inner corners a board must show to be used.
MIN_CORNERS = 20
# The search stops after this many searches in a row that find only grids under MIN_CORNERS: a scene's texture
# (foliage, a patterned rug) shows the detector 3 x 3 to 3 x 5 grids again and again (16 on a 960 x 1080 picture of
# trees, 17 s), while a real board, the largest grid in the image, is found first and grows past it.
MAX_SMALL_FINDS = 3
# Images larger than this (px, the longer side) are searched downscaled, and the corners refined in full.
SEARCH_SIZE_PX = 1400
# The half-width (px) of the window a corner is refined in: a quarter of the way to its nearest corner, at
# least MIN (smaller squares keep the detector's estimate) and at most MAX.
MIN_WINDOW_PX = 4
MAX_WINDOW_PX = 15


@dataclass(frozen=True)
class Board:
    """One checkerboard found in one image.

    Attributes
    ----------
    image_index : int
        Which of the images given it is in.
    pixels : (n, 2) float64, px
        Its inner corners (u, v).
    grid : (n, 2) int
        Each corner's place on the board: (column, row), in squares.
    """

    image_index: int
    pixels: FloatArray
    grid: NDArray[np.intp]

    @property
    def shape(self) -> tuple[int, int]:
        """(columns, rows) of inner corners."""
        return int(self.grid[:, 0].max()) + 1, int(self.grid[:, 1].max()) + 1


def find_boards(image: NDArray[np.generic], image_index: int = 0, max_boards: int = MAX_BOARDS) -> list[Board]:
    """The checkerboards in ``image`` ((H, W) or (H, W, 3) uint8, BGR).

    The detector returns one board per search: each board found is painted over (its corners' hull,
    grown by its squares) and the image searched again, up to ``max_boards``.

    Returns
    -------
    list of Board
        The boards found (each at least ``MIN_CORNERS`` inner corners), in the order found.
    """
    grey = image if image.ndim == 2 else cv2.cvtColor(np.ascontiguousarray(image), cv2.COLOR_BGR2GRAY)
    grey = np.ascontiguousarray(grey, dtype=np.uint8)
    scale = min(1.0, SEARCH_SIZE_PX / max(grey.shape))
    search: NDArray[np.uint8] = np.asarray(
        grey if scale == 1.0 else cv2.resize(grey, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA),
        dtype=np.uint8,
    )
    boards: list[Board] = []
    searched = 0
    small = 0
    while len(boards) < max_boards and small < MAX_SMALL_FINDS:
        # every seed on the first search; after a board, fewer (a search that finds nothing costs all of them)
        found = _largest(search, SEEDS if searched == 0 else SEEDS[:LATER_SEEDS])
        searched += 1
        if found is None:
            break
        pixels, (rows, columns) = found
        search = _painted_over(search, pixels, columns, rows)
        if len(pixels) < MIN_CORNERS or len(pixels) != rows * columns:
            small += 1
            continue
        small = 0
        if scale != 1.0:
            pixels = (pixels + 0.5) / scale - 0.5
        pixels = _refine(grey, pixels, columns, rows)
        column, row = np.meshgrid(np.arange(columns), np.arange(rows))
        grid = np.stack([column.ravel(), row.ravel()], axis=1).astype(np.intp)
        boards.append(Board(image_index, pixels, grid))
    return boards


def _largest(
    search: NDArray[np.uint8], seeds: tuple[tuple[int, int], ...]
) -> tuple[FloatArray, tuple[int, int]] | None:
    """The largest board the detector grows from any seed: corners (n, 2) px and (rows, columns)."""
    flags = cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_LARGER | cv2.CALIB_CB_ACCURACY
    best: tuple[FloatArray, tuple[int, int]] | None = None
    for seed in seeds:
        cv2.setRNGSeed(RNG_SEED)  # the detector samples with OpenCV's global generator: the same image, the same boards
        found, corners, meta = cv2.findChessboardCornersSBWithMeta(search, seed, flags=flags)
        if found and corners is not None and (best is None or len(corners) > len(best[0])):
            best = (corners.reshape(-1, 2).astype(np.float64), (int(meta.shape[0]), int(meta.shape[1])))
    return best


def _painted_over(search: NDArray[np.uint8], pixels: FloatArray, columns: int, rows: int) -> NDArray[np.uint8]:
    """``search`` with a board's corners' hull, grown by two of its squares, filled with its median grey."""
    hull = np.zeros(search.shape, dtype=np.uint8)
    cv2.fillConvexPoly(hull, cv2.convexHull(np.round(pixels).astype(np.int32)), 1)
    grow = 2 * int(np.ceil(np.median(_neighbour_spacing(pixels, columns, rows)))) + 1
    mask = cv2.dilate(hull, np.ones((grow, grow), np.uint8))
    out: NDArray[np.uint8] = search.copy()
    out[mask > 0] = np.uint8(np.median(search))
    return out


def _neighbour_spacing(pixels: FloatArray, columns: int, rows: int) -> FloatArray:
    """Each corner's distance (px) to its nearest neighbour on the grid, (n,)."""
    grid = pixels.reshape(rows, columns, 2)
    nearest = np.full((rows, columns), np.inf)
    along = np.linalg.norm(np.diff(grid, axis=1), axis=2)
    across = np.linalg.norm(np.diff(grid, axis=0), axis=2)
    nearest[:, :-1] = np.minimum(nearest[:, :-1], along)
    nearest[:, 1:] = np.minimum(nearest[:, 1:], along)
    nearest[:-1, :] = np.minimum(nearest[:-1, :], across)
    nearest[1:, :] = np.minimum(nearest[1:, :], across)
    return nearest.ravel()


def _refine(grey: NDArray[np.uint8], pixels: FloatArray, columns: int, rows: int) -> FloatArray:
    """Corners refined by the saddle of the grey levels (``cornerSubPix``) where their squares are large enough.

    The window reaches a quarter of the way to the nearest corner; where that is under ``MIN_WINDOW_PX`` the
    window holds too few pixels of the four squares' edges and the detector's own estimate is kept.
    """
    half = np.floor(_neighbour_spacing(pixels, columns, rows) / 4.0)
    height, width = grey.shape
    margin = np.minimum.reduce([pixels[:, 0], pixels[:, 1], width - 1 - pixels[:, 0], height - 1 - pixels[:, 1]])
    half = np.minimum(half, np.floor(margin) - 1.0)  # the window stays inside the image
    out = pixels.copy()
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 40, 0.01)
    for size in np.unique(np.clip(half[half >= MIN_WINDOW_PX], MIN_WINDOW_PX, MAX_WINDOW_PX)):
        these = np.clip(half, MIN_WINDOW_PX, MAX_WINDOW_PX) == size
        these &= half >= MIN_WINDOW_PX
        corners = pixels[these].astype(np.float32).reshape(-1, 1, 2)
        refined = cv2.cornerSubPix(grey, corners, (int(size), int(size)), (-1, -1), criteria)
        out[these] = refined.reshape(-1, 2)
    return out
