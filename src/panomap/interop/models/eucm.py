"""The enhanced unified camera model (Khomutenko, Garcia & Martinet 2016): Kalibr's ``eucm``, COLMAP's ``EUCM``.

Parameters, in this order: ``alpha, beta, fx, fy, cx, cy`` (Kalibr's ``intrinsics`` order; COLMAP
writes ``fx, fy, cx, cy, alpha, beta``: its reader reorders them).

    d = sqrt(beta (x^2 + y^2) + z^2),   m = alpha d + (1 - alpha) z
    u = fx x / m + cx,   v = fy y / m + cy

Seen where z > -w d, ``w = alpha/(1-alpha)`` if alpha <= 1/2 else ``(1-alpha)/alpha``. Frame and pixels
as in :mod:`.base`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike

from ...errors import PanomapError
from ...geometry import FloatArray
from .base import PinholeIntrinsics, as_rays, pixels, positive


@dataclass(frozen=True)
class EUCM(PinholeIntrinsics):
    name: ClassVar[str] = "eucm"

    alpha: float
    beta: float
    fx: float
    fy: float
    cx: float
    cy: float

    def check(self) -> None:
        super().check()
        positive(self.name, "beta", self.beta)
        if not 0 <= self.alpha <= 1:
            raise PanomapError(f"{self.name}: alpha must be in [0, 1], not {self.alpha:g}")

    @property
    def focal_px(self) -> float:
        return self.fx

    @property
    def w(self) -> float:
        if self.alpha >= 1:
            return 0.0
        return self.alpha / (1 - self.alpha) if self.alpha <= 0.5 else (1 - self.alpha) / self.alpha

    @property
    def max_angle_rad(self) -> float:
        # The edge z = -w d on the unit sphere: z^2 (1 - w^2 + w^2 beta) = w^2 beta, z < 0.
        w2b = self.w**2 * self.beta
        z = -math.sqrt(w2b / (1 - self.w**2 + w2b))
        return math.acos(z)

    def project(self, rays: ArrayLike) -> FloatArray:
        x, y, z = as_rays(rays)
        d = np.sqrt(self.beta * (x * x + y * y) + z * z)
        m = self.alpha * d + (1 - self.alpha) * z
        with np.errstate(invalid="ignore", divide="ignore"):
            seen = (z > -self.w * d + 1e-12 * d) & (m > 0)
            m = np.where(seen, m, 1.0)
        return pixels(self.fx * x / m + self.cx, self.fy * y / m + self.cy, seen)


@dataclass(frozen=True)
class ColmapEUCM(EUCM):
    """COLMAP's ``EUCM``: the same equations, but COLMAP refuses rays at or behind the image plane
    (z <= 0), so its camera sees below 90 deg from the axis only."""

    name: ClassVar[str] = "colmap-eucm"
    max_angle_limit_rad: ClassVar[float] = math.pi / 2

    @property
    def max_angle_rad(self) -> float:
        return min(super().max_angle_rad, math.pi / 2)

    def project(self, rays: ArrayLike) -> FloatArray:
        uv = super().project(rays)
        _, _, z = as_rays(rays)
        return np.where((z > 0)[..., None], uv, np.nan)
