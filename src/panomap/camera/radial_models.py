"""The radial model kinds: each one class (or one instance of a family) registered once.

Convention: ``rho`` is the elevation (rad, Z up, negative below the horizon
through O_m); ``r`` the distance (px) from the image centre. ``axis`` says
which pole the image centre sees: ``"down"`` (a ceiling camera, the paper's
case: the centre sees rho = -pi/2) or ``"up"`` (the centre sees +pi/2).
``alpha`` is the angle of a ray from that pole: ``rho + pi/2`` looking down,
``pi/2 - rho`` looking up.

A kind declares its name, its parameters in order, how it evaluates
``r = f_r(rho)`` from them and how it is fitted to landmark (rho, r) pairs,
and what the fit may do with it (:attr:`RadialKind.centre_given`,
:attr:`RadialKind.weighted`). :data:`RADIAL_KINDS` holds them by name, in the
order the command line lists them; a new model is one class and one line in
:data:`RADIAL_KINDS`. The kinds:

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
- ``fisheye``: ``(f, k)``, ``r = f sin(k alpha) / k`` for ``k > 0``, ``f alpha``
  for ``k = 0``, ``f tan(-k alpha) / (-k)`` for ``k < 0``: the designed fisheye
  projections in one family (k = 1 orthographic, 1/2 equisolid, 0 equidistant,
  -1/2 stereographic, -1 perspective), ``-1 <= k <= 1``; NaN where
  ``|k| alpha > pi/2`` (beyond it the radius would turn back or diverge).
- ``sphere``: ``(f, c)``, a pinhole of focal length f (px) on the axis of a
  spherical mirror, c sphere radii below its apex: ``r = f tan(beta)`` with
  beta the camera ray whose reflection leaves at alpha from the pole
  (:func:`sphere_alpha`). A mirror without a single viewpoint
  (:mod:`panomap.camera.viewpoint`): never chosen by the automatic selection of
  a single-viewpoint fit, tried with its caustic by the landmark fit
  (:mod:`panomap.calibrate.landmarks.viewpoint`); NaN beyond the mirror's rim
  (where alpha stops growing with beta).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from functools import lru_cache
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike

from ..errors import PanomapError
from ..geometry import HALF_PI, FloatArray

AXES = ("down", "up")


def axis_elevation(axis: str) -> float:
    """Elevation (rad) that the image centre sees: -pi/2 down, +pi/2 up."""
    return -HALF_PI if axis == "down" else HALF_PI


def alpha_of_rho(rho: ArrayLike, axis: str) -> FloatArray:
    """Angle (rad) of a ray from the pole the image centre sees."""
    rho = np.asarray(rho, dtype=np.float64)
    return rho + HALF_PI if axis == "down" else HALF_PI - rho


def rho_of_alpha(alpha: ArrayLike, axis: str) -> FloatArray:
    """Elevation (rad) in the camera's axes of a ray at ``alpha`` (rad) from the pole the image centre sees:
    the inverse of :func:`alpha_of_rho`."""
    alpha = np.asarray(alpha, dtype=np.float64)
    return alpha - HALF_PI if axis == "down" else HALF_PI - alpha


@dataclass(frozen=True)
class RadialKind(ABC):
    """One radial model kind: its parameters, its evaluation and its fit.

    Attributes
    ----------
    name : str
        The name in files, on the command line and in reports.
    selection_rank : int
        Automatic selection prefers fewer parameters; among kinds with as many,
        the lower rank.
    centre_given : bool (class)
        The centre pair (r = 0 where the optical axis lands) is one of the
        fit's data: the centre is taken as given and cannot be refined.
    weighted : bool (class)
        The fit follows the noise model: weighted least squares, the joint
        refinement on whitened residuals and, when the kind is asked for by
        name, outlier rejection. False for Algorithm 1, printed unweighted.
    mirror_law : bool (class)
        The kind is the projection law of central mirror cameras (any conic
        mirror): preferred first among kinds with as many parameters when the
        image shows the camera's own reflection (:data:`MIRROR_CANDIDATES`).
    lens_law : bool (class)
        The kind is the law fisheye lenses are designed to (their projections in
        one family), not a curve fitted to them. Automatic selection keeps the
        lens law where the image shows no cut-off disc, and the mirror law where
        it does, against a more flexible kind whose held-out score is better by
        less than a wider margin than among curves.
    auto_candidate : bool (class)
        Automatic selection of a single-viewpoint fit tries the kind. False for a
        law of a mirror without a single viewpoint, which the fit tries with its
        ray origins instead.
    exact_origins : bool (class)
        The kind knows its mirror's ray origins (:meth:`axis_heights`): a
        non-central fit takes them from its coefficients, not from the caustic
        that f_r implies to first order (:mod:`panomap.camera.viewpoint`).
    """

    name: str
    selection_rank: int = 0

    centre_given: ClassVar[bool] = False
    weighted: ClassVar[bool] = True
    mirror_law: ClassVar[bool] = False
    lens_law: ClassVar[bool] = False
    auto_candidate: ClassVar[bool] = True
    exact_origins: ClassVar[bool] = False

    @property
    @abstractmethod
    def parameters(self) -> tuple[str, ...]:
        """The parameters' names, in the order of the coefficients."""

    @property
    def parameter_count(self) -> int:
        return len(self.parameters)

    @property
    def needed_elevations(self) -> int:
        """Distinct landmark elevations a fit needs (the centre pair gives one more)."""
        return self.parameter_count - (1 if self.centre_given else 0)

    @abstractmethod
    def evaluate(self, coefficients: tuple[float, ...], rho: FloatArray, axis: str) -> FloatArray:
        """Image radius (px) at elevations ``rho`` (rad); NaN where undefined."""

    @abstractmethod
    def fit(self, rho: FloatArray, r: FloatArray, axis: str, weights: FloatArray | None) -> tuple[float, ...]:
        """Least-squares coefficients from landmark (rho, r) pairs, weighted by ``weights`` (1/px) if ``weighted``."""

    def axis_heights(self, coefficients: tuple[float, ...], alpha: FloatArray) -> FloatArray:
        """Where the rays at ``alpha`` (rad from the pole) meet the axis, in the mirror's own unit, along the
        axis away from the lens: only for a kind with ``exact_origins``."""
        raise NotImplementedError(f"radial model {self.name!r} does not know its ray origins")


@dataclass(frozen=True)
class PaperPolynomial(RadialKind):
    """The paper's 4th-degree polynomial in rho (eq. 2), fitted as Algorithm 1 prints it."""

    centre_given: ClassVar[bool] = True
    weighted: ClassVar[bool] = False

    @property
    def parameters(self) -> tuple[str, ...]:
        return ("a0", "a1", "a2", "a3", "a4")

    def evaluate(self, coefficients: tuple[float, ...], rho: FloatArray, axis: str) -> FloatArray:
        return np.asarray(np.polynomial.polynomial.polyval(rho, coefficients), dtype=np.float64)

    def fit(self, rho: FloatArray, r: FloatArray, axis: str, weights: FloatArray | None) -> tuple[float, ...]:
        # Algorithm 1, step 3: the centre pair first, then every landmark, raw rho; unweighted.
        rho_all, r_all = with_centre_pair(rho, r, axis)
        design = np.vander(rho_all, self.parameter_count, increasing=True)
        coefficients, *_ = np.linalg.lstsq(design, r_all, rcond=None)
        return tuple(coefficients)


@dataclass(frozen=True)
class AxisPolynomial(RadialKind):
    """``r = sum a_p alpha^p`` over ``powers`` (all >= 1): a polynomial through the optical axis."""

    powers: tuple[int, ...] = (1,)

    def __post_init__(self) -> None:
        if not self.powers or list(self.powers) != sorted(set(self.powers)) or self.powers[0] < 1:
            raise ValueError(f"{self.name}: powers must be distinct, increasing and >= 1, not {self.powers}")

    @property
    def parameters(self) -> tuple[str, ...]:
        return tuple(f"a{p}" for p in self.powers)

    def evaluate(self, coefficients: tuple[float, ...], rho: FloatArray, axis: str) -> FloatArray:
        full = np.zeros(max(self.powers) + 1)  # coefficients of alpha^0, alpha^1, ...
        full[list(self.powers)] = coefficients
        return np.asarray(np.polynomial.polynomial.polyval(alpha_of_rho(rho, axis), full), dtype=np.float64)

    def fit(self, rho: FloatArray, r: FloatArray, axis: str, weights: FloatArray | None) -> tuple[float, ...]:
        alpha = alpha_of_rho(rho, axis)
        w = np.ones_like(r) if weights is None else np.asarray(weights, dtype=np.float64)
        design = np.stack([alpha**p for p in self.powers], axis=-1)
        coefficients, *_ = np.linalg.lstsq(design * w[:, None], r * w, rcond=None)
        return tuple(coefficients)


@dataclass(frozen=True)
class Unified(RadialKind):
    """The unified model of single-viewpoint mirror cameras, ``r = gamma sin(alpha) / (xi + cos(alpha))``."""

    mirror_law: ClassVar[bool] = True
    lens_law: ClassVar[bool] = True

    @property
    def parameters(self) -> tuple[str, ...]:
        return ("gamma", "xi")

    def evaluate(self, coefficients: tuple[float, ...], rho: FloatArray, axis: str) -> FloatArray:
        alpha = alpha_of_rho(rho, axis)
        gamma, xi = coefficients
        denominator = xi + np.cos(alpha)
        with np.errstate(divide="ignore", invalid="ignore"):
            r = gamma * np.sin(alpha) / denominator
        return np.where(denominator > 0, r, np.nan)

    def fit(self, rho: FloatArray, r: FloatArray, axis: str, weights: FloatArray | None) -> tuple[float, ...]:
        """(gamma, xi) minimising the weighted radial residual; gamma is solved in closed form."""
        from scipy import optimize  # here, not at the top: importing SciPy is slow

        alpha = alpha_of_rho(rho, axis)
        w = np.ones_like(r) if weights is None else np.asarray(weights, dtype=np.float64)
        xi_low = max(0.0, -float(np.cos(alpha.max()))) + 1e-6
        xi_high = 50.0

        def profile(xi: float) -> tuple[float, float]:
            g = w * np.sin(alpha) / (xi + np.cos(alpha))
            gamma = float(g @ (w * r) / (g @ g))
            return float(np.sum((gamma * g - w * r) ** 2)), gamma

        grid = xi_low + (xi_high - xi_low) * np.linspace(0.0, 1.0, 401) ** 3
        # The profile over the whole grid at once: (grid, n) arrays, no Python loop.
        g = (w * np.sin(alpha))[None, :] / (grid[:, None] + np.cos(alpha)[None, :])
        wr = w * r
        gammas = (g @ wr) / np.einsum("ij,ij->i", g, g)
        costs = np.sum((gammas[:, None] * g - wr[None, :]) ** 2, axis=1)
        best = int(np.argmin(costs))
        lo, hi = grid[max(best - 1, 0)], grid[min(best + 1, len(grid) - 1)]
        with np.errstate(invalid="ignore"):  # (a side of the bracket where the law is undefined costs inf)
            result = optimize.minimize_scalar(
                lambda x: profile(x)[0], bounds=(lo, hi), method="bounded", options={"xatol": 1e-12}
            )
        xi = float(result.x) if result.fun <= costs[best] else float(grid[best])
        return profile(xi)[1], xi


# The fisheye family's exponent k spans the designed projections, orthographic (1) to perspective (-1).
FISHEYE_K_RANGE = (-1.0, 1.0)


def fisheye_basis(alpha: FloatArray, k: ArrayLike) -> FloatArray:
    """``sin(k alpha) / k`` (k > 0), ``alpha`` (k = 0) or ``tan(-k alpha) / (-k)`` (k < 0); NaN where
    ``|k| alpha > pi/2``. ``alpha`` (n,) in rad; ``k`` a scalar, or (g, 1) for a grid of (g, n) values; the
    result in rad (times f: px)."""
    k = np.asarray(k, dtype=np.float64)
    x = np.abs(k) * alpha
    if k.ndim == 0 and k >= 0:  # the profile's one k (most calls): the sine branch alone, the same values
        return np.asarray(np.where(x <= HALF_PI + 1e-12, alpha * np.sinc(x / np.pi), np.nan), dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        sine = alpha * np.sinc(x / np.pi)  # sin(x) / x, 1 at x = 0
        tangent = alpha * np.where(x > 0, np.tan(x) / np.where(x > 0, x, 1.0), 1.0)
    basis = np.where(k >= 0, sine, tangent)
    valid = np.where(k >= 0, x <= HALF_PI + 1e-12, x < HALF_PI)
    return np.asarray(np.where(valid, basis, np.nan), dtype=np.float64)


@dataclass(frozen=True)
class Fisheye(RadialKind):
    """The designed fisheye projections in one family, ``r = f sin(k alpha) / k`` (k > 0), ``f alpha`` (k = 0),
    ``f tan(-k alpha) / (-k)`` (k < 0)."""

    lens_law: ClassVar[bool] = True

    @property
    def parameters(self) -> tuple[str, ...]:
        return ("f", "k")

    def evaluate(self, coefficients: tuple[float, ...], rho: FloatArray, axis: str) -> FloatArray:
        f, k = coefficients
        return np.asarray(f * fisheye_basis(alpha_of_rho(rho, axis), float(k)), dtype=np.float64)

    def fit(self, rho: FloatArray, r: FloatArray, axis: str, weights: FloatArray | None) -> tuple[float, ...]:
        """(f, k) minimising the weighted radial residual; f is solved in closed form for each k."""
        from scipy import optimize  # here, not at the top: importing SciPy is slow

        alpha = alpha_of_rho(rho, axis)
        w = np.ones_like(r) if weights is None else np.asarray(weights, dtype=np.float64)
        wr = w * r

        def profile(k: float) -> tuple[float, float]:
            g = w * fisheye_basis(alpha, k)
            if not np.all(np.isfinite(g)) or g @ g <= 0:
                return math.inf, math.nan
            f = float(g @ wr / (g @ g))
            return float(np.sum((f * g - wr) ** 2)), f

        grid = np.linspace(*FISHEYE_K_RANGE, 201)
        # The profile over the whole grid at once: (grid, n) arrays, no Python loop.
        g = w * fisheye_basis(alpha, grid[:, None])
        with np.errstate(invalid="ignore", divide="ignore"):
            fs = (g @ wr) / np.einsum("ij,ij->i", g, g)
            costs = np.sum((fs[:, None] * g - wr[None, :]) ** 2, axis=1)
        costs = np.where(np.isfinite(costs), costs, np.inf)
        if not np.any(np.isfinite(costs)):
            raise PanomapError("the fisheye model cannot reach these landmarks' angles")
        best = int(np.argmin(costs))
        lo, hi = grid[max(best - 1, 0)], grid[min(best + 1, len(grid) - 1)]
        with np.errstate(invalid="ignore"):  # (a side of the bracket where the law is undefined costs inf)
            result = optimize.minimize_scalar(
                lambda k: profile(k)[0], bounds=(lo, hi), method="bounded", options={"xatol": 1e-12}
            )
        k = float(result.x) if result.fun <= costs[best] else float(grid[best])
        return profile(k)[1], k


# Camera rays (beta) a spherical mirror's law is tabulated on, from the axis to its rim, and the ratios c (lens
# distance over sphere radius) its fit profiles: c -> infinity is an orthographic view of the sphere (equisolid).
SPHERE_BETA_NODES = 8192
SPHERE_C_RANGE = (0.02, 200.0)
# The sphere's ray along its axis meets the axis at its paraxial focus: taken at this small angle (rad).
SPHERE_PARAXIAL_RAD = 1e-4


def sphere_reflection(beta: FloatArray, c: float) -> tuple[FloatArray, ...]:
    """The camera ray at ``beta`` (rad from the axis) reflected off a sphere of radius 1 whose apex is ``c``
    above the pinhole, in the ray's half-plane: the hit point ``x`` (from the axis) and ``z`` (above the apex)
    and the reflected unit direction ``dx, dz``; NaN beyond the grazing ray. The ray meets the sphere (centre
    ``1 + c`` above the pinhole) at ``t = (1 + c) cos(beta) - sqrt(1 - ((1 + c) sin(beta))^2)``; the normal
    is the radius there."""
    big = 1.0 + c
    sb, cb = np.sin(beta), np.cos(beta)
    with np.errstate(invalid="ignore"):
        t = big * cb - np.sqrt(1.0 - (big * sb) ** 2)
    x, z = t * sb, t * cb - c
    nx, nz = x, z - 1.0  # the unit normal: the hit point less the centre
    dn = sb * nx + cb * nz
    return x, z, sb - 2.0 * dn * nx, cb - 2.0 * dn * nz


def sphere_alpha(beta: FloatArray, c: float) -> FloatArray:
    """Angle (rad) from the pole (straight back at the lens) of the reflection of the camera ray at ``beta``
    (rad from the axis) off the sphere of :func:`sphere_reflection`; NaN beyond the grazing ray."""
    _, _, dx, dz = sphere_reflection(beta, c)
    return np.asarray(np.arctan2(dz, dx) + HALF_PI, dtype=np.float64)


def sphere_axis_height(beta: FloatArray, c: float) -> FloatArray:
    """Height (sphere radii, above the apex, along the axis away from the lens) where the reflection of the
    camera ray at ``beta`` (rad, > 0) off the sphere of :func:`sphere_reflection` meets the axis: the mirror's
    exact ray origin (:meth:`Sphere.axis_heights`)."""
    x, z, dx, dz = sphere_reflection(beta, c)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.asarray(z - x * dz / dx, dtype=np.float64)


@lru_cache(maxsize=64)
def sphere_branch(c: float) -> tuple[FloatArray, FloatArray]:
    """(alpha, beta) of a spherical mirror of ratio ``c`` (:func:`sphere_alpha`), each (k,), from the axis to
    where alpha stops growing (the grazing ray or a fold before it): the part of the mirror a camera sees."""
    grazing = math.asin(1.0 / (1.0 + c))
    beta = np.linspace(0.0, grazing * (1.0 - 1e-9), SPHERE_BETA_NODES)
    alpha = sphere_alpha(beta, c)
    stop = np.flatnonzero(~(np.diff(alpha) > 0))
    end = int(stop[0]) + 1 if stop.size else alpha.size
    return alpha[:end], beta[:end]


def sphere_beta(alpha: FloatArray, c: float) -> FloatArray:
    """The camera ray (rad from the axis) whose reflection leaves at ``alpha`` (rad), for ratio ``c``; NaN where
    the mirror reflects no ray there (everywhere where ``c`` is not > 0)."""
    alpha = np.asarray(alpha, dtype=np.float64)
    if not (math.isfinite(c) and c > 0):
        return np.full(alpha.shape, np.nan)
    table_alpha, table_beta = sphere_branch(float(c))
    inside = (alpha >= 0.0) & (alpha <= table_alpha[-1])
    return np.asarray(np.where(inside, np.interp(np.where(inside, alpha, 0.0), table_alpha, table_beta), np.nan))


def sphere_basis(alpha: FloatArray, c: float) -> FloatArray:
    """``tan(beta)`` of the camera ray that sees the reflection at ``alpha`` (rad), for ratio ``c``; NaN
    where the mirror reflects no ray there."""
    return np.asarray(np.tan(sphere_beta(alpha, c)), dtype=np.float64)


@dataclass(frozen=True)
class Sphere(RadialKind):
    """A pinhole on the axis of a spherical mirror, ``r = f tan(beta(alpha; c))`` (:func:`sphere_alpha`)."""

    auto_candidate: ClassVar[bool] = False
    exact_origins: ClassVar[bool] = True

    @property
    def parameters(self) -> tuple[str, ...]:
        return ("f", "c")

    def axis_heights(self, coefficients: tuple[float, ...], alpha: FloatArray) -> FloatArray:
        """Sphere radii above the apex (:func:`sphere_axis_height`); the ray along the axis at its paraxial
        limit (``SPHERE_PARAXIAL_RAD``)."""
        c = coefficients[1]
        return sphere_axis_height(np.maximum(sphere_beta(alpha, c), SPHERE_PARAXIAL_RAD), c)

    def evaluate(self, coefficients: tuple[float, ...], rho: FloatArray, axis: str) -> FloatArray:
        f, c = coefficients
        return np.asarray(f * sphere_basis(alpha_of_rho(rho, axis), float(c)), dtype=np.float64)

    def fit(self, rho: FloatArray, r: FloatArray, axis: str, weights: FloatArray | None) -> tuple[float, ...]:
        """(f, c) minimising the weighted radial residual; f is solved in closed form for each c, c profiled
        over ``SPHERE_C_RANGE`` on a log scale and refined."""
        from scipy import optimize  # here, not at the top: importing SciPy is slow

        alpha = alpha_of_rho(rho, axis)
        w = np.ones_like(r) if weights is None else np.asarray(weights, dtype=np.float64)
        wr = w * r

        def profile(log_c: float) -> tuple[float, float]:
            g = w * sphere_basis(alpha, math.exp(log_c))
            if not np.all(np.isfinite(g)) or g @ g <= 0:
                return math.inf, math.nan
            f = float(g @ wr / (g @ g))
            return float(np.sum((f * g - wr) ** 2)), f

        grid = np.linspace(math.log(SPHERE_C_RANGE[0]), math.log(SPHERE_C_RANGE[1]), 121)
        costs = np.array([profile(x)[0] for x in grid])
        if not np.any(np.isfinite(costs)):
            raise PanomapError("no spherical mirror reflects rays at these landmarks' angles")
        best = int(np.argmin(costs))
        lo, hi = grid[max(best - 1, 0)], grid[min(best + 1, len(grid) - 1)]
        result = optimize.minimize_scalar(
            lambda x: profile(x)[0], bounds=(lo, hi), method="bounded", options={"xatol": 1e-10}
        )
        log_c = float(result.x) if result.fun <= costs[best] else float(grid[best])
        return profile(log_c)[1], math.exp(log_c)


def with_centre_pair(rho: FloatArray, r: FloatArray, axis: str) -> tuple[FloatArray, FloatArray]:
    """The paper's (O_c, O_m) pair first, then the landmarks: ``r = 0`` at the pole the centre sees."""
    return np.concatenate([[axis_elevation(axis)], rho]), np.concatenate([[0.0], r])


def _registry(*kinds: RadialKind) -> dict[str, RadialKind]:
    registry: dict[str, RadialKind] = {}
    for kind in kinds:
        if kind.name in registry:
            raise AssertionError(f"radial model {kind.name!r} is registered twice")
        registry[kind.name] = kind
    return registry


# Every radial model, by name, in the order the command line lists them.
RADIAL_KINDS: dict[str, RadialKind] = _registry(
    PaperPolynomial("paper"),
    AxisPolynomial("odd1", powers=(1,)),
    Fisheye("fisheye"),
    AxisPolynomial("odd3", powers=(1, 3)),
    AxisPolynomial("odd5", powers=(1, 3, 5)),
    AxisPolynomial("poly2", selection_rank=2, powers=(1, 2)),
    AxisPolynomial("poly3", selection_rank=2, powers=(1, 2, 3)),
    Unified("unified", selection_rank=1),
    Sphere("sphere", selection_rank=3),
)
MODELS = tuple(RADIAL_KINDS)
# The kinds automatic selection of a single-viewpoint fit tries.
AUTO_KINDS = tuple(name for name in MODELS if RADIAL_KINDS[name].auto_candidate)
# The order in which automatic selection prefers models that tie: fewer parameters first.
AUTO_CANDIDATES = tuple(
    sorted(AUTO_KINDS, key=lambda name: (RADIAL_KINDS[name].parameter_count, RADIAL_KINDS[name].selection_rank))
)
# The same for an image that shows a cut-off disc (the camera's reflection: a mirror camera): the mirrors'
# own law first among kinds with as many parameters. A fisheye polynomial with two terms bends as a conic
# mirror's profile does over a few landmarks, and ties with it; beyond them it does not.
MIRROR_CANDIDATES = tuple(
    sorted(
        AUTO_KINDS,
        key=lambda name: (
            RADIAL_KINDS[name].parameter_count,
            not RADIAL_KINDS[name].mirror_law,
            RADIAL_KINDS[name].selection_rank,
        ),
    )
)


def radial_kind(name: str) -> RadialKind:
    """The registered kind called ``name``.

    Raises
    ------
    PanomapError
        If there is none.
    """
    kind = RADIAL_KINDS.get(name)
    if kind is None:
        raise PanomapError(f"unknown radial model {name!r} (known: {', '.join(MODELS)})")
    return kind
