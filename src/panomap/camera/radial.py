"""Radial stretching functions r = f_r(rho): models, fits and their valid range.

Convention: ``rho`` is the elevation (rad, Z up, negative below the horizon
through O_m); ``r`` the distance (px) from the image centre. ``axis`` says
which pole the image centre sees: ``"down"`` (a ceiling camera, the paper's
case: the centre sees rho = -pi/2) or ``"up"`` (the centre sees +pi/2).
``alpha`` is the angle of a ray from that pole: ``rho + pi/2`` looking down,
``pi/2 - rho`` looking up.

Models, with their parameters in order:

- ``paper``: ``(a0, a1, a2, a3, a4)``, ``r = sum a_k rho^k`` (eq. 2), fitted
  by least squares together with the centre pair (the optical axis landing on
  the image centre, r = 0), exactly as Algorithm 1 prints it.
- ``odd1``, ``odd3``, ``odd5``: ``(a1[, a3[, a5]])``,
  ``r = a1 alpha + a3 alpha^3 + a5 alpha^5``: the usual fisheye form; passes
  through the axis by construction.
- ``poly2``, ``poly3``: ``(a1, a2[, a3])``, ``r = a1 alpha + a2 alpha^2 + a3 alpha^3``:
  low-degree polynomials through the optical axis (r = 0 where it lands).
- ``unified``: ``(gamma, xi)``, ``r = gamma sin(alpha) / (xi + cos(alpha))``:
  the unified model of single-viewpoint mirror cameras (xi = 1 parabolic,
  0 < xi < 1 hyperbolic, xi = 0 a pinhole); NaN where ``xi + cos(alpha) <= 0``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..errors import PanomapError
from ..geometry import HALF_PI, FloatArray

AXES = ("down", "up")
MODEL_PARAMETERS: dict[str, int] = {
    "paper": 5,
    "odd1": 1,
    "odd3": 2,
    "odd5": 3,
    "poly2": 2,
    "poly3": 3,
    "unified": 2,
}
MODELS = tuple(MODEL_PARAMETERS)
# The order in which automatic selection prefers models that tie: fewer parameters first.
AUTO_CANDIDATES = ("odd1", "odd3", "unified", "poly2", "odd5", "poly3", "paper")


def axis_elevation(axis: str) -> float:
    """Elevation (rad) that the image centre sees: -pi/2 down, +pi/2 up."""
    return -HALF_PI if axis == "down" else HALF_PI


def alpha_of_rho(rho: ArrayLike, axis: str) -> FloatArray:
    """Angle (rad) of a ray from the pole the image centre sees."""
    rho = np.asarray(rho, dtype=np.float64)
    return rho + HALF_PI if axis == "down" else HALF_PI - rho


@dataclass(frozen=True)
class RadialFunction:
    """A fitted radial stretching function ``r = f_r(rho)``.

    Parameters
    ----------
    kind : str
        One of ``MODELS``.
    coefficients : tuple of float
        The model's parameters, in the order given in the module docstring.
    axis : {"down", "up"}
        Which pole the image centre sees.
    """

    kind: str
    coefficients: tuple[float, ...]
    axis: str = "down"

    def __post_init__(self) -> None:
        if self.kind not in MODEL_PARAMETERS:
            raise PanomapError(f"unknown radial model {self.kind!r} (known: {', '.join(MODELS)})")
        if self.axis not in AXES:
            raise PanomapError(f"axis must be 'down' or 'up', not {self.axis!r}")
        coefficients = tuple(float(c) for c in self.coefficients)
        if len(coefficients) != MODEL_PARAMETERS[self.kind]:
            raise PanomapError(
                f"radial model {self.kind!r} takes {MODEL_PARAMETERS[self.kind]} coefficients, got {len(coefficients)}"
            )
        if not all(np.isfinite(coefficients)):
            raise PanomapError(f"radial model {self.kind!r} has non-finite coefficients")
        object.__setattr__(self, "coefficients", coefficients)

    def __call__(self, rho: ArrayLike) -> FloatArray:
        """Image radius (px) at elevation(s) ``rho`` (rad); NaN where undefined."""
        rho = np.asarray(rho, dtype=np.float64)
        c = self.coefficients
        if self.kind == "paper":
            return np.asarray(np.polynomial.polynomial.polyval(rho, c), dtype=np.float64)
        alpha = alpha_of_rho(rho, self.axis)
        if self.kind == "unified":
            gamma, xi = c
            denominator = xi + np.cos(alpha)
            with np.errstate(divide="ignore", invalid="ignore"):
                r = gamma * np.sin(alpha) / denominator
            return np.where(denominator > 0, r, np.nan)
        return np.asarray(np.polynomial.polynomial.polyval(alpha, _power_coefficients(self.kind, c)), dtype=np.float64)

    def slope(self, rho: ArrayLike) -> FloatArray:
        """dr/drho (px/rad) at elevation(s) ``rho``, by central differences."""
        rho = np.asarray(rho, dtype=np.float64)
        step = 1e-6
        return (self(rho + step) - self(rho - step)) / (2 * step)

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "coefficients": list(self.coefficients), "axis": self.axis}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> RadialFunction:
        try:
            return cls(str(data["kind"]), tuple(data["coefficients"]), str(data["axis"]))
        except (KeyError, TypeError, ValueError) as exc:
            if isinstance(exc, PanomapError):
                raise
            raise PanomapError(f"radial model is malformed ({exc})") from None


def _power_coefficients(kind: str, c: tuple[float, ...]) -> FloatArray:
    """Coefficients of alpha^0, alpha^1, ... of a polynomial model through the axis."""
    if kind.startswith("odd"):
        full = np.zeros(2 * len(c))
        full[1::2] = c
        return full
    return np.concatenate([[0.0], c])


def _design(kind: str, alpha: FloatArray) -> FloatArray:
    """Design matrix (n, p) of a polynomial model through the axis."""
    count = MODEL_PARAMETERS[kind]
    powers = [2 * k + 1 for k in range(count)] if kind.startswith("odd") else [k + 1 for k in range(count)]
    return np.stack([alpha**p for p in powers], axis=-1)


def fit_radial(kind: str, rho: ArrayLike, r: ArrayLike, axis: str, weights: ArrayLike | None = None) -> RadialFunction:
    """Least-squares fit of one radial model to landmark (rho, r) pairs.

    Parameters
    ----------
    kind : str
        One of ``MODELS``.
    rho : (n,) array_like
        Landmark elevations (rad).
    r : (n,) array_like
        Landmark image radii (px).
    axis : {"down", "up"}
        Which pole the image centre sees; gives the centre pair (the paper's
        (O_c, O_m): ``r = 0`` at ``rho = -pi/2`` looking down, ``+pi/2`` up).
    weights : (n,) array_like, optional
        Weight of each landmark's radial residual (1/sigma, 1/px). The
        ``paper`` model ignores them: Algorithm 1 is unweighted.

    Raises
    ------
    PanomapError
        If the data cannot determine the model's parameters.
    """
    rho = np.asarray(rho, dtype=np.float64)
    r = np.asarray(r, dtype=np.float64)
    distinct = _distinct_count(rho)
    needed = MODEL_PARAMETERS[kind] - (1 if kind == "paper" else 0)
    if distinct < needed:
        raise PanomapError(
            f"model {kind!r} needs landmarks at {needed} or more distinct elevations, these are at {distinct}"
        )
    if kind == "paper":
        # Algorithm 1, step 3: the centre pair first, then every landmark, raw rho.
        rho_all = np.concatenate([[axis_elevation(axis)], rho])
        r_all = np.concatenate([[0.0], r])
        design = np.vander(rho_all, 5, increasing=True)
        coefficients, *_ = np.linalg.lstsq(design, r_all, rcond=None)
        return RadialFunction("paper", tuple(coefficients), axis)
    alpha = alpha_of_rho(rho, axis)
    w = np.ones_like(r) if weights is None else np.asarray(weights, dtype=np.float64)
    if kind == "unified":
        return RadialFunction("unified", _fit_unified(alpha, r, w), axis)
    design = _design(kind, alpha)
    coefficients, *_ = np.linalg.lstsq(design * w[:, None], r * w, rcond=None)
    return RadialFunction(kind, tuple(coefficients), axis)


def _fit_unified(alpha: FloatArray, r: FloatArray, w: FloatArray) -> tuple[float, float]:
    """(gamma, xi) minimising the weighted radial residual; gamma is solved in closed form."""
    from scipy import optimize  # here, not at the top: importing SciPy costs every command 0.6 s

    xi_low = max(0.0, -float(np.cos(alpha.max()))) + 1e-6
    xi_high = 50.0

    def profile(xi: float) -> tuple[float, float]:
        g = w * np.sin(alpha) / (xi + np.cos(alpha))
        gamma = float(g @ (w * r) / (g @ g))
        return float(np.sum((gamma * g - w * r) ** 2)), gamma

    grid = xi_low + (xi_high - xi_low) * np.linspace(0.0, 1.0, 401) ** 3
    costs = np.array([profile(x)[0] for x in grid])
    best = int(np.argmin(costs))
    lo, hi = grid[max(best - 1, 0)], grid[min(best + 1, len(grid) - 1)]
    result = optimize.minimize_scalar(
        lambda x: profile(x)[0], bounds=(lo, hi), method="bounded", options={"xatol": 1e-12}
    )
    xi = float(result.x) if result.fun <= costs[best] else float(grid[best])
    return profile(xi)[1], xi


def _distinct_count(rho: FloatArray, tolerance: float = 1e-4) -> int:
    """Number of distinct elevations, counting values closer than ``tolerance`` rad as one."""
    values = np.sort(rho[np.isfinite(rho)])
    if values.size == 0:
        return 0
    return int(1 + np.count_nonzero(np.diff(values) > tolerance))


def is_monotonic(radial: RadialFunction, rho_low: float, rho_high: float, samples: int = 1024) -> bool:
    """Whether f_r is finite and strictly monotonic, in the axis's sense, on [low, high]."""
    rho = np.linspace(rho_low, rho_high, samples)
    r = radial(rho)
    if not np.all(np.isfinite(r)):
        return False
    steps = np.diff(r)
    return bool(np.all(steps > 0) if radial.axis == "down" else np.all(steps < 0))


def coefficient_covariance(
    radial: RadialFunction, rho: FloatArray, r: FloatArray, weights: FloatArray | None = None
) -> FloatArray:
    """Covariance (p, p) of the coefficients from the weighted residuals' Jacobian.

    ``C = (J^T J)^-1 s^2`` with J the Jacobian of the weighted radial residuals
    and ``s^2`` their sum of squares over the degrees of freedom (1 when there
    are none). For the ``paper`` model the centre pair counts as a residual.
    """
    w = np.ones_like(r) if weights is None else np.asarray(weights, dtype=np.float64)
    if radial.kind == "paper":
        rho = np.concatenate([[axis_elevation(radial.axis)], rho])
        r = np.concatenate([[0.0], r])
        w = np.ones_like(r)
    base = np.asarray(radial.coefficients)
    jacobian = np.empty((rho.size, base.size))
    for k in range(base.size):
        step = 1e-6 * max(1.0, abs(base[k]))
        shifted = base.copy()
        shifted[k] += step
        jacobian[:, k] = w * (RadialFunction(radial.kind, tuple(shifted), radial.axis)(rho) - radial(rho)) / step
    residual = w * (radial(rho) - r)
    dof = rho.size - base.size
    scale = float(residual @ residual / dof) if dof > 0 else 1.0
    return np.asarray(np.linalg.pinv(jacobian.T @ jacobian) * scale)


def radius_standard_error(radial: RadialFunction, covariance: FloatArray, rho: ArrayLike) -> FloatArray:
    """Standard error (px) of f_r at elevation(s) ``rho`` given the coefficients' covariance."""
    rho = np.asarray(rho, dtype=np.float64)
    base = np.asarray(radial.coefficients)
    gradient = np.empty((*rho.shape, base.size))
    for k in range(base.size):
        step = 1e-6 * max(1.0, abs(base[k]))
        shifted = base.copy()
        shifted[k] += step
        gradient[..., k] = (RadialFunction(radial.kind, tuple(shifted), radial.axis)(rho) - radial(rho)) / step
    variance = np.einsum("...i,ij,...j->...", gradient, covariance, gradient)
    return np.sqrt(np.maximum(variance, 0.0))


def valid_elevation_range(
    radial: RadialFunction,
    landmark_range: tuple[float, float],
    cutoff_radius: float,
    outer_radius: float,
    samples: int = 20001,
) -> tuple[float, float]:
    """The widest elevation interval around the landmarks where the table is valid.

    Grows ``landmark_range`` in both directions while f_r stays finite,
    strictly monotonic in the axis's sense, and within
    ``[cutoff_radius, outer_radius]``; ends that stop at a radius are refined
    to where f_r equals that radius.

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
            f"the fitted radial function ({radial.kind}) is not monotonic between the "
            f"landmarks' elevations {np.degrees(low):.2f} and {np.degrees(high):.2f} deg; "
            "the landmarks are inconsistent or too few"
        )
    r_low, r_high = sorted((float(radial(low)), float(radial(high))))
    if r_low < cutoff_radius - 1e-9 or r_high > outer_radius + 1e-9:
        raise PanomapError(
            f"landmarks reach radii {r_low:.1f}..{r_high:.1f} px, outside the annulus "
            f"{cutoff_radius:.1f}..{outer_radius:.1f} px given by the cut-off and outer radii"
        )
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
    while start > 0 and inside[start - 1] and rising[start - 1]:
        start -= 1
    while stop < grid.size - 1 and inside[stop + 1] and rising[stop]:
        stop += 1
    rho_s, rho_e = float(grid[start]), float(grid[stop])
    if start > 0 and rising[start - 1] and np.isfinite(r[start - 1]):
        rho_s = _refine_bound(radial, grid[start - 1], grid[start], cutoff_radius, outer_radius)
    if stop < grid.size - 1 and rising[stop] and np.isfinite(r[stop + 1]):
        rho_e = _refine_bound(radial, grid[stop], grid[stop + 1], cutoff_radius, outer_radius)
    return rho_s, rho_e


def _refine_bound(radial: RadialFunction, a: float, b: float, cutoff_radius: float, outer_radius: float) -> float:
    """Elevation in [a, b] where f_r crosses the cut-off or outer radius."""
    from scipy import optimize  # here, not at the top: importing SciPy costs every command 0.6 s

    ra, rb = float(radial(a)), float(radial(b))
    for bound in (cutoff_radius, outer_radius):
        if (ra - bound) * (rb - bound) <= 0 and ra != rb:
            return float(optimize.brentq(lambda x, level=bound: float(radial(x)) - level, a, b, xtol=1e-14))
    # Neither crossed (cannot happen when exactly one endpoint is inside): keep the inside one.
    inside_a = cutoff_radius <= ra <= outer_radius
    return float(a if inside_a else b)
