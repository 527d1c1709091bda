"""The lines' fit (``fit --image`` with fewer than three boards) reads the tilt from the room, not a board.

Truth in closed form: a box room's edges and a checkerboard's rows, columns and paper edges, projected
through a simulated fisheye (equidistant, 960 x 960) mounted 2.0 deg off the vertical, with 0.3 px of noise.
The board (10 x 7 inner corners, 3.5 cm squares, 0.7 m away) is held with its rows leaning 8 deg off the
world's vertical: its 11 rows and paper edges are one family within 12 deg of the axis that outnumbers the
room's 7 vertical edges. In a second picture of the same camera the room alone.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from panomap.calibrate.boards.detect import Board as FoundBoard
from panomap.calibrate.boards.off_board import on_boards
from panomap.calibrate.lines.arcs import EdgeArc
from panomap.calibrate.lines.families import Family
from panomap.calibrate.lines.fit import fit_lines
from panomap.calibrate.lines.vertical import vertical_family
from panomap.simulate.board_scenes import Board
from panomap.simulate.cameras import TiltedCamera, mount_rotation, standard_cameras

from helpers import true_circles

TILT_DEG, LEAN_DEG = 2.0, 8.0
ROOM = ((-2.6, 3.1), (-2.2, 2.4), (-1.3, 1.5))
CAMERA = TiltedCamera(standard_cameras((960, 960))["equidistant"], mount_rotation(math.radians(TILT_DEG), 0.5))


def room_segments() -> list[np.ndarray]:
    """The room's edges, a door's and the floor's tiles: (2, 3) ends, m. Its verticals: 4 corners, 3 door edges."""
    (x0, x1), (y0, y1), (z0, z1) = ROOM
    out = [np.array([(x, y, z0), (x, y, z1)]) for x in (x0, x1) for y in (y0, y1)]
    out += [np.array([(x1, y, z0), (x1, y, 0.8)]) for y in (-1.0, 0.5, 1.5)]
    for z in (z0, z1):
        out += [np.array([(x, y0, z), (x, y1, z)]) for x in (x0, x1)] + [
            np.array([(x0, y, z), (x1, y, z)]) for y in (y0, y1)
        ]
    out += [np.array([(t, y0, z0), (t, y1, z0)]) for t in np.arange(-2.0, 2.5, 0.5)]
    out += [np.array([(x0, t, z0), (x1, t, z0)]) for t in np.arange(-2.0, 2.0, 0.5)]
    return out


def held_board() -> Board:
    """The board 0.7 m away toward azimuth 200 deg, 25 deg below the horizon, facing the camera, its rows (x)
    leaning LEAN_DEG off the vertical sideways."""
    az, el = math.radians(200.0), math.radians(-25.0)
    towards = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    lean = math.radians(LEAN_DEG)
    x = math.cos(lean) * np.array([0.0, 0.0, 1.0]) + math.sin(lean) * np.array([-math.sin(az), math.cos(az), 0.0])
    z = towards - (towards @ x) * x
    z /= np.linalg.norm(z)
    rotation = np.stack([x, np.cross(z, x), z], axis=1)
    square = 0.035
    return Board(10, 7, square, rotation, towards * 0.7 - rotation @ np.array([4.5 * square, 3.0 * square, 0.0]))


def board_segments(board: Board) -> list[np.ndarray]:
    """The checker's rows and columns (its outer squares' edges too) and the paper's edges along its rows."""
    cols, rows = board.cols, board.rows
    ends = [[(-1, j), (cols, j)] for j in range(-1, rows + 1)] + [[(i, -1), (i, rows)] for i in range(-1, cols + 1)]
    ends += [[(-2, j), (cols + 1, j)] for j in (-2, rows + 1)]
    return [board.points(np.array(e, dtype=np.float64) * board.square) for e in ends]


def arcs_of(segments: list[np.ndarray], image_index: int, rng: np.random.Generator) -> list[EdgeArc]:
    """Each segment's visible stretch, points 1 px apart, 0.3 px noise."""
    arcs = []
    for start, end in segments:
        t = np.linspace(0.0, 1.0, 3000)[:, None]
        pixels = CAMERA.project(start * (1 - t) + end * t)
        pixels = pixels[np.all(np.isfinite(pixels), axis=1)]
        if len(pixels) < 30:
            continue
        along = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pixels, axis=0).T))])
        steps = np.arange(0.0, along[-1], 1.0)
        points = np.stack([np.interp(steps, along, pixels[:, 0]), np.interp(steps, along, pixels[:, 1])], axis=-1)
        if len(points) >= 30:
            arcs.append(EdgeArc(points + rng.normal(0.0, 0.3, points.shape), image_index, 50.0))
    return arcs


def test_a_boards_rows_count_for_no_vertical_family() -> None:
    """In closed form: the lines' true planes; the board's family leans LEAN_DEG, the room's is the vertical."""
    up = np.array([0.0, 0.0, 1.0])
    board = held_board()
    room = [np.cross(up, np.array([x, y, 0.0])) for x, y in ((1, 0), (0, 1), (1, 1), (1, -1))]  # 4 verticals
    rows = [np.cross(board.rotation[:, 0], board.points(np.array([[0.0, j * board.square]]))[0]) for j in range(9)]
    normals = np.array([n / np.linalg.norm(n) for n in [*room, *rows]])
    families = [Family(np.arange(4), 0, up), Family(np.arange(4, 13), 0, up)]
    groups = [[k] for k in range(13)]
    taken, count = vertical_family(families, normals, groups)  # the board's 9 lines win
    assert count == 9 and math.degrees(math.acos(abs(taken[2]))) == pytest.approx(LEAN_DEG, abs=1e-6)
    taken, count = vertical_family(families, normals, groups, on_board=range(4, 13))
    assert count == 4 and abs(taken[2]) == pytest.approx(1.0, abs=1e-12)


@pytest.mark.slow
def test_the_lines_fit_reads_the_tilt_from_the_room_not_the_board() -> None:
    """The arcs on the board (:func:`on_boards`, as ``learn_camera`` gives them) make straight lines, no vertical.

    Measured: with the board's lines counted, 13 lines gave a tilt of 7.4 deg; without, the room's 7: 1.86 deg.
    """
    rng = np.random.default_rng(1)
    board = held_board()
    found = FoundBoard(0, CAMERA.project(board.corners), board.grid.astype(np.intp))
    room, on_paper = arcs_of(room_segments(), 0, rng), arcs_of(board_segments(board), 0, rng)
    arcs = [*room, *on_paper, *arcs_of(room_segments(), 1, rng)]
    on_board = on_boards(arcs, [found])
    # the checker's lines, none of the room's (the paper's edges lie on the region's border)
    assert (
        set(range(len(room), len(room) + len(on_paper) - 2))
        <= on_board
        <= set(range(len(room), len(room) + len(on_paper)))
    )
    fit = fit_lines(arcs, true_circles(CAMERA), on_board=on_board)
    assert fit.report.vertical_lines <= 7
    assert math.degrees(fit.model.tilt[0]) == pytest.approx(TILT_DEG, abs=0.3)
