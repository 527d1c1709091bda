"""Outliers (beyond the paper): landmarks that disagree with the rest, found by their held-out errors, and the
choice of model and inliers made together.

Convention: as in :mod:`panomap.calibrate.core.noise`.

With the model chosen robustly (its score trimmed of the largest fifth of the errors), the landmark whose
leave-one-out residual is largest (studentized: whitened by its noise and the others' prediction error
together) is dropped while it exceeds 5 robust standard deviations; dropped landmarks are named in the
report; the model is chosen again on the rest.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ...camera.radial_models import RadialKind
from ...errors import PanomapError
from ...geometry import FloatArray
from ..core import selection
from ..core.noise import Observations
from ..core.selection import LANDMARKS_PER_PARAMETER, acceptable, leave_one_out, select_model

# A landmark is an outlier where its held-out error exceeds this many robust sigmas, the error whitened by
# its own noise and the standard error of the others' prediction together (studentized). Whitened by its
# noise alone, a good landmark at an end of the elevations, predicted by extrapolation, stood out: an
# orthographic fisheye's rim landmark went (5.1 sigmas; 2.4 studentized), and the fit then turned back
# short of the circle. Not four: on a tilted camera the level fit's residuals run in a wave, and at four the
# search before the mount's dropped two good landmarks of a parabolic mirror 1.3 deg off (27.7 px).
OUTLIER_SIGMAS = 5.0


# Median of the norm of a 2-D standard normal vector: sqrt(2 ln 2).
MEDIAN_2D_NORM = math.sqrt(2 * math.log(2))


def choose(
    candidates: tuple[RadialKind, ...],
    data: Observations,
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
            kind, _ = select_model(candidates, data, inliers, annulus, robust=True)
            fewer = _drop_worst(kind, data, inliers, candidates, annulus)
            if fewer is None:
                break
            inliers = fewer
    kind, selection = select_model(candidates, data, inliers, annulus, robust=False)
    return inliers, kind, selection


def choose_start(
    candidates: tuple[RadialKind, ...],
    data: Observations,
    annulus: tuple[float, float] | None,
    robust: bool,
    may_tilt: bool,
) -> tuple[FloatArray, RadialKind, dict[str, float], bool]:
    """:func:`choose` with the annulus, and whether its choice covers it. Where no model covers it: the
    outliers found without the annulus dropped and the choice made again with it; failing that, where a tilt
    may be fitted, the choice without the annulus (a start for the tilt), flagged as not covering."""
    try:
        return (*choose(candidates, data, annulus, robust), True)
    except PanomapError as exc:
        failed = exc
    loose = choose(candidates, data, None, robust) if robust or may_tilt else None
    if loose is not None and robust and not loose[0].all():
        # An outlier (a landmark far off near the rim) can itself push every model off the annulus: found
        # without the annulus, it is dropped, and the choice made again with the annulus on the rest.
        try:
            return (*choose(candidates, data, annulus, robust, start=loose[0]), True)
        except PanomapError:
            pass
    if not may_tilt or loose is None:
        raise failed
    return (*loose, False)


def _drop_worst(
    kind: RadialKind,
    data: Observations,
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
    whitened, _ = leave_one_out(kind, data, inliers, studentized=True)
    scale = max(1.0, float(np.median(whitened)) / MEDIAN_2D_NORM)
    beyond = whitened > OUTLIER_SIGMAS * scale
    if not beyond.any():
        return None
    if count <= selection.EXACT_LOO_MAX:
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
    data: Observations,
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
            if kind is not kinds[0] and acceptable(kind, data, rest, annulus):
                continue
            others, _ = leave_one_out(kind, data, rest)
            if np.all(np.isfinite(others)):
                score = min(score, float(np.sqrt(np.mean(np.square(others)))))
        scores.append(score)
    best = int(np.argmin(scores))
    return worst if not math.isfinite(scores[best]) else int(candidates[best])
