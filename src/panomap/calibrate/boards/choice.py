"""Boards or lines: the camera that explains both the boards' corners and the images' straight lines.

Convention: as :mod:`.fit` (pixels px, rays in the camera's axes of :mod:`..lines.rays`).

The two fits fail in opposite ways. Straight lines leave the scale of the elevations loose, and on
real rooms the line fit can settle at a wrong scale (tens of px off) with every line straight; a board
pins the scale through its perspective but only where it is held, and one or two small boards leave
the radius beyond them loose. Each fit's camera is therefore scored on the other's data: the corners
under the line fit's camera (each board's pose refitted, the camera held), the lines under the boards'
camera (each line's plane refitted, the camera held); each RMS over that fit's own (its noise), squared,
summed: ``(corners RMS / corner noise)^2 + (lines RMS / line noise)^2`` (lines beyond the radius the boards'
camera reaches are not tested). The boards' camera is kept unless the lines' sum is ``LINES_MARGIN`` times
lower. With ``TRUSTED_BOARDS`` boards or more the boards are kept without the line fit: spread boards
pin the radius everywhere they are held, and the line fit of many images is slow. Boards that all face the
camera's axis pin no scale (:mod:`..lines.stretch`): their camera is not taken, and where the lines cannot
pin it either, the command says what the boards lack.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ...errors import PanomapError
from ..circles import ImageCircles
from ..lines.arcs import EdgeArc
from ..lines.fit import MIN_LINES, LineFit, LineFitOptions, fit_lines
from ..lines.objective import LineData, evaluate
from ..lines.rays import InverseRadial
from .detect import Board
from .fit import MIN_CORNERS, board_arcs, fit_boards, pose_of, residuals_under, sparsity
from .off_board import on_boards

# scipy is imported where it is used: its import would cost every command (a video's start-up too) 0.4 s.

# With this many boards or more, the boards' camera is kept without the line fit.
TRUSTED_BOARDS = 3
# The lines' camera is kept only when its sum is this many times lower: where it fails, it fails by tens of px
# (a wrong basin of the loose scale, every line straight; on the real fisheye's images 99 and 112 px, with
# sums within 20% of the boards'), where the boards fail, by a few.
LINES_MARGIN = 2.0
# Lines within this fraction of the radius the boards' f_r reaches are tested under it.
REACH_FRACTION = 0.98


@dataclass(frozen=True)
class LearnedCamera:
    """The camera learned from an image set, where from, and what its report's lines index.

    Attributes
    ----------
    fit : LineFit
    source : {"checkerboards", "lines"}
    arcs : list of EdgeArc
        What ``fit.report`` indexes: the boards' rows and columns, or the edge arcs.
    notes : list of str
        Warnings for the user: what failed.
    choice : str or None
        Which camera was kept and why, where both fits were made.
    """

    fit: LineFit
    source: str
    arcs: list[EdgeArc]
    notes: list[str]
    choice: str | None = None


def learn_camera(
    boards: Sequence[Board],
    arcs: Sequence[EdgeArc],
    circles: ImageCircles,
    options: LineFitOptions,
    progress: Callable[[str], None] | None = None,
) -> LearnedCamera:
    """The camera of an image set from its checkerboards and its edge arcs (either may be empty).

    Raises
    ------
    PanomapError
        As the line fit does, where the boards give no camera either.
    """
    say = progress or (lambda _step: None)
    notes: list[str] = []
    board_fit: LineFit | None = None
    if sum(len(board.pixels) for board in boards) >= MIN_CORNERS:
        say("fitting the camera to the checkerboards")
        try:
            board_fit = fit_boards(boards, circles, options, progress=say, arcs=arcs)
            board_fit.camera_range(circles.cutoff_radius or 0.0, circles.outer_radius)  # it makes a table
        except PanomapError as exc:
            board_fit = None
            notes.append(f"the checkerboards gave no camera ({exc.summary}); learning from the lines instead")
    flat = board_fit.refusal() if board_fit is not None else None  # boards that all face the axis
    if flat is not None:
        notes.append(f"{flat.splitlines()[0]}; learning from the lines instead")
        board_fit = None
    if board_fit is not None and (board_fit.report.boards >= TRUSTED_BOARDS or not arcs):
        return LearnedCamera(board_fit, "checkerboards", board_arcs(boards), notes)
    say("fitting the camera to the lines")
    try:
        # a board's own lines are straight lines like any, but run any way its holder tilts it: no vertical
        line_fit = fit_lines(arcs, circles, options, progress=say, on_board=on_boards(arcs, boards))
        refusal = line_fit.refusal()
        if refusal is not None:  # the picture cannot stand behind the lines' camera (lines.agreement)
            raise PanomapError(refusal)
    except PanomapError:
        if flat is not None:  # what the user's boards lack says more than what the lines lack
            raise PanomapError(flat) from None
        if board_fit is None:
            raise
        return LearnedCamera(board_fit, "checkerboards", board_arcs(boards), notes)
    if board_fit is None:
        return LearnedCamera(line_fit, "lines", list(arcs), notes)
    say("checking the boards' camera against the lines and the lines' against the boards")
    used = [b for b in boards if len(b.pixels) >= 4]
    boards_score = 1.0 + _ratio(_line_rms(board_fit, line_fit, arcs, circles), line_fit.report.rms_px) ** 2
    lines_score = _ratio(_corner_rms(line_fit, used), board_fit.report.corner_rms_px) ** 2 + 1.0
    figures = f"boards' camera {boards_score:.1f}, lines' camera {lines_score:.1f}"
    if lines_score * LINES_MARGIN < boards_score:
        choice = (
            f"the lines' camera explains the boards' corners and the lines better than the boards' ({figures}: "
            "each RMS over its own fit's, squared, summed): learned from the lines"
        )
        return LearnedCamera(line_fit, "lines", list(arcs), notes, choice)
    choice = (
        f"the boards' camera explains the lines and the corners better than the lines' ({figures}: each RMS "
        "over its own fit's, squared, summed): learned from the checkerboards"
    )
    return LearnedCamera(board_fit, "checkerboards", board_arcs(boards), notes, choice)


def _ratio(rms_px: float, noise_px: float) -> float:
    return rms_px / max(noise_px, 1e-3) if math.isfinite(rms_px) else math.inf


def _corner_rms(fit: LineFit, boards: Sequence[Board]) -> float:
    """RMS (px) of the corners under ``fit``'s camera (centre and f_r), each board's pose refitted."""
    model = fit.model
    params = np.array([*model.centre, *model.radial.coefficients])
    kind, axis = model.radial.kind, model.axis
    reach = max(float(np.hypot(*(b.pixels - model.centre).T).max()) for b in boards) * 1.02
    try:
        inverse = InverseRadial.of(model.radial, reach)
    except PanomapError:
        return math.inf
    poses = np.concatenate([pose_of(board, model.centre, inverse) for board in boards])

    def fun(x: np.ndarray) -> np.ndarray:
        return residuals_under(kind, axis, params, x, boards)

    from scipy.optimize import least_squares

    solution = least_squares(fun, poses, jac_sparsity=sparsity(0, boards), x_scale="jac", method="trf", max_nfev=200)
    return float(np.sqrt(np.mean(solution.fun**2) * 2.0))


def _line_rms(board_fit: LineFit, line_fit: LineFit, arcs: Sequence[EdgeArc], circles: ImageCircles) -> float:
    """RMS (px) of the line fit's lines' points from their planes under the boards' camera (planes refitted)."""
    model = board_fit.model
    try:  # the radius up to which the boards' f_r rises: lines beyond it are not tested (the boards say nothing there)
        limit = REACH_FRACTION * float(InverseRadial.of(model.radial, 0.0).r[-1])
    except PanomapError:
        return math.inf
    lines = [np.concatenate([arcs[k].pixels for k in line.arcs]) for line in line_fit.report.lines]
    lines = [p for p in lines if float(np.hypot(*(p - model.centre).T).max()) < limit]
    if len(lines) < MIN_LINES:
        return 0.0
    reach = max(float(np.hypot(*(p - model.centre).T).max()) for p in lines) * 1.01
    params = np.array([*model.centre, *model.radial.coefficients])
    trial = evaluate(model.radial.kind, model.axis, params, LineData.of(lines, reach))
    if trial is None:
        return math.inf
    return float(np.sqrt(np.mean(trial.distances_px**2)))
