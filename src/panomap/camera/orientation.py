"""The camera's orientation: a small tilt of its axis off the world vertical (beyond the paper).

Convention (docs/conventions.md, "A tilted camera"): the rotation ``R`` (3 x 3)
takes camera axes to world axes, so a world ray ``d`` is ``R.T @ d`` in the
camera's frame, where the radial model applies (``d_camera = d @ R`` for
rays in rows). A level camera has ``R = I``.

The tilt is told as two angles:

- ``tilt_rad``: the angle between the optical axis and the world vertical it
  nominally follows (the nadir for a camera looking down, the zenith for one
  looking up);
- ``toward_rad``: the world azimuth toward which the optical axis leans.

``R`` is the smallest rotation that takes the nominal axis to the tilted one
(about a horizontal axis): a turn about the vertical is the image's own
``phi0`` and is not part of it. In a fit the tilt is the horizontal rotation
vector ``w = (w_x, w_y)`` (rad): ``R = exp([w, 0]_x)``, smooth through the
level camera, where the two angles are not.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from ..geometry import FloatArray, wrap_azimuth

IDENTITY = np.eye(3)


def rotation_from_vector(w: ArrayLike) -> FloatArray:
    """Rotation matrix (3, 3) of the rotation vector ``w`` (3,) (axis times angle, rad): Rodrigues' formula."""
    vector = np.asarray(w, dtype=np.float64)
    angle = float(np.linalg.norm(vector))
    if angle < 1e-15:
        return IDENTITY.copy()
    k = vector / angle
    cross = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return IDENTITY + math.sin(angle) * cross + (1 - math.cos(angle)) * (cross @ cross)


def tilt_vector(tilt_rad: float, toward_rad: float, axis: str) -> FloatArray:
    """The horizontal rotation vector (3,) (rad) that tilts the optical axis by ``tilt_rad`` toward ``toward_rad``.

    Looking down, the nadir (0, 0, -1) goes to ``(sin t cos a, sin t sin a, -cos t)``:
    a turn by t about ``(sin a, -cos a, 0)``; looking up, the zenith goes to
    ``(sin t cos a, sin t sin a, cos t)``: about ``(-sin a, cos a, 0)``.
    """
    sign = 1.0 if axis == "down" else -1.0
    return tilt_rad * sign * np.array([math.sin(toward_rad), -math.cos(toward_rad), 0.0])


def tilt_rotation(tilt_rad: float, toward_rad: float, axis: str) -> FloatArray:
    """``R`` (3, 3), camera to world, of a camera tilted by ``tilt_rad`` toward azimuth ``toward_rad``."""
    return rotation_from_vector(tilt_vector(tilt_rad, toward_rad, axis))


def tilt_angles(rotation: ArrayLike, axis: str) -> tuple[float, float]:
    """(tilt_rad, toward_rad) of the optical axis under ``rotation`` (camera to world).

    ``toward_rad`` is in [0, 2*pi); it is 0 for a level camera (where it has no meaning).
    """
    r = np.asarray(rotation, dtype=np.float64)
    nominal = np.array([0.0, 0.0, -1.0 if axis == "down" else 1.0])
    optical = r @ nominal
    tilt = math.acos(min(1.0, abs(float(optical[2]))))
    if math.hypot(optical[0], optical[1]) < 1e-15:
        return 0.0, 0.0
    return tilt, float(wrap_azimuth(math.atan2(optical[1], optical[0])))


def to_camera(rays: ArrayLike, rotation: ArrayLike | None) -> FloatArray:
    """World rays (..., 3) in the camera's axes: ``R.T @ d`` for each (unchanged when ``rotation`` is None)."""
    d = np.asarray(rays, dtype=np.float64)
    return d if rotation is None else d @ np.asarray(rotation, dtype=np.float64)


def to_world(rays: ArrayLike, rotation: ArrayLike | None) -> FloatArray:
    """Camera rays (..., 3) in world axes: ``R @ d`` for each (unchanged when ``rotation`` is None)."""
    d = np.asarray(rays, dtype=np.float64)
    return d if rotation is None else d @ np.asarray(rotation, dtype=np.float64).T
