"""Between the table's frame and an external camera's: the optical axis becomes the vertical.

A calibration's camera frame is OpenCV's (:mod:`.models.base`: x right, y down, z the optical axis).
Its table is level in the camera's own axes (the mount's tilt, if any, is the table model's rotation
R): the optical axis is the vertical, looking **down** (z = world -Z) or **up** (z = world +Z), and
azimuth 0 is along the camera's x axis. So, for a ray d in the level camera's axes:

- ``down``: (x, y, z) = (d_X, -d_Y, -d_Z) (image angle phi = -theta: handedness s = -1);
- ``up``: (x, y, z) = (d_X, d_Y, d_Z) (phi = +theta: s = +1).

Both maps are their own inverse.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..geometry import FloatArray

# Handedness s of the table model for each axis (phi = s theta at the principal point).
HANDEDNESS = {"down": -1, "up": 1}


def camera_rays(level_rays: ArrayLike, axis: str) -> FloatArray:
    """Rays (..., 3) in the calibration's (OpenCV) frame of rays in the level camera's axes; or back."""
    d = np.asarray(level_rays, dtype=np.float64)
    if axis == "up":
        return d
    return d * np.array([1.0, -1.0, -1.0])
