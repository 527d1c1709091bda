"""The images' edge arcs that do not lie on a checkerboard: what may show the world's vertical.

A board held before the camera is tilted any way its holder likes: its rows, columns and outer edges are
straight lines in no particular direction, and a board's family of a dozen parallel lines within a few
degrees of the axis outnumbers the room's few true verticals. The tilt of the axis is read from the other
edges only: an arc is left out where most of its points lie on a board of its own image, that is inside
the board's inner corners' convex hull grown by ``MARGIN_SQUARES`` squares (its outer squares, its white
border and the paper's edge).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np

from ...geometry import FloatArray
from ..lines.arcs import EdgeArc
from .detect import Board

MARGIN_SQUARES = 2.0
"""How far beyond its inner corners' hull a board's own edges reach, in squares (its outer row of squares,
its white border and the paper's edge)."""

ON_BOARD_SHARE = 0.5
"""An arc is a board's where more than this share of its points lie on the board."""


def arcs_off_boards(arcs: Sequence[EdgeArc], boards: Sequence[Board]) -> list[EdgeArc]:
    """The ``arcs`` (any images) that lie on no board of their own image (``boards``: inner corners, px)."""
    on = on_boards(arcs, boards)
    return [arc for k, arc in enumerate(arcs) if k not in on]


def on_boards(arcs: Sequence[EdgeArc], boards: Sequence[Board]) -> frozenset[int]:
    """The indices into ``arcs`` of those that lie on a board of their own image (``boards``: inner corners, px).

    A board's region is its inner corners' convex hull (image px) grown by ``MARGIN_SQUARES`` times its
    mean square size there (the square root of the hull's area per corner cell): every edge's half-plane
    moved out by that much (a mitred growth).
    """
    regions: dict[int, list[tuple[FloatArray, FloatArray]]] = {}
    for board in boards:
        columns, rows = board.shape
        if columns < 2 or rows < 2:
            continue
        hull = cv2.convexHull(board.pixels.astype(np.float32))[:, 0, :].astype(np.float64)
        if len(hull) < 3:
            continue
        square_px = math.sqrt(max(float(cv2.contourArea(hull.astype(np.float32))), 1.0) / ((columns - 1) * (rows - 1)))
        edges = np.roll(hull, -1, axis=0) - hull
        normals = np.stack([edges[:, 1], -edges[:, 0]], axis=1) / np.hypot(*edges.T)[:, None]
        offsets = np.sum(normals * hull, axis=1)
        if np.any(normals @ hull.mean(axis=0) > offsets):  # the hull ran the other way: normals inward
            normals, offsets = -normals, -offsets
        regions.setdefault(board.image_index, []).append((normals, offsets + MARGIN_SQUARES * square_px))
    found = set()
    for k, arc in enumerate(arcs):
        on = np.zeros(len(arc.pixels), dtype=bool)
        for normals, limits in regions.get(arc.image_index, []):
            on |= np.all(arc.pixels @ normals.T <= limits, axis=1)
        if on.mean() > ON_BOARD_SHARE:
            found.add(k)
    return frozenset(found)
