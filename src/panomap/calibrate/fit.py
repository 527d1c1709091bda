"""Landmark learning (paper 2.1, Algorithm 1 and beyond): from landmark pairs to a camera model.

Convention: world Z up; a landmark's ray is ``d = P - O_m``; azimuth and
elevation as in :mod:`panomap.geometry`; pixel radius r and image angle phi
about the image centre (u0, v0); ``phi = s*theta + phi0``, ``r = f_r(rho)``.

The fit, unless ``model="paper"`` (Algorithm 1 exactly: an unweighted least
squares of the 4th-degree polynomial with the centre pair):

1. **Noise model.** Each landmark's residual is split into a radial and a
   tangential part (px), each with its own standard deviation: the pixel's
   (``pixel_sigma``, default 1 px) combined with the world point's
   (``world_sigma``, default 0.4% of the median landmark distance, about a
   centimetre in a room) seen through the camera: ``f_r'(rho) sigma_w / |d|``
   radially and ``r sigma_w / |d_xy|`` tangentially. Fits minimise these
   whitened residuals (the effective-variance method).
2. **Handedness** ``s`` from the landmarks' image angles; ``phi0`` and f_r by
   weighted least squares (they separate while the centre is fixed).
3. **Model choice** by leave-one-out cross-validation among the radial models
   of :mod:`panomap.camera.radial_models` that are monotonic over the landmarks, cover
   the annulus (cut-off to image circle) when it is known, and have at least 2.5
   landmarks per parameter (the paper's 5-coefficient polynomial from 13); the model with
   fewest parameters whose score is within one standard error of the best
   wins (the one-standard-error rule); the camera's law (the central mirror
   cameras' where the image shows a cut-off disc, else the fisheye lenses') within two.
4. **Outliers.** With the model chosen robustly (its score trimmed of the
   largest fifth of the errors), the landmark whose leave-one-out residual is
   largest (studentized: whitened by its noise and the others' prediction error
   together) is dropped while it exceeds 5 robust standard deviations; dropped
   landmarks are named in the report; the model is chosen again on the rest.
5. **Joint refinement** by nonlinear least squares of f_r, phi0 and, with
   ``refine_centre``, the centre; the Jacobian gives the coefficients'
   covariance, hence the standard error of r at every elevation. With
   ``refine_centre`` the paper's model (centre given) is not a candidate, and
   model and outliers are chosen again about the refined centre, then refined
   once more. A refinement that turns f_r back short of the annulus the
   separable fit covered is not taken.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..camera.model import CameraModel
from ..camera.orientation import tilt_rotation, to_camera
from ..camera.radial import RadialFunction, fit_radial
from ..camera.radial_models import AUTO_CANDIDATES, AXES, MIRROR_CANDIDATES, MODELS, RadialKind, radial_kind
from ..camera.uncertainty import coefficient_covariance, radius_standard_error
from ..camera.valid_range import is_monotonic, valid_elevation_range
from ..errors import PanomapError
from ..geometry import FloatArray, azimuth_elevation, inside_image, pixel_polar
from .landmarks import MIN_LANDMARKS, Landmarks
from .mount import (
    MountOptions,
    MountProblem,
    MountSolution,
    camera_rays,
    held_out_errors,
    joint_fit,
    residual_parts,
    tilt_standard_errors,
)
from .report import FitReport, FitSettings, LandmarkResidual, MountReport

MIN_ELEVATION_SPREAD = math.radians(1.0)
AZIMUTH_MODES = ("fit", "paper")
DEFAULT_WORLD_SIGMA_FRACTION = 0.004
# In the robust choice (outlier search), a model within this fraction of the best leave-one-out
# median, with fewer parameters, is preferred.
SELECTION_TOLERANCE = 0.02
# The robust choice scores a model by the RMS of its whitened held-out errors less this share of the largest
# (rounded up: 2 of 10 or 12). The median it used before is blind to a model that extrapolates badly: on a
# level equisolid fisheye (10 landmarks, seed 21007) it chose `unified`, whose held-out error at the top
# landmark (6.9 sigma, where `fisheye` has 1.5) then dropped two good landmarks as outliers (4.20 px; 1.29
# kept). Trimming still ignores the one wrong landmark the outlier search is for.
ROBUST_TRIM = 0.2
# In the automatic choice the camera's law (the mirror law where the image shows a cut-off disc, else the
# lens law) is kept against more flexible kinds whose mean squared held-out error is lower by up to this
# many of its standard errors (one, among curves): a designed projection is likelier than a curve that
# wins by chance on a few noisy landmarks. Only that one law: on a real mirror camera (kaidan, 20 draws
# of 10 corners) keeping the lens law too chose it in 2 draws at 0.95 px, where the curves give 0.62.
CAMERA_LAW_STANDARD_ERRORS = 2.0
# A landmark is an outlier where its held-out error exceeds this many robust sigmas, the error whitened by
# its own noise and the standard error of the others' prediction together (studentized). Whitened by its
# noise alone, a good landmark at an end of the elevations, predicted by extrapolation, stood out: an
# orthographic fisheye's rim landmark went (5.1 sigmas; 2.4 studentized), and the fit then turned back
# short of the circle. Not four: on a tilted camera the level fit's residuals run in a wave, and at four the
# search before the mount's dropped two good landmarks of a parabolic mirror 1.3 deg off (27.7 px).
OUTLIER_SIGMAS = 5.0
# Median of the norm of a 2-D standard normal vector: sqrt(2 ln 2).
MEDIAN_2D_NORM = math.sqrt(2 * math.log(2))
WEIGHT_ITERATIONS = 3
IndexArray = NDArray[np.intp]
# In the automatic choice a model needs this many landmarks per parameter. Below it a flexible model wins
# the leave-one-out score by chance too often: on 10 landmarks, the paper's 5-coefficient polynomial won on
# a fisheye in 2 trials of 20 and bent to 6-8 px between them, where the true 1- or 2-term model kept 2-4 px.
LANDMARKS_PER_PARAMETER = 2.5
# Leave-one-out is exact up to this many landmarks; above, k-fold cross-validation keeps the cost linear.
EXACT_LOO_MAX = 40
# A landmark this many pixel sigmas beyond the cut-off disc or the image circle is measurement noise: kept.
RIM_SLACK_SIGMAS = 3.0
CV_FOLDS = 10
# The tape's default standard deviation on each coordinate of the camera position: this fraction of the
# median landmark distance (2 cm at 2 m).
DEFAULT_CAMERA_SIGMA_FRACTION = 0.01
TILT_MODES = ("fit", "none")
# A tilt given as a pair (tilt_deg, toward_deg) is at most this far off the vertical.
MAX_TILT_DEG = 45.0
# A held-out landmark counts at most this many sigmas in the mount's cross-validation score:
# an undetected outlier cannot decide it.
MOUNT_SCORE_CAP_SIGMAS = 5.0
# A mount with more unknowns must beat a simpler one's held-out errors by this many standard errors of the
# mean paired improvement (one-sided, about 2.5% false alarms where the errors are normal).
MOUNT_SIGNIFICANCE = 2.0
# At most this many rounds of choosing the model and outliers in a mount's frame and refining the mount.
MOUNT_ROUNDS = 3
# The chi-square's 95th percentile for 2, 3 and 5 degrees of freedom: the screen of a mount's unknowns.
CHI2_95 = {2: 5.991, 3: 7.815, 5: 11.070}


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
        )


@dataclass(frozen=True)
class _Data:
    """Per-landmark quantities the fits share; arrays of shape (n,)."""

    theta: FloatArray
    rho: FloatArray
    r: FloatArray
    phi: FloatArray
    sigma_rho: FloatArray  # rad: the world point's error seen as an elevation error
    sigma_theta: FloatArray  # rad: ... as an azimuth error
    pixel_sigma: float
    axis: str
    s: int
    azimuth_mode: str
    # The fits made on these data: (model, the subset's bytes) -> (f_r, phi0), or the error it raised. A fit
    # is a pure function of the data and the subset, and the choice asks for many twice (the outlier search
    # and the model choice refit the same subsets: 35% of them on 40 landmarks). Not copied by replace().
    fitted: dict[tuple[RadialKind, bytes], tuple[RadialFunction, float] | PanomapError] = field(
        default_factory=dict, init=False, repr=False, compare=False
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
    tilt: str | tuple[float, float] = "fit",
    camera_sigma: float | None = None,
    centre_is_guess: bool = False,
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
    tilt : "fit", "none" or (tilt_deg, toward_deg)
        ``"fit"``: estimate the tilt of the camera's axis off the vertical and
        keep it when cross-validation says the landmarks support it;
        ``"none"``: the camera is level (the paper's assumption); a pair fixes
        it: the optical axis ``tilt_deg`` off the vertical, leaning toward world
        azimuth ``toward_deg`` (:mod:`panomap.camera.orientation`).
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

    Raises
    ------
    PanomapError
        Too few landmarks, a landmark at the camera or outside the image, all
        landmarks at one elevation, or no model that fits monotonically.
    """
    if model != "auto" and model not in MODELS:
        raise PanomapError(f"unknown model {model!r}; choose auto or one of {', '.join(MODELS)}")
    if azimuth not in AZIMUTH_MODES:
        raise PanomapError(f"azimuth must be 'fit' or 'paper', not {azimuth!r}")
    if axis is not None and axis not in AXES:
        raise PanomapError(f"axis must be 'down' or 'up', not {axis!r}")
    requested = None if model == "auto" else radial_kind(model)
    if refine_centre and requested is not None and requested.centre_given:
        raise PanomapError(
            f"the {model} model takes the centre as given; refining the centre needs another model than {model!r}"
        )
    camera = tuple(float(c) for c in camera_position)
    if len(camera) != 3 or not all(math.isfinite(c) for c in camera):
        raise PanomapError("the camera position must be three finite numbers X0 Y0 Z0")
    u0, v0 = (float(c) for c in centre)
    if not (math.isfinite(u0) and math.isfinite(v0)):
        raise PanomapError("the image centre must be two finite numbers U0 V0")
    if not (math.isfinite(pixel_sigma) and pixel_sigma > 0):
        raise PanomapError(f"the pixel sigma must be positive, not {pixel_sigma}")
    if world_sigma is not None and not (math.isfinite(world_sigma) and world_sigma >= 0):
        raise PanomapError(f"the world sigma must be zero or positive, not {world_sigma}")
    if camera_sigma is not None and not (math.isfinite(camera_sigma) and camera_sigma >= 0):
        raise PanomapError(f"the camera sigma must be zero or positive, not {camera_sigma}")
    tilt_given = _given_tilt(tilt)
    n = len(landmarks)
    if n < MIN_LANDMARKS:
        raise PanomapError(f"only {n} landmark(s); at least {MIN_LANDMARKS} are needed")
    if image_size is not None:
        _check_inside(landmarks, image_size)
    if float(np.max(np.ptp(landmarks.pixels, axis=0))) == 0.0:
        u, v = landmarks.pixels[0]
        raise PanomapError(
            f"all {n} landmarks are at one pixel ({u:g}, {v:g}); each needs the pixel where its own world point "
            "appears in the image"
        )

    d = landmarks.world - np.asarray(camera)
    distance = np.linalg.norm(d, axis=1)
    at_camera = np.flatnonzero(distance < 1e-9)
    if at_camera.size:
        raise PanomapError(f"landmark {landmarks.names[at_camera[0]]!r} is at the camera position")
    theta_world, rho = azimuth_elevation(d)
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
            axis, axis_source = _detect_axis(rho, r), "detected"
        except PanomapError as exc:
            raise PanomapError(exc.detail + _pixels_hint(rho, landmarks.pixels, (u0, v0), d)) from None
    if world_sigma is None:
        world_sigma = DEFAULT_WORLD_SIGMA_FRACTION * float(np.median(distance))
    if camera_sigma is None:
        camera_sigma = DEFAULT_CAMERA_SIGMA_FRACTION * float(np.median(distance))
    rotation_given = None
    if tilt_given is not None:
        rotation_given = tilt_rotation(math.radians(tilt_given[0]), math.radians(tilt_given[1]), axis)
    d = to_camera(d, rotation_given)
    theta, rho = azimuth_elevation(d)
    horizontal = np.hypot(d[:, 0], d[:, 1])
    s = 1 if azimuth == "paper" else _handedness(theta, phi, r)
    data = _Data(
        theta=theta,
        rho=rho,
        r=r,
        phi=phi,
        sigma_rho=world_sigma / distance,
        sigma_theta=world_sigma / np.maximum(horizontal, 1e-12),
        pixel_sigma=float(pixel_sigma),
        axis=axis,
        s=s,
        azimuth_mode=azimuth,
    )
    # A cut-off disc (the camera's own reflection) shows a mirror camera: its law is preferred among ties.
    preference = MIRROR_CANDIDATES if annulus is not None and annulus[0] > 0 else AUTO_CANDIDATES
    candidates = tuple(map(radial_kind, preference)) if requested is None else (requested,)
    if refine_centre:
        # A kind that takes the centre as given (Algorithm 1) would leave the centre unrefined.
        candidates = tuple(k for k in candidates if not k.centre_given)
    # A kind asked for by name that does not follow the noise model is fitted as printed: no outlier search.
    robust = reject_outliers and (requested is None or requested.weighted)
    # A tilted camera can put landmarks near the rim beyond it under a level model: where a tilt may be
    # fitted, the level fit then only starts the mount's search and cannot be the answer (level_covers).
    may_tilt = tilt == "fit" and azimuth == "fit" and annulus is not None
    inliers, kind, selection, level_covers = _choose_start(candidates, data, annulus, robust, may_tilt)
    radial, phi0 = _fit(kind, data, inliers)
    centre_fit = (u0, v0)
    if kind.weighted:
        # (With the centre refined this is a first pass, chosen again below: the annulus is held then.)
        radial, phi0, centre_fit = _refine(
            radial, phi0, (u0, v0), landmarks.pixels, data, inliers, refine_centre, None if refine_centre else annulus
        )
    if refine_centre:
        # Model and outliers were chosen about the starting centre, whose error (a few px on a real mirror,
        # where the rim's centre is not the axis) swamps the differences between models: choose again
        # about the refined centre, and refine from there.
        r, phi = pixel_polar(landmarks.pixels, centre_fit)
        data = replace(data, r=r, phi=phi)
        inliers, kind, selection, level_covers = _choose_start(candidates, data, annulus, reject_outliers, may_tilt)
        radial, phi0 = _fit(kind, data, inliers)
        radial, phi0, centre_fit = _refine(radial, phi0, centre_fit, landmarks.pixels, data, inliers, True, annulus)
    problem = MountProblem(
        world=landmarks.world,
        pixels=landmarks.pixels,
        camera=np.asarray(camera),
        kind=kind.name,
        axis=axis,
        s=s,
        pixel_sigma=float(pixel_sigma),
        world_sigma=float(world_sigma),
        camera_sigma=float(camera_sigma),
        rotation=rotation_given,
        centre_found=None if centre_is_guess else (u0, v0),
    )
    solution = MountSolution(radial, phi0, centre_fit, np.zeros(2), np.zeros(3), np.empty((0, 0)))
    mount_choice = None
    # (No tilt about the centre as found where it was not found but guessed.)
    twin = len(landmarks) <= EXACT_LOO_MAX and not centre_is_guess
    options = _mount_options(tilt, float(camera_sigma), refine_centre, twin)
    # (The mount is searched whatever kind the automatic choice made; a kind asked for by name that does not
    # follow the noise model, Algorithm 1's, is fitted as printed.)
    if len(options) > 1 and azimuth == "fit" and (requested is None or requested.weighted):
        mount_choice = _choose_mount(
            problem, options, (inliers, kind, selection, solution), data, candidates, annulus, robust, level_covers
        )
        inliers, kind, selection, solution = mount_choice.chosen
        problem = replace(problem, kind=kind.name)
        radial, phi0, centre_fit = solution.radial, solution.phi0, solution.centre
    if not level_covers and mount_choice is None:
        _choose(candidates, data, annulus, robust)  # raises: no model covers the annulus, and no tilt was tried
    rotation = solution.rotation(problem)
    camera_fit = solution.camera(problem)
    d = camera_rays(problem, solution.w, solution.delta)
    theta, rho = azimuth_elevation(d)
    data = replace(data, theta=theta, rho=rho)
    theta_world, rho_world = azimuth_elevation(landmarks.world - camera_fit)
    weights = _radial_weights(radial, data)
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
        mount=_mount_report(problem, solution, tilt, mount_choice, camera_model),
        predicted=predicted,
        residuals_px=residuals,
        radial_residuals_px=radial(rho) - r_now,
        inliers=inliers,
        covariance=covariance,
        axis_source=axis_source,
        azimuth_mode=azimuth,
        azimuth_consistency=_consistency(phi_now - s * theta, r_now),
        selection=selection,
        settings=FitSettings(
            pixel_sigma_px=float(pixel_sigma),
            world_sigma=float(world_sigma),
            refine_centre=refine_centre,
            reject_outliers=reject_outliers,
            model_requested=model,
        ),
        centre_start=(u0, v0),
    )


def _radial_sigma(radial: RadialFunction | None, data: _Data) -> FloatArray:
    """Standard deviation (px) of each landmark's radial residual."""
    slope = np.zeros_like(data.rho) if radial is None else np.nan_to_num(radial.slope(data.rho))
    return np.sqrt(data.pixel_sigma**2 + (slope * data.sigma_rho) ** 2)


def _tangential_sigma(data: _Data, r: FloatArray) -> FloatArray:
    """Standard deviation (px) of each landmark's tangential residual."""
    return np.sqrt(data.pixel_sigma**2 + (r * data.sigma_theta) ** 2)


def _radial_weights(radial: RadialFunction, data: _Data) -> FloatArray:
    return 1.0 / _radial_sigma(radial, data)


def _fit(kind: RadialKind, data: _Data, subset: FloatArray) -> tuple[RadialFunction, float]:
    """f_r and phi0 from the landmarks in ``subset`` (bool mask), the centre fixed; made once per subset."""
    key = (kind, np.asarray(subset, dtype=bool).tobytes())
    if key not in data.fitted:
        try:
            data.fitted[key] = _fit_once(kind, data, subset)
        except PanomapError as exc:
            data.fitted[key] = exc
    made = data.fitted[key]
    if isinstance(made, PanomapError):
        raise made.with_traceback(None)
    return made


def _fit_once(kind: RadialKind, data: _Data, subset: FloatArray) -> tuple[RadialFunction, float]:
    rho, r = data.rho[subset], data.r[subset]
    radial = fit_radial(kind.name, rho, r, data.axis)
    if kind.weighted:
        for _ in range(WEIGHT_ITERATIONS):
            radial = fit_radial(kind.name, rho, r, data.axis, 1.0 / _radial_sigma(radial, data)[subset])
    if data.azimuth_mode == "paper":
        return radial, 0.0
    delta = data.phi[subset] - data.s * data.theta[subset]
    weights = (r / _tangential_sigma(data, data.r)[subset]) ** 2
    return radial, float(np.arctan2(weights @ np.sin(delta), weights @ np.cos(delta)))


def _whitened(
    radial: RadialFunction, phi0: float, data: _Data, index: Any, prediction_se: FloatArray | None = None
) -> FloatArray:
    """Whitened residual norms of the landmarks at ``index``: sqrt(z_radial^2 + z_tangential^2); the radial
    standard deviation includes ``prediction_se`` (px, one per landmark) where given."""
    sigma = _radial_sigma(radial, data)[index]
    if prediction_se is not None:
        sigma = np.sqrt(sigma**2 + prediction_se**2)
    radial_error = (radial(data.rho[index]) - data.r[index]) / sigma
    angle = np.angle(np.exp(1j * (data.s * data.theta[index] + phi0 - data.phi[index])))
    tangential_error = data.r[index] * angle / _tangential_sigma(data, data.r)[index]
    return np.asarray(np.hypot(radial_error, tangential_error))


def _prediction_se(radial: RadialFunction, data: _Data, fitted: FloatArray, index: Any) -> FloatArray:
    """Standard error (px) of f_r at the landmarks at ``index``, f_r fitted to those in ``fitted`` (bool mask)
    under the noise model (the weights are 1 / the residuals' standard deviations)."""
    if not radial.spec.weighted:
        return np.zeros(np.size(data.rho[index]))
    weights = _radial_weights(radial, data)[fitted]
    covariance = coefficient_covariance(radial, data.rho[fitted], data.r[fitted], weights, noise_known=True)
    return np.nan_to_num(radius_standard_error(radial, covariance, data.rho[index]), nan=0.0)


def _pixel_error(radial: RadialFunction, phi0: float, data: _Data, index: Any) -> FloatArray:
    """Distance (px) between the landmarks at ``index`` and where the model puts them."""
    angle = np.angle(np.exp(1j * (data.s * data.theta[index] + phi0 - data.phi[index])))
    return np.asarray(np.hypot(radial(data.rho[index]) - data.r[index], data.r[index] * angle))


def _folds(data: _Data, members: IndexArray) -> list[IndexArray]:
    """Positions (into ``members``) held out together: one each up to ``EXACT_LOO_MAX`` landmarks, else
    ``CV_FOLDS`` folds dealt in elevation order (each fold spans the landmarks' elevations)."""
    if members.size <= EXACT_LOO_MAX:
        return [np.array([position]) for position in range(members.size)]
    order = np.argsort(data.rho[members], kind="stable")
    return [order[fold::CV_FOLDS] for fold in range(CV_FOLDS)]


def _leave_one_out(
    kind: RadialKind, data: _Data, subset: FloatArray, studentized: bool = False
) -> tuple[FloatArray, FloatArray]:
    """Whitened and pixel errors of each landmark in ``subset`` under a fit made without it.

    Exact leave-one-out up to ``EXACT_LOO_MAX`` landmarks; above, ``CV_FOLDS``-fold
    cross-validation (each landmark's error under a fit without its fold), so
    that the cost grows linearly with the number of landmarks. ``studentized``:
    the radial error is whitened by the landmark's noise and the standard error
    of the others' prediction together (a landmark at an end of the elevations,
    predicted by extrapolation, is then judged against what the others can tell).
    """
    members = np.flatnonzero(subset)
    whitened = np.full(members.size, np.inf)
    pixels = np.full(members.size, np.inf)
    for positions in _folds(data, members):
        others = subset.copy()
        others[members[positions]] = False
        try:
            radial, phi0 = _fit(kind, data, others)
        except PanomapError:
            continue
        prediction_se = _prediction_se(radial, data, others, members[positions]) if studentized else None
        whitened[positions] = _whitened(radial, phi0, data, members[positions], prediction_se)
        pixels[positions] = _pixel_error(radial, phi0, data, members[positions])
    return np.where(np.isfinite(whitened), whitened, np.inf), np.where(np.isfinite(pixels), pixels, np.inf)


def _acceptable(kind: RadialKind, data: _Data, subset: FloatArray, annulus: tuple[float, float] | None) -> str | None:
    """Why ``kind`` cannot serve (None when it can): no fit, not monotonic, does not cover the annulus."""
    try:
        radial, _ = _fit(kind, data, subset)
    except PanomapError as exc:
        return exc.detail
    low, high = float(data.rho[subset].min()), float(data.rho[subset].max())
    if not is_monotonic(radial, low, high):
        return "not monotonic over the landmarks"
    if annulus is not None:
        problem = annulus_coverage_problem(radial, (low, high), *annulus, slack_px=rim_slack_px(data.pixel_sigma))
        if problem:
            return problem
    return None


def rim_slack_px(pixel_sigma: float) -> float:
    """How far (px) a landmark may lie beyond the annulus and still count as on it: measurement noise."""
    return RIM_SLACK_SIGMAS * pixel_sigma


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


def _select(
    candidates: tuple[RadialKind, ...],
    data: _Data,
    subset: FloatArray,
    annulus: tuple[float, float] | None,
    robust: bool,
) -> tuple[RadialKind, dict[str, float]]:
    """The model with the best leave-one-out score; the LOO RMS (px) of every candidate.

    The score is the RMS of the whitened leave-one-out errors; the model with
    fewest parameters whose score is within one standard error of the best
    (the one-standard-error rule: the mean squared error plus its standard
    error over the landmarks) wins, or the camera's law (``mirror_law`` where
    ``annulus`` has a cut-off disc, else ``lens_law``) within
    CAMERA_LAW_STANDARD_ERRORS of them. When ``robust`` the score is their RMS
    less the largest ROBUST_TRIM share (one wrong landmark then cannot steer
    the choice), and a model within 2% of the best wins.
    """
    selection: dict[str, float] = {}
    scores: dict[str, float] = {}
    spreads: dict[str, float] = {}
    reasons: dict[str, str] = {}
    count = int(subset.sum())
    for kind in candidates:
        name = kind.name
        needed = kind.needed_elevations
        if len(candidates) > 1 and count - 1 < needed + 1:
            reasons[name] = f"needs more than {needed + 1} landmarks"
            selection[name] = math.inf
            continue
        if len(candidates) > 1 and count < LANDMARKS_PER_PARAMETER * kind.parameter_count:
            reasons[name] = f"needs {math.ceil(LANDMARKS_PER_PARAMETER * kind.parameter_count)} landmarks or more"
            selection[name] = math.inf
            continue
        problem = _acceptable(kind, data, subset, annulus)
        if problem:
            reasons[name] = problem
            selection[name] = math.inf
            continue
        if len(candidates) == 1:
            return kind, {}
        whitened, pixels = _leave_one_out(kind, data, subset)
        selection[name] = float(np.sqrt(np.mean(pixels**2)))
        scores[name] = _robust_score(whitened) if robust else float(np.sqrt(np.mean(whitened**2)))
        if whitened.size < 2:
            spreads[name] = 0.0
        elif not np.all(np.isfinite(whitened)):  # a held-out landmark the fit without it cannot place
            spreads[name] = math.inf
        else:
            spreads[name] = float(np.std(whitened**2, ddof=1) / math.sqrt(whitened.size))
    usable = {k: v for k, v in scores.items() if math.isfinite(v)}
    if not usable:
        detail = "; ".join(f"{k}: {v}" for k, v in reasons.items())
        raise PanomapError(f"no radial model fits these landmarks ({detail})")
    best_kind = min(usable, key=lambda k: usable[k])
    best = usable[best_kind]
    if robust:
        limit = best * (1 + SELECTION_TOLERANCE)
    else:
        # One-standard-error rule: the mean squared LOO error of the best model, plus its standard error.
        spread = spreads[best_kind] if math.isfinite(spreads[best_kind]) else 0.0
        limit = math.sqrt(best**2 + spread)
        law_limit = math.sqrt(best**2 + CAMERA_LAW_STANDARD_ERRORS * spread)
    shows_disc = annulus is not None and annulus[0] > 0
    for kind in candidates:  # in order of preference: fewer parameters first
        if kind.name in usable and usable[kind.name] <= limit + 1e-12:
            return kind, selection
        law = kind.mirror_law if shows_disc else kind.lens_law
        if not robust and law and kind.name in usable and usable[kind.name] <= law_limit + 1e-12:
            return kind, selection
    raise AssertionError("unreachable: the best model is among the usable ones")


def _robust_score(whitened: FloatArray) -> float:
    """The robust choice's score of whitened held-out errors (n,): their RMS less the largest ROBUST_TRIM share."""
    kept = np.sort(whitened)[: max(1, whitened.size - math.ceil(ROBUST_TRIM * whitened.size))]
    return float(np.sqrt(np.mean(kept**2)))


def _choose(
    candidates: tuple[RadialKind, ...],
    data: _Data,
    annulus: tuple[float, float] | None,
    reject_outliers: bool,
    start: FloatArray | None = None,
) -> tuple[FloatArray, RadialKind, dict[str, float]]:
    """Inliers, the chosen model and every candidate's leave-one-out RMS (px).

    With ``reject_outliers``: choose robustly, drop the worst landmark if it is
    an outlier under that choice, repeat; then choose on the inliers. ``start``
    (bool, n) are the landmarks to start from (default all).
    """
    n = data.rho.size
    inliers = np.ones(n, dtype=bool) if start is None else start.copy()
    if reject_outliers:
        for _ in range(n // 4 - int(n - inliers.sum())):
            kind, _ = _select(candidates, data, inliers, annulus, robust=True)
            fewer = _drop_worst(kind, data, inliers, candidates, annulus)
            if fewer is None:
                break
            inliers = fewer
    kind, selection = _select(candidates, data, inliers, annulus, robust=False)
    return inliers, kind, selection


def _drop_worst(
    kind: RadialKind,
    data: _Data,
    inliers: FloatArray,
    candidates: tuple[RadialKind, ...] = (),
    annulus: tuple[float, float] | None = None,
) -> FloatArray | None:
    """``inliers`` less one held-out landmark if the worst (studentized) exceeds OUTLIER_SIGMAS robust sigmas,
    else None.

    The landmark dropped is, of those beyond that bound and the worst one's neighbours in
    elevation, the one whose removal leaves the others' leave-one-out errors smallest under
    the best of ``kind`` and ``candidates`` (the models that may be chosen). At an end of
    the elevation range a wrong landmark drags the prediction of the good one beyond it,
    whose error can then be the larger: the good one's removal leaves the wrong one
    standing out, the wrong one's leaves none. Above ``EXACT_LOO_MAX`` landmarks (k-fold
    errors, where one landmark barely moves the fit of the others) every landmark beyond
    the bound goes at once.
    """
    count = int(inliers.sum())
    if count - 1 < kind.parameter_count + 3:
        return None
    whitened, _ = _leave_one_out(kind, data, inliers, studentized=True)
    scale = max(1.0, float(np.median(whitened)) / MEDIAN_2D_NORM)
    beyond = whitened > OUTLIER_SIGMAS * scale
    if not beyond.any():
        return None
    if count <= EXACT_LOO_MAX:
        kinds = (kind, *(other for other in candidates if other.name != kind.name))
        dropped = _least_harmful_removal(kinds, data, inliers, whitened, beyond, annulus)
        beyond = np.asarray(np.arange(whitened.size) == dropped)
    elif count - int(beyond.sum()) < max(kind.parameter_count + 3, count // 2):
        return None  # most of the landmarks "outliers": the model is wrong, not the landmarks
    fewer = inliers.copy()
    fewer[np.flatnonzero(inliers)[beyond]] = False
    return fewer


def _least_harmful_removal(
    kinds: tuple[RadialKind, ...],
    data: _Data,
    inliers: FloatArray,
    whitened: FloatArray,
    beyond: NDArray[np.bool_],
    annulus: tuple[float, float] | None,
) -> int:
    """Of ``inliers`` (whitened leave-one-out errors ``whitened``), the position of the landmark to drop.

    Candidates: those ``beyond`` the outlier bound and the worst one's neighbours in
    elevation; the winner leaves the smallest RMS of the others' leave-one-out errors,
    under the best of ``kinds`` that can serve without it.
    """
    members = np.flatnonzero(inliers)
    worst = int(np.argmax(whitened))
    by_elevation = np.argsort(data.rho[members], kind="stable")
    rank = int(np.flatnonzero(by_elevation == worst)[0])
    neighbours = by_elevation[max(0, rank - 1) : rank + 2]
    candidates = sorted(set(np.flatnonzero(beyond).tolist()) | set(neighbours.tolist()))
    if len(candidates) == 1:
        return worst
    scores = []
    for position in candidates:
        rest = inliers.copy()
        rest[members[position]] = False
        score = math.inf
        for kind in kinds:
            if rest.sum() < max(kind.needed_elevations + 2, LANDMARKS_PER_PARAMETER * kind.parameter_count):
                continue
            if kind is not kinds[0] and _acceptable(kind, data, rest, annulus):
                continue
            others, _ = _leave_one_out(kind, data, rest)
            if np.all(np.isfinite(others)):
                score = min(score, float(np.sqrt(np.mean(np.square(others)))))
        scores.append(score)
    best = int(np.argmin(scores))
    return worst if not math.isfinite(scores[best]) else int(candidates[best])


def _refine(
    radial: RadialFunction,
    phi0: float,
    centre: tuple[float, float],
    pixels: FloatArray,
    data: _Data,
    subset: FloatArray,
    refine_centre: bool,
    annulus: tuple[float, float] | None = None,
) -> tuple[RadialFunction, float, tuple[float, float]]:
    """Joint nonlinear least squares of f_r, phi0 and (optionally) the centre on whitened residuals.

    The separable solution given is kept where the refined f_r folds over the landmarks, or no
    longer runs to the ends of ``annulus`` when the given one did: near a rim where the law
    flattens (an orthographic fisheye's), a refinement within the noise can turn the curve
    back a few pixels short of the image circle, and the table would then refuse it.
    """
    from scipy import optimize  # here, not at the top: importing SciPy is slow

    count = len(radial.coefficients)
    rho, theta = data.rho[subset], data.theta[subset]
    uv = pixels[subset]
    radial_sigma = _radial_sigma(radial, data)[subset]
    sigma_theta = data.sigma_theta[subset]

    def unpack(p: FloatArray) -> tuple[RadialFunction, float, tuple[float, float]]:
        c = (float(p[count + 1]), float(p[count + 2])) if refine_centre else centre
        return RadialFunction(radial.kind, tuple(p[:count]), radial.axis), float(p[count]), c

    def residuals(p: FloatArray) -> FloatArray:
        f, offset, c = unpack(p)
        r_obs, phi_obs = pixel_polar(uv, c)
        radial_error = (f(rho) - r_obs) / radial_sigma
        angle = np.angle(np.exp(1j * (data.s * theta + offset - phi_obs)))
        tangential_error = r_obs * angle / np.sqrt(data.pixel_sigma**2 + (r_obs * sigma_theta) ** 2)
        return np.nan_to_num(np.concatenate([radial_error, tangential_error]), nan=1e6)

    start = np.array([*radial.coefficients, phi0, *(centre if refine_centre else ())], dtype=np.float64)
    result = optimize.least_squares(residuals, start, x_scale="jac", max_nfev=200 * start.size)
    if not result.success:
        raise PanomapError(f"the joint refinement did not converge ({result.message})")
    refined, offset, c = unpack(result.x)
    offset = float(np.angle(np.exp(1j * offset)))
    low, high = float(rho.min()), float(rho.max())
    if not is_monotonic(refined, low, high):
        return radial, phi0, centre  # keep the separable solution rather than a folded curve
    if annulus is not None:
        slack = rim_slack_px(data.pixel_sigma)
        if annulus_coverage_problem(refined, (low, high), *annulus, slack_px=slack) and not annulus_coverage_problem(
            radial, (low, high), *annulus, slack_px=slack
        ):
            return radial, phi0, centre
    return refined, offset, c


def _check_inside(landmarks: Landmarks, image_size: tuple[int, int]) -> None:
    width, height = image_size
    u, v = landmarks.pixels[:, 0], landmarks.pixels[:, 1]
    outside = np.flatnonzero(~inside_image(u, v, image_size))  # (landmarks are finite)
    if outside.size:
        k = outside[0]
        transposed = bool(np.all(inside_image(v, u, image_size)))
        hint = " (read as (row, column) every landmark is inside it: u is the column, v the row)" if transposed else ""
        raise PanomapError(
            f"landmark {landmarks.names[k]!r} at pixel ({u[k]:g}, {v[k]:g}) is outside the {width} x {height} image"
            + hint
        )


def rank_correlation(a: FloatArray, b: FloatArray) -> float:
    """Spearman's rank correlation of ``a`` and ``b`` (n,); NaN where either is constant (where SciPy
    would warn, and a warning would be printed before the error that explains it)."""
    if float(np.ptp(a)) == 0.0 or float(np.ptp(b)) == 0.0:
        return math.nan
    from scipy import stats  # here, not at the top: importing SciPy is slow

    return float(stats.spearmanr(a, b).statistic)


def _detect_axis(rho: FloatArray, r: FloatArray) -> str:
    """``"down"`` when the image radius grows with elevation, else ``"up"``."""
    correlation = rank_correlation(rho, r)
    if not np.isfinite(correlation) or abs(correlation) < 0.5:
        raise PanomapError(
            "cannot tell from the landmarks whether the camera looks down or up (image radius "
            f"and elevation are not monotonically related, Spearman {correlation:.2f}); "
            "check that world Z is up (a Y-up frame, as CAD tools and game engines use, needs Y and Z swapped), "
            "that the world points and the camera position share units and origin, the centre, "
            "or force the axis (--axis)"
        )
    return "down" if correlation > 0 else "up"


# Ways landmarks' pixels are given wrong that leave them monotonic in elevation once undone: (row, column)
# for (u, v), and an image scaled by these factors (a preview, a thumbnail).
PIXEL_SCALES = (2.0, 0.5, 4.0, 0.25)
# How monotonic (Spearman) the pixels must be once undone for the hint.
UNDONE_MONOTONIC = 0.9


def _pixels_hint(rho: FloatArray, pixels: FloatArray, centre: tuple[float, float], d: FloatArray) -> str:
    """Where the landmarks' image radii do not follow their elevations about ``centre``, but would with the
    world's Y up (rays ``d`` (n, 3) from the camera), or if their pixels were (row, column) or of an image
    scaled by one of PIXEL_SCALES: a sentence saying so ("" else)."""

    def monotonic(uv: FloatArray, elevation: FloatArray = rho) -> bool:
        r, _ = pixel_polar(uv, centre)
        correlation = rank_correlation(elevation, r)
        return bool(np.isfinite(correlation) and abs(correlation) >= UNDONE_MONOTONIC)

    if monotonic(pixels, np.arctan2(d[:, 1], np.hypot(d[:, 0], d[:, 2]))):
        return "; with Y as up they would be: a Y-up world frame needs its points (and the camera) as (x, -z, y)"
    if monotonic(pixels[:, ::-1]):
        return "; read as (row, column) they would be: give u as the column and v as the row"
    for scale in PIXEL_SCALES:
        if monotonic(pixels * scale):
            return (
                f"; times {scale:g} they would be: were they measured on a copy of the image "
                f"{'smaller' if scale > 1 else 'larger'} by {max(scale, 1 / scale):g} times? Give this image's pixels"
            )
    return ""


def _consistency(delta: FloatArray, weights: FloatArray) -> float:
    w = weights**2
    total = float(w.sum())
    if total <= 0:
        return 0.0
    return float(np.hypot(w @ np.cos(delta), w @ np.sin(delta)) / total)


def _handedness(theta: FloatArray, phi: FloatArray, r: FloatArray) -> int:
    """s = +1 or -1: the sign under which the landmarks agree best on one phi0 (weighted by r^2)."""
    if not np.any(r > 1e-9):
        raise PanomapError("no landmark away from the image centre to fix the azimuth")
    plus = _consistency(phi - theta, r)
    minus = _consistency(phi + theta, r)
    return 1 if plus >= minus else -1


# ----------------------------------------------------------------------------- the mount: tilt and position


@dataclass(frozen=True)
class _MountChoice:
    """The mounts tried, their cross-validation scores, and the one chosen (inliers, kind, selection, solution)."""

    chosen: tuple[FloatArray, RadialKind, dict[str, float], MountSolution]
    chosen_options: MountOptions
    scores: dict[str, float]


def _given_tilt(tilt: str | tuple[float, float]) -> tuple[float, float] | None:
    """The pair (tilt_deg, toward_deg) when ``tilt`` fixes it, None for ``"fit"`` or ``"none"``."""
    if isinstance(tilt, str):
        if tilt not in TILT_MODES:
            raise PanomapError(f"tilt must be 'fit', 'none' or a pair (tilt_deg, toward_deg), not {tilt!r}")
        return None
    try:
        tilt_deg, toward_deg = (float(x) for x in tilt)
    except (TypeError, ValueError):
        raise PanomapError(f"tilt must be 'fit', 'none' or a pair (tilt_deg, toward_deg), not {tilt!r}") from None
    if not (math.isfinite(tilt_deg) and math.isfinite(toward_deg) and 0 <= tilt_deg <= MAX_TILT_DEG):
        raise PanomapError(
            f"the tilt must be 0 to {MAX_TILT_DEG:g} deg and its azimuth finite, not {tilt_deg:g}, {toward_deg:g}"
        )
    return tilt_deg, toward_deg


def _mount_options(
    tilt: str | tuple[float, float], camera_sigma: float, refine_centre: bool, few: bool = True
) -> list[MountOptions]:
    """The mounts to try, simplest first: level with the position as given, then what may be refined.

    With the centre refined and ``few`` landmarks (exact leave-one-out), a tilt with the centre held where it
    was found comes second: near the nadir a tilt of the axis and a shift of the centre move the landmarks
    alike, so the level fit, free to shift its centre, stands in for a tilt (10-17 px off at the rim on
    simulated fisheyes tilted 1-3 deg); the two explanations have as many unknowns and are weighed as equals
    (:func:`_choose_mount`). With more landmarks the tilt with the centre refined too is found beyond chance
    (60 landmarks, 24 tilted trials: worst 3.11 px, median 1.3, where the centre held at a rim 2 px off the
    axis gives 2.1; 40 landmarks: 9.26 px without the twin, 4.70 with it).
    """
    tilts = [False, True] if tilt == "fit" else [False]
    positions = [False, True] if camera_sigma > 0 else [False]
    options = [MountOptions(centre=refine_centre, tilt=t, position=p) for p in positions for t in tilts]
    if refine_centre and tilt == "fit" and few:
        options.insert(1, MountOptions(tilt=True, at_rim=True))
    return options


def _choose_mount(
    problem: MountProblem,
    options: list[MountOptions],
    level: tuple[FloatArray, RadialKind, dict[str, float], MountSolution],
    data: _Data,
    candidates: tuple[RadialKind, ...],
    annulus: tuple[float, float] | None,
    robust: bool,
    level_covers: bool = True,
) -> _MountChoice:
    """Fit each mount (refined, then the model and outliers chosen again in its frame) and keep, in order
    of their unknowns, each that clearly beats the best so far on held-out errors (:func:`_clearly_better`).

    When the level fit does not cover the annulus (``level_covers`` False) it only starts the search: the
    simplest mount that does is the first best, and with none the fit fails (PanomapError).
    """
    fits: dict[MountOptions, tuple[FloatArray, RadialKind, dict[str, float], MountSolution]] = {options[0]: level}
    inliers, _, _, start = level
    # A screen before the costly part: a mount whose own fit does not lower the chi-square by more than
    # chance would (for its added unknowns) cannot win the cross-validation; it is not tried further.
    level_chi2 = _chi2(problem, start, inliers)
    screened = [options[0]]
    for option in options[1:]:
        try:
            trial = joint_fit(problem, _mount_start(problem, start, option), inliers, option)
        except PanomapError:
            continue
        if option.at_rim:
            # As many unknowns as the level fit with its centre, which fits the landmarks in the sample at
            # least as well by moving the centre: only held-out landmarks can tell the two apart.
            screened.append(option)
            continue
        added = 2 * option.tilt + 3 * option.position
        # The position refines a tilted mount only where the tilt alone passed (five unknowns on a dozen
        # landmarks pass by chance where two do not: a level camera was given a tilt and a shift).
        if option.tilt and option.position and replace(option, position=False) not in screened:
            continue
        if level_chi2 - _chi2(problem, trial, inliers, option) > CHI2_95[added]:
            screened.append(option)
    if not level_covers:
        screened = list(options)  # no screen: the level fit is no answer
    elif len(screened) == 1:
        return _MountChoice(level, options[0], {})
    for option in screened[1:]:
        # A mount with the position refined starts from the same mount with the position as given: the model
        # and outliers chosen there (a position shift of a few cm barely moves the rays; a tilt turns them all).
        simpler = replace(option, position=False)
        if option.position and simpler in fits:
            kept, kind, selection, base = fits[simpler]
            try:
                solution = joint_fit(replace(problem, kind=kind.name), base, kept, option)
            except PanomapError:
                continue
            if annulus is None or not _mount_misses_annulus(problem, solution, kept, annulus):
                fits[option] = (kept, kind, selection, solution)
            continue
        try:
            kept, kind, selection, solution = _choose_in_frame(
                problem,
                data,
                joint_fit(problem, _mount_start(problem, start, option), inliers, option),
                (inliers, None),
                option,
                candidates,
                annulus,
                robust,
            )
        except PanomapError:
            continue
        if annulus is not None and _mount_misses_annulus(problem, solution, kept, annulus):
            continue
        fits[option] = (kept, kind, selection, solution)
    if not level_covers:
        del fits[options[0]]
        if not fits:
            raise PanomapError("no radial model covers the annulus from these landmarks, level or tilted")
    elif len(fits) == 1:
        return _MountChoice(level, options[0], {})
    common = np.logical_and.reduce([fit[0] for fit in fits.values()])
    members = np.flatnonzero(common)
    folds = _folds(data, members)
    cap = MOUNT_SCORE_CAP_SIGMAS**2
    scores: dict[str, float] = {}
    squared: dict[MountOptions, FloatArray] = {}
    best = next(iter(fits))
    for option, (_, kind, _, solution) in fits.items():
        whitened, _ = held_out_errors(replace(problem, kind=kind.name), solution, common, folds, option)
        squared[option] = np.minimum(whitened**2, cap)
        scores[option.name] = float(np.sqrt(np.mean(squared[option])))
        if option is best:
            continue
        if option.at_rim:
            # A tilt about the centre as found against the level fit's shifted centre: as many unknowns, two
            # explanations of one pattern; the one that predicts the held-out landmarks better. (Asking the
            # tilt to be better by one standard error kept level cameras a little closer, p90 4.69 -> 3.91 px
            # on 40 simulated, but left three tilted ones at 8.8 px and one more view uncovered in 60.)
            if np.mean(squared[option]) < np.mean(squared[best]):
                best = option
        elif _clearly_better(squared[option], squared[best]):
            best = option
    return _MountChoice(fits[best], best, scores)


def _mount_start(problem: MountProblem, start: MountSolution, option: MountOptions) -> MountSolution:
    """Where a mount's fit starts: the level fit, with the centre put back where it was found for ``at_rim``."""
    if option.at_rim and problem.centre_found is not None:
        return replace(start, centre=problem.centre_found)
    return start


def _choose_in_frame(
    problem: MountProblem,
    data: _Data,
    solution: MountSolution,
    chosen: tuple[FloatArray, RadialKind | None],
    option: MountOptions,
    candidates: tuple[RadialKind, ...],
    annulus: tuple[float, float] | None,
    robust: bool,
) -> tuple[FloatArray, RadialKind, dict[str, float], MountSolution]:
    """The model and outliers chosen again in the frame of a mount's ``solution``, and the mount refined with them;
    repeated in the new frame until the choice holds (``MOUNT_ROUNDS`` at most).

    The first frame comes from the level choice's model, which a tilt may have led astray (a flexible
    polynomial absorbing part of the tilt): its tilt is then off, and so is the next choice made in it.
    """
    inliers, kind = chosen
    selection: dict[str, float] = {}
    for _ in range(MOUNT_ROUNDS):
        moved = _in_frame(problem, data, solution)
        kept, new_kind, selection = _choose(candidates, moved, annulus, robust)
        if new_kind is kind and np.array_equal(kept, inliers):
            break
        inliers, kind = kept, new_kind
        radial, phi0 = _fit(kind, moved, kept)
        again = MountSolution(radial, phi0, solution.centre, solution.w, solution.delta, solution.covariance)
        solution = joint_fit(replace(problem, kind=kind.name), again, kept, option)
    assert kind is not None
    if option.tilt and not option.position and len(candidates) > 1:
        kind, solution = _choose_jointly(problem, data, solution, inliers, kind, option, candidates, annulus)
    return inliers, kind, selection, solution


def _in_frame(problem: MountProblem, data: _Data, solution: MountSolution) -> _Data:
    """``data`` with the landmarks' rays, angles and world-noise sigmas in the frame of a mount's ``solution``."""
    rays = camera_rays(problem, solution.w, solution.delta)
    theta, rho = azimuth_elevation(rays)
    r, phi = pixel_polar(problem.pixels, solution.centre)
    distance = np.linalg.norm(rays, axis=1)
    return replace(
        data,
        theta=theta,
        rho=rho,
        r=r,
        phi=phi,
        sigma_rho=problem.world_sigma / distance,
        sigma_theta=problem.world_sigma / np.maximum(np.hypot(rays[:, 0], rays[:, 1]), 1e-12),
    )


def _choose_jointly(
    problem: MountProblem,
    data: _Data,
    solution: MountSolution,
    inliers: FloatArray,
    kind: RadialKind,
    option: MountOptions,
    candidates: tuple[RadialKind, ...],
    annulus: tuple[float, float] | None,
) -> tuple[RadialKind, MountSolution]:
    """The model chosen with the tilt fitted jointly with each candidate as simple as ``kind`` or simpler:
    held-out errors of each joint fit, the one-standard-error rule in the order of preference; and its mount.

    In one mount's frame a flexible model that absorbed part of the tilt holds its own choice (its tilt
    fits it best): on an equisolid fisheye tilted 1.3 deg, a two-term polynomial with a tilt of 1.0 deg
    beat the true odd3 in that frame, and 8.5 px against 1.5 px followed. Each candidate with its own
    tilt compares them on equal terms.
    """
    moved = _in_frame(problem, data, solution)
    members = np.flatnonzero(inliers)
    folds = _folds(data, members)
    cap = MOUNT_SCORE_CAP_SIGMAS**2
    fits: dict[str, tuple[RadialKind, MountSolution, FloatArray]] = {}
    # Only as simple a model as the frame's choice, or simpler: a more flexible one would win the joint
    # held-out score by chance as often (a mirror's law lost to a 3-term polynomial, 6.2 px against 2.8).
    simpler = candidates[: [candidate.name for candidate in candidates].index(kind.name) + 1]
    for candidate in simpler:
        count = int(inliers.sum())
        if count < max(candidate.needed_elevations + 2, LANDMARKS_PER_PARAMETER * candidate.parameter_count):
            continue
        if candidate is not kind and _acceptable(candidate, moved, inliers, annulus):
            continue
        try:
            if candidate is kind:
                joint = solution
            else:
                radial, phi0 = _fit(candidate, moved, inliers)
                start = MountSolution(radial, phi0, solution.centre, solution.w, solution.delta, solution.covariance)
                joint = joint_fit(replace(problem, kind=candidate.name), start, inliers, option)
            if annulus is not None and _mount_misses_annulus(
                replace(problem, kind=candidate.name), joint, inliers, annulus
            ):
                continue
            whitened, _ = held_out_errors(replace(problem, kind=candidate.name), joint, inliers, folds, option)
        except PanomapError:
            continue
        if np.all(np.isfinite(whitened)):
            fits[candidate.name] = (candidate, joint, np.minimum(whitened**2, cap))
    if kind.name not in fits or len(fits) == 1:
        return kind, solution
    best = min(fits, key=lambda name: float(np.mean(fits[name][2])))
    squared = fits[best][2]
    limit = float(np.mean(squared)) + float(np.std(squared, ddof=1)) / math.sqrt(squared.size)
    for candidate in simpler:  # in order of preference
        if candidate.name in fits and float(np.mean(fits[candidate.name][2])) <= limit + 1e-12:
            return fits[candidate.name][0], fits[candidate.name][1]
    return kind, solution


def _mount_misses_annulus(
    problem: MountProblem, solution: MountSolution, subset: FloatArray, annulus: tuple[float, float]
) -> bool:
    """Whether f_r under this mount fails to run across the annulus from the landmarks (as a table needs)."""
    _, rho = azimuth_elevation(camera_rays(problem, solution.w, solution.delta)[subset])
    landmark_range = (float(np.min(rho)), float(np.max(rho)))
    slack = rim_slack_px(problem.pixel_sigma)
    return annulus_coverage_problem(solution.radial, landmark_range, *annulus, slack_px=slack) is not None


def _choose_start(
    candidates: tuple[RadialKind, ...],
    data: _Data,
    annulus: tuple[float, float] | None,
    robust: bool,
    may_tilt: bool,
) -> tuple[FloatArray, RadialKind, dict[str, float], bool]:
    """:func:`_choose` with the annulus, and whether its choice covers it. Where no model covers it: the
    outliers found without the annulus dropped and the choice made again with it; failing that, where a tilt
    may be fitted, the choice without the annulus (a start for the tilt), flagged as not covering."""
    try:
        return (*_choose(candidates, data, annulus, robust), True)
    except PanomapError as exc:
        failed = exc
    loose = _choose(candidates, data, None, robust) if robust or may_tilt else None
    if loose is not None and robust and not loose[0].all():
        # An outlier (a landmark far off near the rim) can itself push every model off the annulus: found
        # without the annulus, it is dropped, and the choice made again with the annulus on the rest.
        try:
            return (*_choose(candidates, data, annulus, robust, start=loose[0]), True)
        except PanomapError:
            pass
    if not may_tilt or loose is None:
        raise failed
    return (*loose, False)


def _chi2(
    problem: MountProblem, solution: MountSolution, subset: FloatArray, options: MountOptions | None = None
) -> float:
    """Sum of squared whitened residuals over ``subset`` (bool, n), with the position's prior terms when refined."""
    radial_error, tangential_error, radial_sigma, tangential_sigma = residual_parts(
        problem, solution, np.flatnonzero(subset)
    )
    total = float(np.sum((radial_error / radial_sigma) ** 2 + (tangential_error / tangential_sigma) ** 2))
    if options is not None and options.position:
        total += float(np.sum((solution.delta / problem.camera_sigma) ** 2))
    return total if math.isfinite(total) else math.inf


def _clearly_better(errors: FloatArray, than: FloatArray) -> bool:
    """Whether held-out squared errors ``errors`` are smaller than ``than`` (same landmarks) beyond chance:
    the mean of the paired improvements exceeds ``MOUNT_SIGNIFICANCE`` standard errors of it."""
    gain = than - errors
    if gain.size < 3:
        return False
    mean = float(np.mean(gain))
    spread = float(np.std(gain, ddof=1)) / math.sqrt(gain.size)
    return mean > MOUNT_SIGNIFICANCE * spread and mean > 0


def _mount_report(
    problem: MountProblem,
    solution: MountSolution,
    tilt: str | tuple[float, float],
    choice: _MountChoice | None,
    model: CameraModel,
) -> MountReport:
    """The mount as fitted: tilt and its standard errors, the position and its shift, how they were chosen."""
    tilt_rad, toward_rad = model.tilt
    refined = choice.chosen_options if choice is not None else MountOptions()
    tilt_se = toward_se = None
    if refined.tilt and solution.covariance.shape[0] >= 2:
        tilt_se_rad, toward_se_rad = tilt_standard_errors(solution.w, solution.covariance[:2, :2])
        tilt_se, toward_se = math.degrees(tilt_se_rad), math.degrees(toward_se_rad)
        toward_se = toward_se if math.isfinite(toward_se) else None
    camera = solution.camera(problem)
    mode = "given" if not isinstance(tilt, str) else tilt
    if choice is None and mode == "fit":
        mode = "none"  # not tried: a model with the paper's vertical axis, or the paper's azimuth
    return MountReport(
        tilt_mode=mode,
        tilt_deg=math.degrees(tilt_rad),
        toward_deg=math.degrees(toward_rad),
        tilt_se_deg=tilt_se,
        toward_se_deg=toward_se,
        tilt_fitted=refined.tilt,
        camera_given=(float(problem.camera[0]), float(problem.camera[1]), float(problem.camera[2])),
        camera=(float(camera[0]), float(camera[1]), float(camera[2])),
        camera_sigma=problem.camera_sigma,
        position_refined=refined.position,
        chosen=refined.name,
        cross_validation={} if choice is None else dict(choice.scores),
    )
