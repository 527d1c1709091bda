"""Rays of pixels under a trial camera, and the residual block of one straight line.

Convention: the camera's own axes with the optical axis at alpha = 0 (alpha the angle of a ray
from the pole the image centre sees, rad) and the image angle phi (rad, from +u towards +v) as the
azimuth: ``d = (sin(alpha) cos(phi), sin(alpha) sin(phi), cos(alpha))``. The handedness ``s`` and
the azimuth origin ``phi0`` of :class:`panomap.camera.model.CameraModel` are a reflection and a
rotation about that axis: they keep planes through the viewpoint planes, so the straightness of a
line does not see them (nor can it learn them).

A world line's rays lie in one plane through the viewpoint, with unit normal ``n``. A pixel's
residual is its distance (px) from the image of that plane, to first order:
``(n . d) / |grad_pixel (n . d)|``, with ``d alpha / d r = 1 / f'(alpha)`` along the radius and
``sin(alpha) / r`` rad per px across it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ...camera.radial import RadialFunction
from ...camera.radial_models import rho_of_alpha
from ...errors import PanomapError
from ...geometry import FloatArray

# The inverse of f_r is tabulated on this many alphas, from the axis to the largest angle tried.
INVERSE_SAMPLES = 2048
# The largest angle from the axis (rad) that any camera here is taken to see: 150 deg.
ALPHA_LIMIT = float(np.radians(150.0))


@dataclass(frozen=True)
class InverseRadial:
    """``alpha(r)`` of a radial function, tabulated where f_r rises monotonically from the axis.

    Attributes
    ----------
    r : (K,) float64, px
        Increasing radii.
    alpha : (K,) float64, rad
        The angle from the axis at each radius.
    """

    r: FloatArray
    alpha: FloatArray

    @classmethod
    def of(cls, radial: RadialFunction, r_max: float) -> InverseRadial:
        """Tabulate ``radial`` from the axis up to radius ``r_max`` (px).

        Raises
        ------
        PanomapError
            If f_r does not rise monotonically from the axis to ``r_max``.
        """
        alpha = np.linspace(0.0, ALPHA_LIMIT, INVERSE_SAMPLES)
        rho = rho_of_alpha(alpha, radial.axis)
        r = np.abs(radial(rho))
        finite = np.isfinite(r)
        steps = np.diff(np.where(finite, r, 0.0))
        rising = np.concatenate([[True], steps > 0]) & finite & np.concatenate([[True], finite[:-1]])
        stop = int(np.argmin(rising)) if not rising.all() else r.size
        if stop < 2 or r[stop - 1] < r_max:
            raise PanomapError(f"the radial function does not rise monotonically to {r_max:.0f} px")
        return cls(r[:stop], alpha[:stop])

    def __call__(self, r: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``alpha`` (rad) and ``d alpha / d r`` (rad/px) at radii ``r`` (px)."""
        alpha = np.interp(r, self.r, self.alpha)
        slope = np.gradient(self.alpha, self.r)
        return alpha, np.interp(r, self.r, slope)


@dataclass(frozen=True)
class PixelRays:
    """The rays of pixels under one trial camera, and how fast they turn per pixel.

    Attributes
    ----------
    d : (N, 3) float64
        Unit rays in the camera's axes (convention above).
    e_alpha, e_phi : (N, 3) float64
        Unit tangents of the sphere at ``d``: towards larger alpha and larger phi.
    alpha_per_px : (N,) float64, rad/px
        ``d alpha / d r``.
    phi_per_px : (N,) float64, rad/px
        Turn of the ray across the radius per px, ``sin(alpha) / r``.
    """

    d: FloatArray
    e_alpha: FloatArray
    e_phi: FloatArray
    alpha_per_px: FloatArray
    phi_per_px: FloatArray


def pixel_rays(pixels: FloatArray, centre: tuple[float, float], inverse: InverseRadial) -> PixelRays:
    """Rays of ``pixels`` ((N, 2) [u, v] px) about ``centre`` (px) under ``inverse``."""
    du = pixels[:, 0] - centre[0]
    dv = pixels[:, 1] - centre[1]
    r = np.maximum(np.hypot(du, dv), 1e-9)
    phi = np.arctan2(dv, du)
    alpha, slope = inverse(r)
    ca, sa, cp, sp = np.cos(alpha), np.sin(alpha), np.cos(phi), np.sin(phi)
    d = np.stack([sa * cp, sa * sp, ca], axis=-1)
    e_alpha = np.stack([ca * cp, ca * sp, -sa], axis=-1)
    e_phi = np.stack([-sp, cp, np.zeros_like(cp)], axis=-1)
    return PixelRays(d, e_alpha, e_phi, slope, sa / r)


def line_block(normal_angles: FloatArray, rays: PixelRays, sigma_px: float = 1.0) -> FloatArray:
    """Whitened residuals of one line's pixels: the residual block of a straight world line.

    Parameters
    ----------
    normal_angles : (2,) float64, rad
        The line's plane through the viewpoint, as the azimuth and elevation of its unit normal
        in the camera's axes: its two unknowns.
    rays : PixelRays
        The line's pixels' rays under the camera being tried (its parameters enter here).
    sigma_px : float
        The edge points' noise (px).

    Returns
    -------
    (N,) float64
        Each pixel's signed distance (px) from the plane's image, divided by ``sigma_px``.
    """
    a, b = float(normal_angles[0]), float(normal_angles[1])
    normal = np.array([np.cos(a) * np.cos(b), np.sin(a) * np.cos(b), np.sin(b)])
    return plane_distances_px(normal, rays) / sigma_px


def plane_distances_px(normal: FloatArray, rays: PixelRays) -> FloatArray:
    """Signed distance (px, first order) of each pixel from the image of its plane.

    ``normal`` is one unit normal (3,) for every pixel, or one per pixel (N, 3).
    """
    normal = np.broadcast_to(normal, rays.d.shape)
    along = np.einsum("ij,ij->i", rays.e_alpha, normal) * rays.alpha_per_px
    across = np.einsum("ij,ij->i", rays.e_phi, normal) * rays.phi_per_px
    dot = np.einsum("ij,ij->i", rays.d, normal)
    return np.asarray(dot / np.maximum(np.hypot(along, across), 1e-12), dtype=np.float64)


def best_planes(rays: PixelRays, line_index: NDArray[np.intp], count: int) -> FloatArray:
    """Unit normals (count, 3) of the planes through the viewpoint that each line's rays lie closest to.

    ``line_index`` (N,) says which line each ray belongs to. Each normal is the smallest eigenvector
    of its line's scatter of rays, each ray weighted by its pixels per radian (so that it nearly
    minimises the distances in px); its sign makes the last component non-negative.
    """
    scale = 1.0 / np.maximum(np.hypot(rays.alpha_per_px, rays.phi_per_px), 1e-12)
    weighted = rays.d * scale[:, None]
    scatter = np.empty((count, 3, 3))
    for i in range(3):
        for j in range(i, 3):
            scatter[:, i, j] = scatter[:, j, i] = np.bincount(
                line_index, weighted[:, i] * weighted[:, j], minlength=count
            )
    _, vectors = np.linalg.eigh(scatter)
    normals = vectors[:, :, 0]
    return np.asarray(np.where(normals[:, 2:3] < 0, -normals, normals), dtype=np.float64)


def normal_angles(normal: FloatArray) -> FloatArray:
    """The two unknowns of :func:`line_block` for a unit ``normal`` (3,): azimuth and elevation, rad."""
    return np.array([np.arctan2(normal[1], normal[0]), np.arcsin(np.clip(normal[2], -1.0, 1.0))])
