"""The generic panorama (paper 2.3.1): columns are azimuths, rows elevations over the table's range."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Self

import numpy as np
from numpy.typing import NDArray

from ..errors import PanomapError
from ..geometry import FloatArray, pixel_centres, ray_from_angles
from ..table.table import PanoMappingTable
from .base import SEEN_AT, AngleArray, Param, Value, View, check_finite, check_view_size, register
from .grid import panorama_azimuths

# The left edge's azimuth, shared with the cylinder panorama.
START = Param("start", Value.ANGLE, "Azimuth at the left edge.", default=0.0, aliases=("--start-deg",))


@register
@dataclass(frozen=True)
class GenericPanorama(View):
    """The generic panorama (paper 2.3.1): columns are azimuths, rows elevations.

    Parameters
    ----------
    size : (W, H), optional
        Output size; default the table's (M, N), as in the paper.
    theta_start_rad : float
        Azimuth (rad) at the left edge; column k sees
        ``theta_start_rad - 2*pi*(k + 0.5)/W``. Rows are evenly spaced in
        elevation over the table's range, highest at the top.
    distance : float, optional
        World units from O_m of what the view shows (default: far away); it changes the view only for a
        camera without a single viewpoint.
    """

    kind: ClassVar[str] = "panorama"
    summary: ClassVar[str] = (
        "Generic panorama (paper 2.3.1): columns are azimuths (decreasing to the right), rows elevations."
    )
    params: ClassVar[tuple[Param, ...]] = (
        Param("size", Value.SIZE, "Output WxH [default: the table's M x N].", optional=True),
        START,
        SEEN_AT,
    )
    example: ClassVar[str] = "size=2048x512,start=0"
    bytes_per_pixel: ClassVar[int] = 24  # (measured: 19.9 bytes a pixel)

    size: tuple[int, int] | None = None
    theta_start_rad: float = 0.0
    distance: float | None = None

    def __post_init__(self) -> None:
        if self.size is not None:
            object.__setattr__(self, "size", check_view_size(self.size))
        check_finite(theta_start_rad=self.theta_start_rad)
        check_distance(self.distance)

    @classmethod
    def from_params(cls, values: Mapping[str, Any]) -> Self:
        """The view from its parameters, as parsed from a view SPEC (every declared name, None where not given)."""
        return cls(values["size"], values["start"], values["distance"])

    def output_size(self, table: PanoMappingTable) -> tuple[int, int]:
        """(W, H) of the output image: ``size``, or the table's (M, N) where not given."""
        return self.size if self.size is not None else table.size

    def angles(self, table: PanoMappingTable) -> tuple[AngleArray, AngleArray]:
        """Azimuth and elevation (rad), each (H, W), of every output pixel."""
        width, height = self.output_size(table)
        theta, rho = self._columns_rows(table)
        return np.broadcast_to(theta, (height, width)), np.broadcast_to(rho[:, None], (height, width))

    def quick_map(self, table: PanoMappingTable, sampling: str) -> NDArray[np.float32]:
        """The exact map, sampled from one row of azimuths and one column of elevations."""
        return table.sample_grid(*self._columns_rows(table), sampling)

    def points(self, table: PanoMappingTable) -> FloatArray | None:
        """The (H, W, 3) points at ``distance`` along the pixels' directions, relative to O_m; None (directions)
        where no distance is given."""
        if self.distance is None:
            return None
        theta, rho = self.angles(table)
        return np.asarray(ray_from_angles(theta, rho)) * self.distance

    def _columns_rows(self, table: PanoMappingTable) -> tuple[FloatArray, FloatArray]:
        """Azimuth (rad) of each column, (W,), and elevation of each row, (H,)."""
        width, height = self.output_size(table)
        _, fy = pixel_centres(1, height)
        rho_s, rho_e = table.elevation_range
        return panorama_azimuths(self.theta_start_rad, width), rho_e - fy * (rho_e - rho_s)


def check_distance(distance: float | None) -> None:
    """Refuse a distance that is not a positive finite number (None: far away)."""
    if distance is not None and not (np.isfinite(distance) and distance > 0):
        raise PanomapError(f"the distance must be positive, not {distance:g}")
