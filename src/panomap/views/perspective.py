"""A virtual pan-tilt-zoom camera: a pinhole at O_m looking anywhere (beyond the paper)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from functools import lru_cache
from typing import Any, ClassVar, Self

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..camera.orientation import view_axes
from ..errors import PanomapError
from ..geometry import HALF_PI, FloatArray
from ..table.table import PanoMappingTable
from .base import SEEN_AT, AngleArray, Param, Value, View, check_finite, check_view_size, radians_hint, register
from .grid import grid_angles
from .lookup import lookup_map, lookup_when_worth_it, row_sine_bounds
from .panorama import check_distance

# The default output size: 1280 x 720.
DEFAULT_SIZE = (1280, 720)


def default_direction(table: PanoMappingTable) -> tuple[float, float]:
    """(yaw_rad, pitch_rad): where a perspective view looks when it is not told.

    The camera's optical axis (its orientation's yaw and pitch) where the table sees along it. A camera that does
    not (a mirror camera, whose centre shows its own reflection, a cut-off disc about the axis: the table's
    camera elevation range stops short of the pole the centre sees; or a mirror camera imported without its
    cut-off radius, whose table reaches the pole) would show that disc alone: the view is
    turned off the axis, in the vertical plane through it (toward the camera's yaw where the axis is vertical),
    by the middle of the angles off the axis the table sees, toward the horizon (up from an axis below it, down
    from one above it).

    Convention: angles in the camera's axes: the centre sees camera elevation -pi/2 (axis ``"down"``) or
    +pi/2 (``"up"``); off the axis by ``alpha`` is camera elevation ``alpha - pi/2`` (down), ``pi/2 - alpha`` (up).
    """
    yaw, pitch, _ = table.model.orientation
    low, high = table.camera_range
    down = table.model.axis == "down"
    nearest = low + HALF_PI if down else HALF_PI - high  # the angle off the axis where the table starts (rad)
    record = table.info.get("import")
    mirror = isinstance(record, dict) and record.get("mirror") is True  # (its centre is its reflection, cut off or not)
    if nearest <= AXIS_SEEN_RAD and not mirror:
        return yaw, pitch
    alpha = HALF_PI + 0.5 * (low + high) if down else HALF_PI - 0.5 * (low + high)
    axis = np.array([math.cos(pitch) * math.cos(yaw), math.cos(pitch) * math.sin(yaw), math.sin(pitch)])
    # The unit vector of growing pitch at (yaw, pitch), turned down for an axis above the horizon.
    up = np.array([-math.sin(pitch) * math.cos(yaw), -math.sin(pitch) * math.sin(yaw), math.cos(pitch)])
    forward = math.cos(alpha) * axis + math.sin(alpha) * (up if pitch <= 0.0 else -up)
    horizontal = math.hypot(forward[0], forward[1])
    turned_yaw = yaw if horizontal < 1e-9 else math.atan2(forward[1], forward[0]) % (2.0 * math.pi)
    return turned_yaw, math.atan2(forward[2], horizontal)


# The camera sees along its axis where its table starts within this angle of it (rad): a fisheye's table
# starts at the pole itself.
AXIS_SEEN_RAD = 1e-6


@register
@dataclass(frozen=True)
class PerspectiveView(View):
    """A virtual pan-tilt-zoom camera: a pinhole at O_m looking anywhere.

    Parameters
    ----------
    yaw_rad : float, optional
        psi, the azimuth (rad) of the optical axis; None: the camera's (:meth:`resolved`,
        :func:`default_direction`).
    pitch_rad : float, optional
        tau, its elevation (rad), in [-pi/2, pi/2]; negative looks down,
        -pi/2 straight down; None: the camera's (its axis, or the middle of what it sees where it does not see
        along its axis).
    roll_rad : float
        omega (rad), about the optical axis: positive tips the camera's right
        side down, which turns the scene counter-clockwise in the image.
    fov_rad : float
        Horizontal field of view (rad), strictly between 0 and pi; default 90 deg.
    size : (W, H)
        Default 1280 x 720.
    distance : float, optional
        World units from O_m of what the view shows (default: far away); it changes the view only for a
        camera without a single viewpoint.

    Convention (the contract's formula): focal ``f = (W/2)/tan(fov/2)`` px;
    forward ``F = (cos tau cos psi, cos tau sin psi, sin tau)``,
    ``R0 = (sin psi, -cos psi, 0)``, ``D0 = F x R0``; right
    ``R = cos(omega) R0 + sin(omega) D0``, down
    ``Dn = cos(omega) D0 - sin(omega) R0``. Output pixel (k, l) sees the ray
    ``F + x R + y Dn`` with ``x = (k + 0.5 - W/2)/f``, ``y = (l + 0.5 - H/2)/f``.
    R0 is defined for every pitch, so straight down needs no special case.
    """

    kind: ClassVar[str] = "perspective"
    summary: ClassVar[str] = "Virtual pan-tilt-zoom camera: a pinhole at the camera position looking anywhere."
    params: ClassVar[tuple[Param, ...]] = (
        Param(
            "yaw",
            Value.ANGLE,
            "Azimuth of the optical axis (counter-clockwise from +X) [default: the camera's axis].",
            optional=True,
            aliases=("--yaw-deg",),
        ),
        Param(
            "pitch",
            Value.ANGLE,
            "Elevation of the optical axis, -90..90 (negative looks down) [default: the camera's axis, or the "
            "middle of what it sees where it does not see along its axis (a mirror's reflection of its camera)].",
            optional=True,
            aliases=("--pitch-deg",),
        ),
        Param(
            "roll",
            Value.ANGLE,
            "Turn about the optical axis (+ dips the right).",
            default=0.0,
            aliases=("--roll-deg",),
        ),
        Param(
            "fov",
            Value.ANGLE,
            "Horizontal field of view, more than 0 and less than 180.",
            default=90.0,
            aliases=("--fov-deg",),
        ),
        Param("size", Value.SIZE, "Output WxH [default: 1280x720].", optional=True),
        SEEN_AT,
    )
    example: ClassVar[str] = "yaw=30,pitch=-20,roll=0,fov=90,size=1280x720"
    bytes_per_pixel: ClassVar[int] = 28  # (measured: 24.0 bytes a pixel)

    yaw_rad: float | None = None
    pitch_rad: float | None = None
    roll_rad: float = 0.0
    fov_rad: float = math.radians(90.0)
    size: tuple[int, int] = DEFAULT_SIZE
    distance: float | None = None

    def __post_init__(self) -> None:
        check_finite(roll_rad=self.roll_rad, fov_rad=self.fov_rad)
        for name, value in (("yaw_rad", self.yaw_rad), ("pitch_rad", self.pitch_rad)):
            if value is not None:
                check_finite(**{name: value})
        if not 0.0 < self.fov_rad < math.pi:
            raise PanomapError(
                f"the field of view must be more than 0 and less than 180 deg, not {math.degrees(self.fov_rad):g} deg"
                + radians_hint(self.fov_rad, math.pi)
            )
        if self.pitch_rad is not None and abs(self.pitch_rad) > HALF_PI + 1e-12:
            raise PanomapError(
                f"the pitch must be between -90 and 90 deg, not {math.degrees(self.pitch_rad):g} deg"
                + (radians_hint(self.pitch_rad, HALF_PI) or " (turn the yaw by 180 deg instead)")
            )
        object.__setattr__(self, "size", check_view_size(self.size))
        check_distance(self.distance)

    @classmethod
    def from_params(cls, values: Mapping[str, Any]) -> Self:
        """The view from its parameters, as parsed from a view SPEC (every declared name, None where not given)."""
        size = DEFAULT_SIZE if values["size"] is None else values["size"]
        return cls(values["yaw"], values["pitch"], values["roll"], values["fov"], size, values["distance"])

    def resolved(self, table: PanoMappingTable) -> PerspectiveView:
        """The view with a yaw or pitch not given taken from the camera (:func:`default_direction`): its optical
        axis, or where it does not see along it (a mirror camera's own reflection), the middle of what it sees."""
        if self.yaw_rad is not None and self.pitch_rad is not None:
            return self
        yaw, pitch = default_direction(table)
        return replace(
            self,
            yaw_rad=yaw if self.yaw_rad is None else self.yaw_rad,
            pitch_rad=pitch if self.pitch_rad is None else self.pitch_rad,
        )

    @property
    def focal(self) -> float:
        """f = (W/2)/tan(fov/2), px."""
        return (self.size[0] / 2.0) / math.tan(self.fov_rad / 2.0)

    def axes(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Forward F, right R and down Dn, each (3,) unit vectors in world axes."""
        if self.yaw_rad is None or self.pitch_rad is None:
            raise PanomapError("this perspective view takes its yaw or pitch from a table: use view.resolved(table)")
        return view_axes(self.yaw_rad, self.pitch_rad, self.roll_rad)

    def _offsets(self) -> tuple[FloatArray, FloatArray]:
        """x (W,) and y (H,): ``(k + 0.5 - W/2)/f`` and ``(l + 0.5 - H/2)/f``."""
        return _offsets(self.size, self.fov_rad)

    def rays(self) -> FloatArray:
        """The (H, W, 3) ray directions ``F + x R + y Dn`` (world axes, not unit) the pixels see."""
        forward, right, down = self.axes()
        x, y = self._offsets()
        return forward + x[None, :, None] * right + y[:, None, None] * down

    def pixels(self, points: ArrayLike) -> FloatArray:
        """Where points (..., 3), relative to O_m, land in this view: (..., 2) (k, l).

        Continuous pixel coordinates with pixel centres at integers (the view's
        pinhole projection, the inverse of :meth:`rays`); NaN for points not in
        front of the camera.
        """
        d = np.asarray(points, dtype=np.float64)
        forward, right, down = self.axes()
        depth = d @ forward
        width, height = self.size
        f = self.focal
        with np.errstate(divide="ignore", invalid="ignore"):
            k = f * (d @ right) / depth + width / 2 - 0.5
            l = f * (d @ down) / depth + height / 2 - 0.5  # noqa: E741 (the contract names the row l)
        return np.where((depth > 0)[..., None], np.stack([k, l], axis=-1), np.nan)

    def output_size(self, table: PanoMappingTable) -> tuple[int, int]:
        """(W, H) of the output image: ``size``."""
        return self.size

    def points(self, table: PanoMappingTable) -> FloatArray | None:
        """The (H, W, 3) points at ``distance`` from O_m along the pixels' rays; None (directions) where no
        distance is given."""
        if self.distance is None:
            return None
        rays = self.rays()
        return rays * (self.distance / np.linalg.norm(rays, axis=-1, keepdims=True))

    def angles(self, table: PanoMappingTable) -> tuple[AngleArray, AngleArray]:
        """Azimuth and elevation (rad) of every pixel, each (H, W) float32 (see :func:`grid_angles`)."""
        forward, right, down = self.axes()
        x, y = self._offsets()
        return grid_angles([forward[a] + y * down[a] for a in range(3)], [x * right[a] for a in range(3)])

    def quick_map(self, table: PanoMappingTable, sampling: str) -> NDArray[np.float32] | None:
        """The bilinear map read from the table's :mod:`direction lookup <panomap.views.lookup>`.

        The rays' lengths ``sqrt(1 + x^2 + y^2)`` are made once per size and
        field of view and kept (for the last few), so turning the camera costs
        only the lookup.
        """
        lookup = lookup_when_worth_it(table) if sampling == "bilinear" else None
        if lookup is None:
            return None
        forward, right, down = self.axes()
        x, y = self._offsets()
        rows = [forward[a] + y * down[a] for a in range(3)]
        cols = [x * right[a] for a in range(3)]
        return lookup_map(lookup, rows, cols, _ray_lengths(self.size, self.fov_rad), row_sine_bounds(rows, right, x))


@lru_cache(maxsize=4)
def _offsets(size: tuple[int, int], fov: float) -> tuple[FloatArray, FloatArray]:
    """x (W,) and y (H,) of a view of ``size`` and ``fov`` (see :meth:`PerspectiveView._offsets`), read-only."""
    width, height = size
    f = (width / 2.0) / math.tan(fov / 2.0)
    x = np.asarray((np.arange(width) + 0.5 - width / 2) / f, dtype=np.float64)
    y = np.asarray((np.arange(height) + 0.5 - height / 2) / f, dtype=np.float64)
    for values in (x, y):
        values.setflags(write=False)
    return x, y


@lru_cache(maxsize=4)
def _ray_lengths(size: tuple[int, int], fov: float) -> NDArray[np.float32]:
    """``|F + x R + y Dn| = sqrt(1 + x^2 + y^2)``, (H, W) float32, read-only: the same for every yaw, pitch, roll."""
    x, y = _offsets(size, fov)
    lengths = np.sqrt(1.0 + np.square(x)[None, :] + np.square(y)[:, None]).astype(np.float32)
    lengths.setflags(write=False)
    return lengths
