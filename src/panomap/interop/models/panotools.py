"""PanoTools' lens (Hugin's and PTGui's ``.pto`` image lines): an ideal projection, the a, b, c, d polynomial, a shift.

Parameters, in this order: ``f`` (px per rad for the fisheye; px for the rectilinear lens), ``cx``, ``cy`` (px, the
optical centre: the image centre moved by the shift), ``a``, ``b``, ``c`` (the radial polynomial) and ``r_norm``
(px, the polynomial's reference radius: half the smaller image side).

    alpha = atan2(hypot(x, y), z)                      (angle from the optical axis)
    r_ideal = f alpha                                  (fisheye, ``f2``/``f3``: equidistant)
    r_ideal = f tan(alpha)                             (rectilinear, ``f0``; below 90 deg)
    R = r_ideal / r_norm
    r = r_ideal (a R^3 + b R^2 + c R + d),   d = 1 - a - b - c
    u = cx + r x / hypot(x, y),   v = cy + r y / hypot(x, y)

PanoTools (libpano13 ``math.c``, Hugin ``SpaceTransform::Init``) maps a panorama's point to the image by a stack:
the ideal image's coordinates (centred, px, y down) are scaled by ``radial`` (the polynomial above, its radius
normalised by ``min(w, h) / 2``), shifted by ``horiz``/``vert`` (``d``, ``e``: px), then the image's centre
``(w/2 - 0.5, h/2 - 0.5)`` is added (``transformImgCoord``): so ``cx = w/2 - 0.5 + d``, ``cy = h/2 - 0.5 + e``,
pixel centres at whole numbers as panomap's. The ideal fisheye has ``f = w / hfov`` (rad; PanoTools' ``distance``
times its ``scale``), the rectilinear ``f = (w/2) / tan(hfov/2)``. The frame is OpenCV's (x right, y down, z ahead),
as PanoTools' own image frame.

The valid range is from the axis to where ``r`` stops increasing (PanoTools' correction radius) or stops being
positive, and at most 180 deg (the fisheye) or 90 deg (the rectilinear lens).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike

from ...errors import PanomapError
from ...geometry import FloatArray
from .base import ExternalCamera, as_rays, pixels, positive

# Angles sampled to find where the radius stops increasing.
TURN_SAMPLES = 20001


@dataclass(frozen=True)
class PanoToolsFisheye(ExternalCamera):
    """PanoTools' equidistant fisheye (``f2`` circular, ``f3`` full frame) with its radial polynomial and shift."""

    name: ClassVar[str] = "panotools-fisheye"

    f: float
    cx: float
    cy: float
    a: float = 0.0
    b: float = 0.0
    c: float = 0.0
    r_norm: float = 1.0

    def check(self) -> None:
        positive(self.name, "f", self.f)
        positive(self.name, "r_norm", self.r_norm)
        if self.max_angle_rad <= 0:
            raise PanomapError(f"{self.name}: a, b, c = {self.a:g}, {self.b:g}, {self.c:g} make no image radius")

    @property
    def d(self) -> float:
        """The polynomial's constant term, ``1 - a - b - c``."""
        return 1.0 - self.a - self.b - self.c

    @property
    def principal_point(self) -> tuple[float, float]:
        return (self.cx, self.cy)

    @property
    def focal_px(self) -> float:
        return self.f

    def ideal_radius(self, alpha: FloatArray) -> FloatArray:
        """The ideal lens's radius (px) at angles (rad) from the axis."""
        return self.f * alpha

    def radius(self, alpha: FloatArray) -> FloatArray:
        """The image's radius (px) at angles (rad) from the axis: the ideal radius through the polynomial."""
        ideal = self.ideal_radius(alpha)
        big_r = ideal / self.r_norm
        return ideal * (((self.a * big_r + self.b) * big_r + self.c) * big_r + self.d)

    @property
    def max_angle_rad(self) -> float:
        """Widest angle from the axis (rad) before the radius stops increasing or being positive."""
        alpha = np.linspace(0.0, self.max_angle_limit_rad, TURN_SAMPLES)
        r = self.radius(alpha)
        bad = np.flatnonzero((np.diff(r) <= 0) | (r[1:] <= 0))
        return self.max_angle_limit_rad if bad.size == 0 else float(alpha[bad[0]])

    def project(self, rays: ArrayLike) -> FloatArray:
        x, y, z = as_rays(rays)
        h = np.hypot(x, y)
        alpha = np.arctan2(h, z)
        seen = alpha <= self.max_angle_rad
        r = self.radius(np.where(seen, alpha, 0.0))
        with np.errstate(invalid="ignore", divide="ignore"):
            scale = np.where(h > 0, r / np.where(h > 0, h, 1.0), 0.0)
        return pixels(self.cx + x * scale, self.cy + y * scale, seen)


@dataclass(frozen=True)
class PanoToolsRectilinear(PanoToolsFisheye):
    """PanoTools' rectilinear lens (``f0``): ``r_ideal = f tan(alpha)``, the same polynomial and shift."""

    name: ClassVar[str] = "panotools-rectilinear"
    max_angle_limit_rad: ClassVar[float] = math.pi / 2 - 1e-6

    def ideal_radius(self, alpha: FloatArray) -> FloatArray:
        return self.f * np.tan(alpha)
