"""Where a radial function can serve a table: finite, monotonic, within the annulus.

Convention: as in :mod:`panomap.camera.radial_models`; "monotonic in the
axis's sense" means r grows with rho looking down and falls looking up.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from ..errors import PanomapError
from ..geometry import HALF_PI

if TYPE_CHECKING:
    from .radial import RadialFunction


def is_monotonic(radial: RadialFunction, rho_low: float, rho_high: float, samples: int = 1024) -> bool:
    """Whether f_r is finite and strictly monotonic, in the axis's sense, on [low, high]."""
    rho = np.linspace(rho_low, rho_high, samples)
    r = radial(rho)
    if not np.all(np.isfinite(r)):
        return False
    steps = np.diff(r)
    return bool(np.all(steps > 0) if radial.axis == "down" else np.all(steps < 0))


def valid_elevation_range(
    radial: RadialFunction,
    landmark_range: tuple[float, float],
    cutoff_radius: float,
    outer_radius: float,
    samples: int = 20001,
    slack_px: float = 0.0,
    data: str = "landmarks",
    annulus: str = "given by the cut-off and outer radii",
) -> tuple[float, float]:
    """The widest elevation interval around the landmarks where the table is valid.

    ``data`` names what ``landmark_range`` spans in the errors ("landmarks", or "lines" for a camera learned
    from straight lines).

    Grows ``landmark_range`` in both directions while f_r stays finite,
    strictly monotonic in the axis's sense, and within
    ``[cutoff_radius, outer_radius]``; ends that stop at a radius are refined
    to where f_r equals that radius. A landmark end up to ``slack_px`` beyond
    the annulus (measurement noise at its rim) is allowed: the interval then
    ends at that landmark, whose direction the camera sees (its pixel is on the
    rim; the fit, within the noise, puts it past). Stopping where f_r reaches
    the circle would leave the directions between uncovered: a degree on a
    lens whose law flattens at its rim (an orthographic fisheye's), where a
    pixel spans a degree.

    ``data`` names what ``landmark_range`` came from in the errors (``"the lines' points"`` for a camera
    learned from lines), ``annulus`` where the radii came from.

    Returns
    -------
    (rho_s, rho_e) : tuple of float
        Elevations (rad), ``rho_s < rho_e``.

    Raises
    ------
    PanomapError
        If f_r is not monotonic over the landmarks or a landmark falls outside
        the annulus.
    """
    low, high = landmark_range
    if not is_monotonic(radial, low, high):
        raise PanomapError(
            f"the fitted radial function ({radial.kind}) is not monotonic between the elevations of "
            f"{data}, {np.degrees(low):.2f} and {np.degrees(high):.2f} deg; {data} are inconsistent or too few"
        )
    r_low, r_high = sorted((float(radial(low)), float(radial(high))))
    if r_low < cutoff_radius - slack_px - 1e-9 or r_high > outer_radius + slack_px + 1e-9:
        raise PanomapError(
            f"{data} reach radii {r_low:.1f}..{r_high:.1f} px, outside the annulus "
            f"{cutoff_radius:.1f}..{outer_radius:.1f} px {annulus}"
        )
    beyond = [not cutoff_radius - 1e-9 <= float(radial(end)) <= outer_radius + 1e-9 for end in (low, high)]
    # The landmarks' ends join the grid; grid points within 1e-9 rad of them go, or a step of
    # ~1e-17 rad between near-duplicates could round to no rise and stop the growth there.
    grid = np.linspace(-HALF_PI, HALF_PI, samples)
    grid = np.sort(np.concatenate([grid[(np.abs(grid - low) > 1e-9) & (np.abs(grid - high) > 1e-9)], [low, high]]))
    r = radial(grid)
    sign = 1.0 if radial.axis == "down" else -1.0
    inside = np.isfinite(r) & (r >= cutoff_radius) & (r <= outer_radius)
    rising = np.concatenate([sign * np.diff(r) > 0, [False]])  # step from k to k+1 keeps order
    start = int(np.searchsorted(grid, low))
    stop = int(np.searchsorted(grid, high))
    while not beyond[0] and start > 0 and inside[start - 1] and rising[start - 1]:
        start -= 1
    while not beyond[1] and stop < grid.size - 1 and inside[stop + 1] and rising[stop]:
        stop += 1
    rho_s, rho_e = float(grid[start]), float(grid[stop])
    if not beyond[0] and start > 0 and rising[start - 1] and np.isfinite(r[start - 1]):
        rho_s = _refine_bound(radial, grid[start - 1], grid[start], cutoff_radius, outer_radius)
    if not beyond[1] and stop < grid.size - 1 and rising[stop] and np.isfinite(r[stop + 1]):
        rho_e = _refine_bound(radial, grid[stop], grid[stop + 1], cutoff_radius, outer_radius)
    return rho_s, rho_e


def _refine_bound(radial: RadialFunction, a: float, b: float, cutoff_radius: float, outer_radius: float) -> float:
    """Elevation in [a, b] where f_r crosses the cut-off or outer radius."""
    from scipy import optimize  # here, not at the top: importing SciPy is slow

    ra, rb = float(radial(a)), float(radial(b))
    for bound in (cutoff_radius, outer_radius):
        if (ra - bound) * (rb - bound) <= 0 and ra != rb:
            return float(optimize.brentq(lambda x, level=bound: float(radial(x)) - level, a, b, xtol=1e-14))
    # Neither crossed (cannot happen when exactly one endpoint is inside): keep the inside one.
    inside_a = cutoff_radius <= ra <= outer_radius
    return float(a if inside_a else b)


def annulus_coverage_problem(
    radial: RadialFunction,
    landmark_range: tuple[float, float],
    cutoff_radius: float,
    outer_radius: float,
    slack_px: float = 0.0,
    to_outer: bool = True,
) -> str | None:
    """Why f_r does not run monotonically from the cut-off radius to the image circle (None if it does).

    Landmarks up to ``slack_px`` beyond the annulus are allowed (see :func:`valid_elevation_range`).
    ``to_outer`` False asks only that it run from the cut-off radius (the outer one a default that
    the table narrows to where f_r runs).
    """
    try:
        rho_s, rho_e = valid_elevation_range(radial, landmark_range, cutoff_radius, outer_radius, slack_px=slack_px)
    except PanomapError as exc:
        return exc.detail
    ends = sorted((float(radial(rho_s)), float(radial(rho_e))))
    tolerance = 1.0  # px
    pole = rho_s <= -math.pi / 2 + 1e-6 if radial.axis == "down" else rho_e >= math.pi / 2 - 1e-6
    if ends[0] > cutoff_radius + tolerance and not pole:
        return f"turns back before the cut-off radius ({ends[0]:.1f} px, needs {cutoff_radius:.1f} px)"
    if to_outer and ends[1] < outer_radius - tolerance:
        return f"turns back or ends before the image circle ({ends[1]:.1f} px, needs {outer_radius:.1f} px)"
    return None
