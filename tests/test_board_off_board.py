"""The tilt is read from edges off the checkerboards: a board's own lines (held tilted any way) are left out.

Truth in closed form: a board of 9 x 7 inner corners, squares of 20 px, turned 30 deg in its image, and arcs
placed along its rows, along its outer edge (a square and a half beyond its last inner corners: its paper),
beyond its border (three squares out), and at the same place in another image.
"""

from __future__ import annotations

import math

import numpy as np

from panomap.calibrate.boards.detect import Board
from panomap.calibrate.boards.off_board import MARGIN_SQUARES, arcs_off_boards
from panomap.calibrate.lines.arcs import EdgeArc

SQUARE_PX, TURN_RAD, ORIGIN = 20.0, math.radians(30.0), np.array([300.0, 200.0])
ALONG = np.array([math.cos(TURN_RAD), math.sin(TURN_RAD)])  # the board's rows in the image
ACROSS = np.array([-math.sin(TURN_RAD), math.cos(TURN_RAD)])  # its columns


def board(image_index: int = 0) -> Board:
    grid = np.array([(c, r) for r in range(7) for c in range(9)], dtype=np.intp)
    pixels = ORIGIN + SQUARE_PX * (grid[:, :1] * ALONG + grid[:, 1:] * ACROSS)
    return Board(image_index, pixels, grid)


def arc_along(rows_squares: float, image_index: int = 0) -> EdgeArc:
    """A straight arc parallel to the board's rows, ``rows_squares`` squares below its first row of corners,
    from a square before its first column to a square after its last."""
    t = np.linspace(-1.0, 9.0, 40)[:, None] * SQUARE_PX
    return EdgeArc(ORIGIN + t * ALONG + rows_squares * SQUARE_PX * ACROSS, image_index, 30.0)


def test_a_boards_own_lines_and_edges_are_left_out_and_the_rest_kept() -> None:
    on_rows = [arc_along(float(r)) for r in range(7)]
    paper_edge = arc_along(6 + 1.5)  # within MARGIN_SQUARES of the last row: the board's border
    beyond = arc_along(6 + MARGIN_SQUARES + 1.0)  # a square past the margin: the room
    elsewhere = arc_along(3.0, image_index=1)  # the same place in another picture, where no board is
    kept = arcs_off_boards([*on_rows, paper_edge, beyond, elsewhere], [board(0)])
    assert [id(a) for a in kept] == [id(beyond), id(elsewhere)]
    # Without boards every arc stands.
    assert len(arcs_off_boards(on_rows, [])) == len(on_rows)
