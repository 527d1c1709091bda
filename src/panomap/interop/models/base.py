"""What every external camera model is: a stateless projection with its parameters, and the shared inverse.

Convention (every model in this folder): rays are in the **OpenCV camera frame**, x along the image
columns (right), y along the rows (down), z = x × y, the optical axis (forward); pixels (u, v) are
panomap's: u the column, v the row, the centre of the top-left pixel at (0, 0). Each model's file says
how its tool's own frame and pixels map onto these (OCamCalib: rows first, rays toward -z; COLMAP:
pixel centres at +0.5).

A model is a frozen dataclass of its parameters, in the order its file declares, checked on creation
(:class:`panomap.errors.PanomapError` naming the parameter). ``project`` maps rays (..., 3) to pixels
(..., 2), NaN where the model does not see the ray; ``unproject`` maps pixels to unit rays, NaN where no
ray lands. ``unproject`` is solved here once for all (:func:`solve_rays`): Newton's method on the ray's
equidistant coordinates (angle from the axis times its direction), smooth through 90 deg, so it serves
fields of view past 180 deg.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ...errors import PanomapError
from ...geometry import FloatArray
from ...values import MAX_ABS


@dataclass(frozen=True)
class ExternalCamera(ABC):
    """A central camera in another tool's model; fields are its parameters in their declared order."""

    # The model's name in this project (the registry's key), and the widest angle from the axis (rad)
    # any parameters of it can see.
    name: ClassVar[str]
    max_angle_limit_rad: ClassVar[float] = math.pi

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            values = value if isinstance(value, tuple) else (value,)
            for x in values:
                if not isinstance(x, (int, float)) or not math.isfinite(float(x)):
                    raise PanomapError(f"{self.name}: parameter {f.name} is {x!r}, not a finite number")
                if abs(float(x)) > MAX_ABS:  # a typing mistake, or a huge number a reader clamped
                    raise PanomapError(f"{self.name}: parameter {f.name} is {x:g}, beyond {MAX_ABS:g} in size")
        self.check()

    @abstractmethod
    def check(self) -> None:
        """Raise :class:`PanomapError` naming the parameter that is out of range (the model's own rules)."""

    def parameters(self) -> dict[str, float | list[float]]:
        """The parameters by name, in their declared order (JSON-ready)."""
        out: dict[str, float | list[float]] = {}
        for f in fields(self):
            value = getattr(self, f.name)
            out[f.name] = [float(x) for x in value] if isinstance(value, tuple) else float(value)
        return out

    @abstractmethod
    def project(self, rays: ArrayLike) -> FloatArray:
        """Pixels (..., 2) of rays (..., 3) in the OpenCV camera frame; NaN where not seen."""

    @property
    @abstractmethod
    def principal_point(self) -> tuple[float, float]:
        """(u, v) px where the optical axis (0, 0, 1) lands."""

    @property
    @abstractmethod
    def focal_px(self) -> float:
        """A focal length (px per rad near the axis): the scale of the first guess of :func:`solve_rays`."""

    def unproject(self, uv: ArrayLike) -> FloatArray:
        """Unit rays (..., 3) of pixels (..., 2); NaN where no ray of the model's valid range lands."""
        return solve_rays(self.project, uv, self.principal_point, self.focal_px, self.max_angle_limit_rad)


class PinholeIntrinsics(ExternalCamera):
    """A model whose parameters include a pinhole's intrinsics: ``fx``, ``fy`` (px, checked > 0) and the
    principal point ``cx``, ``cy`` (px). The subclass declares them as dataclass fields, in its own order."""

    fx: float
    fy: float
    cx: float
    cy: float

    def check(self) -> None:
        positive(self.name, "fx", self.fx)
        positive(self.name, "fy", self.fy)

    @property
    def principal_point(self) -> tuple[float, float]:
        return (self.cx, self.cy)


def ray_of_equidistant(ab: FloatArray) -> FloatArray:
    """Unit rays (..., 3) of equidistant coordinates (..., 2): angle t = |ab| from +z, toward ab."""
    t = np.hypot(ab[..., 0], ab[..., 1])
    scale = np.where(t > 1e-12, np.sin(t) / np.where(t > 1e-12, t, 1.0), 1.0)
    return np.stack([ab[..., 0] * scale, ab[..., 1] * scale, np.cos(t)], axis=-1)


def solve_rays(
    project: Callable[[FloatArray], FloatArray],
    uv: ArrayLike,
    centre: tuple[float, float],
    focal_px: float,
    max_angle_rad: float,
    iterations: int = 40,
) -> FloatArray:
    """Rays (..., 3) whose ``project`` is ``uv`` (..., 2): damped Newton on equidistant coordinates with a
    numerical Jacobian, from the equidistant guess ``(uv - centre) / focal_px``; NaN where it does not
    converge to 1e-6 px or the angle passes ``max_angle_rad``.
    """
    target = np.asarray(uv, dtype=np.float64)
    ab = (target - np.asarray(centre)) / focal_px
    step = 1e-7
    for _ in range(iterations):
        f = project(ray_of_equidistant(ab)) - target
        fa = (project(ray_of_equidistant(ab + np.array([step, 0.0]))) - target - f) / step
        fb = (project(ray_of_equidistant(ab + np.array([0.0, step]))) - target - f) / step
        det = fa[..., 0] * fb[..., 1] - fb[..., 0] * fa[..., 1]
        with np.errstate(invalid="ignore", divide="ignore"):
            da = (fb[..., 1] * f[..., 0] - fb[..., 0] * f[..., 1]) / det
            db = (-fa[..., 1] * f[..., 0] + fa[..., 0] * f[..., 1]) / det
        delta = np.stack([da, db], axis=-1)
        # Keep steps below 0.2 rad, so the guess never jumps past the model's valid range.
        size = np.hypot(da, db)[..., None]
        delta = np.where(size > 0.2, delta * 0.2 / np.where(size > 0, size, 1.0), delta)
        ab = np.where(np.isfinite(delta), ab - delta, ab)
    error = np.hypot(*np.moveaxis(project(ray_of_equidistant(ab)) - target, -1, 0))
    with np.errstate(invalid="ignore"):
        good = (error < 1e-6) & (np.hypot(ab[..., 0], ab[..., 1]) <= max_angle_rad)
    return np.where(good[..., None], ray_of_equidistant(ab), np.nan)


def as_rays(rays: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
    """x, y, z (...) of rays (..., 3), float64."""
    r = np.asarray(rays, dtype=np.float64)
    if r.ndim == 0 or r.shape[-1] != 3:
        raise PanomapError(f"rays must have shape (..., 3), not {r.shape}")
    return r[..., 0], r[..., 1], r[..., 2]


def pixels(u: FloatArray, v: FloatArray, seen: NDArray[np.bool_] | None = None) -> FloatArray:
    """Stack (u, v) into (..., 2), NaN where ``seen`` is False."""
    uv = np.stack([u, v], axis=-1)
    return uv if seen is None else np.where(seen[..., None], uv, np.nan)


def positive(model: str, name: str, value: float) -> None:
    """Raise unless ``value`` > 0."""
    if not value > 0:
        raise PanomapError(f"{model}: {name} must be > 0, not {value:g}")


def farthest_corner_px(centre: tuple[float, float], width: int, height: int) -> float:
    """Distance (px) from ``centre`` (u, v) to the farthest corner of a ``width`` x ``height`` image (its pixels'
    outer edges: -0.5 and W - 0.5, H - 0.5)."""
    u0, v0 = centre
    return max(math.hypot(a, b) for a in (-0.5 - u0, width - 0.5 - u0) for b in (-0.5 - v0, height - 0.5 - v0))
