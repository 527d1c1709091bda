"""A panorama of a vertical cylinder around O_m (paper 2.3.2)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Self

import numpy as np
from numpy.typing import NDArray

from ..errors import PanomapError
from ..geometry import FloatArray
from ..table.table import PanoMappingTable
from .base import OUTPUT_SIZE, Band, Param, Value, View, check_finite, check_view_size, register
from .grid import panorama_azimuths
from .panorama import START


@register
@dataclass(frozen=True)
class CylinderPanorama(View):
    """A panorama of a vertical cylinder around O_m (paper 2.3.2).

    Parameters
    ----------
    distance : float
        Horizontal distance D of the cylinder from O_m.
    band : Band
        Heights relative to O_m (the paper's band is 0..H).
    size : (W, H)
    theta_start_rad : float
        Azimuth (rad) at the left edge, as for the generic panorama.
    """

    kind: ClassVar[str] = "cylinder"
    needs_camera_height: ClassVar[bool] = True
    summary: ClassVar[str] = "Panorama of a cylinder at distance D with a height band (paper 2.3.2)."
    params: ClassVar[tuple[Param, ...]] = (
        Param("distance", Value.NUMBER, "Horizontal distance D of the cylinder."),
        Param("band", Value.PAIR, "Heights of the band's bottom and top relative to the camera.", metavar="ZB ZT"),
        OUTPUT_SIZE,
        START,
    )
    example: ClassVar[str] = "distance=2,band=-2.45:0.15,size=2048x560,start=0"
    bytes_per_pixel: ClassVar[int] = 24  # (measured: 19.9 bytes a pixel)

    distance: float
    band: Band
    size: tuple[int, int]
    theta_start_rad: float = 0.0

    def __post_init__(self) -> None:
        check_finite(distance=self.distance, theta_start_rad=self.theta_start_rad)
        if self.distance <= 0:
            raise PanomapError(f"the distance must be positive, not {self.distance:g}")
        object.__setattr__(self, "size", check_view_size(self.size))

    @classmethod
    def from_params(cls, values: Mapping[str, Any]) -> Self:
        """The view from its parameters, as parsed from a view SPEC (every declared name, None where not given)."""
        return cls(values["distance"], Band(*values["band"]), values["size"], values["start"])

    def output_size(self, table: PanoMappingTable) -> tuple[int, int]:
        """(W, H) of the output image: ``size``."""
        return self.size

    def angles(self, table: PanoMappingTable) -> tuple[FloatArray, FloatArray]:
        """Azimuth and elevation (rad), each (H, W), of every output pixel."""
        width, height = self.size
        theta, rho = self._columns_rows()
        return np.broadcast_to(theta, (height, width)), np.broadcast_to(rho[:, None], (height, width))

    def quick_map(self, table: PanoMappingTable, sampling: str) -> NDArray[np.float32]:
        """The exact map, sampled from one row of azimuths and one column of elevations."""
        return table.sample_grid(*self._columns_rows(), sampling)

    def _columns_rows(self) -> tuple[FloatArray, FloatArray]:
        """Azimuth (rad) of each column, (W,), and elevation of each row, (H,)."""
        width, height = self.size
        return panorama_azimuths(self.theta_start_rad, width), np.arctan2(self.band.heights(height), self.distance)

    def points(self, table: PanoMappingTable) -> FloatArray:
        """The (H, W, 3) points relative to O_m that the pixels see (the same for every table)."""
        width, height = self.size
        theta = panorama_azimuths(self.theta_start_rad, width)
        out = np.empty((height, width, 3))
        out[..., 0] = self.distance * np.cos(theta)[None, :]
        out[..., 1] = self.distance * np.sin(theta)[None, :]
        out[..., 2] = self.band.heights(height)[:, None]
        return out
