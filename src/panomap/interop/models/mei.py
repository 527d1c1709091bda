"""Mei's unified model (Mei & Rives 2007): OpenCV's ``cv::omnidir``, Kalibr's ``omni`` (+ ``radtan`` or ``none``),
BoofCV's ``omnidirectional_universal``.

Parameters, in this order: ``xi``, ``fx, fy, cx, cy`` (px), ``k1, k2, p1, p2`` (radtan; 0 for none),
``skew`` (cv::omnidir's K[0, 1], BoofCV's ``skew``; Kalibr has none), ``k_more`` (the radial
coefficients of r2^3, r2^4, ...: BoofCV's ``radial`` list past its second; empty for the others).

    (xs, ys, zs) = P / |P|;   x = xs / (zs + xi),   y = ys / (zs + xi),   r2 = x^2 + y^2
    radial = 1 + k1 r2 + k2 r2^2 + k_more[0] r2^3 + k_more[1] r2^4 + ...
    xd = x radial + 2 p1 x y + p2 (r2 + 2 x^2)
    yd = y radial + p1 (r2 + 2 y^2) + 2 p2 x y
    u = fx xd + skew yd + cx,   v = fy yd + cy

Frame and pixels as in :mod:`.base`. A ray is seen where zs > -1/xi (xi > 1) or zs > -xi (xi <= 1), as
Kalibr's ``OmniProjection`` and OpenCV decide.
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


def radtan(
    x: FloatArray, y: FloatArray, k1: float, k2: float, p1: float, p2: float, more: tuple[float, ...] = ()
) -> tuple[FloatArray, FloatArray]:
    """OpenCV's radial-tangential distortion of normalised coordinates: radial 1 + k1 r2 + k2 r2^2 and
    ``more`` (the coefficients of r2^3, r2^4, ...; none: OpenCV's k3 = 0)."""
    r2 = x * x + y * y
    radial = 1 + r2 * (k1 + r2 * k2)
    power = r2 * r2
    for k in more:
        power = power * r2
        radial = radial + k * power
    return (
        x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x),
        y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y,
    )


@dataclass(frozen=True)
class Mei(PinholeIntrinsics):
    name: ClassVar[str] = "mei"

    xi: float
    fx: float
    fy: float
    cx: float
    cy: float
    k1: float = 0.0
    k2: float = 0.0
    p1: float = 0.0
    p2: float = 0.0
    skew: float = 0.0
    k_more: tuple[float, ...] = ()

    def check(self) -> None:
        super().check()
        if self.xi < 0:
            raise PanomapError(f"{self.name}: xi must be >= 0, not {self.xi:g}")

    @property
    def focal_px(self) -> float:
        return self.fx / (1 + self.xi)

    @property
    def max_angle_rad(self) -> float:
        """Widest angle from the axis (rad) the model sees."""
        bound = -1 / self.xi if self.xi > 1 else -self.xi
        return math.acos(bound)

    def project(self, rays: ArrayLike) -> FloatArray:
        x, y, z = as_rays(rays)
        norm = np.sqrt(x * x + y * y + z * z)
        zs = z / norm
        bound = -1 / self.xi if self.xi > 1 else -self.xi
        with np.errstate(invalid="ignore", divide="ignore"):
            seen = zs > bound + 1e-12
            denominator = np.where(seen, zs + self.xi, 1.0)
            xd, yd = radtan(
                x / norm / denominator, y / norm / denominator, self.k1, self.k2, self.p1, self.p2, self.k_more
            )
        return pixels(self.fx * xd + self.skew * yd + self.cx, self.fy * yd + self.cy, seen)
