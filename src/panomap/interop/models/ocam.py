"""Scaramuzza's OCamCalib model (Scaramuzza, Martinelli & Siegwart 2006), as ``calib_results.txt`` holds it.

Parameters, in this order: ``pol`` (a0, a1, ..., ascending: ``ss`` in MATLAB), ``invpol`` (ascending:
``invpol``), ``xc`` (the centre's **row**), ``yc`` (its **column**), both from 0 (the centre of the
top-left pixel is (0, 0): the C convention of ``calib_results.txt``; MATLAB's own ``ocam_model`` is
1-based), the affine ``c, d, e``, and the image ``height, width``.

OCamCalib's frame: x along the image rows (down), y along the columns (right), z = x × y, so the image
centre sees **-z**; in :mod:`.base`'s OpenCV frame, the OCam ray (x, y, z) is (y, x, -z).

    cam2world:  [x', y'] = [[c, d], [e, 1]]^-1 [row - xc, col - yc],  r = hypot(x', y'),
                ray = (x', y', pol(r))                                     (the calibration itself)
    world2cam:  t = atan(z / hypot(x, y)),  rho = invpol(t),  (x', y') = (x, y) rho / hypot(x, y),
                row = c x' + d y' + xc,   col = e x' + y' + yc

``invpol`` is OCamCalib's fitted approximation of the inverse of ``pol``: :meth:`OCam.project` inverts
``pol`` itself (to 1e-9 px, by Newton from a tabulated inverse), so a table made from it reproduces
``cam2world`` exactly; ``invpol`` is kept and written back. The valid range runs from the centre to
where the elevation ``atan2(pol(r), r)`` stops increasing with r (a polynomial that turns back).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike

from ...errors import PanomapError
from ...geometry import FloatArray
from .base import ExternalCamera, as_rays, farthest_corner_px, pixels, positive

# The tabulated inverse of pol: this many radii from 0 to the farthest image corner (and a margin).
_INVERSE_NODES = 8193
# Newton steps from that table's linear interpolation (within 0.01 px): each squares the error.
NEWTON_STEPS = 2
# Coefficients of pol and of invpol, at most: OCamCalib writes 5 for pol and up to about 20 for invpol, and a
# polynomial of far higher degree in radii of hundreds of px is no camera (and costs its degree in every
# evaluation: 20001 coefficients took 89 s to import).
MAX_COEFFICIENTS = 64


def check_affine(name: str, c: float, d: float, e: float) -> None:
    """Raise :class:`PanomapError` where OCamCalib's affine ``[[c, d], [e, 1]]`` is singular (``|c - d e|`` under
    1e-9): no pixel could be traced back to its ray."""
    if abs(c - d * e) < 1e-9:
        raise PanomapError(f"{name}: the affine matrix [[c, d], [e, 1]] is singular")


@dataclass(frozen=True)
class OCam(ExternalCamera):
    name: ClassVar[str] = "ocam"

    pol: tuple[float, ...]
    invpol: tuple[float, ...]
    xc: float
    yc: float
    c: float
    d: float
    e: float
    height: int
    width: int

    def check(self) -> None:
        for name, coefficients in (("pol", self.pol), ("invpol", self.invpol)):
            if len(coefficients) > MAX_COEFFICIENTS:
                raise PanomapError(
                    f"{self.name}: {name} has {len(coefficients)} coefficients; at most {MAX_COEFFICIENTS} "
                    "(OCamCalib writes 5 for pol, about 20 for invpol)"
                )
        if len(self.pol) < 2:
            raise PanomapError(f"{self.name}: pol needs at least 2 coefficients, has {len(self.pol)}")
        if not self.pol[0] < 0:
            raise PanomapError(f"{self.name}: pol's a0 must be < 0 (the centre sees -z), not {self.pol[0]:g}")
        positive(self.name, "height", self.height)
        positive(self.name, "width", self.width)
        check_affine(self.name, self.c, self.d, self.e)

    @property
    def principal_point(self) -> tuple[float, float]:
        return (self.yc, self.xc)

    @property
    def focal_px(self) -> float:
        return -self.pol[0]

    @property
    def image_reach_px(self) -> float:
        """Distance (px) from the centre to the farthest image corner."""
        return farthest_corner_px(self.principal_point, self.width, self.height)

    @cached_property
    def _inverse(self) -> tuple[FloatArray, FloatArray]:
        """Radii (px) and their elevations atan2(pol(r), r) (rad), up to the first turn (increasing)."""
        r = np.linspace(0.0, 1.5 * self.image_reach_px, _INVERSE_NODES)
        t = np.arctan2(np.polynomial.polynomial.polyval(r, self.pol), r)
        falling = np.flatnonzero(np.diff(t) <= 0)
        end = t.size if falling.size == 0 else int(falling[0]) + 1
        return r[:end], t[:end]

    @property
    def turn_radius_px(self) -> float:
        """Radius (px) where pol's elevation stops increasing (or the table's end)."""
        return float(self._inverse[0][-1])

    @property
    def max_angle_rad(self) -> float:
        """Widest angle from the optical axis (-z in OCam's frame) the polynomial reaches, rad."""
        return math.pi / 2 + float(self._inverse[1][-1])

    def radius_of_elevation(self, t: ArrayLike) -> FloatArray:
        """r (px, before the affine) with atan2(pol(r), r) = t (rad), OCam's elevation; NaN past the turn."""
        t = np.asarray(t, dtype=np.float64)
        nodes_r, nodes_t = self._inverse
        r = np.interp(t, nodes_t, nodes_r)
        sin_t, cos_t = np.sin(t), np.cos(t)
        derivative = np.polynomial.polynomial.polyder(self.pol)
        for _ in range(NEWTON_STEPS):
            h = np.polynomial.polynomial.polyval(r, self.pol) * cos_t - r * sin_t
            dh = np.polynomial.polynomial.polyval(r, derivative) * cos_t - sin_t
            r = r - h / dh
        with np.errstate(invalid="ignore"):
            outside = (t < nodes_t[0]) | (t > nodes_t[-1])
        return np.where(outside, np.nan, r)

    def project(self, rays: ArrayLike) -> FloatArray:
        x_cv, y_cv, z_cv = as_rays(rays)
        x, y, z = y_cv, x_cv, -z_cv  # OpenCV frame -> OCam frame
        norm = np.hypot(x, y)
        r = self.radius_of_elevation(np.arctan2(z, norm))
        with np.errstate(invalid="ignore", divide="ignore"):
            scale = np.where(norm > 0, r / np.where(norm > 0, norm, 1.0), 0.0)
        xp, yp = x * scale, y * scale
        row = self.c * xp + self.d * yp + self.xc
        col = self.e * xp + yp + self.yc
        return pixels(col, row, np.isfinite(r))

    def world2cam(self, rays: ArrayLike) -> FloatArray:
        """OCamCalib's own world2cam, through ``invpol``: pixels (u, v) (..., 2) of rays in the OpenCV frame.
        What a user of the file gets; :meth:`project` inverts ``pol`` exactly instead."""
        x_cv, y_cv, z_cv = as_rays(rays)
        x, y, z = y_cv, x_cv, -z_cv
        norm = np.hypot(x, y)
        with np.errstate(invalid="ignore", divide="ignore"):
            rho = np.polynomial.polynomial.polyval(np.arctan(z / norm), self.invpol)
            xp, yp = x / norm * rho, y / norm * rho
        return pixels(self.e * xp + yp + self.yc, self.c * xp + self.d * yp + self.xc)

    def cam2world(self, uv: ArrayLike) -> FloatArray:
        """OCamCalib's own cam2world: unit rays (..., 3) in the OpenCV frame of pixels (u, v) (..., 2)."""
        p = np.asarray(uv, dtype=np.float64)
        drow, dcol = p[..., 1] - self.xc, p[..., 0] - self.yc
        det = self.c - self.d * self.e
        xp = (drow - self.d * dcol) / det
        yp = (-self.e * drow + self.c * dcol) / det
        zp = np.polynomial.polynomial.polyval(np.hypot(xp, yp), self.pol)
        ray = np.stack([yp, xp, -zp], axis=-1)
        return ray / np.linalg.norm(ray, axis=-1, keepdims=True)
