"""Families of parallel lines: the planes of lines of one direction share that direction.

Convention: unit plane normals and directions in the camera's axes (:mod:`.rays`).

Lines of one world direction V (a room's vertical edges, a checkerboard's rows) have planes
through the viewpoint whose normals are all perpendicular to V. A linear map of the rays keeps
that (it maps V's family to A V's), so families are found even under a camera that is still wrong;
what the map breaks is the angle between two families' directions, which is how their
orthogonality (a room's walls and edges, a board's rows and columns) fixes the elevation scale
that straightness alone leaves nearly free.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ...geometry import FloatArray

# A line belongs to a family when its normal is within this angle of perpendicular to the direction.
FAMILY_TOLERANCE_RAD = float(np.radians(1.5))
# Fewest lines that make a family.
FAMILY_MIN_LINES = 3
# Most families looked for in one image (a room: the vertical and two horizontal directions).
FAMILY_MAX = 3
# Two families whose directions are within this angle of perpendicular are taken to be orthogonal.
ORTHOGONAL_WITHIN_RAD = float(np.radians(12.0))


@dataclass(frozen=True)
class Family:
    """Lines of one direction in one image.

    Attributes
    ----------
    members : (k,) int
        Indices of the lines.
    image_index : int
    direction : (3,) float64
        The common direction (unit), in the camera's axes.
    """

    members: NDArray[np.intp]
    image_index: int
    direction: FloatArray


def common_direction(normals: FloatArray) -> FloatArray:
    """The unit direction (3,) most nearly perpendicular to every normal (k, 3)."""
    _, vectors = np.linalg.eigh(normals.T @ normals)
    direction = vectors[:, 0]
    return np.asarray(direction if direction[2] >= 0 else -direction, dtype=np.float64)


def find_families(normals: FloatArray, image_index: NDArray[np.intp]) -> list[Family]:
    """Families of the lines with unit plane ``normals`` (L, 3), found in each image on its own.

    Greedy consensus: the direction perpendicular to the most normals (tried: the cross product of
    every pair) takes its lines, then again among the rest, up to ``FAMILY_MAX`` per image.
    """
    families = []
    for image in np.unique(image_index):
        free = np.flatnonzero(image_index == image)
        for _ in range(FAMILY_MAX):
            if free.size < FAMILY_MIN_LINES:
                break
            members = _largest_family(normals[free])
            if members.size < FAMILY_MIN_LINES:
                break
            chosen = free[members]
            families.append(Family(chosen, int(image), common_direction(normals[chosen])))
            free = np.setdiff1d(free, chosen)
    return _exclusive(families, normals)


def _exclusive(families: list[Family], normals: FloatArray) -> list[Family]:
    """The families without the lines whose plane holds another family's direction too (which is theirs is
    not known: a vertical edge straight ahead of a horizontal family), and with too few lines left dropped.
    """
    out = []
    for k, family in enumerate(families):
        others = [f.direction for j, f in enumerate(families) if j != k and f.image_index == family.image_index]
        members = family.members
        if others:
            near = np.abs(normals[members] @ np.array(others).T) < np.sin(2 * FAMILY_TOLERANCE_RAD)
            members = members[~near.any(axis=1)]
        if members.size >= FAMILY_MIN_LINES:
            out.append(Family(members, family.image_index, common_direction(normals[members])))
    return out


def _largest_family(normals: FloatArray) -> NDArray[np.intp]:
    """Indices of the most normals perpendicular (within tolerance) to one direction."""
    first, second = np.triu_indices(len(normals), k=1)
    directions = np.cross(normals[first], normals[second])
    length = np.linalg.norm(directions, axis=1)
    keep = length > np.sin(4 * FAMILY_TOLERANCE_RAD)  # two nearly equal planes fix no direction
    if not keep.any():
        return np.zeros(0, dtype=np.intp)
    directions = directions[keep] / length[keep, None]
    close = np.abs(normals @ directions.T) < np.sin(FAMILY_TOLERANCE_RAD)
    best = int(np.argmax(close.sum(axis=0)))
    members = np.flatnonzero(close[:, best])
    refined = common_direction(normals[members])
    return np.flatnonzero(np.abs(normals @ refined) < np.sin(FAMILY_TOLERANCE_RAD))


def orthogonal_pairs(families: list[Family], within_rad: float = ORTHOGONAL_WITHIN_RAD) -> list[tuple[int, int]]:
    """Pairs of families (indices) of one image whose directions are within ``within_rad`` of perpendicular."""
    pairs = []
    for a in range(len(families)):
        for b in range(a + 1, len(families)):
            same_image = families[a].image_index == families[b].image_index
            cosine = abs(float(families[a].direction @ families[b].direction))
            if same_image and cosine < np.sin(within_rad):
                pairs.append((a, b))
    return pairs
