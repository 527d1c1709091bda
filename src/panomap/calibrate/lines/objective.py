"""The least-squares objective of the line fit: straightness of every line, orthogonality of families.

Convention: as in :mod:`.rays`. The unknowns are the centre (u0, v0) (px) and the radial model's
coefficients; each line's plane (its two unknowns) is solved inside, in closed form, for the
camera being tried (variable projection: the block :func:`.rays.line_block` at its best plane).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ...camera.radial import RadialFunction
from ...errors import PanomapError
from ...geometry import FloatArray
from .families import Family, common_direction
from .rays import InverseRadial, PixelRays, best_planes, pixel_rays, plane_distances_px

# A trial camera whose f_r does not rise monotonically over the lines gets this residual (px) everywhere.
INVALID_RESIDUAL_PX = 1e3
# Weight of one orthogonality residual, in px per radian of the family's pixels' scale, per sqrt(line)
# of the smaller family: the directions are known about as well as sqrt(lines) planes.
ORTHOGONALITY_WEIGHT = 1.0


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


def orthogonality_residuals(
    normals: FloatArray, families: list[Family], pairs: list[tuple[int, int]], px_per_rad: float
) -> FloatArray:
    """Cosine of the angle between each pair of families' directions (recomputed from ``normals``), in px.

    Weighted by ``px_per_rad`` and by the square root of the smaller family's line count.
    """
    directions = [common_direction(normals[family.members]) for family in families]
    out = np.empty(len(pairs))
    for k, (a, b) in enumerate(pairs):
        lines = min(families[a].members.size, families[b].members.size)
        out[k] = ORTHOGONALITY_WEIGHT * px_per_rad * np.sqrt(lines) * float(directions[a] @ directions[b])
    return out


def residuals(
    kind: str,
    axis: str,
    params: FloatArray,
    data: LineData,
    families: list[Family],
    pairs: list[tuple[int, int]],
    px_per_rad: float,
) -> FloatArray:
    """Every point's distance (px) from its line's plane, then the families' orthogonality residuals."""
    trial = evaluate(kind, axis, params, data)
    if trial is None:
        return np.full(data.pixels.shape[0] + len(pairs), INVALID_RESIDUAL_PX)
    return np.concatenate([trial.distances_px, orthogonality_residuals(trial.normals, families, pairs, px_per_rad)])
