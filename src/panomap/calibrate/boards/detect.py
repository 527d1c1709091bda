"""The inner corners of a checkerboard in an omni-image, with their place on the board's grid.

Convention: pixels (u, v) px, pixel centres at integers (as :mod:`panomap.geometry`); a corner's grid
place is (column, row) counted in squares from the first corner found.

OpenCV's sector-based detector (``findChessboardCornersSB``) finds boards bent by a mirror or a
fisheye lens, to a fraction of a pixel; told that the board may be larger than the pattern asked for
(``CALIB_CB_LARGER``) it grows the grid to the whole board, so the board's size need not be known.
It grows from a small seed that it may not find on every board, so several seeds are tried and the
largest grid kept.

The search runs without the detector's upsampling (``CALIB_CB_ACCURACY``, three to four times its time,
and most searches find nothing or the same board again); once a board is found, the detector places its
corners with the upsampling on a crop of the image around it (a tenth of a search's time), where it may
grow the grid by a row the search missed (:func:`_accurate`), and they are refined in full (:func:`_refine`).

The detector grows a grid to about ``PATTERN_CORNERS`` corners at most: a board tiled over the whole frame
is grown on from there corner by corner (:func:`.grid._grown`), and its corners' places are then whatever part of
the board the picture shows, not a rectangle.

Once a board is found, the search for another looks at the image halved first (:func:`_looked`). Many pictures
(:func:`find_boards_each`) are searched in threads, and where the first two show one board each, of one size, the
others are searched for one board only (the search for more, most of what is left, is left out; OpenCV's quick
detector, told the size, looks for a second: :func:`_one_board`; so does it on the second picture, where the first
one's board is beyond doubt: :func:`_bounded_size`). Told the board's size, the sector detector is no quicker: it
needs ``CALIB_CB_EXHAUSTIVE`` to find the real sets' boards (0 of 17 without on the Kaidan set) and then takes as
long as the search grown from a seed (measured on the five sets). OpenCV's quick detector told the size finds the
real fisheye and VMR sets' boards in a fifth of the search's time: where it finds the first pictures' boards and
their squares are large enough for every corner to be refined in full, it stands in for the search on the later
pictures (:func:`_quick_board`): its corners refined in full from where it puts them where each settles on a saddle
(:func:`_settled`: a fortieth of the crop's upsampled placement), else placed as the search's are.
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from functools import partial
from itertools import chain, islice

import cv2
import numpy as np
from numpy.typing import NDArray

from ...geometry import FloatArray
from .grid import (
    MAX_WINDOW_PX,
    _beyond,
    _colouring,
    _grown,
    _least_width,
    _steps,
)

# Seeds (columns, rows of inner corners) the detector grows from, in order; the largest board found is kept. A
# search stops at the first seed that grows to a board of MIN_CORNERS or more: on the 79 pictures of the real sets
# and rendered scenes, the later seeds grew to the same board every time (a quarter of the detection's time).
# (3, 3), tried last, also grows from a scene's texture.
SEEDS = ((4, 4), (5, 5), (3, 3))
# The seeds of the searches after a board was found: one (most images hold one board, and a search that finds
# nothing costs every seed).
LATER_SEEDS = ((4, 4),)
# The search's flags; the corners of a board found are placed with CALIB_CB_ACCURACY on a crop (_accurate).
SEARCH_FLAGS = cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_LARGER
# The crop round a board found reaches this many of its largest squares beyond its outer corners.
CROP_SQUARES = 1.5
# The detector grows a grid to about this many corners at most (its exhaustive search's limit): a grid this large
# is part of a larger pattern (a board tiled over the frame), which the crop round it shows beyond it, and its
# corners are not placed on a crop.
PATTERN_CORNERS = 500
# A board found (_checked) loses an outer row or column where fewer than CHECKED_ROW of its corners show the board's
# colouring (a row past the board's edge shows none), and is refused where fewer than CHECKED_BOARD of those left do
# (a glare or a shadow on a corner or two does not lose a board); corners whose squares are under CHECKED_SQUARE_PX
# wide are not judged.
CHECKED_ROW = 0.5
CHECKED_BOARD = 0.9
CHECKED_SQUARE_PX = 6.0
# A corner placed on the crop is the search's corner where it lies within this fraction of the way to the corner's
# nearest neighbour on the grid, and no other corner of the search's is nearest it (the search's corners, without
# the upsampling, may lie 0.3-0.7 of the way off where a square is a few pixels: 3 px on the MiniOmni set).
SAME_CORNER = 0.75
# The detector draws random samples from OpenCV's global generator; it is seeded before every search.
RNG_SEED = 20071
# Most boards searched for in one image.
MAX_BOARDS = 6
# Pictures the board is learned from (find_boards_each): where each shows one whole board, all of one size, the
# later pictures are searched for one board of that size (the look for more left out: a third of the detection's
# time on the real sets). The second's look for more is the later pictures' where the first picture's first board
# is beyond doubt (_bounded_size) and the second's first board is of its size.
LEARN_PICTURES = 2
# ... where OpenCV's quick detector, told the size, sees no second board (_one_board): its look for a board that is
# most often absent starts with its fast check (CALIB_CB_FAST_CHECK), which ends most such looks early.
QUICK_FLAGS = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_FAST_CHECK
# The quick detector's flags where it looks for the board a picture is expected to show (_quick_suits, _quick_board):
# without the fast check, which only decides whether to look on (the corners where both find a board are the same, bit
# for bit, on the real sets' 63 pictures), took half its time where the board is there (VMR set: 11 against 6 ms a
# picture) and turned away boards it finds (3 of 10 Mei pictures, 17 of 17 Kaidan ones).
FOUND_FLAGS = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
# Fewest inner corners a board must show to be used.
MIN_CORNERS = 20
# The search stops after this many searches in a row that find only grids under MIN_CORNERS: a scene's texture
# (foliage, a patterned rug) shows the detector 3 x 3 to 3 x 5 grids again and again (16 on a 960 x 1080 picture of
# trees, 17 s), while a real board, the largest grid in the image, is found first and grows past it: once a board
# is found, the first search that finds only such a grid ends it.
MAX_SMALL_FINDS = 3
# Images larger than this (px, the longer side) are searched downscaled, and the corners refined in full.
SEARCH_SIZE_PX = 1400
# Once a board is found, the search for another first looks at the search image halved (LOOK_FACTOR: a quarter to
# three quarters of the time, where it finds nothing) and searches the search image itself only where that shows a
# grid: most images hold one board, and the search that finds nothing more was half the detection's time. On the
# 63 pictures of the real sets (the MiniOmni set's squares 3 px at their smallest) the halved image showed every
# board the full search finds; the corners are the full search's, unchanged.
LOOK_FACTOR = 0.5
# The quick detector's corners (_quick_board) are refined in full from where it puts them (twice, the second from the
# first's corners and windows) where each corner settles: refined again from SETTLE_START_PX off it in u and in v (along
# each diagonal, 0.42 px) it comes back within SETTLED_PX, and it moved less than SETTLE_MOVE of the way to its nearest
# neighbour (a corner the quick detector put on no saddle, 11 px off on a real fisheye picture, is drawn 8 px by those
# starts). Else it is placed as the search's, on a crop (_accurate).
SETTLE_START_PX = 0.3
SETTLED_PX = 0.02
SETTLE_MOVE = 0.25
# The half-width (px) of the window a corner is refined in: a quarter of the way to its nearest corner, at
# least MIN (smaller squares keep the detector's estimate) and at most MAX.
MIN_WINDOW_PX = 4
# The quick detector stands in for the search (_quick_board) where every corner's window would be this or more: a
# corner with a window under MIN_WINDOW_PX keeps the upsampled placement on a crop drawn round the quick detector's
# corners instead of the search's.
QUICK_WINDOW_PX = 3


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
    grown by its squares) and the image searched again, up to ``max_boards`` (:func:`_searches`).

    Returns
    -------
    list of Board
        The boards found (each at least ``MIN_CORNERS`` inner corners), in the order found.
    """
    return list(islice(_searches(_grey(image), image_index), max_boards))


def _searches(grey: NDArray[np.uint8], image_index: int) -> Iterator[Board]:
    """The boards of :func:`find_boards` in ``grey`` (H, W), one search at a time, each as soon as it is found: a
    caller that asked for one board and wants more goes on from where the search stopped (:func:`_one_board`: the
    first search is not run again; the boards are those of :func:`find_boards`, bit for bit)."""
    search, scale = _searched(grey)
    searched = 0
    small = 0
    found_any = False
    while small < (1 if found_any else MAX_SMALL_FINDS):
        # every seed on the first search; after it, a search that finds nothing with the first seed ends there
        found = _largest(search, SEEDS) if searched == 0 else _looked(search)
        searched += 1
        if found is None:
            break
        pixels, (rows, columns) = found
        if len(pixels) < MIN_CORNERS or len(pixels) != rows * columns:
            search = _painted_over(search, pixels, _rectangle(columns, rows))
            small += 1
            continue
        if len(pixels) < PATTERN_CORNERS:
            placed = _accurate(search, pixels, columns, rows)
            if placed is not None:
                pixels, (rows, columns) = placed
        checked = _checked(search, pixels, columns, rows)
        if checked is None:  # not a board: a scene's checkered texture, its grid run off it
            search = _painted_over(search, pixels, _rectangle(columns, rows))
            small += 1
            continue
        small = 0
        pixels, (rows, columns) = checked
        if len(pixels) < PATTERN_CORNERS:
            grid = _rectangle(columns, rows)
        else:
            pixels, grid = _grown(search, pixels, _rectangle(columns, rows))
        search = _painted_over(search, pixels, grid)
        if scale != 1.0:
            pixels = _in_image(pixels, scale)
        found_any = True
        yield Board(image_index, _refine(grey, pixels, grid), grid)


def find_boards_each(images: Sequence[NDArray[np.generic]], threads: int | None = None) -> Iterator[list[Board]]:
    """The checkerboards of each of ``images`` (:func:`find_boards`, each board's ``image_index`` its image's place
    in ``images``), image by image in order, each as soon as it and those before it are searched.

    The board is learned from the first pictures: where each of the first ``LEARN_PICTURES`` shows one whole board,
    all of one size (rows x columns, either way round), the others are searched for one board only
    (:func:`_one_board`: the look for more, a third of the detection's time, is left out; OpenCV's quick detector
    told the size looks for a second), and in full where that one is of another size or the quick detector sees a
    second. A later picture that shows two boards of the size that the quick detector misses (a mirror's strongly
    bent boards) gives the first only. Where the quick detector told the size finds the learned pictures' boards and
    their squares are large enough for every corner to be refined in full (:func:`_quick_suits`), it also stands in
    for the search on the later pictures (:func:`_quick_board`).

    Where the first picture's first board is beyond doubt (:func:`_bounded_size`: whole, every corner a board's,
    the pattern running on past none of its edges) and the second picture's first board is whole and of its size,
    the second picture's look for another is the quick detector's, as the later pictures' (:func:`_learning`), not
    the search's look at the picture halved; where the first picture then shows another board, the second is
    searched in full again with the later ones.

    The images are searched ``threads`` at a time (the CPUs', where None): the detector runs in one thread and
    lets the others run, so the wall time falls with the cores free and the CPU time does not. Each search seeds
    the generator of its own thread (OpenCV keeps one per thread): the boards are those found one image at a time.
    The later pictures are searched once the first pictures' first boards are found, while those are searched for
    more (:func:`_learning`: no core waits on the slower one); where one shows more, the later ones again in full.
    """
    learning = range(min(LEARN_PICTURES, len(images)))
    later = range(len(learning), len(images))
    with ThreadPoolExecutor(max(min(len(images), threads or os.cpu_count() or 1), 1), "panomap-boards") as pool:
        firsts: list[Future[Board | None]] = [Future() for _ in learning]
        told: Future[tuple[int, int] | None] = Future()  # the first picture's first board's size, beyond doubt
        searched = [pool.submit(_learning, images[k], k, firsts[k], told if k else None) for k in learning]
        try:
            opening = firsts[0].result() if len(learning) == LEARN_PICTURES else None
            told.set_result(None if opening is None else _bounded_size(images[0], opening))
        finally:  # (the second picture's search waits on it)
            if not told.done():
                told.set_result(None)
        learned = [first.result() for first in firsts]
        size = learned_size([[board] if board is not None else [] for board in learned])  # None: None once all are
        if size is None:
            ahead = [pool.submit(find_boards, images[k], k) for k in later]
        else:
            boards = [board for board in learned if board is not None]
            quick = all(_refined(images[k], board) for k, board in enumerate(boards))  # cheap: before the detector
            quick = quick and all(pool.map(partial(_quick_suits, size=size), images[: len(boards)], boards))
            ahead = [pool.submit(_one_board, images[k], k, size, quick) for k in later]
        try:
            first = [these.result() for these in searched]
            if learned_size(first) == size:
                yield from first
                yield from (these.result() for these in ahead)
                return
        finally:  # those not started where not wanted, or where the caller stops early
            for these in ahead:
                these.cancel()
        if told.result() is not None and len(first) > 1:  # the first picture shows more: the second's look was not
            first[1] = find_boards(images[1], 1)  # the search's
        yield from first
        yield from pool.map(find_boards, [images[k] for k in later], later)


def _bounded_size(image: NDArray[np.generic], board: Board) -> tuple[int, int] | None:
    """The size (lesser, greater count of inner corners) of ``board`` (the first picture's first board, from the
    search) where it is beyond doubt a whole board, one the second picture's may be compared with (:func:`_learning`):
    every corner found, each showing the board's colouring on the search's image (:func:`.grid._colouring`, as
    :func:`_checked` asks), and the pattern running on past none of its edges (:func:`.grid._beyond`: a grid a row
    short of its board runs on past one); else None."""
    if len(board.pixels) != board.shape[0] * board.shape[1] or len(board.pixels) >= PATTERN_CORNERS:
        return None
    search, scale = _searched(_grey(image))
    columns, rows = board.shape
    pixels = _in_search(board.pixels, scale)
    a, b = _steps(pixels, board.grid)
    contrast, parity, colouring, least = _colouring(search, pixels, board.grid, a, b)
    beyond = _beyond(search, pixels.reshape(rows, columns, 2), colouring, least)
    if np.any(contrast * parity * colouring <= least) or max(beyond) >= CHECKED_ROW:
        return None
    low, high = sorted(board.shape)
    return low, high


def _learning(
    image: NDArray[np.generic],
    image_index: int,
    first: Future[Board | None],
    told: Future[tuple[int, int] | None] | None = None,
) -> list[Board]:
    """A learned picture's boards (:func:`find_boards`), its first board (or None) set in ``first`` when found.

    With ``told`` (the second picture's: the first picture's first board's size, where beyond doubt), once its
    first board is found the picture waits for that size: where its board is whole and of that size, the look for
    another is OpenCV's quick detector told the size (:func:`_another`, as the later pictures', :func:`_one_board`),
    not the search's look at the picture halved (a third to a half of a search's time), and the search goes on
    only where that sees another."""
    try:
        grey = _grey(image)
        searches = _searches(grey, image_index)
        board = next(searches, None)
    except BaseException as error:  # (any, the grey image's too: find_boards_each waits on ``first``)
        first.set_exception(error)
        raise
    first.set_result(board)
    if board is None:
        return []
    size = None if told is None else told.result()
    whole = len(board.pixels) == board.shape[0] * board.shape[1]
    if size is not None and whole and tuple(sorted(board.shape)) == size and not _another(grey, board):
        return [board]
    return [board, *islice(searches, MAX_BOARDS - 1)]


def learned_size(found: Sequence[Sequence[Board]]) -> tuple[int, int] | None:
    """The board's size (the lesser and the greater count of inner corners along a side) where each picture's
    boards ``found`` are one whole board, all of one size, and there are ``LEARN_PICTURES`` of them; else None."""
    if len(found) < LEARN_PICTURES or any(len(boards) != 1 for boards in found):
        return None
    sizes = {tuple(sorted(boards[0].shape)) for boards in found}
    whole = all(len(boards[0].pixels) == boards[0].shape[0] * boards[0].shape[1] for boards in found)
    if len(sizes) != 1 or not whole:
        return None
    low, high = sizes.pop()
    return low, high


def _one_board(image: NDArray[np.generic], image_index: int, size: tuple[int, int], quick: bool = False) -> list[Board]:
    """The board of ``size`` (:func:`learned_size`) in ``image``: the first search's board (with ``quick``, the quick
    detector's where :func:`_quick_board` gives one) where it is whole and of that size and OpenCV's quick detector,
    told the size (``findChessboardCorners``, ``CALIB_CB_FAST_CHECK``), sees no other with it painted over; none
    where the search finds none; else every board :func:`find_boards` finds (the search goes on from its first
    board, not run again: 0.45 s of 1 s on the picture of the Kaidan set whose first board is partial).

    The quick detector costs a sixth to a third of the halved look it stands in for, and sees the second board of
    11 of 12 rendered pictures of two 9 x 6 boards before a mirror, and the real sets' fisheye and VMR boards (21 of
    21; the pictures' one board, as a stand-in for a second), not the Kaidan mirror's (0 of 17) nor some of the
    MiniOmni's and Mei's (9 of 15, 7 of 10): there a second board of the size is missed.
    """
    grey = _grey(image)
    board = _quick_board(grey, image_index, size) if quick else None
    searches = _searches(grey, image_index)
    if board is None:  # the search's first board; where more are looked for, the search goes on from it
        board = next(searches, None)
        if board is None:
            return []
        searches = chain((board,), searches)
    if tuple(sorted(board.shape)) != size or len(board.pixels) != size[0] * size[1] or _another(grey, board):
        return list(islice(searches, MAX_BOARDS))
    return [board]


def _another(grey: NDArray[np.uint8], board: Board) -> bool:
    """Whether OpenCV's quick detector told the size of ``board`` (``QUICK_FLAGS``: its fast check first) sees another
    board of it in ``grey`` (H, W) with ``board`` painted over (:func:`_painted_over`)."""
    painted = _painted_over(grey, board.pixels, board.grid)
    another, _ = cv2.findChessboardCorners(painted, board.shape, flags=QUICK_FLAGS)
    return bool(another)


def _refined(image: NDArray[np.generic], board: Board) -> bool:
    """Whether every corner of ``board`` in ``image`` is refined in full: its window (:func:`_windows`) at least
    ``MIN_WINDOW_PX``."""
    return bool(np.all(_windows(_grey(image), board.pixels, board.grid) >= MIN_WINDOW_PX))


def _quick_suits(image: NDArray[np.generic], board: Board, size: tuple[int, int]) -> bool:
    """Whether OpenCV's quick detector told ``size`` finds ``board`` (a learned picture's, found by the search) in
    ``image``, each of its corners within ``SAME_CORNER`` of the way to its neighbour, and every corner of it is
    refined in full (:func:`_refined`): where the learned pictures' boards are so, the quick detector stands in for
    the search on the later pictures (:func:`_one_board`)."""
    if not _refined(image, board):
        return False
    search, scale = _searched(_grey(image))
    found, corners = cv2.findChessboardCorners(search, size, flags=FOUND_FLAGS)
    if not found or corners is None or len(corners) != len(board.pixels):
        return False
    rough = _in_image(corners.reshape(-1, 2).astype(np.float64), scale)
    distance = np.linalg.norm(rough[:, None, :] - board.pixels[None, :, :], axis=2)
    spacing = _neighbour_spacing(board.pixels, board.grid)
    return bool(np.all(distance.min(axis=0) < SAME_CORNER * spacing))


def _quick_board(grey: NDArray[np.uint8], image_index: int, size: tuple[int, int]) -> Board | None:
    """The board of ``size`` (lesser, greater count of inner corners) in ``grey`` (H, W) found by OpenCV's quick
    detector told the size (``findChessboardCorners``, ``FOUND_FLAGS``), its corners refined in full from where it
    puts them where each settles on a saddle and its rows are all a board's (:func:`_settled`, :func:`_checked`),
    else placed as :func:`find_boards` places a board its search found: by the sector detector with its upsampling
    on a crop round it (:func:`_accurate`, in its own order of the corners), then refined in full (:func:`_refine`);
    None where the quick detector finds no board, the crop shows no grid of ``size`` that holds its corners, or a
    corner's squares are too small for it to be refined (its window under ``MIN_WINDOW_PX``).

    It stands in for the search (``findChessboardCornersSBWithMeta``, exhaustive: 60-80 ms a picture on the real
    fisheye and VMR sets, the quick detector 3-20 ms). The crop is drawn round the quick detector's corners, not
    the search's, and the upsampled placement moves with it (0.1 px, up to 2 px where squares are a few pixels):
    corners that keep it, unrefined, would move; refined in full, they converge on the same saddle of the grey
    levels (on the real fisheye and VMR sets' pictures: 0.005 px or less from the search's).
    """
    search, scale = _searched(grey)
    columns, rows = size
    found, corners = cv2.findChessboardCorners(search, (columns, rows), flags=FOUND_FLAGS)
    if not found or corners is None or len(corners) != columns * rows:
        return None
    rough = corners.reshape(-1, 2).astype(np.float64)
    if _neighbour_spacing(rough, _rectangle(columns, rows)).min() / scale < 4.0 * QUICK_WINDOW_PX - 1.0:
        return None  # too small to be refined (the quick detector's corners within half a pixel)
    settled = _settled(grey, _in_image(rough, scale), _rectangle(columns, rows))
    if settled is not None:
        checked = _checked(search, _in_search(settled, scale), columns, rows)
        if checked is not None and len(checked[0]) == len(settled):  # its rows all a board's
            return Board(image_index, settled, _rectangle(columns, rows))
    placed = _accurate(search, rough, columns, rows, own_order=True)
    if placed is not None:  # its rows all a board's (the search's own check, _checked)
        placed = _checked(search, placed[0], placed[1][1], placed[1][0])
    if placed is None or tuple(sorted(placed[1])) != size:
        return None
    pixels, (rows, columns) = placed
    if scale != 1.0:
        pixels = _in_image(pixels, scale)
    grid = _rectangle(columns, rows)
    if np.any(_windows(grey, pixels, grid) < QUICK_WINDOW_PX):
        return None
    return Board(image_index, _refine(grey, pixels, grid), grid)


def _settled(grey: NDArray[np.uint8], rough: FloatArray, grid: NDArray[np.intp]) -> FloatArray | None:
    """The quick detector's corners ``rough`` (n, 2) px at places ``grid`` (n, 2), refined in full (:func:`_refine`,
    twice: the second from the first's corners and windows); None where a corner's window is under ``MIN_WINDOW_PX``, it
    moved ``SETTLE_MOVE`` of the way to its nearest neighbour or more, it does not settle (refined again from
    ``SETTLE_START_PX`` off it in u and in v, along each diagonal, it lands more than ``SETTLED_PX`` from it: the grey
    levels' saddle is no single point there, or another corner's draws it), or its four squares do not show the board's
    colouring (:func:`.grid._colouring`, as :func:`_checked` asks, of every corner: a start on a flat square is not
    moved).

    The search's placement (:func:`_accurate`, a crop searched with the detector's upsampling) only starts the same
    refinement: from the quick detector's corners (0.05-0.7 px off) the corners land on the same saddles, a
    fortieth of the time. Where they do not land on the search's, it is where cornerSubPix stopped short (steps
    under 0.01 px) or the window differs by a pixel (a quarter of the spacing, from other corners): 0.06 px at most
    on the real fisheye and VMR pictures, and on rendered boards as near the true corners as the search's.
    """
    spacing = _neighbour_spacing(rough, grid)
    if np.any(_windows(grey, rough, grid) < MIN_WINDOW_PX):
        return None
    settled = _refine(grey, _refine(grey, rough, grid), grid)
    if np.any(np.linalg.norm(settled - rough, axis=1) >= SETTLE_MOVE * spacing):
        return None
    for du, dv in ((1.0, 1.0), (-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0)):
        again = _refine(grey, settled + SETTLE_START_PX * np.array([du, dv]), grid)
        if np.any(np.linalg.norm(again - settled, axis=1) > SETTLED_PX):
            return None
    a, b = _steps(settled, grid)
    contrast, parity, colouring, least = _colouring(grey, settled, grid, a, b)
    if np.any(contrast * parity * colouring <= least):  # on a flat square cornerSubPix does not move a corner
        return None
    return settled


def _searched(grey: NDArray[np.uint8]) -> tuple[NDArray[np.uint8], float]:
    """The image the detector searches ((h, w) uint8: ``grey`` downscaled to ``SEARCH_SIZE_PX`` where larger) and its
    scale (search px per image px)."""
    scale = min(1.0, SEARCH_SIZE_PX / max(grey.shape))
    search: NDArray[np.uint8] = np.asarray(
        grey if scale == 1.0 else cv2.resize(grey, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA),
        dtype=np.uint8,
    )
    return search, scale


def _in_search(pixels: FloatArray, scale: float) -> FloatArray:
    """Image pixels (n, 2) px as the search image's (:func:`_searched`, ``scale`` search px per image px).

    Convention: pixel centres at integers, the two images' outer top-left corners (-0.5, -0.5) together."""
    return (pixels + 0.5) * scale - 0.5


def _in_image(pixels: FloatArray, scale: float) -> FloatArray:
    """The search image's pixels (n, 2) px as the image's: :func:`_in_search` undone."""
    return (pixels + 0.5) / scale - 0.5


def _grey(image: NDArray[np.generic]) -> NDArray[np.uint8]:
    """``image`` (H, W) or (H, W, 3) BGR as (H, W) 8-bit grey, contiguous: what the detector searches."""
    grey = image if image.ndim == 2 else cv2.cvtColor(np.ascontiguousarray(image), cv2.COLOR_BGR2GRAY)
    return np.ascontiguousarray(grey, dtype=np.uint8)


def _rectangle(columns: int, rows: int) -> NDArray[np.intp]:
    """The grid places (n, 2) (column, row) of a whole board's corners in the detector's order (row by row)."""
    column, row = np.meshgrid(np.arange(columns), np.arange(rows))
    return np.stack([column.ravel(), row.ravel()], axis=1).astype(np.intp)


def _largest(
    search: NDArray[np.uint8], seeds: tuple[tuple[int, int], ...], give_up: bool = False
) -> tuple[FloatArray, tuple[int, int]] | None:
    """The largest board the detector grows from the seeds: corners (n, 2) px and (rows, columns).

    The seeds are tried in order until one has grown to a board of ``MIN_CORNERS`` or more; with ``give_up``,
    none after a first that finds no such board.
    """
    best: tuple[FloatArray, tuple[int, int]] | None = None
    for seed in seeds:
        cv2.setRNGSeed(RNG_SEED)  # the detector samples with OpenCV's global generator: the same image, the same boards
        found, corners, meta = cv2.findChessboardCornersSBWithMeta(search, seed, flags=SEARCH_FLAGS)
        if not found or corners is None:
            if give_up:
                break
            continue
        if best is None or len(corners) > len(best[0]):
            best = (corners.reshape(-1, 2).astype(np.float64), (int(meta.shape[0]), int(meta.shape[1])))
        if give_up or len(best[0]) >= MIN_CORNERS:
            break
    return best


def _looked(search: NDArray[np.uint8]) -> tuple[FloatArray, tuple[int, int]] | None:
    """A later search (``LATER_SEEDS``, giving up at the first seed that finds nothing): :func:`_largest` on
    ``search`` where the detector shows a grid on ``search`` halved (``LOOK_FACTOR``), else None."""
    look = np.asarray(
        cv2.resize(search, None, fx=LOOK_FACTOR, fy=LOOK_FACTOR, interpolation=cv2.INTER_AREA), dtype=np.uint8
    )
    if _largest(look, LATER_SEEDS, give_up=True) is None:
        return None
    return _largest(search, LATER_SEEDS, give_up=True)


def _accurate(
    search: NDArray[np.uint8], pixels: FloatArray, columns: int, rows: int, own_order: bool = False
) -> tuple[FloatArray, tuple[int, int]] | None:
    """A board's corners (n, 2) px as the detector places them with its upsampling, and (rows, columns).

    The detector searches with ``CALIB_CB_ACCURACY`` on the board alone: the crop of ``search`` round its corners'
    hull grown by ``CROP_SQUARES`` of its largest squares, the rest of the crop filled with its median grey (a board
    tiled over the frame would show the detector thousands of corners), from each seed in turn (told the board's
    size, the detector often finds nothing on a crop; grown from a seed on it, the whole board in a tenth of a
    second), and its grid may grow past the search's: the upsampled image shows an outer row the search may miss
    (a 10 x 7 grid of an 11 x 7 board). The first grid of as many corners as ``pixels`` or more is kept where it
    holds every corner of ``pixels`` (each within ``SAME_CORNER`` of the way to its nearest neighbour on the grid),
    the same grid's corners in the order of ``pixels`` (with ``own_order``, in the detector's order, and its (rows,
    columns)); None where it does not (the search's corners are then kept; the later seeds grow the same grid, as
    in the search: on the real sets' two such boards, and a seed that finds nothing costs 0.3 s on a Kaidan crop).
    """
    spacing = _neighbour_spacing(pixels, _rectangle(columns, rows))
    mask = _grown_hull(search.shape, pixels, CROP_SQUARES * float(spacing.max()))
    x, y, width, height = cv2.boundingRect(mask)
    crop = search[y : y + height, x : x + width].copy()
    crop[mask[y : y + height, x : x + width] == 0] = _median_grey(crop)
    for seed in SEEDS:
        cv2.setRNGSeed(RNG_SEED)
        found, corners, meta = cv2.findChessboardCornersSBWithMeta(
            crop, seed, flags=SEARCH_FLAGS | cv2.CALIB_CB_ACCURACY
        )
        if not found or corners is None or len(corners) < len(pixels) or len(corners) != meta.shape[0] * meta.shape[1]:
            continue
        placed = corners.reshape(-1, 2).astype(np.float64) + np.array([x, y], dtype=np.float64)
        distance = np.hypot(*(pixels[:, None, :] - placed[None, :, :]).transpose(2, 0, 1))
        nearest = np.argmin(distance, axis=1)
        close = distance[np.arange(len(pixels)), nearest] < SAME_CORNER * spacing
        if not np.all(close) or len(np.unique(nearest)) != len(pixels):
            return None
        if len(placed) == len(pixels) and not own_order:
            return placed[nearest], (rows, columns)
        return placed, (int(meta.shape[0]), int(meta.shape[1]))
    return None


def _checked(
    search: NDArray[np.uint8], pixels: FloatArray, columns: int, rows: int
) -> tuple[FloatArray, tuple[int, int]] | None:
    """A board's corners (n, 2) px and (rows, columns) with the outer rows and columns that are not a checkerboard's
    taken off; None where what is left is not a board.

    The detector grows a grid past a board's edge where a dark shape lies against it (a row of the outer squares'
    outer vertices, a square's width off the true corners) and runs a scene's checkered texture onto what lies
    beyond it. A checkerboard's corner shows its four squares dark and light as the board's colouring has them
    (:func:`.grid._saddle`, sampled ``GROWN_SAMPLE`` of the way along the grid's diagonals, ``GROWN_CONTRAST`` of the
    median corner's contrast, as :func:`.grid._grown` asks); an outer row or column where fewer than ``CHECKED_ROW`` of
    the corners do is taken off (the worst first, then the others again), and the board is refused where fewer
    than ``CHECKED_BOARD`` of the corners left do or fewer than ``MIN_CORNERS`` are left. Corners whose squares are
    under ``CHECKED_SQUARE_PX`` wide are not judged (too few pixels to sample the squares apart).

    A board's squares end a square past its outer corners: where the pattern runs on past an edge
    (:func:`.grid._beyond`: ``CHECKED_ROW`` of the points one step past it show the colouring), the detector has
    missed a row of a board
    (past one edge of a grid whose corners all show the colouring: 2 of the 63 boards of the real sets, kept) or run
    a scene's texture into a grid (a checkered floor: past two or more edges, or past one of a grid with a corner
    that is no checkerboard's), refused. Not asked of a pattern tiled over the frame (``PATTERN_CORNERS``:
    :func:`.grid._grown`).
    """
    placed = pixels.reshape(rows, columns, 2)
    board = len(pixels) < PATTERN_CORNERS  # a board, not part of a pattern tiled over the frame (_grown)
    while rows >= 3 and columns >= 3 and rows * columns >= MIN_CORNERS:
        flat = placed.reshape(-1, 2)
        grid = _rectangle(columns, rows)
        a, b = _steps(flat, grid)
        contrast, parity, colouring, least = _colouring(search, flat, grid, a, b)
        good = ((contrast * parity * colouring > least) | (_least_width(a, b) < CHECKED_SQUARE_PX)).reshape(
            rows, columns
        )
        edges = (good[0].mean(), good[-1].mean(), good[:, 0].mean(), good[:, -1].mean())
        worst = int(np.argmin(edges))
        if edges[worst] < CHECKED_ROW:
            placed = (placed[1:], placed[:-1], placed[:, 1:], placed[:, :-1])[worst]
            rows, columns = placed.shape[0], placed.shape[1]
            continue
        if good.mean() < CHECKED_BOARD:
            return None
        # a pattern running on past two edges, or past one of a grid with a corner no checkerboard's: a texture
        runs_on = sum(edge >= CHECKED_ROW for edge in _beyond(search, placed, colouring, least)) if board else 0
        if runs_on >= 2 or (runs_on and not good.all()):
            return None
        return placed.reshape(-1, 2), (rows, columns)
    return None


def _painted_over(search: NDArray[np.uint8], pixels: FloatArray, grid: NDArray[np.intp]) -> NDArray[np.uint8]:
    """``search`` with a board's corners' hull, grown by one of its squares (median), filled with its median grey."""
    mask = _grown_hull(search.shape, pixels, float(np.ceil(np.median(_neighbour_spacing(pixels, grid)))))
    out: NDArray[np.uint8] = search.copy()
    out[mask > 0] = _median_grey(search)
    return out


def _median_grey(grey: NDArray[np.uint8]) -> np.uint8:
    """The median grey level of ``grey`` (any shape, uint8, not empty), as ``np.uint8(np.median(grey))`` gives it (of
    an even count, the mean of the two middle levels, truncated), from its histogram: a fifth of the sort's time on a
    VMR picture (6 ms), once for every board painted over."""
    cumulative = np.cumsum(np.bincount(grey.ravel(), minlength=256))
    low = int(np.searchsorted(cumulative, (grey.size - 1) // 2, side="right"))
    high = int(np.searchsorted(cumulative, grey.size // 2, side="right"))
    return np.uint8((low + high) / 2)


def _grown_hull(shape: tuple[int, ...], pixels: FloatArray, grow_px: float) -> NDArray[np.uint8]:
    """A mask (H, W) uint8 of the convex hull of ``pixels`` (n, 2) px grown by ``grow_px`` (1 inside, 0 outside)."""
    hull = np.zeros(shape, dtype=np.uint8)
    cv2.fillConvexPoly(hull, cv2.convexHull(np.round(pixels).astype(np.int32)), 1)
    size = 2 * int(np.ceil(grow_px)) + 1
    grown: NDArray[np.uint8] = np.asarray(cv2.dilate(hull, np.ones((size, size), np.uint8)), dtype=np.uint8)
    return grown


def _neighbour_spacing(pixels: FloatArray, grid: NDArray[np.intp]) -> FloatArray:
    """Each corner's distance (px) to its nearest neighbour on the grid (places ``grid`` (n, 2), from 0), (n,)."""
    columns, rows = int(grid[:, 0].max()) + 1, int(grid[:, 1].max()) + 1
    placed = np.full((rows, columns, 2), np.nan)
    placed[grid[:, 1], grid[:, 0]] = pixels
    nearest = np.full((rows, columns), np.inf)
    along = np.nan_to_num(np.linalg.norm(np.diff(placed, axis=1), axis=2), nan=np.inf)
    across = np.nan_to_num(np.linalg.norm(np.diff(placed, axis=0), axis=2), nan=np.inf)
    nearest[:, :-1] = np.minimum(nearest[:, :-1], along)
    nearest[:, 1:] = np.minimum(nearest[:, 1:], along)
    nearest[:-1, :] = np.minimum(nearest[:-1, :], across)
    nearest[1:, :] = np.minimum(nearest[1:, :], across)
    out: FloatArray = nearest[grid[:, 1], grid[:, 0]]
    return out


def _refine(grey: NDArray[np.uint8], pixels: FloatArray, grid: NDArray[np.intp]) -> FloatArray:
    """Corners refined by the saddle of the grey levels (``cornerSubPix``) where their squares are large enough.

    The window reaches a quarter of the way to the nearest corner; where that is under ``MIN_WINDOW_PX`` the
    window holds too few pixels of the four squares' edges and the detector's own estimate is kept.
    """
    half = _windows(grey, pixels, grid)
    out = pixels.copy()
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 40, 0.01)
    for size in np.unique(np.clip(half[half >= MIN_WINDOW_PX], MIN_WINDOW_PX, MAX_WINDOW_PX)):
        these = np.clip(half, MIN_WINDOW_PX, MAX_WINDOW_PX) == size
        these &= half >= MIN_WINDOW_PX
        corners = pixels[these].astype(np.float32).reshape(-1, 1, 2)
        refined = cv2.cornerSubPix(grey, corners, (int(size), int(size)), (-1, -1), criteria)
        out[these] = refined.reshape(-1, 2)
    return out


def _windows(grey: NDArray[np.uint8], pixels: FloatArray, grid: NDArray[np.intp]) -> FloatArray:
    """The half-width (px, (n,)) of each corner's refining window: a quarter of the way to its nearest corner on the
    grid, within the image."""
    half = np.floor(_neighbour_spacing(pixels, grid) / 4.0)
    height, width = grey.shape
    margin = np.minimum.reduce([pixels[:, 0], pixels[:, 1], width - 1 - pixels[:, 0], height - 1 - pixels[:, 1]])
    out: FloatArray = np.minimum(half, np.floor(margin) - 1.0)  # the window stays inside the image
    return out
