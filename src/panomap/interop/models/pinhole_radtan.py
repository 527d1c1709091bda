"""A pinhole with radial-tangential distortion: Kalibr's ``pinhole`` + ``radtan``, OpenCV's plain model (k3 = 0).

Parameters, in this order: ``fx, fy, cx, cy`` (px), ``k1, k2, p1, p2``.

    x = X / Z,   y = Y / Z,   (xd, yd) = radtan(x, y)  (as in :mod:`.mei`)
    u = fx xd + cx,   v = fy yd + cy

Seen where Z > 0 and the distorted radius still grows with the angle. Frame and pixels as in :mod:`.base`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike

from ...geometry import FloatArray
from .base import PinholeIntrinsics, as_rays, pixels
from .mei import radtan


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

    @property
    def focal_px(self) -> float:
        return self.fx

    @property
    def max_angle_rad(self) -> float:
        """Widest angle (rad) before the radial factor r (1 + k1 r^2 + k2 r^4) stops increasing."""
        angle = np.linspace(0.0, math.pi / 2, 20001)[:-1]
        r = np.tan(angle)
        grows = np.diff(r * (1 + r * r * (self.k1 + r * r * self.k2))) > 0
        bad = np.flatnonzero(~grows)
        return float(angle[-1] if bad.size == 0 else angle[bad[0]])

    def project(self, rays: ArrayLike) -> FloatArray:
        x, y, z = as_rays(rays)
        seen = np.arctan2(np.hypot(x, y), z) < self.max_angle_rad
        zz = np.where(seen, z, 1.0)
        xd, yd = radtan(x / zz, y / zz, self.k1, self.k2, self.p1, self.p2)
        return pixels(self.fx * xd + self.cx, self.fy * yd + self.cy, seen)
