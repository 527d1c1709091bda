"""Evidence that a circle is the rim: rim edge points along rays, edges that step or stand out
(features), the smooth outside.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from ...geometry import FloatArray
from .frame import away_from_frame
from .sampling import _edge_strength, _profiles, _row_medians, _step_levels, _subpixel_peak
from .thresholds import (
    CLEAR_DROP,
    CONVINCING_RIM_FRACTION,
    EDGE_HALF_WINDOW,
    FALL_SLOPE_PX,
    FALL_WIDTH_SHARE,
    FEATURE_MIN_RATIO,
    FEATURE_MIN_STRENGTH,
    HALFWAY_WINDOW_PX,
    LINE_LEAST_LEVELS,
    LINE_SLOPE_RATIO,
    LINE_WIDTH_PX,
    RAYS,
    SOFT_FALL_PX,
    STEP,
    WIDE_REACH,
)
from .types import Circle


def _smooth_beyond(grey: NDArray[Any], circle: Circle) -> bool:
    """Whether the image past the circle (4 px to WIDE_REACH of the radius) has no clear edge on most rays.

    Past a mirror's rim lies its housing, out of focus; past a circle of the scene inside
    the mirror, the rest of the mirror. On each ray the strongest edge there (smoothed as
    for the rim) is taken; their median over the rays seen there must stay under
    FEATURE_MIN_STRENGTH, and half the rays must be seen there.
    """
    radii = np.arange(circle.radius + 4.0, circle.radius * (1 + WIDE_REACH), STEP)
    samples, _, _ = _profiles(grey, circle.centre, radii, RAYS // 4)
    strength = np.where(np.isfinite(samples), _edge_strength(samples), np.nan)
    seen = np.sum(np.isfinite(samples), axis=1) >= 0.5 * len(radii)
    if seen.sum() < 0.5 * len(seen):
        return False
    strongest = np.nanmax(strength[seen], axis=1)
    return bool(np.median(strongest) < FEATURE_MIN_STRENGTH)


def _stepping_rays(grey: NDArray[Any], circle: Circle, polarity: int) -> int:
    """Rays along which the level 2-12 px inside the circle exceeds that 2-12 px outside by 8 grey levels."""
    radii = circle.radius + np.concatenate([np.arange(-12.0, -2.0, STEP), np.arange(2.5, 12.5, STEP)])
    samples, _, _ = _profiles(grey, circle.centre, radii)
    half = samples.shape[1] // 2
    inside, outside = _row_medians(samples[:, :half]), _row_medians(samples[:, half:])
    with np.errstate(invalid="ignore"):
        return int(np.sum(polarity * (inside - outside) > 8.0))


def _feature_rays(grey: NDArray[Any], circle: Circle) -> int:
    """Rays on which an edge or a line, of either polarity, stands out on the circle.

    On each ray the strongest edge within 1.5 px of the circle must reach FEATURE_MIN_STRENGTH
    and FEATURE_MIN_RATIO times the median edge strength 4-12 px either side of it: a
    rim's edge stands out from the smooth mirror and housing beside it, while a circle
    through scene edges meets an edge only where it crosses one.
    """
    radii = circle.radius + np.arange(-14.0, 14.0 + STEP / 2, STEP)
    samples, _, _ = _profiles(grey, circle.centre, radii)
    strength = _edge_strength(samples)
    # Across the rays (1 px along the circle either way): a rim's edge runs along the circle.
    turn = 1.0 / circle.radius
    ahead, _, _ = _profiles(grey, circle.centre, radii, turn_rad=turn)
    behind, _, _ = _profiles(grey, circle.centre, radii, turn_rad=-turn)
    across = np.abs(ahead - behind) / 2
    across = np.where(np.isfinite(across), across, 0.0).astype(np.float32)
    across = cv2.GaussianBlur(across, (17, 1), 2.0 / STEP, borderType=cv2.BORDER_REPLICATE)
    offset = np.abs(radii - circle.radius)
    near = np.flatnonzero(offset <= 1.5)
    index = near[np.argmax(strength[:, near], axis=1)]
    rows = np.arange(RAYS)
    on = strength[rows, index]
    beside = np.median(strength[:, (offset >= 4) & (offset <= 12)], axis=1)
    in_frame = np.all(np.isfinite(samples[:, offset <= 12]), axis=1)
    along = on >= FEATURE_MIN_RATIO * across[rows, index]
    return int(np.sum(in_frame & along & (on >= FEATURE_MIN_STRENGTH) & (on >= FEATURE_MIN_RATIO * beside)))


def _either_polarity(grey: NDArray[Any], circle: Circle) -> str:
    """``'dark inside'`` when the level steps up across the circle on most of the rays that step, else ``'mixed'``."""
    up = _stepping_rays(grey, circle, -1)
    down = _stepping_rays(grey, circle, 1)
    return "dark inside" if up >= CONVINCING_RIM_FRACTION * (up + down) else "mixed"


def _rim_points(
    grey: NDArray[Any], centre: tuple[float, float], radius: float, polarity: int, reach: float, halfway: bool = False
) -> FloatArray:
    """Sub-pixel rim edge points (n, 2): the steepest step near ``radius``, from bright to dark going out.

    ``polarity`` -1 looks for the steepest dark-to-bright step instead. Only edges
    whose neighbourhood lies in the frame count: the frame's border is no rim. The
    search runs ``reach`` times the radius either side of it. Each ray's outermost
    clear drop is taken, not its steepest: past the rim the border stays dark, while
    a scene edge inside the disc (a dark target, a checkerboard) may be steeper than
    a soft rim. With ``halfway``, each ray's half-level crossing instead, on a soft rim only
    where its fall is as wide as the rim's (:func:`_as_wide_as_the_rim`).
    """
    half = max(reach * radius, 8.0)
    radii = np.arange(max(radius - half, 1.0), radius + half, STEP)
    samples, cos, sin = _profiles(grey, centre, radii)
    drops = _drops(samples, polarity)
    steps = drops
    if halfway:
        # Re-measuring a rim found: a thin line's far side (a lens barrel's lit edge just past the rim) is no rim,
        # and the line itself no part of the rim's step.
        # Only past the circle's radius less a line's width: a lit ring lies past the rim, the scene's lines inside.
        opened = np.where(radii[None, :] >= radius - LINE_WIDTH_PX, _without_lines(samples, polarity), samples)
        far = _far_sides(drops) | _past_lines(polarity * (samples - opened))
        samples, drops = opened, _drops(opened, polarity)
        steps = np.where(far, np.float32(0.0), drops)
    index = np.clip(np.argmax(steps[:, 1:-1], axis=1) + 1, 1, len(radii) - 2)
    rows = np.arange(RAYS)
    middle = steps[:, 1:-1]
    clear = middle > np.maximum(2.0, CLEAR_DROP * steps[rows, index])[:, None]
    clear &= middle >= drops[:, :-2]
    clear &= middle > drops[:, 2:]
    last = clear.shape[1] - 1 - np.argmax(clear[:, ::-1], axis=1)
    index = np.where(clear.any(axis=1), last + 1, index)
    drop = drops[rows, index]
    inside, outside, in_frame = _step_levels(samples, index)
    # A rim: a steep step to something clearly darker (brighter for polarity -1).
    good = in_frame & (drop > 2.0) & (polarity * (inside - outside) > 8.0)
    if halfway:
        at = _halfway(samples, index, polarity)
        where = radii[0] + STEP * at
        good &= _as_wide_as_the_rim(_fall_widths(samples, drops, at, polarity), good)
    else:
        where = radii[0] + STEP * _subpixel_peak(drops, index)
    r = where[good]
    points = np.stack([centre[0] + r * cos[good], centre[1] + r * sin[good]], axis=-1)
    return away_from_frame(points, grey.shape)


def _feature_points(
    grey: NDArray[Any], centre: tuple[float, float], radius: float, reach: float, nearest: bool, beyond: float = 0.0
) -> FloatArray:
    """Sub-pixel rim points (n, 2) of either polarity: peaks of the edge strength near ``radius``.

    A rim whose contrast changes sign around the circle (a mirror in a bright housing:
    darker inside on some arcs, a thin bright or dark line on others) has no one
    polarity to look for. Each ray's clear peaks of the gradient magnitude within
    ``reach`` times the radius either side of it are the candidates: all of them (a
    rough start, for the consensus fit to choose from) or, with ``nearest``, the one
    nearest the start circle on each ray. Only peaks whose neighbourhood lies in the
    frame, and further than ``beyond`` (px) from ``centre``, count.
    """
    half = max(reach * radius, 8.0)
    radii = np.arange(max(radius - half, 1.0, beyond - EDGE_HALF_WINDOW * STEP), radius + half, STEP)
    samples, cos, sin = _profiles(grey, centre, radii)
    strength = _edge_strength(samples)
    rows = np.arange(RAYS)
    middle = strength[:, 1:-1]
    strongest = middle.max(axis=1)
    peak = (middle >= strength[:, :-2]) & (middle > strength[:, 2:])
    peak &= middle > np.maximum(FEATURE_MIN_STRENGTH, CLEAR_DROP * strongest)[:, None]
    # The neighbourhood in the frame: EDGE_HALF_WINDOW samples either way finite.
    finite = np.isfinite(samples).astype(np.float32)
    window = cv2.blur(finite, (2 * EDGE_HALF_WINDOW + 1, 1), borderType=cv2.BORDER_CONSTANT)
    peak &= (window[:, 1:-1] > 1 - 1e-6) & (radii[1:-1] > beyond)[None, :]
    if nearest:
        distance = np.where(peak, np.abs(radii[1:-1] - radius)[None, :], np.inf)
        index = np.argmin(distance, axis=1)
        ray = rows[np.isfinite(distance[rows, index])]
        index = index[ray] + 1
    else:
        ray, index = np.nonzero(peak)
        index = index + 1
    where = radii[0] + STEP * _feature_position(samples[ray], index) if len(ray) else np.zeros(0)
    points = np.stack([centre[0] + where * cos[ray], centre[1] + where * sin[ray]], axis=-1)
    return np.asarray(away_from_frame(points, grey.shape), dtype=np.float64)


def _feature_position(samples: NDArray[Any], index: NDArray[Any]) -> FloatArray:
    """Sub-sample position of each row's edge or line found near ``index`` (a peak of the smoothed edge strength).

    The wide smoothing that merges a thin line's two slopes into one peak also pulls that
    peak towards any slope beside it; the position is therefore read from the profile
    itself: a line (slopes of both signs, each at least half the other, within 2 px) at
    its extreme level, a step at its steepest slope, each by a parabola through three samples.
    """
    count = samples.shape[1]
    rows = np.arange(samples.shape[0])
    span = np.arange(-4, 5)
    near = np.clip(index[:, None] + span[None, :], 1, count - 2)
    gradient = np.gradient(samples, axis=1)
    slopes = np.where(np.isfinite(gradient[rows[:, None], near]), gradient[rows[:, None], near], 0.0)
    rise, fall = slopes.max(axis=1), -slopes.min(axis=1)
    line = np.minimum(rise, fall) > 0.5 * np.maximum(rise, fall)
    level = np.where(np.isfinite(samples[rows[:, None], near]), samples[rows[:, None], near], np.nan)
    # A bright line peaks, a dark one dips: the extreme the slopes point to (rise before fall: bright).
    bright = np.argmax(slopes, axis=1) < np.argmin(slopes, axis=1)
    extreme = np.where(
        bright,
        np.nanargmax(np.nan_to_num(level, nan=-np.inf), axis=1),
        np.nanargmin(np.nan_to_num(level, nan=np.inf), axis=1),
    )
    steepest = np.argmax(np.abs(slopes), axis=1)
    at = near[rows, np.where(line, extreme, steepest)]
    at = np.clip(at, 1, count - 2)
    signed = np.where(bright, 1.0, -1.0)[:, None]
    values = np.where(line[:, None], signed * samples, np.abs(gradient))
    return _subpixel_peak(np.where(np.isfinite(values), values, 0.0), at)


def _far_sides(drops: NDArray[Any]) -> NDArray[np.bool_]:
    """Where each ray's drop (rays, R; grey levels per px going out, the rim's polarity) is the far side of a
    thin line: a slope the other way at least LINE_SLOPE_RATIO of it within LINE_WIDTH_PX inward.

    A lens barrel's edge lit past the rim (a bright ring a few px out on some arcs: a Ricoh Theta's, a glow at
    an OCam's rim) falls to the dark surround as the rim does, further out: each ray's outermost clear drop
    was the ring's on those arcs and the rim's on the others, the centre pulled towards the ring by several px
    (unkind renders, bench/bench_circles_unkind.py). A rim is a step: the level does not rise just before it.
    """
    width = max(1, round(LINE_WIDTH_PX / STEP))
    rises = np.maximum(-drops, 0.0).astype(np.float32)
    # The highest rise over the ``width`` samples inward and the sample itself (no rise where there is a drop).
    kernel = np.ones((1, width + 1), np.uint8)
    before = cv2.dilate(rises, kernel, anchor=(width, 0), borderType=cv2.BORDER_CONSTANT, borderValue=0.0)
    return np.asarray((drops > 0) & (before >= LINE_SLOPE_RATIO * drops))


def _drops(samples: NDArray[Any], polarity: int) -> NDArray[Any]:
    """The drop in level going out along each ray (rays, R; grey levels per px; a rise for ``polarity`` -1), 0
    off the image; each pass in place, as these arrays are the search's bulk."""
    drops = np.gradient(samples, axis=1)
    np.nan_to_num(drops, copy=False, nan=0.0)
    drops *= np.float32(-polarity / STEP)
    return drops


def _past_lines(removed: NDArray[Any]) -> NDArray[np.bool_]:
    """Where each ray (rays, R) lies within LINE_WIDTH_PX past (outward of) a line that :func:`_without_lines`
    removed, LINE_LEAST_LEVELS grey levels or more high: ``removed`` is what it took off (the rim's polarity)."""
    width = max(1, round(LINE_WIDTH_PX / STEP))
    kernel = np.ones((1, width + 1), np.uint8)
    high = np.nan_to_num(np.asarray(removed, np.float32), nan=0.0)
    before = cv2.dilate(high, kernel, anchor=(width, 0), borderType=cv2.BORDER_CONSTANT, borderValue=0.0)
    return np.asarray(before >= LINE_LEAST_LEVELS)


def _without_lines(samples: NDArray[Any], polarity: int) -> NDArray[Any]:
    """Profiles (rays, R; NaN off the frame) with every line of the rim's polarity (bright for ``polarity`` 1)
    narrower than LINE_WIDTH_PX removed: a grey opening along each ray (a closing for ``polarity`` -1).

    A step, blurred or not, is monotone and an opening leaves it exactly where it is; a lens barrel's edge lit
    just past the rim (a bright ring 1-2 px wide, 4-9 px out) sits on the rim's blurred outer slope, where the
    level rises again before it falls to the surround: the ring's rise was too small beside its fall for
    :func:`_far_sides` to see a line, and its level over the rim's half level, so each ray's half-level crossing
    there was the ring's far side (a robot's fisheye render: the centre 4.3 px off, bench/bench_circles_unkind.py).
    Opened, the ring is the level of the valley before it, and the crossing is the rim's.
    """
    width = 2 * max(1, round(LINE_WIDTH_PX / STEP / 2)) + 1
    kernel = np.ones((1, width), np.uint8)
    level = np.asarray(polarity * samples, np.float32)
    missing = ~np.isfinite(level)
    # Off the frame counts as neither the lowest (in the erosion) nor the highest (in the dilation).
    eroded = cv2.erode(np.where(missing, np.float32(np.inf), level), kernel, borderType=cv2.BORDER_REPLICATE)
    eroded = np.where(missing, -np.inf, eroded).astype(np.float32)
    opened = cv2.dilate(eroded, kernel, borderType=cv2.BORDER_REPLICATE)
    return np.where(missing, np.nan, polarity * opened)


def _fall_widths(samples: NDArray[Any], drops: NDArray[Any], at: FloatArray, polarity: int) -> FloatArray:
    """Each ray's fall width (px) at its half-level crossing ``at`` (rays, R; sub-sample positions): its step (the
    highest level HALFWAY_WINDOW_PX inside less the lowest as far outside, the rim's polarity) over its steepest drop
    within FALL_SLOPE_PX of the crossing. A step blurred by a Gaussian of sigma s is sqrt(2 pi) s wide; NaN where
    the ray has no drop there."""
    count = samples.shape[1]
    cols = np.arange(count)[None, :]
    centre = np.rint(at)[:, None]
    width = max(1, round(HALFWAY_WINDOW_PX / STEP))
    level = polarity * samples
    with np.errstate(invalid="ignore"):
        high = np.nanmax(np.where((cols >= centre - width) & (cols <= centre), level, -np.inf), axis=1)
        low = np.nanmin(np.where((cols >= centre) & (cols <= centre + width), level, np.inf), axis=1)
    near = np.abs(cols - centre) <= max(1, round(FALL_SLOPE_PX / STEP))
    steepest = np.max(np.where(near, drops, 0.0), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(steepest > 0, (high - low) / steepest, np.nan)


def _as_wide_as_the_rim(widths: FloatArray, good: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """Which rays' falls (``widths``, px) are as wide as the rim's: at least FALL_WIDTH_SHARE of the median over the
    ``good`` rays, where that median is SOFT_FALL_PX or more; every ray where it is less (a sharp rim).

    A field stop out of focus blurs the rim alike all round; the scene is in focus. Where a dark thing of the scene
    lies at a soft rim (a checkerboard's black square, a dark wall), the ray's half level falls at the thing's edge,
    5-10 px inside the rim, and that fall is a few times narrower than the rim's."""
    finite = good & np.isfinite(widths)
    if finite.sum() == 0:
        return good
    median = float(np.median(widths[finite]))
    if median < SOFT_FALL_PX:
        return good
    with np.errstate(invalid="ignore"):
        return np.asarray(good & (widths >= FALL_WIDTH_SHARE * median))


def _halfway(samples: NDArray[Any], index: NDArray[Any], polarity: int) -> FloatArray:
    """Sub-sample position on each ray (rays, R) of the crossing, going out, nearest sample ``index`` of the level
    halfway between the highest level (the rim's polarity) HALFWAY_WINDOW_PX inside ``index`` and the lowest as far
    outside it, within that window; ``index`` where there is none.

    A blurred step's half level is its edge whatever the blur (a field stop out of focus); its steepest slope is
    too, but only where nothing else lies on the slope: a lit barrel's ring on the rim's outer slope (a shoulder),
    or a glow past it, made each ray's outermost clear drop the ring's, several px out on the arcs where it shows
    (bench/bench_circles_unkind.py). The ring's level lies under the half level: the crossing stays the rim's.
    """
    rows = np.arange(samples.shape[0])
    count = samples.shape[1]
    width = max(1, round(HALFWAY_WINDOW_PX / STEP))
    cols = np.arange(count)[None, :]
    level = polarity * samples
    inner = (cols >= index[:, None] - width) & (cols <= index[:, None])
    outer = (cols >= index[:, None]) & (cols <= index[:, None] + width)
    with np.errstate(invalid="ignore"):
        high = np.nanmax(np.where(inner, level, -np.inf), axis=1)
        low = np.nanmin(np.where(outer, level, np.inf), axis=1)
        half = 0.5 * (high + low)
        above = level > half[:, None]
    crossing = above[:, :-1] & ~above[:, 1:] & (inner | outer)[:, :-1] & (inner | outer)[:, 1:]
    has = crossing.any(axis=1) & np.isfinite(half)
    distance = np.where(crossing, np.abs(cols[:, :-1] - index[:, None]), count)
    last = np.where(has, np.argmin(distance, axis=1), 0)
    before, after = level[rows, last], level[rows, last + 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        fraction = np.where(before > after, (before - half) / (before - after), 0.5)
    return np.where(has, last + np.clip(fraction, 0.0, 1.0), index)
