"""The equirectangular panorama, as ffmpeg ``v360``'s ``e``: the whole sphere, yaw 0 at the centre column.

Convention (docs/conventions.md, the views' table): output pixel (k, l) of a W x H view sees azimuth
``psi + pi - 2*pi*(k + 0.5)/W`` and elevation ``pi/2 - pi*(l + 0.5)/H`` (W = 2H by default). Beyond the
contract, a pitch tau and a roll omega turn the sphere as a perspective view's axes turn
(:func:`panomap.camera.orientation.view_axes`): the pixel at local azimuth ``a`` (from the centre column,
counter-clockwise seen from above) and local elevation ``e`` sees ``cos(e) (cos(a) F - sin(a) R) - sin(e) Dn``;
with tau = omega = 0 that is the contract's ray.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Self

import numpy as np
from numpy.typing import NDArray

from ..camera.orientation import view_axes
from ..errors import PanomapError
from ..geometry import HALF_PI, TWO_PI, FloatArray, pixel_centres, ray_from_angles, wrap_azimuth
from ..table.table import PanoMappingTable
from .base import SEEN_AT, AngleArray, Param, Value, View, check_finite, check_view_size, radians_hint, register
from .panorama import check_distance

# The default height when the table gives none to follow: 1024 rows (a 2048 x 1024 panorama).
DEFAULT_HEIGHT = 1024
# Default heights stop here (a 8192 x 4096 panorama).
MAX_DEFAULT_HEIGHT = 4096


@register
@dataclass(frozen=True)
class EquirectView(View):
    """The equirectangular panorama of the whole sphere (as ffmpeg ``v360``'s ``e``).

    Parameters
    ----------
    yaw_rad : float
        psi, the azimuth (rad) of the centre column.
    pitch_rad, roll_rad : float
        Turn the sphere as a perspective view's pitch and roll (rad): 0 and 0 (the default) is upright,
        the horizon along the middle row.
    size : (W, H), optional
        Default ``(2H, H)`` with one row per table entry along the camera's elevations (H about the
        camera's image radius times pi over its field of view), at most 4096 rows.
    distance : float, optional
        World units from O_m of what the view shows (default: far away); it changes the view only for a
        camera without a single viewpoint.
    """

    kind: ClassVar[str] = "equirect"
    summary: ClassVar[str] = (
        "Equirectangular panorama of the whole sphere, as ffmpeg v360's 'e': yaw at the centre column, "
        "black (alpha 0) where the camera sees nothing."
    )
    params: ClassVar[tuple[Param, ...]] = (
        Param("yaw", Value.ANGLE, "Azimuth at the centre column.", default=0.0),
        Param("pitch", Value.ANGLE, "Turn the sphere up (+) or down, -90..90.", default=0.0),
        Param("roll", Value.ANGLE, "Turn the sphere about the centre column's direction.", default=0.0),
        Param("size", Value.SIZE, "Output WxH [default: 2H x H at about the camera's resolution].", optional=True),
        SEEN_AT,
    )
    example: ClassVar[str] = "yaw=0,size=2048x1024"
    bytes_per_pixel: ClassVar[int] = 36  # (measured: 27.9 bytes a pixel; 30.4 at 4000 x 2000)

    yaw_rad: float = 0.0
    pitch_rad: float = 0.0
    roll_rad: float = 0.0
    size: tuple[int, int] | None = None
    distance: float | None = None

    def __post_init__(self) -> None:
        check_finite(yaw_rad=self.yaw_rad, pitch_rad=self.pitch_rad, roll_rad=self.roll_rad)
        if abs(self.pitch_rad) > HALF_PI + 1e-12:
            raise PanomapError(
                f"the pitch must be between -90 and 90 deg, not {math.degrees(self.pitch_rad):g} deg"
                + radians_hint(self.pitch_rad, HALF_PI)
            )
        if self.size is not None:
            object.__setattr__(self, "size", check_view_size(self.size))
        check_distance(self.distance)

    @classmethod
    def from_params(cls, values: Mapping[str, Any]) -> Self:
        """The view from its parameters, as parsed from a view SPEC (every declared name, None where not given)."""
        return cls(values["yaw"], values["pitch"], values["roll"], values["size"], values["distance"])

    @property
    def upright(self) -> bool:
        """No pitch and no roll: columns are world azimuths and rows world elevations."""
        return self.pitch_rad == 0.0 and self.roll_rad == 0.0

    def output_size(self, table: PanoMappingTable) -> tuple[int, int]:
        """(W, H): ``size``, or ``(2H, H)`` with H the table's rows per radian of the camera's own elevations
        times pi (about one row per image pixel along the radius), within 16..4096."""
        if self.size is not None:
            return self.size
        low, high = table.camera_range
        rows_per_rad = table.size[1] / max(high - low, 1e-6)
        height = int(min(max(round(math.pi * rows_per_rad / 2) * 2, 16), MAX_DEFAULT_HEIGHT))
        return 2 * height, height

    def _columns_rows(self, table: PanoMappingTable) -> tuple[FloatArray, FloatArray]:
        """Local azimuth (rad) of each column, (W,), from the centre column, and elevation of each row, (H,)."""
        width, height = self.output_size(table)
        fx, fy = pixel_centres(width, height)
        return math.pi - TWO_PI * fx, HALF_PI - math.pi * fy

    def angles(self, table: PanoMappingTable) -> tuple[AngleArray, AngleArray]:
        """World azimuth and elevation (rad), each (H, W), of every output pixel."""
        local_azimuth, elevation = self._columns_rows(table)
        if self.upright:
            theta = wrap_azimuth(self.yaw_rad + local_azimuth)
            return np.broadcast_to(theta, (elevation.size, theta.size)), np.broadcast_to(
                elevation[:, None], (elevation.size, theta.size)
            )
        rays = self.rays(table)
        horizontal = np.hypot(rays[..., 0], rays[..., 1])
        theta = np.arctan2(-rays[..., 1], -rays[..., 0]) + np.float32(math.pi)
        return theta.astype(np.float32), np.arctan2(rays[..., 2], horizontal).astype(np.float32)

    def rays(self, table: PanoMappingTable) -> NDArray[np.float32]:
        """Unit rays (H, W, 3), world axes, float32: ``cos(e) (cos(a) F - sin(a) R) - sin(e) Dn``."""
        local_azimuth, elevation = self._columns_rows(table)
        forward, right, down = view_axes(self.yaw_rad, self.pitch_rad, self.roll_rad)
        across = np.cos(local_azimuth)[:, None] * forward - np.sin(local_azimuth)[:, None] * right  # (W, 3)
        cos_e = np.cos(elevation).astype(np.float32)[:, None, None]
        sin_e = np.sin(elevation)[:, None, None]
        return cos_e * across.astype(np.float32)[None] - (sin_e * down).astype(np.float32)

    def quick_map(self, table: PanoMappingTable, sampling: str) -> NDArray[np.float32] | None:
        """Upright: the exact map, sampled from one row of azimuths and one column of elevations."""
        if not self.upright:
            return None
        local_azimuth, elevation = self._columns_rows(table)
        return table.sample_grid(wrap_azimuth(self.yaw_rad + local_azimuth), elevation, sampling)

    def points(self, table: PanoMappingTable) -> FloatArray | None:
        """The (H, W, 3) points at ``distance`` along the pixels' rays, relative to O_m; None (directions)
        where no distance is given."""
        if self.distance is None:
            return None
        theta, rho = self.angles(table)
        return np.asarray(ray_from_angles(theta, rho)) * self.distance
