"""A camera without a single viewpoint: where each elevation's ray leaves the optical axis.

A mirror of revolution seen by a camera on its axis (a spherical or a conical mirror) reflects every ray
within the plane through the axis and the ray, so each reflected ray, extended, meets the axis; but not
all at one point, as a single-viewpoint mirror's rays do (the paper's mirrors "of any shape"). The ray of
camera elevation rho leaves from the axis point

    O(rho) = O_m + z(rho) * a,

with ``a`` the camera's own Z axis (world up for a level camera, ``R @ (0, 0, 1)`` for a tilted one) and
``z`` in world units. Its direction is the table's (azimuth, elevation): a point far away is seen where
the table says, a point at a finite distance along the ray through it
(:meth:`Viewpoint.elevation_of_point`). A single-viewpoint camera has no ``Viewpoint`` (z = 0).

**The caustic of a mirror of revolution** (:func:`caustic_shape`). A camera at distance c below the
mirror's apex sees, at angle beta off the axis, the mirror point at distance t(beta) from its lens; the
law of reflection, with the reflected ray at angle alpha from the pole the image centre sees, gives
``d ln t / d beta = tan((alpha + beta) / 2)``, and the reflected ray meets the axis at height
``t sin(alpha + beta) / sin(alpha)`` above the lens. For a camera far from the mirror compared with its
size (beta small, ``beta = r / f``), to first order in 1/f::

    z(alpha) = k_0 + k_1 h(alpha),   h(alpha) = int_0^r(alpha) tan(alpha'/2) dr' + r(alpha) cot(alpha)

with ``r = |f_r|`` the radial function (px): the mirror's whole shape is in f_r, its size in k_1 (world
units a pixel) and the lens' place in k_0. On a spherical mirror this is within 0.2 mm of the exact ray
origins over a 53 mm spread (docs/fitting.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..errors import PanomapError
from ..geometry import HALF_PI, FloatArray
from ..values import MAX_ABS
from .radial import RadialFunction
from .radial_models import alpha_of_rho, rho_of_alpha

# Newton steps of :meth:`Viewpoint.elevation_of_point`: z moves by centimetres over a radian, so each step
# gains a factor of about |z'| / distance (1e-2 at a centimetre's spread seen from a metre); six are rounding.
NEWTON_STEPS = 6
# Nodes of a viewpoint's z(rho), and of the grid the caustic's integral is taken on.
VIEWPOINT_NODES = 181
CAUSTIC_GRID = 1024
# Most nodes a table file's viewpoint may hold.
MAX_VIEWPOINT_NODES = 4096
# Distance (world units) at which the fit report states the parallax a single-viewpoint table would make.
PARALLAX_DISTANCE = 1.0


@dataclass(frozen=True)
class Viewpoint:
    """The ray origins of a camera without a single viewpoint, along its axis: z at elevation nodes.

    Parameters
    ----------
    elevations_rad : tuple of float
        Camera elevations rho (rad), increasing: the nodes (2 to ``MAX_VIEWPOINT_NODES``).
    offsets : tuple of float
        z at each node: the ray origin's height above O_m along the camera's Z axis (world units). Between
        nodes z is linear; beyond the ends, it keeps the end's value.
    """

    elevations_rad: tuple[float, ...]
    offsets: tuple[float, ...]

    def __post_init__(self) -> None:
        rho = tuple(float(x) for x in self.elevations_rad)
        z = tuple(float(x) for x in self.offsets)
        if not 2 <= len(rho) <= MAX_VIEWPOINT_NODES or len(z) != len(rho):
            raise PanomapError(
                f"a viewpoint needs 2 to {MAX_VIEWPOINT_NODES} elevations and as many offsets, "
                f"not {len(rho)} and {len(z)}"
            )
        if not all(math.isfinite(x) for x in rho + z):
            raise PanomapError("the viewpoint's elevations or offsets are not finite")
        if not all(abs(x) <= MAX_ABS for x in z):
            raise PanomapError(
                f"the viewpoint's offsets reach {max(abs(x) for x in z):g} world units: beyond {MAX_ABS:g} in size "
                "(no mirror is that large; the views' arithmetic would overflow)"
            )
        if not all(-HALF_PI - 1e-9 <= x <= HALF_PI + 1e-9 for x in rho) or not all(np.diff(rho) > 0):
            raise PanomapError("the viewpoint's elevations are not increasing within -90..90 deg")
        object.__setattr__(self, "elevations_rad", rho)
        object.__setattr__(self, "offsets", z)

    def offset(self, rho: ArrayLike) -> FloatArray:
        """z(rho) (world units), (...) like the camera elevations ``rho`` (rad)."""
        return np.asarray(np.interp(np.asarray(rho, dtype=np.float64), self.elevations_rad, self.offsets))

    def slope(self, rho: ArrayLike) -> FloatArray:
        """dz/drho (world units a rad), (...) like ``rho``: each segment's, 0 beyond the ends."""
        nodes = np.asarray(self.elevations_rad)
        steps = np.diff(self.offsets) / np.diff(nodes)
        rho = np.asarray(rho, dtype=np.float64)
        index = np.clip(np.searchsorted(nodes, rho) - 1, 0, steps.size - 1)
        inside = (rho >= nodes[0]) & (rho <= nodes[-1])
        return np.where(inside, steps[index], 0.0)

    def elevation_of_point(self, horizontal: ArrayLike, height: ArrayLike) -> FloatArray:
        """Camera elevation (rad) of the ray that passes through a point.

        Solves ``rho = atan2(height - z(rho), horizontal)`` by Newton's method from the ray from O_m.

        Parameters
        ----------
        horizontal : (...) array_like
            The point's distance from the camera's axis, world units (>= 0).
        height : (...) array_like
            Its height above O_m along the camera's axis, world units.

        Returns
        -------
        (...) ndarray
            rho (rad); NaN where an input is NaN.
        """
        h = np.asarray(horizontal, dtype=np.float64)
        z = np.asarray(height, dtype=np.float64)
        with np.errstate(invalid="ignore"):
            rho = np.arctan2(z - self.offset(np.arctan2(z, h)), h)
            for _ in range(NEWTON_STEPS):
                rise = z - self.offset(rho)
                squared = h * h + rise * rise
                with np.errstate(divide="ignore"):
                    residual = rho - np.arctan2(rise, h)
                    derivative = 1.0 + self.slope(rho) * h / squared
                    step = np.where(squared > 0, residual / derivative, 0.0)
                rho = rho - np.clip(step, -0.5, 0.5)
        return np.asarray(rho)

    def excursion(self, low_rad: float, high_rad: float) -> float:
        """How far (world units) the ray origin moves along the axis over camera elevations low..high (rad)."""
        z = self.offset(np.linspace(low_rad, high_rad, 257))
        return float(np.max(z) - np.min(z))

    def to_dict(self) -> dict[str, Any]:
        """Plain data: the nodes and what they mean."""
        return {
            "elevations_rad": list(self.elevations_rad),
            "offsets": list(self.offsets),
            "along": "the camera's z axis, from O_m, world units",
        }

    @classmethod
    def from_dict(cls, data: Any) -> Viewpoint:
        if not isinstance(data, dict):
            raise PanomapError("the camera's viewpoint is malformed (not an object)")
        lists: list[list[Any]] = []
        for key in ("elevations_rad", "offsets"):
            values = data.get(key)
            if not isinstance(values, list) or len(values) > MAX_VIEWPOINT_NODES:
                raise PanomapError(
                    f"the camera's viewpoint is malformed (its nodes are not lists of at most {MAX_VIEWPOINT_NODES})"
                )
            if not all(isinstance(c, int | float) and not isinstance(c, bool) for c in values):
                raise PanomapError("the camera's viewpoint is malformed (a node is not a number)")
            lists.append(values)
        return cls(tuple(lists[0]), tuple(lists[1]))


def caustic_shape(radial: RadialFunction, rho: ArrayLike) -> FloatArray:
    """h (px) of the caustic of a mirror of revolution with radial function ``radial`` (see the module's
    docstring), at camera elevations ``rho`` (rad, (...)): ``z = k_0 + k_1 h`` are its ray origins. A kind
    that knows its ray origins (``exact_origins``: the spherical mirror's law) gives them itself, exact, in
    its own unit (sphere radii).

    The integral runs from the pole the image centre sees (alpha = 0) on ``CAUSTIC_GRID`` steps of alpha;
    NaN where alpha is not in (0, pi).
    """
    alpha = alpha_of_rho(rho, radial.axis)
    if radial.spec.exact_origins:
        return np.asarray(radial.spec.axis_heights(radial.coefficients, alpha), dtype=np.float64)
    finite = alpha[np.isfinite(alpha)]
    top = float(np.max(finite)) if finite.size else 0.0
    if not 0.0 < top < math.pi:
        top = min(max(top, 1e-3), math.pi - 1e-3)
    grid = np.linspace(top / CAUSTIC_GRID, top, CAUSTIC_GRID)
    r = np.abs(radial(rho_of_alpha(grid, radial.axis)))
    slopes = np.tan(grid / 2)
    integral = np.concatenate([[0.0], np.cumsum(0.5 * (slopes[1:] + slopes[:-1]) * np.diff(r))])
    h = integral + r / np.tan(grid)
    with np.errstate(invalid="ignore"):
        inside = (alpha > 0) & (alpha < math.pi)
    return np.where(inside, np.interp(alpha, grid, h), np.nan)


def caustic_viewpoint(radial: RadialFunction, k0: float, k1: float, elevation_range: tuple[float, float]) -> Viewpoint:
    """The :class:`Viewpoint` ``z = k0 + k1 h`` (k0 world units, k1 world units a px) of the caustic of
    ``radial`` (:func:`caustic_shape`), at ``VIEWPOINT_NODES`` nodes over camera elevations ``elevation_range``
    (rad)."""
    rho = np.linspace(*elevation_range, VIEWPOINT_NODES)
    z = k0 + k1 * caustic_shape(radial, rho)
    if not np.all(np.isfinite(z)):
        raise PanomapError("the mirror's caustic is not finite over the elevations (its radial function ends)")
    return Viewpoint(tuple(rho.tolist()), tuple(z.tolist()))


def parallax_px(
    radial: RadialFunction,
    viewpoint: Viewpoint,
    elevation_range: tuple[float, float],
    distance: float = PARALLAX_DISTANCE,
) -> float:
    """The largest error (px) a single-viewpoint table of this camera would make for points at horizontal
    ``distance`` (world units) from the axis, over camera elevations ``elevation_range`` (rad): the point on
    each ray at that distance, seen from O_m instead of from the ray's origin."""
    rho = np.linspace(*elevation_range, 181)
    height = viewpoint.offset(rho) + distance * np.tan(rho)
    seen = np.arctan2(height, distance)
    return float(np.nanmax(np.abs(radial(seen) - radial(rho))))
