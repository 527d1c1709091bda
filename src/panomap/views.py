"""Views (paper 2.3): what ray each output pixel sees, and the map that follows.

Convention: an output image is W x H; pixel (k, l) is column k, row l and
samples at its centre, ``(k + 0.5)/W`` across and ``(l + 0.5)/H`` down the
view's extent. Views are upright (higher elevation higher up) and not
mirrored (what is on your left, standing at O_m facing the view, is on the
left), so azimuth decreases from left to right. Lengths are relative to O_m,
in world units; angles in rad.

A view is a frozen value. ``view.angles(table)`` gives the (H, W) azimuth and
elevation of every output pixel; :func:`build_map` turns them into the
(H, W, 2) float32 (u, v) map that ``cv2.remap`` takes, NaN where there is no
source.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from .errors import PanomapError
from .geometry import TWO_PI, FloatArray, azimuth_elevation, pixel_centres, wrap_azimuth
from .table import PanoMappingTable

MAX_VIEW_PIXELS = 50_000_000
MAX_VIEW_SIDE = 32_000


def check_view_size(size: tuple[int, int], what: str = "--size") -> tuple[int, int]:
    """Validate an output size (W, H): positive, each side and the area bounded."""
    width, height = (int(x) for x in size)
    if width <= 0 or height <= 0:
        raise PanomapError(f"{what} {width}x{height}: width and height must be positive")
    if width > MAX_VIEW_SIDE or height > MAX_VIEW_SIDE or width * height > MAX_VIEW_PIXELS:
        raise PanomapError(
            f"{what} {width}x{height}: too large (at most {MAX_VIEW_SIDE} px a side and {MAX_VIEW_PIXELS:,} px in all)"
        )
    return width, height


def _check_finite(**values: float) -> None:
    for name, value in values.items():
        if not math.isfinite(value):
            raise PanomapError(f"{name} must be a finite number, not {value}")


class View(Protocol):
    """What every view offers."""

    def output_size(self, table: PanoMappingTable) -> tuple[int, int]:
        """(W, H) of the output image."""
        ...

    def angles(self, table: PanoMappingTable) -> tuple[FloatArray, FloatArray]:
        """Azimuth and elevation (rad), each (H, W), of every output pixel."""
        ...


def _panorama_azimuths(theta_start: float, width: int) -> FloatArray:
    """``theta_start - 2*pi*(k + 0.5)/W`` wrapped to [0, 2*pi); shape (W,)."""
    fx, _ = pixel_centres(width, 1)
    return wrap_azimuth(theta_start - TWO_PI * fx)


@dataclass(frozen=True)
class GenericPanorama:
    """The generic panorama (paper 2.3.1): columns are azimuths, rows elevations.

    Parameters
    ----------
    size : (W, H), optional
        Output size; default the table's (M, N), as in the paper.
    theta_start : float
        Azimuth (rad) at the left edge; column k sees
        ``theta_start - 2*pi*(k + 0.5)/W``. Rows are evenly spaced in
        elevation over the table's range, highest at the top.
    """

    size: tuple[int, int] | None = None
    theta_start: float = 0.0

    def __post_init__(self) -> None:
        if self.size is not None:
            object.__setattr__(self, "size", check_view_size(self.size))
        _check_finite(theta_start=self.theta_start)

    def output_size(self, table: PanoMappingTable) -> tuple[int, int]:
        return self.size if self.size is not None else table.size

    def angles(self, table: PanoMappingTable) -> tuple[FloatArray, FloatArray]:
        width, height = self.output_size(table)
        _, fy = pixel_centres(1, height)
        rho_s, rho_e = table.elevation_range
        theta = np.broadcast_to(_panorama_azimuths(self.theta_start, width), (height, width))
        rho = np.broadcast_to((rho_e - fy * (rho_e - rho_s))[:, None], (height, width))
        return theta, rho


@dataclass(frozen=True)
class Band:
    """A height band ``z_bottom < z_top`` relative to O_m (world units)."""

    z_bottom: float
    z_top: float

    def __post_init__(self) -> None:
        _check_finite(z_bottom=self.z_bottom, z_top=self.z_top)
        if not self.z_bottom < self.z_top:
            raise PanomapError(f"the band must have z_bottom < z_top, got {self.z_bottom:g}..{self.z_top:g}")

    def heights(self, rows: int) -> FloatArray:
        """``z_top - (l + 0.5)*(z_top - z_bottom)/H`` for l = 0..H-1; shape (H,)."""
        _, fy = pixel_centres(1, rows)
        return self.z_top - fy * (self.z_top - self.z_bottom)


@dataclass(frozen=True)
class CylinderPanorama:
    """A panorama of a vertical cylinder around O_m (paper 2.3.2).

    Parameters
    ----------
    distance : float
        Horizontal distance D of the cylinder from O_m.
    band : Band
        Heights relative to O_m (the paper's band is 0..H).
    size : (W, H)
    theta_start : float
        Azimuth (rad) at the left edge, as for the generic panorama.
    """

    distance: float
    band: Band
    size: tuple[int, int]
    theta_start: float = 0.0

    def __post_init__(self) -> None:
        _check_finite(distance=self.distance, theta_start=self.theta_start)
        if self.distance <= 0:
            raise PanomapError(f"the distance must be positive, not {self.distance:g}")
        object.__setattr__(self, "size", check_view_size(self.size))

    def output_size(self, table: PanoMappingTable) -> tuple[int, int]:
        return self.size

    def angles(self, table: PanoMappingTable) -> tuple[FloatArray, FloatArray]:
        width, height = self.size
        theta = np.broadcast_to(_panorama_azimuths(self.theta_start, width), (height, width))
        rho = np.broadcast_to(np.arctan2(self.band.heights(height), self.distance)[:, None], (height, width))
        return theta, rho

    def points(self) -> FloatArray:
        """The (H, W, 3) points relative to O_m that the pixels see."""
        width, height = self.size
        theta = _panorama_azimuths(self.theta_start, width)
        out = np.empty((height, width, 3))
        out[..., 0] = self.distance * np.cos(theta)[None, :]
        out[..., 1] = self.distance * np.sin(theta)[None, :]
        out[..., 2] = self.band.heights(height)[:, None]
        return out


@dataclass(frozen=True)
class PlaneView:
    """A perspective view of a vertical W_p x band rectangle (paper 2.3.3).

    Parameters
    ----------
    distance : float
        Horizontal distance D of both vertical edges from O_m.
    width : float
        Plane width W_p (world units), at most 2 D.
    band : Band
        Heights relative to O_m.
    azimuth : float
        Centre azimuth theta_c (rad); the left edge is at ``theta_c + phi/2``,
        the right at ``theta_c - phi/2``, ``phi = acos(1 - W_p^2/(2 D^2))``
        (eq. 13).
    size : (W, H)
    """

    distance: float
    width: float
    band: Band
    azimuth: float
    size: tuple[int, int]

    def __post_init__(self) -> None:
        _check_finite(distance=self.distance, width=self.width, azimuth=self.azimuth)
        if self.distance <= 0:
            raise PanomapError(f"the distance must be positive, not {self.distance:g}")
        if self.width <= 0:
            raise PanomapError(f"the plane width must be positive, not {self.width:g}")
        if self.width > 2 * self.distance:
            raise PanomapError(
                f"a plane {self.width:g} wide cannot have both edges at distance {self.distance:g} (needs width <= 2 D)"
            )
        object.__setattr__(self, "size", check_view_size(self.size))

    @property
    def subtended(self) -> float:
        """phi = acos(1 - W_p^2 / (2 D^2)), rad (eq. 13)."""
        return math.acos(1.0 - self.width**2 / (2.0 * self.distance**2))

    def points(self) -> FloatArray:
        """The (H, W, 3) points relative to O_m that the pixels see."""
        width, height = self.size
        half = self.subtended / 2
        left = self.distance * np.array([math.cos(self.azimuth + half), math.sin(self.azimuth + half)])
        right = self.distance * np.array([math.cos(self.azimuth - half), math.sin(self.azimuth - half)])
        fx, _ = pixel_centres(width, 1)
        xy = left + fx[:, None] * (right - left)
        heights = self.band.heights(height)
        out = np.empty((height, width, 3))
        out[..., :2] = xy[None, :, :]
        out[..., 2] = heights[:, None]
        return out

    def output_size(self, table: PanoMappingTable) -> tuple[int, int]:
        return self.size

    def angles(self, table: PanoMappingTable) -> tuple[FloatArray, FloatArray]:
        return azimuth_elevation(self.points())


def build_map(table: PanoMappingTable, view: View, sampling: str = "bilinear") -> NDArray[np.float32]:
    """The (H, W, 2) float32 (u, v) source map of ``view``, NaN where there is no source."""
    theta, rho = view.angles(table)
    return table.sample(theta, rho, sampling).astype(np.float32)
