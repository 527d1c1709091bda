"""What every view is: the :class:`View` base, how a kind declares its parameters, and the one registry.

Convention: an output image is W x H; pixel (k, l) is column k, row l and
samples at its centre, ``(k + 0.5)/W`` across and ``(l + 0.5)/H`` down the
view's extent. Views are upright (higher elevation higher up) and not
mirrored (what is on your left, standing at O_m facing the view, is on the
left), so azimuth decreases from left to right. Lengths are relative to O_m,
in world units; angles in rad, and every angle field says so in its name
(``yaw_rad``, ``fov_rad``, ``azimuth_rad``, ``theta_start_rad``), as the
specs and the command line, which take degrees, say ``yaw=30`` / ``--yaw-deg``.

A view is a frozen value. ``view.angles(table)`` gives the (H, W) azimuth and
elevation of every output pixel; :func:`build_map` turns them into the
(H, W, 2) float32 (u, v) map that ``cv2.remap`` takes, NaN where there is no
source; ``view.remapper(table)`` builds that map once and hands out a
:class:`~panomap.remap.Remapper` to apply it to any number of frames. A view
of a surface (a cylinder, a plane, the floor) also gives the points it sees,
``view.points(table)``, relative to O_m; a view of directions gives None.

A view kind is one class in one file, registered once with :func:`register`:
it declares its kind name, its parameters (:class:`Param`: the spec key and
option name, the value type, the default, the help, older option names) and
how to build itself from them (:meth:`View.from_params`). The view specs
(:mod:`panomap.views.spec`) and the view commands are generated from these
declarations, so a new kind is one new file plus its import in
``views/__init__.py``.
"""

from __future__ import annotations

import enum
import math
from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Self, TypeVar

import numpy as np
from numpy.typing import NDArray

from .. import inputs
from ..errors import PanomapError
from ..geometry import FloatArray, pixel_centres
from ..remap import Remapper
from ..table.table import PanoMappingTable, check_table

# Angles of any float precision: the perspective and floor views compute theirs in float32.
AngleArray = NDArray[np.floating[Any]]

MAX_VIEW_PIXELS = 50_000_000
MAX_VIEW_SIDE = 32_000


class ParameterError(PanomapError):
    """A parameter out of range; ``key`` names it, ``problem`` says what is wrong.

    The message is ``"KEY PROBLEM"``; a caller that knows the parameter by
    another name (the command line's ``--size``) can say it its own way.
    """

    def __init__(self, key: str, problem: str) -> None:
        self.key = key
        self.problem = problem
        super().__init__(f"{key} {problem}")


def check_view_size(size: tuple[int, int], what: str = "size") -> tuple[int, int]:
    """Validate an output size (W, H): positive, each side and the area bounded.

    Raises :class:`ParameterError` with key ``what``.
    """
    width, height = inputs.whole_numbers(size, 2, f"the {what} (W, H)")
    if width <= 0 or height <= 0:
        raise ParameterError(what, f"{width}x{height}: width and height must be positive")
    if width > MAX_VIEW_SIDE or height > MAX_VIEW_SIDE or width * height > MAX_VIEW_PIXELS:
        raise ParameterError(
            what,
            f"{width}x{height}: too large (at most {MAX_VIEW_SIDE} px a side and {MAX_VIEW_PIXELS:,} px in all)",
        )
    return width, height


def check_finite(**values: float) -> None:
    """Refuse NaN, infinities and beyond ``MAX_ABS`` (PanomapError), and what is no number (text, None, an array:
    TypeError), naming the value."""
    for name, value in values.items():
        inputs.number(value, name)


def radians_hint(value_rad: float, most_rad: float) -> str:
    """`` (the angle is in radians: ...)`` where ``value_rad``, beyond ``most_rad``, reads as degrees typed in (more
    than 2 pi, at most 360, in whole or half degrees: a spec's 400 deg, 6.98 rad, gets none); else ""."""
    size = abs(value_rad)
    if size <= max(most_rad, 2.0 * math.pi) or size > 360.0 or not (2.0 * size).is_integer():
        return ""
    return f" (the angle is in radians: math.radians({value_rad:g}) for {value_rad:g} deg)"


@dataclass(frozen=True)
class Band:
    """A height band ``z_bottom < z_top`` relative to O_m (world units)."""

    z_bottom: float
    z_top: float

    def __post_init__(self) -> None:
        check_finite(z_bottom=self.z_bottom, z_top=self.z_top)
        if not self.z_bottom < self.z_top:
            raise PanomapError(f"the band must have z_bottom < z_top, got {self.z_bottom:g}..{self.z_top:g}")

    def heights(self, rows: int) -> FloatArray:
        """``z_top - (l + 0.5)*(z_top - z_bottom)/H`` for l = 0..H-1; shape (H,)."""
        _, fy = pixel_centres(1, rows)
        return self.z_top - fy * (self.z_top - self.z_bottom)


class Value(enum.Enum):
    """The type of a view parameter, as specs and the command line write it.

    NUMBER a finite number; ANGLE a finite number of degrees (radians in the
    view); PAIR two numbers (``A:B`` in a spec, two values on the command
    line); SIZE ``WxH``.
    """

    NUMBER = "number"
    ANGLE = "angle"
    PAIR = "pair"
    SIZE = "size"


@dataclass(frozen=True)
class Param:
    """One declared parameter of a view kind.

    Parameters
    ----------
    name : str
        The spec key, and the command line's option ``--name``.
    value : Value
        Its type.
    help : str
        One line for ``--help``.
    default : float, optional
        The value when it is not given, in spec units (degrees for angles).
    optional : bool
        May be left out with no default: the view gets None.
    aliases : tuple of str
        Older option names that still work (``"--start-deg"``).
    metavar : str, optional
        How ``--help`` and messages show the value; default from the type.
    """

    name: str
    value: Value
    help: str
    default: float | None = None
    optional: bool = False
    aliases: tuple[str, ...] = ()
    metavar: str | None = None

    @property
    def required(self) -> bool:
        return self.default is None and not self.optional

    @property
    def shown_as(self) -> str | None:
        """The metavar: the declared one, else the type's (None: the option type's own)."""
        return self.metavar or {Value.ANGLE: "DEG", Value.PAIR: "A B", Value.SIZE: "WxH"}.get(self.value)


# The output size, as most kinds take it.
OUTPUT_SIZE = Param("size", Value.SIZE, "Output WxH.")
# Where a view of directions (the panorama, the perspective view) sees things: far away unless given. Only a
# camera without a single viewpoint (a spherical or conical mirror) sees a near point elsewhere.
SEEN_AT = Param(
    "distance",
    Value.NUMBER,
    "Distance of what the view shows, for a mirror without a single viewpoint [default: far away].",
    optional=True,
)


@dataclass(frozen=True)
class OneOf:
    """Parameters of which exactly one must be given, e.g. the output size or a resolution.

    ``what`` names what they give ("the output size"), for messages.
    """

    what: str
    names: tuple[str, ...]

    @property
    def how_many(self) -> str:
        return "one of the two" if len(self.names) == 2 else "exactly one of them"


class View(ABC):
    """What every view offers; a kind declares ``kind``, ``summary``, ``params`` and :meth:`from_params`.

    Class attributes
    ----------------
    kind : str
        The kind's name, in specs (``KIND:...``) and as its command.
    summary : str
        One line for its command's ``--help``.
    params : tuple of Param
        Its parameters, in the order the command's help lists them.
    one_of : OneOf, optional
        Parameters of which exactly one must be given.
    example : str
        The ``key=value,...`` of one valid view of this kind.
    """

    kind: ClassVar[str]
    summary: ClassVar[str]
    params: ClassVar[tuple[Param, ...]]
    one_of: ClassVar[OneOf | None] = None
    example: ClassVar[str]
    # The view places world points at distances and heights (floor, cylinder, plane): a table learned from
    # lines knows no distance (its camera is at the origin unless its height was given).
    needs_camera_height: ClassVar[bool] = False
    # The memory a still view of this kind takes made (bytes per output pixel: its map, the steps making it, the
    # remap's maps, the picture out), erring high: each kind's from the peak RSS of its views of 1000 x 500 and
    # 8000 x 4000 px of the demo's table (the slope between them), rounded up by 15% or more.
    bytes_per_pixel: ClassVar[int] = 64

    @classmethod
    @abstractmethod
    def from_params(cls, values: Mapping[str, Any]) -> Self:
        """Build the view from its parameters: every declared name, None where not given.

        Values are parsed: angles in rad, pairs and sizes as tuples.
        """

    @abstractmethod
    def output_size(self, table: PanoMappingTable) -> tuple[int, int]:
        """(W, H) of the output image."""

    @abstractmethod
    def angles(self, table: PanoMappingTable) -> tuple[AngleArray, AngleArray]:
        """Azimuth and elevation (rad), each (H, W), of every output pixel."""

    def memory_bytes(self, size: tuple[int, int]) -> int:
        """The memory (bytes, about, erring high) this view takes made at ``size`` (W, H) px."""
        return int(size[0]) * int(size[1]) * self.bytes_per_pixel

    def resolved(self, table: PanoMappingTable) -> View:
        """This view with the values it takes from the table filled in (a perspective view's default axis is
        the camera's); the view itself where it takes none. :func:`build_map` calls it first."""
        return self

    def points(self, table: PanoMappingTable) -> FloatArray | None:
        """The (H, W, 3) points the pixels see, relative to O_m (world axes); None for a view of directions.

        Views of a surface (cylinder, plane, floor) give its points, the
        same for every table except that the floor, placed in world
        coordinates, is taken relative to ``table.camera_position``; the
        panorama and the perspective view see directions, not a surface.
        """
        return None

    def quick_map(self, table: PanoMappingTable, sampling: str) -> NDArray[np.float32] | None:
        """This view's map by a quicker way than sampling its angles, or None (see :func:`build_map`)."""
        return None

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
        map_uv = build_map(table, self, sampling)
        return Remapper(map_uv, table.image_size, interpolation, fill, fixed_point)


_KINDS: dict[str, type[View]] = {}
ViewClass = TypeVar("ViewClass", bound=type[View])


def register(cls: ViewClass) -> ViewClass:
    """Register a view kind under ``cls.kind``, once (a class decorator)."""
    if cls.kind in _KINDS:
        raise ValueError(f"view kind {cls.kind!r} is registered twice")
    names = [param.name for param in cls.params]
    if len(set(names)) != len(names) or "name" in names or "kind" in names:
        raise ValueError(f"view kind {cls.kind!r}: parameter names must be unique and not 'name' or 'kind'")
    if cls.one_of is not None and not set(cls.one_of.names) <= {p.name for p in cls.params if p.optional}:
        raise ValueError(f"view kind {cls.kind!r}: one_of must name optional parameters")
    _KINDS[cls.kind] = cls
    return cls


def view_kinds() -> Mapping[str, type[View]]:
    """Every registered kind, name -> class, in registration order (``import panomap.views`` registers them)."""
    return _KINDS


def check_view(value: Any, what: str = "the view") -> View:
    """``value`` if it is a :class:`View`; a TypeError naming ``what`` and how one is made otherwise."""
    checked: View = inputs.instance(value, View, what, " (a view value such as panomap.PerspectiveView(...))")
    return checked


def build_map(
    table: PanoMappingTable, view: View, sampling: str = "bilinear", *, exact: bool = False
) -> NDArray[np.float32]:
    """The (H, W, 2) float32 (u, v) source map of ``view``, NaN where there is no source.

    The one place maps are made. The exact way: the view's angles, sampled
    from the table. By default a view's :meth:`View.quick_map` is used where it
    has one (the perspective and floor views read a lookup of the table by ray
    direction, within 0.01 px of the exact map and with the same pixels
    valid; the panoramas sample the table at their row and column angles,
    giving the exact map); ``exact=True`` takes the exact way always. The
    lookup is made from the second such map of a table on (it costs about two
    exact maps): a lone map, as a still render or a video's, is exact.

    For a camera without a single viewpoint (:mod:`panomap.camera.viewpoint`), a view of a surface
    (cylinder, plane, floor) reads each point through the ray that reaches it from its own origin on the
    axis; the panoramas and the perspective view see directions, the rays at infinity.

    Parameters
    ----------
    table : PanoMappingTable
        The camera's table.
    view : View
        Any view: :class:`GenericPanorama`, :class:`CylinderPanorama`, :class:`PlaneView`,
        :class:`PerspectiveView`, :class:`FloorView`.
    sampling : {"bilinear", "nearest"}
        How the table is read between its entries (``nearest``: the paper's floor indices).
    exact : bool
        Make the map the exact way, never the quick one.

    Returns
    -------
    (H, W, 2) float32 ndarray
        Each output pixel's source pixel (u, v), NaN where there is none.
    """
    check_table(table)
    check_view(view)
    view = view.resolved(table)
    if not table.model.single_viewpoint:
        # A camera without a single viewpoint sees a point along the ray through it from its own origin: the
        # views of a surface read the table at those rays' directions; the views of directions, at infinity.
        points = view.points(table)
        if points is not None:
            theta_ray, rho_ray = table.model.point_angles(points)
            return table.sample(theta_ray.astype(np.float32), rho_ray.astype(np.float32), sampling, overwrite=True)
    if not exact:
        quick = view.quick_map(table, sampling)
        if quick is not None:
            return quick
    theta, rho = view.angles(table)
    # The angles are this function's own: sampling may reuse their memory.
    return table.sample(theta, rho, sampling, overwrite=True)
