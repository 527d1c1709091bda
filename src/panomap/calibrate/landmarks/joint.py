"""Lines and landmarks in one refinement: the straight lines of an image join a landmark fit (beyond the paper).

Convention: as in :mod:`panomap.calibrate.core.refine` (landmark rays in the camera's axes, pixel radius r about the
centre, ``r = f_r(rho)``); a line's points in px.

A landmark fits f_r, the centre, phi0, the tilt and the position at once, and a few landmarks leave them
entangled: near the nadir a tilt of the axis and a shift of the centre move the landmarks alike, and five
landmarks hold a flexible f_r loosely. The straight lines of an image of the same camera fix f_r and the centre
on their own (:mod:`panomap.calibrate.lines`), but neither the azimuth, nor the tilt against the world's
vertical where no vertical edge shows, nor any distance. Together, in the one refinement of
:func:`panomap.calibrate.core.refine.refine`, each line is a residual block (:class:`LineBlock`): every point's
distance (px) from the image of its line's plane through the viewpoint, over that line's measured noise (so that
the lines' residuals are in standard deviations, as the landmarks' are). The plane of each line is solved in
closed form for every trial camera (variable projection, as the line fit does), so a block adds no unknowns of
its own to the refinement.

The steps (:func:`refine_with_lines`):

1. **Lines**: the line fit (:func:`panomap.calibrate.lines.fit.fit_lines`) on the image's edge arcs, with the
   landmarks' axis; it finds the straight lines, sets aside the curved arcs, finds the families of parallel
   lines, and chooses the radial kind by cross-validation over lines (each line scored by a fit without its
   fold).
2. **Noise**: each line's sigma is its own RMS under the line fit, at least the edge noise of all lines
   (``LineFitReport.sigma_px``): a blurred or slightly bent edge counts less, none counts more than the rest.
3. **Vertical edges**: the lines of the family the line fit took for the world's vertical have their planes
   solved through the world's vertical as the camera being tried places it (:class:`VerticalLines`): they
   measure the tilt, as they do in a fit from lines alone.
4. **Kind and mount**: the lines' kind and, where it differs, the landmark fit's, each refined with the lines
   and the landmark fit's mount (its tilt and position as it chose them, the tilt also where vertical edges
   show; the centre refined unless it was given and held); the one with the lower chi-square plus Akaike's
   penalty (2 per coefficient) is kept. Then, where no tilt was refined, the tilt is tried and kept where the
   chi-square falls by more than chance would for two unknowns (:data:`panomap.calibrate.landmarks.mount.CHI2_95`):
   with f_r and the centre held by the lines, a tilt no longer trades against a shift of the centre.
5. **Agreement**: the lines join only where they agree with the landmarks (:func:`_disagreement`: the
   landmarks' chi-square, from the landmark fit to the joint one, rises by no more than chance would for
   the unknowns the lines take over, in their assumed noise and in their own scatter) and predict them no
   worse than the landmarks alone do (:func:`_held_out`), and where the joint f_r stays monotonic over the
   view and covers the annulus. Otherwise, or where the line fit fails (too few lines), the landmark fit
   stands, with a note that says why.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass, field, replace
from typing import TypeVar

import numpy as np
from numpy.typing import NDArray

from ...camera.orientation import rotation_from_vector
from ...camera.radial_models import radial_kind
from ...camera.valid_range import is_monotonic
from ...errors import PanomapError
from ...geometry import FloatArray, azimuth_elevation
from ..boards.choice import LearnedCamera, learn_camera
from ..boards.detect import Board
from ..boards.off_board import on_boards
from ..circles import ImageCircles
from ..core.line_report import FittedLine, LineFitReport
from ..core.refine import (
    LandmarkBlock,
    MountOptions,
    MountProblem,
    MountSolution,
    Refinement,
    camera_rays,
    refine,
    residual_parts,
)
from ..lines.arcs import EdgeArc
from ..lines.families import FAMILY_MIN_LINES, common_direction
from ..lines.fit import LineFit, LineFitOptions, fit_lines
from ..lines.objective import LineData, evaluate
from ..lines.rays import InverseRadial, PixelRays, best_planes, pixel_rays, plane_distances_px
from ..lines.vertical import VERTICAL_WITHIN_DEG
from .mount import CHI2_95, MOUNT_SCORE_CAP_SIGMAS, _mount_misses_annulus

T = TypeVar("T")

# Points per arc the joint refinement takes (evenly along it): half the line fit's, for speed (a refit of the learn
# page at every change of its landmarks), and since neighbouring edge points share their errors.
POINTS_PER_ARC = 50
# The lines disagree with the landmarks where the landmarks' chi-square rises, from the landmark fit to the
# joint one, beyond this quantile of a chi-square with as many degrees of freedom as the lines take over.
DISAGREE_QUANTILE = 0.999
# The landmarks are left out one at a time up to this many, else in this many folds, to ask whether the lines
# predict them better than the landmarks alone do.
HELD_OUT_FOLDS = 10


@dataclass(frozen=True)
class ImageLines:
    """The edge arcs of an image of the camera, for a landmark fit to take its straight lines from.

    Attributes
    ----------
    arcs : sequence of EdgeArc
        Candidate arcs (:func:`panomap.calibrate.lines.arcs.find_arcs`), px.
    circles : ImageCircles
        The image circles the arcs were found in.
    boards : sequence of Board
        The checkerboards of the image (:func:`panomap.calibrate.boards.detect.find_boards`), where looked for.
    """

    arcs: Sequence[EdgeArc]
    circles: ImageCircles
    boards: Sequence[Board] = ()
    _fits: dict[LineFitOptions, LineFit | PanomapError] = field(default_factory=dict, compare=False, repr=False)
    _learned: dict[LineFitOptions, LearnedCamera | PanomapError] = field(
        default_factory=dict, compare=False, repr=False
    )

    def learned(self, options: LineFitOptions) -> LearnedCamera:
        """The camera as ``panomap fit --image`` learns it from this image (its checkerboards and its lines,
        :func:`panomap.calibrate.boards.choice.learn_camera`), found once per options.

        Raises
        ------
        PanomapError
            As the line fit does, where the boards give no camera either.
        """
        return _once(self._learned, options, lambda: learn_camera(self.boards, self.arcs, self.circles, options))

    def line_fit(self, options: LineFitOptions) -> LineFit:
        """The line fit of these arcs with ``options`` (:func:`panomap.calibrate.lines.fit.fit_lines`), found once
        per options (a page that refits at every change of its landmarks fits the lines once).

        Raises
        ------
        PanomapError
            As the line fit does (too few lines, no two orthogonal families).
        """
        on_board = on_boards(self.arcs, self.boards)  # a board's rows run any way it is held: no vertical
        return _once(self._fits, options, lambda: fit_lines(self.arcs, self.circles, options, on_board=on_board))


def _once(cache: dict[LineFitOptions, T | PanomapError], options: LineFitOptions, make: Callable[[], T]) -> T:
    """``make()``'s result (or its error, raised again) for ``options``, made once and kept in ``cache``."""
    if options not in cache:
        try:
            cache[options] = make()
        except PanomapError as exc:
            cache[options] = exc
    found = cache[options]
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
    warns : bool
        Whether ``note`` is a warning (False: the lines agree with the landmarks within their stated noise, but
        the landmarks alone fit far more tightly than that, as exact ones do: leaving the lines out is right).
    """

    report: LineFitReport | None
    note: str | None = None
    warns: bool = True


@dataclass(frozen=True)
class VerticalLines:
    """Which lines are the world's vertical edges, and what places the world's vertical in the camera's rays.

    Attributes
    ----------
    members : (L,) bool
        True for the lines of the vertical family.
    s : {+1, -1}
        The handedness.
    rotation : (3, 3) ndarray or None
        A rotation given by the user (camera to world), applied before the tilt ``w``.
    """

    members: NDArray[np.bool_]
    s: int
    rotation: FloatArray | None


class LineBlock:
    """The straight lines as one residual block of :func:`panomap.calibrate.core.refine.refine`; no unknowns.

    Each line's plane is the one its rays lie closest to; a vertical edge's (``vertical``) is the closest that
    holds the world's vertical as the camera being tried places it (its tilt ``w``, phi0 and ``s``), so that the
    vertical edges measure the tilt, as they do in a fit from lines alone.

    Parameters
    ----------
    lines : list of (k_i, 2) ndarray
        Each line's points, px.
    sigmas_px : (L,) ndarray
        Each line's noise, px.
    axis : {"down", "up"}
    r_max : float
        The radius (px) f_r must reach (beyond the farthest point).
    vertical : VerticalLines, optional
        The vertical edges among the lines.
    """

    unknowns = 0

    def __init__(
        self,
        lines: list[FloatArray],
        sigmas_px: FloatArray,
        axis: str,
        r_max: float,
        vertical: VerticalLines | None = None,
    ) -> None:
        self.data = LineData.of(lines, r_max)
        self.axis = axis
        self.point_sigma = np.asarray(sigmas_px, dtype=np.float64)[self.data.line_index]
        self.vertical = vertical if vertical is not None and vertical.members.any() else None

    def start(self) -> FloatArray:
        return np.empty(0)

    def distances_px(self, camera: MountSolution) -> FloatArray | None:
        """Each point's distance (px) from its line's plane image under ``camera``; None where f_r does not
        rise monotonically to the lines."""
        try:
            inverse = InverseRadial.of(camera.radial, self.data.r_max)
        except PanomapError:
            return None
        rays = pixel_rays(self.data.pixels, camera.centre, inverse)
        normals = best_planes(rays, self.data.line_index, self.data.count)
        if self.vertical is not None:
            up = self.world_vertical(camera)
            held = planes_holding(rays, self.data.line_index, self.data.count, up)
            normals[self.vertical.members] = held[self.vertical.members]
        return plane_distances_px(normals[self.data.line_index], rays)

    def world_vertical(self, camera: MountSolution) -> FloatArray:
        """The world's vertical (3,) in the rays' axes (:mod:`panomap.calibrate.lines.rays`) under ``camera``."""
        assert self.vertical is not None
        rotation = np.eye(3) if not np.any(camera.w) else rotation_from_vector([camera.w[0], camera.w[1], 0.0])
        if self.vertical.rotation is not None:
            rotation = self.vertical.rotation @ rotation
        up = rotation.T @ np.array([0.0, 0.0, 1.0])  # in the camera's axes (theta, rho)
        # The rays' axes: the image angle phi = s theta + phi0 as azimuth, alpha from the pole the centre sees.
        up = up * np.array([1.0, self.vertical.s, -1.0 if self.axis == "down" else 1.0])
        c, s = math.cos(camera.phi0), math.sin(camera.phi0)
        return np.array([c * up[0] - s * up[1], s * up[0] + c * up[1], up[2]])

    def residuals(self, camera: MountSolution, own: FloatArray) -> FloatArray:
        distances = self.distances_px(camera)
        if distances is None:
            return np.full(self.data.pixels.shape[0], np.nan)
        return np.asarray(distances / self.point_sigma, dtype=np.float64)


def planes_holding(rays: PixelRays, line_index: NDArray[np.intp], count: int, up: FloatArray) -> FloatArray:
    """Unit normals (count, 3) of the planes through the viewpoint that hold the direction ``up`` (3,) and that
    each line's rays lie closest to (weighted as :func:`panomap.calibrate.lines.rays.best_planes` weighs them)."""
    scale = 1.0 / np.maximum(np.hypot(rays.alpha_per_px, rays.phi_per_px), 1e-12)
    weighted = rays.d * scale[:, None]
    up = up / np.linalg.norm(up)
    e1 = np.cross(up, [1.0, 0.0, 0.0] if abs(up[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(up, e1)
    a, b = weighted @ e1, weighted @ e2
    saa = np.bincount(line_index, a * a, minlength=count)
    sab = np.bincount(line_index, a * b, minlength=count)
    sbb = np.bincount(line_index, b * b, minlength=count)
    # The normal is the direction of least spread of the rays in the plane across ``up``: the minor axis.
    t = 0.5 * np.arctan2(2.0 * sab, saa - sbb) + 0.5 * math.pi
    return np.asarray(np.cos(t)[:, None] * e1 + np.sin(t)[:, None] * e2, dtype=np.float64)


def vertical_members(fit: LineFit, block_data: LineData, on_board: Collection[int] = ()) -> NDArray[np.bool_]:
    """The lines (L,) of the family that the line fit took for the world's vertical (the most populated within
    ``VERTICAL_WITHIN_DEG`` of the axis, lines all of whose arcs are ``on_board`` left out, as the fit leaves them:
    :mod:`panomap.calibrate.lines.vertical`); none where it found none."""
    members = np.zeros(block_data.count, dtype=bool)
    if not fit.report.vertical_lines:
        return members
    params = np.array([*fit.model.centre, *fit.model.radial.coefficients], dtype=np.float64)
    trial = evaluate(fit.model.radial.kind, fit.model.radial.axis, params, block_data)
    if trial is None:
        return members
    families = {line.family for line in fit.report.lines if line.family is not None}
    best: NDArray[np.bool_] | None = None
    for family in families:
        mask = np.array([line.family == family and not set(line.arcs) <= set(on_board) for line in fit.report.lines])
        if mask.sum() < FAMILY_MIN_LINES:
            continue
        direction = common_direction(trial.normals[mask])
        near_axis = abs(direction[2]) > math.cos(math.radians(VERTICAL_WITHIN_DEG))
        if near_axis and (best is None or mask.sum() > best.sum()):
            best = mask
    return members if best is None else best


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
    r_max = reach * 1.02 + 2.0
    # The vertical edges hold the world's vertical: they measure the tilt beside the landmarks.
    vertical = None
    if tilt:
        members = vertical_members(line_fit, LineData.of(lines, r_max), on_boards(image.arcs, image.boards))
        vertical = VerticalLines(members, problem.s, problem.rotation)
    block = LineBlock(lines, line_sigmas(line_fit.report), problem.axis, r_max, vertical)
    centre = line_fit.model.centre if refine_centre else landmark_solution.centre
    # The lines' kind, from its own fit; and the landmarks' where it differs (and the choice is automatic).
    starts = [line_fit.model.radial]
    if model == "auto" and landmark_solution.radial.kind != starts[0].kind:
        if not radial_kind(landmark_solution.radial.kind).centre_given:
            starts.append(landmark_solution.radial)
    # The landmark fit's mount (its tilt and position as it chose them, the centre refined with the lines), for each
    # kind; then, for the kind kept, the tilt where the landmark fit did not take one: lines that fix f_r and the
    # centre let the landmarks show a tilt that a shift of the centre stood in for.
    mount = MountOptions(
        centre=refine_centre, tilt=tilt and (landmark_options.tilt or block.vertical is not None),
        position=landmark_options.position,
    )  # fmt: skip
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
    disagreement = _disagreement(problem, landmark_solution, landmark_options, joint_problem, solution, chosen, inliers)
    if disagreement is not None:
        note, tighter = disagreement
        if tighter:  # (the figures in ``note`` are the detail; the line says what was done and why)
            return JointLines(
                None,
                f"the landmarks fit alone: the image's {len(lines)} straight lines agree with them within their "
                "stated noise, but they fit far more tightly without the lines",
                warns=False,
            )
        return JointLines(
            None,
            f"the {len(lines)} straight lines of the image disagree with the landmarks ({note}): "
            "no line joined the fit",
        )
    if not _monotonic(joint_problem, solution, inliers, line_fit.report.elevation_range_deg):
        return JointLines(None, f"with the lines the {kind} model folds over the view: no line joined the fit")
    if annulus is not None and _mount_misses_annulus(joint_problem, solution, inliers, annulus):
        return JointLines(None, f"with the lines the {kind} model does not cover the annulus: no line joined the fit")
    landmark_problem = replace(problem, kind=landmark_solution.radial.kind)
    alone = _held_out(landmark_problem, landmark_solution, inliers, landmark_options, ())
    joined = _held_out(joint_problem, solution, inliers, chosen, (block,))
    if joined > alone:
        return JointLines(
            None,
            f"the {len(lines)} straight lines of the image predict the landmarks worse than the landmarks do alone "
            f"(held-out RMS {joined:.2f} against {alone:.2f} standard deviations): no line joined the fit",
        )
    return JointResult(solution, chosen, kind, refinement, JointLines(_joint_report(line_fit, block, solution)))


def _monotonic(
    problem: MountProblem, solution: MountSolution, inliers: FloatArray, lines_deg: tuple[float, float]
) -> bool:
    """Whether f_r rises monotonically (and finitely) over the landmarks' and the lines' elevations."""
    _, rho = azimuth_elevation(camera_rays(problem, solution.w, solution.delta)[inliers])
    low = min(float(np.min(rho)), math.radians(lines_deg[0]))
    high = max(float(np.max(rho)), math.radians(lines_deg[1]))
    grid = np.linspace(low, high, 200)
    return bool(is_monotonic(solution.radial, low, high) and np.all(np.isfinite(solution.radial(grid))))


def _held_out(
    problem: MountProblem,
    solution: MountSolution,
    inliers: FloatArray,
    option: MountOptions,
    blocks: tuple[LineBlock, ...],
) -> float:
    """The RMS (in standard deviations, each capped at ``MOUNT_SCORE_CAP_SIGMAS``) of the landmarks' errors under
    fits made without them (with ``blocks``): one left out at a time, or ``HELD_OUT_FOLDS`` folds dealt in
    elevation order; each fit starts from ``solution``. A fold whose fit fails counts as the cap."""
    members = np.flatnonzero(inliers)
    if members.size <= HELD_OUT_FOLDS:
        folds = [np.array([k]) for k in range(members.size)]
    else:
        _, rho = azimuth_elevation(camera_rays(problem, solution.w, solution.delta)[members])
        order = np.argsort(rho, kind="stable")
        folds = [order[k::HELD_OUT_FOLDS] for k in range(HELD_OUT_FOLDS)]
    cap = MOUNT_SCORE_CAP_SIGMAS**2
    squared = np.full(members.size, cap)
    for positions in folds:
        others = inliers.copy()
        others[members[positions]] = False
        try:
            fold = refine(problem, solution, others, option, blocks=blocks, what="a held-out fit").solution
        except PanomapError:
            continue
        errors = residual_parts(problem, fold, members[positions]).whitened_norm
        squared[positions] = np.minimum(np.where(np.isfinite(errors), errors**2, cap), cap)
    return math.sqrt(float(np.mean(squared)))


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
) -> tuple[str, bool] | None:
    """Why the lines disagree with the landmarks, and whether only with the landmarks' own scatter (True: within
    their assumed noise), or None where they agree: the landmarks' chi-square rises, from
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
        return f"their chi-square rises from {before:.1f} to {after:.1f} with the lines", False
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
            ), True
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
