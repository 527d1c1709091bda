"""A bird's-eye map of a horizontal plane, in world coordinates (beyond the paper)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Self

import numpy as np
from numpy.typing import NDArray

from .. import inputs
from ..errors import PanomapError
from ..geometry import FloatArray, pixel_centres
from ..table.table import PanoMappingTable
from .base import (
    MAX_VIEW_PIXELS,
    MAX_VIEW_SIDE,
    AngleArray,
    OneOf,
    Param,
    Value,
    View,
    check_finite,
    check_view_size,
    register,
)
from .grid import grid_angles
from .lookup import lookup_map, lookup_when_worth_it, row_sine_bounds


@register
@dataclass(frozen=True)
class FloorView(View):
    """A bird's-eye map of a horizontal plane, in world coordinates.

    Parameters
    ----------
    z_plane : float
        Height Z of the plane (world units, world frame, not relative to O_m).
    x_range, y_range : (min, max)
        The plane's extent in world X and Y, ``min < max``.
    size : (W, H)

    Convention: output pixel (k, l) sees the world point
    ``X = x_min + (k + 0.5)(x_max - x_min)/W``,
    ``Y = y_max - (l + 0.5)(y_max - y_min)/H``, ``Z = z_plane``: a map seen
    from above, +X to the right, +Y up. A camera looking down sees only planes
    below O_m, one looking up only planes above (one turned any way, the side its
    table's elevations reach); :meth:`angles` refuses the
    others.
    """

    kind: ClassVar[str] = "floor"
    needs_camera_height: ClassVar[bool] = True
    summary: ClassVar[str] = "Bird's-eye map of the horizontal plane Z (world): +X to the right, +Y up."
    params: ClassVar[tuple[Param, ...]] = (
        Param("z", Value.NUMBER, "Height Z of the plane (world)."),
        Param("x", Value.PAIR, "World X extent.", metavar="XMIN XMAX"),
        Param("y", Value.PAIR, "World Y extent.", metavar="YMIN YMAX"),
        Param("size", Value.SIZE, "Output WxH (or give --resolution).", optional=True),
        Param("resolution", Value.NUMBER, "World units per pixel, instead of --size.", optional=True, metavar="R"),
    )
    one_of: ClassVar[OneOf | None] = OneOf("the output size", ("size", "resolution"))
    example: ClassVar[str] = "z=0,x=0:6,y=0:5,size=1200x1000"
    bytes_per_pixel: ClassVar[int] = 28  # (measured: 23.8 bytes a pixel)

    z_plane: float
    x_range: tuple[float, float]
    y_range: tuple[float, float]
    size: tuple[int, int]

    def __post_init__(self) -> None:
        x_min, x_max = inputs.numbers(self.x_range, 2, "the x range (x_min, x_max)")
        y_min, y_max = inputs.numbers(self.y_range, 2, "the y range (y_min, y_max)")
        check_finite(z_plane=self.z_plane)
        for axis, low, high in (("x", x_min, x_max), ("y", y_min, y_max)):
            if not low < high:
                raise PanomapError(f"the {axis} extent {low:g}..{high:g} is empty: it needs {axis}_min < {axis}_max")
        object.__setattr__(self, "x_range", (x_min, x_max))
        object.__setattr__(self, "y_range", (y_min, y_max))
        object.__setattr__(self, "size", check_view_size(self.size))

    @classmethod
    def with_resolution(
        cls, z_plane: float, x_range: tuple[float, float], y_range: tuple[float, float], resolution: float
    ) -> Self:
        """A floor view of about ``resolution`` world units per pixel.

        ``W = round((x_max - x_min)/resolution)`` and likewise H (at least 1);
        the extent is kept, so pixels are ``(x_max - x_min)/W`` wide.
        """
        x_min, x_max = inputs.numbers(x_range, 2, "the x range (x_min, x_max)")
        y_min, y_max = inputs.numbers(y_range, 2, "the y range (y_min, y_max)")
        check_finite(resolution=resolution)
        if resolution <= 0:
            raise PanomapError(f"the resolution must be positive, not {resolution:g}")
        # An empty extent gets one pixel here and is refused, with its reason, by the constructor.
        # Rounded only where it can be: a tiny resolution over a wide extent overflows to infinity.
        extent_px = ((x_max - x_min) / resolution, (y_max - y_min) / resolution)
        width, height = (max(1, round(side)) if side < 2 * MAX_VIEW_SIDE else side for side in extent_px)
        if width * height > MAX_VIEW_PIXELS or max(width, height) > MAX_VIEW_SIDE:
            raise PanomapError(
                f"a resolution of {resolution:g} gives an image of {width:.6g} x {height:.6g} px: too large "
                f"(at most {MAX_VIEW_SIDE} px a side and {MAX_VIEW_PIXELS:,} px in all)"
            )
        return cls(z_plane, (x_min, x_max), (y_min, y_max), (int(width), int(height)))

    @classmethod
    def from_params(cls, values: Mapping[str, Any]) -> Self:
        """From ``z``, ``x``, ``y`` and one of ``size`` and ``resolution`` (the other None)."""
        if values["size"] is not None:
            return cls(values["z"], values["x"], values["y"], values["size"])
        return cls.with_resolution(values["z"], values["x"], values["y"], values["resolution"])

    def world_points(self) -> FloatArray:
        """The (H, W, 3) world points the pixels see."""
        width, height = self.size
        fx, fy = pixel_centres(width, height)
        (x_min, x_max), (y_min, y_max) = self.x_range, self.y_range
        out = np.empty((height, width, 3))
        out[..., 0] = (x_min + fx * (x_max - x_min))[None, :]
        out[..., 1] = (y_max - fy * (y_max - y_min))[:, None]
        out[..., 2] = self.z_plane
        return out

    def points(self, table: PanoMappingTable) -> FloatArray:
        """The (H, W, 3) points the pixels see, relative to O_m: :meth:`world_points` less ``table.camera_position``.

        Refuses a plane the camera cannot see (:meth:`check_plane`)."""
        self.check_plane(table)
        return self.world_points() - np.asarray(table.camera_position)

    def check_plane(self, table: PanoMappingTable) -> None:
        """Refuse a plane the table's camera cannot see: at or above O_m looking down, at or below looking up; for
        a camera turned any way, through O_m, or on a side of it that its table's elevations do not reach."""
        z0 = table.camera_position[2]
        if table.model.rotation is not None:
            rho_s, rho_e = table.elevation_range
            if self.z_plane == z0 or (self.z_plane < z0 and rho_s >= 0) or (self.z_plane > z0 and rho_e <= 0):
                raise PanomapError(
                    f"the plane Z = {self.z_plane:g} is not seen by the camera (Z0 = {z0:g}, which sees elevations "
                    f"{np.degrees(rho_s):.1f}..{np.degrees(rho_e):.1f} deg)"
                )
            return
        if table.model.axis == "down" and self.z_plane >= z0:
            raise PanomapError(
                f"the plane Z = {self.z_plane:g} is at or above the camera (Z0 = {z0:g}); "
                "a camera looking down sees only planes below it"
            )
        if table.model.axis == "up" and self.z_plane <= z0:
            raise PanomapError(
                f"the plane Z = {self.z_plane:g} is at or below the camera (Z0 = {z0:g}); "
                "a camera looking up sees only planes above it"
            )

    def output_size(self, table: PanoMappingTable) -> tuple[int, int]:
        """(W, H) of the output image: ``size``."""
        return self.size

    def angles(self, table: PanoMappingTable) -> tuple[AngleArray, AngleArray]:
        """Azimuth and elevation (rad) of every pixel, each (H, W) float32 (see :func:`grid_angles`)."""
        return grid_angles(*self._rays(table))

    def quick_map(self, table: PanoMappingTable, sampling: str) -> NDArray[np.float32] | None:
        """The bilinear map read from the table's :mod:`direction lookup <panomap.views.lookup>`."""
        lookup = lookup_when_worth_it(table) if sampling == "bilinear" else None
        if lookup is None:
            return None
        rows, cols = self._rays(table)
        # |d|^2 = X^2 + (Y^2 + Z^2): a column term plus a row term.
        lengths = np.add(
            (np.square(rows[1]) + np.square(rows[2])).astype(np.float32)[:, None],
            np.square(cols[0]).astype(np.float32)[None, :],
        )
        row_sines = row_sine_bounds(rows, np.array([1.0, 0.0, 0.0]), cols[0])
        return lookup_map(lookup, rows, cols, np.sqrt(lengths, out=lengths), row_sines)

    def _rays(self, table: PanoMappingTable) -> tuple[list[FloatArray], list[FloatArray]]:
        """The rays to the pixels' points, relative to O_m, as row and column terms (see :func:`grid_angles`).

        Refuses a plane the camera cannot see (:meth:`check_plane`).
        """
        self.check_plane(table)
        width, height = self.size
        fx, fy = pixel_centres(width, height)
        (x_min, x_max), (y_min, y_max) = self.x_range, self.y_range
        x0, y0, z0 = table.camera_position
        rows = [np.zeros(height), y_max - fy * (y_max - y_min) - y0, np.full(height, self.z_plane - z0)]
        cols = [x_min + fx * (x_max - x_min) - x0, np.zeros(width), np.zeros(width)]
        return rows, cols
