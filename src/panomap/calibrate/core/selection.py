"""Model choice by cross-validation (paper 2.1 fits one model; beyond it): which radial model the landmarks
support, and the held-out errors of a refined mount.

Convention: as in :mod:`panomap.calibrate.core.noise`; errors are whitened (standard deviations) or px.

The choice is among the radial models of :mod:`panomap.camera.radial_models` that are monotonic over the
landmarks, cover the annulus (cut-off to image circle) when it is known, and have at least 2.5 landmarks
per parameter (the paper's 5-coefficient polynomial from 13), by leave-one-out (k-fold above
``EXACT_LOO_MAX`` landmarks): the model with fewest parameters whose score is within one standard error of
the best wins (the one-standard-error rule); the camera's law (the central mirror cameras' where the image
shows a cut-off disc, else the fisheye lenses') within two.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ...camera.radial_models import RadialKind
from ...camera.valid_range import annulus_coverage_problem, is_monotonic
from ...errors import PanomapError
from ...geometry import FloatArray
from .noise import Observations, observation_residuals, prediction_se, rim_slack_px
from .refine import MountOptions, MountProblem, MountSolution, joint_fit, residual_parts
from .start import separable_fit

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


IndexArray = NDArray[np.intp]


# In the automatic choice a model needs this many landmarks per parameter. Below it a flexible model wins
# the leave-one-out score by chance too often: on 10 landmarks, the paper's 5-coefficient polynomial won on
# a fisheye in 2 trials of 20 and bent to 6-8 px between them, where the true 1- or 2-term model kept 2-4 px.
LANDMARKS_PER_PARAMETER = 2.5


# Leave-one-out is exact up to this many landmarks; above, k-fold cross-validation keeps the cost linear.
EXACT_LOO_MAX = 40


CV_FOLDS = 10


def held_out_folds(data: Observations, members: IndexArray) -> list[IndexArray]:
    """Positions (into ``members``) held out together: one each up to ``EXACT_LOO_MAX`` landmarks, else
    ``CV_FOLDS`` folds dealt in elevation order (each fold spans the landmarks' elevations)."""
    if members.size <= EXACT_LOO_MAX:
        return [np.array([position]) for position in range(members.size)]
    order = np.argsort(data.rho[members], kind="stable")
    return [order[fold::CV_FOLDS] for fold in range(CV_FOLDS)]


def leave_one_out(
    kind: RadialKind, data: Observations, subset: FloatArray, studentized: bool = False
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
    for positions in held_out_folds(data, members):
        others = subset.copy()
        others[members[positions]] = False
        try:
            radial, phi0 = separable_fit(kind, data, others)
        except PanomapError:
            continue
        held = members[positions]
        extra = prediction_se(radial, data, others, held) if studentized else None
        errors = observation_residuals(radial, phi0, data, held, extra)
        whitened[positions] = errors.whitened_norm
        pixels[positions] = errors.pixel_norm
    return np.where(np.isfinite(whitened), whitened, np.inf), np.where(np.isfinite(pixels), pixels, np.inf)


def acceptable(
    kind: RadialKind, data: Observations, subset: FloatArray, annulus: tuple[float, float] | None
) -> str | None:
    """Why ``kind`` cannot serve (None when it can): no fit, not monotonic, does not cover the annulus."""
    try:
        radial, _ = separable_fit(kind, data, subset)
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


def select_model(
    candidates: tuple[RadialKind, ...],
    data: Observations,
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
        problem = acceptable(kind, data, subset, annulus)
        if problem:
            reasons[name] = problem
            selection[name] = math.inf
            continue
        if len(candidates) == 1:
            return kind, {}
        whitened, pixels = leave_one_out(kind, data, subset)
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


def held_out_errors(
    problem: MountProblem,
    solution: MountSolution,
    subset: FloatArray,
    folds: list[IndexArray],
    options: MountOptions,
) -> tuple[FloatArray, FloatArray]:
    """Whitened and pixel errors of each landmark of ``subset`` under a joint fit made without its fold.

    ``folds`` are positions into ``np.flatnonzero(subset)``; each fit starts
    from ``solution`` (the fit on all of them). A fold whose fit fails counts
    as infinitely wrong.
    """
    members = np.flatnonzero(subset)
    whitened = np.full(members.size, np.inf)
    pixels = np.full(members.size, np.inf)
    for positions in folds:
        others = subset.copy()
        others[members[positions]] = False
        try:
            fold = joint_fit(problem, solution, others, options)
        except PanomapError:
            continue
        errors = residual_parts(problem, fold, members[positions])
        whitened[positions] = errors.whitened_norm
        pixels[positions] = errors.pixel_norm
    bad = ~np.isfinite(whitened)
    return np.where(bad, np.inf, whitened), np.where(bad | ~np.isfinite(pixels), np.inf, pixels)
