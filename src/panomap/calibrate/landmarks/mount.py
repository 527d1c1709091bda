"""How the camera is mounted: its tilt and its position, chosen and refined with the radial model (beyond the
paper).

Convention: as in :mod:`panomap.calibrate.core.refine`.

The paper takes the camera's axis as exactly vertical and its position O_m as exact. A real mount is a
degree or three off the vertical, and O_m is measured with a tape. Each mount (level, tilted, position
refined, both; with the centre held where it was found as a twin of the level fit) is refined
(:func:`panomap.calibrate.core.refine.refine`), the model and outliers chosen again in its frame, and kept
where its held-out errors (:func:`panomap.calibrate.core.selection.held_out_errors`) clearly beat the simpler
mounts'.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ...camera.model import CameraModel
from ...camera.orientation import rotation_of_orientation
from ...camera.radial_models import RadialKind
from ...camera.valid_range import annulus_coverage_problem
from ...errors import PanomapError
from ...geometry import FloatArray, azimuth_elevation, pixel_polar
from ..core.noise import Observations, rim_slack_px, world_sigmas
from ..core.refine import MountOptions, MountProblem, MountSolution, camera_rays, joint_fit, residual_parts
from ..core.report import MountReport, tilt_standard_errors
from ..core.selection import LANDMARKS_PER_PARAMETER, acceptable, held_out_errors, held_out_folds
from ..core.start import separable_fit
from .outliers import choose

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
class MountChoice:
    """The mounts tried, their cross-validation scores, and the one chosen (inliers, kind, selection, solution)."""

    chosen: tuple[FloatArray, RadialKind, dict[str, float], MountSolution]
    chosen_options: MountOptions
    scores: dict[str, float]


def given_tilt(tilt: str | tuple[float, float]) -> tuple[float, float] | None:
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


def orientation_rotation(
    tilt_given: tuple[float, float] | None, orientation_deg: tuple[float, float, float] | None, axis: str | None
) -> FloatArray | None:
    """R (3, 3), camera to world, of the orientation given (the model looking down in its own axes; with
    phi0 = 0 both handednesses give the same R, so the handedness is found after), or None."""
    if orientation_deg is None:
        return None
    if tilt_given is not None or axis is not None:
        raise PanomapError("give the camera's orientation, or its axis and tilt, not both")
    try:
        values = tuple(float(x) for x in orientation_deg)
    except (TypeError, ValueError):
        raise PanomapError("the orientation must be three numbers (yaw, pitch, roll) deg") from None
    if len(values) != 3 or not all(math.isfinite(x) for x in values) or abs(values[1]) > 90:
        raise PanomapError(f"the orientation must be (yaw, pitch, roll) deg with the pitch in -90..90, not {values}")
    yaw, pitch, roll = (math.radians(x) for x in values)
    return rotation_of_orientation(yaw, pitch, roll, "down", -1, 0.0)


def mount_options(
    tilt: str | tuple[float, float], camera_sigma: float, refine_centre: bool, few: bool = True
) -> list[MountOptions]:
    """The mounts to try, simplest first: level with the position as given, then what may be refined.

    With the centre refined and ``few`` landmarks (exact leave-one-out), a tilt with the centre held where it
    was found comes second: near the nadir a tilt of the axis and a shift of the centre move the landmarks
    alike, so the level fit, free to shift its centre, stands in for a tilt (10-17 px off at the rim on
    simulated fisheyes tilted 1-3 deg); the two explanations have as many unknowns and are weighed as equals
    (:func:`choose_mount`). With more landmarks the tilt with the centre refined too is found beyond chance
    (60 landmarks, 24 tilted trials: worst 3.11 px, median 1.3, where the centre held at a rim 2 px off the
    axis gives 2.1; 40 landmarks: 9.26 px without the twin, 4.70 with it).
    """
    tilts = [False, True] if tilt == "fit" else [False]
    positions = [False, True] if camera_sigma > 0 else [False]
    options = [MountOptions(centre=refine_centre, tilt=t, position=p) for p in positions for t in tilts]
    if refine_centre and tilt == "fit" and few:
        options.insert(1, MountOptions(tilt=True, at_rim=True))
    return options


def choose_mount(
    problem: MountProblem,
    options: list[MountOptions],
    level: tuple[FloatArray, RadialKind, dict[str, float], MountSolution],
    data: Observations,
    candidates: tuple[RadialKind, ...],
    annulus: tuple[float, float] | None,
    robust: bool,
    level_covers: bool = True,
) -> MountChoice:
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
        return MountChoice(level, options[0], {})
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
        return MountChoice(level, options[0], {})
    common = np.logical_and.reduce([fit[0] for fit in fits.values()])
    members = np.flatnonzero(common)
    folds = held_out_folds(data, members)
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
    return MountChoice(fits[best], best, scores)


def _mount_start(problem: MountProblem, start: MountSolution, option: MountOptions) -> MountSolution:
    """Where a mount's fit starts: the level fit, with the centre put back where it was found for ``at_rim``."""
    if option.at_rim and problem.centre_found is not None:
        return replace(start, centre=problem.centre_found)
    return start


def _choose_in_frame(
    problem: MountProblem,
    data: Observations,
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
        kept, new_kind, selection = choose(candidates, moved, annulus, robust)
        if new_kind is kind and np.array_equal(kept, inliers):
            break
        inliers, kind = kept, new_kind
        radial, phi0 = separable_fit(kind, moved, kept)
        again = MountSolution(radial, phi0, solution.centre, solution.w, solution.delta, solution.covariance)
        solution = joint_fit(replace(problem, kind=kind.name), again, kept, option)
    assert kind is not None
    if option.tilt and not option.position and len(candidates) > 1:
        kind, solution = _choose_jointly(problem, data, solution, inliers, kind, option, candidates, annulus)
    return inliers, kind, selection, solution


def _in_frame(problem: MountProblem, data: Observations, solution: MountSolution) -> Observations:
    """``data`` with the landmarks' rays, angles and world-noise sigmas in the frame of a mount's ``solution``."""
    rays = camera_rays(problem, solution.w, solution.delta)
    theta, rho = azimuth_elevation(rays)
    r, phi = pixel_polar(problem.pixels, solution.centre)
    sigma_rho, sigma_theta = world_sigmas(rays, problem.world_sigma)
    return replace(data, theta=theta, rho=rho, r=r, phi=phi, sigma_rho=sigma_rho, sigma_theta=sigma_theta)


def _choose_jointly(
    problem: MountProblem,
    data: Observations,
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
    folds = held_out_folds(data, members)
    cap = MOUNT_SCORE_CAP_SIGMAS**2
    fits: dict[str, tuple[RadialKind, MountSolution, FloatArray]] = {}
    # Only as simple a model as the frame's choice, or simpler: a more flexible one would win the joint
    # held-out score by chance as often (a mirror's law lost to a 3-term polynomial, 6.2 px against 2.8).
    simpler = candidates[: [candidate.name for candidate in candidates].index(kind.name) + 1]
    for candidate in simpler:
        count = int(inliers.sum())
        if count < max(candidate.needed_elevations + 2, LANDMARKS_PER_PARAMETER * candidate.parameter_count):
            continue
        if candidate is not kind and acceptable(candidate, moved, inliers, annulus):
            continue
        try:
            if candidate is kind:
                joint = solution
            else:
                radial, phi0 = separable_fit(candidate, moved, inliers)
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


def _chi2(
    problem: MountProblem, solution: MountSolution, subset: FloatArray, options: MountOptions | None = None
) -> float:
    """Sum of squared whitened residuals over ``subset`` (bool, n), with the position's prior terms when refined."""
    radial_error, tangential_error = residual_parts(problem, solution, np.flatnonzero(subset)).whitened
    total = float(np.sum(radial_error**2 + tangential_error**2))
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


def mount_report(
    problem: MountProblem,
    solution: MountSolution,
    tilt: str | tuple[float, float],
    choice: MountChoice | None,
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
