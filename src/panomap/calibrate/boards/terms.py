"""Which image terms (aspect, skew, decentering, fields) the boards' camera keeps: those that predict images
left out.

Convention: as :mod:`.fit` (pixels px, a board's corners in squares, rays in the camera's axes).

A real sensor's pixels may be a little taller than wide, its columns a little skewed, its lens or mirror a
little off its axis (:mod:`panomap.camera.image_terms`); each term is one or two more parameters, which
always bring the corners of the images fitted closer, and on a few images follow their noise as readily as
the camera. So each is kept only where it predicts images the fit did not see: the images are dealt in
turn into ``FOLDS`` folds (whole images, so a board never helps predict itself); for a set of terms, the
camera (the radial kind as chosen, its centre, coefficients and those terms) is fitted to the boards of
every fold but one, from the camera fitted to all, and each board of the fold left out has its pose fitted
to its corners under that camera, held: the RMS (px) of those corners over every fold is the set's
held-out RMS (BabelCalib's held-out measure within the images given). Forward, greedily: from no term,
the term whose addition lowers the held-out RMS most (but one with fewer values, unless the larger one's is
``MIN_GAIN`` lower still; the smooth field is not tried beside the decentering or the thin prism, whose
quadratic parts it holds) is kept where it lowers it by more than its own noise: the mean, over the images,
of the drop of each image's mean squared distance must exceed ``SE_FACTOR`` times its standard error (a
term that helps on most images, not one that one image's luck favours), and the held-out RMS must fall by
``MIN_GAIN`` of itself (a gain worth a parameter); then the next, among the rest; until none does (a term
that alone lowers it not at all is not tried again: at most six sets of terms, each fitted ``FOLDS`` times,
from the camera fitted to all).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np

from ...camera.image_terms import TERM_KINDS, TERMS, ImageTerms, check_term_names, parameter_count
from ...geometry import FloatArray
from ..core.term_choice import TermChoice
from .detect import Board
from .solve import BlockJacobian, least_squares_blocks

# Folds of images, at most; fewer images than MIN_IMAGES leave nothing to hold out: no term is kept.
FOLDS = 5
MIN_IMAGES = 3
# A term is kept where it lowers the held-out mean squared distance, image by image, by more than this many
# standard errors of that gain (the one-standard-error rule), and the held-out RMS by at least MIN_GAIN of
# itself: the folds share their training images, so the images' gains are not independent and their standard
# error is too small on a few images (a camera tilted on its mount, 5 images: decentering lowered the held-out
# RMS 1%, past one standard error, and moved the rays 2.6 px at p90 where the camera without it is within 1.2).
# Real sets' kept terms lower it 6-7%, simulated ones' 13-22%.
SE_FACTOR = 1.0
MIN_GAIN = 0.03
# Each fold's fit: damped Gauss-Newton steps (:mod:`.solve`), at most GN_STEPS, until a step lowers the cost by
# less than GN_TOLERANCE of it (the held-out RMS is wanted to a small fraction of MARGIN).
GN_STEPS = 30
GN_TOLERANCE = 1e-5


@dataclass(frozen=True)
class TermLayout:
    """The image terms a fit frees (:mod:`panomap.camera.image_terms`, in its order) and their scale R (px):
    their values follow f_r's coefficients in the camera's parameters."""

    kept: tuple[str, ...] = ()
    radius_px: float = 1.0

    @property
    def count(self) -> int:
        return parameter_count(self.kept)

    def terms(self, values: FloatArray) -> ImageTerms:
        return ImageTerms(self.kept, tuple(float(v) for v in values), self.radius_px)


NO_TERMS = TermLayout()


# The fit's residuals and their Jacobian in blocks (:func:`.fit._residuals`, :func:`.fit._jacobian_blocks`): x
# (the camera, its terms' values, then the poses), the radial kind, the axis, the boards, their observed corners
# (n, 2) and a TermLayout.
ProblemFunctions = tuple[Callable[..., FloatArray], Callable[..., Any]]


def image_folds(boards: Sequence[Board], folds: int = FOLDS) -> list[list[int]]:
    """The boards' indices in each fold: the images (in order of first appearance) dealt in turn into ``folds``
    folds (at most one per image), each image's boards together."""
    images = list(dict.fromkeys(board.image_index for board in boards))
    count = min(folds, len(images))
    fold_of = {image: k % count for k, image in enumerate(images)}
    return [[b for b, board in enumerate(boards) if fold_of[board.image_index] == k] for k in range(count)]


@dataclass(frozen=True)
class HeldOut:
    """A set of terms' held-out corners, image by image: each image's sum of squared corner distances (px^2)
    and its corners, in the order of :func:`image_folds`' images."""

    squares: FloatArray
    corners: FloatArray

    @property
    def rms_px(self) -> float:
        return float(math.sqrt(self.squares.sum() / self.corners.sum()))

    def gain_over(self, other: HeldOut) -> tuple[float, float]:
        """How much lower this set's mean squared distance is than ``other``'s (px^2), image by image: the
        mean of the images' differences and its standard error."""
        differences = other.squares / other.corners - self.squares / self.corners
        return float(differences.mean()), float(differences.std(ddof=1) / math.sqrt(differences.size))


def choose_terms(
    fit: Any, boards: Sequence[Board], axis: str, radius_px: float, asked: str, functions: ProblemFunctions
) -> tuple[tuple[str, ...], TermChoice]:
    """The terms to keep for the camera ``fit`` (a :class:`.fit._Fit` without terms, of all ``boards``).

    ``asked``: ``"auto"`` (the held-out choice above), ``"none"``, or terms' names joined by commas (kept as
    given, without a choice). ``radius_px`` is the decentering terms' scale R; ``functions`` the fit's
    residuals and Jacobian.
    """
    if asked == "none":
        return (), TermChoice((), (), 0, "none asked for")
    if asked != "auto":
        names = check_term_names([name.strip() for name in asked.split(",") if name.strip()])
        return names, TermChoice(names, (), 0, "as asked for")
    folds = image_folds(boards)
    if len(folds) < MIN_IMAGES:
        return (), TermChoice((), (), 0, f"{len(folds)} image(s): at least {MIN_IMAGES} are needed to leave images out")

    def score(names: tuple[str, ...]) -> HeldOut | None:
        return held_out(fit, TermLayout(names, radius_px), boards, axis, folds, functions)

    kept: tuple[str, ...] = ()
    current = score(kept)
    if current is None:
        return (), TermChoice((), (((), math.inf),), len(folds), "the fit without terms failed on a fold")
    base = current
    tried = [(kept, current.rms_px)]
    candidates = list(TERMS)
    while candidates:
        scored = [(check_term_names([*kept, t]), t) for t in candidates if not _overlapping([*kept, t])]
        results = [(names, score(names), t) for names, t in scored]
        tried += [(names, math.inf if out is None else out.rms_px) for names, out, _ in results]
        better = [(names, out, t) for names, out, t in results if out is not None and out.rms_px < current.rms_px]
        if not kept:  # a term that alone predicts the images left out no better is not tried again
            candidates = [t for _, _, t in better]
        if not better:
            break
        names, out, term = _parsimonious(better)
        gain, error = out.gain_over(current)
        if gain <= SE_FACTOR * error or out.rms_px > (1.0 - MIN_GAIN) * current.rms_px:
            break
        kept, current = names, out
        candidates = [t for t in candidates if t != term]
    images = int(base.corners.size)
    reason = (
        f"held-out RMS {base.rms_px:.3f} px without terms, {current.rms_px:.3f} px with them, over {images} images "
        f"left out in {len(folds)} folds"
        if kept
        else f"none predicted the {images} images left out in {len(folds)} folds (held-out RMS {base.rms_px:.3f} px "
        f"without terms) better by more than its standard error and {MIN_GAIN:.0%}"
    )
    return kept, TermChoice(kept, tuple(tried), len(folds), reason)


def held_out(
    fit: Any,
    layout: TermLayout,
    boards: Sequence[Board],
    axis: str,
    folds: list[list[int]],
    functions: ProblemFunctions,
) -> HeldOut | None:
    """The held-out corners of a set of terms (``layout``) over ``folds``: the
    camera fitted to every other fold's boards from ``fit`` (the camera without terms and every board's pose,
    fitted to all ``boards``), each left-out board's pose fitted to its corners under it, held. None where a
    fold's fit is singular or runs beyond the terms' limits."""
    residuals = functions[0]

    start = np.concatenate([fit.params, _identity_values(layout.kept)])
    count = start.size
    images = list(dict.fromkeys(board.image_index for board in boards))
    squares = np.zeros(len(images))
    corners = np.zeros(len(images))
    for fold in folds:
        left_out = set(fold)
        train = [boards[b] for b in range(len(boards)) if b not in left_out]
        test = [boards[b] for b in fold]
        observed = np.concatenate([board.pixels for board in train])
        poses = fit.poses[[b for b in range(len(boards)) if b not in left_out]].ravel()
        problem = (fit.kind, axis, train, observed, layout)
        trained = _gauss_newton(
            partial(_camera_residuals, problem=problem, functions=functions),
            partial(_camera_jacobian, problem=problem, functions=functions),
            np.concatenate([start, poses]),
        )
        if trained is None or layout.terms(trained[count - layout.count : count]).beyond_limits():
            return None
        params = trained[:count]
        observed = np.concatenate([board.pixels for board in test])
        problem = (fit.kind, axis, test, observed, layout)
        held = _gauss_newton(
            partial(_camera_residuals, problem=problem, functions=functions, camera=params),
            partial(_camera_jacobian, problem=problem, functions=functions, camera=params),
            fit.poses[fold].ravel(),
        )
        if held is None:
            return None
        distances = residuals(np.concatenate([params, held]), fit.kind, axis, test, observed, layout).reshape(-1, 2)
        owner = np.repeat([images.index(board.image_index) for board in test], [len(b.pixels) for b in test])
        np.add.at(squares, owner, np.sum(distances**2, axis=1))
        np.add.at(corners, owner, 1.0)
    return HeldOut(squares, corners)


def _camera_residuals(
    x: FloatArray, problem: tuple[Any, ...], functions: ProblemFunctions, camera: FloatArray | None = None
) -> FloatArray:
    """The corners' residuals (2N,) px of ``problem`` (kind, axis, boards, observed, layout) at ``x``: the
    camera and the poses, or the poses alone under ``camera``, held."""
    full = x if camera is None else np.concatenate([camera, x])
    return np.asarray(functions[0](full, *problem), dtype=np.float64)


def _camera_jacobian(
    x: FloatArray, problem: tuple[Any, ...], functions: ProblemFunctions, camera: FloatArray | None = None
) -> BlockJacobian:
    """The Jacobian (in blocks) of :func:`_camera_residuals` in ``x``."""
    if camera is None:
        return functions[1](x, *problem)
    jacobian: BlockJacobian = functions[1](np.concatenate([camera, x]), *problem, camera=False)
    return jacobian.poses_only()


def _gauss_newton(
    fun: Callable[[FloatArray], FloatArray], jac: Callable[[FloatArray], BlockJacobian], x0: FloatArray
) -> FloatArray | None:
    """The least-squares minimum of ``fun`` near ``x0`` by damped Gauss-Newton (Levenberg-Marquardt) steps
    (:func:`.solve.least_squares_blocks`): a fold's fit starts at the camera fitted to all, a few steps from its
    own. None where the normal equations are singular. It stops after ``GN_STEPS`` steps where it has not met its
    tolerance: the cost only falls, so a fold's score is then a little high (against the terms tried: at most 0.5%
    in the cases measured)."""
    try:
        return least_squares_blocks(fun, jac, x0, GN_STEPS, GN_TOLERANCE).x
    except np.linalg.LinAlgError:
        return None


def _parsimonious(better: list[tuple[tuple[str, ...], HeldOut, str]]) -> tuple[tuple[str, ...], HeldOut, str]:
    """The candidate to add: the one with fewest values, unless one with more lowers the held-out RMS by
    ``MIN_GAIN`` of its own (the smooth field's 13 values tie with the decentering's two on Kaidan's images)."""
    ordered = sorted(better, key=lambda item: (parameter_count(item[0]), item[1].rms_px))
    chosen = ordered[0]
    for candidate in ordered[1:]:
        if candidate[1].rms_px < (1.0 - MIN_GAIN) * chosen[1].rms_px:
            chosen = candidate
    return chosen


def _overlapping(names: Sequence[str]) -> bool:
    """Whether ``names`` hold the smooth field beside the decentering or the thin-prism field (its monomials hold
    their quadratic parts: together they are degenerate)."""
    return "smooth" in names and bool({"decentering", "field"} & set(names))


def _identity_values(kept: Sequence[str]) -> FloatArray:
    return np.array([value for name in kept for value in TERM_KINDS[name].identity], dtype=np.float64)
