"""What a fit's residuals say, in words: patterns that point to a cause, and what to do.

Convention: residuals are the fit's radial residuals (fitted minus measured
radius, px) of the inlier landmarks, against their azimuth theta and elevation
rho (rad); ``pixel_sigma`` is the landmarks' pixel noise (px).

- **Sinusoidal in azimuth** (``a cos(theta) + b sin(theta)``): the image centre
  is off, or the camera's axis is not vertical (a tilted mount).
- **A trend in elevation** (a low-degree polynomial in rho): the radial model
  does not follow the camera.
- **Dropped landmarks**: a world point or pixel measured wrong.
- **Residuals far above the noise** (over ``FAR_ABOVE_NOISE`` times what the noise model
  expects, landmark by landmark (:func:`noise_ratio`): the pixel noise, and the world noise as
  the camera sees it, radially through f_r' and tangentially through r): no camera at this position sees these world
  points at these pixels; many landmarks are wrong together (units, axes, a height).
- **A tilt about the centre as found** (the mount ``tilt, centre as found``): near the nadir a
  tilt of the axis and a centre off the rim's look alike, and the fit chose the tilt; said so,
  with what tells the two apart.
- **A centre guessed, then moved** (no rim in the image: the fit started from the frame's
  middle and moved the centre more than ``GUESS_SHIFT_PX``, level): without a rim a tilt and a
  moved centre look alike except near the horizon; simulated full-frame fisheyes tilted 1-3 deg
  had the centre moved 7-34 px in its stead.

A pattern is reported when it explains most of the residuals' variance and
its size is well above the noise (``PATTERN_SIGMAS`` pixel sigmas), with at
least ``MIN_LANDMARKS`` inliers to see it.
"""

from __future__ import annotations

import math

import numpy as np

from ...geometry import pixel_polar
from ..core.report import CENTRE_AS_FOUND
from .fit import CameraFit

PATTERN_SIGMAS = 2.0
EXPLAINED_FRACTION = 0.5
MIN_LANDMARKS = 8
GUESS_SHIFT_PX = 2.0
# A centre refined further from the rim's than this (px, and this share of the landmarks' largest radius) says
# the pixels are not of the image: the five real cameras' rims are 0.7-2.3 px (0.25-1% of the radius) off axis.
FAR_FROM_RIM_PX = 10.0
FAR_FROM_RIM_SHARE = 0.025
# A centre refined to its start's transpose says (row, column) pixels only where the two are this far apart (px).
TRANSPOSED_APART_PX = 8.0
# RMS residual against the RMS the noise model expects. Measured: 288 fits of 10-12 noisy landmarks (the 12
# cameras of bench_fit, spread, random and with an outlier, 8 seeds each) 0.78 median, 1.67 at most; 40 trials of
# bench_image_fit (tilted, the tape off, circles cut, full frames) 0.83 median, 1.31 at most.
FAR_ABOVE_NOISE = 4.0


def diagnose(fit: CameraFit, centre_guessed: bool = False) -> list[str]:
    """Sentences on the patterns in ``fit``'s residuals (empty when there is none); ``centre_guessed``: the
    fit started from a centre the image does not show (the frame's middle, where no rim was found)."""
    notes = []
    keep = fit.inliers
    residual = fit.radial_residuals_px[keep]
    theta, rho = fit.theta[keep], fit.rho[keep]
    sigma = fit.settings.pixel_sigma_px
    if residual.size >= MIN_LANDMARKS:
        amplitude, towards = _sinusoid(theta, residual)
        if amplitude is not None and amplitude > PATTERN_SIGMAS * sigma:
            notes.append(
                f"the radial residuals swing with azimuth (amplitude {amplitude:.1f} px, largest towards "
                f"{math.degrees(towards):.0f} deg): the image centre is off or the camera is tilted; "
                + (
                    "the centre was refined, so check the mount (is the axis vertical?) and the camera position"
                    if fit.settings.refine_centre
                    else "let the landmarks refine the centre, or check the mount"
                )
                + ("" if fit.mount is None or fit.mount.tilt_mode == "fit" else " (or let the fit find the tilt)")
            )
        trend = _trend(rho, residual)
        if trend is not None and trend > PATTERN_SIGMAS * sigma:
            notes.append(
                f"the radial residuals trend with elevation (by {trend:.1f} px across the landmarks): the radial "
                f"model ({fit.model.radial.kind}) does not follow this camera; let the model be chosen "
                "automatically, or add landmarks across the elevations"
            )
    mount = fit.mount
    if mount is not None and mount.chosen.endswith(CENTRE_AS_FOUND) and mount.tilt_shows:
        notes.append(
            f"the centre was kept where the image shows it and the camera given a tilt of "
            f"{mount.tilt_deg:.2f} deg: near the nadir a tilt and a centre off the rim's look alike, and the "
            "landmarks favour the tilt; if the camera is known to be level, give --tilt none; landmarks near the "
            "horizon tell the two apart"
        )
    level = fit.mount is None or fit.mount.tilt_deg == 0
    if centre_guessed and fit.settings.refine_centre and level and fit.centre_shift_px > GUESS_SHIFT_PX:
        notes.append(
            f"the centre was refined {fit.centre_shift_px:.1f} px from the frame's middle (no rim in the image to "
            "find it): without a rim a tilted axis and a moved centre look alike except near the horizon; if the "
            "camera may be tilted, give its centre from a calibration (--centre), or add landmarks near the horizon"
        )
    if not centre_guessed and _centre_transposed(fit):
        start = fit.centre_start or fit.model.centre
        notes.append(
            f"the centre moved from ({start[0]:.1f}, {start[1]:.1f}), where the image shows it, to "
            f"({fit.model.centre[0]:.1f}, {fit.model.centre[1]:.1f}): that point with u and v swapped. The "
            "landmarks' pixels look like (row, column): give u as the column and v as the row, or every view will "
            "show the image transposed"
        )
    elif not centre_guessed and fit.settings.refine_centre and _centre_moved_far(fit):
        start = fit.centre_start or fit.model.centre
        notes.append(
            f"the centre moved {fit.centre_shift_px:.1f} px from ({start[0]:.1f}, {start[1]:.1f}), where the "
            "circles found in the image put it: further than a rim lies off its camera's axis (a percent of its "
            "radius at most): either the circle found is not the rim (look at panomap centre --overlay), or the "
            "landmarks' pixels are not of this image (its size, not a crop or a scaled copy); --centre gives a "
            "centre from a calibration"
        )
    ratio = noise_ratio(fit)
    rms = float(np.sqrt(np.mean(fit.residuals_px[keep] ** 2))) if np.any(keep) else 0.0
    if ratio > FAR_ABOVE_NOISE:
        notes.append(
            f"the residuals (RMS {rms:.1f} px) are {ratio:.0f} times what the landmarks' noise explains, landmark "
            "by landmark: no camera at this position puts these world points at these pixels; check the world "
            "points' units and axes (Z up, the same units and origin as the camera position), the camera "
            "position, and that each pixel is its world point's"
        )
    if fit.outliers:
        notes.append(
            f"dropped as outliers: {', '.join(fit.outliers)}: their world point or pixel is probably wrong; "
            "measure them again"
        )
    return notes


def _explains(design: np.ndarray, residual: np.ndarray) -> tuple[np.ndarray, float] | None:
    """Least-squares coefficients of ``design`` for ``residual`` and the fraction of variance they explain."""
    total = float(np.sum((residual - residual.mean()) ** 2))
    if total <= 0:
        return None
    coefficients, *_ = np.linalg.lstsq(design, residual, rcond=None)
    left = float(np.sum((residual - design @ coefficients) ** 2))
    return coefficients, 1.0 - left / total


def _sinusoid(theta: np.ndarray, residual: np.ndarray) -> tuple[float | None, float]:
    """Amplitude (px) and azimuth (rad) of the residuals' sinusoid in azimuth, when it explains most of them."""
    found = _explains(np.stack([np.ones_like(theta), np.cos(theta), np.sin(theta)], axis=1), residual)
    if found is None or found[1] < EXPLAINED_FRACTION:
        return None, 0.0
    _, a, b = found[0]
    return float(math.hypot(a, b)), float(math.atan2(b, a)) % (2 * math.pi)


def _trend(rho: np.ndarray, residual: np.ndarray) -> float | None:
    """Range (px) of a quadratic trend of the residuals in elevation, when it explains most of them."""
    x = (rho - rho.mean()) / max(float(np.ptp(rho)), 1e-9)
    found = _explains(np.stack([np.ones_like(x), x, x**2], axis=1), residual)
    if found is None or found[1] < EXPLAINED_FRACTION:
        return None
    values = np.stack([np.ones_like(x), x, x**2], axis=1) @ found[0]
    return float(np.ptp(values))


def noise_ratio(fit: CameraFit) -> float:
    """How many times the inlier landmarks' residuals exceed what the fit's noise model expects of each: the
    RMS over them of residual / expected (1 where the model holds). Each landmark's expected error is its
    pixel noise and its world noise seen from the camera (radially through f_r', tangentially through r).
    Landmark by landmark, not the ratio of two RMS: one landmark next to the camera, whose world noise is a
    large angle, would otherwise hide every other landmark's misfit."""
    keep = np.asarray(fit.inliers, dtype=bool)
    rho = (fit.rho_camera if fit.rho_camera is not None else fit.rho)[keep]
    offset = fit.landmarks.world[keep] - np.asarray(fit.camera_position)
    distance = np.maximum(np.linalg.norm(offset, axis=1), 1e-12)
    horizontal = np.maximum(np.hypot(offset[:, 0], offset[:, 1]), 1e-12)
    world = fit.settings.world_sigma
    radial = np.abs(fit.model.radial.slope(rho)) * world / distance
    tangential = np.abs(fit.model.radial(rho)) * world / horizontal
    variance = 2 * fit.settings.pixel_sigma_px**2 + radial**2 + tangential**2
    whitened = fit.residuals_px[keep] ** 2 / variance
    finite = np.isfinite(whitened)
    return float(np.sqrt(np.mean(whitened[finite]))) if np.any(finite) else 0.0


def _centre_transposed(fit: CameraFit) -> bool:
    """Whether the refinement took the centre from where it started (the rim's) to near that point's transpose
    (v0, u0): what landmarks measured as (row, column) do, as a transposed image fits them as well. Only where
    the two are TRANSPOSED_APART_PX or more apart, and the centre ended within a quarter of that of the
    transpose."""
    if fit.centre_start is None:
        return False
    (u0, v0), (u, v) = fit.centre_start, fit.model.centre
    apart = math.dist((u0, v0), (v0, u0))
    return apart >= TRANSPOSED_APART_PX and math.dist((u, v), (v0, u0)) <= apart / 4


def _centre_moved_far(fit: CameraFit) -> bool:
    """Whether the refinement took the centre further from where it started (the rim's centre) than
    FAR_FROM_RIM_PX and FAR_FROM_RIM_SHARE of the largest landmark radius."""
    if fit.centre_start is None:
        return False
    radius, _ = pixel_polar(fit.landmarks.pixels, fit.model.centre)
    return fit.centre_shift_px > max(FAR_FROM_RIM_PX, FAR_FROM_RIM_SHARE * float(np.max(radius)))
