"""Kannala-Brandt (2006): OpenCV's ``cv::fisheye``, Kalibr's ``pinhole-equidistant``, COLMAP's ``OPENCV_FISHEYE``.

Parameters, in this order: ``fx, fy, cx, cy`` (px), ``k1, k2, k3, k4``.

    theta = atan2(hypot(x, y), z)                 (angle from the optical axis, 0..pi: past 90 deg too)
    theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)
    u = fx theta_d x / hypot(x, y) + cx,   v = fy theta_d y / hypot(x, y) + cy

Frame and pixels as in :mod:`.base` (OpenCV's and Kalibr's own; COLMAP's readers shift the centre by
0.5 px). OpenCV computes ``theta = atan(hypot(x/z, y/z))``, which equals the above only for z > 0:
``cv2.fisheye`` cannot hold a ray at or past 90 deg from the axis (its ``undistortPoints`` returns
x/z, y/z). cv::fisheye's skew ``alpha`` is not read (0).

The valid range is from the axis to where theta_d stops increasing (or pi; below 90 deg for
:class:`OpenCVFisheye`, as OpenCV and COLMAP compute it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike

from ...geometry import FloatArray
from .base import PinholeIntrinsics, as_rays, pixels


def first_turn(poly: FloatArray, limit: float) -> float:
    """The first angle in (0, limit] where theta_d(theta) = theta * poly(theta^2) stops increasing."""
    theta = np.linspace(0.0, limit, 20001)
    theta_d = theta * np.polynomial.polynomial.polyval(theta**2, poly)
    falling = np.flatnonzero(np.diff(theta_d) <= 0)
    return limit if falling.size == 0 else float(theta[falling[0]])


@dataclass(frozen=True)
class KannalaBrandt(PinholeIntrinsics):
    name: ClassVar[str] = "kannala-brandt"

    fx: float
    fy: float
    cx: float
    cy: float
    k1: float = 0.0
    k2: float = 0.0
    k3: float = 0.0
    k4: float = 0.0

    @property
    def focal_px(self) -> float:
        return self.fx

    @property
    def max_angle_rad(self) -> float:
        """Widest angle from the axis (rad) before theta_d turns back (``max_angle_limit_rad`` at most)."""
        return first_turn(np.array([1.0, self.k1, self.k2, self.k3, self.k4]), self.max_angle_limit_rad)

    def project(self, rays: ArrayLike) -> FloatArray:
        x, y, z = as_rays(rays)
        r = np.hypot(x, y)
        theta = np.arctan2(r, z)
        t2 = theta * theta
        theta_d = theta * (1 + t2 * (self.k1 + t2 * (self.k2 + t2 * (self.k3 + t2 * self.k4))))
        with np.errstate(invalid="ignore", divide="ignore"):
            scale = np.where(r > 0, theta_d / np.where(r > 0, r, 1.0), 1.0)
        return pixels(self.fx * x * scale + self.cx, self.fy * y * scale + self.cy, theta <= self.max_angle_rad)


@dataclass(frozen=True)
class OpenCVFisheye(KannalaBrandt):
    """Kannala-Brandt as ``cv2.fisheye`` and COLMAP's ``OPENCV_FISHEYE`` compute it: theta = atan(r) of
    (x/z, y/z), so only rays below 90 deg from the axis exist (the same equations, a narrower range)."""

    name: ClassVar[str] = "opencv-fisheye"
    max_angle_limit_rad: ClassVar[float] = math.pi / 2 - 1e-6
