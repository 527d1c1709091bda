"""Angle grids that several view kinds share: panorama columns, and rays of a row term plus a column term."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ..geometry import TWO_PI, FloatArray, pixel_centres, wrap_azimuth
from .base import AngleArray


def panorama_azimuths(theta_start_rad: float, width: int) -> FloatArray:
    """``theta_start_rad - 2*pi*(k + 0.5)/W`` wrapped to [0, 2*pi); shape (W,)."""
    fx, _ = pixel_centres(width, 1)
    return wrap_azimuth(theta_start_rad - TWO_PI * fx)


def grid_angles(rows: list[FloatArray], cols: list[FloatArray]) -> tuple[AngleArray, AngleArray]:
    """Azimuth and elevation (rad), (H, W) float32, of rays ``d[l, k, a] = rows[a][l] + cols[a][k]``.

    Parameters
    ----------
    rows : three (H,) arrays
    cols : three (W,) arrays
        The x, y and z components of the rays (world axes) as a row term plus a
        column term, as the perspective and floor views' rays are.

    float32 for speed: about 2.4e-7 rad of rounding, 2e-4 px at a 900 px image
    radius. The azimuth is ``atan2(-d_y, -d_x) + pi``, which lands in [0, 2*pi]
    without a wrapping pass.
    """

    def component(axis: int, sign: float) -> NDArray[np.float32]:
        row = (sign * rows[axis]).astype(np.float32)
        col = (sign * cols[axis]).astype(np.float32)
        return np.add(row[:, None], col[None, :])

    minus_x, minus_y, d_z = component(0, -1.0), component(1, -1.0), component(2, 1.0)
    theta = np.arctan2(minus_y, minus_x)
    theta += np.float32(math.pi)
    # In place (fewer fresh pages), and in NumPy: cv2.magnitude's last bit depends on the
    # arrays' alignment in memory, which would make maps differ from run to run.
    horizontal = np.multiply(minus_x, minus_x, out=minus_x)
    horizontal += np.multiply(minus_y, minus_y, out=minus_y)
    np.sqrt(horizontal, out=horizontal)
    rho = np.arctan2(d_z, horizontal, out=d_z)
    return theta, rho
