"""The fit of a camera from the checkerboards in its images: radial function, centre, each board's pose.

Convention: pixels (u, v) px; rays in the camera's axes of :mod:`..lines.rays` (alpha from the pole
the image centre sees, the image angle phi as azimuth); a board's corners are ``R (c, r, 0) + t`` in
those axes, (c, r) its grid place in squares, so distances are in squares (the square's size, like
every distance, is not learned).

The method: the paper's landmark learning with landmarks whose positions are known up to their board's
pose. Each corner's residual is the distance (px) between the corner found and the projection
``centre + f_r(alpha) (cos phi, sin phi)`` of its place on the board; all of them are minimised
together over the centre, the radial coefficients and six pose parameters per board. Straightness,
even spacing, right angles and square squares are all in it. Starts: equidistant cameras at several
scales about the circle's centre, each board's pose from its corners' rays (a planar PnP on the rays
turned to face the board); the start that ends lowest is kept. Corners far off (a misread corner) and
boards mostly off (a misread board) are set aside and the fit repeated. The radial kind is chosen by
the Bayesian information criterion over the corners, the camera's own law (the mirrors' for an image
with a cut-off disc, the lenses' else) preferred within a margin.

What boards cannot know, as lines cannot: the azimuth origin, the handedness (a planar board seen
mirrored is the same board seen from its back) and every distance. Nor the tilt of the axis: the
vertical edges of the images give it, straight under the camera the boards gave (``arcs``); without
them the camera is taken as level.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.sparse import lil_matrix
from scipy.spatial.transform import Rotation

from ...camera.image_terms import TERM_KINDS, ImageTerms
from ...camera.model import CameraModel
from ...camera.radial import RadialFunction, fit_radial
from ...camera.radial_models import AUTO_CANDIDATES, MIRROR_CANDIDATES, radial_kind, rho_of_alpha
from ...errors import PanomapError
from ...geometry import FloatArray
from ..circles import ImageCircles
from ..core.line_report import FittedLine, LineFitReport, RejectedArc, empty_bands
from ..lines.angles import annulus_deg, default_handedness
from ..lines.arcs import EdgeArc
from ..lines.fit import LineFit, LineFitOptions, vertical_under
from ..lines.orientation import level_rotation, zero_azimuth
from ..lines.rays import ALPHA_LIMIT, InverseRadial, pixel_rays
from .detect import Board
from .off_board import arcs_off_boards
from .solve import NEAR_DAMPING, BlockJacobian, least_squares_blocks
from .terms import NO_TERMS, TermChoice, TermLayout, choose_terms
from .uncertainty import board_band

# Fewest corners, over all boards, a fit needs.
MIN_CORNERS = 24
# Scales tried at the start: the angle (deg) from the axis at the image circle.
START_ANGLES_DEG = (60.0, 75.0, 90.0, 105.0, 120.0)
# The radial kind used from the starts (flexible enough to bring every pose home).
START_KIND = "odd3"
# The kind whose residuals tell misread corners: flexible enough for any camera here.
FLEXIBLE_KIND = "odd5"
# Starts whose costs differ by less than this fraction have come home to one minimum, and no more are tried: on
# the five real sets every start ends within 1.3e-5 of the others (the later ones cost 30-50% of the fit).
SAME_START = 1.0e-4
# Evaluations each start may take, and the scale (px) of its robust loss.
START_EVALUATIONS = 40
ROBUST_SCALE_PX = 2.0
# The damping a start's steps begin with (:mod:`.solve`; the fits from a fit begin with NEAR_DAMPING): from a start
# 5 px RMS off, 1e-6 spent half of the 40 evaluations on steps refused (two real sets: three starts, not two).
FAR_DAMPING = 1e-3
# Evaluations of the residuals a joint fit may take (a slow one has found its minimum long before).
MAX_EVALUATIONS = 400
# ... and the flexible kind's fits, whose residuals only tell misread corners and boards (5 sigma and 1.5 px at
# least): on the real sets they end in 2-11 (the same fits); on one board tiled over the 1600 x 1600 fisheye
# picture the first crept on for 389 (its cost 0.2% lower than at 60), and with 60 none is set aside either, the
# camera chosen is the same (its centre within 3e-6 px, its band within 1e-6 px) and the fit's time halves.
FLEXIBLE_EVALUATIONS = 60
# A corner is set aside beyond this many times the noise per coordinate (and this floor, px): 4e-6 of
# honest corners are.
OUTLIER_FACTOR = 5.0
OUTLIER_FLOOR_PX = 1.5
# A board with more than this fraction of its corners set aside is misread as a whole and set aside.
BOARD_OFF_FRACTION = 0.3
# Corners are found to a fraction of a pixel (0.2-0.5 px RMS on real sets): a fit worse than this is of
# something else (tiles that are not a square grid, a grid misread as a whole).
MAX_RMS_PX = 1.0
# Fewer boards than this choose among two-parameter kinds only.
FEW_BOARDS = 3
# The camera's own law wins unless another kind's BIC is lower by more than this (nats).
OWN_LAW_MARGIN = 10.0
# A residual where the model gives no radius (beyond a law's range), px.
UNREACHED_PX = 1.0e3


@dataclass(frozen=True)
class _Fit:
    """One converged joint fit: the kind, centre, coefficients and image terms, the poses, the corner residuals."""

    kind: str
    params: FloatArray
    poses: FloatArray
    residuals_px: FloatArray
    jacobian: BlockJacobian
    layout: TermLayout = NO_TERMS

    @property
    def cost(self) -> float:
        return float(np.sum(self.residuals_px**2))

    @property
    def coefficients(self) -> FloatArray:
        """f_r's coefficients (the parameters after the centre, before the terms)."""
        return self.params[2 : 2 + radial_kind(self.kind).parameter_count]

    @property
    def terms(self) -> ImageTerms:
        return self.layout.terms(self.params[2 + radial_kind(self.kind).parameter_count :])


def fit_boards(
    boards: Sequence[Board],
    circles: ImageCircles,
    options: LineFitOptions = LineFitOptions(),
    progress: Callable[[str], None] | None = None,
    arcs: Sequence[EdgeArc] = (),
) -> LineFit:
    """Learn the camera from checkerboards found in one or more images of it.

    Parameters
    ----------
    boards : sequence of Board
        The boards of every image (:func:`.detect.find_boards`).
    circles : ImageCircles
        The image circles (of the first image): the centre to start from and the annulus.
    options : LineFitOptions
        What boards cannot know (axis, handedness, azimuth origin) and the radial kind.
    progress : callable, optional
        Called with a short description of each step.
    arcs : sequence of EdgeArc
        The images' edge arcs (:func:`..lines.arcs.find_arcs`): their vertical lines, straight under the
        camera the boards gave, give the tilt of its axis (boards do not show the vertical). None: level.

    Raises
    ------
    PanomapError
        With fewer than ``MIN_CORNERS`` corners, or when no start converges.
    """
    say = progress or (lambda _step: None)
    boards = [b for b in boards if len(b.pixels) >= 4]
    corners = sum(len(b.pixels) for b in boards)
    if corners < MIN_CORNERS:
        raise PanomapError(
            f"{len(boards)} checkerboard(s) with {corners} corners were found; the fit needs {MIN_CORNERS} or more"
        )
    axis = options.axis
    given = list(boards)
    dropped: list[tuple[int, str, float]] = []
    # a fit over MAX_RMS_PX sets its worst board aside and fits again, up to half the boards: a misread board the
    # fit half follows spoils the others' residuals as much as its own (a 5 x 5 grid read off a rendered room's
    # boards: 5.0 px RMS, the two true boards 2.4 px with it, 0.10 px without)
    while True:
        kept = [k for k in range(len(given)) if k not in {d[0] for d in dropped}]
        final, fits, boards, kept_index, rejected = _fit_all([given[k] for k in kept], circles, axis, options, say)
        kept_index = [kept[k] for k in kept_index]
        rejected = [(kept[k], why, rms) for k, why, rms in rejected]
        rms_px = float(np.sqrt(np.mean(final.residuals_px**2)))
        if rms_px <= MAX_RMS_PX:
            break
        worst, worst_rms, others = _worst_board(final, boards)
        if len(dropped) + 1 > len(given) // 2:
            raise PanomapError(
                f"the checkerboards' corners fit no camera better than {rms_px:.1f} px RMS (a board's corners are "
                f"found to a fraction of a pixel: what was found is no board, or not a square grid)"
            )
        say("setting aside a board no camera fits with the rest")
        dropped.append(
            (kept_index[worst], f"board misread (RMS {worst_rms:.1f} px, the rest {others:.2f} px)", worst_rms)
        )
    rms = {kind: (None if fit is None else float(np.sqrt(np.mean(fit.residuals_px**2)))) for kind, fit in fits.items()}
    say("choosing the image terms by leaving images out")
    final, choice = _with_terms(final, boards, axis, circles.outer_radius, options.terms)
    radial_params = final.params[: 2 + radial_kind(final.kind).parameter_count]
    vertical = None
    if arcs:  # the arcs' pixels as the radial model sees them (the terms undone)
        off = arcs_off_boards(arcs, boards)  # a board's own lines run any way its holder tilts it
        vertical = vertical_under(_undone(off, final), circles, final.kind, axis, radial_params) if off else None
    r_max = _farthest(boards, circles.centre) * 1.05
    return _result(
        final, given, boards, kept_index, sorted(dropped + rejected), rms, options, circles, r_max, vertical, choice
    )


def _with_terms(fit: _Fit, boards: Sequence[Board], axis: str, radius_px: float, asked: str) -> tuple[_Fit, TermChoice]:
    """``fit`` refitted with the image terms :func:`.terms.choose_terms` keeps (``fit`` itself without any)."""
    kept, choice = choose_terms(fit, boards, axis, radius_px, asked, (_residuals, _jacobian_blocks))
    if not kept:
        return fit, choice
    layout = TermLayout(kept, radius_px)
    start = np.concatenate([fit.params, [v for name in kept for v in TERM_KINDS[name].identity]])
    refit = _joint(boards, fit.kind, axis, start, fit.poses, layout=layout)
    beyond = refit.terms.beyond_limits()
    if beyond is not None:
        if asked != "auto":
            raise PanomapError(f"the boards' fit with the image terms asked for failed: {beyond}")
        return fit, replace(choice, kept=(), reason=f"those kept ran beyond their limits on all images ({beyond})")
    return refit, replace(choice, values=refit.terms.values)


def _undone(arcs: Sequence[EdgeArc], fit: _Fit) -> list[EdgeArc]:
    """``arcs`` with the fit's image terms undone from their pixels."""
    if not fit.layout.kept:
        return list(arcs)
    centre, terms = fit.params[:2], fit.terms
    return [replace(arc, pixels=terms.undo(arc.pixels - centre) + centre) for arc in arcs]


def _fit_all(
    boards: list[Board], circles: ImageCircles, axis: str, options: LineFitOptions, say: Callable[[str], None]
) -> tuple[_Fit, dict[str, _Fit | None], list[Board], list[int], list[tuple[int, str, float]]]:
    """The fit of ``boards``: the chosen kind's, every candidate's, the boards kept (their indices) and those set
    aside or trimmed (index, why, RMS px)."""
    # f_r must rise to the farthest corner (the image circle may be a stand-in far beyond the mirror's reach)
    r_max = _farthest(boards, circles.centre) * 1.05
    say("starting scale")
    best = _from_starts(boards, circles, axis, r_max)
    best = _refit_as(boards, best, FLEXIBLE_KIND, axis, r_max, FLEXIBLE_EVALUATIONS) or best
    say("setting aside misread corners")
    # misread boards first (they spoil every residual), then misread corners against the fit without them
    boards, kept_index, rejected = _without_outliers(boards, best, corners=False)
    best = _joint(boards, best.kind, axis, best.params, best.poses[kept_index], FLEXIBLE_EVALUATIONS)
    boards, again, more = _without_outliers(boards, best, corners=True)
    rejected += [(kept_index[k], why, rms) for k, why, rms in more]
    kept_index = [kept_index[k] for k in again]
    best = _joint(boards, best.kind, axis, best.params, best.poses[again], FLEXIBLE_EVALUATIONS)
    if float(np.sqrt(np.mean(best.residuals_px**2))) > MAX_RMS_PX:  # no kind will save it: a board to set aside
        return best, {best.kind: best}, boards, kept_index, rejected
    r_max = _farthest(boards, circles.centre) * 1.05  # the boards kept: a misread one may lie beyond the mirror
    say("choosing the radial model")
    candidates = _candidates(options, circles, len(boards))
    fits = {kind: _refit_as(boards, best, kind, axis, r_max) for kind in candidates}
    scores = {kind: (None if fit is None else _bic(fit)) for kind, fit in fits.items()}
    final = fits[_choose(scores, candidates, circles)]
    assert final is not None
    return final, fits, boards, kept_index, rejected


def _worst_board(fit: _Fit, boards: Sequence[Board]) -> tuple[int, float, float]:
    """The board with the largest RMS (px) under ``fit``, its RMS, and the RMS of the others' corners."""
    owner = np.repeat(np.arange(len(boards)), [len(b.pixels) for b in boards])
    rms = [float(np.sqrt(np.mean(fit.residuals_px[owner == k] ** 2))) for k in range(len(boards))]
    worst = int(np.argmax(rms))
    others = fit.residuals_px[owner != worst]
    return worst, rms[worst], float(np.sqrt(np.mean(others**2))) if others.size else 0.0


def _farthest(boards: Sequence[Board], centre: tuple[float, float]) -> float:
    return max(float(np.hypot(*(b.pixels - centre).T).max()) for b in boards)


def _candidates(options: LineFitOptions, circles: ImageCircles, boards: int) -> list[str]:
    """The kinds tried: the one asked for, or every kind that fits the centre (two parameters at most when
    the boards are few: a flexible kind follows them and turns away beyond them, where BIC cannot see)."""
    if options.model != "auto":
        if radial_kind(options.model).centre_given:
            raise PanomapError(f"the {options.model} model takes the centre as given; boards fit the centre")
        return [options.model]
    order = MIRROR_CANDIDATES if circles.cutoff is not None else AUTO_CANDIDATES
    most = 2 if boards < FEW_BOARDS else 99
    return [
        kind for kind in order if not radial_kind(kind).centre_given and 2 <= radial_kind(kind).parameter_count <= most
    ]


# -- the projection and the residuals ---------------------------------------------------------------


def project(kind: str, axis: str, params: FloatArray, points: FloatArray, layout: TermLayout = NO_TERMS) -> FloatArray:
    """Pixels (n, 2) of points (n, 3) in the camera's axes under the camera ``params`` (u0, v0, coefficients,
    then the values of the image terms ``layout`` frees)."""
    rho = elevations(points, axis)
    phi = np.arctan2(points[:, 1], points[:, 0])
    count = radial_kind(kind).parameter_count
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        r = radial_kind(kind).evaluate(tuple(float(c) for c in params[2 : 2 + count]), rho, axis)
        offsets = np.stack([r * np.cos(phi), r * np.sin(phi)], axis=1)
        if layout.kept:
            offsets = layout.terms(params[2 + count :]).apply(offsets)
    return np.asarray(params[:2] + offsets, dtype=np.float64)


def elevations(points: FloatArray, axis: str) -> FloatArray:
    """Elevations rho (n,) rad of points (n, 3) in the camera's axes (alpha from the pole the centre sees)."""
    length = np.maximum(np.linalg.norm(points, axis=1), 1e-300)
    alpha = np.arccos(np.clip(points[:, 2] / length, -1.0, 1.0))
    return rho_of_alpha(alpha, axis)


def board_points(poses: FloatArray, boards: Sequence[Board]) -> FloatArray:
    """Corners (N, 3) of every board, in the camera's axes, from the poses (B, 6): rotation vector, translation."""
    poses = np.asarray(poses).reshape(-1, 6)
    plane, owner = _planes(boards)
    if len(poses) != len(boards):
        raise ValueError(f"{len(poses)} poses for {len(boards)} boards")
    rotations = Rotation.from_rotvec(poses[:, :3]).as_matrix()  # one call for every board (B, 3, 3)
    out: FloatArray = np.einsum("nij,nj->ni", rotations[owner], plane) + poses[owner, 3:]
    return out


def _planes(boards: Sequence[Board]) -> tuple[FloatArray, NDArray[np.intp]]:
    """Every board's corners on its plane (N, 3) (grid place, z = 0) and the board each is on (N,)."""
    plane = np.zeros((sum(len(b.grid) for b in boards), 3))
    plane[:, :2] = np.concatenate([b.grid for b in boards])
    owner = np.repeat(np.arange(len(boards)), [len(b.grid) for b in boards])
    return plane, owner


def board_axis_deg(poses: FloatArray) -> FloatArray:
    """Each board's (poses (B, 6)) normal's angle (deg) from the camera's axis, 0-90."""
    normals = Rotation.from_rotvec(np.asarray(poses)[:, :3]).apply([0.0, 0.0, 1.0])
    return np.asarray(np.degrees(np.arccos(np.clip(np.abs(normals[:, 2]), 0.0, 1.0))), dtype=np.float64)


def residuals_under(
    kind: str,
    axis: str,
    params: FloatArray,
    poses: FloatArray,
    boards: Sequence[Board],
    layout: TermLayout = NO_TERMS,
) -> FloatArray:
    """The corners' residuals (2N,) px, u and v interleaved, under the camera ``params`` with ``poses`` (6B,)."""
    observed = np.concatenate([b.pixels for b in boards])
    return _residuals(np.concatenate([params, poses]), kind, axis, boards, observed, layout)


def _residuals(
    x: FloatArray, kind: str, axis: str, boards: Sequence[Board], observed: FloatArray, layout: TermLayout = NO_TERMS
) -> FloatArray:
    count = 2 + radial_kind(kind).parameter_count + layout.count
    params, poses = x[:count], x[count:].reshape(-1, 6)
    predicted = project(kind, axis, params, board_points(poses, boards), layout)
    out = (predicted - observed).ravel()
    return np.where(np.isfinite(out), out, UNREACHED_PX)


def _jacobian_blocks(
    x: FloatArray,
    kind: str,
    axis: str,
    boards: Sequence[Board],
    observed: FloatArray,
    layout: TermLayout = NO_TERMS,
    camera: bool = True,
) -> BlockJacobian:
    """The Jacobian (2N, count + 6B) of :func:`_residuals`, in closed form but for f_r's derivatives.

    ``pixel = centre + f_r(rho(X)) (cos phi, sin phi)`` with ``X = R(w) p + t``: the chain through the point's
    angle from the axis and its azimuth is exact; f_r's derivatives in its coefficients and in rho, and the
    rotation's in its vector, are central differences (steps 1e-6; f_r costs one pass over the corners, where
    differencing every parameter through the whole projection cost 90% of the fit). A residual set to
    ``UNREACHED_PX`` has zero derivatives. Image terms (``layout``): the radial offset's derivatives through the
    terms' Jacobian, the terms' own in closed form (:mod:`panomap.camera.image_terms`). In blocks (each corner
    sees the camera and its board's pose): :mod:`.solve` steps on their normal equations. ``camera`` False: the
    camera's columns but the centre's are left zero (a fit of the poses alone, the camera held, needs none).
    """
    spec = radial_kind(kind)
    radial_count = 2 + spec.parameter_count
    count = radial_count + layout.count
    params, poses = x[:count], x[count:].reshape(-1, 6)
    points = board_points(poses, boards)
    n = len(points)
    x_, y_, z_ = points.T
    s2 = np.maximum(x_**2 + y_**2, 1e-300)
    s = np.sqrt(s2)
    n2 = s2 + z_**2
    alpha = np.arctan2(s, z_)
    phi = np.arctan2(y_, x_)
    rho = rho_of_alpha(alpha, axis)
    sign = 1.0 if axis == "down" else -1.0  # d rho / d alpha

    def f(coefficients: FloatArray, at: FloatArray) -> FloatArray:
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            return np.asarray(spec.evaluate(tuple(float(c) for c in coefficients), at, axis), dtype=np.float64)

    coefficients = params[2:radial_count]
    r = f(coefficients, rho)
    dr_drho = (f(coefficients, rho + 1e-6) - f(coefficients, rho - 1e-6)) / 2e-6
    cos_phi, sin_phi = np.cos(phi), np.sin(phi)
    # d(pixel offset) / d(radial offset) (n, 2, 2): the identity without terms
    offsets = np.stack([r * cos_phi, r * sin_phi], axis=1)
    terms = layout.terms(params[radial_count:]) if layout.kept else None
    chain = terms.jacobian(offsets) if terms is not None else None

    def through(du: FloatArray, dv: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Derivatives of the radial offset (n,) or (n, k) as the pixel's, through the terms."""
        if chain is None:
            return du, dv
        a, b, c, d = (chain[:, i, j].reshape((-1,) + (1,) * (du.ndim - 1)) for i in (0, 1) for j in (0, 1))
        return a * du + b * dv, c * du + d * dv

    # each row's camera columns (count), then its board's six pose columns: built row by row as CSR (a dense
    # (2N, count + 6B) array and its conversion cost 12% of the fit on the real sets; the same values)
    jac = np.zeros((2 * n, count + 6))
    jac[0::2, 0] = 1.0
    jac[1::2, 1] = 1.0
    for k in range(spec.parameter_count if camera else 0):
        step = 1e-6 * max(1.0, abs(float(coefficients[k])))
        up, down = coefficients.copy(), coefficients.copy()
        up[k] += step
        down[k] -= step
        dr = (f(up, rho) - f(down, rho)) / (2.0 * step)
        jac[0::2, 2 + k], jac[1::2, 2 + k] = through(dr * cos_phi, dr * sin_phi)
    if terms is not None and camera:
        with np.errstate(invalid="ignore", over="ignore"):
            own = terms.parameter_jacobian(offsets)
        jac[0::2, radial_count:count] = own[:, 0, :]
        jac[1::2, radial_count:count] = own[:, 1, :]
    # d alpha / dX and d phi / dX (n, 3)
    d_alpha = np.stack([z_ * x_ / (s * n2), z_ * y_ / (s * n2), -s / n2], axis=1)
    d_phi = np.stack([-y_ / s2, x_ / s2, np.zeros(n)], axis=1)
    radial_part = (sign * dr_drho)[:, None] * d_alpha
    du_dx, dv_dx = through(
        radial_part * cos_phi[:, None] - (r * sin_phi)[:, None] * d_phi,
        radial_part * sin_phi[:, None] + (r * cos_phi)[:, None] * d_phi,
    )
    # the rotation's derivatives, every board's at once: R(w +- 1e-6 e_k) p (B, 3 (k), 2 (+-), 3, 3)
    plane, owner = _planes(boards)
    steps = np.concatenate([np.eye(3), -np.eye(3)]) * 1e-6
    turned = Rotation.from_rotvec((poses[:, None, :3] + steps[None]).reshape(-1, 3)).as_matrix()
    turned = turned.reshape(len(boards), 2, 3, 3, 3).transpose(0, 2, 1, 3, 4)
    moved = np.einsum("nksij,nj->nksi", turned[owner], plane)
    dp = (moved[:, :, 0] - moved[:, :, 1]) / 2e-6  # (n, 3 (k), 3)
    jac[0::2, count : count + 3] = np.einsum("nki,ni->nk", dp, du_dx)
    jac[1::2, count : count + 3] = np.einsum("nki,ni->nk", dp, dv_dx)
    jac[0::2, count + 3 :] = du_dx
    jac[1::2, count + 3 :] = dv_dx
    with np.errstate(invalid="ignore", over="ignore"):  # the residuals, as project gives them
        pixels = params[:2] + (offsets if terms is None else terms.apply(offsets))
    jac[~np.isfinite((pixels - observed).ravel())] = 0.0
    return BlockJacobian(np.where(np.isfinite(jac), jac, 0.0), np.repeat(owner, 2), count, len(boards))


def sparsity(count: int, boards: Sequence[Board]) -> lil_matrix:
    rows = 2 * sum(len(b.pixels) for b in boards)
    pattern = lil_matrix((rows, count + 6 * len(boards)), dtype=int)
    pattern[:, :count] = 1
    row = 0
    for k, board in enumerate(boards):
        n = 2 * len(board.pixels)
        pattern[row : row + n, count + 6 * k : count + 6 * k + 6] = 1
        row += n
    return pattern


def _joint(
    boards: Sequence[Board],
    kind: str,
    axis: str,
    params: FloatArray,
    poses: FloatArray,
    max_nfev: int | None = None,
    robust: bool = False,
    layout: TermLayout = NO_TERMS,
    ftol: float = 1e-8,
) -> _Fit:
    """The joint least-squares fit of the camera and the poses from a start (``robust``: a misread board
    pulls less, for the starts, before misread boards are set aside; ``layout``: the image terms freed, their
    values at the end of ``params``; ``ftol``: the relative drop of the cost where it stops)."""
    observed = np.concatenate([b.pixels for b in boards])
    count = 2 + radial_kind(kind).parameter_count + layout.count
    problem = (kind, axis, boards, observed, layout)
    evaluations = max_nfev or MAX_EVALUATIONS
    try:
        solution = least_squares_blocks(
            functools.partial(_residuals_of, problem=problem),
            functools.partial(_jacobian_of, problem=problem),
            np.concatenate([params, poses.ravel()]),
            steps=evaluations,
            tolerance=ftol,
            evaluations=evaluations,
            robust_scale=ROBUST_SCALE_PX if robust else None,
            damping=FAR_DAMPING if robust else NEAR_DAMPING,
        )
    except np.linalg.LinAlgError:
        raise PanomapError("the boards' fit is singular: the corners do not pin the camera and the poses") from None
    residuals_px = np.hypot(*solution.residuals.reshape(-1, 2).T)
    x = solution.x
    return _Fit(kind, x[:count], x[count:].reshape(-1, 6), residuals_px, _jacobian_blocks(x, *problem), layout)


def _residuals_of(x: FloatArray, problem: tuple[str, str, Sequence[Board], FloatArray, TermLayout]) -> FloatArray:
    return _residuals(x, *problem)


def _jacobian_of(x: FloatArray, problem: tuple[str, str, Sequence[Board], FloatArray, TermLayout]) -> BlockJacobian:
    return _jacobian_blocks(x, *problem)


# -- the starts -------------------------------------------------------------------------------------


def _from_starts(boards: Sequence[Board], circles: ImageCircles, axis: str, r_max: float) -> _Fit:
    """The joint fit from each start scale, brought home; the one that ends lowest, or the lower of the first two
    that end at one cost (``SAME_START``)."""
    tried: list[_Fit] = []
    for angle_deg in START_ANGLES_DEG:
        a1 = circles.outer_radius / math.radians(angle_deg)
        params = np.array([circles.centre[0], circles.centre[1], a1, 0.0])
        radial = RadialFunction("odd1", (a1,), axis)
        try:
            inverse = InverseRadial.of(radial, r_max)
            poses = np.array([pose_of(board, circles.centre, inverse) for board in boards])
            fit = _joint(boards, START_KIND, axis, params, poses, max_nfev=START_EVALUATIONS, robust=True)
        except PanomapError:
            continue
        if any(abs(fit.cost - other.cost) <= SAME_START * max(fit.cost, other.cost) for other in tried):
            return min([*tried, fit], key=lambda fit: fit.cost)  # two starts came home to one minimum
        tried.append(fit)
    if not tried:
        raise PanomapError("no start scale brought the boards' poses home")
    return min(tried, key=lambda fit: fit.cost)


def pose_of(board: Board, centre: tuple[float, float], inverse: InverseRadial) -> FloatArray:
    """A board's pose (6,) from its corners' rays under a trial camera: a planar PnP facing the board."""
    rays = pixel_rays(board.pixels, centre, inverse).d
    mean = rays.mean(axis=0)
    facing = _facing(mean / np.linalg.norm(mean))
    turned = rays @ facing.T
    turned[:, 2] = np.maximum(turned[:, 2], 1e-3)
    plane = np.column_stack([board.grid.astype(np.float64), np.zeros(len(board.grid))])
    ok, rvec, tvec = cv2.solvePnP(plane, turned[:, :2] / turned[:, 2:3], np.eye(3), None, flags=cv2.SOLVEPNP_IPPE)
    if not ok:
        rvec, tvec = np.zeros(3), np.array([0.0, 0.0, 10.0])
    rotation = facing.T @ cv2.Rodrigues(rvec)[0]
    return np.concatenate([Rotation.from_matrix(rotation).as_rotvec(), facing.T @ np.ravel(tvec)])


def _facing(direction: FloatArray) -> FloatArray:
    """A rotation (3, 3) taking the unit ``direction`` to +z."""
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(direction, z)
    sine, cosine = float(np.linalg.norm(axis)), float(direction @ z)
    if sine < 1e-12:
        return np.eye(3) if cosine > 0 else np.diag([1.0, -1.0, -1.0])
    return np.asarray(Rotation.from_rotvec(axis / sine * math.atan2(sine, cosine)).as_matrix())


# -- outliers, kinds and the choice -----------------------------------------------------------------


def _without_outliers(
    boards: Sequence[Board], fit: _Fit, corners: bool
) -> tuple[list[Board], list[int], list[tuple[int, str, float]]]:
    """The boards kept and their indices; boards mostly misread dropped, and with ``corners`` the misread
    corners of the others set aside (index, why, RMS px)."""
    # the noise per coordinate from the median corner distance (a Rayleigh's median is sigma sqrt(ln 4))
    sigma = float(np.median(fit.residuals_px)) / math.sqrt(math.log(4.0))
    limit = max(OUTLIER_FACTOR * sigma, OUTLIER_FLOOR_PX)
    kept: list[Board] = []
    kept_index: list[int] = []
    rejected: list[tuple[int, str, float]] = []
    start = 0
    for k, board in enumerate(boards):
        residuals = fit.residuals_px[start : start + len(board.pixels)]
        start += len(board.pixels)
        off = residuals > limit
        rms = float(np.sqrt(np.mean(residuals**2)))
        if off.mean() > BOARD_OFF_FRACTION:
            rejected.append((k, f"board misread ({int(off.sum())} of {off.size} corners off by > {limit:.1f} px)", rms))
            continue
        if corners and off.any():
            kept.append(Board(board.image_index, board.pixels[~off], board.grid[~off]))
            rejected.append((k, f"{int(off.sum())} corner(s) off by > {limit:.1f} px", rms))
        else:
            kept.append(board)
        kept_index.append(k)
    if sum(len(b.pixels) for b in kept) < MIN_CORNERS:
        raise PanomapError(
            f"the checkerboards' corners do not agree with any one camera ({len(rejected)} board(s) misread)"
        )
    return kept, kept_index, rejected


def _refit_as(
    boards: Sequence[Board], fit: _Fit, kind: str, axis: str, r_max: float, max_nfev: int | None = None
) -> _Fit | None:
    """The joint fit with radial ``kind``, started from ``fit`` (its f_r refitted as ``kind``; ``max_nfev``: the
    evaluations it may take, ``MAX_EVALUATIONS`` where None)."""
    rho_low, rho_high = _corner_rho(fit, boards, axis)
    rho = np.linspace(rho_low, rho_high, 64)
    start = RadialFunction(fit.kind, tuple(float(c) for c in fit.coefficients), axis)
    try:
        converted = fit_radial(kind, rho, start(rho), axis)
        params = np.concatenate([fit.params[:2], converted.coefficients])
        result = _joint(boards, kind, axis, params, fit.poses, max_nfev)
    except (PanomapError, ValueError, np.linalg.LinAlgError):
        return None
    if not (np.all(np.isfinite(result.residuals_px)) and result.residuals_px.max() < UNREACHED_PX):
        return None
    points = board_points(result.poses, boards)
    if np.any(points[:, 2] < np.cos(ALPHA_LIMIT) * np.linalg.norm(points, axis=1)):
        return None  # corners beyond any camera's view: the fit went round the back
    try:  # a law that turns back or ends before the image circle gives no table there
        InverseRadial.of(RadialFunction(kind, tuple(float(c) for c in result.coefficients), axis), r_max)
    except PanomapError:
        return None
    return result


def _corner_rho(fit: _Fit, boards: Sequence[Board], axis: str) -> tuple[float, float]:
    rho = elevations(board_points(fit.poses, boards), axis)
    return float(rho.min()), float(rho.max())


def _bic(fit: _Fit) -> float:
    n = 2 * fit.residuals_px.size
    k = fit.params.size + fit.poses.size
    return n * math.log(max(fit.cost, 1e-12) / n) + k * math.log(n)


def _choose(scores: dict[str, float | None], candidates: list[str], circles: ImageCircles) -> str:
    """The kind with the lowest BIC; the camera's own law within ``OWN_LAW_MARGIN`` of it."""
    valid = {kind: score for kind, score in scores.items() if score is not None}
    if not valid:
        raise PanomapError("no radial model follows the checkerboards' corners")
    best = min(valid, key=lambda kind: (valid[kind], candidates.index(kind)))
    mirror = circles.cutoff is not None
    own = [k for k in valid if (radial_kind(k).mirror_law if mirror else radial_kind(k).lens_law)]
    if own and valid[own[0]] <= valid[best] + OWN_LAW_MARGIN:
        return own[0]
    return best


# -- the result -------------------------------------------------------------------------------------


def _result(
    fit: _Fit,
    given: Sequence[Board],
    boards: Sequence[Board],
    kept_index: list[int],
    rejected: list[tuple[int, str, float]],
    scores: dict[str, float | None],
    options: LineFitOptions,
    circles: ImageCircles,
    r_max: float,
    vertical: tuple[FloatArray, int] | None,
    choice: TermChoice,
) -> LineFit:
    """The camera model, the covariance of its radial coefficients and the report.

    The report's lines are the boards' rows and columns; their ``arcs`` index :func:`board_arcs` of the
    boards given, and a board set aside points at its first row there.
    """
    first_arc = _first_arcs(given)
    axis = options.axis
    n = fit.residuals_px.size
    dof = max(2 * n - fit.params.size - fit.poses.size, 1)
    sigma = math.sqrt(fit.cost / dof)
    jacobian = fit.jacobian.dense()
    covariance = np.linalg.pinv(jacobian.T @ jacobian) * sigma**2
    count = 2 + radial_kind(fit.kind).parameter_count
    radial = RadialFunction(fit.kind, tuple(float(c) for c in fit.coefficients), axis)
    s = options.s if options.s is not None else default_handedness(circles.cutoff is not None, axis)
    rotation = None if vertical is None else level_rotation(vertical[0], axis, s)
    model = CameraModel(
        (float(fit.params[0]), float(fit.params[1])),
        radial,
        s,
        0.0,
        None if rotation is None else tuple(map(tuple, rotation)),
        terms=fit.terms,
    )
    if options.azimuth_zero is not None:
        model = zero_azimuth(model, options.azimuth_zero, circles)
    rho_deg = np.degrees(elevations(board_points(fit.poses, boards), axis))
    lines: list[FittedLine] = []
    start = 0
    for k, board in enumerate(boards):
        residuals = fit.residuals_px[start : start + len(board.pixels)]
        board_rho_deg = rho_deg[start : start + len(board.pixels)]
        start += len(board.pixels)
        places = _places(given[kept_index[k]])
        for column, place in places:
            on = board.grid[:, column] == place
            if on.sum() >= 2:
                lines.append(
                    FittedLine(
                        arcs=(first_arc[kept_index[k]] + places.index((column, place)),),
                        image_index=board.image_index,
                        points=int(on.sum()),
                        rms_px=float(np.sqrt(np.mean(residuals[on] ** 2))),
                        max_px=float(residuals[on].max()),
                        family=2 * k + column,
                        elevation_deg=(float(board_rho_deg[on].min()), float(board_rho_deg[on].max())),
                    )
                )
    report = LineFitReport(
        model=fit.kind,
        sigma_px=sigma,
        lines=tuple(lines),
        rejected=tuple(
            RejectedArc(
                arc=first_arc[k],
                image_index=given[k].image_index,
                reason=f"board {k + 1} (image {given[k].image_index + 1}): {why}",
                rms_px=rms,
            )
            for k, why, rms in rejected
        ),
        families=2 * len(boards),
        vertical_lines=0 if vertical is None else int(vertical[1]),
        model_selection_cv_rms_px=dict(scores),
        elevation_range_deg=(float(rho_deg.min()), float(rho_deg.max())),
        empty_bands_deg=empty_bands(rho_deg, annulus_deg(radial, circles, r_max)),
        azimuth_source="given" if options.azimuth_zero is not None else "image angle 0",
        handedness_source="given" if options.s is not None else ("mirror" if circles.cutoff is not None else "lens"),
        boards=len(boards),
        corners=int(n),
        corner_rms_px=float(np.sqrt(np.mean(fit.residuals_px**2))),
        board_axis_deg=tuple(float(a) for a in board_axis_deg(fit.poses)),
        terms=choice,
        # (a law chosen from the corners is not taken as known: the band leaves the camera free to stretch)
        projection=board_band(
            functools.partial(project, layout=fit.layout),
            fit.kind,
            axis,
            fit.params,
            fit.poses,
            board_points(fit.poses, boards),
            jacobian,
            boards,
            circles,
            sigma,
            options.model == "auto",
        ),
    )
    return LineFit(model, np.asarray(covariance[2:count, 2:count], dtype=np.float64), report)


def _places(board: Board) -> list[tuple[int, int]]:
    """The board's lines as (grid column that is constant, its value): its rows (1, row), then columns (0, column)."""
    return [(1, int(r)) for r in np.unique(board.grid[:, 1])] + [(0, int(c)) for c in np.unique(board.grid[:, 0])]


def _first_arcs(boards: Sequence[Board]) -> list[int]:
    """Index in :func:`board_arcs` of each board's first line."""
    counts = [len(_places(board)) for board in boards]
    return [int(x) for x in np.concatenate([[0], np.cumsum(counts)[:-1]])]


def board_arcs(boards: Sequence[Board]) -> list[EdgeArc]:
    """Each board's rows, then its columns, as arcs through their corners (for the overlay), boards in order."""
    arcs = []
    for board in boards:
        for column, place in _places(board):
            on = board.grid[:, column] == place
            order = np.argsort(board.grid[on, 1 - column])
            arcs.append(EdgeArc(board.pixels[on][order], board.image_index, 0.0))
    return arcs


def camera_project(fit: LineFit) -> Callable[[FloatArray], FloatArray]:
    """The fitted camera's pixels (n, 2) of points (n, 3) in the fit's camera axes (before any levelling), as the
    fit projects them: for a board's corners held out of the fit (its pose fitted under this camera)."""
    model = fit.model
    return lambda points: model.with_terms(
        project(model.radial.kind, model.axis, np.array([0.0, 0.0, *model.radial.coefficients]), points)
    )


def camera_lift(fit: LineFit) -> Callable[[FloatArray], FloatArray]:
    """The fitted camera's unit rays (n, 3) of pixels (n, 2), in the axes of :func:`camera_project`."""
    model = fit.model
    inverse = InverseRadial.of(model.radial, 0.0)
    return lambda pixels: pixel_rays(model.radial_pixels(pixels), model.centre, inverse).d
