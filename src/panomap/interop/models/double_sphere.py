"""The double sphere model (Usenko, Demmel & Cremers 2018): Kalibr's ``ds``, Basalt's ``ds``.

Parameters, in this order (Kalibr's ``intrinsics``): ``xi, alpha, fx, fy, cx, cy``.

    d1 = |P|,   d2 = sqrt(x^2 + y^2 + (xi d1 + z)^2)
    m = alpha d2 + (1 - alpha) (xi d1 + z)
    u = fx x / m + cx,   v = fy y / m + cy

Seen where z > -w2 d1, ``w1 = alpha/(1-alpha)`` if alpha <= 1/2 else ``(1-alpha)/alpha``,
``w2 = (w1 + xi) / sqrt(2 w1 xi + xi^2 + 1)`` (the paper's eq. 43). Frame and pixels as in :mod:`.base`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike

from ...errors import PanomapError
from ...geometry import FloatArray
from .base import PinholeIntrinsics, as_rays, pixels


@dataclass(frozen=True)
class DoubleSphere(PinholeIntrinsics):
    name: ClassVar[str] = "double-sphere"

    xi: float
    alpha: float
    fx: float
    fy: float
    cx: float
    cy: float

    def check(self) -> None:
        super().check()
        if not 0 <= self.alpha < 1:
            raise PanomapError(f"{self.name}: alpha must be in [0, 1), not {self.alpha:g}")
        if not -1 < self.xi < 1:
            raise PanomapError(f"{self.name}: xi must be in (-1, 1), not {self.xi:g}")

    @property
    def focal_px(self) -> float:
        return self.fx / ((1 + self.xi) * (1 - self.alpha) + self.alpha * (1 + self.xi))

    @property
    def bound(self) -> float:
        """w2: a ray is seen where z / |P| > -w2."""
        w1 = self.alpha / (1 - self.alpha) if self.alpha <= 0.5 else (1 - self.alpha) / self.alpha
        return (w1 + self.xi) / math.sqrt(2 * w1 * self.xi + self.xi**2 + 1)

    @property
    def max_angle_rad(self) -> float:
        return math.acos(-self.bound)

    def project(self, rays: ArrayLike) -> FloatArray:
        x, y, z = as_rays(rays)
        d1 = np.sqrt(x * x + y * y + z * z)
        k = self.xi * d1 + z
        d2 = np.sqrt(x * x + y * y + k * k)
        m = self.alpha * d2 + (1 - self.alpha) * k
        with np.errstate(invalid="ignore", divide="ignore"):
            seen = z > -self.bound * d1 + 1e-12 * d1
            m = np.where(seen, m, 1.0)
        return pixels(self.fx * x / m + self.cx, self.fy * y / m + self.cy, seen)
