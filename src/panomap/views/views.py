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
source; ``view.remapper(table)`` builds that map once and hands out a
:class:`~panomap.remap.Remapper` to apply it to any number of frames.

Beyond the paper: :class:`PerspectiveView`, a virtual pan-tilt-zoom pinhole
camera at O_m, and :class:`FloorView`, a bird's-eye map of a horizontal plane
in world coordinates.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import PanomapError
from ..geometry import HALF_PI, TWO_PI, FloatArray, azimuth_elevation, pixel_centres, wrap_azimuth
from ..remap import Remapper
from ..table.table import PanoMappingTable

# Angles of any float precision: the perspective view computes its own in float32.
AngleArray = NDArray[np.floating[Any]]

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

    def angles(self, table: PanoMappingTable) -> tuple[AngleArray, AngleArray]:
        """Azimuth and elevation (rad), each (H, W), of every output pixel."""
        ...

    def remapper(
        self,
        table: PanoMappingTable,
        sampling: str = "bilinear",
        interpolation: str = "linear",
        fill: float | tuple[float, ...] = 0.0,
        fixed_point: bool = False,
    ) -> Remapper:
        """The view's map, built once, ready to apply to frames of ``table``'s camera."""
        ...


class _Remappable:
    """Gives a view :meth:`remapper`; the view itself supplies ``output_size`` and ``angles``."""

    def remapper(
        self,
        table: PanoMappingTable,
        sampling: str = "bilinear",
        interpolation: str = "linear",
        fill: float | tuple[float, ...] = 0.0,
        fixed_point: bool = False,
    ) -> Remapper:
        """Build this view's map once and return a :class:`Remapper` applying it.

        Parameters
        ----------
        table : PanoMappingTable
            The camera's table; frames must have its image size (any size when
            the table has none).
        sampling : {"bilinear", "nearest"}
            Table sampling, as in :func:`build_map`.
        interpolation : {"nearest", "linear", "cubic"}
            Image interpolation.
        fill : float or tuple of float
            Value of output pixels without a source.
        fixed_point : bool
            Keep the map in OpenCV's fixed-point form (smaller; positions in
            1/32 px); see :class:`Remapper`.
        """
        map_uv = build_map(table, self, sampling)  # type: ignore[arg-type]
        return Remapper(map_uv, table.image_size, interpolation, fill, fixed_point)


def _panorama_azimuths(theta_start: float, width: int) -> FloatArray:
    """``theta_start - 2*pi*(k + 0.5)/W`` wrapped to [0, 2*pi); shape (W,)."""
    fx, _ = pixel_centres(width, 1)
    return wrap_azimuth(theta_start - TWO_PI * fx)


@dataclass(frozen=True)
class GenericPanorama(_Remappable):
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

    def angles(self, table: PanoMappingTable) -> tuple[AngleArray, AngleArray]:
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
class CylinderPanorama(_Remappable):
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
class PlaneView(_Remappable):
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


@dataclass(frozen=True)
class PerspectiveView(_Remappable):
    """A virtual pan-tilt-zoom camera: a pinhole at O_m looking anywhere.

    Parameters
    ----------
    yaw : float
        psi, the azimuth (rad) of the optical axis.
    pitch : float
        tau, its elevation (rad), in [-pi/2, pi/2]; negative looks down,
        -pi/2 straight down.
    roll : float
        omega (rad), about the optical axis: positive tips the camera's right
        side down, which turns the scene counter-clockwise in the image.
    fov : float
        Horizontal field of view (rad), strictly between 0 and pi.
    size : (W, H)

    Convention (the contract's formula): focal ``f = (W/2)/tan(fov/2)`` px;
    forward ``F = (cos tau cos psi, cos tau sin psi, sin tau)``,
    ``R0 = (sin psi, -cos psi, 0)``, ``D0 = F x R0``; right
    ``R = cos(omega) R0 + sin(omega) D0``, down
    ``Dn = cos(omega) D0 - sin(omega) R0``. Output pixel (k, l) sees the ray
    ``F + x R + y Dn`` with ``x = (k + 0.5 - W/2)/f``, ``y = (l + 0.5 - H/2)/f``.
    R0 is defined for every pitch, so straight down needs no special case.
    """

    yaw: float
    pitch: float
    roll: float
    fov: float
    size: tuple[int, int]

    def __post_init__(self) -> None:
        _check_finite(yaw=self.yaw, pitch=self.pitch, roll=self.roll, fov=self.fov)
        if not 0.0 < self.fov < math.pi:
            raise PanomapError(
                f"the field of view must be more than 0 and less than 180 deg, not {math.degrees(self.fov):g} deg"
            )
        if abs(self.pitch) > HALF_PI + 1e-12:
            raise PanomapError(
                f"the pitch must be between -90 and 90 deg, not {math.degrees(self.pitch):g} deg "
                "(turn the yaw by 180 deg instead)"
            )
        object.__setattr__(self, "size", check_view_size(self.size))

    @property
    def focal(self) -> float:
        """f = (W/2)/tan(fov/2), px."""
        return (self.size[0] / 2.0) / math.tan(self.fov / 2.0)

    def axes(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Forward F, right R and down Dn, each (3,) unit vectors in world axes."""
        psi, tau, omega = self.yaw, self.pitch, self.roll
        forward = np.array([math.cos(tau) * math.cos(psi), math.cos(tau) * math.sin(psi), math.sin(tau)])
        right0 = np.array([math.sin(psi), -math.cos(psi), 0.0])
        down0 = np.cross(forward, right0)
        right = math.cos(omega) * right0 + math.sin(omega) * down0
        down = math.cos(omega) * down0 - math.sin(omega) * right0
        return forward, right, down

    def _offsets(self) -> tuple[FloatArray, FloatArray]:
        """x (W,) and y (H,): ``(k + 0.5 - W/2)/f`` and ``(l + 0.5 - H/2)/f``."""
        width, height = self.size
        f = self.focal
        x = np.asarray((np.arange(width) + 0.5 - width / 2) / f, dtype=np.float64)
        y = np.asarray((np.arange(height) + 0.5 - height / 2) / f, dtype=np.float64)
        return x, y

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
        return self.size

    def angles(self, table: PanoMappingTable) -> tuple[AngleArray, AngleArray]:
        """Azimuth and elevation (rad) of every pixel, each (H, W) float32 (see :func:`_grid_angles`)."""
        forward, right, down = self.axes()
        x, y = self._offsets()
        return _grid_angles([forward[a] + y * down[a] for a in range(3)], [x * right[a] for a in range(3)])


@dataclass(frozen=True)
class FloorView(_Remappable):
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
    below O_m, one looking up only planes above; :meth:`angles` refuses the
    others.
    """

    z_plane: float
    x_range: tuple[float, float]
    y_range: tuple[float, float]
    size: tuple[int, int]

    def __post_init__(self) -> None:
        x_min, x_max = (float(c) for c in self.x_range)
        y_min, y_max = (float(c) for c in self.y_range)
        _check_finite(z_plane=self.z_plane, x_min=x_min, x_max=x_max, y_min=y_min, y_max=y_max)
        for axis, low, high in (("x", x_min, x_max), ("y", y_min, y_max)):
            if not low < high:
                raise PanomapError(f"the {axis} extent {low:g}..{high:g} is empty: it needs {axis}_min < {axis}_max")
        object.__setattr__(self, "x_range", (x_min, x_max))
        object.__setattr__(self, "y_range", (y_min, y_max))
        object.__setattr__(self, "size", check_view_size(self.size))

    @classmethod
    def with_resolution(
        cls, z_plane: float, x_range: tuple[float, float], y_range: tuple[float, float], resolution: float
    ) -> FloorView:
        """A floor view of about ``resolution`` world units per pixel.

        ``W = round((x_max - x_min)/resolution)`` and likewise H (at least 1);
        the extent is kept, so pixels are ``(x_max - x_min)/W`` wide.
        """
        x_min, x_max = (float(c) for c in x_range)
        y_min, y_max = (float(c) for c in y_range)
        _check_finite(x_min=x_min, x_max=x_max, y_min=y_min, y_max=y_max, resolution=resolution)
        if resolution <= 0:
            raise PanomapError(f"the resolution must be positive, not {resolution:g}")
        # An empty extent gets one pixel here and is refused, with its reason, by the constructor.
        width = max(1, round((x_max - x_min) / resolution))
        height = max(1, round((y_max - y_min) / resolution))
        if width * height > MAX_VIEW_PIXELS or max(width, height) > MAX_VIEW_SIDE:
            raise PanomapError(
                f"a resolution of {resolution:g} gives a {width} x {height} image: too large "
                f"(at most {MAX_VIEW_SIDE} px a side and {MAX_VIEW_PIXELS:,} px in all)"
            )
        return cls(z_plane, (x_min, x_max), (y_min, y_max), (width, height))

    def points(self) -> FloatArray:
        """The (H, W, 3) world points the pixels see."""
        width, height = self.size
        fx, fy = pixel_centres(width, height)
        (x_min, x_max), (y_min, y_max) = self.x_range, self.y_range
        out = np.empty((height, width, 3))
        out[..., 0] = (x_min + fx * (x_max - x_min))[None, :]
        out[..., 1] = (y_max - fy * (y_max - y_min))[:, None]
        out[..., 2] = self.z_plane
        return out

    def check_plane(self, table: PanoMappingTable) -> None:
        """Refuse a plane the table's camera cannot see: at or above O_m looking down, at or below looking up."""
        z0 = table.camera_position[2]
        if table.model.radial.axis == "down" and self.z_plane >= z0:
            raise PanomapError(
                f"the plane Z = {self.z_plane:g} is at or above the camera (Z0 = {z0:g}); "
                "a camera looking down sees only planes below it"
            )
        if table.model.radial.axis == "up" and self.z_plane <= z0:
            raise PanomapError(
                f"the plane Z = {self.z_plane:g} is at or below the camera (Z0 = {z0:g}); "
                "a camera looking up sees only planes above it"
            )

    def output_size(self, table: PanoMappingTable) -> tuple[int, int]:
        return self.size

    def angles(self, table: PanoMappingTable) -> tuple[AngleArray, AngleArray]:
        """Azimuth and elevation (rad) of every pixel, each (H, W) float32 (see :func:`_grid_angles`)."""
        self.check_plane(table)
        width, height = self.size
        fx, fy = pixel_centres(width, height)
        (x_min, x_max), (y_min, y_max) = self.x_range, self.y_range
        x0, y0, z0 = table.camera_position
        rows = [np.zeros(height), y_max - fy * (y_max - y_min) - y0, np.full(height, self.z_plane - z0)]
        cols = [x_min + fx * (x_max - x_min) - x0, np.zeros(width), np.zeros(width)]
        return _grid_angles(rows, cols)


def _grid_angles(rows: list[FloatArray], cols: list[FloatArray]) -> tuple[AngleArray, AngleArray]:
    """Azimuth and elevation (rad), (H, W) float32, of rays ``d[l, k, a] = rows[a][l] + cols[a][k]``.

    Parameters
    ----------
    rows : three (H,) arrays
    cols : three (W,) arrays
        The x, y and z components of the rays (world axes) as a row term plus a
        column term, as the perspective and floor views' rays are.

    float32 for speed: about 2.4e-7 rad of rounding, 2e-4 px at a 900 px image
    radius. The azimuth is ``atan2(-d_y, -d_x) + pi``, which lands in [0, 2*pi]
    without a wrapping pass.
    """

    def component(axis: int, sign: float) -> NDArray[np.float32]:
        row = (sign * rows[axis]).astype(np.float32)
        col = (sign * cols[axis]).astype(np.float32)
        return np.add(row[:, None], col[None, :])

    minus_x, minus_y, d_z = component(0, -1.0), component(1, -1.0), component(2, 1.0)
    theta = np.arctan2(minus_y, minus_x)
    theta += np.float32(math.pi)
    # In place (fewer fresh pages), and in NumPy: cv2.magnitude's last bit depends on the
    # arrays' alignment in memory, which would make maps differ from run to run.
    horizontal = np.multiply(minus_x, minus_x, out=minus_x)
    horizontal += np.multiply(minus_y, minus_y, out=minus_y)
    np.sqrt(horizontal, out=horizontal)
    rho = np.arctan2(d_z, horizontal, out=d_z)
    return theta, rho


def build_map(table: PanoMappingTable, view: View, sampling: str = "bilinear") -> NDArray[np.float32]:
    """The (H, W, 2) float32 (u, v) source map of ``view``, NaN where there is no source.

    The one place maps are made: the view's angles, sampled from the table.
    """
    theta, rho = view.angles(table)
    # The angles are this function's own: sampling may reuse their memory.
    return table.sample(theta, rho, sampling, overwrite=True)
