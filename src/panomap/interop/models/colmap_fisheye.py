"""COLMAP's own fisheye models: ``FOV``, ``SIMPLE_RADIAL_FISHEYE``, ``RADIAL_FISHEYE``, ``THIN_PRISM_FISHEYE``.

Parameters as COLMAP orders them, with the principal point in **panomap's pixels** (COLMAP's cx, cy
minus 0.5: its readers and writers shift it, since COLMAP puts the centre of the top-left pixel at
(0.5, 0.5)). Each model works on the normalised point (a, b) = (x/z, y/z), r = hypot(a, b):

- ``FOV`` (Devernay & Faugeras): ``fx, fy, cx, cy, omega``;
  ``(a, b) *= atan(2 r tan(omega/2)) / (omega r)`` (1 where omega or r is 0). Below omega = 0.01 COLMAP
  switches to its series ``1 - omega^2/12 + omega^2 r^2/3`` (``colmap-fov``; Kalibr's ``fov``
  distortion, the same model, keeps the closed form down to omega = 0: ``fov``).
- ``SIMPLE_RADIAL_FISHEYE``: ``f, cx, cy, k``; ``RADIAL_FISHEYE``: ``f, cx, cy, k1, k2``:
  ``theta = atan(r)``, ``(a, b) *= theta (1 + k1 theta^2 + k2 theta^4) / r``.
- ``THIN_PRISM_FISHEYE``: ``fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, sx1, sy1``:
  ``(a', b') = (a, b) atan(r) / r``, ``s2 = a'^2 + b'^2``,
  ``R = k1 s2 + k2 s2^2 + k3 s2^3 + k4 s2^4``,
  ``a'' = a' (1 + R) + 2 p1 a' b' + p2 (s2 + 2 a'^2) + sx1 s2``,
  ``b'' = b' (1 + R) + 2 p2 a' b' + p1 (s2 + 2 b'^2) + sy1 s2``.

Then ``u = fx a + cx``, ``v = fy b + cy``. COLMAP divides by z: rays at or past 90 deg from the axis
are not seen (and the radius must still grow with the angle).
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


class _Normalised(ExternalCamera):
    """A model of the normalised point (a, b): ``distort`` it, then scale and shift."""

    max_angle_limit_rad: ClassVar[float] = math.pi / 2

    def scales(self) -> tuple[float, float, float, float]:
        """fx, fy, cx, cy."""
        raise NotImplementedError

    def distort(self, a: FloatArray, b: FloatArray) -> tuple[FloatArray, FloatArray]:
        raise NotImplementedError

    def check(self) -> None:
        fx, fy, _, _ = self.scales()
        positive(self.name, "the focal length", min(fx, fy))

    @property
    def principal_point(self) -> tuple[float, float]:
        return self.scales()[2:]

    @property
    def focal_px(self) -> float:
        return self.scales()[0]

    @property
    def max_angle_rad(self) -> float:
        """Widest angle (rad) before the distorted radius stops growing (below 90 deg)."""
        angle = np.linspace(0.0, math.pi / 2, 20001)[1:-1]
        a, _ = self.distort(np.tan(angle), np.zeros_like(angle))
        bad = np.flatnonzero(np.diff(a) <= 0)
        return float(angle[-1] if bad.size == 0 else angle[bad[0]])

    def project(self, rays: ArrayLike) -> FloatArray:
        x, y, z = as_rays(rays)
        seen = np.arctan2(np.hypot(x, y), z) < self.max_angle_rad
        zz = np.where(seen, z, 1.0)
        a, b = self.distort(x / zz, y / zz)
        fx, fy, cx, cy = self.scales()
        return pixels(fx * a + cx, fy * b + cy, seen)


def _equidistant(a: FloatArray, b: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """theta = atan(r) and the scale theta / r (1 at r = 0)."""
    r = np.hypot(a, b)
    theta = np.arctan(r)
    return theta, np.where(r > 1e-12, theta / np.where(r > 1e-12, r, 1.0), 1.0), r


@dataclass(frozen=True)
class FOV(_Normalised):
    """The FOV model in its closed form (Kalibr's ``fov`` distortion; its ``w`` is ``omega``)."""

    name: ClassVar[str] = "fov"

    fx: float
    fy: float
    cx: float
    cy: float
    omega: float

    def scales(self) -> tuple[float, float, float, float]:
        return (self.fx, self.fy, self.cx, self.cy)

    def check(self) -> None:
        super().check()
        if not abs(self.omega) < math.pi:  # tan(omega/2) turns at pi: the radius no longer grows
            raise PanomapError(f"{self.name}: omega must be in (-pi, pi), not {self.omega:g}")

    def distort(self, a: FloatArray, b: FloatArray) -> tuple[FloatArray, FloatArray]:
        r = np.hypot(a, b)
        if abs(self.omega) < 1e-9:
            return a, b
        small = r < 1e-12
        safe = np.where(small, 1.0, r)
        factor = np.where(
            small,
            2 * math.tan(self.omega / 2) / self.omega,
            np.arctan(2 * safe * math.tan(self.omega / 2)) / (self.omega * safe),
        )
        return a * factor, b * factor


# Below this omega COLMAP's FOV uses its series (its ``omega^2 < 1e-4``).
COLMAP_FOV_SERIES_OMEGA = 0.01


@dataclass(frozen=True)
class ColmapFOV(FOV):
    """COLMAP's ``FOV``: the closed form, and COLMAP's own series below omega = 0.01 (as its
    ``FOVCameraModel::Distortion`` writes it: ``1 - omega^2/12 + omega^2 r^2/3``)."""

    name: ClassVar[str] = "colmap-fov"

    def distort(self, a: FloatArray, b: FloatArray) -> tuple[FloatArray, FloatArray]:
        if abs(self.omega) >= COLMAP_FOV_SERIES_OMEGA:
            return super().distort(a, b)
        omega2 = self.omega * self.omega
        factor = 1 - omega2 / 12 + omega2 * (a * a + b * b) / 3
        return a * factor, b * factor


@dataclass(frozen=True)
class ColmapRadialFisheye(_Normalised):
    """``SIMPLE_RADIAL_FISHEYE`` (k2 = 0) and ``RADIAL_FISHEYE``."""

    name: ClassVar[str] = "colmap-radial-fisheye"

    f: float
    cx: float
    cy: float
    k1: float = 0.0
    k2: float = 0.0

    def scales(self) -> tuple[float, float, float, float]:
        return (self.f, self.f, self.cx, self.cy)

    def distort(self, a: FloatArray, b: FloatArray) -> tuple[FloatArray, FloatArray]:
        theta, scale, _ = _equidistant(a, b)
        t2 = theta * theta
        factor = scale * (1 + t2 * (self.k1 + t2 * self.k2))
        return a * factor, b * factor


@dataclass(frozen=True)
class ColmapThinPrismFisheye(_Normalised):
    name: ClassVar[str] = "colmap-thin-prism-fisheye"

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
    sx1: float = 0.0
    sy1: float = 0.0

    def scales(self) -> tuple[float, float, float, float]:
        return (self.fx, self.fy, self.cx, self.cy)

    def distort(self, a: FloatArray, b: FloatArray) -> tuple[FloatArray, FloatArray]:
        _, scale, _ = _equidistant(a, b)
        a, b = a * scale, b * scale
        s2 = a * a + b * b
        radial = s2 * (self.k1 + s2 * (self.k2 + s2 * (self.k3 + s2 * self.k4)))
        return (
            a * (1 + radial) + 2 * self.p1 * a * b + self.p2 * (s2 + 2 * a * a) + self.sx1 * s2,
            b * (1 + radial) + 2 * self.p2 * a * b + self.p1 * (s2 + 2 * b * b) + self.sy1 * s2,
        )
