"""The camera's orientation: any rotation, told as a view's yaw, pitch and roll, or a tilt off the vertical.

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

**Any orientation** (a fisheye looking ahead, up or askew) is told as a perspective view's yaw psi,
pitch tau and roll omega (docs/conventions.md, "A camera looking any way"): the optical axis looks
along ``F``, the image's right is ``R`` and its down ``Dn`` (:func:`view_axes`, the perspective view's
formula), so ``G = [R, Dn, F]`` (columns) takes the image's camera frame (OpenCV's: x right, y down, z
ahead) to the world. A mirrored image (a mirror camera, ``s * c = +1`` below) shows ``Dn`` upward.
The model's own frame (its radial function about the pole ``c = -1`` looking down, ``+1`` up, its
azimuth mapping ``phi = s theta + phi0``) meets the image's frame through
``A = Rz(phi0) diag(1, s, c)`` (a ray ``d_c`` of the model's frame is ``A d_c`` in the image's), so

    R_model = G diag(1, sigma, 1) A,    sigma = s * c

(:func:`rotation_of_orientation`), and back (:func:`orientation_of_rotation`). The paper's ceiling
camera (``R = I``, looking down, ``s = +1``, ``phi0 = 0``) is yaw 90, pitch -90, roll 0.
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

    ``tilt_rad`` is in [0, pi]: the angle from the nominal pole (the nadir looking down, the zenith up);
    ``toward_rad`` is in [0, 2*pi); it is 0 for a level camera (where it has no meaning).
    """
    optical = optical_axis(rotation, axis)
    nominal_z = -1.0 if axis == "down" else 1.0
    tilt = math.acos(min(1.0, max(-1.0, nominal_z * float(optical[2]))))
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


def optical_axis(rotation: ArrayLike | None, axis: str) -> FloatArray:
    """The optical axis (3,), unit, in world axes: the model's pole (``(0, 0, -1)`` looking down,
    ``(0, 0, 1)`` up) through ``rotation`` (camera to world; None: level)."""
    nominal = np.array([0.0, 0.0, -1.0 if axis == "down" else 1.0])
    return nominal if rotation is None else np.asarray(rotation, dtype=np.float64) @ nominal


def world_elevation_range(
    camera_range: tuple[float, float], rotation: ArrayLike | None, axis: str
) -> tuple[float, float]:
    """The world elevations (rad) of the rays a camera sees: ``camera_range`` (its own elevations, rad)
    are the angles ``alpha`` in ``[a_low, a_high]`` from its optical axis, which lies ``T`` from the nadir;
    those rays lie ``|T - alpha|`` to ``min(T + alpha, 2 pi - T - alpha)`` from the nadir. Exact for any
    orientation (a level camera gets ``camera_range`` back); where the camera does not see a ray of that
    band, its table entry is NaN."""
    low, high = camera_range
    if axis == "down":
        a_low, a_high = low + math.pi / 2, high + math.pi / 2
    else:
        a_low, a_high = math.pi / 2 - high, math.pi / 2 - low
    if rotation is None:
        return float(low), float(high)
    optical = optical_axis(rotation, axis)
    t = math.acos(min(1.0, max(-1.0, -float(optical[2]))))  # from the nadir
    if a_low <= t <= a_high:
        nearest = 0.0
    else:
        nearest = t - a_high if t > a_high else a_low - t
    if a_low <= math.pi - t <= a_high:
        farthest = math.pi
    else:
        farthest = t + a_high if math.pi - t > a_high else 2 * math.pi - t - a_low
    return -math.pi / 2 + nearest, -math.pi / 2 + min(farthest, math.pi)


def view_axes(yaw_rad: float, pitch_rad: float, roll_rad: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Forward F, right R and down Dn (each (3,), unit, world axes) of yaw psi, pitch tau and roll omega
    (rad), the conventions' formula: ``F = (cos tau cos psi, cos tau sin psi, sin tau)``,
    ``R0 = (sin psi, -cos psi, 0)``, ``D0 = F x R0``, ``R = cos(omega) R0 + sin(omega) D0``,
    ``Dn = cos(omega) D0 - sin(omega) R0``."""
    psi, tau, omega = yaw_rad, pitch_rad, roll_rad
    cos_tau, sin_tau, cos_psi, sin_psi = math.cos(tau), math.sin(tau), math.cos(psi), math.sin(psi)
    forward = np.array([cos_tau * cos_psi, cos_tau * sin_psi, sin_tau])
    right0 = np.array([sin_psi, -cos_psi, 0.0])
    down0 = np.array([sin_tau * cos_psi, sin_tau * sin_psi, -cos_tau])  # F x R0
    right = math.cos(omega) * right0 + math.sin(omega) * down0
    down = math.cos(omega) * down0 - math.sin(omega) * right0
    return forward, right, down


def angles_of_axes(forward: ArrayLike, right: ArrayLike) -> tuple[float, float, float]:
    """(yaw, pitch, roll) rad of the unit axes F and R (world axes), the inverse of :func:`view_axes`:
    yaw in [0, 2 pi), pitch in [-pi/2, pi/2], roll in (-pi, pi]. Looking straight up or down, yaw and
    roll turn about the same axis: roll is 0 there and yaw carries the turn."""
    f = np.asarray(forward, dtype=np.float64)
    r = np.asarray(right, dtype=np.float64)
    pitch = math.asin(min(1.0, max(-1.0, float(f[2]))))
    if math.hypot(f[0], f[1]) < 1e-9:
        return float(wrap_azimuth(math.atan2(r[0], -r[1]))), pitch, 0.0
    yaw = float(wrap_azimuth(math.atan2(f[1], f[0])))
    right0 = np.array([math.sin(yaw), -math.cos(yaw), 0.0])
    down0 = np.cross(f, right0)
    return yaw, pitch, math.atan2(float(r @ down0), float(r @ right0))


def _model_to_image(axis: str, s: int, phi0_rad: float) -> FloatArray:
    """``A = Rz(phi0) diag(1, s, c)`` (3, 3): a ray of the model's frame in the image's camera frame."""
    c = -1.0 if axis == "down" else 1.0
    cos_phi, sin_phi = math.cos(phi0_rad), math.sin(phi0_rad)
    turn = np.array([[cos_phi, -sin_phi, 0.0], [sin_phi, cos_phi, 0.0], [0.0, 0.0, 1.0]])
    return turn @ np.diag([1.0, float(s), c])


def rotation_of_orientation(
    yaw_rad: float, pitch_rad: float, roll_rad: float, axis: str, s: int, phi0_rad: float
) -> FloatArray:
    """``R`` (3, 3), camera to world, of a model (``axis``, handedness ``s``, offset ``phi0_rad``) whose
    camera looks along yaw, pitch and roll (rad); entries within 1e-12 of 0 or +-1 are made exact, so
    that the paper's camera (yaw 90, pitch -90, roll 0 with ``s = +1``, ``phi0 = 0``) gets ``R = I``."""
    forward, right, down = view_axes(yaw_rad, pitch_rad, roll_rad)
    frame = np.stack([right, down, forward], axis=1)
    c = -1 if axis == "down" else 1
    rotation = frame @ np.diag([1.0, float(s * c), 1.0]) @ _model_to_image(axis, s, phi0_rad)
    for exact in (-1.0, 0.0, 1.0):
        rotation[np.abs(rotation - exact) < 1e-12] = exact
    return rotation


def orientation_of_rotation(
    rotation: ArrayLike | None, axis: str, s: int, phi0_rad: float
) -> tuple[float, float, float]:
    """(yaw, pitch, roll) rad of a model's camera: the inverse of :func:`rotation_of_orientation`
    (``G = R A^T diag(1, sigma, 1)``; None is a level camera)."""
    r = IDENTITY if rotation is None else np.asarray(rotation, dtype=np.float64)
    c = -1 if axis == "down" else 1
    frame = r @ _model_to_image(axis, s, phi0_rad).T @ np.diag([1.0, float(s * c), 1.0])
    return angles_of_axes(frame[:, 2], frame[:, 0])
