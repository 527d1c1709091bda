"""The bundled room through cameras that calibration tools describe: a fisheye looking ahead, a dual fisheye.

The demo writes these pictures beside the calibration files that describe their cameras (a Basalt double
sphere, a Kalibr camchain of two equidistant lenses back to back), so that the documented commands run on
them. Each lens traces its pixels to rays in closed form (the OpenCV camera frame: x right, y down, z
ahead); :func:`camera_axes` turns them into the world (the conventions' yaw, pitch and roll); the room
gives each ray its colour (:func:`.room.render_rays`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .room import Room, render_rays


class Lens(Protocol):
    """A camera's pixels to rays: ``size`` (W, H) px and ``rays(uv)``: (..., 2) px to (..., 3) rays."""

    @property
    def size(self) -> tuple[int, int]: ...

    def rays(self, uv: ArrayLike) -> NDArray[np.float64]:
        """Rays (..., 3) of pixels (..., 2), the OpenCV camera frame; NaN where no ray lands."""
        ...


@dataclass(frozen=True)
class DoubleSphereLens:
    """The double sphere camera (Usenko, Demmel and Cremers 2018; Basalt's ``ds``): focal lengths ``fx``,
    ``fy`` and principal point ``cx``, ``cy`` (px), ``xi`` and ``alpha`` (unitless), picture ``size``
    (W, H) px."""

    fx: float
    fy: float
    cx: float
    cy: float
    xi: float
    alpha: float
    size: tuple[int, int]

    def rays(self, uv: ArrayLike) -> NDArray[np.float64]:
        """Rays (..., 3) of pixels (..., 2): the paper's closed-form unprojection (its eq. 47-49), NaN past
        ``r^2 <= 1 / (2 alpha - 1)`` where alpha > 1/2."""
        p = np.asarray(uv, dtype=np.float64)
        mx, my = (p[..., 0] - self.cx) / self.fx, (p[..., 1] - self.cy) / self.fy
        r2 = mx * mx + my * my
        a, xi = self.alpha, self.xi
        with np.errstate(invalid="ignore", divide="ignore"):
            mz = (1 - a * a * r2) / (a * np.sqrt(1 - (2 * a - 1) * r2) + 1 - a)
            k = (mz * xi + np.sqrt(mz * mz + (1 - xi * xi) * r2)) / (mz * mz + r2)
        out = np.stack([k * mx, k * my, k * mz - xi], axis=-1)
        if a > 0.5:
            out[r2 > 1 / (2 * a - 1)] = np.nan
        return out


@dataclass(frozen=True)
class EquidistantLens:
    """An ideal equidistant fisheye (Kalibr's ``pinhole`` with ``equidistant`` distortion, all zero): a ray
    ``alpha`` rad off the axis lands ``f_px * alpha`` px from the centre ``(cx, cy)``; its image circle
    ``half_fov_rad`` off the axis; picture ``size`` (W, H) px."""

    f_px: float
    cx: float
    cy: float
    half_fov_rad: float
    size: tuple[int, int]

    def rays(self, uv: ArrayLike) -> NDArray[np.float64]:
        """Unit rays (..., 3) of pixels (..., 2); NaN past the image circle."""
        p = np.asarray(uv, dtype=np.float64)
        du, dv = p[..., 0] - self.cx, p[..., 1] - self.cy
        r = np.hypot(du, dv)
        alpha = r / self.f_px
        with np.errstate(invalid="ignore", divide="ignore"):
            scale = np.where(r > 0, np.sin(alpha) / r, 1.0 / self.f_px)
        out = np.stack([du * scale, dv * scale, np.cos(alpha)], axis=-1)
        out[alpha > self.half_fov_rad] = np.nan
        return out


def camera_axes(yaw_deg: float, pitch_deg: float, roll_deg: float) -> NDArray[np.float64]:
    """G (3, 3), columns the camera's right, down and forward (world axes, Z up) of a camera looking along
    yaw, pitch and roll (deg), the conventions' formula: ``F = (cos tau cos psi, cos tau sin psi, sin tau)``,
    ``R0 = (sin psi, -cos psi, 0)``, ``D0 = F x R0``, rolled by omega; a camera ray x maps to ``G x``."""
    psi, tau, omega = (math.radians(a) for a in (yaw_deg, pitch_deg, roll_deg))
    forward = np.array([math.cos(tau) * math.cos(psi), math.cos(tau) * math.sin(psi), math.sin(tau)])
    right0 = np.array([math.sin(psi), -math.cos(psi), 0.0])
    down0 = np.cross(forward, right0)
    right = math.cos(omega) * right0 + math.sin(omega) * down0
    down = math.cos(omega) * down0 - math.sin(omega) * right0
    return np.stack([right, down, forward], axis=1)


def render_lens(room: Room, lens: Lens, origin: ArrayLike, axes: ArrayLike, supersample: int = 2) -> NDArray[np.uint8]:
    """The room as ``lens`` sees it from ``origin`` (3,) m, world, with camera axes ``axes`` (3, 3) (columns
    right, down, forward in the world): (H, W, 3) uint8 BGR, each pixel the mean of ``supersample**2`` rays
    at its sub-pixels' centres, black where the lens has no ray."""
    width, height = lens.size
    sub = (np.arange(supersample) + 0.5) / supersample - 0.5
    v, u, dv, du = np.meshgrid(np.arange(height), np.arange(width), sub, sub, indexing="ij")
    rays = lens.rays(np.stack([u + du, v + dv], axis=-1)) @ np.asarray(axes, dtype=np.float64).T
    colours = np.nan_to_num(render_rays(room, np.asarray(origin, dtype=np.float64), rays))
    mean = colours.reshape(height, width, supersample * supersample, 3).mean(axis=2)
    return np.clip(np.rint(mean), 0, 255).astype(np.uint8)
