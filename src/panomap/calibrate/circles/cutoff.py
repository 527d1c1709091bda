"""The cut-off disc (the mirror's self-reflection): about a centre, or found without a rim."""

from __future__ import annotations

import math
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from ...errors import PanomapError
from ...geometry import FloatArray
from .fitting import _robust_circle
from .sampling import _downscaled, _profiles, _row_medians, _step_levels, _subpixel_peak, to_grey
from .thresholds import (
    CUTOFF_CENTRE_FRACTION,
    CUTOFF_ITERATIONS,
    CUTOFF_MIN_MEDIAN_RISE,
    CUTOFF_MIN_RATIO,
    DISC_CANDIDATES,
    DISC_GRID_HALF,
    DISC_GRID_STEP,
    DISC_MAX_OFFSET,
    DISC_MIN_FRACTION,
    DISC_RADII,
    EDGE_HALF_WINDOW,
    LEVEL_SAMPLES,
    MAX_CUTOFF_RMS_PX,
    MIN_CUTOFF_FRACTION,
    PROFILE_SIGMA_PX,
    RAYS,
    STEP,
)
from .types import Circle


def _cutoff_circle(grey: NDArray[Any], centre: tuple[float, float], outer_radius: float) -> Circle | None:
    """The self-occlusion disc: a dark-to-bright step at one radius on most rays; None when there is none.

    The disc's radius is where the median over the rays of the radial gradient peaks,
    so that a textured or lit self-reflection, or scene edges, do not hide it; each
    ray's steepest rise near that radius is then fitted as the rim is. The peak is looked
    for from 0.8 CUTOFF_MIN_RATIO of ``outer_radius`` up (a fitted edge may lie a little
    outside the peak's radius), and a disc is kept only from CUTOFF_MIN_RATIO up: a smaller
    dark thing at the centre is no camera's reflection (a fisheye's).
    """
    # The median over a quarter of the rays finds the radius; all of them then find the edge.
    smallest = CUTOFF_MIN_RATIO * outer_radius
    radii = np.arange(2.0, 0.75 * outer_radius, STEP)
    samples, _, _ = _profiles(grey, centre, radii, RAYS // 4)
    gradient = np.gradient(samples, axis=1) / STEP
    if not np.isfinite(gradient).any():
        return None
    # The median gradient per radius over the rays that are in the frame there.
    score = np.nan_to_num(_row_medians(gradient.T))
    score = np.convolve(score, np.ones(5) / 5, mode="same")
    score[radii < 0.8 * smallest] = 0.0
    index = int(np.argmax(score))
    if score[index] < CUTOFF_MIN_MEDIAN_RISE:
        return None
    radius = float(radii[index])

    def passes(circle: Circle | None, reach_px: float) -> bool:
        return (
            circle is not None
            and circle.radius >= smallest
            and circle.inliers >= MIN_CUTOFF_FRACTION * RAYS
            and circle.rms_px <= MAX_CUTOFF_RMS_PX
            and math.dist(circle.centre, centre) < reach_px
        )

    circle = _cutoff_edge(grey, centre, radius)
    if passes(circle, max(2.0, 0.05 * radius)):
        return circle
    # The disc is centred on the optical axis, which can sit a few px off the rim's centre (a
    # mirror not quite centred in its housing): its edge is searched for again, first as far
    # either side of the radius as the centres may differ, then about each fit's own centre.
    reach = max(2.0, CUTOFF_CENTRE_FRACTION * outer_radius)
    circle = _cutoff_edge(grey, centre, radius, half_px=reach)
    for _ in range(CUTOFF_ITERATIONS):
        if circle is None:
            return None
        found = _cutoff_edge(grey, circle.centre, circle.radius)
        moved = math.inf if found is None else math.dist(found.centre, circle.centre)
        circle = found
        if moved < 0.05:
            break
    return circle if passes(circle, reach) else None


def find_cutoff_about(image: NDArray[Any], centre: tuple[float, float], outer_radius: float) -> Circle | None:
    """The cut-off disc of an omni-image looked for about ``centre`` (u, v), px, in an image circle of
    ``outer_radius`` px, or None: :func:`find_image_circles`' search about the rim's centre, for a caller
    that knows the optical axis better (a centre refined with landmarks, where the rim's was off)."""
    return _cutoff_circle(to_grey(image), centre, outer_radius)


def find_cutoff_without_rim(image: NDArray[Any]) -> Circle | None:
    """The cut-off disc of an omni-image whose rim is not in it (a mirror image that overfills the frame), or
    None: :func:`find_image_circles`' search where no rim passes (see :func:`_disc_without_rim`), for a caller
    that knows the rim found is wrong (landmarks far outside it)."""
    grey = to_grey(image)
    small, factor = _downscaled(grey)
    return _disc_without_rim(grey, small, factor)


def _disc_without_rim(grey: NDArray[Any], small: NDArray[Any], factor: int) -> Circle | None:
    """The cut-off disc of an image with no rim (a mirror image that overfills the frame); None when none is clear.

    About each centre of a grid near the frame's middle (DISC_GRID_HALF of the short side,
    in steps of DISC_GRID_STEP), in ``small`` (``grey`` shrunk by ``factor``), the median over
    the rays of the radial gradient peaks at the disc's radius, highest about its centre
    (off it, the peak spreads: 5-7 px off a disc of 113-230 px, it fell under the bar that
    :func:`_cutoff_circle` sets, which is why that search alone missed 3 of 10). A camera's
    board about its lens peaks too (its square edge, further out): the DISC_CANDIDATES
    highest peaks of different radii are tried in turn, each edge fitted at full resolution
    from its centre, then about each fit's centre, as the disc of an image with a rim is;
    the first that is clear is kept (DISC_MIN_FRACTION of the rays, within DISC_MAX_OFFSET of
    the middle, a radius within DISC_RADII of the short side).
    """
    height, width = grey.shape
    short = min(height, width)
    middle = ((width - 1) / 2, (height - 1) / 2)
    radii = np.arange(2.0, DISC_RADII[1] * short / factor, STEP)
    steps = round(DISC_GRID_HALF / DISC_GRID_STEP)
    offsets = np.arange(-steps, steps + 1) * DISC_GRID_STEP * short
    starts = [(middle[0] + du, middle[1] + dv) for du in offsets for dv in offsets]
    coarse = (np.asarray(starts) + 0.5) / factor - 0.5
    # (A row of the grid at a time: arrays that stay in the cache.)
    scores = np.concatenate([_median_rise(small, row, radii, RAYS // 8) for row in np.split(coarse, len(offsets))])
    local = (scores[:, 1:-1] >= scores[:, :-2]) & (scores[:, 1:-1] > scores[:, 2:])
    local &= scores[:, 1:-1] >= CUTOFF_MIN_MEDIAN_RISE
    peaks = [  # (score, centre, radius px), in the grid's order
        (float(scores[i, k + 1]), starts[i], float(radii[k + 1]) * factor) for i, k in np.argwhere(local)
    ]
    tried: list[float] = []
    for _, seed, radius in sorted(peaks, key=lambda peak: -peak[0]):
        if len(tried) == DISC_CANDIDATES:
            break
        if any(abs(radius - other) < 0.1 * other for other in tried):
            continue
        tried.append(radius)
        circle = _cutoff_edge(grey, seed, radius, half_px=DISC_GRID_HALF * short)
        for _ in range(CUTOFF_ITERATIONS):
            if circle is None:
                break
            found = _cutoff_edge(grey, circle.centre, circle.radius)
            moved = math.inf if found is None else math.dist(found.centre, circle.centre)
            circle = found
            if moved < 0.05:
                break
        if (
            circle is not None
            and circle.inliers >= DISC_MIN_FRACTION * RAYS
            and circle.rms_px <= MAX_CUTOFF_RMS_PX
            and math.dist(circle.centre, middle) <= DISC_MAX_OFFSET * short
            and DISC_RADII[0] * short < circle.radius < DISC_RADII[1] * short
        ):
            return circle
    return None


def _median_rise(image: NDArray[Any], centres: FloatArray, radii: FloatArray, rays: int) -> FloatArray:
    """The median over ``rays`` rays of the profiles' radial gradient (dark to bright going out, grey levels
    per px) about each of ``centres`` (n, 2) at ``radii`` (R,), smoothed over 5 samples: (n, R).

    :func:`_profiles` about every centre at once (one remap, one blur for all of them).
    """
    angles = np.linspace(0.0, 2 * math.pi, rays, endpoint=False)
    count = len(centres)
    map_u = (centres[:, 0, None, None] + np.cos(angles)[:, None] * radii[None, :]).astype(np.float32)
    map_v = (centres[:, 1, None, None] + np.sin(angles)[:, None] * radii[None, :]).astype(np.float32)
    map_u, map_v = map_u.reshape(count * rays, len(radii)), map_v.reshape(count * rays, len(radii))
    height, width = image.shape
    samples = cv2.remap(image, map_u, map_v, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan)
    samples[(map_u < 0) | (map_u > width - 1) | (map_v < 0) | (map_v > height - 1)] = np.nan
    samples = cv2.GaussianBlur(samples, (13, 1), PROFILE_SIGMA_PX / STEP, borderType=cv2.BORDER_REPLICATE)
    gradient = (np.gradient(samples, axis=1) / STEP).reshape(count, rays, len(radii))
    medians = _row_medians(gradient.transpose(0, 2, 1).reshape(count * len(radii), rays)).reshape(count, -1)
    padded = np.pad(np.nan_to_num(medians), ((0, 0), (2, 2)))
    return np.asarray(sum(padded[:, k : k + len(radii)] for k in range(5)) / 5, dtype=float)


def _cutoff_edge(grey: NDArray[Any], centre: tuple[float, float], radius: float, half_px: float = 0.0) -> Circle | None:
    """The circle through each ray's steepest dark-to-bright step within 5% (3 px, ``half_px`` at least) of
    ``radius`` about ``centre``; None where too few rays have one."""
    half = max(3.0, 0.05 * radius, half_px)
    margin = STEP * (EDGE_HALF_WINDOW + LEVEL_SAMPLES + 4)
    radii = np.arange(max(radius - half - margin, 1.0), radius + half + margin, STEP)
    samples, cos, sin = _profiles(grey, centre, radii)
    gradient = np.gradient(samples, axis=1) / STEP
    finite = np.isfinite(gradient)
    window = np.abs(radii - radius) <= half
    rising = np.where(window[None, :] & finite, gradient, -np.inf)
    best = np.clip(np.argmax(rising, axis=1), 1, len(radii) - 2)
    rows = np.arange(RAYS)
    before, after, in_frame = _step_levels(samples, best)
    good = in_frame & (gradient[rows, best] > 2.0) & (after - before > 8.0)
    if good.sum() < MIN_CUTOFF_FRACTION * RAYS:
        return None
    where = radii[0] + STEP * _subpixel_peak(np.where(finite, gradient, 0.0), best)
    r = where[good]
    points = np.stack([centre[0] + r * cos[good], centre[1] + r * sin[good]], axis=-1)
    try:
        return _robust_circle(points, centre, radius)
    except PanomapError:
        return None
