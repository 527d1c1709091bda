"""Where the fit starts (paper 2.1, beyond Algorithm 1): the camera's axis, its handedness, and the first
values of f_r and phi0 with the centre fixed.

Convention: as in :mod:`panomap.calibrate.core.noise`. The axis is ``"down"`` where the image radius grows with
elevation; the handedness ``s`` is the sign under which the landmarks agree best on one phi0; f_r and phi0
then separate while the centre is fixed: f_r by (weighted) least squares on (rho, r), phi0 as the weighted
circular mean of ``phi - s*theta``.
"""

from __future__ import annotations

import math

import numpy as np

from ...camera.radial import RadialFunction, fit_radial
from ...camera.radial_models import RadialKind
from ...errors import PanomapError
from ...geometry import FloatArray, pixel_polar
from .noise import Observations, radial_weights, tangential_sigma

WEIGHT_ITERATIONS = 3


def rank_correlation(a: FloatArray, b: FloatArray) -> float:
    """Spearman's rank correlation of ``a`` and ``b`` (n,); NaN where either is constant (where SciPy
    would warn, and a warning would be printed before the error that explains it)."""
    if float(np.ptp(a)) == 0.0 or float(np.ptp(b)) == 0.0:
        return math.nan
    from scipy import stats  # here, not at the top: importing SciPy is slow

    return float(stats.spearmanr(a, b).statistic)


def detect_axis(rho: FloatArray, r: FloatArray) -> str:
    """``"down"`` when the image radius grows with elevation, else ``"up"``."""
    correlation = rank_correlation(rho, r)
    if not np.isfinite(correlation) or abs(correlation) < 0.5:
        raise PanomapError(
            "cannot tell from the landmarks whether the camera looks down or up (image radius "
            f"and elevation are not monotonically related, Spearman {correlation:.2f}); "
            "check that world Z is up (a Y-up frame, as CAD tools and game engines use, needs Y and Z swapped), "
            "that the world points and the camera position share units and origin, the centre, "
            "or give the axis"
        )
    return "down" if correlation > 0 else "up"


# Ways landmarks' pixels are given wrong that leave them monotonic in elevation once undone: (row, column)
# for (u, v), and an image scaled by these factors (a preview, a thumbnail).
PIXEL_SCALES = (2.0, 0.5, 4.0, 0.25)


# How monotonic (Spearman) the pixels must be once undone for the hint.
UNDONE_MONOTONIC = 0.9


def pixels_hint(rho: FloatArray, pixels: FloatArray, centre: tuple[float, float], d: FloatArray) -> str:
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


def consistency(delta: FloatArray, weights: FloatArray) -> float:
    w = weights**2
    total = float(w.sum())
    if total <= 0:
        return 0.0
    return float(np.hypot(w @ np.cos(delta), w @ np.sin(delta)) / total)


def handedness(theta: FloatArray, phi: FloatArray, r: FloatArray) -> int:
    """s = +1 or -1: the sign under which the landmarks agree best on one phi0 (weighted by r^2)."""
    if not np.any(r > 1e-9):
        raise PanomapError("no landmark away from the image centre to fix the azimuth")
    plus = consistency(phi - theta, r)
    minus = consistency(phi + theta, r)
    return 1 if plus >= minus else -1


def separable_fit(kind: RadialKind, data: Observations, subset: FloatArray) -> tuple[RadialFunction, float]:
    """f_r and phi0 from the landmarks in ``subset`` (bool mask), the centre fixed; made once per subset."""
    key = (kind, np.asarray(subset, dtype=bool).tobytes())
    if key not in data.fitted:
        try:
            data.fitted[key] = _separable_fit_once(kind, data, subset)
        except PanomapError as exc:
            data.fitted[key] = exc
    made = data.fitted[key]
    if isinstance(made, PanomapError):
        raise made.with_traceback(None)
    return made


def _separable_fit_once(kind: RadialKind, data: Observations, subset: FloatArray) -> tuple[RadialFunction, float]:
    rho, r = data.rho[subset], data.r[subset]
    radial = fit_radial(kind.name, rho, r, data.axis)
    if kind.weighted:
        for _ in range(WEIGHT_ITERATIONS):
            radial = fit_radial(kind.name, rho, r, data.axis, radial_weights(radial, data)[subset])
    if data.azimuth_mode == "paper":
        return radial, 0.0
    delta = data.phi[subset] - data.s * data.theta[subset]
    weights = (r / tangential_sigma(data, data.r)[subset]) ** 2
    return radial, float(np.arctan2(weights @ np.sin(delta), weights @ np.cos(delta)))
