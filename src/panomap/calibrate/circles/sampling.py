"""Images and profiles: the grey image, intensity profiles along rays (bilinear, smoothed along the
ray), sub-pixel peaks and step levels.

Convention: pixel (u, v), u the column, v the row, the centre of the top-left pixel at (0, 0); radii
in px.
"""

from __future__ import annotations

import math
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from ...geometry import FloatArray
from .thresholds import COARSE_SIDE, EDGE_HALF_WINDOW, LEVEL_SAMPLES, PROFILE_SIGMA_PX, RAYS, STEP


def to_grey(image: NDArray[Any]) -> NDArray[Any]:
    """(H, W) float32 grey levels on a 0..255 scale, from 8- or 16-bit, 1, 3 or 4 channels."""
    scale = 255.0 / 65535.0 if image.dtype == np.uint16 else 1.0
    if image.ndim == 3 and image.shape[2] >= 3:
        grey = cv2.cvtColor(image[..., :3], cv2.COLOR_BGR2GRAY)
    else:
        grey = image.reshape(image.shape[0], image.shape[1])
    return grey.astype(np.float32) * np.float32(scale) if scale != 1.0 else grey.astype(np.float32)


def _edge_strength(samples: NDArray[Any]) -> FloatArray:
    """Gradient magnitude along each ray (grey levels per px), smoothed along it (sigma 2 px); 0 outside the frame.

    Either polarity: a step up or down gives a peak at the step, and a thin bright or dark
    line (its two opposite slopes merged by the smoothing) a peak at its middle.
    """
    gradient = np.abs(np.gradient(samples, axis=1)) / STEP
    gradient = np.where(np.isfinite(gradient), gradient, 0.0).astype(np.float32)
    return np.asarray(cv2.GaussianBlur(gradient, (17, 1), 2.0 / STEP, borderType=cv2.BORDER_REPLICATE), np.float64)


def _downscaled(grey: NDArray[Any]) -> tuple[NDArray[Any], int]:
    """The image shrunk by an integer factor to at most COARSE_SIDE px a side, smoothed; and that factor."""
    height, width = grey.shape
    factor = max(1, math.ceil(max(height, width) / COARSE_SIDE))
    small = cv2.resize(grey, (width // factor, height // factor), interpolation=cv2.INTER_AREA)
    return cv2.GaussianBlur(small, (0, 0), 1.5), factor


def _full_resolution(point: tuple[float, float], factor: int) -> tuple[float, float]:
    """A position in the downscaled image in full-resolution px: sample k is at (k + 0.5) * factor - 0.5."""
    return (point[0] + 0.5) * factor - 0.5, (point[1] + 0.5) * factor - 0.5


def _profiles(
    grey: NDArray[Any], centre: tuple[float, float], radii: FloatArray, rays: int = RAYS, turn_rad: float = 0.0
) -> tuple[NDArray[Any], FloatArray, FloatArray]:
    """Bilinear samples (rays, R) of ``grey`` along rays at ``radii``, turned by ``turn_rad``; NaN off the image."""
    angles = np.linspace(0.0, 2 * math.pi, rays, endpoint=False) + turn_rad
    cos, sin = np.cos(angles), np.sin(angles)
    map_u = (centre[0] + cos[:, None] * radii[None, :]).astype(np.float32)
    map_v = (centre[1] + sin[:, None] * radii[None, :]).astype(np.float32)
    height, width = grey.shape
    samples = cv2.remap(grey, map_u, map_v, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan)
    samples[(map_u < 0) | (map_u > width - 1) | (map_v < 0) | (map_v > height - 1)] = np.nan
    # Smoothed along each ray (sigma 1 px; NaN spreads to the samples it touches): far
    # cheaper than smoothing the whole image, and it is across the rim that noise matters.
    return cv2.GaussianBlur(samples, (13, 1), PROFILE_SIGMA_PX / STEP, borderType=cv2.BORDER_REPLICATE), cos, sin


def _subpixel_peak(values: NDArray[Any], index: NDArray[Any]) -> FloatArray:
    """Parabola vertex through samples index-1, index, index+1 of each row (index inside)."""
    rows = np.arange(values.shape[0])
    left, mid, right = values[rows, index - 1], values[rows, index], values[rows, index + 1]
    denominator = left - 2 * mid + right
    with np.errstate(divide="ignore", invalid="ignore"):
        offset = np.where(denominator != 0, 0.5 * (left - right) / denominator, 0.0)
    return index + np.clip(offset, -0.5, 0.5)


def _step_levels(samples: NDArray[Any], index: NDArray[Any]) -> tuple[FloatArray, FloatArray, NDArray[np.bool_]]:
    """Median level just before and just after each row's edge at ``index``, and whether its window is in the frame."""
    rows = np.arange(samples.shape[0])[:, None]
    count = samples.shape[1]
    near = np.clip(index[:, None] + np.arange(-EDGE_HALF_WINDOW, EDGE_HALF_WINDOW + 1)[None, :], 0, count - 1)
    in_frame = np.all(np.isfinite(samples[rows, near]), axis=1)
    in_frame &= (index >= EDGE_HALF_WINDOW) & (index < count - EDGE_HALF_WINDOW)
    offsets = np.arange(4, 4 + LEVEL_SAMPLES)[None, :]
    before = samples[rows, np.clip(index[:, None] - offsets, 0, count - 1)]
    after = samples[rows, np.clip(index[:, None] + offsets, 0, count - 1)]
    return _row_medians(before), _row_medians(after), in_frame


def _row_medians(values: NDArray[Any]) -> FloatArray:
    """Median of each row's finite values (NaN where it has none): ``np.nanmedian(axis=1)``, vectorised."""
    ordered = np.sort(values, axis=1)  # NaN sort last
    count = np.sum(np.isfinite(values), axis=1)
    rows = np.arange(values.shape[0])
    low = ordered[rows, np.maximum(count - 1, 0) // 2]
    high = ordered[rows, np.maximum(count, 1) // 2 - (count == 0)]
    return np.where(count > 0, 0.5 * (low + high), np.nan)
