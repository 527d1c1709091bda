"""Landmark learning (paper 2.1, Algorithm 1 and beyond): from landmark pairs to a camera model.

Convention: world Z up; a landmark's ray is ``d = P - O_m``; azimuth and
elevation as in :mod:`panomap.geometry`; pixel radius r and image angle phi
about the image centre (u0, v0); ``phi = s*theta + phi0``, ``r = f_r(rho)``.

The fit, unless ``model="paper"`` (Algorithm 1 exactly: an unweighted least
squares of the 4th-degree polynomial with the centre pair), in the order
:func:`fit_camera` takes its steps, each in its own file:

1. **Noise model** (:mod:`.noise`): each landmark's residual split into a radial
   and a tangential part, each whitened by its own standard deviation.
2. **Start** (:mod:`.start`): the axis, the handedness ``s`` from the landmarks'
   image angles; ``phi0`` and f_r by weighted least squares (they separate
   while the centre is fixed).
3. **Model choice** (:mod:`.selection`) by leave-one-out cross-validation, and
   **outliers** (:mod:`.outliers`), dropped while the worst held-out residual
   exceeds 5 robust standard deviations.
4. **Joint refinement** (:mod:`.refine`) by nonlinear least squares of f_r,
   phi0 and, with ``refine_centre``, the centre; with ``refine_centre`` the
   paper's model (centre given) is not a candidate, and model and outliers are
   chosen again about the refined centre, then refined once more. A refinement
   that turns f_r back short of the annulus the separable fit covered is not
   taken.
5. **Mount** (:mod:`.mount`): the tilt and the position, kept where
   cross-validation says the landmarks support them.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, replace
from typing import TypeVar

import numpy as np

from ...camera.model import CameraModel
from ...camera.orientation import tilt_rotation, to_camera
from ...camera.radial import RadialFunction
from ...camera.radial_models import AUTO_CANDIDATES, MIRROR_CANDIDATES, RadialKind, radial_kind
from ...camera.uncertainty import coefficient_covariance
from ...camera.valid_range import annulus_coverage_problem, is_monotonic
from ...camera.viewpoint import PARALLAX_DISTANCE, parallax_px
from ...errors import PanomapError
from ...geometry import FloatArray, azimuth_elevation, pixel_polar
from ..core import selection as selection_module
from ..core.line_report import LineFitReport
from ..core.noise import DEFAULT_WORLD_SIGMA_FRACTION, Observations, radial_weights, rim_slack_px, world_sigmas
from ..core.refine import MountOptions, MountProblem, MountSolution, camera_rays, refine
from ..core.report import FitReport, FitSettings, LandmarkResidual, MountReport, ViewpointReport
from ..core.start import consistency, detect_axis, handedness, pixels_hint, separable_fit
from .arguments import checked_arguments
from .joint import ImageLines, JointLines, JointResult, refine_with_lines
from .mount import (
    DEFAULT_CAMERA_SIGMA_FRACTION,
    MountChoice,
    choose_mount,
    mount_options,
    mount_report,
    orientation_rotation,
)
from .outliers import choose, choose_start
from .pairs import Landmarks
from .viewpoint import (
    SphericalMirror,
    annulus_elevations,
    check_viewpoint,
    choose_viewpoint,
    landmark_rays,
)

_T = TypeVar("_T")
# The choice of a fit: inliers (bool), radial kind, every candidate's held-out RMS, the refined camera.
_Chosen = tuple[FloatArray, RadialKind, dict[str, float], MountSolution]

MIN_ELEVATION_SPREAD = math.radians(1.0)


@dataclass(frozen=True)
class CameraFit:
    """A fitted camera model with the fit report.

    Attributes
    ----------
    model : CameraModel
    landmarks : Landmarks
    camera_position : (X0, Y0, Z0)
    theta, rho : (n,) ndarray
        Landmark azimuths and elevations (rad).
    predicted : (n, 2) ndarray
        Where the model puts each landmark, px.
    residuals_px : (n,) ndarray
        Distance (px) between each landmark's pixel and its prediction.
    radial_residuals_px : (n,) ndarray
        Fitted minus measured radius, px.
    inliers : (n,) bool ndarray
        False for landmarks dropped as outliers.
    covariance : (p, p) ndarray
        Covariance of the radial model's coefficients.
    axis_source : str
        ``"given"`` or ``"detected"``.
    azimuth_mode : str
        ``"fit"`` (s and phi0 estimated) or ``"paper"`` (s = +1, phi0 = 0).
    azimuth_consistency : float
        Weighted mean resultant length (0..1) of ``phi - s*theta``.
    selection : dict
        Leave-one-out RMS residual (px) of each candidate radial model.
    settings : FitSettings
        The noise model and options used.
    centre_start : (u0, v0)
        The centre the fit started from (px): ``model.centre`` is the same
        unless the fit refined it.
    rho_camera : (n,) ndarray, optional
        Landmark elevations (rad) in the camera's axes, where f_r applies
        (``rho`` is in the world's; the same for a level camera).
    mount : MountReport, optional
        The camera's tilt and position as fitted, and how they were chosen.
    lines : LineFitReport, optional
        The straight lines of an image that joined the fit (:mod:`.joint`), each line's residual under the
        fitted camera; None where no line joined.
    lines_note : str, optional
        Why no line joined, where lines were offered and none did.
    lines_note_warns : bool
        Whether ``lines_note`` is a warning (False: the landmarks alone fit far more tightly than the lines).
    viewpoint : ViewpointReport, optional
        Whether the camera has a single viewpoint, as cross-validation over the landmarks says
        (:mod:`.viewpoint`); None where it was not tried.
    """

    model: CameraModel
    landmarks: Landmarks
    camera_position: tuple[float, float, float]
    theta: FloatArray
    rho: FloatArray
    predicted: FloatArray
    residuals_px: FloatArray
    radial_residuals_px: FloatArray
    inliers: FloatArray
    covariance: FloatArray
    axis_source: str
    azimuth_mode: str
    azimuth_consistency: float
    selection: dict[str, float]
    settings: FitSettings
    centre_start: tuple[float, float] | None = None
    rho_camera: FloatArray | None = None
    mount: MountReport | None = None
    lines: LineFitReport | None = None
    lines_note: str | None = None
    lines_note_warns: bool = True
    viewpoint: ViewpointReport | None = None

    @property
    def rms_px(self) -> float:
        """RMS residual (px) over the inliers."""
        return float(np.sqrt(np.mean(self.residuals_px[self.inliers] ** 2)))

    @property
    def max_px(self) -> float:
        """Largest residual (px) over the inliers."""
        return float(np.max(self.residuals_px[self.inliers]))

    @property
    def centre_shift_px(self) -> float:
        """How far (px) the fit moved the centre from where it started (0 when it did not refine it)."""
        if self.centre_start is None:
            return 0.0
        return math.dist(self.model.centre, self.centre_start)

    @property
    def outliers(self) -> list[str]:
        """Names of the landmarks dropped as outliers."""
        return [name for name, keep in zip(self.landmarks.names, self.inliers, strict=True) if not keep]

    @property
    def landmark_range(self) -> tuple[float, float]:
        """Lowest and highest inlier landmark elevation (rad) in the camera's axes (where f_r applies)."""
        rho = (self.rho if self.rho_camera is None else self.rho_camera)[self.inliers]
        return float(np.min(rho)), float(np.max(rho))

    def report(self) -> FitReport:
        """The fit report (angles in degrees, residuals in px)."""
        rows = tuple(
            LandmarkResidual(
                name=name,
                u=pixel[0],
                v=pixel[1],
                X=world[0],
                Y=world[1],
                Z=world[2],
                azimuth_deg=math.degrees(float(self.theta[k])),
                elevation_deg=math.degrees(float(self.rho[k])),
                u_fit=float(self.predicted[k, 0]),
                v_fit=float(self.predicted[k, 1]),
                residual_px=float(self.residuals_px[k]),
                radial_residual_px=float(self.radial_residuals_px[k]),
                outlier=not bool(self.inliers[k]),
            )
            for k, (name, pixel, world) in enumerate(
                zip(self.landmarks.names, self.landmarks.pixels.tolist(), self.landmarks.world.tolist(), strict=True)
            )
        )
        low, high = self.landmark_range
        return FitReport(
            model=self.model.radial.kind,
            axis=self.model.axis,
            axis_source=self.axis_source,
            azimuth_mode=self.azimuth_mode,
            s=self.model.s,
            phi0_deg=math.degrees(self.model.phi0),
            centre=self.model.centre,
            azimuth_consistency=self.azimuth_consistency,
            rms_px=self.rms_px,
            max_px=self.max_px,
            outliers=tuple(self.outliers),
            landmark_elevation_range_deg=(math.degrees(low), math.degrees(high)),
            model_selection_loo_rms_px={k: (v if math.isfinite(v) else None) for k, v in self.selection.items()},
            covariance=tuple(tuple(row) for row in self.covariance.tolist()),
            settings=self.settings,
            landmarks=rows,
            centre_start=self.centre_start,
            mount=self.mount,
            lines=self.lines,
            viewpoint=self.viewpoint,
        )


def fit_camera(
    landmarks: Landmarks,
    camera_position: tuple[float, float, float],
    centre: tuple[float, float],
    *,
    model: str = "auto",
    azimuth: str = "fit",
    axis: str | None = None,
    image_size: tuple[int, int] | None = None,
    annulus: tuple[float, float] | None = None,
    refine_centre: bool = False,
    pixel_sigma: float = 1.0,
    world_sigma: float | None = None,
    reject_outliers: bool = True,
    tilt_deg: str | tuple[float, float] = "fit",
    camera_sigma: float | None = None,
    centre_is_guess: bool = False,
    tilt: str | tuple[float, float] | None = None,
    lines: ImageLines | None = None,
    viewpoint: str | SphericalMirror = "auto",
    orientation_deg: tuple[float, float, float] | None = None,
) -> CameraFit:
    """Fit the camera model to landmark pairs.

    Parameters
    ----------
    landmarks : Landmarks
        At least 5 pairs, spread in elevation.
    camera_position : (X0, Y0, Z0)
        Mirror (lens) centre O_m in world units.
    centre : (u0, v0)
        Image centre, px (the start, with ``refine_centre``).
    model : str
        ``"auto"`` (leave-one-out choice) or one of ``panomap.camera.radial_models.MODELS``;
        ``"paper"`` is Algorithm 1 exactly.
    azimuth : {"fit", "paper"}
        Estimate ``s`` and ``phi0``, or take the paper's ``s = +1, phi0 = 0``.
    axis : {"down", "up"}, optional
        Force the viewing direction; found from the landmarks when omitted.
    image_size : (width, height), optional
        When given, landmarks outside the image are refused.
    annulus : (cutoff_radius, outer_radius), optional
        The visible annulus (px); automatic selection then only takes models
        that are monotonic all across it.
    refine_centre : bool
        Refine the centre together with f_r and phi0.
    pixel_sigma : float
        Standard deviation of the landmarks' pixels, px.
    world_sigma : float, optional
        Standard deviation of the world points' coordinates, world units;
        default 0.4% of the median landmark distance.
    reject_outliers : bool
        Drop landmarks that disagree with the rest (named in the report).
    tilt_deg : "fit", "none" or (tilt_deg, toward_deg)
        ``"fit"``: estimate the tilt of the camera's axis off the vertical and keep it when cross-validation says
        the landmarks support it; ``"none"``: the camera is level (the paper's assumption); a pair fixes it: the
        optical axis ``tilt_deg`` off the vertical, toward world azimuth ``toward_deg`` (deg).
    camera_sigma : float, optional
        Standard deviation (world units) of each coordinate of
        ``camera_position`` (a tape measurement); the fit refines the position
        when cross-validation says the landmarks support it. 0 keeps it exact;
        default 1% of the median landmark distance.
    centre_is_guess : bool
        The starting ``centre`` was not measured (the frame's middle, where the
        image shows no rim): with ``refine_centre``, no tilt is tried about it
        (a tilt about a point the image does not show would stand in for the
        centre's own error: 5-10 px on simulated full-frame fisheyes).
    tilt : optional
        The old spelling of ``tilt_deg``: still taken, with a DeprecationWarning.
    lines : ImageLines, optional
        The edge arcs of an image of the camera: its straight lines join the landmarks in the final refinement
        (:mod:`.joint`), each weighted by its measured noise; the radial kind is then the lines'
        cross-validated choice. Where they cannot join, the landmark fit stands and ``CameraFit.lines_note``
        says why.
    viewpoint : {"auto", "single", "caustic"} or SphericalMirror
        ``"single"``: every ray from O_m (the paper's model). ``"auto"``: a mirror camera (one with a cut-off disc
        in ``annulus``) gets each elevation's ray origin on the axis, as a mirror of revolution's caustic, where
        cross-validation over the landmarks chooses it (:mod:`.viewpoint`); a lens keeps the single viewpoint.
        ``"caustic"``: the caustic is fitted whatever cross-validation says (a sphere or a cone seen from landmarks
        too far to show it); a :class:`.viewpoint.SphericalMirror`: its law with the ray origins its radius gives.
        Lines joined to the landmarks keep the single viewpoint.
    orientation_deg : (yaw, pitch, roll), optional
        A camera looking any way (deg): the fit starts there (``tilt_deg="fit"`` refines it); not with ``axis``.

    Raises
    ------
    PanomapError
        Too few landmarks, one at the camera or outside the image, all at one elevation, or no model that fits.
    """
    tilt = renamed_keyword("fit_camera", "tilt", tilt, "tilt_deg", tilt_deg)
    check_viewpoint(model, azimuth, viewpoint)
    requested, camera, start_centre, tilt_given = checked_arguments(
        landmarks, camera_position, centre, model, azimuth, axis, image_size, refine_centre, pixel_sigma,
        world_sigma, camera_sigma, tilt,
    )  # fmt: skip
    setup = _observe(landmarks, camera, start_centre, azimuth, axis, pixel_sigma, world_sigma, camera_sigma,
                     tilt_given, orientation_deg)  # fmt: skip
    data, problem = setup.data, replace(setup.problem, centre_found=None if centre_is_guess else start_centre)
    candidates, robust = _candidates(requested, annulus, refine_centre, reject_outliers)
    # A tilted camera can put landmarks near the rim beyond it under a level model: where a tilt may be
    # fitted, the level fit then only starts the mount's search and cannot be the answer (level_covers).
    may_tilt = tilt == "fit" and azimuth == "fit" and annulus is not None
    chosen, level_covers, data = _level_fit(
        problem, data, start_centre, candidates, annulus, robust, reject_outliers, may_tilt, refine_centre
    )
    chosen, mount_choice, problem = _mount(
        problem, data, chosen, candidates, annulus, robust, level_covers, tilt, refine_centre,
        # (No tilt about the centre as found where it was not found but guessed.)
        twin=len(landmarks) <= selection_module.EXACT_LOO_MAX and not centre_is_guess,
        search=azimuth == "fit" and (requested is None or requested.weighted),
    )  # fmt: skip
    joint, chosen, mount_choice, problem = _join_lines(
        problem, chosen, mount_choice, lines, model, refine_centre, tilt == "fit" and azimuth == "fit", annulus
    )
    fitted = _camera_fit(
        landmarks, problem, data, chosen, mount_choice, tilt, start_centre, setup.axis_source, model, refine_centre,
        reject_outliers,
    )  # fmt: skip
    return _finished(fitted, joint, viewpoint, azimuth, annulus, None if model == "auto" else model)


def _candidates(
    requested: RadialKind | None, annulus: tuple[float, float] | None, refine_centre: bool, reject_outliers: bool
) -> tuple[tuple[RadialKind, ...], bool]:
    """The radial kinds the fit chooses among (the one asked for, or the automatic choice's candidates), and
    whether landmarks that disagree are searched for (``robust``)."""
    # A cut-off disc (the camera's own reflection) shows a mirror camera: its law is preferred among ties.
    preference = MIRROR_CANDIDATES if annulus is not None and annulus[0] > 0 else AUTO_CANDIDATES
    candidates = tuple(map(radial_kind, preference)) if requested is None else (requested,)
    if refine_centre:
        # A kind that takes the centre as given (Algorithm 1) would leave the centre unrefined.
        candidates = tuple(k for k in candidates if not k.centre_given)
    # A kind asked for by name that does not follow the noise model is fitted as printed: no outlier search.
    robust = reject_outliers and (requested is None or requested.weighted)
    return candidates, robust


def _mount(
    problem: MountProblem,
    data: Observations,
    chosen: _Chosen,
    candidates: tuple[RadialKind, ...],
    annulus: tuple[float, float] | None,
    robust: bool,
    level_covers: bool,
    tilt: str | tuple[float, float],
    refine_centre: bool,
    *,
    twin: bool,
    search: bool,
) -> tuple[_Chosen, MountChoice | None, MountProblem]:
    """The mount (tilt, position) chosen from the level fit ``chosen`` where ``search`` allows more than the
    level one; the choice, the mounts' choice (None where none was searched) and the problem of its kind.

    (The mount is searched whatever kind the automatic choice made; a kind asked for by name that does not
    follow the noise model, Algorithm 1's, is fitted as printed: ``search`` is then False.)

    Raises
    ------
    PanomapError
        No model covers the annulus, and no tilt was tried.
    """
    problem = replace(problem, kind=chosen[1].name)
    mount_choice = None
    options = mount_options(tilt, problem.camera_sigma, refine_centre, twin)
    if len(options) > 1 and search:
        mount_choice = choose_mount(problem, options, chosen, data, candidates, annulus, robust, level_covers)
        chosen = mount_choice.chosen
        problem = replace(problem, kind=chosen[1].name)
    if not level_covers and mount_choice is None:
        choose(candidates, data, annulus, robust)  # raises: no model covers the annulus, and no tilt was tried
    return chosen, mount_choice, problem


def _join_lines(
    problem: MountProblem,
    chosen: _Chosen,
    mount_choice: MountChoice | None,
    lines: ImageLines | None,
    model: str,
    refine_centre: bool,
    tilt: bool,
    annulus: tuple[float, float] | None,
) -> tuple[JointResult | JointLines | None, _Chosen, MountChoice | None, MountProblem]:
    """The landmark fit ``chosen`` refined with the image's straight lines (:func:`.joint.refine_with_lines`):
    the joint result (or why the lines could not join; None without ``lines``), and the choice, mounts and
    problem it leaves."""
    if lines is None:
        return None, chosen, mount_choice, problem
    landmark_options = mount_choice.chosen_options if mount_choice is not None else MountOptions(refine_centre)
    joint = refine_with_lines(
        problem, chosen[3], chosen[0], landmark_options, lines, model=model, refine_centre=refine_centre,
        tilt=tilt, annulus=annulus,
    )  # fmt: skip
    if isinstance(joint, JointResult):
        chosen = (chosen[0], radial_kind(joint.kind), chosen[2], joint.solution)
        mount_choice = MountChoice(chosen, joint.options, {})
        problem = replace(problem, kind=joint.kind)
    return joint, chosen, mount_choice, problem


def _finished(
    fitted: CameraFit,
    joint: JointResult | JointLines | None,
    viewpoint: str | SphericalMirror,
    azimuth: str,
    annulus: tuple[float, float] | None,
    model: str | None = None,
) -> CameraFit:
    """The fit with what the lines joined to it say (their covariance and report, or why they did not join),
    or, without lines, with its viewpoint chosen (:func:`with_viewpoint`) where ``viewpoint`` asks for it: the
    caustic forced (``"caustic"``) of the radial ``model`` forced, where one is, or refused with the reason."""
    if isinstance(joint, JointResult):
        count = len(joint.solution.radial.coefficients)
        covariance = joint.refinement.covariance[:count, :count]
        return replace(fitted, covariance=covariance, lines=joint.lines.report)
    if joint is not None:
        return replace(fitted, lines_note=joint.note, lines_note_warns=joint.warns)
    if isinstance(viewpoint, SphericalMirror):
        return with_viewpoint(fitted, annulus, sphere=viewpoint)
    if viewpoint == "single" or azimuth != "fit" or (viewpoint == "auto" and (annulus is None or annulus[0] <= 0)):
        return fitted
    forced = viewpoint == "caustic"
    result = with_viewpoint(fitted, annulus, forced=forced, only=model)
    if forced and result.model.viewpoint is None:
        with_model = f" with model {model}" if model is not None else ""
        why = "too few of them, or a caustic that folds or stops short of the image circle"
        raise PanomapError(f"viewpoint caustic: no ray origins can be fitted to the landmarks{with_model} ({why})")
    return result


def with_viewpoint(
    fitted: CameraFit,
    annulus: tuple[float, float] | None = None,
    forced: bool = False,
    sphere: SphericalMirror | None = None,
    only: str | None = None,
) -> CameraFit:
    """The fit with each elevation's ray origin on the axis, where cross-validation over the inlier landmarks
    chooses it (:func:`.viewpoint.choose_viewpoint`), its residuals and covariance made again; else the fit
    as it is, with the report of the choice."""
    model, inliers = fitted.model, fitted.inliers
    world, pixels = fitted.landmarks.world[inliers], fitted.landmarks.pixels[inliers]
    settings = fitted.settings
    rays = landmark_rays(
        world, pixels, fitted.camera_position, model.rotation, model.centre, model.radial,
        settings.pixel_sigma_px, settings.world_sigma, annulus_elevations(model.radial, annulus),
    )  # fmt: skip
    choice = choose_viewpoint(rays, model.radial, forced, sphere, only)
    single = replace(fitted, viewpoint=ViewpointReport(True, 0.0, 0.0, PARALLAX_DISTANCE, choice.held_out))
    if choice.fit is None or choice.fit.viewpoint is None:
        return single if choice.held_out else fitted
    radial, viewpoint = choice.fit.radial, choice.fit.viewpoint
    camera_model = replace(model, radial=radial, viewpoint=viewpoint)
    d = fitted.landmarks.world - np.asarray(fitted.camera_position)
    theta, rho = camera_model.point_angles(d)
    _, rho_camera = camera_model.camera_angles(theta, rho)
    low, high = float(np.min(rho_camera[inliers])), float(np.max(rho_camera[inliers]))
    slack = rim_slack_px(settings.pixel_sigma_px)
    if not is_monotonic(radial, low, high) or (
        annulus is not None and annulus_coverage_problem(radial, (low, high), *annulus, slack_px=slack) is not None
    ):
        # A caustic whose f_r folds or stops short of the annulus makes no table: the single viewpoint stands.
        if sphere is not None:
            raise PanomapError(
                f"a spherical mirror of radius {sphere.radius:g} does not explain these landmarks across the annulus "
                "(its law folds or stops short of the image circle): is the camera's mirror a sphere?"
            )
        return single
    predicted = camera_model.pixels(theta, rho)
    r, _ = pixel_polar(fitted.landmarks.pixels, model.centre)
    covariance = coefficient_covariance(radial, rho_camera[inliers], r[inliers], 1.0 / rays.sigma)
    report = ViewpointReport(
        single_viewpoint=False,
        excursion=viewpoint.excursion(low, high),
        parallax_px=parallax_px(radial, viewpoint, (low, high)),
        parallax_distance=PARALLAX_DISTANCE,
        cross_validation=choice.held_out,
    )
    return replace(
        fitted,
        model=camera_model,
        theta=theta,
        rho=rho,
        rho_camera=rho_camera,
        predicted=predicted,
        residuals_px=np.linalg.norm(predicted - fitted.landmarks.pixels, axis=1),
        radial_residuals_px=radial(rho_camera) - r,
        covariance=covariance,
        viewpoint=report,
    )


def renamed_keyword(function: str, old: str, old_value: _T | None, new: str, new_value: _T) -> _T:
    """``new_value``, or ``old_value`` where the old spelling ``old`` of keyword ``new`` was given (with a
    DeprecationWarning naming ``function``)."""
    if old_value is None:
        return new_value
    warnings.warn(f"{function}({old}=...) is deprecated: the keyword is {new}", DeprecationWarning, stacklevel=3)
    return old_value


@dataclass(frozen=True)
class _Setup:
    """The landmarks observed from the camera as given: the observations, the refinement's problem, and
    whether the axis was given or detected."""

    data: Observations
    problem: MountProblem
    axis_source: str


def _observe(
    landmarks: Landmarks,
    camera: tuple[float, ...],
    centre: tuple[float, float],
    azimuth: str,
    axis: str | None,
    pixel_sigma: float,
    world_sigma: float | None,
    camera_sigma: float | None,
    tilt_given: tuple[float, float] | None,
    orientation_deg: tuple[float, float, float] | None,
) -> _Setup:
    """The landmarks' rays from ``camera``, their elevations checked, the axis and handedness found, the noise
    model's defaults filled in: the observations about ``centre`` in the frame of the tilt given."""
    u0, v0 = centre
    oriented = orientation_rotation(tilt_given, orientation_deg, axis)
    axis = "down" if oriented is not None else axis
    d = landmarks.world - np.asarray(camera)
    distance = np.linalg.norm(d, axis=1)
    at_camera = np.flatnonzero(distance < 1e-9)
    if at_camera.size:
        raise PanomapError(f"landmark {landmarks.names[at_camera[0]]!r} is at the camera position")
    # (In the camera's own axes where its orientation is given: a camera looking ahead sees its landmarks at
    # world elevations that say nothing of its radial function.)
    _, rho = azimuth_elevation(to_camera(d, oriented))
    if float(np.ptp(rho)) < MIN_ELEVATION_SPREAD:
        raise PanomapError(
            f"all landmarks are at one elevation ({math.degrees(float(np.mean(rho))):.2f} deg, "
            f"spread {math.degrees(float(np.ptp(rho))):.3f} deg); the radial fit needs them spread "
            "in elevation"
        )
    r, phi = pixel_polar(landmarks.pixels, (u0, v0))
    axis_source = "given"
    if axis is None:
        try:
            axis, axis_source = detect_axis(rho, r), "detected"
        except PanomapError as exc:
            raise PanomapError(exc.detail + pixels_hint(rho, landmarks.pixels, (u0, v0), d)) from None
    if world_sigma is None:
        world_sigma = DEFAULT_WORLD_SIGMA_FRACTION * float(np.median(distance))
    if camera_sigma is None:
        camera_sigma = DEFAULT_CAMERA_SIGMA_FRACTION * float(np.median(distance))
    rotation_given = oriented
    if tilt_given is not None:
        rotation_given = tilt_rotation(math.radians(tilt_given[0]), math.radians(tilt_given[1]), axis)
    d = to_camera(d, rotation_given)
    theta, rho = azimuth_elevation(d)
    sigma_rho, sigma_theta = world_sigmas(d, world_sigma)
    s = 1 if azimuth == "paper" else handedness(theta, phi, r)
    data = Observations(
        theta=theta,
        rho=rho,
        r=r,
        phi=phi,
        sigma_rho=sigma_rho,
        sigma_theta=sigma_theta,
        pixel_sigma=float(pixel_sigma),
        axis=axis,
        s=s,
        azimuth_mode=azimuth,
    )
    problem = MountProblem(
        world=landmarks.world,
        pixels=landmarks.pixels,
        camera=np.asarray(camera),
        kind="",
        axis=axis,
        s=s,
        pixel_sigma=float(pixel_sigma),
        world_sigma=float(world_sigma),
        camera_sigma=float(camera_sigma),
        rotation=rotation_given,
    )
    return _Setup(data, problem, axis_source)


def _level_fit(
    problem: MountProblem,
    data: Observations,
    centre: tuple[float, float],
    candidates: tuple[RadialKind, ...],
    annulus: tuple[float, float] | None,
    robust: bool,
    reject_outliers: bool,
    may_tilt: bool,
    refine_centre: bool,
) -> tuple[tuple[FloatArray, RadialKind, dict[str, float], MountSolution], bool, Observations]:
    """The level camera from ``centre``: model and inliers chosen, f_r and phi0 fitted and refined (with the
    centre, when ``refine_centre``: then chosen again about the refined centre, and refined from there).

    Returns the choice (inliers, kind, every candidate's leave-one-out RMS, the refined camera), whether the
    choice covers the annulus, and the observations about the centre refined.
    """
    inliers, kind, selection, level_covers = choose_start(candidates, data, annulus, robust, may_tilt)
    radial, phi0 = separable_fit(kind, data, inliers)
    if kind.weighted:
        # (With the centre refined this is a first pass, chosen again below: the annulus is held then.)
        radial, phi0, centre = _refine_level(
            radial, phi0, centre, problem, data, inliers, refine_centre, None if refine_centre else annulus
        )
    if refine_centre:
        # Model and outliers were chosen about the starting centre, whose error (a few px on a real mirror,
        # where the rim's centre is not the axis) swamps the differences between models: choose again
        # about the refined centre, and refine from there.
        r, phi = pixel_polar(problem.pixels, centre)
        data = replace(data, r=r, phi=phi)
        inliers, kind, selection, level_covers = choose_start(candidates, data, annulus, reject_outliers, may_tilt)
        radial, phi0 = separable_fit(kind, data, inliers)
        radial, phi0, centre = _refine_level(radial, phi0, centre, problem, data, inliers, True, annulus)
    solution = MountSolution(radial, phi0, centre, np.zeros(2), np.zeros(3), np.empty((0, 0)))
    return (inliers, kind, selection, solution), level_covers, data


def _refine_level(
    radial: RadialFunction,
    phi0: float,
    centre: tuple[float, float],
    problem: MountProblem,
    data: Observations,
    subset: FloatArray,
    refine_centre: bool,
    annulus: tuple[float, float] | None = None,
) -> tuple[RadialFunction, float, tuple[float, float]]:
    """f_r, phi0 and (optionally) the centre refined (:func:`panomap.calibrate.core.refine.refine`) from the
    separable solution given, on the level camera.

    The separable solution is kept where the refined f_r folds over the landmarks, or no
    longer runs to the ends of ``annulus`` when the given one did: near a rim where the law
    flattens (an orthographic fisheye's), a refinement within the noise can turn the curve
    back a few pixels short of the image circle, and the table would then refuse it.
    """
    start = MountSolution(radial, phi0, centre, np.zeros(2), np.zeros(3), np.empty((0, 0)))
    options = MountOptions(centre=refine_centre)
    refined = refine(problem, start, subset, options, evaluations_per_unknown=200, what="the joint refinement")
    solution = refined.solution
    rho = data.rho[subset]
    low, high = float(rho.min()), float(rho.max())
    if not is_monotonic(solution.radial, low, high):
        return radial, phi0, centre  # keep the separable solution rather than a folded curve
    if annulus is not None:
        slack = rim_slack_px(data.pixel_sigma)
        if annulus_coverage_problem(
            solution.radial, (low, high), *annulus, slack_px=slack
        ) and not annulus_coverage_problem(radial, (low, high), *annulus, slack_px=slack):
            return radial, phi0, centre
    return solution.radial, solution.phi0, solution.centre


def _camera_fit(
    landmarks: Landmarks,
    problem: MountProblem,
    data: Observations,
    chosen: tuple[FloatArray, RadialKind, dict[str, float], MountSolution],
    mount_choice: MountChoice | None,
    tilt: str | tuple[float, float],
    centre_start: tuple[float, float],
    axis_source: str,
    model: str,
    refine_centre: bool,
    reject_outliers: bool,
) -> CameraFit:
    """The fit as :class:`CameraFit` reports it: the camera model, its residuals and covariance, the mount."""
    inliers, _, selection, solution = chosen
    radial, phi0, centre_fit, s = solution.radial, solution.phi0, solution.centre, problem.s
    rotation = solution.rotation(problem)
    camera_fit = solution.camera(problem)
    d = camera_rays(problem, solution.w, solution.delta)
    theta, rho = azimuth_elevation(d)
    data = replace(data, theta=theta, rho=rho)
    theta_world, rho_world = azimuth_elevation(landmarks.world - camera_fit)
    weights = radial_weights(radial, data)
    r_fit, _ = pixel_polar(landmarks.pixels, centre_fit)
    covariance = coefficient_covariance(radial, rho[inliers], r_fit[inliers], weights[inliers])
    camera_model = CameraModel(centre_fit, radial, s, phi0, None if rotation is None else tuple(map(tuple, rotation)))
    predicted = camera_model.pixels(theta_world, rho_world)
    residuals = np.linalg.norm(predicted - landmarks.pixels, axis=1)
    r_now, phi_now = pixel_polar(landmarks.pixels, centre_fit)
    return CameraFit(
        model=camera_model,
        landmarks=landmarks,
        camera_position=(float(camera_fit[0]), float(camera_fit[1]), float(camera_fit[2])),
        theta=theta_world,
        rho=rho_world,
        rho_camera=rho,
        mount=mount_report(problem, solution, tilt, mount_choice, camera_model),
        predicted=predicted,
        residuals_px=residuals,
        radial_residuals_px=radial(rho) - r_now,
        inliers=inliers,
        covariance=covariance,
        axis_source=axis_source,
        azimuth_mode=data.azimuth_mode,
        azimuth_consistency=consistency(phi_now - s * theta, r_now),
        selection=selection,
        settings=FitSettings(
            pixel_sigma_px=float(problem.pixel_sigma),
            world_sigma=float(problem.world_sigma),
            refine_centre=refine_centre,
            reject_outliers=reject_outliers,
            model_requested=model,
        ),
        centre_start=centre_start,
    )
