"""Lines and landmarks in one refinement: the straight lines of an image join a landmark fit (beyond the paper).

Convention: as in :mod:`panomap.calibrate.refine` (landmark rays in the camera's axes, pixel radius r about the
centre, ``r = f_r(rho)``); a line's points in px.

A landmark fits f_r, the centre, phi0, the tilt and the position at once, and a few landmarks leave them
entangled: near the nadir a tilt of the axis and a shift of the centre move the landmarks alike, and five
landmarks hold a flexible f_r loosely. The straight lines of an image of the same camera fix f_r and the centre
on their own (:mod:`panomap.calibrate.lines`), but neither the azimuth, nor the tilt against the world's
vertical where no vertical edge shows, nor any distance. Together, in the one refinement of
:func:`panomap.calibrate.refine.refine`, each line is a residual block (:class:`LineBlock`): every point's
distance (px) from the image of its line's plane through the viewpoint, over that line's measured noise (so that
the lines' residuals are in standard deviations, as the landmarks' are). The plane of each line is solved in
closed form for every trial camera (variable projection, as the line fit does), so a block adds no unknowns of
its own to the refinement.

The steps (:func:`refine_with_lines`):

1. **Lines**: the line fit (:func:`panomap.calibrate.lines.fit.fit_lines`) on the image's edge arcs, with the
   landmarks' axis; it finds the straight lines, sets aside the curved arcs, and chooses the radial kind by
   cross-validation over lines (each line scored by a fit without its fold). Its kind is the joint fit's: the
   lines hold far more of f_r than a dozen landmarks do.
2. **Noise**: each line's sigma is its own RMS under the line fit, at least the edge noise of all lines
   (``LineFitReport.sigma_px``): a blurred or slightly bent edge counts less, none counts more than the rest.
3. **Kind and mount**: the lines' kind and, where it differs, the landmark fit's, each refined with the lines
   and the landmark fit's mount (its tilt and position as it chose them; the centre refined unless it was given
   and held); the one with the lower chi-square plus Akaike's penalty (2 per coefficient) is kept. Then, where
   the landmark fit took no tilt, the tilt is refined too and kept where the chi-square falls by more than
   chance would for two unknowns (:data:`panomap.calibrate.mount.CHI2_95`): with f_r and the centre held by
   the lines, a tilt no longer trades against a shift of the centre.
4. **Agreement**: where the landmarks' chi-square under the joint camera exceeds theirs under the landmark
   fit by more than chance would for the unknowns the lines take over (:data:`DISAGREE_QUANTILE`), the
   lines and the landmarks disagree (lines that are not straight in the world, landmarks measured in another
   frame): the landmark fit stands, with a note that says so. So it does where the line fit fails (too few
   lines) or the joint f_r does not cover the annulus.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from ..camera.radial_models import radial_kind
from ..errors import PanomapError
from ..geometry import FloatArray
from .circles import ImageCircles
from .lines.arcs import EdgeArc
from .lines.fit import LineFit, LineFitOptions, fit_lines
from .lines.objective import LineData, evaluate
from .lines.report import FittedLine, LineFitReport
from .mount import CHI2_95, _mount_misses_annulus
from .refine import LandmarkBlock, MountOptions, MountProblem, MountSolution, Refinement, refine

# Points per arc the joint refinement takes (evenly along it): half the line fit's, for speed (a refit of the learn
# page at every change of its landmarks), and since neighbouring edge points share their errors.
POINTS_PER_ARC = 50
# The lines disagree with the landmarks where the landmarks' chi-square rises, from the landmark fit to the
# joint one, beyond this quantile of a chi-square with as many degrees of freedom as the lines take over.
DISAGREE_QUANTILE = 0.999


@dataclass(frozen=True)
class ImageLines:
    """The edge arcs of an image of the camera, for a landmark fit to take its straight lines from.

    Attributes
    ----------
    arcs : sequence of EdgeArc
        Candidate arcs (:func:`panomap.calibrate.lines.arcs.find_arcs`), px.
    circles : ImageCircles
        The image circles the arcs were found in.
    """

    arcs: Sequence[EdgeArc]
    circles: ImageCircles
    _fits: dict[LineFitOptions, LineFit | PanomapError] = field(default_factory=dict, compare=False, repr=False)

    def line_fit(self, options: LineFitOptions) -> LineFit:
        """The line fit of these arcs with ``options`` (:func:`panomap.calibrate.lines.fit.fit_lines`), found once
        per options (a page that refits at every change of its landmarks fits the lines once).

        Raises
        ------
        PanomapError
            As the line fit does (too few lines, no two orthogonal families).
        """
        if options not in self._fits:
            try:
                self._fits[options] = fit_lines(self.arcs, self.circles, options)
            except PanomapError as exc:
                self._fits[options] = exc
        found = self._fits[options]
        if isinstance(found, PanomapError):
            raise PanomapError(found.detail)
        return found


@dataclass(frozen=True)
class JointLines:
    """What the lines brought to a landmark fit.

    Attributes
    ----------
    report : LineFitReport or None
        The lines that joined, each line's RMS (px) under the joint camera; None where none joined.
    note : str or None
        Why no line joined (the line fit failed, the lines disagree with the landmarks), None where they did.
    """

    report: LineFitReport | None
    note: str | None = None


class LineBlock:
    """The straight lines as one residual block of :func:`panomap.calibrate.refine.refine`; no unknowns.

    Parameters
    ----------
    lines : list of (k_i, 2) ndarray
        Each line's points, px.
    sigmas_px : (L,) ndarray
        Each line's noise, px.
    axis : {"down", "up"}
    r_max : float
        The radius (px) f_r must reach (beyond the farthest point).
    """

    unknowns = 0

    def __init__(self, lines: list[FloatArray], sigmas_px: FloatArray, axis: str, r_max: float) -> None:
        self.data = LineData.of(lines, r_max)
        self.axis = axis
        self.point_sigma = np.asarray(sigmas_px, dtype=np.float64)[self.data.line_index]

    def start(self) -> FloatArray:
        return np.empty(0)

    def distances_px(self, camera: MountSolution) -> FloatArray | None:
        """Each point's distance (px) from its line's plane image under ``camera``; None where f_r does not
        rise monotonically to the lines."""
        params = np.array([*camera.centre, *camera.radial.coefficients], dtype=np.float64)
        trial = evaluate(camera.radial.kind, self.axis, params, self.data)
        return None if trial is None else trial.distances_px

    def residuals(self, camera: MountSolution, own: FloatArray) -> FloatArray:
        distances = self.distances_px(camera)
        if distances is None:
            return np.full(self.data.pixels.shape[0], np.nan)
        return np.asarray(distances / self.point_sigma, dtype=np.float64)


def line_pixels(fit: LineFit, arcs: Sequence[EdgeArc]) -> list[FloatArray]:
    """Each line's points (px): its arcs' points, at most :data:`POINTS_PER_ARC` evenly along each."""
    out = []
    for line in fit.report.lines:
        pieces = []
        for k in line.arcs:
            pixels = np.asarray(arcs[k].pixels, dtype=np.float64)
            if len(pixels) > POINTS_PER_ARC:
                pixels = pixels[np.round(np.linspace(0, len(pixels) - 1, POINTS_PER_ARC)).astype(int)]
            pieces.append(pixels)
        out.append(np.concatenate(pieces))
    return out


def line_sigmas(report: LineFitReport) -> FloatArray:
    """Each line's noise (px): its RMS under the line fit, at least the edge noise of all the lines."""
    floor = max(report.sigma_px, 1e-3)
    return np.array([max(line.rms_px, floor) for line in report.lines], dtype=np.float64)


@dataclass(frozen=True)
class JointResult:
    """The joint refinement: the camera, the mount refined, the radial kind, and the lines' account."""

    solution: MountSolution
    options: MountOptions
    kind: str
    refinement: Refinement
    lines: JointLines


def landmark_chi2(problem: MountProblem, solution: MountSolution, subset: FloatArray, rays_move: bool) -> float:
    """The landmarks' (``subset``, bool) sum of squared whitened residuals under ``solution``."""
    block = LandmarkBlock(problem, solution, np.flatnonzero(subset), rays_move=rays_move)
    value = float(np.sum(block.residuals(solution, np.empty(0)) ** 2))
    return value if math.isfinite(value) else math.inf


def refine_with_lines(
    problem: MountProblem,
    landmark_solution: MountSolution,
    inliers: FloatArray,
    landmark_options: MountOptions,
    image: ImageLines,
    *,
    model: str,
    refine_centre: bool,
    tilt: bool,
    annulus: tuple[float, float] | None,
) -> JointResult | JointLines:
    """The camera refined on the landmarks (``inliers``, bool) and the straight lines of ``image`` together.

    ``landmark_solution`` (refined with ``landmark_options``) is the landmark fit's camera; ``model`` is the
    kind asked for (``"auto"``: the lines' cross-validated choice); ``refine_centre`` whether the centre is
    refined; ``tilt`` whether a tilt may be fitted. Returns a :class:`JointResult`, or a :class:`JointLines`
    with its note where the lines do not join (the landmark fit then stands).
    """
    if model != "auto" and radial_kind(model).centre_given:
        return JointLines(None, f"the {model} model takes the centre as given; no line joined the fit")
    try:
        line_fit = image.line_fit(LineFitOptions(axis=problem.axis, s=problem.s, model=model))
    except PanomapError as exc:
        return JointLines(None, f"no line joined the fit: {exc.detail}")
    lines = line_pixels(line_fit, image.arcs)
    reach = max(float(np.max(np.hypot(*(p - np.asarray(line_fit.model.centre)).T))) for p in lines)
    block = LineBlock(lines, line_sigmas(line_fit.report), problem.axis, reach * 1.02 + 2.0)
    centre = line_fit.model.centre if refine_centre else landmark_solution.centre
    # The lines' kind, from its own fit; and the landmarks' where it differs (and the choice is automatic).
    starts = [line_fit.model.radial]
    if model == "auto" and landmark_solution.radial.kind != starts[0].kind:
        if not radial_kind(landmark_solution.radial.kind).centre_given:
            starts.append(landmark_solution.radial)
    # The landmark fit's mount (its tilt and position as it chose them, the centre refined with the lines), for each
    # kind; then, for the kind kept, the tilt where the landmark fit did not take one: lines that fix f_r and the
    # centre let the landmarks show a tilt that a shift of the centre stood in for.
    mount = MountOptions(centre=refine_centre, tilt=tilt and landmark_options.tilt, position=landmark_options.position)
    tried: list[tuple[float, str, Refinement]] = []
    for radial in starts:
        start = MountSolution(
            radial, landmark_solution.phi0, centre, landmark_solution.w, landmark_solution.delta, np.empty((0, 0))
        )
        refinement = _refined(replace(problem, kind=radial.kind), start, inliers, block, mount)
        if refinement is not None:
            # Akaike's penalty: each coefficient more must lower the chi-square by 2.
            tried.append((_chi2(refinement) + 2 * len(radial.coefficients), radial.kind, refinement))
    if not tried:
        return JointLines(None, "no line joined the fit: the refinement with the lines did not converge")
    _, kind, refinement = min(tried, key=lambda t: t[0])
    chosen = mount
    if tilt and not mount.tilt:
        tilted = replace(mount, tilt=True)
        trial = _refined(replace(problem, kind=kind), refinement.solution, inliers, block, tilted)
        if trial is not None and _chi2(refinement) - _chi2(trial) > CHI2_95[2]:
            chosen, refinement = tilted, trial
    joint_problem = replace(problem, kind=kind)
    solution = refinement.solution
    note = _disagreement(problem, landmark_solution, landmark_options, joint_problem, solution, chosen, inliers)
    if note is not None:
        return JointLines(
            None,
            f"the {len(lines)} straight lines of the image disagree with the landmarks ({note}): "
            "no line joined the fit",
        )
    if annulus is not None and _mount_misses_annulus(joint_problem, solution, inliers, annulus):
        return JointLines(None, f"with the lines the {kind} model does not cover the annulus: no line joined the fit")
    return JointResult(solution, chosen, kind, refinement, JointLines(_joint_report(line_fit, block, solution)))


def _refined(
    problem: MountProblem, start: MountSolution, inliers: FloatArray, block: LineBlock, option: MountOptions
) -> Refinement | None:
    """The refinement of ``start`` with the lines' ``block`` and the mount ``option``; None where it fails."""
    begin = replace(
        start,
        w=start.w if option.tilt else np.zeros(2),
        delta=start.delta if option.position else np.zeros(3),
    )
    try:
        return refine(problem, begin, inliers, option, blocks=(block,), what="the refinement with the lines")
    except PanomapError:
        return None


def _disagreement(
    problem: MountProblem,
    landmark_solution: MountSolution,
    landmark_options: MountOptions,
    joint_problem: MountProblem,
    solution: MountSolution,
    chosen: MountOptions,
    inliers: FloatArray,
) -> str | None:
    """Why the lines disagree with the landmarks (None where they agree): the landmarks' chi-square rises, from
    the landmark fit to the joint one, beyond :data:`DISAGREE_QUANTILE` of chance for the unknowns the lines take
    over (f_r's coefficients and the centre), measured in their assumed noise (a chi-square test) or in their own
    scatter about the landmark fit (an F test, where they have 3 degrees of freedom or more: landmarks far more
    precise than assumed, exact ones in the limit, are not moved by lines that miss them by a pixel)."""
    from scipy import stats  # here, not at the top: importing SciPy is slow

    before = landmark_chi2(problem, landmark_solution, inliers, landmark_options.tilt or landmark_options.position)
    after = landmark_chi2(joint_problem, solution, inliers, chosen.tilt or chosen.position)
    taken_over = len(solution.radial.coefficients) + 2 * chosen.centre
    rise = after - before
    if rise > float(stats.chi2.ppf(DISAGREE_QUANTILE, taken_over)):
        return f"their chi-square rises from {before:.1f} to {after:.1f} with the lines"
    unknowns = len(landmark_solution.radial.coefficients) + 1 + 2 * landmark_options.centre
    unknowns += 2 * landmark_options.tilt + 3 * landmark_options.position
    dof = 2 * int(np.count_nonzero(inliers)) - unknowns
    if dof >= 3 and rise > 0:
        ratio = (rise / taken_over) / max(before / dof, 1e-12)
        if ratio > float(stats.f.ppf(DISAGREE_QUANTILE, taken_over, dof)):
            rms_before, rms_after = (math.sqrt(x / (2 * np.count_nonzero(inliers))) for x in (before, after))
            times = f"{ratio:.0f} times" if ratio < 1000 else "over 1000 times"
            return (
                f"their whitened RMS rises from {rms_before:.2f} to {rms_after:.2f} with the lines, "
                f"{times} their own scatter"
            )
    return None


def _chi2(refinement: Refinement) -> float:
    return float(refinement.residuals @ refinement.residuals)


def _joint_report(line_fit: LineFit, block: LineBlock, solution: MountSolution) -> LineFitReport:
    """The line fit's report with each line's RMS and largest distance (px) under the joint camera."""
    distances = block.distances_px(solution)
    report = line_fit.report
    if distances is None:
        return report
    index = block.data.line_index
    count = block.data.count
    points = np.maximum(np.bincount(index, minlength=count), 1)
    rms = np.sqrt(np.bincount(index, distances**2, minlength=count) / points)
    worst = np.zeros(count)
    np.maximum.at(worst, index, np.abs(distances))
    lines = tuple(
        FittedLine(
            line.arcs,
            line.image_index,
            int(np.sum(index == k)),
            float(rms[k]),
            float(worst[k]),
            line.family,
            line.elevation_deg,
        )
        for k, line in enumerate(report.lines)
    )
    return replace(report, lines=lines)
