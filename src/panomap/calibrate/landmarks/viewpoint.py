"""A camera without a single viewpoint, learned from landmarks (beyond the paper).

The paper's table holds one pixel per direction, as if every ray left the mirror centre O_m. A mirror
without a single viewpoint (a sphere, a cone) sends each elevation's ray from its own point on the axis
(:mod:`panomap.camera.viewpoint`): a table made for far landmarks then misplaces near points, by pixels
at a metre. Landmarks at several distances show it: the elevation a landmark is seen at depends on its
distance as well as its direction.

:func:`choose_viewpoint` fits, after the landmark fit (:func:`panomap.calibrate.landmarks.fit.fit_camera`), the
radial function together with the ray origins of a mirror of revolution, ``z = k_1 (h(rho) - h_mean)`` with
h the caustic that f_r itself implies (:func:`panomap.camera.viewpoint.caustic_shape`; one unknown, the
mirror's size, with a prior; O_m the axis point nearest the rays), to the inlier landmarks' radii; the azimuth does
not depend on z, so the centre, the handedness, phi0, the tilt and the position stay as fitted. Each
residual is whitened by the noise model (:mod:`.noise`). The camera is taken as non-central only where
leave-one-out cross-validation says so: its held-out whitened RMS is at most ``VIEWPOINT_GAIN`` times the
single viewpoint's (or always, asked for). A single-viewpoint camera keeps its fit unchanged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...camera.orientation import to_camera
from ...camera.radial import RadialFunction, fit_radial
from ...camera.radial_models import MODELS, radial_kind, rho_of_alpha
from ...camera.viewpoint import Viewpoint, caustic_viewpoint
from ...errors import PanomapError
from ...geometry import HALF_PI, FloatArray, pixel_polar
from ..core import selection
from ..core.noise import radial_sigma, world_sigmas
from ..core.selection import CV_FOLDS

# scipy is imported where it is used: its import would cost every command (a video's start-up too) 0.4 s.

# What ``fit_camera(viewpoint=...)`` takes: choose by cross-validation, keep O_m, or fit the caustic.
VIEWPOINT_MODES = ("auto", "single", "caustic")
# A non-central camera is kept where its held-out RMS is at most this fraction of the single viewpoint's: at 0.9,
# random landmark layouts of single-viewpoint mirrors chose it by chance (bench_fit: parabolic 1.89 -> 3.14 px).
VIEWPOINT_GAIN = 0.75
# The spherical mirror's law (camera/radial_models), which knows its ray origins and is tried with them whatever
# kind the single viewpoint chose; and the fraction of the single viewpoint's held-out RMS such a law's must reach
# to be chosen: nearer 1 than VIEWPOINT_GAIN, as the law fits no single-viewpoint mirror (held out on simulated
# parabolic and hyperbolic mirrors, its RMS was 1.4-7 times the single viewpoint's), but not 1: the caustic's size
# is loosely pinned, and where the two tie, the single viewpoint is as often the better (bench/bench_noncentral.py).
SPHERE_KIND = "sphere"
SPHERE_GAIN = 0.9
# Fewer inliers than the unknowns plus this leave too little to hold out: the camera stays single-viewpoint.
SPARE_LANDMARKS = 3
# The viewpoint's nodes reach this far (rad) beyond the landmarks' elevations, within alpha 1..179 deg.
NODE_MARGIN_RAD = math.radians(20.0)
NODE_LIMIT_RAD = math.radians(1.0)
# The radial kinds the caustic is tried with, beside the single viewpoint's own: those of at most this many
# parameters (a stiff law cannot bend to stand in for the ray origins).
CAUSTIC_KIND_PARAMETERS = 2
# The prior of the mirror's size: the spread of its ray origins over the landmarks' elevations has a standard
# deviation of this fraction of the landmarks' median distance (a mirror is small beside the room it sees). A
# dozen landmarks with a centimetre of error pin the spread loosely: without the prior, the fitted spread of a
# simulated sphere's was 0.4-3.6 times the true one, and 1 m views 12 px off (bench/bench_noncentral.py).
SPREAD_PRIOR_FRACTION = 0.02
# The starts of the caustic's size: its spread over the landmarks' elevations as a fraction of their distance.
START_SPREADS = (0.0, -0.04, -0.02, -0.01, -0.005, 0.005, 0.01, 0.02, 0.04)


@dataclass(frozen=True)
class SphericalMirror:
    """A spherical mirror of known radius (``fit_camera(viewpoint=SphericalMirror(r))``): its law
    (``sphere``) and its exact ray origins, whose size the radius gives, where a dozen landmarks pin it
    loosely (within about its own size, at room distances: bench/bench_noncentral.py).

    Attributes
    ----------
    radius : float
        The sphere's radius, in the landmarks' world units (> 0).
    """

    radius: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.radius) and self.radius > 0):
            raise PanomapError(f"the spherical mirror's radius must be finite and > 0, not {self.radius!r}")


@dataclass(frozen=True)
class LandmarkRays:
    """The inlier landmarks in the camera's axes, what a viewpoint fit needs, each (n,).

    Attributes
    ----------
    horizontal, height : (n,) ndarray
        Distance from the camera's axis and height above O_m along it (world units).
    r : (n,) ndarray
        Pixel radius about the centre (px).
    sigma : (n,) ndarray
        Standard deviation of each radial residual (px), from the noise model (held fixed).
    reference_rad : (low, high) or None
        Camera elevations (rad) whose rays O_m is the axis point nearest (the annulus'); the landmarks' own
        where None.
    """

    horizontal: FloatArray
    height: FloatArray
    r: FloatArray
    sigma: FloatArray
    reference_rad: tuple[float, float] | None = None

    def subset(self, keep: Any) -> LandmarkRays:
        return LandmarkRays(
            self.horizontal[keep], self.height[keep], self.r[keep], self.sigma[keep], self.reference_rad
        )


@dataclass(frozen=True)
class ViewpointFit:
    """The radial function and the ray origins fitted together."""

    radial: RadialFunction
    viewpoint: Viewpoint | None


@dataclass(frozen=True)
class ViewpointChoice:
    """What :func:`choose_viewpoint` chose.

    Attributes
    ----------
    fit : ViewpointFit or None
        The non-central camera, where cross-validation chose it; None keeps the single viewpoint.
    held_out : dict of str to float
        Leave-one-out whitened RMS of the landmarks' radii of each candidate: ``"single viewpoint"`` and
        ``"mirror caustic (KIND)"`` for each radial kind tried and held out in every fold.
    """

    fit: ViewpointFit | None
    held_out: dict[str, float]


def landmark_rays(
    world: FloatArray,
    pixels: FloatArray,
    camera: tuple[float, float, float],
    rotation: Any,
    centre: tuple[float, float],
    radial: RadialFunction,
    pixel_sigma: float,
    world_sigma: float,
    reference_rad: tuple[float, float] | None = None,
) -> LandmarkRays:
    """Landmarks (world (n, 3), pixels (n, 2)) as :class:`LandmarkRays` of a camera at ``camera`` turned by
    ``rotation`` (camera to world, or None), centred at ``centre``; sigmas from the noise model with the
    slope of ``radial``; ``reference_rad``, the camera elevations (rad) whose rays O_m is the axis point nearest
    (:func:`annulus_elevations`; the landmarks' own where None)."""
    d = to_camera(np.asarray(world, dtype=np.float64) - np.asarray(camera), rotation)
    horizontal = np.hypot(d[:, 0], d[:, 1])
    r, _ = pixel_polar(pixels, centre)
    sigma_rho, _ = world_sigmas(d, world_sigma)
    sigma = radial_sigma(radial, np.arctan2(d[:, 2], horizontal), sigma_rho, pixel_sigma)
    return LandmarkRays(horizontal, d[:, 2], r, sigma, reference_rad)


def annulus_elevations(radial: RadialFunction, annulus: tuple[float, float] | None) -> tuple[float, float] | None:
    """The camera elevations (rad) whose radius under ``radial`` is within ``annulus`` (cut-off and outer
    radius, px), on f_r's branch from the pole the image centre sees: the range over which O_m is the mean ray
    origin; None where unknown or empty."""
    if annulus is None:
        return None
    alpha = np.linspace(NODE_LIMIT_RAD, np.pi - NODE_LIMIT_RAD, 2001)
    rho = rho_of_alpha(alpha, radial.axis)
    with np.errstate(invalid="ignore"):
        r = np.abs(radial(rho))
    reached = np.flatnonzero(r >= annulus[0])
    if reached.size == 0:
        return None
    first = int(reached[0])
    beyond = np.flatnonzero(~(r[first:] <= annulus[1]))
    last = first + (int(beyond[0]) if beyond.size else r.size - first) - 1
    if last <= first:
        return None
    ends = (float(rho[first]), float(rho[last]))
    return (min(ends), max(ends))


def node_range(rays: LandmarkRays) -> tuple[float, float]:
    """Camera elevations (rad) a fitted viewpoint's nodes span: the landmarks' and ``NODE_MARGIN_RAD`` beyond,
    within alpha ``NODE_LIMIT_RAD``..180 deg less that (the caustic is not defined at the poles)."""
    rho = np.arctan2(rays.height, rays.horizontal)
    low, high = float(np.min(rho)) - NODE_MARGIN_RAD, float(np.max(rho)) + NODE_MARGIN_RAD
    bottom, top = -HALF_PI + NODE_LIMIT_RAD, HALF_PI - NODE_LIMIT_RAD
    return max(low, bottom), min(high, top)


def fit_viewpoint(
    rays: LandmarkRays,
    start: RadialFunction,
    caustic: bool,
    shape_from: RadialFunction | None = None,
    size: float | None = None,
) -> ViewpointFit:
    """f_r and, with ``caustic``, the mirror's ray origins, by least squares of the whitened radial residuals
    from ``start`` and z = 0; without, f_r alone about O_m. ``size`` holds k_1 (no prior then): the radius
    of a known sphere, signed as its origins run along the camera's axis.

    The ray origins are ``z = k_1 (h - h_mean)``: h the caustic of ``shape_from`` (default ``start``;
    :func:`caustic_viewpoint`), held while f_r moves (the ``sphere`` law's follows it), and h_mean the axis
    point nearest the rays of the reference elevations (``rays.reference_rad``, each weighted by its image
    area), so that O_m is that point, as the position given for a mirror camera (its mirror's centre) means.
    Unless ``size`` holds it, the mirror's size k_1 has a prior: the origins' spread over the reference
    elevations has a standard deviation of ``SPREAD_PRIOR_FRACTION`` of the landmarks' distance.

    Raises
    ------
    PanomapError
        If the least squares does not end at a finite camera.
    """
    spec = start.spec
    count = len(start.coefficients)
    straight = np.arctan2(rays.height, rays.horizontal)
    x0 = np.asarray(start.coefficients, dtype=np.float64)

    def radial_of(x: FloatArray) -> RadialFunction:
        return RadialFunction(start.kind, tuple(float(c) for c in x[:count]), start.axis)

    def whitened(x: FloatArray, rho: FloatArray) -> FloatArray:
        predicted = spec.evaluate(tuple(float(c) for c in x[:count]), rho, start.axis)
        return np.nan_to_num((predicted - rays.r) / rays.sigma, nan=1e6, posinf=1e6, neginf=-1e6)

    if not caustic:
        from scipy.optimize import least_squares

        solution = least_squares(lambda x: whitened(x, straight), x0, x_scale="jac", max_nfev=100 * x0.size)
        try:
            return ViewpointFit(radial_of(solution.x), None)
        except PanomapError as exc:
            raise PanomapError(f"the viewpoint fit failed ({exc.detail})") from None

    landmark_span = (float(np.min(straight)), float(np.max(straight)))
    reference = landmark_span if rays.reference_rad is None else rays.reference_rad
    nodes = node_range(rays)
    distance = float(np.median(np.hypot(rays.horizontal, rays.height)))
    spread_sigma = SPREAD_PRIOR_FRACTION * distance

    def caustic_of(mirror: RadialFunction) -> tuple[Viewpoint, FloatArray, float, float]:
        """The caustic's unit shape at its nodes, h (nodes,), the axis point nearest its rays over the
        reference (O_m), and its spread over the reference."""
        shape = caustic_viewpoint(mirror, 0.0, 1.0, nodes)
        rho_nodes = np.asarray(shape.elevations_rad)
        inside = (rho_nodes >= reference[0]) & (rho_nodes <= reference[1])
        # O_m: the axis point nearest the rays in least squares, each ray weighted by the image area it covers
        # (r dr); an axis point dz from a ray's origin is dz cos(rho) from the ray.
        weight = np.abs(mirror(rho_nodes) * mirror.slope(rho_nodes) * np.cos(rho_nodes) ** 2)[inside]
        h = np.asarray(shape.offsets)
        total = float(np.sum(weight))
        mean = float(np.sum(weight * h[inside]) / total) if total > 0 else float(np.mean(h[inside]))
        return shape, h, mean, float(np.ptp(h[inside])) if np.any(inside) else float(np.ptp(h))

    # The caustic's shape h from the starting f_r, held: a radial kind that bends near the rim would otherwise
    # trade its shape against the caustic's size (2-3 times the true spread, on simulated spheres). A kind that
    # knows its ray origins (the spherical mirror's law) is the mirror itself: its shape follows its coefficients.
    held = None if spec.exact_origins else caustic_of(start if shape_from is None else shape_from)

    def camera_and_spread(x: FloatArray) -> tuple[ViewpointFit, float]:
        shape, h, mean, unit_spread = caustic_of(radial_of(x)) if held is None else held
        k = float(x[count]) if size is None else size
        offsets = k * (h - mean)
        fitted = ViewpointFit(radial_of(x), Viewpoint(shape.elevations_rad, tuple(offsets.tolist())))
        return fitted, k * unit_spread

    def camera(x: FloatArray) -> ViewpointFit:
        return camera_and_spread(x)[0]

    def residuals(x: FloatArray) -> FloatArray:
        try:
            fitted, spread = camera_and_spread(x)
        except PanomapError:
            return np.full(rays.r.size + (size is None), 1e6)
        assert fitted.viewpoint is not None
        rho = fitted.viewpoint.elevation_of_point(rays.horizontal, rays.height)
        return np.append(whitened(x, rho), spread / spread_sigma) if size is None else whitened(x, rho)

    if size is not None:
        from scipy.optimize import least_squares

        solution = least_squares(residuals, x0, x_scale="jac", max_nfev=100 * x0.size)
        try:
            return camera(solution.x)
        except PanomapError as exc:
            raise PanomapError(f"the viewpoint fit failed ({exc.detail})") from None

    # The ray origins' spread is weakly pinned by a dozen landmarks: the least squares starts from the best of a
    # profile over spreads of 0 to 4% of the landmarks' distance, each way (or it can stop short).
    unit = camera(np.append(x0, 1.0)).viewpoint
    assert unit is not None
    spread = max(unit.excursion(*landmark_span), 1e-12)
    starts = [np.append(x0, f * distance / spread) for f in START_SPREADS]
    start_x = min(starts, key=lambda x: float(np.sum(residuals(x) ** 2)))
    from scipy.optimize import least_squares

    solution = least_squares(residuals, start_x, x_scale="jac", max_nfev=100 * start_x.size)
    try:
        return camera(solution.x)
    except PanomapError as exc:
        raise PanomapError(f"the viewpoint fit failed ({exc.detail})") from None


def held_out_rms(
    rays: LandmarkRays,
    start: RadialFunction,
    caustic: bool,
    shape_from: RadialFunction | None = None,
    size: float | None = None,
) -> float:
    """Held-out RMS of the whitened radial residuals of :func:`fit_viewpoint` (inf where a fold fails): exact
    leave-one-out up to ``EXACT_LOO_MAX`` landmarks, else ``CV_FOLDS`` folds dealt in elevation order, as the
    radial model's choice holds out (:mod:`..core.selection`)."""
    n = rays.r.size
    if n <= selection.EXACT_LOO_MAX:
        folds = [np.array([k]) for k in range(n)]
    else:
        order = np.argsort(np.arctan2(rays.height, rays.horizontal), kind="stable")
        folds = [order[fold::CV_FOLDS] for fold in range(CV_FOLDS)]
    errors = []
    for fold in folds:
        keep = np.ones(n, dtype=bool)
        keep[fold] = False
        try:
            fitted = fit_viewpoint(rays.subset(keep), start, caustic, shape_from, size)
        except PanomapError:
            return math.inf
        one = rays.subset(~keep)
        rho = (
            np.arctan2(one.height, one.horizontal)
            if fitted.viewpoint is None
            else fitted.viewpoint.elevation_of_point(one.horizontal, one.height)
        )
        errors.append((fitted.radial(rho) - one.r) / one.sigma)
    values = np.concatenate(errors)
    return float(np.sqrt(np.mean(values**2))) if np.all(np.isfinite(values)) else math.inf


SINGLE = "single viewpoint"
CAUSTIC = "mirror caustic"


def check_viewpoint(model: str, azimuth: str, viewpoint: str | SphericalMirror) -> None:
    """Raise PanomapError where ``viewpoint`` is no mode, or conflicts with ``model`` or ``azimuth``
    (:func:`viewpoint_conflict`)."""
    if not isinstance(viewpoint, SphericalMirror) and viewpoint not in VIEWPOINT_MODES:
        raise PanomapError(f"viewpoint must be one of {', '.join(VIEWPOINT_MODES)}, not {viewpoint!r}")
    conflict = viewpoint_conflict(model, azimuth, viewpoint)
    if conflict is not None:
        raise PanomapError(conflict.replace("--sphere-radius", "viewpoint=SphericalMirror(...)"))


def viewpoint_conflict(model: str, azimuth: str, viewpoint: str | SphericalMirror) -> str | None:
    """Why ray origins asked for (``viewpoint`` "caustic", or a :class:`SphericalMirror`) cannot be fitted with
    the ``model`` and ``azimuth`` asked for, in words naming the options; None where they go together.

    The paper's azimuth and its model (Algorithm 1, unweighted) are the paper's single-viewpoint camera: its
    fit is not cross-validated, and neither is its caustic. A sphere of known radius is fitted with its own law
    (``sphere``), and no other kind.
    """
    sphere = isinstance(viewpoint, SphericalMirror)
    if not sphere and viewpoint != "caustic":
        return None
    asked = "--sphere-radius (the sphere's ray origins)" if sphere else "--viewpoint caustic (ray origins)"
    if azimuth != "fit":
        return f"{asked} does not go with --azimuth {azimuth} (the paper's single-viewpoint camera)"
    if sphere and model not in ("auto", SPHERE_KIND):
        return f"{asked} fits the sphere's own law: --model {model} does not go with it (leave --model out)"
    if model in MODELS and not radial_kind(model).weighted:
        return f"{asked} does not go with --model {model} (the paper's single-viewpoint fit, unweighted)"
    return None


def choose_viewpoint(
    rays: LandmarkRays,
    start: RadialFunction,
    forced: bool = False,
    sphere: SphericalMirror | None = None,
    only: str | None = None,
) -> ViewpointChoice:
    """The single viewpoint, or the mirror's caustic where its held-out RMS is at most ``VIEWPOINT_GAIN`` times
    the single viewpoint's (``SPHERE_GAIN`` with the spherical mirror's law; see the module's docstring), the
    best held out of those that are; with ``forced``, the caustic of the best kind whatever their scores.

    The caustic is tried with the single viewpoint's radial kind and with the spherical mirror's law
    (``sphere``, its caustic shaped by its own law: the law of no single-viewpoint mirror, so it fits none);
    forced, with every weighted kind of at most ``CAUSTIC_KIND_PARAMETERS`` too (each started about O_m): the
    kind a single-viewpoint fit chose may bend to stand in for the ray origins at the landmarks' distances, and
    then trade its shape against the caustic's size. A known ``sphere``: its law with the ray origins its
    radius gives, whatever the scores. ``only`` (the kind the user forced): the caustic of that kind alone.

    Raises
    ------
    PanomapError
        Where a known sphere's law cannot be fitted to the landmarks.
    """
    straight = np.arctan2(rays.height, rays.horizontal)
    if sphere is not None:
        law = fit_radial(SPHERE_KIND, straight, rays.r, start.axis, 1.0 / rays.sigma)
        size = sphere.radius if start.axis == "down" else -sphere.radius  # the origins run away from the lens
        scores = {
            SINGLE: held_out_rms(rays, start, False),
            f"{CAUSTIC} (sphere of the radius given)": held_out_rms(rays, law, True, size=size),
        }
        finite = {name: score for name, score in scores.items() if math.isfinite(score)}
        return ViewpointChoice(fit_viewpoint(rays, law, True, size=size), finite)
    if not start.spec.weighted or rays.r.size < len(start.coefficients) + 2 + SPARE_LANDMARKS:
        return ViewpointChoice(None, {})
    held_out = {SINGLE: held_out_rms(rays, start, False)}
    candidates: dict[str, RadialFunction] = {}
    for name in MODELS:
        kind = radial_kind(name)
        own = name == start.kind
        forced_kind = forced and kind.weighted and kind.parameter_count <= CAUSTIC_KIND_PARAMETERS
        if not (own or kind.exact_origins or forced_kind) or (only is not None and name != only):
            continue
        try:
            candidates[name] = start if own else fit_radial(name, straight, rays.r, start.axis, 1.0 / rays.sigma)
        except PanomapError:
            continue
        score = held_out_rms(rays, candidates[name], True, start)
        if math.isfinite(score):
            held_out[f"{CAUSTIC} ({name})"] = score
        else:  # a fold it could not fit: not a candidate (the report holds finite scores only)
            del candidates[name]

    def gain(name: str) -> float:
        """The candidate's held-out RMS over what it must reach to be chosen (at most 1)."""
        needed = SPHERE_GAIN if radial_kind(name).exact_origins else VIEWPOINT_GAIN
        return held_out[f"{CAUSTIC} ({name})"] / (needed * held_out[SINGLE])

    eligible = [name for name in candidates if forced or gain(name) <= 1.0]
    best = min(eligible, key=lambda name: held_out[f"{CAUSTIC} ({name})"], default=None)
    if best is None:
        return ViewpointChoice(None, held_out)
    try:
        return ViewpointChoice(fit_viewpoint(rays, candidates[best], True, start), held_out)
    except PanomapError:
        return ViewpointChoice(None, held_out)
