"""Frames, angles and pixels: the conventions, stated once.

Convention (binding, see ``docs/conventions.md``):

- World: right-handed, X and Y horizontal, Z up, any length unit.
- Camera position O_m = (X0, Y0, Z0); camera axes parallel to the world's.
  A ray to a world point P is ``d = P - O_m``.
- Azimuth ``theta = atan2(d_y, d_x)`` in [0, 2*pi): counter-clockwise from +X,
  seen from above. Elevation ``rho = atan2(d_z, hypot(d_x, d_y))`` in
  [-pi/2, pi/2], negative below the horizontal plane through O_m.
- Pixel (u, v): u the column (right), v the row (down); the centre of the
  top-left pixel is (0, 0), as in ``cv2.remap``. Images are (H, W[, C]).
- Image model: ``u = u0 + r cos(phi)``, ``v = v0 + r sin(phi)``,
  ``phi = s*theta + phi0``, ``r = f_r(rho)``.
- The library takes radians; the CLI degrees. Names carry the unit.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

TWO_PI = 2.0 * np.pi
HALF_PI = 0.5 * np.pi

FloatArray = NDArray[np.float64]


def wrap_azimuth(theta: ArrayLike) -> FloatArray:
    """Wrap angles (rad) into [0, 2*pi)."""
    wrapped = np.mod(np.asarray(theta, dtype=np.float64), TWO_PI)
    # np.mod can return exactly 2*pi for tiny negative inputs.
    return np.where(wrapped >= TWO_PI, 0.0, wrapped)


def azimuth_elevation(rays: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Azimuth and elevation (rad) of rays.

    Parameters
    ----------
    rays : (..., 3) array_like
        Ray directions ``d = P - O_m`` in world axes; need not be unit length.

    Returns
    -------
    theta : (...) ndarray
        Azimuth in [0, 2*pi), counter-clockwise from +X seen from above.
    rho : (...) ndarray
        Elevation in [-pi/2, pi/2]. NaN where the ray is zero or not finite.
    """
    d = np.asarray(rays, dtype=np.float64)
    horizontal = np.hypot(d[..., 0], d[..., 1])
    theta = wrap_azimuth(np.arctan2(d[..., 1], d[..., 0]))
    rho = np.arctan2(d[..., 2], horizontal)
    bad = ~np.all(np.isfinite(d), axis=-1) | ((horizontal == 0) & (d[..., 2] == 0))
    theta = np.where(bad, np.nan, theta)
    rho = np.where(bad, np.nan, rho)
    return theta, rho


def ray_from_angles(theta: ArrayLike, rho: ArrayLike) -> FloatArray:
    """Unit ray direction (..., 3) in world axes for azimuth/elevation (rad)."""
    theta = np.asarray(theta, dtype=np.float64)
    rho = np.asarray(rho, dtype=np.float64)
    cos_rho = np.cos(rho)
    return np.stack([cos_rho * np.cos(theta), cos_rho * np.sin(theta), np.sin(rho)], axis=-1)


def ray_plane_points(origin: ArrayLike, theta: ArrayLike, rho: ArrayLike, z_plane: float) -> FloatArray:
    """Where rays meet a horizontal plane.

    Parameters
    ----------
    origin : (3,) or (..., 3) array_like
        The rays' origin (X0, Y0, Z0), world units: the camera position O_m, or each ray's own origin
        (a camera without a single viewpoint), broadcast with ``theta`` and ``rho``.
    theta, rho : (...) array_like
        Azimuth and elevation (rad) of each ray.
    z_plane : float
        Height Z of the plane, world units.

    Returns
    -------
    (..., 3) ndarray
        World points (X, Y, Z); NaN where the ray does not reach the plane
        (it runs parallel to it or away from it, or its angles are NaN).
    """
    origin = np.asarray(origin, dtype=np.float64)
    x0, y0, z0 = origin[..., 0], origin[..., 1], origin[..., 2]
    theta = np.asarray(theta, dtype=np.float64)
    rho = np.asarray(rho, dtype=np.float64)
    rise = z_plane - z0
    sin_rho = np.sin(rho)
    with np.errstate(divide="ignore", invalid="ignore"):
        reaches = (rise * sin_rho > 0) & np.isfinite(theta)
        along = np.where(reaches, rise / sin_rho, np.nan)  # distance along the unit ray
    horizontal = along * np.cos(rho)
    points = np.stack(
        np.broadcast_arrays(
            x0 + horizontal * np.cos(theta), y0 + horizontal * np.sin(theta), np.full(horizontal.shape, z_plane)
        ),
        axis=-1,
    )
    return np.where(reaches[..., None], points, np.nan)


def pixel_polar(uv: ArrayLike, centre: tuple[float, float]) -> tuple[FloatArray, FloatArray]:
    """Radius and image angle of pixels about a centre.

    Parameters
    ----------
    uv : (..., 2) array_like
        Pixels (u, v).
    centre : (u0, v0)
        The centre, px.

    Returns
    -------
    r : (...) ndarray
        ``hypot(u - u0, v - v0)``, px.
    phi : (...) ndarray
        Image angle ``atan2(v - v0, u - u0)`` (rad) in [-pi, pi]: from +u towards +v.
    """
    points = np.asarray(uv)
    du = points[..., 0] - centre[0]
    dv = points[..., 1] - centre[1]
    return np.hypot(du, dv), np.arctan2(dv, du)


def inside_image(u: Any, v: Any, image_size: tuple[int, int]) -> Any:
    """Whether pixels (u, v) lie on an image of ``image_size`` (width, height).

    Convention: pixel centres at integers, so the image spans
    [-0.5, width - 0.5] x [-0.5, height - 0.5]. Scalars give a bool, arrays a
    bool array; NaN is outside.
    """
    width, height = image_size
    return (u >= -0.5) & (u <= width - 0.5) & (v >= -0.5) & (v <= height - 0.5)


def pixel_centres(width: int, height: int) -> tuple[FloatArray, FloatArray]:
    """Fractions across and down a view at its pixel centres.

    Returns ``(fx, fy)`` of shapes (W,) and (H,): ``(k + 0.5)/W`` and
    ``(l + 0.5)/H``, the conventions' sampling positions of output pixels.
    """
    fx = (np.arange(width, dtype=np.float64) + 0.5) / width
    fy = (np.arange(height, dtype=np.float64) + 0.5) / height
    return fx, fy
