"""The tilt from the vertical lines, and the azimuth origin from a pixel: the camera model's frame.

Convention: rays in this package's axes (:mod:`.rays`: alpha from the axis, the image angle phi as
azimuth) are the camera's axes of :class:`panomap.camera.model.CameraModel` (Z up, elevation rho)
up to ``diag(1, s, -1)`` looking down (``rho = alpha - pi/2``, ``theta = s phi``) or
``diag(1, s, 1)`` looking up. R takes the camera's axes to the world's.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ...camera.model import CameraModel
from ...errors import PanomapError
from ...geometry import FloatArray
from ..circles.types import ImageCircles
from .rays import InverseRadial


def to_camera_axes(direction: FloatArray, axis: str, s: int) -> FloatArray:
    """A direction (3,) in this package's axes, in the camera model's."""
    return np.asarray(direction * np.array([1.0, s, -1.0 if axis == "down" else 1.0]), dtype=np.float64)


def level_rotation(vertical: FloatArray, axis: str, s: int) -> FloatArray:
    """R (3, 3), camera to world, taking the vertical lines' direction (this package's axes) to world Z.

    The smallest such rotation: it leaves the azimuth origin where the image angle 0 put it.
    """
    v = to_camera_axes(vertical, axis, s)
    v = v / np.linalg.norm(v)
    if v[2] < 0:
        v = -v
    k = np.cross(v, [0.0, 0.0, 1.0])
    sine, cosine = float(np.linalg.norm(k)), float(v[2])
    if sine < 1e-12:
        return np.eye(3)
    k = k / sine
    cross = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.asarray(np.eye(3) + sine * cross + (1.0 - cosine) * cross @ cross, dtype=np.float64)


def pixel_world_azimuth(model: CameraModel, pixel: tuple[float, float]) -> float:
    """World azimuth (rad) of the ray that ``model`` sees at ``pixel`` (u, v) px."""
    radial_pixel = model.radial_pixels(np.array(pixel, dtype=np.float64))  # any image terms undone
    du, dv = float(radial_pixel[0]) - model.centre[0], float(radial_pixel[1]) - model.centre[1]
    r = math.hypot(du, dv)
    alpha, _ = InverseRadial.of(model.radial, r + 1.0)(np.array([r]))
    rho = float(alpha[0]) - math.pi / 2 if model.axis == "down" else math.pi / 2 - float(alpha[0])
    theta = (math.atan2(dv, du) - model.phi0) / model.s
    theta_world, _ = model.world_angles(np.array([theta]), np.array([rho]))
    return float(theta_world[0])


# A pixel closer than this to the image centre has no azimuth to speak of (its angle turns a degree for each
# hundredth of a pixel the centre moves).
MIN_AZIMUTH_RADIUS_PX = 5.0


def check_scene_pixel(pixel: tuple[float, float], centre: tuple[float, float], circles: ImageCircles) -> None:
    """Refuse a ``pixel`` (u, v) that sees no azimuth of the scene: nearer the ``centre`` than the cut-off disc
    (or :data:`MIN_AZIMUTH_RADIUS_PX`), where every azimuth meets, or past the image circle, where the camera
    sees nothing (the user's click or typing gone astray)."""
    radius = math.hypot(pixel[0] - centre[0], pixel[1] - centre[1])
    inner = max(circles.cutoff.radius if circles.cutoff is not None else 0.0, MIN_AZIMUTH_RADIUS_PX)
    if not inner <= radius <= circles.outer_radius:
        raise PanomapError(
            f"the pixel given for azimuth 0, ({pixel[0]:g}, {pixel[1]:g}), is {radius:.1f} px from the image centre: "
            f"give a pixel of the scene, {inner:.0f} to {circles.outer_radius:.0f} px from it"
        )


def zero_azimuth(model: CameraModel, pixel: tuple[float, float], circles: ImageCircles) -> CameraModel:
    """``model`` with its azimuth origin turned so that ``pixel`` (u, v) sees world azimuth 0; a pixel outside
    the scene's ring of ``circles`` is refused (:func:`check_scene_pixel`)."""
    check_scene_pixel(pixel, model.centre, circles)
    theta0 = pixel_world_azimuth(model, pixel)
    if model.rotation is None:
        return replace(model, phi0=model.phi0 + model.s * theta0, rotation=None)
    c, s = math.cos(-theta0), math.sin(-theta0)
    turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    rotation = turn @ np.asarray(model.rotation)
    return replace(model, rotation=tuple(map(tuple, rotation)))
