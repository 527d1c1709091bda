"""The world's vertical among a fit's families of parallel lines, a checkerboard's own lines left out.

Convention: unit plane normals and directions in the camera's axes (:mod:`.rays`).

The family within ``VERTICAL_WITHIN_DEG`` of the axis with most lines is the room's vertical edges and gives
the tilt. A checkerboard is held tilted any way its holder likes: its rows are a dozen parallel lines that
may fall within that angle and outnumber the room's few verticals, so lines all of whose arcs lie on a board
of their picture (:func:`panomap.calibrate.boards.off_board.on_boards`) count for no family here.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Sequence

import numpy as np

from ...geometry import FloatArray
from .families import FAMILY_MIN_LINES, Family, common_direction

# A family whose direction is within this angle of the optical axis is the world's vertical (it gives the
# tilt); a checkerboard's rows held at an angle are not.
VERTICAL_WITHIN_DEG = 12.0


def vertical_family(
    families: Sequence[Family], normals: FloatArray, groups: Sequence[Sequence[int]], on_board: Collection[int] = ()
) -> tuple[FloatArray, int] | None:
    """The world's vertical (3,) and how many lines show it, or None.

    ``families`` index lines whose plane ``normals`` (L, 3) one camera gives; ``groups[line]`` are the arcs
    merged into each line; a line whose arcs are all in ``on_board`` (arc indices) is left out, and a family
    left with fewer than ``FAMILY_MIN_LINES`` lines with it. Each family's direction is that of its lines kept.
    """
    best: tuple[FloatArray, int] | None = None
    for family in families:
        members = np.array([m for m in family.members if not set(groups[m]) <= set(on_board)], dtype=np.intp)
        if members.size < FAMILY_MIN_LINES:
            continue
        direction = common_direction(normals[members])
        if abs(direction[2]) > math.cos(math.radians(VERTICAL_WITHIN_DEG)) and (best is None or members.size > best[1]):
            best = (direction, int(members.size))
    return best
