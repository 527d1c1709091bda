"""A perspective view of a vertical rectangle at a distance from O_m (paper 2.3.3)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Self

import numpy as np

from ..errors import PanomapError
from ..geometry import FloatArray, azimuth_elevation, pixel_centres
from ..table.table import PanoMappingTable
from .base import OUTPUT_SIZE, Band, Param, Value, View, check_finite, check_view_size, register


@register
@dataclass(frozen=True)
class PlaneView(View):
    """A perspective view of a vertical W_p x band rectangle (paper 2.3.3).

    Parameters
    ----------
    distance : float
        Horizontal distance D of both vertical edges from O_m (not of the plane's middle).
    width : float
        Plane width W_p (world units), less than 2 D (at 2 D the plane passes through O_m).
    band : Band
        Heights relative to O_m.
    azimuth_rad : float
        Centre azimuth theta_c (rad); the left edge is at ``theta_c + phi/2``,
        the right at ``theta_c - phi/2``, ``phi = acos(1 - W_p^2/(2 D^2))``
        (eq. 13).
    size : (W, H)
    """

    kind: ClassVar[str] = "plane"
    needs_camera_height: ClassVar[bool] = True
    summary: ClassVar[str] = "Perspective view of a vertical W_p x band plane at distance D (paper 2.3.3)."
    params: ClassVar[tuple[Param, ...]] = (
        Param("distance", Value.NUMBER, "Horizontal distance D of both vertical edges."),
        Param("width", Value.NUMBER, "Plane width W_p (less than 2 D).", aliases=("--plane-width",)),
        Param("band", Value.PAIR, "Heights of the plane's bottom and top relative to the camera.", metavar="ZB ZT"),
        Param("azimuth", Value.ANGLE, "Azimuth of the plane's centre.", aliases=("--azimuth-deg",)),
        OUTPUT_SIZE,
    )
    example: ClassVar[str] = "distance=1.8,width=2.4,band=-2.45:0.15,azimuth=90,size=800x860"
    bytes_per_pixel: ClassVar[int] = 64  # (measured: 56.6 bytes a pixel)

    distance: float
    width: float
    band: Band
    azimuth_rad: float
    size: tuple[int, int]

    def __post_init__(self) -> None:
        check_finite(distance=self.distance, width=self.width, azimuth_rad=self.azimuth_rad)
        if self.distance <= 0:
            raise PanomapError(f"the distance must be positive, not {self.distance:g}")
        if self.width <= 0:
            raise PanomapError(f"the plane width must be positive, not {self.width:g}")
        if self.width >= 2 * self.distance:
            # At W_p = 2 D the plane passes through the camera: it subtends 180 deg and has no perspective view.
            raise PanomapError(
                f"a plane {self.width:g} wide cannot have both edges at distance {self.distance:g} and stay in "
                "front of the camera (needs width < 2 D; D is the distance to the plane's vertical edges)"
            )
        object.__setattr__(self, "size", check_view_size(self.size))

    @classmethod
    def from_params(cls, values: Mapping[str, Any]) -> Self:
        """The view from its parameters, as parsed from a view SPEC (every declared name, None where not given)."""
        return cls(values["distance"], values["width"], Band(*values["band"]), values["azimuth"], values["size"])

    @property
    def subtended(self) -> float:
        """phi = acos(1 - W_p^2 / (2 D^2)), rad (eq. 13)."""
        return math.acos(1.0 - self.width**2 / (2.0 * self.distance**2))

    def points(self, table: PanoMappingTable) -> FloatArray:
        """The (H, W, 3) points relative to O_m that the pixels see (the same for every table)."""
        width, height = self.size
        half = self.subtended / 2
        left = self.distance * np.array([math.cos(self.azimuth_rad + half), math.sin(self.azimuth_rad + half)])
        right = self.distance * np.array([math.cos(self.azimuth_rad - half), math.sin(self.azimuth_rad - half)])
        fx, _ = pixel_centres(width, 1)
        xy = left + fx[:, None] * (right - left)
        heights = self.band.heights(height)
        out = np.empty((height, width, 3))
        out[..., :2] = xy[None, :, :]
        out[..., 2] = heights[:, None]
        return out

    def output_size(self, table: PanoMappingTable) -> tuple[int, int]:
        """(W, H) of the output image: ``size``."""
        return self.size

    def angles(self, table: PanoMappingTable) -> tuple[FloatArray, FloatArray]:
        """Azimuth and elevation (rad), each (H, W), of every output pixel."""
        return azimuth_elevation(self.points(table))
