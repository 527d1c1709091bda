"""How the camera is mounted: its tilt and its position, refined with the radial model (beyond the paper).

The paper takes the camera's axis as exactly vertical and its position O_m as
exact. A real mount is a degree or three off the vertical, and O_m is measured
with a tape. :func:`joint_fit` refines, with f_r, phi0 and (optionally) the
centre:

- the **tilt**, as the horizontal rotation vector ``w = (w_x, w_y)`` (rad) of
  :mod:`panomap.camera.orientation`: a landmark's ray in the camera's axes is
  ``R(w).T (P - O_m)``;
- the **position**, as a shift ``delta`` (world units) of O_m, with the tape
  measurement as a prior: each coordinate of ``delta`` adds a residual
  ``delta_k / camera_sigma``.

Residuals are whitened as in :mod:`panomap.calibrate.fit` (radial and
tangential, each with the pixel's and the world point's standard deviation).
:func:`held_out_errors` gives each landmark's error under a fit made without it
(or without its fold), the score by which :func:`panomap.calibrate.fit.fit_camera`
decides whether the landmarks support a tilt, a position shift, both or neither.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..camera.orientation import rotation_from_vector, to_camera
from ..camera.radial import RadialFunction
from ..errors import PanomapError
from ..geometry import FloatArray, azimuth_elevation, pixel_polar
from .report import CENTRE_AS_FOUND

IndexArray = np.ndarray


@dataclass(frozen=True)
class MountProblem:
    """What a joint fit of the mount works on; arrays over all n landmarks.

    Attributes
    ----------
    world : (n, 3) ndarray
        Landmark world points, world units.
    pixels : (n, 2) ndarray
        Their pixels, px.
    camera : (3,) ndarray
        O_m as given (the tape measurement), world units.
    kind : str
        The radial model kind.
    axis : {"down", "up"}
    s : {+1, -1}
    pixel_sigma : float
        px.
    world_sigma : float
        World units.
    camera_sigma : float
        Standard deviation of each coordinate of the given O_m, world units (the
        prior on ``delta``).
    rotation : (3, 3) ndarray or None
        A rotation given by the user (camera to world), applied before ``w``.
    centre_found : (u0, v0) or None
        The centre where the fit started (found at the rim), px, for the mounts
        that hold it there (``MountOptions.at_rim``).
    """

    world: FloatArray
    pixels: FloatArray
    camera: FloatArray
    kind: str
    axis: str
    s: int
    pixel_sigma: float
    world_sigma: float
    camera_sigma: float
    rotation: FloatArray | None = None
    centre_found: tuple[float, float] | None = None


@dataclass(frozen=True)
class MountOptions:
    """Which of the mount's unknowns a fit refines, besides f_r and phi0."""

    centre: bool = False
    tilt: bool = False
    position: bool = False
    at_rim: bool = False  # the centre held where it was found, among mounts that refine it

    @property
    def name(self) -> str:
        parts = [part for part, on in (("tilt", self.tilt), ("position", self.position)) if on]
        return (" + ".join(parts) or "level, position as given") + (CENTRE_AS_FOUND if self.at_rim else "")


@dataclass(frozen=True)
class MountSolution:
    """A joint fit's result.

    Attributes
    ----------
    radial : RadialFunction
    phi0 : float
        rad.
    centre : (u0, v0)
        px.
    w : (2,) ndarray
        The tilt's rotation vector (rad), zero when not refined.
    delta : (3,) ndarray
        The position's shift, world units, zero when not refined.
    covariance : (k, k) ndarray
        Covariance of the refined mount unknowns, in the order w (2, with
        ``tilt``), delta (3, with ``position``); empty when neither is refined.
    """

    radial: RadialFunction
    phi0: float
    centre: tuple[float, float]
    w: FloatArray
    delta: FloatArray
    covariance: FloatArray

    def rotation(self, problem: MountProblem) -> FloatArray | None:
        """R (3, 3), camera to world: the given rotation, then the refined tilt (None when level)."""
        tilt = rotation_from_vector([self.w[0], self.w[1], 0.0]) if np.any(self.w) else None
        if problem.rotation is None:
            return tilt
        return problem.rotation if tilt is None else problem.rotation @ tilt

    def camera(self, problem: MountProblem) -> FloatArray:
        """O_m, refined (world units)."""
        return np.asarray(problem.camera + self.delta, dtype=np.float64)


def camera_rays(problem: MountProblem, w: FloatArray, delta: FloatArray) -> FloatArray:
    """Landmark rays (n, 3) in the camera's axes, for tilt ``w`` (2,) and position shift ``delta`` (3,)."""
    d = problem.world - (problem.camera + delta)
    if problem.rotation is not None:
        d = to_camera(d, problem.rotation)
    if np.any(w):
        d = to_camera(d, rotation_from_vector([w[0], w[1], 0.0]))
    return np.asarray(d)


def _sigmas(problem: MountProblem, radial: RadialFunction, d: FloatArray, rho: FloatArray) -> tuple[FloatArray, ...]:
    """Radial sigma (px) and the world point's azimuth sigma (rad) of each landmark."""
    distance = np.linalg.norm(d, axis=1)
    horizontal = np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-12)
    slope = np.nan_to_num(radial.slope(rho))
    radial_sigma = np.sqrt(problem.pixel_sigma**2 + (slope * problem.world_sigma / distance) ** 2)
    return radial_sigma, problem.world_sigma / horizontal


def residual_parts(
    problem: MountProblem, solution: MountSolution, index: IndexArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Radial and tangential errors (px) and their sigmas (px) of the landmarks at ``index`` under ``solution``."""
    d = camera_rays(problem, solution.w, solution.delta)[index]
    theta, rho = azimuth_elevation(d)
    r_obs, phi_obs = pixel_polar(problem.pixels[index], solution.centre)
    radial_sigma, sigma_theta = _sigmas(problem, solution.radial, d, rho)
    angle = np.angle(np.exp(1j * (problem.s * theta + solution.phi0 - phi_obs)))
    tangential_sigma = np.sqrt(problem.pixel_sigma**2 + (r_obs * sigma_theta) ** 2)
    return solution.radial(rho) - r_obs, r_obs * angle, radial_sigma, tangential_sigma


def joint_fit(problem: MountProblem, start: MountSolution, subset: FloatArray, options: MountOptions) -> MountSolution:
    """Nonlinear least squares of f_r, phi0 and what ``options`` names, on the landmarks in ``subset`` (bool, n).

    Sigmas are those of ``start`` (fixed while the fit runs, as in the
    effective-variance method). Raises PanomapError when it does not converge.
    """
    from scipy import optimize  # here, not at the top: importing SciPy is slow

    index = np.flatnonzero(subset)
    count = len(start.radial.coefficients)
    d0 = camera_rays(problem, start.w, start.delta)[index]
    _, rho0 = azimuth_elevation(d0)
    radial_sigma, _ = _sigmas(problem, start.radial, d0, rho0)
    world = problem.world[index]
    pixels = problem.pixels[index]
    layout = [("coefficients", count), ("phi0", 1)]
    layout += [("centre", 2)] if options.centre else []
    layout += [("tilt", 2)] if options.tilt else []
    layout += [("position", 3)] if options.position else []

    def unpack(p: FloatArray) -> MountSolution:
        at = count + 1
        centre = start.centre
        if options.centre:
            centre, at = (float(p[at]), float(p[at + 1])), at + 2
        w = start.w
        if options.tilt:
            w, at = p[at : at + 2], at + 2
        delta = start.delta
        if options.position:
            delta = p[at : at + 3]
        radial = RadialFunction(start.radial.kind, tuple(float(c) for c in p[:count]), start.radial.axis)
        return MountSolution(radial, float(p[count]), centre, np.asarray(w), np.asarray(delta), np.empty((0, 0)))

    def residuals(p: FloatArray) -> FloatArray:
        solution = unpack(p)
        d = world - (problem.camera + solution.delta)
        if problem.rotation is not None:
            d = to_camera(d, problem.rotation)
        if options.tilt or np.any(solution.w):
            d = to_camera(d, rotation_from_vector([solution.w[0], solution.w[1], 0.0]))
        theta, rho = azimuth_elevation(d)
        horizontal = np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-12)
        r_obs, phi_obs = pixel_polar(pixels, solution.centre)
        radial_error = (solution.radial(rho) - r_obs) / radial_sigma
        angle = np.angle(np.exp(1j * (problem.s * theta + solution.phi0 - phi_obs)))
        sigma_theta = problem.world_sigma / horizontal
        tangential_error = r_obs * angle / np.sqrt(problem.pixel_sigma**2 + (r_obs * sigma_theta) ** 2)
        parts = [radial_error, tangential_error]
        if options.position:
            parts.append(solution.delta / problem.camera_sigma)
        return np.nan_to_num(np.concatenate(parts), nan=1e6, posinf=1e6, neginf=-1e6)

    start_vector = [*start.radial.coefficients, start.phi0]
    start_vector += list(start.centre) if options.centre else []
    start_vector += list(start.w) if options.tilt else []
    start_vector += list(start.delta) if options.position else []
    x0 = np.asarray(start_vector, dtype=np.float64)
    result = optimize.least_squares(residuals, x0, x_scale="jac", max_nfev=100 * x0.size)
    if not result.success:
        raise PanomapError(f"the joint refinement of the mount did not converge ({result.message})")
    solution = unpack(result.x)
    mount = count + 1 + (2 if options.centre else 0)
    covariance = np.empty((0, 0))
    if options.tilt or options.position:
        jacobian = np.asarray(result.jac)
        dof = max(jacobian.shape[0] - jacobian.shape[1], 1)
        scale = max(float(result.fun @ result.fun) / dof, 1.0)
        full = np.linalg.pinv(jacobian.T @ jacobian) * scale
        covariance = full[mount:, mount:]
    return MountSolution(
        solution.radial,
        float(np.angle(np.exp(1j * solution.phi0))),
        solution.centre,
        np.array(solution.w, dtype=np.float64),
        np.array(solution.delta, dtype=np.float64),
        covariance,
    )


def held_out_errors(
    problem: MountProblem,
    solution: MountSolution,
    subset: FloatArray,
    folds: list[IndexArray],
    options: MountOptions,
) -> tuple[FloatArray, FloatArray]:
    """Whitened and pixel errors of each landmark of ``subset`` under a joint fit made without its fold.

    ``folds`` are positions into ``np.flatnonzero(subset)``; each fit starts
    from ``solution`` (the fit on all of them). A fold whose fit fails counts
    as infinitely wrong.
    """
    members = np.flatnonzero(subset)
    whitened = np.full(members.size, np.inf)
    pixels = np.full(members.size, np.inf)
    for positions in folds:
        others = subset.copy()
        others[members[positions]] = False
        try:
            fold = joint_fit(problem, solution, others, options)
        except PanomapError:
            continue
        radial_error, tangential_error, radial_sigma, tangential_sigma = residual_parts(
            problem, fold, members[positions]
        )
        whitened[positions] = np.hypot(radial_error / radial_sigma, tangential_error / tangential_sigma)
        pixels[positions] = np.hypot(radial_error, tangential_error)
    bad = ~np.isfinite(whitened)
    return np.where(bad, np.inf, whitened), np.where(bad | ~np.isfinite(pixels), np.inf, pixels)


def tilt_standard_errors(w: FloatArray, covariance: FloatArray) -> tuple[float, float]:
    """Standard errors (rad) of the tilt |w| and of the azimuth it leans toward, from w's covariance (2, 2).

    The azimuth's is infinite for a level camera (it has no direction).
    """
    norm = float(np.hypot(w[0], w[1]))
    if norm < 1e-12:
        return math.sqrt(max(float(np.trace(covariance)) / 2, 0.0)), math.inf
    along = np.array([w[0], w[1]]) / norm
    across = np.array([-w[1], w[0]]) / norm**2
    return (
        math.sqrt(max(float(along @ covariance @ along), 0.0)),
        math.sqrt(max(float(across @ covariance @ across), 0.0)),
    )
