"""Simulated omnidirectional cameras with known ground truth.

Convention (see ``docs/conventions.md``):

- World frame: right-handed, Z up. Every camera's axes are parallel to the world's; its
  optical axis is vertical (:class:`TiltedCamera` mounts any of them with a rotation).
  Points given to :meth:`project` and ray origins returned by :meth:`trace` are
  *relative to the nominal camera position* O_m, in world axes.
- Ray of a point with offset ``d = P - O_m``: azimuth ``theta = atan2(d_y, d_x)`` in
  ``[0, 2*pi)`` (counter-clockwise from +X seen from above), elevation
  ``rho = atan2(d_z, hypot(d_x, d_y))`` (negative below the horizontal plane through O_m).
- Pixels ``(u, v)``: u is the column (right), v the row (down); the centre of the top-left
  pixel is ``(0, 0)``, so an image of ``W x H`` pixels covers ``[-0.5, W - 0.5] x
  [-0.5, H - 0.5]``.
- Image model: ``u = u0 + r*cos(phi)``, ``v = v0 + r*sin(phi)``, ``phi = s*theta + phi0``,
  with ``r`` the radius given by the camera's radial law.

Angles are in radians, lengths in metres, radii and image coordinates in pixels. Invalid
results (a pixel outside the visible annulus, a point the camera does not see) are NaN.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from panomap.errors import PanomapError

__all__ = [
    "RADIAL_LAWS",
    "SVP_CAMERA_NAMES",
    "RadialCamera",
    "SimulatedCamera",
    "SphericalMirrorCamera",
    "TiltedCamera",
    "mount_rotation",
    "standard_cameras",
]

#: Radial laws understood by :class:`RadialCamera`.
RADIAL_LAWS = ("equidistant", "equisolid", "stereographic", "orthographic", "polynomial", "unified")

#: Names of the single-viewpoint cameras returned by :func:`standard_cameras`.
SVP_CAMERA_NAMES = ("equidistant", "equisolid", "parabolic", "hyperbolic")

#: Fraction of ``min(W, H)`` filled by the image circle of the standard cameras.
_STANDARD_OUTER_FRACTION = 0.47

#: Largest bisection step count of :meth:`SphericalMirrorCamera.project`.
_MAX_BISECTION_ITERATIONS = 100

#: Bisection tolerance on the camera-ray angle beta (rad).
_BETA_TOLERANCE = 1e-12


@runtime_checkable
class SimulatedCamera(Protocol):
    """Interface shared by all simulated cameras.

    Attributes
    ----------
    name : str
        Short name.
    image_size : tuple of int
        ``(width, height)`` in pixels.
    centre : tuple of float
        ``(u0, v0)``: where the optical axis lands (px).
    s : int
        Mirror handedness, +1 or -1.
    phi0 : float
        Image-angle offset (rad).
    cutoff_radius, outer_radius : float
        Radii (px) of the self-occlusion disc and of the image circle.
    elevation_range : tuple of float
        ``(low, high)`` elevations (rad) of the visible annulus seen from O_m.
    """

    @property
    def name(self) -> str: ...

    @property
    def image_size(self) -> tuple[int, int]: ...

    @property
    def centre(self) -> tuple[float, float]: ...

    @property
    def s(self) -> int: ...

    @property
    def phi0(self) -> float: ...

    @property
    def cutoff_radius(self) -> float: ...

    @property
    def outer_radius(self) -> float: ...

    @property
    def elevation_range(self) -> tuple[float, float]: ...

    def project(self, points: ArrayLike) -> NDArray[np.float64]:
        """Map ``(..., 3)`` points relative to O_m to ``(..., 2)`` pixels, NaN if unseen."""
        ...

    def trace(self, uv: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Map ``(..., 2)`` pixels to ``(..., 3)`` ray origins (relative to O_m) and unit
        directions, NaN outside the visible annulus."""
        ...


# ----------------------------------------------------------------------------------------
# Shared helpers
# ----------------------------------------------------------------------------------------


def _as_points(points: ArrayLike) -> NDArray[np.float64]:
    """Return ``points`` as a float64 array of shape ``(..., 3)``."""
    p = np.asarray(points, dtype=np.float64)
    if p.ndim == 0 or p.shape[-1] != 3:
        raise PanomapError(f"points must have shape (..., 3), got {p.shape}")
    return p


def _as_pixels(uv: ArrayLike) -> NDArray[np.float64]:
    """Return ``uv`` as a float64 array of shape ``(..., 2)``."""
    q = np.asarray(uv, dtype=np.float64)
    if q.ndim == 0 or q.shape[-1] != 2:
        raise PanomapError(f"uv must have shape (..., 2), got {q.shape}")
    return q


def _azimuth_elevation(d: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
    """Azimuth in ``[0, 2*pi)``, elevation and horizontal distance of offsets ``d``.

    Parameters
    ----------
    d : (..., 3) ndarray
        Offsets from O_m, world axes.

    Returns
    -------
    theta, rho, horizontal : (...) ndarray
        Azimuth (rad), elevation (rad) and ``hypot(d_x, d_y)``.
    """
    horizontal = np.hypot(d[..., 0], d[..., 1])
    theta = np.mod(np.arctan2(d[..., 1], d[..., 0]), 2.0 * np.pi)
    rho = np.arctan2(d[..., 2], horizontal)
    return theta, rho, horizontal


def _in_image(u: NDArray[np.float64], v: NDArray[np.float64], image_size: tuple[int, int]) -> NDArray[np.bool_]:
    """True where ``(u, v)`` lies in the image rectangle ``[-0.5, W-0.5] x [-0.5, H-0.5]``."""
    width, height = image_size
    return (u >= -0.5) & (u <= width - 0.5) & (v >= -0.5) & (v <= height - 0.5)


def _polar_pixels(
    uv: NDArray[np.float64], centre: tuple[float, float]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Radius (px) and image angle ``phi = atan2(v - v0, u - u0)`` of pixels ``(..., 2)``."""
    du = uv[..., 0] - centre[0]
    dv = uv[..., 1] - centre[1]
    return np.hypot(du, dv), np.arctan2(dv, du)


def _pixels_from_polar(
    r: NDArray[np.float64],
    theta: NDArray[np.float64],
    centre: tuple[float, float],
    s: int,
    phi0: float,
) -> NDArray[np.float64]:
    """``(..., 2)`` pixels at radius ``r`` and azimuth ``theta`` (``phi = s*theta + phi0``)."""
    phi = s * theta + phi0
    return np.stack([centre[0] + r * np.cos(phi), centre[1] + r * np.sin(phi)], axis=-1)


def _directions(theta: NDArray[np.float64], rho: NDArray[np.float64]) -> NDArray[np.float64]:
    """``(..., 3)`` unit directions with azimuth ``theta`` and elevation ``rho`` (rad)."""
    c = np.cos(rho)
    return np.stack([c * np.cos(theta), c * np.sin(theta), np.sin(rho)], axis=-1)


def _check_common(
    name: str,
    image_size: tuple[int, int],
    centre: tuple[float, float],
    s: int,
    phi0: float,
) -> None:
    """Validate the fields every simulated camera has; raise ``ValueError`` if bad."""
    if not isinstance(name, str) or not name:
        raise PanomapError("name must be a non-empty string")
    if len(image_size) != 2 or not all(isinstance(n, (int, np.integer)) for n in image_size) or min(image_size) <= 0:
        raise PanomapError(f"image_size must be two positive integers, got {image_size!r}")
    if len(centre) != 2 or not all(math.isfinite(float(c)) for c in centre):
        raise PanomapError(f"centre must be two finite numbers, got {centre!r}")
    if s not in (1, -1):
        raise PanomapError(f"s must be +1 or -1, got {s!r}")
    if not math.isfinite(phi0):
        raise PanomapError(f"phi0 must be finite, got {phi0!r}")


# ----------------------------------------------------------------------------------------
# Single-viewpoint cameras with a closed-form radial law
# ----------------------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class RadialCamera:
    """Single-viewpoint omni-camera at O_m with a closed-form radial law.

    ``alpha`` is the angle between a ray and the direction the image centre sees: for
    ``axis='down'`` ``alpha = rho + pi/2``, for ``axis='up'`` ``alpha = pi/2 - rho``.
    The pixel radius is

    - ``'equidistant'``: ``r = scale*alpha``;
    - ``'equisolid'``: ``r = 2*scale*sin(alpha/2)``;
    - ``'stereographic'``: ``r = 2*scale*tan(alpha/2)``;
    - ``'orthographic'``: ``r = scale*sin(alpha)`` (``alpha_max <= pi/2``);
    - ``'polynomial'`` (a real lens's deviation from its design, as in Kannala and Brandt's
      model and OpenCV's fisheye module): ``r = scale*(alpha + k1*alpha**3 + k2*alpha**5 + ...)``
      with ``distortion = (k1, k2, ...)``;
    - ``'unified'`` (Mei/Geyer model of single-viewpoint catadioptric cameras):
      ``r = scale*sin(alpha)/(xi + cos(alpha))``; ``xi = 1`` is a parabolic mirror,
      ``0 < xi < 1`` a hyperbolic one, ``xi = 0`` a pinhole.

    Convention: points and ray origins are relative to O_m in world axes; pixel centres
    are integers, top-left pixel at ``(0, 0)``; ``phi = s*theta + phi0``.

    Parameters
    ----------
    name : str
        Short name.
    law : {'equidistant', 'equisolid', 'stereographic', 'orthographic', 'polynomial', 'unified'}
        Radial law.
    scale : float
        Scale of the law (px), > 0.
    xi : float
        Mirror parameter of the unified law, >= 0; must be 0 for the other laws.
    distortion : tuple of float
        ``(k1, k2, ...)`` of the polynomial law; must be empty for the other laws.
    image_size : tuple of int
        ``(width, height)`` (px).
    centre : tuple of float
        ``(u0, v0)`` (px).
    s : int
        +1 or -1.
    phi0 : float
        Image-angle offset (rad).
    axis : {'down', 'up'}
        Where the optical axis points.
    alpha_min : float
        Cut-off angle (rad): rays with ``alpha < alpha_min`` are self-occluded; 0 for none.
    alpha_max : float
        Angle (rad) of the image circle; ``alpha_min < alpha_max <= pi`` and the law is
        increasing up to ``alpha_max``.
    """

    name: str
    law: str
    scale: float
    xi: float = 0.0
    distortion: tuple[float, ...] = ()
    image_size: tuple[int, int]
    centre: tuple[float, float]
    s: int = 1
    phi0: float = 0.0
    axis: str = "down"
    alpha_min: float = 0.0
    alpha_max: float

    def __post_init__(self) -> None:
        _check_common(self.name, self.image_size, self.centre, self.s, self.phi0)
        if self.law not in RADIAL_LAWS:
            raise PanomapError(f"law must be one of {RADIAL_LAWS}, got {self.law!r}")
        if not (math.isfinite(self.scale) and self.scale > 0):
            raise PanomapError(f"scale must be finite and > 0, got {self.scale!r}")
        if self.axis not in ("down", "up"):
            raise PanomapError(f"axis must be 'down' or 'up', got {self.axis!r}")
        if not (
            math.isfinite(self.alpha_min)
            and math.isfinite(self.alpha_max)
            and 0.0 <= self.alpha_min < self.alpha_max <= math.pi
        ):
            raise PanomapError(
                f"need 0 <= alpha_min < alpha_max <= pi, got alpha_min={self.alpha_min!r}, alpha_max={self.alpha_max!r}"
            )
        if self.law == "unified":
            if not (math.isfinite(self.xi) and self.xi >= 0):
                raise PanomapError(f"xi must be finite and >= 0, got {self.xi!r}")
            # r(alpha) is finite while xi + cos(alpha) > 0, and increasing while
            # dr/dalpha = scale*(1 + xi*cos(alpha))/(xi + cos(alpha))**2 > 0. Both
            # expressions decrease with alpha, so checking alpha_max suffices.
            ca = math.cos(self.alpha_max)
            if not (self.xi + ca > 0 and 1.0 + self.xi * ca > 0):
                raise PanomapError(
                    f"unified law with xi={self.xi} is not finite and increasing up to "
                    f"alpha_max={self.alpha_max} rad (need xi + cos(alpha_max) > 0 and "
                    "1 + xi*cos(alpha_max) > 0)"
                )
        elif self.xi != 0.0:
            raise PanomapError(f"xi is only used by the unified law; got xi={self.xi!r}")
        if self.law != "polynomial" and self.distortion:
            raise PanomapError(f"distortion is only used by the polynomial law; got {self.distortion!r}")
        if self.law == "orthographic" and self.alpha_max > 0.5 * math.pi:
            raise PanomapError(f"the orthographic law is increasing up to pi/2 only; got alpha_max={self.alpha_max!r}")
        if self.law == "stereographic" and self.alpha_max >= math.pi:
            raise PanomapError(f"the stereographic law is finite below pi only; got alpha_max={self.alpha_max!r}")
        if self.law == "polynomial":
            grid = np.linspace(0.0, self.alpha_max, 2049)
            if not (all(math.isfinite(k) for k in self.distortion) and np.all(np.diff(self.radius(grid)) > 0)):
                raise PanomapError(
                    f"the polynomial law with distortion={self.distortion!r} is not increasing up to "
                    f"alpha_max={self.alpha_max!r}"
                )

    # -- radial law ----------------------------------------------------------------------

    def radius(self, alpha: ArrayLike) -> NDArray[np.float64]:
        """Pixel radius of rays at angle ``alpha`` (rad) from the image-centre direction.

        The law is evaluated as written, without range checks (see
        :meth:`radius_of_rho` for the checked ground-truth function).

        Parameters
        ----------
        alpha : (...) array_like
            Angles (rad).

        Returns
        -------
        (...) ndarray
            Radii (px).
        """
        a = np.asarray(alpha, dtype=np.float64)
        if self.law == "equidistant":
            return self.scale * a
        if self.law == "equisolid":
            return 2.0 * self.scale * np.sin(0.5 * a)
        if self.law == "stereographic":
            return 2.0 * self.scale * np.tan(0.5 * a)
        if self.law == "orthographic":
            return self.scale * np.sin(a)
        if self.law == "polynomial":
            return self.scale * (a + sum(k * a ** (2 * i + 3) for i, k in enumerate(self.distortion)))
        return self.scale * np.sin(a) / (self.xi + np.cos(a))

    def alpha_of_radius(self, r: ArrayLike) -> NDArray[np.float64]:
        """Inverse of :meth:`radius` on ``[0, radius(pi or its limit)]``, closed-form but for the
        polynomial law (Newton's method from the equidistant guess, to 1e-13 rad, on ``[0, alpha_max]``).

        For the unified law, ``r*(xi + cos a) = scale*sin a`` with ``t = r/scale`` reads
        ``sin(a - atan t) = t*xi/sqrt(1 + t**2)``, so ``a = atan t + asin(t*xi/sqrt(1+t**2))``
        (the principal branch is the increasing part of the law).

        Parameters
        ----------
        r : (...) array_like
            Radii (px), >= 0.

        Returns
        -------
        (...) ndarray
            Angles (rad); NaN where ``r`` is negative or beyond the law's range.
        """
        rr = np.asarray(r, dtype=np.float64)
        t = rr / self.scale
        with np.errstate(invalid="ignore"):
            if self.law == "equidistant":
                a = t.copy()
            elif self.law == "equisolid":
                a = 2.0 * np.arcsin(0.5 * t)
            elif self.law == "stereographic":
                a = 2.0 * np.arctan(0.5 * t)
            elif self.law == "orthographic":
                a = np.arcsin(t)
            elif self.law == "polynomial":
                a = self._invert_polynomial(t)
            else:
                a = np.arctan(t) + np.arcsin(t * self.xi / np.sqrt(1.0 + t * t))
        return np.where(rr >= 0, a, np.nan)

    def _invert_polynomial(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """``alpha`` with ``radius(alpha) = t*scale``, by Newton's method (NaN beyond ``alpha_max``)."""
        beyond = t > float(self.radius(self.alpha_max)) / self.scale * (1 + 1e-12)
        a = np.clip(np.where(np.isfinite(t), t, 0.0), 0.0, self.alpha_max)
        for _ in range(60):
            value = a + sum(k * a ** (2 * i + 3) for i, k in enumerate(self.distortion)) - t
            slope = 1.0 + sum((2 * i + 3) * k * a ** (2 * i + 2) for i, k in enumerate(self.distortion))
            step = value / slope
            a = np.clip(a - step, 0.0, self.alpha_max)
            if np.all(np.abs(np.where(np.isfinite(step), step, 0.0)) < 1e-13):
                break
        return np.where(beyond | ~np.isfinite(t), np.nan, a)

    @property
    def cutoff_radius(self) -> float:
        """Radius (px) of the self-occlusion disc, ``radius(alpha_min)``."""
        return float(self.radius(self.alpha_min))

    @property
    def outer_radius(self) -> float:
        """Radius (px) of the image circle, ``radius(alpha_max)``."""
        return float(self.radius(self.alpha_max))

    def _rho_of_alpha(self, alpha: NDArray[np.float64]) -> NDArray[np.float64]:
        return alpha - 0.5 * np.pi if self.axis == "down" else 0.5 * np.pi - alpha

    def _alpha_of_rho(self, rho: NDArray[np.float64]) -> NDArray[np.float64]:
        return rho + 0.5 * np.pi if self.axis == "down" else 0.5 * np.pi - rho

    @property
    def elevation_range(self) -> tuple[float, float]:
        """``(low, high)`` elevations (rad) of the visible annulus."""
        a = np.array([self.alpha_min, self.alpha_max])
        rho = self._rho_of_alpha(a)
        return float(rho.min()), float(rho.max())

    def radius_of_rho(self, rho: ArrayLike) -> NDArray[np.float64]:
        """Ground-truth radial stretching function ``r = f_r(rho)``.

        Parameters
        ----------
        rho : (...) array_like
            Elevations (rad).

        Returns
        -------
        (...) ndarray
            Radii (px); NaN outside ``elevation_range``.
        """
        a = self._alpha_of_rho(np.asarray(rho, dtype=np.float64))
        ok = (a >= self.alpha_min) & (a <= self.alpha_max)
        return np.where(ok, self.radius(np.where(ok, a, 0.0)), np.nan)

    def rho_of_radius(self, r: ArrayLike) -> NDArray[np.float64]:
        """Inverse of :meth:`radius_of_rho`.

        Parameters
        ----------
        r : (...) array_like
            Radii (px).

        Returns
        -------
        (...) ndarray
            Elevations (rad); NaN outside ``[cutoff_radius, outer_radius]``.
        """
        rr = np.asarray(r, dtype=np.float64)
        ok = (rr >= self.cutoff_radius) & (rr <= self.outer_radius)
        return np.where(ok, self._rho_of_alpha(self.alpha_of_radius(np.where(ok, rr, 0.0))), np.nan)

    # -- projection ----------------------------------------------------------------------

    def project(self, points: ArrayLike) -> NDArray[np.float64]:
        """Pixels where points relative to O_m are seen.

        Convention: points in world axes relative to O_m; pixel centres are integers.

        Parameters
        ----------
        points : (..., 3) array_like
            Points relative to O_m.

        Returns
        -------
        (..., 2) ndarray
            ``(u, v)`` (px); NaN inside the cut-off, beyond the image circle, outside the
            image rectangle or at O_m.
        """
        d = _as_points(points)
        theta, rho, horizontal = _azimuth_elevation(d)
        alpha = self._alpha_of_rho(rho)
        ok = ((horizontal > 0) | (d[..., 2] != 0)) & (alpha >= self.alpha_min) & (alpha <= self.alpha_max)
        r = self.radius(np.where(ok, alpha, 0.0))
        uv = _pixels_from_polar(r, theta, self.centre, self.s, self.phi0)
        ok &= _in_image(uv[..., 0], uv[..., 1], self.image_size)
        return np.where(ok[..., None], uv, np.nan)

    def trace(self, uv: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Rays seen by pixels.

        Convention: pixel centres are integers; rays in world axes relative to O_m.

        Parameters
        ----------
        uv : (..., 2) array_like
            Pixels ``(u, v)``.

        Returns
        -------
        origins : (..., 3) ndarray
            Ray origins relative to O_m (zero: a single viewpoint).
        directions : (..., 3) ndarray
            Unit directions.
            Both are NaN where the pixel is outside the image rectangle or the annulus
            ``[cutoff_radius, outer_radius]``.
        """
        q = _as_pixels(uv)
        r, phi = _polar_pixels(q, self.centre)
        ok = (r >= self.cutoff_radius) & (r <= self.outer_radius) & _in_image(q[..., 0], q[..., 1], self.image_size)
        alpha = self.alpha_of_radius(np.where(ok, r, 0.0))
        theta = self.s * (phi - self.phi0)
        directions = _directions(theta, self._rho_of_alpha(alpha))
        directions = np.where(ok[..., None], directions, np.nan)
        origins = np.where(ok[..., None], 0.0, np.nan) * np.ones_like(directions)
        return origins, directions


# ----------------------------------------------------------------------------------------
# Non-single-viewpoint camera: pinhole looking at a convex spherical mirror
# ----------------------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class SphericalMirrorCamera:
    """Pinhole camera looking up at a convex spherical mirror (no single viewpoint).

    Geometry in the mirror's local frame (world axes, origin at the mirror apex): the
    sphere of radius ``R = mirror_radius`` is centred at ``(0, 0, R)``, its apex (lowest
    point) at the origin; the pinhole is at ``(0, 0, -camera_distance)`` looking up. A
    camera ray at angle ``beta`` from the axis and azimuth ``theta`` lands at pixel radius
    ``r = focal_px*tan(beta)`` and image angle ``phi = s*theta + phi0``; it reflects off the
    sphere (``d' = d - 2 (d.n) n``) into the room, at the same azimuth ``theta``.

    The nominal camera position O_m is the point on the axis closest, in the weighted
    least-squares sense, to the reflected ray lines of the visible annulus (each ray
    weighted by the image area it covers, ``r dr``); its height above the apex is
    ``viewpoint_offset``. ``project`` and ``trace`` work relative to O_m.

    Parameters
    ----------
    name : str
        Short name.
    mirror_radius : float
        Sphere radius (m), > 0.
    camera_distance : float
        Distance (m) from the pinhole up to the apex, > 0.
    focal_px : float
        Pinhole focal length (px), > 0.
    image_size : tuple of int
        ``(width, height)`` (px).
    centre : tuple of float
        ``(u0, v0)`` (px).
    s : int
        +1 or -1.
    phi0 : float
        Image-angle offset (rad).
    beta_min : float
        Cut-off (rad): camera rays with smaller ``beta`` see the camera's own reflection.
    beta_max : float
        Mirror rim / image circle (rad); below the grazing angle
        ``asin(R/(R + camera_distance))``.
    """

    name: str
    mirror_radius: float
    camera_distance: float
    focal_px: float
    image_size: tuple[int, int]
    centre: tuple[float, float]
    s: int = 1
    phi0: float = 0.0
    beta_min: float
    beta_max: float
    viewpoint_offset: float = field(init=False)

    def __post_init__(self) -> None:
        _check_common(self.name, self.image_size, self.centre, self.s, self.phi0)
        for label, value in (
            ("mirror_radius", self.mirror_radius),
            ("camera_distance", self.camera_distance),
            ("focal_px", self.focal_px),
        ):
            if not (math.isfinite(value) and value > 0):
                raise PanomapError(f"{label} must be finite and > 0, got {value!r}")
        grazing = math.asin(self.mirror_radius / (self.mirror_radius + self.camera_distance))
        if not (
            math.isfinite(self.beta_min)
            and math.isfinite(self.beta_max)
            and 0.0 <= self.beta_min < self.beta_max < grazing
        ):
            raise PanomapError(
                f"need 0 <= beta_min < beta_max < {grazing!r} (grazing angle), got "
                f"beta_min={self.beta_min!r}, beta_max={self.beta_max!r}"
            )
        betas = np.linspace(self.beta_min, self.beta_max, 2001)
        if not np.all(np.diff(self.elevation_of_beta(betas)) > 0):
            raise PanomapError("reflected elevation is not increasing over [beta_min, beta_max]")
        object.__setattr__(self, "viewpoint_offset", self._fit_viewpoint(betas))

    def with_mirror(self, mirror_radius: float, camera_distance: float, beta_max: float) -> SphericalMirrorCamera:
        """The same camera (image, centre, handedness, cut-off) with another sphere ``mirror_radius`` (m),
        ``camera_distance`` (m) below the lens, seen to ``beta_max`` (rad) off the axis: the focal length set so
        that the mirror's rim stays on the image circle (``outer_radius``)."""
        return replace(
            self, mirror_radius=mirror_radius, camera_distance=camera_distance, beta_max=beta_max,
            focal_px=self.outer_radius / math.tan(beta_max),
        )  # fmt: skip

    # -- ray geometry in the vertical plane through the axis -----------------------------

    def _reflect(self, beta: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
        """Reflection in the radial half-plane of camera rays at angle ``beta`` (rad).

        Returns
        -------
        x, z, dx, dz : (...) ndarray
            Reflection point (radial distance from the axis, height above the apex, m) and
            unit reflected direction (radial and vertical components).
        """
        big = self.mirror_radius + self.camera_distance
        sb, cb = np.sin(beta), np.cos(beta)
        # |C + t d - K|^2 = R^2 with C = (0, -c), K = (0, R), d = (sin b, cos b).
        t = big * cb - np.sqrt(self.mirror_radius**2 - (big * sb) ** 2)
        x = t * sb
        z = t * cb - self.camera_distance
        nx = x / self.mirror_radius
        nz = (z - self.mirror_radius) / self.mirror_radius
        dn = sb * nx + cb * nz
        return x, z, sb - 2.0 * dn * nx, cb - 2.0 * dn * nz

    def elevation_of_beta(self, beta: ArrayLike) -> NDArray[np.float64]:
        """Elevation (rad) of the reflected ray of camera rays at angle ``beta`` (rad).

        Parameters
        ----------
        beta : (...) array_like
            Camera-ray angles from the axis (rad), below the grazing angle.

        Returns
        -------
        (...) ndarray
            Elevations of the reflected directions (rad); ``-pi/2`` at ``beta = 0``.
        """
        _, _, dx, dz = self._reflect(np.asarray(beta, dtype=np.float64))
        return np.arctan2(dz, dx)

    def _fit_viewpoint(self, betas: NDArray[np.float64]) -> float:
        """Height above the apex of the axis point closest to the reflected ray lines.

        The squared distance from the axis point ``(0, z)`` to the line through ``(x, zp)``
        with direction ``(dx, dz)`` (both in the ray's radial half-plane) is
        ``(x*dz - zp*dx + z*dx)**2``; the weighted least-squares ``z`` is closed form.
        """
        x, zp, dx, dz = self._reflect(betas)
        a = x * dz - zp * dx
        weights = np.tan(betas) / np.cos(betas) ** 2  # r dr/dbeta, up to focal_px**2
        denominator = float(np.sum(weights * dx * dx))
        if not denominator > 0:
            raise PanomapError("cannot fit a viewpoint: the reflected rays are all vertical")
        return -float(np.sum(weights * a * dx)) / denominator

    def closest_approach(self, beta: ArrayLike) -> NDArray[np.float64]:
        """Distance (m) from O_m to the reflected ray lines of camera rays at ``beta``.

        Zero for all ``beta`` would mean a single viewpoint.

        Parameters
        ----------
        beta : (...) array_like
            Camera-ray angles (rad).

        Returns
        -------
        (...) ndarray
            Distances (m) from O_m to the (infinite) reflected lines.
        """
        x, zp, dx, dz = self._reflect(np.asarray(beta, dtype=np.float64))
        return np.abs(x * dz - (zp - self.viewpoint_offset) * dx)

    # -- camera interface ----------------------------------------------------------------

    @property
    def cutoff_radius(self) -> float:
        """Radius (px) of the cut-off disc, ``focal_px*tan(beta_min)``."""
        return self.focal_px * math.tan(self.beta_min)

    @property
    def outer_radius(self) -> float:
        """Radius (px) of the image circle, ``focal_px*tan(beta_max)``."""
        return self.focal_px * math.tan(self.beta_max)

    @property
    def elevation_range(self) -> tuple[float, float]:
        """Elevations (rad) of the reflected directions at ``beta_min`` and ``beta_max``.

        These are the elevations seen from O_m of points far away; points close to the
        mirror are seen at slightly different elevations (no single viewpoint).
        """
        low, high = self.elevation_of_beta(np.array([self.beta_min, self.beta_max]))
        return float(low), float(high)

    def trace(self, uv: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Forward ray trace of pixels through the mirror.

        Convention: pixel centres are integers; rays in world axes relative to O_m.

        Parameters
        ----------
        uv : (..., 2) array_like
            Pixels ``(u, v)``.

        Returns
        -------
        origins : (..., 3) ndarray
            Reflection points relative to O_m (m).
        directions : (..., 3) ndarray
            Unit reflected directions.
            Both are NaN where the pixel is outside the image rectangle or the annulus
            ``[cutoff_radius, outer_radius]``.
        """
        q = _as_pixels(uv)
        r, phi = _polar_pixels(q, self.centre)
        beta = np.arctan2(r, self.focal_px)
        ok = (beta >= self.beta_min) & (beta <= self.beta_max) & _in_image(q[..., 0], q[..., 1], self.image_size)
        x, z, dx, dz = self._reflect(np.where(ok, beta, self.beta_min))
        theta = self.s * (phi - self.phi0)
        ct, st = np.cos(theta), np.sin(theta)
        origins = np.stack([x * ct, x * st, z - self.viewpoint_offset], axis=-1)
        directions = np.stack([dx * ct, dx * st, dz], axis=-1)
        nan = np.where(ok[..., None], 0.0, np.nan)
        return origins + nan, directions + nan

    def project(self, points: ArrayLike) -> NDArray[np.float64]:
        """Pixels where points relative to O_m are seen, by solving for the camera ray.

        In the vertical half-plane through the axis and the point, finds ``beta`` in
        ``[beta_min, beta_max]`` with the point on the reflected ray, by vectorised
        bisection on ``F(beta) = cross(d'(beta), X - P(beta))`` (the reflected fan turns
        monotonically with ``beta``), to ``1e-12`` rad.

        Convention: points in world axes relative to O_m; pixel centres are integers.

        Parameters
        ----------
        points : (..., 3) array_like
            Points relative to O_m (m).

        Returns
        -------
        (..., 2) ndarray
            ``(u, v)`` (px); NaN where no reflected ray in the annulus reaches the point
            in front of the mirror, or the pixel is outside the image rectangle.

        Raises
        ------
        RuntimeError
            If the bisection does not reach the tolerance within its iteration cap.
        """
        d = _as_points(points)
        theta = np.mod(np.arctan2(d[..., 1], d[..., 0]), 2.0 * np.pi)
        h = np.hypot(d[..., 0], d[..., 1])
        zx = d[..., 2] + self.viewpoint_offset  # height above the apex

        def residual(beta: NDArray[np.float64]) -> NDArray[np.float64]:
            x, z, dx, dz = self._reflect(beta)
            return dx * (zx - z) - dz * (h - x)

        lo = np.full(h.shape, self.beta_min)
        hi = np.full(h.shape, self.beta_max)
        f_lo = residual(lo)
        f_hi = residual(hi)
        ok = np.isfinite(f_lo) & np.isfinite(f_hi) & (np.sign(f_lo) * np.sign(f_hi) <= 0)
        positive_lo = f_lo > 0
        for _ in range(_MAX_BISECTION_ITERATIONS):
            if not np.any(ok & (hi - lo > _BETA_TOLERANCE)):
                break
            mid = 0.5 * (lo + hi)
            f_mid = residual(mid)
            same_as_lo = (f_mid > 0) == positive_lo
            lo = np.where(same_as_lo, mid, lo)
            hi = np.where(same_as_lo, hi, mid)
        else:
            if np.any(ok & (hi - lo > _BETA_TOLERANCE)):
                raise RuntimeError(
                    f"bisection did not reach {_BETA_TOLERANCE} rad in {_MAX_BISECTION_ITERATIONS} iterations"
                )
        beta = 0.5 * (lo + hi)
        x, z, dx, dz = self._reflect(beta)
        ok &= dx * (h - x) + dz * (zx - z) > 0  # the point is in front of the mirror
        uv = _pixels_from_polar(self.focal_px * np.tan(beta), theta, self.centre, self.s, self.phi0)
        ok &= _in_image(uv[..., 0], uv[..., 1], self.image_size)
        return np.where(ok[..., None], uv, np.nan)


# ----------------------------------------------------------------------------------------
# The standard set
# ----------------------------------------------------------------------------------------


def standard_cameras(
    size: tuple[int, int] = (960, 960),
    seed: int | None = None,
    *,
    centre: tuple[float, float] | None = None,
    s: int = 1,
    phi0: float = 0.0,
    outer_radius: float | None = None,
) -> dict[str, SimulatedCamera]:
    """The named simulated cameras used across the tests, each filling a ``size`` image.

    Every image circle has radius ``0.47*min(size)`` px (``outer_radius`` when given: a
    larger one is cut by the frame, as a round image on a 4:3 or 16:9 sensor). The
    cameras look down.

    - ``'equidistant'``, ``'equisolid'``: fisheyes, ``alpha_max = 95 deg``, no cut-off;
    - ``'parabolic'``: unified ``xi = 1``, ``alpha`` in ``[12, 105] deg``;
    - ``'hyperbolic'``: unified ``xi = 0.8``, ``alpha`` in ``[12, 100] deg``;
    - ``'spherical'``: spherical mirror ``R = 0.05`` m, pinhole 0.15 m below the apex,
      ``beta`` in ``[2, 12] deg``: rays inside the cut-off come back down within about
      4.3 cm of the lens (the camera housing); reflected elevations span about -76 to
      +10.5 deg; O_m is about 14.9 mm above the apex.

    Parameters
    ----------
    size : tuple of int
        ``(width, height)`` (px).
    seed : int or None
        None: ideal cameras. An integer: each camera's centre is moved by a uniform
        offset of up to ``0.01*min(size)`` px per axis and ``phi0`` by up to 0.1 rad,
        drawn from ``np.random.default_rng(seed)`` in the order of the names.
    centre : tuple of float or None
        ``(u0, v0)`` for all cameras; default the image middle ``((W-1)/2, (H-1)/2)``.
    s : int
        Handedness for all cameras.
    phi0 : float
        Image-angle offset (rad) for all cameras.
    outer_radius : float or None
        Radius of every image circle (px), > 0; default ``0.47*min(size)``.

    Returns
    -------
    dict of str to SimulatedCamera
        Keys ``'equidistant', 'equisolid', 'parabolic', 'hyperbolic', 'spherical'``.
    """
    width, height = int(size[0]), int(size[1])
    outer = _STANDARD_OUTER_FRACTION * min(width, height) if outer_radius is None else float(outer_radius)
    if not (math.isfinite(outer) and outer > 0):
        raise PanomapError(f"outer_radius must be finite and > 0, got {outer_radius!r}")
    base_centre = ((width - 1) / 2.0, (height - 1) / 2.0) if centre is None else centre
    rng = None if seed is None else np.random.default_rng(seed)

    def placement() -> tuple[tuple[float, float], float]:
        c0, p0 = (float(base_centre[0]), float(base_centre[1])), float(phi0)
        if rng is not None:
            jitter = rng.uniform(-0.01, 0.01, size=2) * min(width, height)
            c0 = (c0[0] + float(jitter[0]), c0[1] + float(jitter[1]))
            p0 += float(rng.uniform(-0.1, 0.1))
        return c0, p0

    deg = math.pi / 180.0
    a95 = 95 * deg
    radial = {
        "equidistant": ("equidistant", 0.0, outer / a95, 0.0, a95),
        "equisolid": ("equisolid", 0.0, outer / (2.0 * math.sin(a95 / 2.0)), 0.0, a95),
        "parabolic": (
            "unified",
            1.0,
            outer * (1.0 + math.cos(105 * deg)) / math.sin(105 * deg),
            12 * deg,
            105 * deg,
        ),
        "hyperbolic": (
            "unified",
            0.8,
            outer * (0.8 + math.cos(100 * deg)) / math.sin(100 * deg),
            12 * deg,
            100 * deg,
        ),
    }
    cams: dict[str, SimulatedCamera] = {}
    for name, (law, xi, scale, a_min, a_max) in radial.items():
        c0, p0 = placement()
        cams[name] = RadialCamera(
            name=name,
            law=law,
            scale=scale,
            xi=xi,
            image_size=(width, height),
            centre=c0,
            s=s,
            phi0=p0,
            alpha_min=a_min,
            alpha_max=a_max,
        )
    beta_max = 12 * deg
    c0, p0 = placement()
    cams["spherical"] = SphericalMirrorCamera(
        name="spherical",
        mirror_radius=0.05,
        camera_distance=0.15,
        focal_px=outer / math.tan(beta_max),
        image_size=(width, height),
        centre=c0,
        s=s,
        phi0=p0,
        beta_min=2 * deg,
        beta_max=beta_max,
    )
    return cams


# ----------------------------------------------------------------------------------------
# A tilted mount: any camera above, its axes rotated off the world's
# ----------------------------------------------------------------------------------------


def mount_rotation(tilt: float, toward: float, looking_down: bool = True) -> NDArray[np.float64]:
    """Rotation (3, 3), camera axes to world axes, of a camera whose optical axis is ``tilt`` (rad) off the
    vertical (the nadir looking down, the zenith looking up), leaning toward world azimuth ``toward`` (rad).

    Built here from the two directions (the smallest rotation taking the vertical to the tilted axis),
    independently of the library's own.
    """
    vertical = np.array([0.0, 0.0, -1.0 if looking_down else 1.0])
    optical = np.array(
        [math.sin(tilt) * math.cos(toward), math.sin(tilt) * math.sin(toward), vertical[2] * math.cos(tilt)]
    )
    axis = np.cross(vertical, optical)
    sine = float(np.linalg.norm(axis))
    if sine < 1e-15:
        return np.eye(3)
    k = axis / sine
    cosine = float(vertical @ optical)
    k_cross = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + sine * k_cross + (1.0 - cosine) * (k_cross @ k_cross)


@dataclass(frozen=True)
class TiltedCamera:
    """A simulated camera mounted with its axes rotated by ``rotation`` (camera to world).

    :meth:`project` takes points relative to O_m in world axes and projects ``R.T d``
    through ``camera``; :meth:`trace` returns rays in world axes. Every other attribute is
    the inner camera's (``elevation_range`` is in the camera's own axes).
    """

    camera: SimulatedCamera
    rotation: NDArray[np.float64]

    @property
    def name(self) -> str:
        return f"{self.camera.name} (tilted)"

    @property
    def image_size(self) -> tuple[int, int]:
        return self.camera.image_size

    @property
    def centre(self) -> tuple[float, float]:
        return self.camera.centre

    @property
    def s(self) -> int:
        return self.camera.s

    @property
    def phi0(self) -> float:
        return self.camera.phi0

    @property
    def cutoff_radius(self) -> float:
        return self.camera.cutoff_radius

    @property
    def outer_radius(self) -> float:
        return self.camera.outer_radius

    @property
    def elevation_range(self) -> tuple[float, float]:
        return self.camera.elevation_range

    def project(self, points: ArrayLike) -> NDArray[np.float64]:
        """Pixels (..., 2) of points (..., 3) relative to O_m in world axes; NaN if unseen."""
        return self.camera.project(_as_points(points) @ self.rotation)

    def trace(self, uv: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Ray origins and unit directions (..., 3), relative to O_m in world axes, of pixels (..., 2)."""
        origins, directions = self.camera.trace(uv)
        return origins @ self.rotation.T, directions @ self.rotation.T
