"""Between the table's frame and an external camera's: the optical axis becomes the vertical.

A calibration's camera frame is OpenCV's (:mod:`.models.base`: x along the image's columns, y along
its rows, z the optical axis). A table's model says where a ray of azimuth theta and elevation rho (in
the camera's own, level axes) lands: at image angle ``phi = s theta + phi0`` and at angle ``alpha``
from the pole the image centre sees (``rho + pi/2`` looking down, ``pi/2 - rho`` looking up). So the
ray in the camera's frame is

    (sin(alpha) cos(phi), sin(alpha) sin(phi), cos(alpha)).

An imported table has ``phi0 = 0`` and ``s = -1`` looking down (the ray is world (X, -Y, -Z): azimuth 0
along the camera's x axis, x × y = z pointing down) or ``s = +1`` looking up (world (X, Y, Z)). A table
fitted to a mirror camera looking down has ``s = +1``: its exported frame is then the world's mirror
image, as the frame of any single-mirror camera is (every ray/pixel pair holds).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..geometry import FloatArray

# Handedness s of an imported table's model for each axis (phi = s theta, phi0 = 0).
HANDEDNESS = {"down": -1, "up": 1}


def camera_rays(theta: ArrayLike, rho: ArrayLike, axis: str, s: int, phi0: float) -> FloatArray:
    """Unit rays (..., 3) in the calibration's (OpenCV) frame of azimuths and elevations (rad) in the
    level camera's axes, for a table model with ``axis``, handedness ``s`` and offset ``phi0`` (rad)."""
    theta = np.asarray(theta, dtype=np.float64)
    rho = np.asarray(rho, dtype=np.float64)
    alpha = rho + np.pi / 2 if axis == "down" else np.pi / 2 - rho
    phi = s * theta + phi0
    sin_alpha = np.sin(alpha)
    return np.stack(np.broadcast_arrays(sin_alpha * np.cos(phi), sin_alpha * np.sin(phi), np.cos(alpha)), axis=-1)
