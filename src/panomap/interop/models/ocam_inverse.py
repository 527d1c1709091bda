"""OCamCalib's inverse polynomial alone, in the OpenCV frame: OpenCalib's (PJLab SensorsCalibration) OCam files.

OpenCalib's surround-view tool (``surround-camera/manual_calib``, ``run_avm.cpp``) keeps of an OCamCalib
calibration only the inverse polynomial ``invpol`` (``cam_dist``), the centre and the affine (``cam_K`` =
[[c, d, u0], [e, 1, v0], [0, 0, 1]]) and projects with its own ``world2cam``. Parameters, in this order:
``invpol`` (ascending), ``u0`` (the centre's **column**), ``v0`` (its **row**), both from 0 at the top-left
pixel's centre (the tool samples with ``cv::remap``), the affine ``c, d, e``, and the image ``width, height``.

The tool's equations, for a direction (X, Y, Z) of the OpenCV frame (x right, y down, z forward), as its
code has them (``distortPointsOcam`` builds M = (X/Z, Y/Z, -1): OCam's z axis points away from the scene)::

    x = X/Z, y = Y/Z, norm = hypot(x, y),  t = atan(-1 / norm),  rho = sum_i invpol[i] t^i
    u = c (x/norm) rho + d (y/norm) rho + u0,   v = e (x/norm) rho + (y/norm) rho + v0

Unlike OCamCalib's own ``world2cam`` (:mod:`.ocam`: ``row = c x' + d y' + xc`` in OCam's frame, x along
the rows), the affine here acts on (column, row): c and d give the column, e the row.

**Beyond 90 deg.** The code divides by Z, so it is meaningful for Z > 0 only (a direction behind the
image plane lands on the point opposite the centre). Its elevation ``t = atan(-1/norm)`` is
``atan2(-Z, hypot(X, Y))`` for Z > 0, and that form goes on smoothly through Z = 0: the lens's own
equation, which this model uses everywhere. OCamCalib fits ``invpol`` over elevations from -pi/2 up to
where its radius reaches the image's half diagonal (``findinvpoly``: t up to 1.2 rad), so a full-frame
fisheye's polynomial holds past 90 deg off the axis (t > 0) as far as the image reaches. The model's
range runs from the axis to where ``rho`` stops increasing or passes the image's farthest corner.
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
from .ocam import MAX_COEFFICIENTS, NEWTON_STEPS, check_affine

# The tabulated polynomial: this many elevations from -pi/2 to pi/2.
_NODES = 8193


@dataclass(frozen=True)
class OCamInverse(ExternalCamera):
    name: ClassVar[str] = "ocam-invpol"

    invpol: tuple[float, ...]
    u0: float
    v0: float
    c: float
    d: float
    e: float
    width: int
    height: int

    def check(self) -> None:
        if not 2 <= len(self.invpol) <= MAX_COEFFICIENTS:
            raise PanomapError(
                f"{self.name}: invpol has {len(self.invpol)} coefficients; from 2 to {MAX_COEFFICIENTS} "
                "(OCamCalib writes about 10 to 20)"
            )
        positive(self.name, "width", self.width)
        positive(self.name, "height", self.height)
        check_affine(self.name, self.c, self.d, self.e)

    @property
    def principal_point(self) -> tuple[float, float]:
        return (self.u0, self.v0)

    @property
    def focal_px(self) -> float:
        """px per rad near the axis: the polynomial's slope at t = -pi/2."""
        slope = np.polynomial.polynomial.polyval(-math.pi / 2, np.polynomial.polynomial.polyder(self.invpol))
        return float(slope) if slope > 0 else 1.0

    @property
    def image_reach_px(self) -> float:
        """Distance (px) from the centre to the farthest image corner."""
        return farthest_corner_px(self.principal_point, self.width, self.height)

    @cached_property
    def _nodes(self) -> tuple[FloatArray, FloatArray]:
        """Elevations t (rad) and their radii rho (px, before the affine) over the valid range: from the axis
        (t = -pi/2) to where rho stops increasing or first reaches the farthest corner's radius (the corner's
        pixel offset divided by the affine's smallest stretch, and 1 px)."""
        t = np.linspace(-math.pi / 2, math.pi / 2, _NODES)
        rho = np.asarray(np.polynomial.polynomial.polyval(t, self.invpol), dtype=np.float64)
        stretch = np.linalg.svd(np.array([[self.c, self.d], [self.e, 1.0]]), compute_uv=False)[-1]
        falling = np.flatnonzero(np.diff(rho) <= 0)
        end = t.size if falling.size == 0 else int(falling[0]) + 1
        past = np.flatnonzero(rho[:end] > self.image_reach_px / stretch + 1.0)
        if past.size:
            end = int(past[0]) + 1
        return t[:end], rho[:end]

    @property
    def axis_radius_px(self) -> float:
        """rho at the axis (t = -pi/2), px: where the rays next to the axis land from the centre (0 for an exact
        inverse; OCamCalib fits it within 0.01 px)."""
        return float(np.polynomial.polynomial.polyval(-math.pi / 2, self.invpol))

    @property
    def reach_px(self) -> float:
        """rho (px) at the end of the valid range."""
        return float(self._nodes[1][-1])

    @property
    def max_angle_rad(self) -> float:
        """Widest angle from the optical axis the model reaches, rad."""
        return math.pi / 2 + float(self._nodes[0][-1])

    def project(self, rays: ArrayLike) -> FloatArray:
        x, y, z = as_rays(rays)
        norm = np.hypot(x, y)
        t = np.arctan2(-z, norm)  # = atan(-1 / hypot(X/Z, Y/Z)) where Z > 0
        rho = np.polynomial.polynomial.polyval(t, self.invpol)
        with np.errstate(invalid="ignore", divide="ignore"):
            scale = np.where(norm > 0, rho / np.where(norm > 0, norm, 1.0), 0.0)
            seen = t <= self._nodes[0][-1]
        xp, yp = x * scale, y * scale
        return pixels(self.c * xp + self.d * yp + self.u0, self.e * xp + yp + self.v0, seen)

    def unproject(self, uv: ArrayLike) -> FloatArray:
        """Unit rays (..., 3) of pixels (..., 2): the affine undone, then rho = invpol(t) solved for t by Newton
        from the tabulated polynomial (to about 1e-9 px); NaN past the valid range. Pixels closer to the centre
        than the axis's own radius (:attr:`axis_radius_px`) get the axis."""
        p = np.asarray(uv, dtype=np.float64)
        du, dv = p[..., 0] - self.u0, p[..., 1] - self.v0
        det = self.c - self.d * self.e
        xp = (du - self.d * dv) / det
        yp = (-self.e * du + self.c * dv) / det
        r = np.hypot(xp, yp)
        nodes_t, nodes_rho = self._nodes
        t = np.interp(r, nodes_rho, nodes_t)
        derivative = np.polynomial.polynomial.polyder(self.invpol)
        for _ in range(NEWTON_STEPS):
            step = (np.polynomial.polynomial.polyval(t, self.invpol) - r) / np.polynomial.polynomial.polyval(
                t, derivative
            )
            t = np.clip(t - step, nodes_t[0], nodes_t[-1])
        t = np.where(r <= nodes_rho[0], -math.pi / 2, t)
        with np.errstate(invalid="ignore", divide="ignore"):
            cos_t = np.cos(t) / np.where(r > 0, r, 1.0)
            ray = np.stack([xp * cos_t, yp * cos_t, -np.sin(t)], axis=-1)
        return np.where((r <= nodes_rho[-1])[..., None], ray, np.nan)
