"""The fit of a camera from the straight lines in its images.

Convention: pixels (u, v) px; rays in the camera's axes as in :mod:`.rays`; the camera model as in
:class:`panomap.camera.model.CameraModel`.

The method: the paper's landmark learning with the landmarks replaced by lines. Each candidate
arc's pixels must map to rays in one plane through the viewpoint. Starting from an equidistant
camera about the circle's centre at the scale the orthogonal families like best, the fit
alternates between the model and the grouping: arcs whose rays leave their plane by more than the
noise allows under the current camera are set aside (curved objects, arcs across a corner), pieces
of one line (planes that coincide) are merged, families of parallel lines are found, and the
centre and a flexible radial model are refitted to the lines kept, with the orthogonality of each
image's families. The radial kind is then chosen by cross-validation over lines (each line scored
by a fit without its fold) and refitted on all of them. The tilt follows from the vertical family.

What lines cannot know: the azimuth origin, the handedness and every distance; they are set by
the caller (:class:`LineFitOptions`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ...camera.model import CameraModel
from ...camera.radial import RadialFunction, fit_radial
from ...camera.radial_models import AUTO_CANDIDATES, MIRROR_CANDIDATES, radial_kind, rho_of_alpha
from ...camera.valid_range import valid_elevation_range
from ...errors import PanomapError, refusal
from ...geometry import FloatArray
from ..circles import ImageCircles
from ..core.line_report import FittedLine, LineFitReport, RejectedArc, empty_bands
from .agreement import Camera, PinnedBand, pinned_band, ring_alphas, ruled_out
from .angles import annulus_deg, default_handedness
from .arcs import EdgeArc
from .families import Family, common_direction, find_families, orthogonal_pairs
from .objective import LineData, evaluate, orthogonality_residuals, residuals
from .orientation import level_rotation, zero_azimuth
from .rays import InverseRadial
from .refusals import no_right_angles, not_straight, too_few
from .stretch import FLAT_BOARD_DEG, StretchRange, stretch_range, stretched_normals
from .vertical import vertical_family

# Fewest lines a fit needs, and fewest of them with a family orthogonal to another (the scale).
MIN_LINES = 8
# Points per arc used in the fit (evenly along it): enough for its curvature, few for speed.
POINTS_PER_ARC = 100
# With many arcs (images pooled), fewer points per arc, down to this many, keep about MAX_POINTS in all.
MIN_POINTS_PER_ARC = 16
MAX_POINTS = 12000
# An arc is straight under a camera when its RMS distance from its plane is within this many
# times the typical line's (and this floor, px); looser in the first rounds.
STRAIGHT_FACTOR = 3.0
STRAIGHT_FLOOR_PX = 0.6
FIRST_ROUND_PX = 6.0
# Two arcs of one image are pieces of one line when their planes are within this angle.
MERGE_WITHIN_RAD = float(np.radians(0.4))
# Arcs shorter than this angle of their plane test nothing and are set aside.
MIN_SPAN_RAD = float(np.radians(4.0))
# Rounds of alternation between model and grouping.
ROUNDS = 4
# The flexible model used while grouping.
GROUPING_KIND = "odd5"
# The loss of the point distances (px): soft_l1 at 0.5 px gained 0.13 px (p90) on a rendered mirror
# room and took twice the time.
LOSS = "linear"
LOSS_SCALE_PX = 0.5
# Folds of the cross-validation over lines.
CV_FOLDS = 5
# A kind with more parameters must beat a simpler one by this fraction of its held-out score.
CV_MARGIN = 0.02
# The camera's own law (the mirrors' for an image with a cut-off disc, the lenses' else) wins within this
# fraction of the best held-out score: a flexible polynomial follows the scale that lines leave loose and
# wins held-out straightness by a few percent (the Mei set's first image: odd5 by 6% over the unified
# law, p90 13.6 px against 4.4 px from the established calibration).
CAMERA_LAW_MARGIN = 0.10
# Kinds whose RMS over all lines is within this fraction of the best are cross-validated.
CONTENDER_MARGIN = 0.25
# The best starts grouped to the end; the one that leaves the arcs straightest is kept (on the real
# fisheye's first image, the best start by its own score ended at p90 28 px, two others at 3.7 px).
STARTS_KEPT = 3
# Least noise (px) taken for the points when weighting the orthogonality residuals.
SIGMA_FLOOR_PX = 0.1
# Scales tried at the start: the angle (deg) from the axis at the image circle.
START_ANGLES_DEG = (60.0, 75.0, 90.0, 100.0, 110.0, 125.0)


@dataclass(frozen=True)
class LineFitOptions:
    """What lines cannot know, and the choices of the fit.

    Attributes
    ----------
    axis : {"down", "up"}
        The pole the image centre sees (a ceiling camera looks down).
    s : {+1, -1} or None
        Handedness; None: from the kind of camera the circle shows (a cut-off disc, the camera's
        reflection: a mirror, +1; none: a lens, -1 looking down, +1 looking up).
    azimuth_zero : (u, v) or None
        A pixel whose world azimuth is 0; None: the image angle 0 (+u) is azimuth 0.
    model : str
        ``"auto"`` (cross-validation over lines) or a radial kind's name.
    terms : str
        The image terms beyond the radial law a checkerboards' fit may keep (:mod:`..boards.terms`):
        ``"auto"`` (those that predict images left out), ``"none"``, or names joined by commas
        (``"aspect,skew"``). Lines learn none.
    """

    axis: str = "down"
    s: int | None = None
    azimuth_zero: tuple[float, float] | None = None
    model: str = "auto"
    terms: str = "auto"


@dataclass(frozen=True)
class LineFit:
    """The camera learned from lines, and what the fit saw.

    Attributes
    ----------
    model : CameraModel
    covariance : (p, p) float64
        Covariance of the radial coefficients.
    report : LineFitReport
    """

    model: CameraModel
    covariance: FloatArray
    report: LineFitReport
    band: PinnedBand | None = None

    def jacobian_se_px(self) -> FloatArray:
        """The Jacobian's standard error (px) of the radius at the band's rings (empty without a band)."""
        from ...camera.uncertainty import radius_standard_error

        if self.band is None:
            return np.zeros(0)
        alpha = np.radians(self.band.alpha_deg)
        return radius_standard_error(self.model.radial, self.covariance, rho_of_alpha(alpha, self.model.axis))

    def refusal(self) -> str | None:
        """Why the picture cannot stand behind this camera (:mod:`.agreement`; boards that all face the axis,
        :mod:`.stretch`), in one sentence; None where it can."""
        facing = self.report.board_axis_deg
        if self.report.boards and facing and max(facing) < FLAT_BOARD_DEG:
            return refusal(
                f"the {'checkerboard faces' if len(facing) == 1 else 'checkerboards all face'} the camera's axis "
                f"(within {max(facing):.1f} deg): hold one tilted 30-60 deg in some pictures",
                "boards flat under a camera looking down or up, or square before one looking ahead: a camera "
                "stretched along its axis sees such boards as the same squares, so they cannot pin the scale of "
                "its elevations",
            )
        pictures = len({line.image_index for line in self.report.lines})
        if self.report.projection is not None:  # boards: their corners' noise through the fit (boards.uncertainty)
            return self.report.projection.refusal(max(pictures, 1))
        if self.band is None:
            return None
        return self.band.refusal(self.jacobian_se_px(), len(self.report.lines), max(pictures, 1))

    def camera_range(self, cutoff_radius: float, outer_radius: float) -> tuple[float, float]:
        """The elevations (rad, camera axes) a table of this camera spans over the annulus ``[cutoff_radius,
        outer_radius]`` (px): where f_r runs monotonically from the fit's data outwards.

        Raises
        ------
        PanomapError
            If f_r does not run monotonically across the fit's elevations.
        """
        low_deg, high_deg = self.report.elevation_range_deg
        data_range = (math.radians(low_deg), math.radians(high_deg))
        u0, v0 = self.model.centre
        data = "the checkerboards' corners" if self.report.boards else "the straight lines' points"
        return valid_elevation_range(
            self.model.radial,
            data_range,
            cutoff_radius,
            outer_radius,
            slack_px=1.0,
            data=f"{data} (under the fitted camera, about its centre ({u0:.1f}, {v0:.1f}))",
            annulus="between the cut-off disc and the image circle found in the image",
        )


@dataclass
class _State:
    """The grouping in progress: which arcs form which line."""

    arcs: list[FloatArray]
    images: list[int]
    groups: list[list[int]] = field(default_factory=list)
    rejected: dict[int, tuple[str, float]] = field(default_factory=dict)

    def line_pixels(self) -> list[FloatArray]:
        return [np.concatenate([self.arcs[k] for k in group]) for group in self.groups]

    def line_images(self) -> np.ndarray:
        return np.array([self.images[group[0]] for group in self.groups], dtype=np.intp)


def fit_lines(
    arcs: Sequence[EdgeArc],
    circles: ImageCircles,
    options: LineFitOptions = LineFitOptions(),
    progress: Callable[[str], None] | None = None,
    on_board: Collection[int] = (),
) -> LineFit:
    """Learn the camera from the edge arcs of one or more images of it.

    Parameters
    ----------
    arcs : sequence of EdgeArc
        Candidate arcs of every image (their ``image_index`` says which).
    circles : ImageCircles
        The image circles (of the first image): the centre to start from and the annulus.
    options : LineFitOptions
    progress : callable, optional
        Called with a short description of each step.
    on_board : collection of int
        The arcs (indices) that lie on a checkerboard: straight lines like any, but no world's vertical
        (:mod:`.vertical`).

    Raises
    ------
    PanomapError
        With fewer than ``MIN_LINES`` straight lines, or no two orthogonal families to fix the scale.
    """
    say = progress or (lambda _step: None)
    axis = options.axis
    outer = circles.outer_radius
    per_arc = int(np.clip(MAX_POINTS // max(len(arcs), 1), MIN_POINTS_PER_ARC, POINTS_PER_ARC))
    state = _State([_thin(arc.pixels, per_arc) for arc in arcs], [arc.image_index for arc in arcs])
    state.groups = [[k] for k in range(len(arcs))]
    if len(state.groups) < MIN_LINES:
        raise too_few(len(state.groups), "edge arcs", MIN_LINES)
    say("starting scale")
    r_max = _r_max(state, circles)
    tried = []
    failures: list[PanomapError] = []
    for k, start in enumerate(_starts(state, circles, axis, r_max)[:STARTS_KEPT]):
        say(f"grouping from start {k + 1} of {STARTS_KEPT}")
        trial_state = _State(state.arcs, state.images, [list(g) for g in state.groups])
        try:
            params, families = _group(trial_state, axis, start, r_max, outer)
        except PanomapError as exc:  # this start leaves too few straight arcs to fit: the others may not
            failures.append(exc)
            continue
        tried.append((_start_score(trial_state, axis, params, families, r_max), k, params, families, trial_state))
    if not tried:
        raise failures[0]
    _, best_k, params, families, state = min(tried, key=lambda t: (t[0], t[1]))
    start_ends = [Camera(GROUPING_KIND, p, f"start {k + 1} of {len(tried)}") for _, k, p, _, _ in tried if k != best_k]
    if len(state.groups) < MIN_LINES:
        raise too_few(len(state.groups), "straight lines", MIN_LINES)
    if not orthogonal_pairs(families):
        raise no_right_angles(len(state.groups))
    say("choosing the radial model")
    chosen, scores, final, others, folds = _choose(state, families, axis, params, r_max, outer, options, circles)
    alternatives = _not_ruled_out(start_ends, Camera(chosen, final, "chosen"), axis, state, families, r_max)
    return _result(
        chosen, axis, final, state, families, r_max, outer, scores, options, circles, [*alternatives, *others], folds,
        on_board,
    )  # fmt: skip


def _units(camera: Camera, axis: str, data: LineData, families: list[Family]) -> FloatArray | None:
    """What ``camera`` leaves unexplained, unit by unit (L + P,): each line's sum of squared point distances (px^2)
    and each orthogonal pair's squared residual (scaled as the fit weighs it: one pair as much as one line)."""
    trial = evaluate(camera.kind, axis, camera.params, data)
    if trial is None:
        return None
    per_line = np.bincount(data.line_index, trial.distances_px**2, minlength=data.count)
    scale = _orthogonality_scale(camera.kind, axis, camera.params, data)
    square = orthogonality_residuals(trial.normals, families, orthogonal_pairs(families), scale)
    return np.concatenate([per_line, square**2 * data.pixels.shape[0] / max(data.count, 1)])


def _not_ruled_out(
    others: Sequence[Camera], chosen: Camera, axis: str, state: _State, families: list[Family], r_max: float
) -> list[Camera]:
    """The ``others`` (other starts' ends) that explain the chosen grouping's lines and right angles about as well
    as the chosen camera (:func:`.agreement.ruled_out` over :func:`_units`)."""
    data = LineData.of(state.line_pixels(), r_max)
    mine = _units(chosen, axis, data, families)
    if mine is None:
        return list(others)
    out = []
    for other in others:
        theirs = _units(other, axis, data, families)
        if theirs is not None and not ruled_out(theirs, mine):
            out.append(other)
    return out


def _thin(pixels: FloatArray, count: int) -> FloatArray:
    """At most ``count`` points evenly along an arc."""
    pixels = np.asarray(pixels, dtype=np.float64)
    if len(pixels) <= count:
        return pixels
    return pixels[np.round(np.linspace(0, len(pixels) - 1, count)).astype(int)]


def _r_max(state: _State, circles: ImageCircles) -> float:
    pixels = np.concatenate(state.arcs)
    reach = float(np.max(np.hypot(pixels[:, 0] - circles.centre[0], pixels[:, 1] - circles.centre[1])))
    return max(reach, 1.0) * 1.02 + 2.0


def _orthogonality_scale(kind: str, axis: str, params: FloatArray, data: LineData) -> float:
    """The scale (px) of the whitened orthogonality residuals, fixed during one least-squares fit: the points'
    RMS distance from their planes under ``params`` (at least ``SIGMA_FLOOR_PX``) times the square root of
    the points per line. A line's points are not independent (the edge's blur and its sub-pixel step err
    alike along it), so its straightness is worth about one measurement of its plane: each pair's
    orthogonality counts as much as one line's points."""
    trial = evaluate(kind, axis, params, data)
    sigma = SIGMA_FLOOR_PX if trial is None else max(float(np.sqrt(np.mean(trial.distances_px**2))), SIGMA_FLOOR_PX)
    return sigma * math.sqrt(data.pixels.shape[0] / max(data.count, 1))


def _starts(state: _State, circles: ImageCircles, axis: str, r_max: float) -> list[FloatArray]:
    """Equidistant cameras about the circle's centre, best first by how well their scale fits straightness and
    families (as parameters of the grouping's kind)."""
    u0, v0 = circles.centre
    data = LineData.of(state.line_pixels(), r_max)
    # the angles are tried at the rim; with no rim in the frame (a stand-in circle through the frame's corner,
    # frame_circles), at the farthest arc instead
    rim = circles.outer_radius if circles.rim_in_frame > 0 else r_max
    ranked: list[tuple[float, FloatArray]] = []
    for angle_deg in START_ANGLES_DEG:
        params = np.array([u0, v0, rim / math.radians(angle_deg)])
        trial = evaluate("odd1", axis, params, data)
        if trial is None:
            continue
        spans = _spans(trial.rays.d, data)
        keep = spans > MIN_SPAN_RAD
        rms = _line_rms(trial.distances_px, data)
        straight = keep & (rms < FIRST_ROUND_PX)
        families = find_families(trial.normals[straight], state.line_images()[straight])
        pairs = orthogonal_pairs(families)
        angles = [abs(float(families[a].direction @ families[b].direction)) for a, b in pairs]
        score = float(np.median(rms[straight])) if straight.any() else np.inf
        score += 100.0 * (float(np.mean(angles)) if angles else 1.0)
        ranked.append((score, params))
    if not ranked:
        raise PanomapError("no starting camera maps the arcs to rays")
    return [_convert("odd1", GROUPING_KIND, axis, params, r_max) for _, params in sorted(ranked, key=lambda t: t[0])]


def _group(state: _State, axis: str, params: FloatArray, r_max: float, outer: float) -> tuple[FloatArray, list[Family]]:
    """The alternation between the grouping and the flexible model, from ``params``; ``state`` is regrouped."""
    families: list[Family] = []
    for round_ in range(ROUNDS):
        params, families = _regroup(state, GROUPING_KIND, axis, params, r_max, first=round_ == 0)
        params = _refit(GROUPING_KIND, axis, params, state, families, r_max, outer)
    return params, families


def _start_score(state: _State, axis: str, params: FloatArray, families: list[Family], r_max: float) -> float:
    """How well a start ended (px): the median RMS distance of every arc from its own plane (how straight the
    camera makes the arcs, the curved ones included: a start that sets more arcs aside gains nothing by it),
    and the families' orthogonality residuals' sum of squares per point of the lines, in quadrature.
    Straightness alone leaves the scale nearly free (module doc of :mod:`.families`): two starts can end
    equally straight at different scales, and only the right angles tell them apart."""
    data = LineData.of(state.arcs, r_max)
    trial = evaluate(GROUPING_KIND, axis, params, data)
    if trial is None:
        return math.inf
    straight = float(np.median(_line_rms(trial.distances_px, data)))
    lines = LineData.of(state.line_pixels(), r_max)
    grouped = evaluate(GROUPING_KIND, axis, params, lines)
    if grouped is None:
        return math.inf
    scale = _orthogonality_scale(GROUPING_KIND, axis, params, lines)
    square = orthogonality_residuals(grouped.normals, families, orthogonal_pairs(families), scale)
    return math.sqrt(straight**2 + float(np.sum(square**2)) / lines.pixels.shape[0])


def _convert(kind: str, to_kind: str, axis: str, params: FloatArray, r_max: float) -> FloatArray:
    """Parameters of ``to_kind`` that follow ``kind``'s f_r over the radii up to ``r_max``."""
    radial = RadialFunction(kind, tuple(params[2:]), axis)
    rho = _rho_grid(radial, r_max)
    converted = fit_radial(to_kind, rho, np.abs(radial(rho)), axis)
    return np.concatenate([params[:2], converted.coefficients])


def _rho_grid(radial: RadialFunction, r_max: float) -> FloatArray:
    alpha = np.linspace(0.02, math.radians(150.0), 400)
    rho = rho_of_alpha(alpha, radial.axis)
    r = np.abs(radial(rho))
    inside = np.isfinite(r) & (r <= r_max)
    return rho[inside] if inside.sum() >= 8 else rho[:8]


def _spans(rays: FloatArray, data: LineData) -> FloatArray:
    """The angle (rad) between the first and last ray of each line."""
    starts = np.searchsorted(data.line_index, np.arange(data.count))
    ends = np.searchsorted(data.line_index, np.arange(data.count), side="right") - 1
    cosine = np.einsum("ij,ij->i", rays[starts], rays[ends])
    return np.asarray(np.arccos(np.clip(cosine, -1.0, 1.0)), dtype=np.float64)


def _line_rms(distances_px: FloatArray, data: LineData) -> FloatArray:
    sums = np.bincount(data.line_index, distances_px**2, minlength=data.count)
    counts = np.bincount(data.line_index, minlength=data.count)
    return np.asarray(np.sqrt(sums / np.maximum(counts, 1)), dtype=np.float64)


def _regroup(
    state: _State, kind: str, axis: str, params: FloatArray, r_max: float, *, first: bool
) -> tuple[FloatArray, list[Family]]:
    """Test every arc's straightness under the current camera, merge pieces, find families."""
    single = LineData.of(state.arcs, r_max)
    trial = evaluate(kind, axis, params, single)
    if trial is None:
        raise PanomapError("the radial function stopped rising inside the lines' radii")
    rms = _line_rms(trial.distances_px, single)
    spans = _spans(trial.rays.d, single)
    long_enough = spans > MIN_SPAN_RAD
    typical = float(np.median(rms[long_enough])) if long_enough.any() else STRAIGHT_FLOOR_PX
    limit = FIRST_ROUND_PX if first else max(STRAIGHT_FACTOR * typical, STRAIGHT_FLOOR_PX)
    state.rejected = {}
    kept = []
    for k in range(len(state.arcs)):
        if not long_enough[k]:
            state.rejected[k] = (f"too short to test (spans {math.degrees(spans[k]):.1f} deg)", float(rms[k]))
        elif rms[k] > limit:
            state.rejected[k] = (f"not straight under the fitted camera (RMS {rms[k]:.2f} px)", float(rms[k]))
        else:
            kept.append(k)
    if len(kept) < MIN_LINES:
        raise not_straight(len(kept), rms, long_enough, limit, MIN_LINES)
    state.groups = _merge(kept, trial.normals, state.images, rms, limit)
    data = LineData.of(state.line_pixels(), r_max)
    merged = evaluate(kind, axis, params, data)
    assert merged is not None
    families = find_families(merged.normals, state.line_images())
    return params, families


def _merge(kept: list[int], normals: FloatArray, images: list[int], rms: FloatArray, limit: float) -> list[list[int]]:
    """Groups of arcs of one image whose planes coincide (pieces of one line); each arc in one group.

    The straightest arcs lead; each other arc joins the first leader of its image within
    ``MERGE_WITHIN_RAD``, or leads a group of its own.
    """
    groups: list[list[int]] = []
    leader_normals = np.zeros((0, 3))
    leader_images = np.zeros(0, dtype=np.intp)
    for k in sorted(kept, key=lambda j: rms[j]):
        close = (np.abs(leader_normals @ normals[k]) > math.cos(MERGE_WITHIN_RAD)) & (leader_images == images[k])
        if close.any():
            groups[int(np.argmax(close))].append(k)
        else:
            groups.append([k])
            leader_normals = np.vstack([leader_normals, normals[k]])
            leader_images = np.append(leader_images, images[k])
    return groups


def _refit(
    kind: str,
    axis: str,
    params: FloatArray,
    state: _State,
    families: list[Family],
    r_max: float,
    outer: float,
    groups: list[int] | None = None,
) -> FloatArray:
    """Least-squares centre and coefficients of ``kind`` on the lines (``groups``: a subset of them)."""
    from scipy import optimize  # here, not at the top: importing SciPy is slow

    lines = state.line_pixels()
    if groups is not None:
        lines = [lines[g] for g in groups]
        families = _restrict(families, groups)
    data = LineData.of(lines, r_max)
    pairs = orthogonal_pairs(families)
    scale = _orthogonality_scale(kind, axis, params, data)

    def fun(x: FloatArray) -> FloatArray:
        return residuals(kind, axis, x, data, families, pairs, scale)

    if LOSS == "linear":
        solution = optimize.least_squares(fun, params, method="lm", x_scale="jac", max_nfev=400)
    else:
        solution = optimize.least_squares(
            fun, params, method="trf", loss=LOSS, f_scale=LOSS_SCALE_PX, x_scale="jac", max_nfev=400
        )
    return np.asarray(solution.x, dtype=np.float64)


def _restrict(families: list[Family], groups: list[int]) -> list[Family]:
    """The families renumbered for the lines ``groups`` (those with too few left dropped)."""
    where = {g: k for k, g in enumerate(groups)}
    out = []
    for family in families:
        members = np.array([where[m] for m in family.members if m in where], dtype=np.intp)
        if members.size >= 3:
            out.append(Family(members, family.image_index, family.direction))
    return out


def _held_out_rms(
    kind: str, axis: str, params: FloatArray, state: _State, families: list[Family], r_max: float, outer: float
) -> tuple[float, list[FloatArray], FloatArray]:
    """RMS distance (px) of every line's points from its plane under a fit without the line's fold, those
    fits' parameters (one per fold) and each line's held-out sum of squared distances (L,) px^2."""
    count = len(state.groups)
    folds = np.arange(count) % CV_FOLDS
    lines = state.line_pixels()
    total, points = 0.0, 0
    fits: list[FloatArray] = []
    per_line = np.full(count, math.inf)
    for fold in range(CV_FOLDS):
        train = [g for g in range(count) if folds[g] != fold]
        test = [g for g in range(count) if folds[g] == fold]
        if not test:
            continue
        fitted = _refit(kind, axis, params, state, families, r_max, outer, groups=train)
        trial = evaluate(kind, axis, fitted, LineData.of([lines[g] for g in test], r_max))
        if trial is None:
            return math.inf, fits, per_line
        fits.append(fitted)
        per_line[test] = np.bincount(_index_of(test, lines), trial.distances_px**2, minlength=len(test))
        total += float(np.sum(trial.distances_px**2))
        points += trial.distances_px.size
    return math.sqrt(total / max(points, 1)), fits, per_line


def _index_of(test: list[int], lines: list[FloatArray]) -> NDArray[np.intp]:
    """Which of the ``test`` lines each of their concatenated points belongs to (0..len(test)-1)."""
    return np.concatenate([np.full(len(lines[g]), k, dtype=np.intp) for k, g in enumerate(test)])


def _choose(
    state: _State,
    families: list[Family],
    axis: str,
    params: FloatArray,
    r_max: float,
    outer: float,
    options: LineFitOptions,
    circles: ImageCircles,
) -> tuple[str, dict[str, float | None], FloatArray, list[Camera], list[FloatArray]]:
    """The radial kind with the best held-out score (fewer parameters win ties), every kind's score, the
    chosen kind's parameters fitted to all lines, the other kinds the held-out lines cannot rule out (within
    ``ALTERNATIVE_MARGIN`` of the best score) and the chosen kind's fits without each fold.

    Every kind is fitted to all lines first; only those whose RMS there is within ``CONTENDER_MARGIN`` of
    the best are cross-validated (the others score None): they cannot win, and skipping them halves the time.
    """
    kinds = (
        [options.model]
        if options.model != "auto"
        else [
            k
            for k in (MIRROR_CANDIDATES if circles.cutoff is not None else AUTO_CANDIDATES)
            if not radial_kind(k).centre_given
        ]
    )
    fitted: dict[str, tuple[FloatArray, float]] = {}
    data = LineData.of(state.line_pixels(), r_max)
    for kind in kinds:
        try:
            solution = _refit(
                kind, axis, _convert(GROUPING_KIND, kind, axis, params, r_max), state, families, r_max, outer
            )
        except (PanomapError, np.linalg.LinAlgError, ValueError):
            continue
        trial = evaluate(kind, axis, solution, data)
        if trial is not None:
            fitted[kind] = (solution, float(np.sqrt(np.mean(trial.distances_px**2))))
    if not fitted:
        raise PanomapError("no radial model fits the lines")
    if options.model != "auto":
        _, folds, _ = _held_out_rms(options.model, axis, fitted[options.model][0], state, families, r_max, outer)
        return options.model, {}, fitted[options.model][0], [], folds
    best_in = min(rms for _, rms in fitted.values())
    scores: dict[str, float | None] = {}
    fold_fits: dict[str, list[FloatArray]] = {}
    held_out: dict[str, FloatArray] = {}
    for kind in kinds:
        if kind in fitted and fitted[kind][1] <= best_in * (1.0 + CONTENDER_MARGIN):
            scores[kind], fold_fits[kind], held_out[kind] = _held_out_rms(
                kind, axis, fitted[kind][0], state, families, r_max, outer
            )
        else:
            scores[kind] = None
    valid = {k: v for k, v in scores.items() if v is not None and math.isfinite(v)}
    if not valid:
        raise PanomapError("no radial model fits the lines")
    best = min(valid.values())
    mirror = circles.cutoff is not None

    def wins(kind: str) -> bool:
        law = radial_kind(kind).mirror_law if mirror else radial_kind(kind).lens_law
        return valid[kind] <= best * (1.0 + (CAMERA_LAW_MARGIN if law else CV_MARGIN))

    chosen = next(k for k in valid if wins(k))
    # a kind the held-out lines, line by line, find less straight is ruled out; so is one that explains the lines
    # and their right angles less well
    others = _not_ruled_out(
        [
            Camera(k, fitted[k][0], f"the {k} law")
            for k in valid
            if k != chosen and not ruled_out(held_out[k], held_out[chosen])
        ],
        Camera(chosen, fitted[chosen][0], "chosen"),
        axis,
        state,
        families,
        r_max,
    )
    return chosen, scores, fitted[chosen][0], others, fold_fits[chosen]


def _result(
    kind: str,
    axis: str,
    params: FloatArray,
    state: _State,
    families: list[Family],
    r_max: float,
    outer: float,
    scores: dict[str, float | None],
    options: LineFitOptions,
    circles: ImageCircles,
    alternatives: Sequence[Camera] = (),
    folds: Sequence[FloatArray] = (),
    on_board: Collection[int] = (),
) -> LineFit:
    """The camera model, its covariance, how well the picture pins it (:mod:`.agreement`, from the
    ``alternatives`` and the chosen kind's ``folds``) and the report of the final fit; the tilt from the
    vertical family of the lines not on a board (``on_board``: arcs, :mod:`.vertical`)."""
    lines = state.line_pixels()
    data = LineData.of(lines, r_max)
    trial = evaluate(kind, axis, params, data)
    assert trial is not None
    radial = RadialFunction(kind, tuple(float(c) for c in params[2:]), axis)
    rms = _line_rms(trial.distances_px, data)
    worst = np.zeros(data.count)
    np.maximum.at(worst, data.line_index, np.abs(trial.distances_px))
    sigma = float(
        np.sqrt(
            np.mean(trial.distances_px**2)
            * data.pixels.shape[0]
            / max(data.pixels.shape[0] - 2 * data.count - params.size, 1)
        )
    )
    covariance = _covariance(kind, axis, params, data, families, outer, sigma)
    s = options.s if options.s is not None else default_handedness(circles.cutoff is not None, axis)
    seen = _seen(families, trial.normals)
    vertical = vertical_family(families, trial.normals, state.groups, on_board)
    rotation = None if vertical is None else level_rotation(vertical[0], axis, s)
    model = CameraModel(
        (float(params[0]), float(params[1])), radial, s, 0.0, None if rotation is None else tuple(map(tuple, rotation))
    )
    if options.azimuth_zero is not None:
        model = zero_azimuth(model, options.azimuth_zero, circles)
    family_of = {int(m): f for f, family in enumerate(families) for m in family.members}
    rho = _camera_elevations(trial.rays.d, axis)
    fitted = tuple(
        FittedLine(
            arcs=tuple(state.groups[g]),
            image_index=int(state.images[state.groups[g][0]]),
            points=int(np.sum(data.line_index == g)),
            rms_px=float(rms[g]),
            max_px=float(worst[g]),
            family=family_of.get(g),
            elevation_deg=(
                float(np.degrees(rho[data.line_index == g].min())),
                float(np.degrees(rho[data.line_index == g].max())),
            ),
        )
        for g in range(data.count)
    )
    rejected = tuple(
        RejectedArc(arc=k, image_index=int(state.images[k]), reason=reason, rms_px=value)
        for k, (reason, value) in sorted(state.rejected.items())
    )
    low, high = float(np.degrees(rho.min())), float(np.degrees(rho.max()))
    report = LineFitReport(
        model=kind,
        sigma_px=sigma,
        lines=fitted,
        rejected=rejected,
        families=len(families),
        vertical_lines=0 if vertical is None else int(vertical[1]),
        model_selection_cv_rms_px=scores,
        elevation_range_deg=(low, high),
        empty_bands_deg=empty_bands(np.degrees(rho), annulus_deg(radial, circles, r_max)),
        azimuth_source="given" if options.azimuth_zero is not None else "image angle 0",
        handedness_source="given" if options.s is not None else ("mirror" if circles.cutoff is not None else "lens"),
    )
    reach_alpha = _reach_alpha(radial, circles, r_max, float(np.max(np.arccos(np.clip(trial.rays.d[:, 2], -1.0, 1.0)))))
    # The right angles' families, as this camera sees them: only they can measure the stretch (:mod:`.stretch`).
    squared = sorted({k for pair in orthogonal_pairs(seen) for k in pair})
    directions = np.array([seen[k].direction for k in squared]).reshape(-1, 3)
    stretch = _stretch(trial.normals, families)
    band = pinned_band(
        Camera(kind, params, "chosen"), alternatives, folds, axis, ring_alphas(reach_alpha), directions, stretch
    )
    return LineFit(model, covariance, report, band)


def _stretch(normals: FloatArray, families: list[Family]) -> StretchRange:
    """The stretches along the axis that the lines' right angles (their planes' ``normals`` (L, 3) under the chosen
    camera) do not reject (:func:`.stretch.stretch_range`): each pair's cosine over its standard error, as the fit
    weighs it (:func:`.objective.orthogonality_residuals`), under the stretched camera's planes."""
    pairs = orthogonal_pairs(families)
    return stretch_range(lambda s: orthogonality_residuals(stretched_normals(normals, s), families, pairs, 1.0))


def _reach_alpha(radial: RadialFunction, circles: ImageCircles, r_max: float, lines_alpha: float) -> float:
    """The angle (rad) from the axis up to which a table of this camera is judged: its image circle's rim (the
    table covers it, lines or none), else (no rim in the frame) the farthest line."""
    if circles.rim_in_frame <= 0:
        return lines_alpha
    try:
        alpha, _ = InverseRadial.of(radial, circles.outer_radius)(np.array([circles.outer_radius]))
    except PanomapError:
        return lines_alpha
    return max(float(alpha[0]), lines_alpha) if np.isfinite(alpha[0]) else lines_alpha


def vertical_under(
    arcs: Sequence[EdgeArc], circles: ImageCircles, kind: str, axis: str, params: FloatArray
) -> tuple[FloatArray, int] | None:
    """The world's vertical (this package's axes) from the vertical edges among ``arcs`` under a camera
    learned otherwise (``params``: centre and ``kind``'s coefficients), and how many lines show it.

    The arcs within the camera's reach are tested for straightness and grouped under it (no refit); the
    family within ``VERTICAL_WITHIN_DEG`` of the axis with most lines gives the direction. None without one.
    """
    try:
        reach = float(InverseRadial.of(RadialFunction(kind, tuple(float(c) for c in params[2:]), axis), 0.0).r[-1])
    except PanomapError:
        return None
    centre = params[:2]
    inside = [a for a in arcs if float(np.hypot(*(a.pixels - centre).T).max()) < 0.98 * reach]
    if len(inside) < MIN_LINES:
        return None
    per_arc = int(np.clip(MAX_POINTS // len(inside), MIN_POINTS_PER_ARC, POINTS_PER_ARC))
    state = _State([_thin(arc.pixels, per_arc) for arc in inside], [arc.image_index for arc in inside])
    state.groups = [[k] for k in range(len(inside))]
    r_max = min(_r_max(state, circles), reach)
    try:
        _, families = _regroup(state, kind, axis, params, r_max, first=False)
    except PanomapError:
        return None
    trial = evaluate(kind, axis, params, LineData.of(state.line_pixels(), r_max))
    return None if trial is None else vertical_family(families, trial.normals, state.groups)


def _covariance(
    kind: str, axis: str, params: FloatArray, data: LineData, families: list[Family], outer: float, sigma: float
) -> FloatArray:
    """Covariance of the radial coefficients from the Jacobian at the solution."""
    pairs = orthogonal_pairs(families)
    scale = _orthogonality_scale(kind, axis, params, data)
    base = residuals(kind, axis, params, data, families, pairs, scale)
    jacobian = np.empty((base.size, params.size))
    for j in range(params.size):
        step = 1e-6 * max(abs(float(params[j])), 1.0)
        shifted = params.copy()
        shifted[j] += step
        jacobian[:, j] = (residuals(kind, axis, shifted, data, families, pairs, scale) - base) / step
    full = np.linalg.pinv(jacobian.T @ jacobian) * sigma**2
    return np.asarray(full[2:, 2:], dtype=np.float64)


def _seen(families: list[Family], normals: FloatArray) -> list[Family]:
    """The families with their directions as the lines' plane ``normals`` (L, 3) under one camera place them."""
    return [Family(f.members, f.image_index, common_direction(normals[f.members])) for f in families]


def _camera_elevations(rays: FloatArray, axis: str) -> FloatArray:
    """Elevation (rad) in the camera's axes of rays in this package's axes (alpha from the axis)."""
    return rho_of_alpha(np.arccos(np.clip(rays[:, 2], -1.0, 1.0)), axis)
