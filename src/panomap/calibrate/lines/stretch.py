"""The stretch along the axis: the cameras a picture's lines and right angles cannot tell apart.

Convention: rays and directions in the camera's axes, +z (or -z: the sign does not matter here) its optical axis,
unit vectors (n, 3); angles in degrees where the name says so.

Take a camera and stretch its rays along its own axis: the camera ``C_s`` that sees, at each pixel, the ray ``d``
of the first turned into ``S d / |S d|``, ``S = diag(1, 1, s)``: its azimuths are the first camera's, its angles
from the axis ``tan(alpha') = tan(alpha) / s``, and it is again a radial camera (``r = f(alpha(alpha'))``). ``S`` is
linear, so it maps each plane through the viewpoint onto a plane through the viewpoint: **a pixel lies exactly
as far from a line's image under ``C_s`` as under the first camera**, for every ``s``. Straightness cannot tell
``C_s`` from the camera. A direction ``D`` becomes ``S D``: two directions at right angles stay at right angles
when each lies along the axis or square to it (the vertical and the walls of a room, for a camera looking
straight down, straight up or along a wall), and the angle between two directions oblique to the axis moves
(``a`` off the axis and its perpendicular in the same plane: ``cos = sin a cos a (1 - s^2) / (|S d1| |S d2|)``).

A checkerboard is no better where it faces the axis (flat under a camera looking down or up, square before
one looking ahead: its plane ``z = h`` becomes ``z = s h``, its squares stay square: the stretch is the focal
length that fronto-parallel boards leave free for a pinhole camera). A board turned ``b`` from that sees its
squares' sides along the turn shortened by ``(1 - s^2) sin^2(b) / 2``.

So a picture whose lines run only along and across the axis pins the scale of the elevations by nothing but the
radial law's own stiffness, which no picture measures: no number of such pictures does. With the camera's
directions 1-3 deg off them (a level camera), a room must be square to hundredths of a degree for its right
angles to place the camera within a px (``bench/bench_line_floor.py``); rooms are square to tenths.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ...geometry import FloatArray

#: A family of lines whose direction is within this of the axis or of square to it (deg) says little about the
#: stretch: a pair's angle turns by about ``sin(2 a) (1 - s^2) / 2`` rad, half its value at 45 deg here, a tenth at
#: 3 deg (a level camera's room).
OBLIQUE_MIN_DEG = 15.0

#: Boards that all face the axis within this (deg) cannot pin the stretch: a 10% stretch changes a square's sides
#: by ``(1 - s^2) sin^2(b) / 2``, under 0.3% here, about what a small board's corners measure. Measured: a real
#: paracatadioptric image's one board 7.5 deg off facing the axis, every corner within 0.34 px, its camera 78.7 px
#: (p90) from the calibration; rendered flat boards under a fisheye tilted 2 deg, 6.4 / 11.5 px (p90 / max).
FLAT_BOARD_DEG = 10.0


def axial_stretch(rays: FloatArray, s: float) -> FloatArray:
    """The rays (n, 3) of the camera stretched by ``s`` along its axis: ``S d / |S d|``, ``S = diag(1, 1, s)``."""
    out = np.asarray(rays, dtype=np.float64) * np.array([1.0, 1.0, s])
    return np.asarray(out / np.linalg.norm(out, axis=-1, keepdims=True), dtype=np.float64)


def obliqueness_deg(directions: FloatArray) -> FloatArray:
    """Each direction's (k, 3) angle (deg) from the nearer of the axis and the plane square to it: 0 along or
    across the axis, 45 halfway."""
    d = np.asarray(directions, dtype=np.float64)
    from_axis = np.degrees(np.arccos(np.clip(np.abs(d[:, 2]) / np.linalg.norm(d, axis=1), 0.0, 1.0)))
    return np.asarray(np.minimum(from_axis, 90.0 - from_axis), dtype=np.float64)


#: The stretches tried when the right angles are asked which they cannot reject: ``s`` from 1/2 to 2, log-spaced (a
#: stretch past them moves the rings by tens of px on any camera: refused either way).
STRETCH_LIMITS = (0.5, 2.0)
STRETCH_STEPS = 281
#: A stretch is not rejected while the right angles' chi-square lies within this of its least (chi-square, one
#: degree of freedom, 95%), times their dispersion where they are less square than their standard errors say.
CHI2_95_ONE = 3.841


@dataclass(frozen=True)
class StretchRange:
    """The stretches along the axis that a picture's right angles do not reject (:func:`stretch_range`).

    Attributes
    ----------
    low, high : float
        The least and largest ``s`` not rejected (1 is the chosen camera).
    best : float
        The ``s`` that makes the right angles squarest.
    dispersion : float
        Their least chi-square per degree of freedom, at least 1: how much less square than their standard
        errors say the world's right angles are (the threshold is widened by it).
    """

    low: float
    high: float
    best: float
    dispersion: float


def stretched_normals(normals: FloatArray, s: float) -> FloatArray:
    """The unit normals (n, 3) of the lines' planes under the camera stretched by ``s``: ``S^-1 n / |S^-1 n|``
    (the plane ``n . d = 0`` becomes ``(S^-1 n) . (S d) = 0``)."""
    out = np.asarray(normals, dtype=np.float64) / np.array([1.0, 1.0, s])
    return np.asarray(out / np.linalg.norm(out, axis=-1, keepdims=True), dtype=np.float64)


def stretch_range(squareness: Callable[[float], FloatArray]) -> StretchRange:
    """The stretches ``s`` in ``STRETCH_LIMITS`` whose right angles are not significantly less square than the
    squarest: ``squareness(s)`` (P,) gives each pair of families' cosine over its standard error under the camera
    stretched by ``s``. Their lines are exactly as straight under every ``s`` (module doc), so only the right
    angles can reject one: ``chi2(s) <= min chi2 + CHI2_95_ONE * dispersion``, the dispersion the least chi-square
    over ``P - 1`` (at least 1), as an F-test does where the noise is estimated from the same residuals.

    One pair must not decide (a pair of families that are not quite square in the world, a diagonal taken for a
    right angle, pins a wrong ``s`` as firmly as a true one): the range is the union of those of every pair left
    out in turn (a grouped jackknife over the pairs), so a picture with one oblique pair pins nothing. The ends
    are found on a log-spaced grid, then by bisection to ``BISECTIONS`` halvings of its step."""
    grid = np.geomspace(*STRETCH_LIMITS, STRETCH_STEPS)
    grid[np.argmin(np.abs(grid - 1.0))] = 1.0
    squares = np.array([np.square(squareness(float(s))) for s in grid]).reshape(grid.size, -1)
    pairs = squares.shape[1]
    subsets = [np.ones(pairs, dtype=bool)] + [np.arange(pairs) != k for k in range(pairs)]
    low, high, best, dispersion = math.inf, -math.inf, 1.0, 1.0
    for k, used in enumerate(subsets):
        values = squares[:, used].sum(axis=1)
        least = int(np.argmin(values))
        spread = max(float(values[least]) / (int(used.sum()) - 1), 1.0) if used.sum() > 1 else 1.0
        limit = float(values[least]) + CHI2_95_ONE * spread
        if k == 0:
            best, dispersion = float(grid[least]), spread

        def chi2(s: float, used: NDArray[np.bool_] = used) -> float:
            return float(np.sum(np.square(squareness(s))[used]))

        kept = np.flatnonzero(values <= limit)
        end_low, end_high = float(grid[kept[0]]), float(grid[kept[-1]])
        if kept[0] > 0:
            end_low = _crossing(chi2, limit, float(grid[kept[0] - 1]), end_low)
        if kept[-1] < grid.size - 1:
            end_high = _crossing(chi2, limit, float(grid[kept[-1] + 1]), end_high)
        low, high = min(low, end_low), max(high, end_high)
    return StretchRange(low, high, best, dispersion)


#: Halvings of the grid's step at each end of the range (0.5% / 2^20: far below what moves a ring by 0.01 px).
BISECTIONS = 20


def _crossing(chi2: Callable[[float], float], limit: float, rejected: float, kept: float) -> float:
    """The ``s`` between ``rejected`` (chi2 above ``limit``) and ``kept`` (within it) where chi2 crosses ``limit``,
    by bisection; the end kept."""
    for _ in range(BISECTIONS):
        middle = math.sqrt(rejected * kept)
        if chi2(middle) <= limit:
            kept = middle
        else:
            rejected = middle
    return kept
