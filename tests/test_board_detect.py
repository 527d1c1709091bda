"""The checkerboards found in rendered omni-images (``find_boards``) against their true corners.

The truth is ``camera.project`` of each inner corner's 3-D point (:mod:`panomap.simulate.board_scenes`);
the detector sees only the rendered image (vignetting, noise, JPEG). Each found corner is matched to the
nearest true corner of any board; a board is right when each of its corners matches a different true corner
within a fraction of a pixel and its grid places are the true board's up to a quarter turn or a flip (the
detector cannot know which corner is the board's first).
"""

from __future__ import annotations

from collections.abc import Iterator

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from panomap.calibrate.boards import detect
from panomap.calibrate.boards.detect import Board as Found
from panomap.calibrate.boards.detect import find_boards
from panomap.simulate.board_scenes import Board as TrueBoard
from panomap.simulate.board_scenes import BoardScene, board_poses, render_board_scene
from panomap.simulate.cameras import standard_cameras
from panomap.simulate.line_scenes import line_camera


def matched(found: Found, scene: BoardScene) -> tuple[int, NDArray[np.float64], NDArray[np.int64]]:
    """The true board ``found`` lies on (the one most of its corners are nearest), each corner's distance (px)
    to its nearest true corner of that board, and that corner's true grid place (n, 2)."""
    best = None
    for k, truth in enumerate(scene.truth):
        distance = np.linalg.norm(found.pixels[:, None, :] - truth.pixels[None, :, :], axis=2)
        distance[np.isnan(distance)] = np.inf  # corners the camera does not see
        nearest = np.argmin(distance, axis=1)
        error = distance[np.arange(len(nearest)), nearest]
        if best is None or np.median(error) < np.median(best[1]):
            best = (k, error, truth.grid[nearest])
    assert best is not None
    return best


def assert_grid_is_the_boards(found: Found, true_grid: NDArray[np.int64]) -> None:
    """The found grid places map to the true ones by a quarter turn or a flip and a shift, exactly."""
    design = np.column_stack([found.grid.astype(np.float64), np.ones(len(found.grid))])
    solution, *_ = np.linalg.lstsq(design, true_grid.astype(np.float64), rcond=None)
    turn = solution[:2].T
    np.testing.assert_allclose(design @ solution, true_grid, atol=1e-9)
    np.testing.assert_allclose(np.abs(turn), np.round(np.abs(turn)), atol=1e-9)
    assert abs(abs(np.linalg.det(turn)) - 1.0) < 1e-9


@pytest.fixture(scope="module")
def mirror_pair() -> BoardScene:
    """Two boards (8 x 5 and 7 x 6 inner corners, squares 11-15 px) before a tilted hyperbolic mirror camera,
    800 x 600: squares this small are placed by the detector's upsampling on a crop (no window for cornerSubPix)."""
    camera = line_camera("hyperbolic", 0.5, tilt_deg=2.0)
    return render_board_scene(camera, board_poses(camera, 2, seed=30), seed=0, supersample=2)


def test_both_boards_are_found_whole_on_their_true_corners(mirror_pair: BoardScene) -> None:
    """Measured: both boards whole, nothing else; corners median 0.07, max 0.30 px from the truth (the
    detector's upsampled corners; without the upsampling the same boards' corners p90 0.13-0.15 px)."""
    found = find_boards(mirror_pair.image)
    assert len(found) == 2
    onto = set()
    for board in found:
        k, error, true_grid = matched(board, mirror_pair)
        onto.add(k)
        truth = mirror_pair.boards[k]
        assert sorted(board.shape) == sorted((truth.cols, truth.rows))
        assert len(np.unique(true_grid, axis=0)) == len(true_grid), "two corners on one true corner"
        assert_grid_is_the_boards(board, true_grid)
        assert np.median(error) < 0.15 and error.max() < 0.6, (np.median(error), error.max())
    assert onto == {0, 1}


def upsampled_over_the_whole_image(grey: NDArray[np.uint8], board: Found, others: list[Found]) -> NDArray[np.float64]:
    """A board's corners as the search before this one placed them: the detector with its upsampling
    (``CALIB_CB_ACCURACY``) over the whole image (the other boards painted over), refined as find_boards refines
    them; in the order of ``board.pixels``."""
    search = grey.copy()
    for other in others:
        search = detect._painted_over(search, other.pixels, other.grid)
    columns, rows = board.shape
    flags = cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY
    cv2.setRNGSeed(detect.RNG_SEED)
    found, corners = cv2.findChessboardCornersSB(search, (columns, rows), flags=flags)
    assert found
    refined = detect._refine(grey, corners.reshape(-1, 2).astype(np.float64), detect._rectangle(columns, rows))
    distance = np.linalg.norm(board.pixels[:, None, :] - refined[None, :, :], axis=2)
    nearest = np.argmin(distance, axis=1)
    assert len(np.unique(nearest)) == len(nearest), "two corners on one"
    out: NDArray[np.float64] = refined[nearest]
    return out


def test_corners_are_the_exhaustive_searchs(mirror_pair: BoardScene) -> None:
    """The search without the upsampling, the corners placed with it on a crop round each board: the corners of
    the upsampled detector over the whole image, the same (to cornerSubPix's 0.01 px) where it refines them
    (squares of 16 px or more) and within a tenth of a pixel where the squares are smaller and the detector's own
    estimate is kept (measured: 0.094 px at most, median 0.000)."""
    found = find_boards(mirror_pair.image)
    assert len(found) == 2
    for k, board in enumerate(found):
        before = upsampled_over_the_whole_image(mirror_pair.image, board, found[:k] + found[k + 1 :])
        distance = np.linalg.norm(board.pixels - before, axis=1)
        refined = detect._windows(mirror_pair.image, board.pixels, board.grid) >= detect.MIN_WINDOW_PX
        assert np.all(distance[refined] < 0.01)  # cornerSubPix stops at steps under 0.01 px
        assert np.median(distance) < 0.01 and distance.max() < 0.12, (np.median(distance), distance.max())


def test_a_board_tiled_over_the_frame_is_found_whole() -> None:
    """A 40 x 40 board filling an 800 x 800 equidistant fisheye's frame (1,576 inner corners in it): the detector
    grows its grid to about PATTERN_CORNERS and stops; the rest is grown from it corner by corner (_grown), to
    where the squares, squeezed at the rim, are too thin to tell. Measured: one board, 1,103 corners on as many
    true ones, its grid the true grid, median 0.14 px, p99 0.65 px, max 2.2 px (at the rim, where rendering
    one ray per pixel blurs the squares' edges) from the truth."""
    camera = standard_cameras((800, 800), outer_radius=800 * 1131.0 / 1600)["equidistant"]
    columns, square, below = 40, 0.05, 0.4
    # flat under the camera, which looks down: the board's x along the image's u, its y along v
    turn = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
    corner = np.array([-(columns - 1) / 2 * square, (columns - 1) / 2 * square, -below])
    scene = render_board_scene(camera, (TrueBoard(columns, columns, square, turn, corner),), seed=3, supersample=2)
    found = find_boards(scene.image)
    assert len(found) == 1
    board = found[0]
    assert len(board.pixels) >= 2 * detect.PATTERN_CORNERS
    _, error, true_grid = matched(board, scene)
    assert len(np.unique(true_grid, axis=0)) == len(true_grid), "two corners on one true corner"
    assert_grid_is_the_boards(board, true_grid)
    assert np.median(error) < 0.2 and np.percentile(error, 99) < 0.8 and error.max() < 3.0


def test_a_later_search_looks_at_the_image_halved_first(mirror_pair: BoardScene) -> None:
    """Once a board is found, the search for another (_looked) asks the detector on the image halved first: where
    that shows a grid, the result is the full search's own (the same corners, bit for bit); with both boards
    painted over, nothing (the full search, which finds nothing there either, is not run)."""
    image = mirror_pair.image
    grey = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    looked = detect._looked(grey)
    full = detect._largest(grey, detect.LATER_SEEDS, give_up=True)
    assert looked is not None and full is not None
    np.testing.assert_array_equal(looked[0], full[0])
    assert looked[1] == full[1]
    painted = grey
    for board in find_boards(image):
        painted = detect._painted_over(painted, board.pixels, board.grid)
    assert detect._looked(painted) is None
    assert detect._largest(painted, detect.LATER_SEEDS, give_up=True) is None


def test_images_searched_in_threads_give_each_images_boards(mirror_pair: BoardScene) -> None:
    """find_boards_each in two threads: each image's boards as find_boards finds them alone, bit for bit (OpenCV's
    generator, seeded before each search, is its thread's own), in the images' order, with their indices."""
    images = [mirror_pair.image, np.ascontiguousarray(mirror_pair.image[::-1]), mirror_pair.image[:, ::-1].copy()]
    threaded = list(detect.find_boards_each(images, threads=2))
    assert len(threaded) == len(images)
    for k, (image, boards) in enumerate(zip(images, threaded, strict=True)):
        alone = find_boards(image, k)
        assert len(boards) == len(alone) == 2
        for board, single in zip(boards, alone, strict=True):
            assert board.image_index == k
            np.testing.assert_array_equal(board.pixels, single.pixels)
            np.testing.assert_array_equal(board.grid, single.grid)


@pytest.fixture(scope="module")
def one_board_pictures() -> list[BoardScene]:
    """Three pictures of one 9 x 6 board each (inner corners) in three poses before mirror_pair's camera."""
    camera = line_camera("hyperbolic", 0.5, tilt_deg=2.0)
    return [
        render_board_scene(camera, board_poses(camera, 1, seed=40 + k, sizes=((9, 6),)), seed=k, supersample=2)
        for k in range(3)
    ]


def test_the_board_learned_from_the_first_pictures_is_the_true_one(one_board_pictures: list[BoardScene]) -> None:
    """The first LEARN_PICTURES pictures each show one whole board: its size is learned, the true 6 x 9; the later
    picture, searched for one board of that size only, gives the boards find_boards gives it alone, bit for bit."""
    images = [scene.image for scene in one_board_pictures]
    found = list(detect.find_boards_each(images, threads=1))
    assert detect.learned_size(found[: detect.LEARN_PICTURES]) == (6, 9)
    for k, (scene, boards) in enumerate(zip(one_board_pictures, found, strict=True)):
        alone = find_boards(scene.image, k)
        assert len(boards) == len(alone) == 1
        np.testing.assert_array_equal(boards[0].pixels, alone[0].pixels)
        _, error, _ = matched(boards[0], scene)
        assert np.median(error) < 0.15, np.median(error)  # on the true corners (the detector's accuracy, as above)


def test_a_later_picture_whose_board_is_of_another_size_is_searched_in_full(
    one_board_pictures: list[BoardScene], mirror_pair: BoardScene
) -> None:
    """After two pictures of a 9 x 6 board, a picture of an 8 x 5 and a 7 x 6 board: the one board first found is
    of another size, so the picture is searched in full and both are found (as find_boards finds them); where the
    first pictures show two boards, no size is learned."""
    images = [one_board_pictures[0].image, one_board_pictures[1].image, mirror_pair.image]
    found = list(detect.find_boards_each(images, threads=2))
    assert len(found[2]) == 2
    for board, alone in zip(found[2], find_boards(mirror_pair.image, 2), strict=True):
        np.testing.assert_array_equal(board.pixels, alone.pixels)
    assert detect.learned_size([found[2], found[0]]) is None
    assert detect.learned_size(found[:1]) is None  # one picture is not enough


def test_a_picture_searched_in_full_after_its_first_board_is_not_searched_again(
    mirror_pair: BoardScene, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A later picture whose first board is of another size than the learned one: the search goes on from that
    board (one first search of every seed, not two: on the real Kaidan set, half of one picture's 1 s), and gives
    find_boards' boards, bit for bit."""
    alone = find_boards(mirror_pair.image, 2)
    searches = []
    largest = detect._largest

    def counted(search: NDArray[np.uint8], seeds: tuple[tuple[int, int], ...], give_up: bool = False):  # type: ignore[no-untyped-def]
        searches.append(seeds)
        return largest(search, seeds, give_up)

    monkeypatch.setattr(detect, "_largest", counted)
    found = detect._one_board(mirror_pair.image, 2, size=(6, 9))
    assert searches.count(detect.SEEDS) == 1
    assert len(found) == len(alone) == 2
    for board, single in zip(found, alone, strict=True):
        np.testing.assert_array_equal(board.pixels, single.pixels)
        np.testing.assert_array_equal(board.grid, single.grid)


@pytest.fixture(scope="module")
def pair() -> BoardScene:
    """Two 9 x 6 boards (inner corners) before mirror_pair's camera."""
    camera = line_camera("hyperbolic", 0.5, tilt_deg=2.0)
    return render_board_scene(camera, board_poses(camera, 2, seed=50, sizes=((9, 6),)), seed=3, supersample=2)


def test_a_later_picture_with_two_boards_of_the_size_gives_both(
    one_board_pictures: list[BoardScene], pair: BoardScene
) -> None:
    """After two pictures of a 9 x 6 board, a picture of two 9 x 6 boards: the quick detector told the size sees the
    second with the first painted over, so the picture is searched in full: both boards, as find_boards finds them,
    each on its true board (the quick detector sees the second board on 11 of 12 such renders: see _one_board)."""
    images = [one_board_pictures[0].image, one_board_pictures[1].image, pair.image]
    found = list(detect.find_boards_each(images, threads=1))
    assert len(found[2]) == 2
    onto = set()
    for board, alone in zip(found[2], find_boards(pair.image, 2), strict=True):
        np.testing.assert_array_equal(board.pixels, alone.pixels)
        k, error, _ = matched(board, pair)
        onto.add(k)
        assert np.median(error) < 0.15, np.median(error)
    assert onto == {0, 1}


def test_a_second_picture_with_two_boards_of_the_size_gives_both(
    one_board_pictures: list[BoardScene], pair: BoardScene
) -> None:
    """After a picture of one 9 x 6 board (beyond doubt), a picture of two: the second picture's first board is of the
    size, and the quick detector told it sees the other with the first painted over, so the search goes on: both
    boards, as find_boards finds them, bit for bit; no size is learned, and the third picture is searched in full."""
    images = [one_board_pictures[0].image, pair.image, one_board_pictures[2].image]
    found = list(detect.find_boards_each(images, threads=2))
    assert detect._bounded_size(images[0], found[0][0]) == (6, 9)
    for k, count in ((1, 2), (2, 1)):
        alone = find_boards(images[k], k)
        assert len(found[k]) == len(alone) == count
        for board, single in zip(found[k], alone, strict=True):
            np.testing.assert_array_equal(board.pixels, single.pixels)
    assert {matched(board, pair)[0] for board in found[1]} == {0, 1}


def test_a_first_picture_with_two_boards_has_the_later_ones_searched_in_full(
    one_board_pictures: list[BoardScene], pair: BoardScene, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The first picture shows two 9 x 6 boards, the second one: the second picture, whose look for another board was
    the quick detector's (its first board of the first one's first board's size, _bounded_size), and the later ones
    are searched again in full (find_boards) once the first picture shows its second: no size is learned from it."""
    searched_in_full = []
    find = detect.find_boards

    def counted(image: NDArray[np.uint8], image_index: int = 0, max_boards: int = detect.MAX_BOARDS) -> list[Found]:
        searched_in_full.append(image_index)
        return find(image, image_index, max_boards)

    monkeypatch.setattr(detect, "find_boards", counted)
    images = [pair.image, one_board_pictures[0].image, one_board_pictures[2].image]
    found = list(detect.find_boards_each(images, threads=2))
    assert [len(boards) for boards in found] == [2, 1, 1]
    assert detect._bounded_size(images[0], found[0][0]) == (6, 9)
    assert searched_in_full == [1, 2]
    for k in (1, 2):
        np.testing.assert_array_equal(found[k][0].pixels, find(images[k], k)[0].pixels)


@pytest.fixture(scope="module")
def board_over_floor() -> BoardScene:
    """A 9 x 6 board (inner corners) before an 800 x 800 equidistant fisheye, a dark shape against its edge, over
    the room's checkered floor."""
    camera = standard_cameras((800, 800), outer_radius=400)["equidistant"]
    boards = board_poses(camera, 1, seed=71, sizes=((9, 6),), min_square_px=18)
    return render_board_scene(camera, boards, seed=71, supersample=2, background="lines")


def test_a_board_before_a_dark_shape_and_a_checkered_floor_gives_its_inner_corners_only(
    board_over_floor: BoardScene,
) -> None:
    """A 9 x 6 board before an 800 x 800 equidistant fisheye, a dark shape against its edge, over the room's
    checkered floor: OpenCV's detector grows the board by a row of its outer squares' outer vertices (6 x 10, that
    row a square's width, 25 px, from the nearest inner corner) and runs the floor's texture off the floor (a 6 x 4
    grid); _checked takes the row off and refuses the floor. Measured: one board, 54 corners on the 54 true ones,
    max 0.19 px."""
    scene = board_over_floor
    found = find_boards(scene.image)
    assert [sorted(board.shape) for board in found] == [[6, 9]]
    _, error, true_grid = matched(found[0], scene)
    assert len(np.unique(true_grid, axis=0)) == len(true_grid) == 54
    assert_grid_is_the_boards(found[0], true_grid)
    assert error.max() < 0.5, error.max()


def test_a_grid_a_row_short_of_its_board_is_kept_and_a_row_past_its_edge_taken_off(
    board_over_floor: BoardScene,
) -> None:
    """The true corners of the board less its first row (a row the detector missed): the pattern runs on past that
    edge alone and every corner is a checkerboard's, so the grid is a board's, kept as it is; the same grid with the
    row a square past its last edge (the outer squares' outer vertices, where the detector put the issue's row; no
    checkerboard's corners) loses that row, the rest kept."""
    truth = board_over_floor.truth[0]
    board = board_over_floor.boards[0]
    placed = truth.pixels.reshape(board.rows, board.cols, 2)
    grey = detect._grey(board_over_floor.image)
    short = placed[1:].reshape(-1, 2)
    kept = detect._checked(grey, short, board.cols, board.rows - 1)
    assert kept is not None and kept[1] == (board.rows - 1, board.cols)
    np.testing.assert_array_equal(kept[0], short)
    past = board_over_floor.camera.project(
        board.points(np.column_stack([np.arange(board.cols), np.full(board.cols, board.rows)]) * board.square)
    )
    grown = np.concatenate([placed[1:], past[None]], axis=0)
    trimmed = detect._checked(grey, grown.reshape(-1, 2), board.cols, board.rows)
    assert trimmed is not None and trimmed[1] == (board.rows - 1, board.cols)
    np.testing.assert_array_equal(trimmed[0], short)


@pytest.fixture(scope="module")
def fisheye_pictures() -> list[BoardScene]:
    """Three pictures of a 9 x 6 board (inner corners, squares 18 px or more) through a 190-degree fisheye, 960 x 540:
    squares large enough for the quick detector to stand in for the search (_quick_suits)."""
    camera = line_camera("fisheye190", 0.5)
    return [
        render_board_scene(
            camera, board_poses(camera, 1, seed=80 + k, sizes=((9, 6),), min_square_px=18.0), seed=k, supersample=2
        )
        for k in range(3)
    ]


def test_the_second_pictures_look_for_another_board_is_the_quick_detectors(
    fisheye_pictures: list[BoardScene], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The first picture's board is beyond doubt (_bounded_size) and the second's first board is of its size: the
    second picture's look for another board is the quick detector's (_another), not the search's look at the picture
    halved (one such look, the first picture's, not two), and its board is find_boards' own, bit for bit."""
    images = [scene.image for scene in fisheye_pictures]
    halved = []
    looked = detect._looked

    def counted(search: NDArray[np.uint8]):  # type: ignore[no-untyped-def]
        halved.append(search.shape)
        return looked(search)

    monkeypatch.setattr(detect, "_looked", counted)
    found = list(detect.find_boards_each(images, threads=2))
    assert len(halved) == 1
    assert [[sorted(board.shape) for board in boards] for boards in found] == [[[6, 9]]] * 3
    np.testing.assert_array_equal(found[1][0].pixels, find_boards(images[1], 1)[0].pixels)
    k, error, _ = matched(found[1][0], fisheye_pictures[1])
    assert k == 0 and np.median(error) < 0.15 and error.max() < 0.5, (np.median(error), error.max())


def test_a_second_picture_whose_board_is_partly_hidden_is_searched_in_full(
    fisheye_pictures: list[BoardScene],
) -> None:
    """The second picture's board has its last three columns of corners hidden (painted over, as a hand holding it
    would): its first board (5 x 6) is not of the first picture's size, so the picture is searched in full (as
    find_boards finds it alone, bit for bit), no size is learned, and the third picture is searched in full too."""
    truth = fisheye_pictures[1].truth[0]
    hidden = fisheye_pictures[1].image.copy()
    spacing = float(np.median(np.linalg.norm(np.diff(truth.pixels.reshape(6, 9, 2), axis=1), axis=2)))
    mask = detect._grown_hull(hidden.shape[:2], truth.pixels[truth.grid[:, 0] >= 6], spacing)
    hidden[mask > 0] = np.median(hidden)
    images = [fisheye_pictures[0].image, hidden, fisheye_pictures[2].image]
    found = list(detect.find_boards_each(images, threads=2))
    assert detect._bounded_size(images[0], found[0][0]) == (6, 9)
    for k in (1, 2):
        alone = find_boards(images[k], k)
        assert len(found[k]) == len(alone) == 1
        np.testing.assert_array_equal(found[k][0].pixels, alone[0].pixels)
    assert sorted(found[1][0].shape) == [5, 6]
    _, error, _ = matched(found[1][0], fisheye_pictures[1])
    assert error.max() < 0.5, error.max()


def test_a_grid_a_row_short_of_its_board_is_not_beyond_doubt(board_over_floor: BoardScene) -> None:
    """The true corners of the board less its first row (a row the detector missed): the pattern runs on past that
    edge, so its size is not one the second picture is looked at for (_bounded_size: a 9 x 5 grid of the 9 x 6 board
    would be found there); the whole board's is."""
    truth = board_over_floor.truth[0]
    board = board_over_floor.boards[0]
    short = truth.pixels.reshape(board.rows, board.cols, 2)[1:].reshape(-1, 2)
    image = board_over_floor.image
    assert detect._bounded_size(image, Found(0, short, detect._rectangle(board.cols, board.rows - 1))) is None
    whole = Found(0, truth.pixels, detect._rectangle(board.cols, board.rows))
    assert detect._bounded_size(image, whole) == (6, 9)


@pytest.mark.slow
def test_a_later_picture_found_by_the_quick_detector_is_on_the_true_corners(
    fisheye_pictures: list[BoardScene],
) -> None:
    """Three pictures of a 9 x 6 board (squares 18 px or more) through a 190-degree fisheye: the quick detector told
    the learned size finds the learned pictures' boards, so on the third it stands in for the search (_quick_board;
    its board is the one find_boards_each gives). Measured: the corners median 0.07, max 0.34 px from the truth, as
    the search's; 0.03 px at most from the search's own (seven renders: cornerSubPix stops at steps under 0.01 px,
    from another start). A fourth picture, of the room without the board: the quick detector (told the size, without
    its fast check) finds none, and neither does the search it falls back to."""
    scenes = fisheye_pictures
    empty = render_board_scene(line_camera("fisheye190", 0.5), (), seed=3, supersample=2).image
    images = [scene.image for scene in scenes]
    found = list(detect.find_boards_each([*images, empty], threads=1))
    assert found[3] == []
    found = found[:3]
    size = detect.learned_size(found[: detect.LEARN_PICTURES])
    assert size == (6, 9)
    assert all(detect._quick_suits(image, boards[0], size) for image, boards in zip(images, found, strict=False))
    quick = detect._quick_board(detect._grey(images[2]), 2, size)
    assert quick is not None and len(found[2]) == 1
    np.testing.assert_array_equal(found[2][0].pixels, quick.pixels)  # the quick detector's board, not the search's
    k, error, true_grid = matched(quick, scenes[2])
    assert k == 0 and len(np.unique(true_grid, axis=0)) == len(true_grid)
    assert_grid_is_the_boards(quick, true_grid)
    assert np.median(error) < 0.15 and error.max() < 0.5, (np.median(error), error.max())
    searched = find_boards(images[2], 2)[0].pixels
    moved = np.linalg.norm(quick.pixels[:, None, :] - searched[None, :, :], axis=2).min(axis=1)
    assert moved.max() < 0.05, moved.max()


def test_the_quick_detectors_corners_settle_on_the_true_corners_and_a_start_off_a_saddle_is_refused() -> None:
    """A 9 x 6 board (squares 18 px or more) through a 190-degree fisheye: the quick detector's corners (0.3 px off
    at most) refined in full from where it puts them (_settled) land on the true corners, as the search's do.
    Measured: median 0.055, max 0.17 px from the truth. A corner started on a flat square (cornerSubPix does not
    move it) or on its neighbour's saddle is refused, and the picture is placed on a crop instead."""
    camera = line_camera("fisheye190", 0.5)
    poses = board_poses(camera, 1, seed=81, sizes=((9, 6),), min_square_px=18.0)
    scene = render_board_scene(camera, poses, seed=1, supersample=2)
    grey = detect._grey(scene.image)
    found, corners = cv2.findChessboardCorners(grey, (6, 9), flags=detect.FOUND_FLAGS)
    assert found
    rough = corners.reshape(-1, 2).astype(np.float64)
    grid = detect._rectangle(6, 9)
    assert detect._windows(grey, rough, grid).min() >= detect.MIN_WINDOW_PX  # every corner refined in full
    settled = detect._settled(grey, rough, grid)
    assert settled is not None
    k, error, true_grid = matched(Found(0, settled, grid), scene)
    assert k == 0 and len(np.unique(true_grid, axis=0)) == len(true_grid)
    assert np.median(error) < 0.1 and error.max() < 0.35, (np.median(error), error.max())
    searched = find_boards(scene.image)[0]
    _, search_error, _ = matched(searched, scene)
    assert np.median(error) < np.median(search_error) + 0.01
    on_square = rough.copy()
    on_square[20] += 0.5 * (rough[21] - rough[20]) + 0.5 * (rough[26] - rough[20])  # a square's middle
    assert detect._settled(grey, on_square, grid) is None
    on_neighbour = rough.copy()
    on_neighbour[20] = rough[21]
    assert detect._settled(grey, on_neighbour, grid) is None


def test_a_later_picture_with_small_squares_is_placed_on_a_crop_round_the_quick_detectors_corners() -> None:
    """A 9 x 6 board before a hyperbolic mirror, squares 12-16 px at their smallest: 16 corners' windows are 3 px
    (under MIN_WINDOW_PX: they keep the upsampled placement on the crop, drawn round the quick detector's corners,
    not the search's). Measured: median 0.068, max 0.19 px from the truth, as the search's; 0.022 px at most from
    the search's own corners."""
    camera = line_camera("hyperbolic", 0.75)
    scene = render_board_scene(
        camera, board_poses(camera, 1, seed=62, sizes=((9, 6),), min_square_px=12.0), seed=62, supersample=2
    )
    quick = detect._quick_board(detect._grey(scene.image), 0, (6, 9))
    assert quick is not None
    windows = detect._windows(detect._grey(scene.image), quick.pixels, quick.grid)
    assert windows.min() == detect.QUICK_WINDOW_PX < detect.MIN_WINDOW_PX
    k, error, true_grid = matched(quick, scene)
    assert k == 0 and len(np.unique(true_grid, axis=0)) == len(true_grid)
    assert_grid_is_the_boards(quick, true_grid)
    assert np.median(error) < 0.12 and error.max() < 0.4, (np.median(error), error.max())
    searched = find_boards(scene.image, 0, max_boards=1)[0].pixels
    moved = np.linalg.norm(quick.pixels[:, None, :] - searched[None, :, :], axis=2).min(axis=1)
    assert moved.max() < 0.06, moved.max()


class _Stopped(BaseException):
    """Not an Exception: a search stopped by something beyond the search's own errors."""


def raised_within(images: list[NDArray[np.uint8]], seconds: float) -> list[BaseException]:
    """What ``find_boards_each`` of ``images`` raised, run in a thread given ``seconds`` to end."""
    import threading

    raised: list[BaseException] = []

    def run() -> None:
        try:
            list(detect.find_boards_each(images, threads=2))
        except BaseException as error:
            raised.append(error)

    worker = threading.Thread(target=run, daemon=True)
    worker.start()
    worker.join(timeout=seconds)
    assert not worker.is_alive(), "find_boards_each still waits"
    return raised


def test_a_learned_picture_that_cannot_be_made_grey_is_raised_not_waited_on() -> None:
    """A first picture of two channels: OpenCV refuses to make it grey before its search starts; before, that
    refusal left ``find_boards_each`` waiting for the picture's first board for ever."""
    raised = raised_within([np.zeros((32, 32, 2), np.uint8)] + [np.zeros((32, 32), np.uint8)] * 2, 10)
    assert len(raised) == 1 and isinstance(raised[0], cv2.error)


def test_a_learned_pictures_search_that_stops_is_raised_not_waited_on(monkeypatch: pytest.MonkeyPatch) -> None:
    """``find_boards_each`` waits on each learned picture's first board: a search that stops with any exception,
    not only an Exception, must end that wait and be raised (before, the wait never ended)."""

    def stopped(*_: object) -> Iterator[Found]:  # (a generator, as the search is)
        raise _Stopped
        yield

    monkeypatch.setattr(detect, "_searches", stopped)
    raised = raised_within([np.zeros((32, 32), np.uint8)] * 3, 10)
    assert len(raised) == 1 and isinstance(raised[0], _Stopped)


def test_the_median_grey_is_the_middle_level_of_the_sorted_pixels() -> None:
    """_median_grey (from the histogram) against the sorted pixels' middle (NumPy's median): odd and even counts
    (the mean of the two middle levels, truncated as uint8 truncates), flat images, and a picture-sized one."""
    assert detect._median_grey(np.array([3], np.uint8)) == 3
    assert detect._median_grey(np.array([0, 255], np.uint8)) == 127  # 127.5 truncated
    assert detect._median_grey(np.array([[1, 2], [3, 4]], np.uint8)) == 2  # 2.5 truncated
    assert detect._median_grey(np.array([9, 1, 5], np.uint8)) == 5
    assert detect._median_grey(np.full((7, 9), 200, np.uint8)) == 200
    rng = np.random.default_rng(5)
    for size in [*rng.integers(1, 400, 300), 768 * 1024]:
        levels = rng.integers(0, 256, int(size), dtype=np.uint8)
        middle = np.sort(levels)[[(levels.size - 1) // 2, levels.size // 2]]
        assert detect._median_grey(levels) == np.uint8(middle.astype(np.float64).mean())
        assert detect._median_grey(levels) == np.uint8(np.median(levels))
