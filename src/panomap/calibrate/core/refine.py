"""The one least-squares refinement of the camera: f_r, phi0 and, optionally, centre, tilt and position.

Convention: world Z up; a landmark's ray in the camera's axes is ``R(w).T R_given.T (P - (O_m + delta))``
(:mod:`panomap.camera.orientation`); pixel radius r and image angle phi about the centre (u0, v0), px and
rad; ``r = f_r(rho)``, ``phi = s*theta + phi0``.

The paper takes the centre as found, the camera's axis as exactly vertical and its position O_m as
exact. :func:`refine` refines, with f_r's coefficients and phi0, what :class:`MountOptions` names:

- the **centre** (u0, v0), px;
- the **tilt**, as the horizontal rotation vector ``w = (w_x, w_y)`` (rad) of
  :mod:`panomap.camera.orientation`;
- the **position**, as a shift ``delta`` (world units) of O_m, with the tape measurement as a prior:
  each coordinate of ``delta`` adds a residual ``delta_k / camera_sigma``.

Residual blocks
---------------
The sum of squares :func:`refine` minimises is made of **residual blocks**, each an object with the
:class:`ResidualBlock` interface:

- ``unknowns`` (int): how many unknowns of its own the block adds to the refinement (0 for none);
- ``start()`` -> ``(unknowns,)`` float array: their starting values;
- ``residuals(camera, own)`` -> ``(m,)`` float array: the block's residuals, already whitened (each in
  standard deviations, so that the sum of squares is a chi-square), for the camera ``camera`` (a
  :class:`MountSolution` holding the current f_r, phi0, centre, tilt ``w`` and position shift ``delta``;
  its covariance is empty while the refinement runs) and ``own`` (``(unknowns,)``, the block's own
  unknowns at their current values). ``m`` must not change between calls. A NaN or infinite residual is
  replaced by 1e6 (a point the camera cannot place counts as very wrong, never as a crash).

The unknowns' vector is laid out as f_r's coefficients, phi0, then (with the options) centre (2), tilt
(2) and position (3), then each block's own unknowns in the order the blocks are given. The landmarks
(:class:`LandmarkBlock`: a radial and a tangential residual each, no unknowns of their own) and, when
the position is refined, the tape's prior (:class:`PositionPrior`, 3 residuals) are always the first
blocks; :func:`refine`'s ``blocks`` come after them. A block of straight lines, for example, adds two
unknowns per line (the unit normal of the line's plane through the viewpoint, as two angles), starts
them from the lines' first fit, and returns one whitened residual per edge point (its distance, px,
from the line's curve as the camera images that plane, over its pixel sigma).

The result (:class:`Refinement`) holds the refined camera, each block's own unknowns, and the
covariance of all unknowns (``Refinement.covariance``), from the Jacobian at the solution, scaled by
the reduced chi-square where it exceeds 1.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ...camera.orientation import rotation_from_vector, to_camera
from ...camera.radial import RadialFunction
from ...errors import PanomapError
from ...geometry import FloatArray, azimuth_elevation, pixel_polar
from .noise import Residuals, landmark_residuals, radial_sigma, world_sigmas
from .report import CENTRE_AS_FOUND

IndexArray = np.ndarray


@dataclass(frozen=True)
class MountProblem:
    """What a refinement works on; arrays over all n landmarks.

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
    """Which of the camera's unknowns a refinement refines, besides f_r and phi0."""

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
    """A refined camera.

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


def rays_of(problem: MountProblem, world: FloatArray, w: FloatArray, delta: FloatArray) -> FloatArray:
    """Rays (m, 3) to world points ``world`` (m, 3) in the camera's axes, for tilt ``w`` (2,) and shift ``delta``."""
    d = world - (problem.camera + delta)
    if problem.rotation is not None:
        d = to_camera(d, problem.rotation)
    if np.any(w):
        d = to_camera(d, rotation_from_vector([w[0], w[1], 0.0]))
    return np.asarray(d)


def camera_rays(problem: MountProblem, w: FloatArray, delta: FloatArray) -> FloatArray:
    """Landmark rays (n, 3) in the camera's axes, for tilt ``w`` (2,) and position shift ``delta`` (3,)."""
    return rays_of(problem, problem.world, w, delta)


def residual_parts(problem: MountProblem, solution: MountSolution, index: IndexArray) -> Residuals:
    """The noise model's residuals (:class:`panomap.calibrate.core.noise.Residuals`) of the landmarks at ``index``
    under ``solution``, the radial sigma that of its own f_r."""
    d = camera_rays(problem, solution.w, solution.delta)[index]
    theta, rho = azimuth_elevation(d)
    r_obs, phi_obs = pixel_polar(problem.pixels[index], solution.centre)
    sigma_rho, sigma_theta = world_sigmas(d, problem.world_sigma)
    return landmark_residuals(
        solution.radial,
        solution.phi0,
        problem.s,
        theta,
        rho,
        r_obs,
        phi_obs,
        radial_sigma(solution.radial, rho, sigma_rho, problem.pixel_sigma),
        sigma_theta,
        problem.pixel_sigma,
    )


class ResidualBlock(Protocol):
    """A part of the refinement's sum of squares (see the module's docstring)."""

    @property
    def unknowns(self) -> int: ...

    def start(self) -> FloatArray: ...

    def residuals(self, camera: MountSolution, own: FloatArray) -> FloatArray: ...


class LandmarkBlock:
    """The landmarks at ``index``: a whitened radial and tangential residual each (2m); no unknowns.

    The radial sigmas are those of ``start`` (held fixed while the refinement runs, as in the
    effective-variance method); the tangential ones follow the rays. Where the rays do not move
    (``rays_move`` False: neither tilt nor position refined) their angles are found once.
    """

    unknowns = 0

    def __init__(self, problem: MountProblem, start: MountSolution, index: IndexArray, rays_move: bool) -> None:
        self.problem = problem
        self.world = problem.world[index]
        self.pixels = problem.pixels[index]
        d0 = camera_rays(problem, start.w, start.delta)[index]
        theta0, rho0 = azimuth_elevation(d0)
        sigma_rho, sigma_theta0 = world_sigmas(d0, problem.world_sigma)
        self.radial_sigma = radial_sigma(start.radial, rho0, sigma_rho, problem.pixel_sigma)
        self.fixed = None if rays_move else (theta0, rho0, sigma_theta0)

    def start(self) -> FloatArray:
        return np.empty(0)

    def residuals(self, camera: MountSolution, own: FloatArray) -> FloatArray:
        if self.fixed is None:
            d = rays_of(self.problem, self.world, camera.w, camera.delta)
            theta, rho = azimuth_elevation(d)
            _, sigma_theta = world_sigmas(d, self.problem.world_sigma)
        else:
            theta, rho, sigma_theta = self.fixed
        r_obs, phi_obs = pixel_polar(self.pixels, camera.centre)
        parts = landmark_residuals(
            camera.radial,
            camera.phi0,
            self.problem.s,
            theta,
            rho,
            r_obs,
            phi_obs,
            self.radial_sigma,
            sigma_theta,
            self.problem.pixel_sigma,
        )
        radial_error, tangential_error = parts.whitened
        return np.concatenate([radial_error, tangential_error])


class PositionPrior:
    """The tape's measurement of O_m: ``delta_k / camera_sigma`` for each coordinate (3); no unknowns."""

    unknowns = 0

    def __init__(self, camera_sigma: float) -> None:
        self.camera_sigma = camera_sigma

    def start(self) -> FloatArray:
        return np.empty(0)

    def residuals(self, camera: MountSolution, own: FloatArray) -> FloatArray:
        return np.asarray(camera.delta / self.camera_sigma)


@dataclass(frozen=True)
class Refinement:
    """What :func:`refine` found.

    Attributes
    ----------
    solution : MountSolution
        The refined camera; its covariance is that of the mount's unknowns (w, delta), as
        :class:`MountSolution` documents.
    own : tuple of ndarray
        Each added block's own unknowns at the solution, in the order the blocks were given.
    jacobian : (m, k) ndarray
        The whitened residuals' Jacobian at the solution, over all k unknowns.
    residuals : (m,) ndarray
        The whitened residuals at the solution.
    """

    solution: MountSolution
    own: tuple[FloatArray, ...]
    jacobian: FloatArray
    residuals: FloatArray

    @functools.cached_property
    def covariance(self) -> FloatArray:
        """(k, k): the covariance of all k unknowns, laid out as the module's docstring says: the inverse of
        J^T J, scaled by the reduced chi-square where it exceeds 1."""
        return _covariance(self.jacobian, self.residuals)


def refine(
    problem: MountProblem,
    start: MountSolution,
    subset: FloatArray,
    options: MountOptions,
    blocks: tuple[ResidualBlock, ...] = (),
    evaluations_per_unknown: int = 100,
    what: str = "the joint refinement of the mount",
) -> Refinement:
    """Nonlinear least squares of f_r, phi0 and what ``options`` names, on the landmarks in ``subset`` (bool, n),
    with the residual ``blocks`` added (see the module's docstring).

    Raises PanomapError (naming ``what``) when it does not converge within ``evaluations_per_unknown``
    residual evaluations per unknown.
    """
    from scipy import optimize  # here, not at the top: importing SciPy is slow

    count = len(start.radial.coefficients)
    every: list[ResidualBlock] = [
        LandmarkBlock(problem, start, np.flatnonzero(subset), rays_move=options.tilt or options.position)
    ]
    if options.position:
        every.append(PositionPrior(problem.camera_sigma))
    every += blocks
    mount_size = 2 * options.centre + 2 * options.tilt + 3 * options.position
    own_at = count + 1 + mount_size

    def unpack(p: FloatArray) -> tuple[MountSolution, list[FloatArray]]:
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
        camera = MountSolution(radial, float(p[count]), centre, np.asarray(w), np.asarray(delta), np.empty((0, 0)))
        own, at = [], own_at
        for block in every:
            own.append(p[at : at + block.unknowns])
            at += block.unknowns
        return camera, own

    def residuals(p: FloatArray) -> FloatArray:
        camera, own = unpack(p)
        parts = [block.residuals(camera, values) for block, values in zip(every, own, strict=True)]
        return np.nan_to_num(np.concatenate(parts), nan=1e6, posinf=1e6, neginf=-1e6)

    start_vector = [*start.radial.coefficients, start.phi0]
    start_vector += list(start.centre) if options.centre else []
    start_vector += list(start.w) if options.tilt else []
    start_vector += list(start.delta) if options.position else []
    x0 = np.concatenate([np.asarray(start_vector, dtype=np.float64), *(block.start() for block in every)])
    result = optimize.least_squares(residuals, x0, x_scale="jac", max_nfev=evaluations_per_unknown * x0.size)
    if not result.success:
        raise PanomapError(f"{what} did not converge ({result.message})")
    camera, own = unpack(result.x)
    jacobian = np.asarray(result.jac)
    mount = count + 1 + 2 * options.centre
    solution = MountSolution(
        camera.radial,
        float(np.angle(np.exp(1j * camera.phi0))),
        camera.centre,
        np.array(camera.w, dtype=np.float64),
        np.array(camera.delta, dtype=np.float64),
        _covariance(jacobian, result.fun)[mount:own_at, mount:own_at]
        if options.tilt or options.position
        else np.empty((0, 0)),
    )
    added = tuple(np.array(values) for values in own[len(every) - len(blocks) :])
    return Refinement(solution, added, jacobian, np.asarray(result.fun))


def _covariance(jacobian: FloatArray, residuals: FloatArray) -> FloatArray:
    """The unknowns' covariance (k, k) from the whitened residuals' Jacobian (m, k) and residuals (m,)."""
    dof = max(jacobian.shape[0] - jacobian.shape[1], 1)
    scale = max(float(residuals @ residuals) / dof, 1.0)
    return np.asarray(np.linalg.pinv(jacobian.T @ jacobian) * scale)


def joint_fit(problem: MountProblem, start: MountSolution, subset: FloatArray, options: MountOptions) -> MountSolution:
    """The camera :func:`refine` finds from ``start`` on the landmarks in ``subset`` (bool, n), no blocks added."""
    return refine(problem, start, subset, options).solution
