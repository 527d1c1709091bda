"""The least-squares objective of the line fit: straightness of every line, orthogonality of families.

Convention: as in :mod:`.rays`. The unknowns are the centre (u0, v0) (px) and the radial model's
coefficients; each line's plane (its two unknowns) is solved inside, in closed form, for the
camera being tried (variable projection: the block :func:`.rays.line_block` at its best plane).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ...camera.radial import RadialFunction
from ...errors import PanomapError
from ...geometry import FloatArray
from .families import Family
from .rays import InverseRadial, PixelRays, best_planes, pixel_rays, plane_distances_px

# A trial camera whose f_r does not rise monotonically over the lines gets this residual (px) everywhere.
INVALID_RESIDUAL_PX = 1e3
# How square the world's right angles are (deg): a room's walls and edges, a board's rows and columns, to a
# few tenths of a degree (under the established calibrations, the real sets' room pairs are 0.1-0.9 deg
# off, their boards' 0.1-0.2 deg). Added to each pair's measured uncertainty.
WORLD_SQUARENESS_DEG = 0.3
# Least spread (rad) of a family's plane normals about its direction (a family of three lines that happen
# to agree exactly tells nothing more precise than this).
NORMAL_SPREAD_FLOOR_RAD = 1e-3


@dataclass(frozen=True)
class LineData:
    """The points of the lines being fitted, concatenated.

    Attributes
    ----------
    pixels : (N, 2) float64, px
    line_index : (N,) int
        Which line each point belongs to, 0..count-1.
    count : int
        Number of lines.
    r_max : float, px
        The largest radius that f_r must reach (the farthest point, with a margin).
    """

    pixels: FloatArray
    line_index: NDArray[np.intp]
    count: int
    r_max: float

    @classmethod
    def of(cls, lines: list[FloatArray], r_max: float) -> LineData:
        pixels = np.concatenate(lines)
        index = np.concatenate([np.full(len(p), k, dtype=np.intp) for k, p in enumerate(lines)])
        return cls(pixels, index, len(lines), r_max)


@dataclass(frozen=True)
class Trial:
    """One trial camera's rays, planes and residuals.

    Attributes
    ----------
    rays : PixelRays
    normals : (L, 3) float64
        Each line's best plane.
    distances_px : (N,) float64
        Each point's distance from its line's plane image.
    """

    rays: PixelRays
    normals: FloatArray
    distances_px: FloatArray


def radial_of(kind: str, axis: str, params: FloatArray) -> RadialFunction:
    """The radial function of ``params`` ([u0, v0, *coefficients])."""
    return RadialFunction(kind, tuple(float(c) for c in params[2:]), axis)


def evaluate(kind: str, axis: str, params: FloatArray, data: LineData) -> Trial | None:
    """The trial camera ``params`` on ``data``; None where its f_r does not reach the lines."""
    try:
        inverse = InverseRadial.of(radial_of(kind, axis, params), data.r_max)
    except PanomapError:
        return None
    rays = pixel_rays(data.pixels, (float(params[0]), float(params[1])), inverse)
    normals = best_planes(rays, data.line_index, data.count)
    return Trial(rays, normals, plane_distances_px(normals[data.line_index], rays))


def direction_spread(normals: FloatArray) -> tuple[FloatArray, FloatArray]:
    """A family's direction (3,) and its covariance (3, 3) from its lines' unit plane normals (k, 3).

    The direction is the eigenvector of the normals' scatter with the least eigenvalue l1; each normal's
    spread about it is ``s^2 = l1 / (k - 2)`` (at least ``NORMAL_SPREAD_FLOOR_RAD``); the direction then
    varies along the other eigenvectors e2, e3 by ``s^2 / l2`` and ``s^2 / l3``: a family whose planes
    all nearly coincide fixes its direction poorly across them.
    """
    values, vectors = np.linalg.eigh(normals.T @ normals)
    direction = vectors[:, 0] if vectors[2, 0] >= 0 else -vectors[:, 0]
    spread2 = max(float(values[0]) / max(normals.shape[0] - 2, 1), NORMAL_SPREAD_FLOOR_RAD**2)
    covariance = sum(spread2 / max(float(values[j]), 1e-12) * np.outer(vectors[:, j], vectors[:, j]) for j in (1, 2))
    return np.asarray(direction, dtype=np.float64), np.asarray(covariance, dtype=np.float64)


def orthogonality_residuals(
    normals: FloatArray, families: list[Family], pairs: list[tuple[int, int]], sigma_px: float
) -> FloatArray:
    """Cosine of the angle between each pair of families' directions (recomputed from ``normals``) over its
    standard error, times ``sigma_px``: what one standard error is worth in the points' px (the fit gives the
    points' noise times the square root of the points per line, ``fit._orthogonality_scale``).

    The standard error is the directions' (:func:`direction_spread`, to first order) and the world's own
    squareness (``WORLD_SQUARENESS_DEG``) together. A pair whose angle hardly moves with the camera's scale (a
    level camera's vertical and horizontal edges) or whose directions are loosely known then cannot pull the
    scale by many px for a fraction of a degree.
    """
    spread = [direction_spread(normals[family.members]) for family in families]
    world = math.sin(math.radians(WORLD_SQUARENESS_DEG)) ** 2
    out = np.empty(len(pairs))
    for k, (a, b) in enumerate(pairs):
        (va, ca), (vb, cb) = spread[a], spread[b]
        variance = float(vb @ ca @ vb + va @ cb @ va) + world
        out[k] = sigma_px * float(va @ vb) / math.sqrt(variance)
    return out


def residuals(
    kind: str,
    axis: str,
    params: FloatArray,
    data: LineData,
    families: list[Family],
    pairs: list[tuple[int, int]],
    sigma_px: float,
) -> FloatArray:
    """Every point's distance (px) from its line's plane, then the families' orthogonality residuals (over their
    standard errors, times ``sigma_px``: :func:`orthogonality_residuals`)."""
    trial = evaluate(kind, axis, params, data)
    if trial is None:
        return np.full(data.pixels.shape[0] + len(pairs), INVALID_RESIDUAL_PX)
    return np.concatenate([trial.distances_px, orthogonality_residuals(trial.normals, families, pairs, sigma_px)])
