"""A pinhole with radial-tangential distortion: Kalibr's ``pinhole`` + ``radtan``, OpenCV's plain model (its
rational form of eight coefficients), Basalt's ``pinhole-radtan8``.

Parameters, in this order (OpenCV's and Basalt's): ``fx, fy, cx, cy`` (px), ``k1, k2, p1, p2``,
``k3, k4, k5, k6`` (0 for Kalibr's radtan, and OpenCV's four-coefficient form).

    x = X / Z,   y = Y / Z,   r2 = x^2 + y^2
    d = (1 + k1 r2 + k2 r2^2 + k3 r2^3) / (1 + k4 r2 + k5 r2^2 + k6 r2^3)
    xd = x d + 2 p1 x y + p2 (r2 + 2 x^2),   yd = y d + p1 (r2 + 2 y^2) + 2 p2 x y
    u = fx xd + cx,   v = fy yd + cy

Seen where Z > 0 and the distorted radius r d still grows with the angle (Basalt's ``rpmax`` cuts at
0.85 of its estimate of that place, a margin of its own, not applied here). Frame and pixels as in
:mod:`.base`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike

from ...geometry import FloatArray
from .base import PinholeIntrinsics, as_rays, pixels


@dataclass(frozen=True)
class PinholeRadtan(PinholeIntrinsics):
    name: ClassVar[str] = "pinhole-radtan"
    max_angle_limit_rad: ClassVar[float] = math.pi / 2

    fx: float
    fy: float
    cx: float
    cy: float
    k1: float = 0.0
    k2: float = 0.0
    p1: float = 0.0
    p2: float = 0.0
    k3: float = 0.0
    k4: float = 0.0
    k5: float = 0.0
    k6: float = 0.0

    @property
    def focal_px(self) -> float:
        return self.fx

    def radial_factor(self, r2: FloatArray) -> FloatArray:
        """d of squared normalised radii: NaN where its denominator is not positive."""
        numerator = 1 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3))
        denominator = 1 + r2 * (self.k4 + r2 * (self.k5 + r2 * self.k6))
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(denominator > 0, numerator / np.where(denominator > 0, denominator, 1.0), np.nan)

    @property
    def max_angle_rad(self) -> float:
        """Widest angle (rad) before the distorted radius r d stops increasing (or d's denominator reaches 0)."""
        angle = np.linspace(0.0, math.pi / 2, 20001)[:-1]
        r = np.tan(angle)
        grows = np.diff(r * self.radial_factor(r * r)) > 0
        bad = np.flatnonzero(~grows)
        return float(angle[-1] if bad.size == 0 else angle[bad[0]])

    def project(self, rays: ArrayLike) -> FloatArray:
        x, y, z = as_rays(rays)
        seen = np.arctan2(np.hypot(x, y), z) < self.max_angle_rad
        zz = np.where(seen, z, 1.0)
        a, b = x / zz, y / zz
        r2 = a * a + b * b
        d = self.radial_factor(r2)
        xd = a * d + 2 * self.p1 * a * b + self.p2 * (r2 + 2 * a * a)
        yd = b * d + self.p1 * (r2 + 2 * b * b) + 2 * self.p2 * a * b
        return pixels(self.fx * xd + self.cx, self.fy * yd + self.cy, seen)
