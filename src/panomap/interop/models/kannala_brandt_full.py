"""Kannala & Brandt's full model (2006) as BoofCV writes it (``kannala_brandt``): symmetric and asymmetric terms.

Parameters, in this order: ``fx, fy, cx, cy`` (px), ``skew`` (px), ``symmetric`` (k1, k2, ...: any count,
at least one), ``radial`` and ``tangent`` (l1, l2, ... and m1, m2, ...: any count, the same), and
``radial_trig``, ``tangent_trig`` (i1..i4 and j1..j4: four each, or none). As BoofCV's
``KannalaBrandtStoP_F64`` computes it:

    theta = acos(z / |P|)   (0..pi: past 90 deg too),   phi = atan2(y, x)
    poly(c, theta) = c1 theta + c2 theta^3 + c3 theta^5 + ...
    trig(c, phi) = c1 cos(phi) + c2 sin(phi) + c3 sin(2 phi) + c4 cos(2 phi)   (0 without coefficients)
    r = poly(symmetric, theta),   dr = poly(radial, theta) trig(radial_trig, phi),
    dt = poly(tangent, theta) trig(tangent_trig, phi)
    xd = (r + dr) cos(phi) - dt sin(phi),   yd = (r + dr) sin(phi) + dt cos(phi)
    u = fx xd + skew yd + cx,   v = fy yd + cy

(BoofCV's class comment lists ``c3 cos(2 phi) + c4 sin(2 phi)``; its code, followed here, puts sin(2 phi)
third.) With no asymmetric terms and skew 0 this is :class:`.kannala_brandt.KannalaBrandt` with fx and fy
times k1. Frame and pixels as in :mod:`.base` (BoofCV's own: x right, y down, pixel centres at integers).
The valid range runs from the axis to where the image radius first stops increasing, in any of 72
azimuths (or pi).
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

# Azimuths over which the valid range is checked (the asymmetric terms make it vary with phi).
RANGE_AZIMUTHS = 72


def odd_polynomial(coefficients: tuple[float, ...], theta: FloatArray) -> FloatArray:
    """c1 theta + c2 theta^3 + c3 theta^5 + ... (0 without coefficients)."""
    result = np.zeros_like(theta)
    power = theta
    for c in coefficients:
        result = result + c * power
        power = power * theta * theta
    return result


def trig(coefficients: tuple[float, ...], cos: FloatArray, sin: FloatArray) -> FloatArray:
    """c1 cos(phi) + c2 sin(phi) + c3 sin(2 phi) + c4 cos(2 phi) (0 without coefficients)."""
    if not coefficients:
        return np.zeros_like(cos)
    c1, c2, c3, c4 = coefficients
    return c1 * cos + c2 * sin + c3 * 2 * cos * sin + c4 * (2 * cos * cos - 1)


@dataclass(frozen=True)
class KannalaBrandtFull(PinholeIntrinsics):
    name: ClassVar[str] = "kannala-brandt-full"

    fx: float
    fy: float
    cx: float
    cy: float
    skew: float = 0.0
    symmetric: tuple[float, ...] = (1.0,)
    radial: tuple[float, ...] = ()
    tangent: tuple[float, ...] = ()
    radial_trig: tuple[float, ...] = ()
    tangent_trig: tuple[float, ...] = ()

    def check(self) -> None:
        super().check()
        if not self.symmetric:
            raise PanomapError(f"{self.name}: symmetric needs at least one coefficient")
        if not self.symmetric[0] > 0:
            raise PanomapError(f"{self.name}: symmetric[0] (the radius per radian at the axis) must be > 0")
        for name in ("radial_trig", "tangent_trig"):
            if len(getattr(self, name)) not in (0, 4):
                raise PanomapError(f"{self.name}: {name} has {len(getattr(self, name))} values, expected 0 or 4")

    @property
    def focal_px(self) -> float:
        return self.fx * self.symmetric[0]

    def _normalised(self, theta: FloatArray, cos: FloatArray, sin: FloatArray) -> tuple[FloatArray, FloatArray]:
        r = odd_polynomial(self.symmetric, theta)
        dr = odd_polynomial(self.radial, theta) * trig(self.radial_trig, cos, sin)
        dt = odd_polynomial(self.tangent, theta) * trig(self.tangent_trig, cos, sin)
        return (r + dr) * cos - dt * sin, (r + dr) * sin + dt * cos

    @property
    def max_angle_rad(self) -> float:
        """Widest angle from the axis (rad) before the image radius turns back in any azimuth (pi at most)."""
        theta = np.linspace(0.0, math.pi, 4001)[:, None]
        phi = 2 * math.pi * np.arange(RANGE_AZIMUTHS)[None, :] / RANGE_AZIMUTHS
        xd, yd = self._normalised(theta, np.cos(phi), np.sin(phi))
        radius = np.hypot(self.fx * xd + self.skew * yd, self.fy * yd)
        falling = np.flatnonzero(np.any(np.diff(radius, axis=0) <= 0, axis=1))
        return math.pi if falling.size == 0 else float(theta[falling[0], 0])

    def project(self, rays: ArrayLike) -> FloatArray:
        x, y, z = as_rays(rays)
        norm = np.sqrt(x * x + y * y + z * z)
        with np.errstate(invalid="ignore", divide="ignore"):
            theta = np.arccos(np.clip(z / norm, -1.0, 1.0))
        phi = np.arctan2(y, x)
        xd, yd = self._normalised(theta, np.cos(phi), np.sin(phi))
        return pixels(self.fx * xd + self.skew * yd + self.cx, self.fy * yd + self.cy, theta <= self.max_angle_rad)
